"""User abbreviations of the printed equations, and the errors of the printing's options.

``abbreviations={name: expression or callable of an arrow}`` names pieces of the printed
equations: an expression is recognised wherever it occurs (also inside sums with a common
factor, :func:`replace_occurrences`), a callable is evaluated, like the Lagrangian, on each
arrow of the window (in the named pieces, when the form has them) and named with the arrow's
index.  Every abbreviation becomes a "where" row, and a layer of what verification writes
out (:class:`~._forms.Form`).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import sympy as sp

from .._errors import SymgroupoidError
from .._symbols import StepSymbol, greek_spelled, latex_name, scalar_expression
from ..derivation import PieceRule, as_scalar, call_user, window
from ..groupoids import is_constant_matrix
from ._collect import replace_occurrences
from ._forms import Definition, Form, index_range
from ._latex import NamedConstant, latex
from ._pieces import (
    arrow_label,
    generic_arrow,
    half_label,
    indexed_name,
    pair_coordinates,
    piece_symbols,
)


class LatexOptionError(SymgroupoidError, ValueError):
    """An option of the LaTeX printing is invalid: a page width that is not a positive
    number of points, abbreviations that are not a mapping of names to expressions or
    callables, or an abbreviation name that is not a string or a SymPy Symbol."""


class UnusedAbbreviationWarning(UserWarning):
    """Abbreviations given to the printing that do not occur in the printed equations (their
    value is not a part of the printed form); ``names``: their LaTeX names."""

    def __init__(self, message: str, names: Sequence[str] = ()):
        super().__init__(message)
        self.names = list(names)



@dataclass(frozen=True)
class Abbreviation:
    """A user-named piece: its LaTeX name, the symbol it prints as (a :class:`NamedConstant`
    when its value is in the parameters only, so it is ordered with them), and its value:
    an expression, or a callable of an arrow evaluated on each arrow of the window."""

    tex: str
    symbol: sp.Symbol | None
    value: object


def abbreviations_of(abbreviations, step) -> list[Abbreviation]:
    """The checked ``abbreviations`` option: a mapping name → expression or callable; a name
    is a non-empty string (its LaTeX) or a SymPy Symbol, and prints unlike every symbol of
    the step; an expression is a SymPy expression in symbols (not a number, not a string)."""
    if abbreviations is None:
        return []
    if not isinstance(abbreviations, Mapping):
        raise LatexOptionError(f"latex: abbreviations must be a mapping name → expression or "
                               f"callable, got {type(abbreviations).__name__}")
    symbols = printed_symbols(step)
    constants = {rendered(t): what for t, what in constant_names(step).items()}
    taken = {rendered(t) for t in
             ({latex(s) for s in symbols} | _indexed_bases(step) | RESERVED_NAMES)}
    out = []
    for name, value in abbreviations.items():
        if isinstance(name, sp.Symbol):
            tex, symbol = latex(name), name
        elif isinstance(name, str) and name.strip():
            tex, symbol = _typeset_name(name), None
        else:
            raise LatexOptionError(f"latex: an abbreviation's name must be a non-empty string "
                                   f"(its LaTeX) or a SymPy Symbol, got {name!r}")
        shown = rendered(tex)
        if shown in constants:
            raise LatexOptionError(f"latex: the abbreviation {tex!r} prints like "
                                   f"{constants[shown]} of {step.name}'s printed equations; "
                                   f"choose another name")
        if shown in taken:
            raise LatexOptionError(f"latex: the abbreviation {tex!r} prints like a symbol of "
                                   f"{step.name}; choose another name")
        _check_name_shape(tex)
        _check_name_reading(tex)
        taken.add(shown)
        if not callable(value):
            value = _abbreviation_value(tex, value)
            _check_symbols(tex, value, symbols, step)
            if symbol is None and value.free_symbols <= set(step.parameters):
                symbol = NamedConstant(tex)
        out.append(Abbreviation(tex, symbol, value))
    return out


def constant_names(step) -> dict[str, str]:
    """The LaTeX of the constant matrices the step's matrix form keeps by name (the basis
    E_a of a Lie algebra, a user's J_d) and of the unit vectors e_i the "where" list writes
    a basis in, each with words saying what it is."""
    names: dict[str, str] = {}
    for e in step.structured or ():
        for c in sp.sympify(e).atoms(sp.MatrixSymbol):
            if is_constant_matrix(c):
                names[latex(c)] = f"the constant matrix {latex(c)}"
                names.update({f"e_{{{i + 1}}}": f"the unit vector e_{{{i + 1}}}"
                              for i in range(c.shape[0])})
    return names


#: operator names written with \operatorname that LaTeX also has as commands
_OPERATOR_COMMANDS = ("sin", "cos", "tan", "exp", "log", "ln", "det")


def rendered(tex: str) -> str:
    r"""``tex`` as it typesets, for comparing names: spaces, empty groups (``L_{}``,
    ``x^{}``, ``{}``) and braces around the whole name (``{L}``) dropped, an operator name
    written ``\operatorname{sin}`` as ``\sin``, ``\overline`` as ``\bar`` and a letter
    in a font of upright or italic letters (``\mathrm{h}``) as the letter."""
    out = re.sub(r"\s+", "", tex)
    for word in _OPERATOR_COMMANDS:
        out = out.replace(f"\\operatorname{{{word}}}", f"\\{word}")
    out = re.sub(r"\\(?:overline|widebar)\{", r"\\bar{", out)  # (they print alike)
    out = re.sub(r"\\(?:mathrm|mathit|text|textrm|textit)\{([A-Za-z])\}", r"\1", out)
    previous = None
    while previous != out:
        previous = out
        out = re.sub(r"[_^]?\{\}", "", out)
        if out.startswith("{") and out.endswith("}") and _balanced(out[1:-1]):
            out = out[1:-1]
    return out


def _balanced(tex: str) -> bool:
    depth = 0
    for ch in tex:
        depth += {"{": 1, "}": -1}.get(ch, 0)
        if depth < 0:
            return False
    return depth == 0


#: names the printed equations use for their own parts: the Lagrangian, the forces, the
#: arrows g_k, the step index k and the index j of the "for j = k, k+1" rows, the
#: difference quotients Δq, the multipliers λ, the functions SymPy prints as operators
RESERVED_NAMES = frozenset({"L", "L_{d}", "f", "f^{+}", "f^{-}", "g", "k", "j", r"\Delta",
                            r"\lambda", r"\sin", r"\cos", r"\tan",
                            r"\exp", r"\log", r"\ln", r"\operatorname{tr}", r"\mathrm{d}",
                            r"\partial"})
#: LaTeX that ends, breaks or restructures an ``align`` row rather than naming something
_STRUCTURE = ("\\\\", r"\left", r"\right", r"\begin", r"\end", r"\intertext", r"\tag",
              r"\label", r"\notag", r"\nonumber")


def _indexed_bases(step) -> set:
    """The names the step's indexed symbols carry before their step index: x for x_{k},
    u_{1} for (u_{1})_{k}.  A name printed bare beside x_{k−1}, x_k would read as a
    coordinate."""
    bases = set()
    for s in (*step.knowns, *step.unknowns, *step.fibre_unknowns):
        tex = latex(s)
        if tex.startswith("(") and ")_{" in tex:
            bases.add(tex[1:tex.rindex(")_{")])
        elif "_{" in tex:
            bases.add(tex[:tex.index("_{")])
    return bases


#: commands that do not name anything by themselves: operators and spacing, which act on
#: what stands beside them in the row (``\over`` makes the whole row a fraction)
_OPERATORS = frozenset({"over", "atop", "choose", "above", "sum", "prod", "int", "oint",
                        "not", "big", "Big", "bigg", "Bigg", "bigl", "bigr", "Bigl", "Bigr",
                        "phantom", "hphantom", "vphantom", "quad", "qquad", "displaystyle",
                        "textstyle", "scriptstyle", "limits", "nolimits", "mathop"})
#: commands that take an argument: a name may use them only with one (``\hat{m}``)
_TAKES_ARGUMENT = frozenset({"frac", "dfrac", "tfrac", "sqrt", "hat", "bar", "tilde", "vec",
                             "dot", "ddot", "check", "breve", "acute", "grave", "widehat",
                             "widetilde", "overline", "underline", "mathbb", "mathcal",
                             "mathrm", "mathbf", "mathit", "mathsf", "mathtt", "mathfrak",
                             "boldsymbol", "operatorname", "text", "textrm", "textit"})
_COMMAND = re.compile(r"\\([A-Za-z]+)\s*(\{)?")


#: the commands a name may use: Greek letters, accents, fonts and a few letter-like symbols
_GREEK = ("alpha beta gamma delta epsilon varepsilon zeta eta theta vartheta iota kappa "
          "varkappa lambda mu nu xi omicron pi varpi rho varrho sigma varsigma tau upsilon "
          "phi varphi chi psi omega Gamma Delta Theta Lambda Xi Pi Sigma Upsilon Phi Psi "
          "Omega").split()
_NAMING = frozenset({*_GREEK, *_TAKES_ARGUMENT, "ell", "hbar", "imath", "jmath", "aleph",
                     "prime", "star", "ast", "circ", "dagger"})
#: a subscript holding the step index k or the row index j as a token: x_{k}, θ_{1,k}
_STEP_INDEX = re.compile(r"_\{[^{}]*(?<![A-Za-z\\])[kj](?![A-Za-z])[^{}]*\}|_[kj](?![A-Za-z])")


def _check_name_reading(tex: str) -> None:
    r"""An abbreviation's name reads as itself: only the commands of :data:`_NAMING` (a
    command LaTeX does not know, ``\foo``, stops pdflatex; ``\input``, ``\def`` act), no
    control character (a newline prints nothing), no subscript with the step index
    (``\theta_{1,k}``, ``(\theta_{1})_{k+2}`` read as a value at a step) and no ∂ (the
    printed equations write L's partial derivatives with it): a :class:`LatexOptionError`."""
    odd = next((ch for ch in tex if ord(ch) < 32), None)
    unknown = next((m.group(1) for m in _COMMAND.finditer(tex) if m.group(1) not in _NAMING),
                   None)
    why = (f"holds the control character {odd!r}" if odd is not None else
           f"uses \\{unknown}, which is not a Greek letter, an accent or a font" if unknown
           else "has the step index k or j in a subscript, which reads as a value at a step"
           if _STEP_INDEX.search(rendered(tex)) else None)
    if why is not None:
        raise LatexOptionError(f"latex: the abbreviation's name {tex!r} {why}; give a name "
                               f"such as 'M', 'K_{{1}}' or r'\\hat{{\\Omega}}'")


def _check_name_shape(tex: str) -> None:
    """An abbreviation's name names something: it holds a letter, is not a number or an
    operator, does not end in ^ or _, and holds no LaTeX that restructures a row
    (:class:`LatexOptionError`); nor an operator (``\\over``, ``\\sum``, ``\\phantom``) or a
    command that takes an argument without one (``\\frac``, ``\\sqrt``, ``\\hat`` alone)."""
    letters = any(ch.isalpha() for ch in tex.replace("\\\\", ""))
    broken = tex.rstrip().endswith(("^", "_")) or any(c in tex for c in _STRUCTURE)
    if not letters or broken:
        why = "holds no letter" if not letters else "holds LaTeX that breaks a row"
        raise LatexOptionError(f"latex: the abbreviation's name {tex!r} {why}; give a name "
                               f"such as 'M', 'K_{{1}}' or r'\\Omega'")
    for m in _COMMAND.finditer(tex):
        word, argument = m.group(1), m.group(2)
        if word in _OPERATORS or (word in _TAKES_ARGUMENT and not argument):
            why = ("is an operator, which acts on what stands beside it in the row"
                   if word in _OPERATORS else "takes an argument and is given none")
            raise LatexOptionError(f"latex: the abbreviation's name {tex!r} uses \\{word}, "
                                   f"which {why}; give a name such as 'M', r'\\hat{{m}}' or "
                                   f"r'\\Omega'")


def printed_symbols(step) -> list:
    """The symbols the printing of ``step`` shows: its coordinates, multipliers, inputs and
    parameters, and the pieces q̄, Δq at every subscript it gives them (the window's k ± 1/2,
    the generic j − 1/2, none).  No name of the printing's own may print as one of them."""
    return [*step.knowns, *step.unknowns, *step.fibre_unknowns, *step.parameters,
            *printed_pieces(step)]


def printed_pieces(step) -> list:
    """The pieces q̄, Δq of the step's pair coordinates at every subscript the printing
    gives them (the window's k ± 1/2, the generic j − 1/2, none)."""
    labels = [None, half_label("j", 0)] + [half_label("k", o) for o in window(step.order)[0]]
    return [p for c in pair_coordinates(step.groupoid) for label in labels
            for p in piece_symbols(c, label)]


def _check_symbols(tex: str, value: sp.Expr, symbols: Sequence, step) -> None:
    """An abbreviation's value reads only the step's symbols and the printed pieces: what
    else it reads occurs nowhere in the equations (:class:`LatexOptionError`)."""
    foreign = sorted(value.free_symbols - set(symbols), key=str)
    if foreign:
        raise LatexOptionError(f"latex: the abbreviation {tex!r} reads "
                               f"{', '.join(map(str, foreign))}, not a symbol of {step.name} "
                               f"(its coordinates, multipliers, inputs and parameters, or the "
                               f"printed pieces)")


#: characters an abbreviation's LaTeX may not hold: they end or break the formula
_UNSAFE = set("#$%&")


def _typeset_name(name: str) -> str:
    """An abbreviation's LaTeX as a document typesets it: a Greek character as its command
    (``Ω`` → ``\\Omega``: pdflatex stops at the character in mathematics, lualatex drops
    it); refused (:class:`LatexOptionError`) when it holds another character outside ASCII,
    one of ``# $ % &`` or unbalanced braces, which no document compiles."""
    tex = ""
    if len(name) > 1 and greek_spelled(name[0]) != name[0] and name[1:].isdigit():
        name = latex_name(name)  # a letter and its number, as the coordinates' (θ1: \theta_{1})
    for i, ch in enumerate(name):
        spelled = greek_spelled(ch)
        command = spelled != ch
        after = name[i + 1:i + 2]
        tex += ("\\" + spelled + (" " if after.isalpha() else "")) if command else ch
    bad = sorted({ch for ch in tex if ord(ch) > 127 or ch in _UNSAFE})
    depth = 0
    for ch in tex:
        depth += {"{": 1, "}": -1}.get(ch, 0)
        if depth < 0:
            break
    if bad or depth:
        why = (f"holds {', '.join(repr(c) for c in bad)}" if bad else "has unbalanced braces")
        raise LatexOptionError(f"latex: the abbreviation's name {name!r} {why}, which no "
                               f"LaTeX document compiles; give its LaTeX in ASCII (e.g. "
                               f"r'\\Omega', 'M_{{1}}')")
    return tex


def _abbreviation_value(tex: str, value) -> sp.Expr:
    expr = scalar_expression(value)
    if expr is None or not expr.free_symbols:
        number = (f" (a number, {value}, is printed as itself: an abbreviation names "
                  f"something the equations compute)" if expr is not None else "")
        raise LatexOptionError(f"latex: the abbreviation {tex!r} must stand for a SymPy "
                               f"expression in the step's symbols, or a callable of an arrow; "
                               f"got {value!r}{number}")
    return expr


def abbreviate(form: Form, step, abbreviations: Sequence[Abbreviation],
               rule: PieceRule | None) -> Form:
    """``form`` with each abbreviation recognised in the equations and the "where" rows.

    ``name → expression``: the expression (in the step's symbols or the printed pieces) is
    replaced by the name wherever it occurs, also inside sums with a common factor.
    ``name → callable``: the callable is evaluated, like the Lagrangian, on each arrow of the
    window (written in the pieces) and named with the arrow's index.
    """
    layer: dict = {}
    definitions: list[Definition] = []
    equations = list(form.equations)
    generic = dict(form.generic)
    arrow: dict = {}  # the generic arrow's coordinates → the first window arrow's (once)
    rows = list(form.definitions)
    for a in abbreviations:
        if callable(a.value):
            pairs, (g_symbol, g_value) = _per_arrow(step, a.tex, a.value, rule, form.unindexed)
            definitions.append(Definition(g_symbol, g_value, frozenset(p for p, _ in pairs),
                                          abbreviation=a.tex))
            generic[g_symbol] = pairs[0][0]
            arrow = arrow or _generic_arrow(step, rule, form.unindexed)
            for at_j, at_k in arrow.items():
                generic.setdefault(at_j, at_k)
        else:
            symbol = a.symbol if a.symbol is not None else StepSymbol(a.tex)
            g_symbol, g_value = symbol, a.value
            pairs = [(symbol, g_value)]
            definitions.append(Definition(symbol, g_value, frozenset([symbol]),
                                          abbreviation=a.tex))
        for s, v in pairs:
            layer[s] = v
            equations = [replace_occurrences(e, v, s) for e in equations]
        rows = [d if d.literal else dataclasses.replace(
            d, rhs=replace_occurrences(d.rhs, g_value, g_symbol)) for d in rows]
    # the rows defining the equations' names, then the abbreviations they use, then the rest
    ordered = ([d for d in rows if not d.literal] + definitions
               + [d for d in rows if d.literal])
    intros = list(form.intros)
    if intros[:1] == ["where"] and any(callable(a.value) for a in abbreviations):
        intros[0] = f"where, for {index_range(window(step.order)[0])},"  # rows at j
    return Form(equations, [layer, *form.layers], ordered, intros, generic, form.unindexed)


def _arrow_in_pieces(step, offset: int, index: str, rule: PieceRule | None,
                     unindexed: bool = False) -> tuple:
    """The coordinates of g_{index+offset} with its pair coordinates written in the pieces
    (``unindexed``: in the pieces without index)."""
    G = step.groupoid
    coords = list(G.named_arrow(offset)) if index == "k" else list(generic_arrow(G))
    if rule is None:
        return tuple(coords)
    for c in pair_coordinates(G):
        mid, diff = piece_symbols(c, None if unindexed else half_label(index, offset))
        coords[c.source], coords[c.target] = rule.coordinates(coords[c.source],
                                                              coords[c.target], mid, diff)
    return tuple(coords)


def _generic_arrow(step, rule: PieceRule | None, unindexed: bool = False) -> dict:
    """The coordinates (and pieces) of the generic arrow g_j, at which a callable's "where"
    row is written, → the same at the window's first arrow, whose name the row's symbol
    stands for at k (so that the row is checked at k: :func:`~._rows.checked_form`)."""
    first = window(step.order)[0][0]
    at_j = _arrow_in_pieces(step, 0, "j", rule, unindexed)
    at_k = _arrow_in_pieces(step, first, "k", rule)
    out = {a: b for a, b in zip(at_j, at_k) if isinstance(a, sp.Symbol) and a != b}
    if rule is not None:
        for c in pair_coordinates(step.groupoid):
            label = None if unindexed else half_label("j", 0)
            out.update(zip(piece_symbols(c, label), piece_symbols(c, half_label("k", first))))
    return out


def _per_arrow(step, tex: str, fn: Callable, rule: PieceRule | None, unindexed: bool = False):
    """(symbol, value) at each window arrow, and the generic (symbol, value) at g_j (with
    ``unindexed``, in the pieces without index, named without index)."""
    G = step.groupoid
    label = half_label if pair_coordinates(G) else arrow_label

    def at(index: str, offset: int):
        arrow = G.view(_arrow_in_pieces(step, offset, index, rule))
        value = as_scalar(step.name, f"abbreviation {tex}", call_user(
            step.name, f"abbreviation {tex}", fn, arrow))
        return StepSymbol(indexed_name(tex, label(index, offset))), value

    pairs = [at("k", o) for o in window(step.order)[0]]
    if unindexed:
        arrow = G.view(_arrow_in_pieces(step, 0, "j", rule, unindexed=True))
        value = as_scalar(step.name, f"abbreviation {tex}", call_user(
            step.name, f"abbreviation {tex}", fn, arrow))
        return pairs, (StepSymbol(tex), value)
    return pairs, at("j", 0)
