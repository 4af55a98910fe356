"""Rows of printed equations, broken to a page width, as ``align`` or ``aligned``.

An equation ``lhs = t₁ ± t₂ ± …`` is printed term by term: terms are packed greedily onto
lines whose width, as TeX sets them in a display, stays within the room a page of text
width ``width`` (default :data:`PAGE_WIDTH`, the text width of the documents) leaves them;
continuation lines start at the alignment point with ``\\quad`` and the operator.  A term
wider than a line that is a :class:`~._latex.Collected` sum is split into several collected
sums with the same factor; any other term stays whole (a standalone document sets such a
line smaller, :func:`render_align`).

The room: ``align`` centres its block of lines and needs, for an equation number on the same
line, the number and :data:`TAG_SEPARATION` free on both sides of the block; so each line gets
``width − 2 (number + separation)`` (numbers up to two digits), divided by
:data:`TEX_PER_MATHTEXT`.

Widths are those of matplotlib's mathtext at 10 pt (DejaVu fonts), measured on the line as
a display sets it (:class:`~._latex.DisplayLatexPrinter`: fractions at display size): with
the widest left-hand side of the block in front (the alignment column) and ``=``
(continuation lines also ``\\quad``), so the bound holds for every line of the block.
Without matplotlib an estimate from the length of the LaTeX (2.5 pt per character) is used.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import sympy as sp

from .._arguments import caller_level
from .._rational import expanded_vanishes
from ._latex import (
    Collected,
    DisplayLatexPrinter,
    GroupoidLatexPrinter,
    LatexVerificationError,
    MemoLatexPrinter,
)

#: pt: the text width of the standalone documents (their geometry), and the default width
PAGE_WIDTH = 450.0
#: pt: the least space amsmath leaves between an equation and its number (0.5 em at 10 pt)
TAG_SEPARATION = 5.0
#: TeX's width of a display line (Computer Modern, 10 pt) per mathtext's (DejaVu Sans,
#: fractions at display size): 0.94–1.032 on the lines of the seed systems and of a
#: satellite with a reaction wheel (pdflatex's box widths)
TEX_PER_MATHTEXT = 1.04
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
    """"Where" definitions printed whole, ``(lhs, rhs, as_written)`` pairs of expressions
    packed ``a = x, \\quad b = y`` as many to a line as the width allows (by
    :func:`lay_out`); ``as_written``: the right-hand side's terms in the order given;
    ``packed`` False: one definition to a row (long ones, whose measured widths run short of
    TeX's)."""

    pairs: list[tuple]
    packed: bool = True


@dataclass
class Text:
    """Words between rows (``\\intertext``), with inline math: "where, for $j = k, k+1$,"."""

    words: str


@dataclass
class PrintedRows:
    """What a whole printed block holds: equation rows, then text and definition rows, the
    page's text width in pt and the printer of the terms."""

    items: list  # Row | Definitions | Text
    width: float = PAGE_WIDTH
    printer: GroupoidLatexPrinter = field(default_factory=MemoLatexPrinter)


@dataclass
class Line:
    """A laid-out line: its LaTeX, and its measured width in pt when it is wider than its
    room (a single term that cannot be split; None otherwise) with that room."""

    tex: str
    over: float | None = None
    room: float | None = None


def display_twin(printer: GroupoidLatexPrinter, **settings) -> DisplayLatexPrinter:
    """A :class:`~._latex.DisplayLatexPrinter` with ``printer``'s settings (to measure what
    ``printer`` prints)."""
    given = {k: v for k, v in printer._settings.items() if k in printer._default_settings}
    return DisplayLatexPrinter({**given, **settings})


def number_room(numbered: bool) -> float:
    """pt an ``align`` needs beside its centred block for equation numbers of up to two
    digits: the number and :data:`TAG_SEPARATION`, on both sides."""
    if not numbered:
        return 0.0
    return 2 * (formula_width("(99)") + TAG_SEPARATION)


def line_room(width: float, numbered: bool) -> float:
    """The mathtext width a line may have on a page of text width ``width``."""
    return (width - number_room(numbered)) / TEX_PER_MATHTEXT


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
        "frac_scale": (w("\\dfrac{aaaaaaaa}{b}") - w("\\dfrac{a}{b}")) / (w("aaaaaaaa") - w("a")),
        "parens": max(w("\\left(a\\right)") - w("a"),
                      w("\\left(\\dfrac{a}{b}\\right)") - w("\\dfrac{a}{b}")),
        "script": max((w("a^{bbbb}") - w("a")) / w("bbbb"), 0.75),
    }


def _fraction(numerator: float, denominator: float) -> float:
    """Width of a display fraction n/d: the wider part, plus padding."""
    m = _metrics()
    pad = formula_width("\\dfrac{a}{b}") - m["frac_scale"] * formula_width("a")
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
        elif chunk:  # its sum printed with a leading plus: − f (a − b), not + f (−a + b)
            total, sign = sp.Add(*[t.sign * t.expr for t in chunk]), term.sign
            if signed_terms(total, model.printer)[0].sign < 0:
                total, sign = -total, -sign
            pieces.append(Term(sign, Collected(factor, total)))
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
                model: WidthModel | None = None, column: str | None = None) -> list[Line]:
    """The right-hand side ``Σ terms`` as lines of at most ``width`` pt of mathtext (rendered
    with ``column = `` in front: the widest left-hand side of the block, ``lhs`` by
    default, and measured as the ``model``'s printer prints them: as a display).

    Lines are packed by the :class:`WidthModel`'s estimates; a line estimated above 97 % of
    the room is measured whole and gives back terms (or splits a collected sum) until it
    fits.  A single term wider than the page that cannot be split stays whole (its
    :class:`Line` says how wide it is)."""
    printer = printer or MemoLatexPrinter()
    model = model or WidthModel(display_twin(printer))
    column = lhs if column is None else column
    pending = list(terms)
    lines: list[Line] = []
    laid: list[Term] = []  # the terms as laid out (collected sums may have been split)
    current: list[Term] = []

    def room(continuation: bool) -> float:
        return width - formula_width(_prefix(column, continuation))

    def texts(line: list[Term], continuation: bool, how: GroupoidLatexPrinter) -> list[str]:
        return [term_text(t, i == 0 and not continuation, how) for i, t in enumerate(line)]

    def estimate(line: list[Term], continuation: bool) -> float:
        return sum(model.term(t, i == 0 and not continuation) for i, t in enumerate(line))

    def excess(line: list[Term], continuation: bool) -> float:
        if estimate(line, continuation) <= _CHECK * room(continuation):
            return 0.0
        return _line_width(column, texts(line, continuation, model.printer),
                           continuation) - width

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
        lines.append(Line(_join(texts(current, continuation, printer)),
                          width + over if over > 0 else None, width if over > 0 else None))
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
    return lines


def same_sum(laid: list[Term], terms: list[Term], what: str) -> None:
    """Raise :class:`~._latex.LatexVerificationError` unless Σ laid = Σ terms exactly (the
    same terms, or the same sum: :func:`~symgroupoid._rational.expanded_vanishes`)."""
    if laid == list(terms):
        return
    difference = sp.expand(sp.Add(*[t.value() for t in laid])
                           - sp.Add(*[t.value() for t in terms]))
    if not expanded_vanishes(difference):
        raise LatexVerificationError(f"{what}: the printed terms differ from the equation by "
                                     f"{difference}")


def lay_out(rows: PrintedRows, numbered: bool = True) -> list:
    """The items with every :class:`Row` broken to the room a page of text width
    ``rows.width`` leaves a line (:func:`line_room`; ``numbered``: beside equation numbers)
    and the :class:`Definitions` packed into rows, all measured against the widest
    left-hand side of the block (where ``align`` puts the alignment point)."""
    measure = display_twin(rows.printer)
    literal, literal_measure = (GroupoidLatexPrinter({"order": "none"}),
                                DisplayLatexPrinter({"order": "none"}))

    def pair_texts(how, as_written_how) -> list[list[tuple[str, str]]]:
        return [[((as_written_how if w else how).doprint(a), (as_written_how if w else how)
                  .doprint(b)) for a, b, w in item.pairs]
                for item in rows.items if isinstance(item, Definitions)]

    shown, measured = pair_texts(rows.printer, literal), pair_texts(measure, literal_measure)
    heads = [item.lhs for item in rows.items if isinstance(item, Row)]
    heads += [lhs for pairs in measured for lhs, _ in pairs]
    column = max(heads, key=formula_width, default="")
    width = line_room(rows.width, numbered and any(
        isinstance(item, Row) and item.numbered for item in rows.items))
    model = WidthModel(measure)
    out: list = []
    definitions = iter(zip(shown, measured))
    for item in rows.items:
        if isinstance(item, Row):
            lines = break_terms(item.lhs, item.terms, width, rows.printer, model, column)
            out.append(Row(item.lhs, item.terms, item.numbered, lines))
        elif isinstance(item, Definitions):
            texts = next(definitions)
            out += _packed_rows(*texts, width, column) if item.packed else [
                row for pair in zip(*texts)
                for row in _packed_rows([pair[0]], [pair[1]], width, column)]
        else:
            out.append(item)
    return out


def _packed(pairs: list[tuple[str, str]]) -> str:
    """``a = x, \\quad b = y``: the right-hand side of a packed row after its first ``a``."""
    (_, rhs), rest = pairs[0], pairs[1:]
    return ", \\quad ".join([rhs, *(f"{a} = {b}" for a, b in rest)])


def _packed_rows(shown: list[tuple[str, str]], measured: list[tuple[str, str]], width: float,
                 column: str) -> list[Row]:
    """Definitions several to a row while the row fits in ``width`` (estimated as the sum of
    its definitions' widths, as ``measured`` prints them; measured whole above 97 % of the
    width)."""
    separator = formula_width("a, \\quad b") - 2 * formula_width("a")
    room = width - formula_width(column)  # the first definition's lhs sits in the column

    def fits(line: list[int]) -> bool:
        pairs = [measured[i] for i in line]
        estimate = sum(formula_width(f"{a} = {b}") for a, b in pairs) \
            + separator * (len(pairs) - 1) - formula_width(pairs[0][0])
        if estimate <= _CHECK * room:
            return True
        return _line_width(column, [_packed(pairs)], False) <= width

    rows: list[Row] = []
    line: list[int] = []

    def close() -> None:
        pairs = [shown[i] for i in line]
        over = _line_width(column, [_packed([measured[i] for i in line])], False)
        rows.append(Row(pairs[0][0], [], False, [Line(_packed(pairs), over, width)
                                                 if over > width else Line(_packed(pairs))]))

    for i in range(len(shown)):
        if line and not fits([*line, i]):
            close()
            line = []
        line.append(i)
    if line:
        close()
    return rows


#: the least factor a line too wide for its room is set at in a document (below it, the
#: line stays at this size and runs into the margin: a term this wide needs a narrower
#: form, e.g. an abbreviation)
SMALLEST_SCALE = 0.5


def _scaled(line: Line, document: bool) -> str:
    """A line as printed: in a document, a line wider than its room (a term that cannot be
    broken) is set smaller to fit (``\\scalebox``, graphicx)."""
    if not document or line.over is None:
        return line.tex
    factor = max(SMALLEST_SCALE, int(100 * line.room / line.over) / 100)
    return f"\\scalebox{{{factor:.2f}}}{{$\\displaystyle {line.tex}$}}"


class WideLinesWarning(UserWarning):
    """Lines of a document that no break and no scaling makes fit (a single term wider than
    twice the room of a line, the smallest scaling): typeset, they run off the page.
    ``widths``: theirs in pt; ``room``: the widest one's room."""

    def __init__(self, message: str, widths: list[float], room: float):
        super().__init__(message)
        self.widths, self.room = widths, room


#: what a wide line's warning advises, for a printing that takes abbreviations (a step's)
NAME_THE_PARTS = " or abbreviations= that name their long parts"


def _warn_wide(lines: list[Line], remedy: str = "") -> None:
    """A :class:`WideLinesWarning` for the lines of a document that will not fit even at
    :data:`SMALLEST_SCALE` (none: nothing); ``remedy`` follows the advice of a larger
    width (:data:`NAME_THE_PARTS` where the printing takes abbreviations)."""
    wide = [line for line in lines
            if line.over is not None and SMALLEST_SCALE * line.over > line.room + 1.0]
    if not wide:
        return
    import warnings

    widest = max(wide, key=lambda line: line.over)
    warnings.warn(WideLinesWarning(
        f"{len(wide)} printed line{'s' if len(wide) > 1 else ''} will not fit the page even "
        f"at half size (the widest {widest.over:.0f} pt where a line has {widest.room:.0f} "
        f"pt) and would run off it: give a larger width= (a landscape page){remedy}",
        [line.over for line in wide], widest.room), stacklevel=caller_level())


def render_align(rows: PrintedRows, document: bool = False, remedy: str = "") -> str:
    """An amsmath ``align`` environment: one numbered row per equation, continuation lines
    and "where" rows unnumbered (``\\notag``), words as ``\\intertext``; in a
    ``document``, lines too wide for the page are set smaller (:func:`_scaled`), and those
    that will not fit even so are reported with a :class:`WideLinesWarning` (advising
    ``remedy`` too)."""
    out: list[str] = []
    intro = ""
    laid = lay_out(rows)
    if document:
        _warn_wide([line for item in laid if not isinstance(item, Text) for line in item.lines],
                   remedy)
    for item in laid:
        if isinstance(item, Text):
            intro = f"\\intertext{{{item.words}}}\n"
            continue
        for i, line in enumerate(item.lines):
            last = i == len(item.lines) - 1
            head = f"{item.lhs} &= " if i == 0 else "&\\quad "
            tag = "" if (last and item.numbered) else " \\notag"
            out.append(f"{intro}{head}{_scaled(line, document)}{tag}")
            intro = ""
    return "\\begin{align}\n" + " \\\\\n".join(out) + "\n\\end{align}"


def render_aligned(rows: PrintedRows) -> str:
    """The same rows in an ``aligned`` block (no numbers; words as ``\\text``)."""
    out: list[str] = []
    for item in lay_out(rows, numbered=False):
        if isinstance(item, Text):
            out.append(f"&\\text{{{item.words}}}")
            continue
        for i, line in enumerate(item.lines):
            head = f"{item.lhs} &= " if i == 0 else "&\\quad "
            out.append(f"{head}{line.tex}")
    return "\\begin{aligned}" + " \\\\ ".join(out) + "\\end{aligned}"
