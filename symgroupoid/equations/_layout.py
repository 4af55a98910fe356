"""Rows of printed equations, broken to a page width, as ``align`` or ``aligned``.

An equation ``lhs = t₁ ± t₂ ± …`` is printed term by term: terms are packed greedily onto
lines whose rendered width stays within the page width (default 450 pt); continuation
lines start at the alignment point with ``\\quad`` and the operator.  A term wider than a
line that is a :class:`~._latex.Collected` sum is split into several collected sums with the
same factor; any other term stays whole.

Widths are those of matplotlib's mathtext at 10 pt (DejaVu fonts), measured on the line as
it renders: with the widest left-hand side of the block in front (the alignment column) and
``=`` (continuation lines also ``\\quad``), so the bound holds for every line of the block.
Without matplotlib an estimate from the length of the LaTeX (2.5 pt per character) is used.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import sympy as sp

from ._latex import Collected, GroupoidLatexPrinter, LatexVerificationError

PAGE_WIDTH = 450.0  # pt
_FONT_SIZE = 10.0  # pt, matplotlib's default
_PT_PER_CHAR = 2.5  # mathtext width per LaTeX character, without matplotlib (lines of the
# seed systems render at 0.7–2.4 pt per character; single letters at up to 10)


@dataclass(frozen=True)
class Term:
    """One printed term ``sign · expr``; ``expr`` prints without a leading minus."""

    sign: int
    expr: sp.Expr

    def value(self) -> sp.Expr:
        from ._latex import uncollected

        return self.sign * uncollected(self.expr)


@dataclass
class Row:
    """A row ``lhs &= Σ terms``, broken into ``lines`` by :func:`lay_out` (``lines[0]`` after
    the alignment point, ``lines[1:]`` its continuation lines); ``numbered`` rows carry an
    equation number in ``align``."""

    lhs: str
    terms: list[Term]
    numbered: bool = True
    lines: list[str] = field(default_factory=list)


@dataclass
class Definitions:
    """"Where" definitions printed whole, ``(lhs, rhs)`` pairs packed ``a = x, \\quad b = y``
    as many to a line as the width allows (by :func:`lay_out`)."""

    pairs: list[tuple[str, str]]


@dataclass
class Text:
    """Words between rows (``\\intertext``), with inline math: "where, for $j = k, k+1$,"."""

    words: str


@dataclass
class PrintedRows:
    """What a whole printed block holds: equation rows, then text and definition rows, the
    page width in pt and the printer of the terms."""

    items: list  # Row | Definitions | Text
    width: float = 450.0
    printer: GroupoidLatexPrinter = field(default_factory=GroupoidLatexPrinter)


@functools.lru_cache(maxsize=1)
def _parser():
    try:
        from matplotlib.font_manager import FontProperties
        from matplotlib.mathtext import MathTextParser
    except ImportError:  # pragma: no cover - matplotlib is optional
        return None
    return MathTextParser("path"), FontProperties(family="DejaVu Sans", size=_FONT_SIZE,
                                                  math_fontfamily="dejavusans")


_OVERSAMPLE = 8  # measure at 8 × 72 dpi: widths to 1/8 pt


@functools.lru_cache(maxsize=8192)
def formula_width(tex: str) -> float:
    """Rendered width in pt of the math formula ``tex`` (mathtext, 10 pt), or the estimate
    ``2.5 pt × len(tex)`` when matplotlib is unavailable or cannot parse it (above what
    whole lines render at; not a bound for very short formulas)."""
    parser = _parser()
    if parser is not None:
        mathtext, prop = parser
        try:
            width = mathtext.parse(f"${tex}$", dpi=72 * _OVERSAMPLE, prop=prop)[0]
            return float(width) / _OVERSAMPLE
        except ValueError:
            pass
    return _PT_PER_CHAR * len(tex)


def _join(texts: list[str]) -> str:
    return " ".join(texts)


def _prefix(column: str, continuation: bool) -> str:
    return f"{column} = \\quad" if continuation else f"{column} ="


def _line_width(column: str, texts: list[str], continuation: bool) -> float:
    """The exact rendered width of a line (measured whole, the widest left-hand side of the
    block in front: the alignment column)."""
    return formula_width(f"{_prefix(column, continuation)} {_join(texts)}")


@functools.lru_cache(maxsize=1)
def _metrics() -> dict:
    """Widths of the layout elements the model composes, measured once."""
    w = formula_width
    return {
        "op": w("a + b") - w("a") - w("b"),
        "unary": w("-a") - w("a"),
        "frac_scale": (w("\\frac{aaaaaaaa}{b}") - w("\\frac{a}{b}")) / (w("aaaaaaaa") - w("a")),
        "parens": max(w("\\left(a\\right)") - w("a"),
                      w("\\left(\\frac{a}{b}\\right)") - w("\\frac{a}{b}")),
        "script": max((w("a^{bbbb}") - w("a")) / w("bbbb"), 0.75),
    }


def _fraction(numerator: float, denominator: float) -> float:
    """Width of \\frac{n}{d}: the wider part at the fraction's (smaller) size, plus padding."""
    m = _metrics()
    pad = formula_width("\\frac{a}{b}") - m["frac_scale"] * formula_width("a")
    return m["frac_scale"] * max(numerator, denominator) + pad


_MARGIN = 1.02  # the model's estimates are scaled up by this factor


class WidthModel:
    """Rendered widths of expressions as the printer prints them, composed from measured
    atoms: a sum is its terms plus operators, a product its factors (a fraction the wider of
    numerator and denominator, at the fraction's size), a power its base and a scaled
    exponent; atoms (symbols, matrix entries, functions, traces) are measured with mathtext
    once each.  Estimates for packing lines (within about 2 % on the seed systems); lines near
    the limit are measured whole."""

    def __init__(self, printer: GroupoidLatexPrinter):
        self.printer = printer
        self.memo: dict = {}

    def term(self, term: Term, first: bool) -> float:
        """Width a term adds to a line, its operator included."""
        m = _metrics()
        sign = (m["unary"] if term.sign < 0 else 0.0) if first else m["op"]
        return sign + self.width(term.expr)

    def width(self, expr: sp.Expr) -> float:
        if expr not in self.memo:
            self.memo[expr] = self._width(expr)
        return self.memo[expr]

    def _width(self, expr: sp.Expr) -> float:
        m = _metrics()
        if isinstance(expr, Collected):
            numerator, denominator = sp.fraction(expr.factor)
            if numerator == 1 and denominator != 1:
                return _fraction(self.width(expr.total), self.width(denominator))
            factor = 0.0 if expr.factor == 1 else self.width(expr.factor)
            return factor + self.width(expr.total) + m["parens"]
        if isinstance(expr, sp.Add):
            terms = [_signed(t) for t in expr.args]
            return self.term(terms[0], True) + sum(self.term(t, False) for t in terms[1:])
        if isinstance(expr, sp.Mul):
            return self._product(expr)
        if isinstance(expr, sp.Pow) and expr.exp.is_positive:
            base = self.width(expr.base) + (m["parens"] if expr.base.is_Add else 0.0)
            return base + m["script"] * self.width(expr.exp)
        return formula_width(self.printer.doprint(expr))  # an atom: measured, cached

    def _product(self, expr: sp.Mul) -> float:
        m = _metrics()
        coeff, rest = expr.as_coeff_Mul()
        if coeff.is_negative:
            return m["unary"] + self.width(-expr)
        numerator, denominator = sp.fraction(expr, exact=True)
        if denominator != 1:
            return _fraction(self.width(numerator), self.width(denominator))
        total = 0.0
        for factor in expr.args:
            total += self.width(factor) + (m["parens"] if factor.is_Add else 0.0)
        return _MARGIN * total


def term_text(term: Term, first: bool, printer: GroupoidLatexPrinter) -> str:
    """``+ t`` / ``- t`` (no ``+`` on the first term of an equation)."""
    body = printer.doprint(term.expr)
    if term.sign < 0:
        return f"- {body}"
    return body if first else f"+ {body}"


def signed_terms(expr: sp.Expr, printer: GroupoidLatexPrinter) -> list[Term]:
    """The top-level terms of ``expr`` in the printer's order, each with its sign apart."""
    if expr == 0:
        return [Term(1, sp.S.Zero)]
    terms = printer._as_ordered_terms(expr) if isinstance(expr, sp.Add) else [expr]
    return [_signed(t) for t in terms]


def _signed(term: sp.Expr) -> Term:
    coeff, rest = term.as_coeff_Mul()
    if coeff.is_negative:
        return Term(-1, -term)
    return Term(1, term)


def _split(term: Term, room: float, model: WidthModel) -> list[Term]:
    """A collected term too wide for a line, as several collected terms whose estimated
    widths fit in ``room`` pt (an inner term that alone is too wide becomes a product
    term)."""
    factor, inner = term.expr.factor, signed_terms(term.expr.total, model.printer)
    frame = model.term(Term(term.sign, Collected(factor, sp.Symbol("x"))), False) - \
        formula_width("x")
    pieces: list[Term] = []
    chunk: list[Term] = []
    used = 0.0

    def close():
        if len(chunk) == 1:
            pieces.append(_product(term.sign * chunk[0].sign, factor, chunk[0].expr))
        elif chunk:
            total = sp.Add(*[t.sign * t.expr for t in chunk])
            pieces.append(Term(term.sign, Collected(factor, total)))
        chunk.clear()

    for t in inner:
        w = model.term(t, not chunk)
        if chunk and frame + used + w > room:
            close()
            used = 0.0
            w = model.term(t, True)
        if not chunk and frame + w > room:
            pieces.append(_product(term.sign * t.sign, factor, t.expr))
            continue
        chunk.append(t)
        used += w
    close()
    return pieces


def _product(sign: int, factor: sp.Expr, expr: sp.Expr) -> Term:
    """The term sign·factor·expr (a collected ``expr`` takes the factor into its own)."""
    if isinstance(expr, Collected):
        return Term(sign, Collected(factor * expr.factor, expr.total))
    return _signed(sign * factor * expr)


_CHECK = 0.97  # lines estimated above this fraction of the room are measured whole


def break_terms(lhs: str, terms: list[Term], width: float = PAGE_WIDTH,
                printer: GroupoidLatexPrinter | None = None,
                model: WidthModel | None = None, column: str | None = None) -> list[str]:
    """The right-hand side ``Σ terms`` as lines of at most ``width`` pt (rendered with
    ``column = `` in front: the widest left-hand side of the block, ``lhs`` by default);
    returns the LaTeX of each line.

    Lines are packed by the :class:`WidthModel`'s estimates; a line estimated above 97 % of
    the room is measured whole and gives back terms (or splits a collected sum) until it
    fits.  A single term wider than the page that cannot be split stays whole."""
    printer = printer or GroupoidLatexPrinter()
    model = model or WidthModel(printer)
    column = lhs if column is None else column
    pending = list(terms)
    lines: list[list[str]] = []
    laid: list[Term] = []  # the terms as laid out (collected sums may have been split)
    current: list[Term] = []

    def room(continuation: bool) -> float:
        return width - formula_width(_prefix(column, continuation))

    def texts(line: list[Term], continuation: bool) -> list[str]:
        return [term_text(t, i == 0 and not continuation, printer) for i, t in enumerate(line)]

    def estimate(line: list[Term], continuation: bool) -> float:
        return sum(model.term(t, i == 0 and not continuation) for i, t in enumerate(line))

    def excess(line: list[Term], continuation: bool) -> float:
        if estimate(line, continuation) <= _CHECK * room(continuation):
            return 0.0
        return _line_width(column, texts(line, continuation), continuation) - width

    def close() -> None:
        """Emit ``current``, giving back trailing terms while the whole line is too wide
        (a collected sum alone on a line and too wide is split instead)."""
        continuation = bool(lines)
        while len(current) > 1 and excess(current, continuation) > 0:
            pending.insert(0, current.pop())
        over = excess(current, continuation)
        if over > 0 and isinstance(current[0].expr, Collected):
            parts = _split(current[0], room(True) - over, model)
            if len(parts) > 1:
                pending[:0] = parts
                current.clear()
                return
        lines.append(texts(current, continuation))
        laid.extend(current)
        current.clear()

    while pending:
        term = pending.pop(0)
        continuation = bool(lines)
        if estimate(current + [term], continuation) <= room(continuation):
            current.append(term)
            continue
        if current:
            pending.insert(0, term)
            close()
            continue
        if isinstance(term.expr, Collected):
            parts = _split(term, room(True), model)
            if len(parts) > 1 or parts[0] != term:
                pending[:0] = parts
                continue
        current.append(term)
        close()
    if current:
        close()
    same_sum(laid, terms, f"the broken lines of {lhs} = …")
    return [_join(line) for line in lines]


def same_sum(laid: list[Term], terms: list[Term], what: str) -> None:
    """Raise :class:`~._latex.LatexVerificationError` unless Σ laid = Σ terms exactly (the
    same terms, or the same sum expanded)."""
    if laid == list(terms):
        return
    difference = sp.expand(sp.Add(*[t.value() for t in laid])
                           - sp.Add(*[t.value() for t in terms]))
    if difference != 0:
        raise LatexVerificationError(f"{what}: the printed terms differ from the equation by "
                                     f"{difference}")


def lay_out(rows: PrintedRows) -> list:
    """The items with every :class:`Row` broken to the page width and the
    :class:`Definitions` packed into rows, all measured against the widest left-hand side
    of the block (where ``align`` puts the alignment point)."""
    heads = [item.lhs for item in rows.items if isinstance(item, Row)]
    heads += [lhs for item in rows.items if isinstance(item, Definitions)
              for lhs, _ in item.pairs]
    column = max(heads, key=formula_width, default="")
    model = WidthModel(rows.printer)
    out: list = []
    for item in rows.items:
        if isinstance(item, Row):
            lines = break_terms(item.lhs, item.terms, rows.width, rows.printer, model, column)
            out.append(Row(item.lhs, item.terms, item.numbered, lines))
        elif isinstance(item, Definitions):
            out += _packed_rows(item.pairs, rows.width, column)
        else:
            out.append(item)
    return out


def _packed(pairs: list[tuple[str, str]]) -> str:
    """``a = x, \\quad b = y``: the right-hand side of a packed row after its first ``a``."""
    (_, rhs), rest = pairs[0], pairs[1:]
    return ", \\quad ".join([rhs, *(f"{a} = {b}" for a, b in rest)])


def _packed_rows(pairs: list[tuple[str, str]], width: float, column: str) -> list[Row]:
    """Definitions several to a row while the row fits in ``width`` (estimated as the sum of
    its definitions' widths; measured whole above 97 % of the width)."""
    separator = formula_width("a, \\quad b") - 2 * formula_width("a")
    room = width - formula_width(column)  # the first definition's lhs sits in the column

    def fits(line: list[tuple[str, str]]) -> bool:
        estimate = sum(formula_width(f"{a} = {b}") for a, b in line) \
            + separator * (len(line) - 1) - formula_width(line[0][0])
        if estimate <= _CHECK * room:
            return True
        return _line_width(column, [_packed(line)], False) <= width

    rows: list[Row] = []
    line: list[tuple[str, str]] = []
    for pair in pairs:
        if line and not fits([*line, pair]):
            rows.append(Row(line[0][0], [], False, [_packed(line)]))
            line = []
        line.append(pair)
    if line:
        rows.append(Row(line[0][0], [], False, [_packed(line)]))
    return rows


def render_align(rows: PrintedRows) -> str:
    """An amsmath ``align`` environment: one numbered row per equation, continuation lines
    and "where" rows unnumbered (``\\notag``), words as ``\\intertext``."""
    out: list[str] = []
    intro = ""
    for item in lay_out(rows):
        if isinstance(item, Text):
            intro = f"\\intertext{{{item.words}}}\n"
            continue
        for i, line in enumerate(item.lines):
            last = i == len(item.lines) - 1
            head = f"{item.lhs} &= " if i == 0 else "&\\quad "
            tag = "" if (last and item.numbered) else " \\notag"
            out.append(f"{intro}{head}{line}{tag}")
            intro = ""
    return "\\begin{align}\n" + " \\\\\n".join(out) + "\n\\end{align}"


def render_aligned(rows: PrintedRows) -> str:
    """The same rows in an ``aligned`` block (no numbers; words as ``\\text``)."""
    out: list[str] = []
    for item in lay_out(rows):
        if isinstance(item, Text):
            out.append(f"&\\text{{{item.words}}}")
            continue
        for i, line in enumerate(item.lines):
            head = f"{item.lhs} &= " if i == 0 else "&\\quad "
            out.append(f"{head}{line}")
    return "\\begin{aligned}" + " \\\\ ".join(out) + "\\end{aligned}"
