"""LaTeX in the papers' notation, by SymPy printer type dispatch.

Step symbols print as their names (x_{k+1}, (g_{k})_{12}, (\\lambda_{k+1})_{1}); matrix
entries are 1-based; diagonal constant matrices print as diag(…); traces as tr(…);
trigonometric functions as \\sin(x) (parentheses sized only around fractions); a
:class:`Collected` term as its common factor times its sum in parentheses.

Whole steps print through :mod:`._printing` (named pieces, collected terms, a "where" list,
every printed equation verified against the explicit residual) and :mod:`._layout` (rows
broken to a page width).
"""

from __future__ import annotations

import re

import sympy as sp
from sympy.functions.elementary.trigonometric import TrigonometricFunction
from sympy.matrices.expressions.matexpr import MatrixElement
from sympy.matrices.expressions.trace import Trace
from sympy.printing.latex import LatexPrinter

from .._arguments import flag_argument, shown_value
from .._errors import SymgroupoidError
from .._symbols import StepSymbol, greek_spelled

#: operations of a step's residual program above which Jupyter shows the plain repr instead
#: of the typeset equations (printing a 5-link planar chain, about 300 operations, takes a
#: few seconds)
DISPLAY_LIMIT = 400

#: operations of a step's residuals written out as expression trees
#: (:meth:`~symgroupoid.ir.Program.expanded_size`) above which they are not printed: every
#: printed form is derived from and checked against the written-out residuals, whose cost
#: grows with that size (measured: the 3D chain of 8 bodies, 6.5e4 operations, 10 s; the
#: planar chain of 16 links, 1.2e5, 48 s), while a continuous system discretised on a Lie
#: group shares its stages' subexpressions so much that 2 000 graph operations write out
#: to 10⁹ (a free rigid body at order 4, whose printing never finished)
PRINT_LIMIT = 1_000_000

#: terms of a step's residuals expanded (:func:`~._printing.expanded_terms`: products
#: multiplied out over sums, a bound without cancellation) above which they are not printed:
#: printing collects and checks the expanded residuals, and a rational L whose products of
#: sums share few subexpressions expands far beyond its size written out (measured: the
#: planar chain of 32 links, 2.4e4 terms, 115 s; the second-order attitude problem on SO(3),
#: 4.9e4 operations written out but 1.5e6 terms, never finished)
EXPANSION_LIMIT = 100_000


#: the most nonzero entries a square matrix of ±1 and 0 is written with by place
UNIT_ENTRIES = 4


def _unit_entries(expr) -> list[tuple[int, int, int]] | None:
    """(i, j, ±1) of every nonzero entry of a square matrix (at least 2 × 2) whose entries
    are 0, 1 or −1, at most :data:`UNIT_ENTRIES` of them — printed Σ ±e_i e_jᵀ (e_i the
    standard basis vectors), which a LaTeX matrix environment is not needed for; else None."""
    rows, cols = expr.shape
    if rows != cols or rows < 2:
        return None
    out = []
    for i in range(rows):
        for j in range(cols):
            v = expr[i, j]
            if v == 0:
                continue
            if v not in (1, -1) or len(out) == UNIT_ENTRIES:
                return None
            out.append((i, j, int(v)))
    return out or None


def unit_vector_dimension(expr) -> int | None:
    """n when ``expr`` is an n × n matrix printed in the unit vectors e_i of Rⁿ (Σ ±e_i e_jᵀ,
    :func:`_unit_entries`), which the "where" list then says; else None."""
    if not isinstance(expr, sp.MatrixBase) or expr.is_diagonal():
        return None
    return expr.shape[0] if _unit_entries(expr) is not None else None


class LatexVerificationError(SymgroupoidError, AssertionError):
    """A printed form of an equation is not the equation (a defect of the printing: the
    forms are built to be equal, and checked before they are printed)."""


class Collected(sp.Expr):
    """``factor · (total)`` kept as written: terms collected by a common factor.

    ``Collected(h/2, a + b)`` prints as ``\\frac{h}{2} \\left(a + b\\right)``,
    ``Collected(1/h, a - b)`` as ``\\frac{a - b}{h}``;
    :meth:`expanded` is the plain product (what verification compares).
    """

    is_commutative = True

    def __new__(cls, factor, total):
        return sp.Expr.__new__(cls, sp.sympify(factor), sp.sympify(total))

    @property
    def factor(self) -> sp.Expr:
        return self.args[0]

    @property
    def total(self) -> sp.Expr:
        return self.args[1]

    def expanded(self) -> sp.Expr:
        """The product ``factor · total`` (nested collections expanded too)."""
        return self.factor * uncollected(self.total)


def uncollected(expr: sp.Expr) -> sp.Expr:
    """``expr`` with every :class:`Collected` replaced by its product."""
    return expr.replace(lambda e: isinstance(e, Collected), lambda e: e.expanded())


class NamedOperator(sp.MatrixSymbol):
    """A linear operator printed by name, e.g. Ad*_{g_k} (``NamedOperator(r"\\operatorname{Ad}
    ^{*}_{g_{k}}", 3, 3)``); its value is substituted when an equation is verified."""


class NamedConstant(StepSymbol):
    """A name printed verbatim that stands for an expression in the parameters only (a
    user's abbreviation M = m₁ + m₂): products order it with the parameters."""


class GroupoidLatexPrinter(LatexPrinter):
    """SymPy's LaTeX printer, extended for step-indexed symbols and matrix parts."""

    #: the fraction command (:class:`DisplayLatexPrinter`: ``\\dfrac``, as a display sets it)
    fraction = "\\frac"

    def __init__(self, settings=None):
        super().__init__({"mul_symbol": None, **(settings or {})})

    def _frac(self, numerator: str, denominator: str) -> str:
        """A fraction of two printed parts."""
        return f"{self.fraction}{{{numerator}}}{{{denominator}}}"

    def _print_StepSymbol(self, expr) -> str:
        return expr.name

    def _print_Symbol(self, expr, style="plain") -> str:
        """A symbol; Greek letters in its name printed as commands (:func:`greek_spelled`)."""
        spelled = greek_spelled(expr.name)
        if spelled != expr.name:
            expr = sp.Symbol(spelled, **expr.assumptions0)
        return super()._print_Symbol(expr, style)

    def _print_NamedOperator(self, expr) -> str:
        return expr.name

    def _print_MatrixElement(self, expr) -> str:
        parent = self._print(expr.parent)
        if not isinstance(expr.parent, sp.MatrixSymbol):
            parent = f"\\left({parent}\\right)"
        else:
            parent = f"({parent})"
        rows, cols = expr.parent.shape
        if cols == 1:
            return f"{parent}_{{{expr.i + 1}}}"
        return f"{parent}_{{{expr.i + 1}{expr.j + 1}}}"

    def _print_Trace(self, expr) -> str:
        """tr(g_{k} E_{1} E_{2}): plain parentheses unless the argument is tall (a fraction,
        an explicit matrix)."""
        arg = self._print(expr.arg)
        if _has_fraction(expr.arg) or any(isinstance(a, sp.MatrixBase)
                                          for a in sp.preorder_traversal(expr.arg)):
            return f"\\operatorname{{tr}}\\left({arg}\\right)"
        return f"\\operatorname{{tr}}({arg})"

    def _print_ImmutableDenseMatrix(self, expr) -> str:
        rows, cols = expr.shape
        if rows == cols and expr.is_diagonal():
            entries = ", ".join(self._print(expr[i, i]) for i in range(rows))
            return f"\\operatorname{{diag}}\\left({entries}\\right)"
        units = _unit_entries(expr)
        if units is not None:  # a Lie algebra's basis matrix E_a: its entries ±1 by place
            return " ".join(("- " if v < 0 else "+ " if k else "")
                            + f"e_{{{i + 1}}} e_{{{j + 1}}}^{{T}}"
                            for k, (i, j, v) in enumerate(units))
        return super()._print_MatrixBase(expr)

    _print_NamedMatrix = _print_ImmutableDenseMatrix

    def _print_trigonometric(self, expr: TrigonometricFunction, exp=None) -> str:
        """\\sin(x), \\cos^{2}(x - y): plain parentheses unless the argument has a fraction."""
        arg = self._print(expr.args[0])
        name = f"\\{type(expr).__name__}"
        if exp is not None:
            name += f"^{{{exp}}}"
        if _has_fraction(expr.args[0]):
            return f"{name}\\left({arg}\\right)"
        return f"{name}({arg})"

    _print_sin = _print_cos = _print_tan = _print_trigonometric
    _print_cot = _print_sec = _print_csc = _print_trigonometric

    def _print_Add(self, expr, order=None) -> str:
        """A sum whose terms all have coefficients over one denominator d > 1 prints over it:
        ``\\frac{q_{k+1} + q_{k}}{2}`` rather than ``\\frac{q_{k+1}}{2} + \\frac{q_{k}}{2}``."""
        denominator = _common_denominator(expr)
        if denominator == 1 or self.order in ("old", "none"):
            return self._print_difference(expr, order)
        numerator = sp.Add(*[t * denominator for t in expr.args])
        return self._frac(self._print_difference(numerator, order), str(denominator))

    def _print_difference(self, expr, order=None) -> str:
        """A sum of two terms, one negated, as the papers write a difference, the positive
        term first: t_{k} − t_{k−1} rather than − t_{k−1} + t_{k}; any other sum as SymPy
        orders it."""
        if not isinstance(expr, sp.Add) or self.order in ("old", "none"):
            return super()._print_Add(expr, order)
        terms = self._as_ordered_terms(expr, order=order)
        if len(terms) != 2 or not terms[0].could_extract_minus_sign() \
                or terms[1].could_extract_minus_sign():
            return super()._print_Add(expr, order)
        first, second = self._print(terms[1]), -terms[0]
        text = self._print(second)
        if self._needs_add_brackets(second):
            text = f"\\left({text}\\right)"
        return f"{first} - {text}"

    def _print_Mul(self, expr) -> str:
        """Products in the papers' order: numbers, parameters (plain symbols) and sums of
        them, step variables (x_{k}, (g_{k})_{12}, …), functions (\\sin, tr), then the
        rest: ``g h l_{1} \\left(m_{1} + m_{2}\\right) \\Delta x_{k} \\sin(\\bar{x}_{k})``.
        Settings that fold fractions, and non-commutative or unevaluated products, print
        as SymPy prints them."""
        if (isinstance(expr, sp.Pow) and expr.is_commutative and expr.exp.is_negative
                and expr.exp.is_Rational and expr.base != 1):
            return self._frac("1", self._print(1 / expr))  # 1/h, \\frac{1}{h^{2}}
        if (isinstance(expr, sp.Mul) and not expr.is_commutative
                and not self._settings["fold_short_frac"]
                and not self._settings["long_frac_ratio"]):
            return self._print_ordered_product(expr)
        if (not isinstance(expr, sp.Mul) or not expr.is_commutative
                or self._settings["fold_short_frac"] or self._settings["long_frac_ratio"]):
            return super()._print_Mul(expr)
        if self.order in ("old", "none") or _unevaluated(expr):
            return self._print_as_given(expr)
        if expr.could_extract_minus_sign():
            positive = -expr
            if not isinstance(positive, sp.Mul):
                return super()._print_Mul(expr)
            return "- " + self._print_Mul(positive)
        numerator, denominator = sp.fraction(expr, exact=True)
        if denominator == 1:
            return self._print_factors(expr)
        return self._frac(self._print_factors(numerator), self._print_factors(denominator))

    def _print_ordered_product(self, expr: sp.Mul) -> str:
        """A non-commutative product (operators applied in order, h Ad^T F/6): its rational
        coefficient's denominator through this printer's fraction (``\\dfrac`` in a
        display, which a page's width is measured with), the factors as SymPy prints them."""
        coeff, rest = expr.as_coeff_Mul()
        if not (isinstance(coeff, sp.Rational) and coeff.q != 1) or rest == 1:
            return super()._print_Mul(expr)
        if coeff < 0:
            return "- " + self._print_ordered_product(-expr)
        numerator = self._print(rest) if coeff.p == 1 else f"{coeff.p} {self._print(rest)}"
        return self._frac(numerator, str(coeff.q))

    def _print_as_given(self, expr: sp.Mul) -> str:
        """A product in the order given (``order="none"``, unevaluated products): a
        fraction of the factors with negative powers, as SymPy prints it; SymPy's own
        printing otherwise."""
        numerator, denominator = sp.fraction(expr, exact=True)
        if denominator == 1 or any(isinstance(a, sp.Number) for a in sp.Mul.make_args(
                numerator)) and len(sp.Mul.make_args(numerator)) > 1:
            return super()._print_Mul(expr)
        return self._frac(self._print(numerator), self._print(denominator))

    def _print_factors(self, expr) -> str:
        """The factors of a product side by side, in :func:`factor_rank` order, each
        bracketed where SymPy brackets it."""
        if isinstance(expr, list):
            factors = expr
        else:
            factors = expr.as_ordered_factors() if isinstance(expr, sp.Mul) else [expr]
        factors = _numbered_in_order(sorted(factors, key=factor_rank))  # stable within a rank
        texts = []
        for i, factor in enumerate(factors):
            tex = self._print(factor)
            if len(factors) > 1 and self._needs_mul_brackets(factor, first=i == 0,
                                                             last=i == len(factors) - 1):
                tex = f"\\left({tex}\\right)"
            texts.append(tex)
        return self._settings["mul_symbol_latex"].join(texts)

    def _print_Collected(self, expr: Collected) -> str:
        """``f \\left(a + b\\right)``; a factor 1/d prints as ``\\frac{a + b}{d}``."""
        numerator, denominator = sp.fraction(expr.factor)
        if factor_rank(expr.total) == 1:  # a sum of parameters: in the product's order
            factors = [f for f in sp.Mul.make_args(numerator) if f != 1]
            product = (self._print_factors([*factors, expr.total]) if factors
                       else self._print(expr.total))  # (1/h)(a + b): (a + b)/h, no "1 ("
            if denominator == 1:
                return product
            return self._frac(product, self._print(denominator))
        total = self._print(expr.total)
        if numerator == 1 and denominator != 1:
            return self._frac(total, self._print(denominator))
        factor = "" if expr.factor == 1 else self._print(expr.factor) + " "
        return f"{factor}\\left({total}\\right)"


class MemoLatexPrinter(GroupoidLatexPrinter):
    """The printer remembering what it printed (one printing of a whole step prints the same
    terms many times: to compare forms, to measure and to lay out lines)."""

    def __init__(self, settings=None):
        super().__init__(settings)
        self._printed: dict = {}

    def doprint(self, expr) -> str:
        if expr not in self._printed:
            self._printed[expr] = super().doprint(expr)
        return self._printed[expr]


class DisplayLatexPrinter(MemoLatexPrinter):
    """The printer as a display (``align``) sets it, for measuring widths: fractions at
    display size (``\\dfrac``), as TeX sets a fraction in a display; what matplotlib's
    mathtext measures with ``\\frac`` is the smaller inline fraction."""

    fraction = "\\dfrac"


def _common_denominator(expr: sp.Add) -> int:
    """d when every term's rational coefficient has the denominator d (else 1)."""
    coefficients = [t.as_coeff_Mul()[0] for t in expr.args]
    if not all(c.is_Rational for c in coefficients):  # a float (0.5) among them
        return 1
    denominators = {c.q for c in coefficients}
    return denominators.pop() if len(denominators) == 1 else 1


def _unevaluated(expr: sp.Mul) -> bool:
    """An unevaluated product (identities or several numbers kept): SymPy prints it as given."""
    args = expr.args
    return args[0] is sp.S.One or any(isinstance(a, sp.Number) for a in args[1:])


def _symbol_of(factor: sp.Expr) -> sp.Symbol | None:
    """The symbol of a factor s or sⁿ, else None."""
    base = factor.base if isinstance(factor, sp.Pow) else factor
    return base if isinstance(base, sp.Symbol) else None


def _natural_key(name: str) -> tuple:
    """A name's parts, its numbers compared as numbers (α_2 before α_10)."""
    return tuple((0, int(part), "") if part.isdigit() else (1, 0, part)
                 for part in re.split(r"(\d+)", name) if part)


def _numbered_in_order(factors: list) -> list:
    """``factors`` with the factors of symbols of each :func:`factor_rank` reordered among
    the places they hold, by their names' numbers as numbers (SymPy orders names as
    strings: α_1 α_10 α_11 α_2); the other factors keep their places."""
    out = list(factors)
    for rank in {factor_rank(f) for f in factors}:
        places = [i for i, f in enumerate(factors)
                  if factor_rank(f) == rank and _symbol_of(f) is not None]
        ordered = sorted((factors[i] for i in places),
                         key=lambda f: _natural_key(_symbol_of(f).name))
        for i, f in zip(places, ordered):
            out[i] = f
    return out


def factor_rank(factor: sp.Expr) -> int:
    """0 numbers, 1 parameters (plain symbols, their powers and sums), 2 step variables
    (:class:`StepSymbol`, matrix entries) and their powers, 3 functions and their powers,
    4 anything else."""
    base = factor.base if isinstance(factor, sp.Pow) else factor
    if isinstance(factor, sp.Number):
        return 0
    if _is_parameter(base) or isinstance(base, NamedConstant) or (isinstance(base, sp.Add) and all(
            _is_parameter(s) for s in base.free_symbols) and not base.atoms(
            sp.Function, MatrixElement)):
        return 1
    if isinstance(base, (StepSymbol, MatrixElement)):
        return 2
    if isinstance(base, (sp.Function, Trace)):
        return 3
    return 4


def _is_parameter(expr: sp.Expr) -> bool:
    return type(expr) is sp.Symbol


def _has_fraction(expr: sp.Expr) -> bool:
    """Whether ``expr`` prints with a fraction (a non-integer rational or a negative power)."""
    return any((isinstance(e, sp.Rational) and e.q != 1)
               or (isinstance(e, sp.Pow) and e.exp.is_negative)
               for e in sp.preorder_traversal(expr))


def latex(expr, **settings) -> str:
    """LaTeX of an expression in the papers' notation: a SymPy expression or matrix, a
    number, or a list, tuple, set or dict of them.  Anything else (which SymPy would print
    as its ``repr`` in typewriter type) and an unknown setting raise
    :class:`~symgroupoid.equations.LatexOptionError`."""
    from ._abbreviations import LatexOptionError

    if not _latex_value(expr):
        raise LatexOptionError(f"latex: expected a SymPy expression or matrix, a number, or "
                               f"a list, tuple, set or dict of them, got "
                               f"{type(expr).__name__} {expr!r:.80}")
    try:
        printer = GroupoidLatexPrinter(settings)
    except (TypeError, ValueError) as error:
        raise LatexOptionError(f"latex: {error} (the settings of sympy.latex)") from None
    try:
        return printer.doprint(expr)
    except (TypeError, ValueError) as error:  # e.g. a dict whose keys SymPy cannot order
        raise LatexOptionError(f"latex: {shown_value(expr)} cannot be printed: {error}") from None


def _latex_value(expr, depth: int = 0) -> bool:
    """Whether ``expr`` is something :func:`latex` prints as mathematics."""
    if isinstance(expr, (sp.Basic, sp.MatrixBase, int, float, complex)) \
            or hasattr(expr, "_latex"):
        return True
    if depth > 20:
        return False
    if isinstance(expr, dict):
        return all(_latex_value(k, depth + 1) and _latex_value(v, depth + 1)
                   for k, v in expr.items())
    if isinstance(expr, (list, tuple, set, frozenset)):
        return all(_latex_value(e, depth + 1) for e in expr)
    return False


def equation_lines(step) -> list[str]:
    """One ``0 &= …`` line per residual (the matrix form when available), unbroken: the
    plain printing of :attr:`StepEquations.structured` or :attr:`StepEquations.residuals`."""
    forms = step.structured if step.structured is not None else step.residuals
    return [f"0 &= {latex(r)}" for r in forms]


def step_latex(step, document: bool = False, abbreviations=None,
               width: float | None = None) -> str:
    """An ``align`` environment of the step equations, or a standalone document.

    The equations are printed in their most readable verified form (:mod:`._printing`):
    named pieces and ``abbreviations`` where they shorten it, terms collected by
    multipliers and parameters, rows broken to a page of text width ``width`` pt (default
    450), and a "where" list of what was named; a document (:func:`latex_document`) sets a
    line too wide to break smaller.
    """
    from ._layout import NAME_THE_PARTS
    from ._printing import printed_step

    document = flag_argument(document, "document", owner=step.name)
    rows = printed_step(step, abbreviations=abbreviations, width=width)
    return rows_latex(rows, document,
                      f"{step.name}: {len(step)} equations in {len(step.unknowns)} unknowns",
                      NAME_THE_PARTS)


def rows_latex(rows, document: bool, comment: str, remedy: str = "") -> str:
    """Printed rows (:class:`~._layout.PrintedRows`) as an ``align`` environment, or a
    standalone document (:func:`latex_document`, wide lines set smaller) with ``comment``
    (``remedy``: what the warning of lines that cannot fit advises beside a larger width)."""
    from ._layout import render_align

    body = render_align(rows, document=document, remedy=remedy)
    return latex_document(body, rows.width, comment) if document else body


#: A4's width in TeX points (210 mm) and the least side margin of a document (one inch)
A4_WIDTH, SIDE_MARGIN = 597.51, 72.27


def paper_option(width: float) -> str:
    """geometry's paper for a text ``width`` pt wide: A4 while the text leaves a margin of
    an inch on each side, else a page as tall as A4 and that much wider than the text (a
    wider text on A4 would run off the paper, equation numbers first)."""
    if width + 2 * SIDE_MARGIN <= A4_WIDTH:
        return "a4paper"
    return f"paperwidth={width + 2 * SIDE_MARGIN:.2f}pt,paperheight=297mm"


def latex_document(body: str, width: float, comment: str) -> str:
    """A standalone article around ``body`` whose text is ``width`` pt wide (the width the
    lines were broken to; the paper widened past A4 for a wide text, :func:`paper_option`),
    displays breaking across pages (``\\allowdisplaybreaks``); amsmath, amssymb, graphicx
    (lines set smaller) and geometry: all in TeX Live's ``texlive-latex-base``.  The
    ``comment`` is written as one TeX comment (its line breaks as spaces)."""
    comment = " ".join(str(comment).split())
    return ("\\documentclass[10pt]{article}\n"
            f"\\usepackage[{paper_option(width)},textwidth={width:g}pt,vmargin=2.5cm]"
            "{geometry}\n"
            "\\usepackage{amsmath,amssymb,graphicx}\n"
            "\\allowdisplaybreaks\n"
            "\\begin{document}\n"
            f"% {comment}\n"
            f"{body}\n\\end{{document}}\n")


def step_latex_aligned(step, abbreviations=None, width: float | None = None) -> str:
    """The same rows as :func:`step_latex` in an ``aligned`` block between ``$$`` (Jupyter)."""
    from ._layout import render_aligned
    from ._printing import printed_step

    rows = printed_step(step, abbreviations=abbreviations, width=width)
    return "$$" + render_aligned(rows) + "$$"
