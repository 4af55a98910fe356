"""Symbols for coordinates at discrete steps, named in the papers' notation.

A :class:`StepSymbol` carries its LaTeX as its name: ``x_{k+1}``, ``(g_{k})_{12}``,
``(\\lambda_{k+1})_{1}``.  The LaTeX printer prints it verbatim.
"""

from __future__ import annotations

import re
import unicodedata
from collections.abc import Sequence

import sympy as sp

_LABEL = re.compile(r"^k(?:([+-])(\d+))?$")


class StepSymbol(sp.Symbol):
    """A real coordinate of a configuration, arrow or multiplier at a step ``k + offset``."""

    def __new__(cls, name: str, **assumptions):
        assumptions.setdefault("real", True)
        return super().__new__(cls, name, **assumptions)


def step_label(offset: int) -> str:
    """The paper's subscript for step ``k + offset``: ``k``, ``k+1``, ``k-1``."""
    if offset == 0:
        return "k"
    return f"k{offset:+d}"


def parse_step(step: str | int) -> int:
    """Inverse of :func:`step_label`; accepts ``"k+1"``, ``"k-2"``, ``"k"`` or an int offset."""
    if isinstance(step, int):
        return step
    m = _LABEL.match(step.replace(" ", ""))
    if m is None:
        raise ValueError(f"step must look like 'k', 'k+1' or 'k-1', got {step!r}")
    if m.group(1) is None:
        return 0
    value = int(m.group(2))
    return value if m.group(1) == "+" else -value


#: Unicode's spelling of a Greek letter -> the LaTeX command's
_GREEK_SPELLING = {"lamda": "lambda"}

#: letters outside the Greek block that mathematics writes as commands
_LETTER_SPELLING = {"\u2113": "ell", "\u0127": "hbar", "\u210f": "hbar"}

#: characters read as a Greek letter (the micro sign µ is μ to a reader)
_AS_GREEK = {"\u00b5": "\u03bc"}

#: combining accents over a letter, as SymPy's name modifiers spell them (ẋ: xdot → \dot{x})
_ACCENT_SPELLING = {"\u0307": "dot", "\u0308": "ddot", "\u0302": "hat", "\u0304": "bar",
                    "\u0303": "tilde", "\u0301": "acute", "\u0300": "grave",
                    "\u0306": "breve", "\u030c": "check", "\u20d7": "vec"}


def scalar_expressions(values: Sequence) -> tuple[tuple, int | None]:
    """(the :func:`scalar_expression` of each of ``values``, the index of the first that is
    none or None): one reading for the callers that name the failing entry their own way."""
    out = []
    for i, v in enumerate(values):
        e = scalar_expression(v)
        if e is None:
            return tuple(out), i
        out.append(e)
    return tuple(out), None


def scalar_expression(value) -> sp.Expr | None:
    """``value`` as a SymPy scalar expression (a number, a symbol, an expression), or None
    for anything else (a string, a container, a matrix, an object SymPy does not know):
    the one reading of "a number or expression" of every argument check."""
    if isinstance(value, (str, bytes)):
        return None
    try:
        expr = sp.sympify(value, strict=True)
    except (sp.SympifyError, TypeError, ValueError, AttributeError):
        return None
    return expr if isinstance(expr, sp.Expr) else None


def greek_spelled(name: str) -> str:
    """``name`` with every Greek letter spelt out as SymPy names it (``θ1`` → ``theta1``,
    ``Ω`` → ``Omega``, ``ϑ`` → ``vartheta``), so that it prints as ``\\theta_{1}``: LaTeX
    engines typeset the commands, not the characters (pdflatex stops at a Greek character in
    mathematics, lualatex drops its glyph); a subscript digit as an index (``θ₁`` →
    ``theta_1``, which prints as ``\\theta_{1}``); ``ℓ``, ``ħ`` and the micro sign ``µ`` as
    ``ell``, ``hbar`` and ``mu``; a letter with a combining accent as SymPy's modifier
    (``ẋ`` → ``xdot``, printed ``\\dot{x}``).  Other characters are kept
    (:func:`unspelled_character` finds those a LaTeX engine would not typeset)."""
    out = []
    for ch in _accents_spelled(name):
        ch = _AS_GREEK.get(ch, ch)
        if ch in _LETTER_SPELLING:
            out.append(("_" if out and out[-1][-1:].isalpha() else "") + _LETTER_SPELLING[ch])
            continue
        words = unicodedata.name(ch, "").split() if ord(ch) > 127 else []
        if words[:1] == ["SUBSCRIPT"] and unicodedata.digit(ch, None) is not None:
            # θ₁ as theta_1, θ₁₂ as theta_12
            digit = str(unicodedata.digit(ch))
            out.append(digit if out and out[-1][-1:].isdigit() and "_" in out[-1]
                       else "_" + digit)
            continue
        if words[:1] != ["GREEK"]:
            out.append(ch)
            continue
        base = words[words.index("SYMBOL") - 1] if "SYMBOL" in words else words[-1]
        letter = _GREEK_SPELLING.get(base.lower(), base.lower())
        if "SYMBOL" in words or "FINAL" in words:  # ϑ, ϕ, ϖ, ϱ, ϵ, ς: the variants
            letter = "var" + letter
        elif "CAPITAL" in words:
            letter = letter.capitalize()
        follows = len(out) and out[-1][-1:].isalpha()
        out.append(("_" if follows else "") + letter)
    return "".join(out)


def _accents_spelled(name: str) -> str:
    """``name`` with each letter that carries one combining accent of
    :data:`_ACCENT_SPELLING` written as the letter and the accent's modifier word, where the
    letter ends the name or a digit follows (SymPy reads a modifier at the end of a name's
    base: ``ẋ1`` → ``xdot1``, printed ``\\dot{x}_{1}``)."""
    decomposed = unicodedata.normalize("NFD", name)
    out, i = [], 0
    while i < len(decomposed):
        ch = decomposed[i]
        accent = decomposed[i + 1] if i + 1 < len(decomposed) else ""
        rest = decomposed[i + 2:]
        if ch.isascii() and ch.isalpha() and accent in _ACCENT_SPELLING \
                and (not rest or rest[0].isdigit() or rest[0] == "_"):
            out.append(ch + _ACCENT_SPELLING[accent])
            i += 2
            continue
        out.append(ch)
        i += 1
    return unicodedata.normalize("NFC", "".join(out))


def unspelled_character(name: str) -> str | None:
    """The first character of ``name`` that stays outside ASCII after
    :func:`greek_spelled` (a LaTeX engine would stop at it or drop its glyph), or None."""
    for ch in greek_spelled(name):
        if not ch.isascii():
            return ch
    return None


#: a superscript of digits or Latin letters (SymPy prints m__2 and m^2 as m^{2}, a__b as
#: a^{b}): read as a power
_POWER_SUPERSCRIPT = re.compile(r"\^(\{[0-9A-Za-z]+\}|[0-9A-Za-z])")


def reads_as_power(name: str) -> bool:
    """Whether ``name`` prints with a superscript of digits or Latin letters, as a power
    reads (``m__2``, ``m^2``: m^{2}, the square of m; ``a__b``: a^{b})."""
    return _POWER_SUPERSCRIPT.search(latex_name(name)) is not None


#: names SymPy prints as a word that the printed equations use as an operator
OPERATOR_WORDS = frozenset({"sin", "cos", "tan", "exp", "log", "ln", "tr", "det", "sqrt",
                            "diag", "Ad"})


def misread_name(name: str, words: bool = True) -> str | None:
    """How ``name``, printed, would read as something else ("prints as …"), or None: as an
    operator word (``tr`` beside the trace tr(W E_1), ``sin``; with ``words``: a scalar's
    name, not a group's, whose values print as matrices g_k), or with an empty subscript or
    superscript (``x_`` prints x_{}, which reads as x)."""
    if words and name in OPERATOR_WORDS:
        return (f"prints as the word {name}, which the printed equations use as an "
                f"operator ({name}(…))")
    printed = latex_name(name)
    if re.search(r"[_^]\{\}", printed):
        return (f"prints as {printed}, an empty subscript or superscript, which reads as "
                f"the name without it")
    return None


def latex_name(name: str) -> str:
    """LaTeX of a user-supplied coordinate name (``Gamma`` → ``\\Gamma``, ``θ`` →
    ``\\theta``)."""
    return sp.latex(sp.Symbol(greek_spelled(name)))


def aliased_names(names: Sequence[str]) -> tuple[str, str] | None:
    """The first two of ``names`` that would name one symbol — equal, or spelt apart but
    written alike (``θ``, ``theta`` and ``\\theta`` are all ``\\theta``: the step
    symbols are named by their LaTeX) — or None."""
    seen: dict[str, str] = {}
    for name in names:
        key = latex_name(name)
        if key in seen:
            return seen[key], name
        seen[key] = name
    return None


#: the multipliers' names in the state (λ in any spelling prints as they do)
MULTIPLIER_NAMES = ("lambda", "multipliers")

#: the LaTeX commands a name may hold besides Greek letters: accents and alphabets
_NAME_COMMANDS = frozenset({"bar", "hat", "tilde", "dot", "ddot", "vec", "check", "breve",
                            "mathrm", "mathbf", "mathcal", "mathit", "mathsf", "boldsymbol",
                            "prime", "ell"})

#: characters that LaTeX reads as commands or structure: a name holding one would break
#: the printed document (% comments out the rest of a row, & is a column of align)
_LATEX_SPECIAL = re.compile(r"[%&#$~]|\\(?![A-Za-z])")


def is_multiplier_name(name: str) -> bool:
    """Whether ``name`` is written as the multipliers' (λ, lambda, lamda, \\lambda,
    multipliers)."""
    return latex_name(name) in {latex_name(n) for n in MULTIPLIER_NAMES}


def is_difference_name(name: str) -> bool:
    """Whether ``name`` is written Δ, as the printed equations write the differences of the
    coordinates (Δq for q_{k+1} − q_k): ``Delta``, ``Δ``, ``\\Delta``."""
    return latex_name(name) == r"\Delta"


#: a name whose subscript reads as a step index: x_{k}, x_{k+1}, x_{j}
_STEP_INDEXED = re.compile(r"_\{?[kj]([+-]\d+)?\}?$")


def reads_as_step_value(tex: str) -> bool:
    """Whether a name printed ``tex`` reads as a value at a step (x_{k}, x_{k+1}, x_{j})."""
    return _STEP_INDEXED.search(tex) is not None


def unprintable_name(name: str, words: bool = True) -> str | None:
    """Why ``name`` cannot name a coordinate, a part or an input in the printed equations,
    or None: it must start with a letter (or be a LaTeX command such as ``\\theta``: a name
    starting with a digit or a sign reads as arithmetic, -1_{k}), hold no character LaTeX
    reads as structure (% & # $ ~, a lone backslash) and balanced braces, and not be written
    Δ (the differences' symbol)."""
    if not (name[:1].isalpha() or re.match(r"\\[A-Za-z]", name)):
        return "it must start with a letter (a digit or a sign would read as arithmetic)"
    if any(ch.isspace() for ch in name):
        return "it holds a space (a CSV header or a name=value list could not name it)"
    odd = unspelled_character(name)
    if odd is not None:
        return (f"it holds the character {odd!r} ({unicodedata.name(odd, 'unnamed')}), which "
                f"LaTeX does not typeset in mathematics (Greek letters, ℓ, ħ, µ and accented "
                f"letters such as ẋ are spelt as commands)")
    if reads_as_power(name):
        return (f"it prints as {latex_name(name)}, which reads as a power (a superscript of "
                f"digits or letters); write the index as a subscript (m_2)")
    if _LATEX_SPECIAL.search(name):
        return "it holds a character LaTeX reads as structure (% & # $ ~ or a lone backslash)"
    for command in re.findall(r"\\([A-Za-z]+)", name):
        if command not in _NAME_COMMANDS and sp.latex(sp.Symbol(command)) != "\\" + command:
            return (f"it holds the LaTeX command \\{command}, which is neither a Greek "
                    f"letter nor an accent")
    depth = 0
    for ch in name:
        depth += {"{": 1, "}": -1}.get(ch, 0)
        if depth < 0:
            break
    if depth != 0:
        return "its braces are not balanced"
    misread = misread_name(name, words)
    if misread is not None:
        return f"it {misread}"
    if reads_as_step_value(latex_name(name)):
        return (f"it is written {latex_name(name)}, as a value at a step is: its values would "
                f"print ({latex_name(name)})_{{k+1}}")
    if is_difference_name(name):
        return ("it is written \\Delta, as the printed equations write the differences of "
                "the coordinates (\\Delta q for q_{k+1} - q_k: a coordinate Δ would print "
                "as \\Delta \\Delta)")
    return None


def printable_name(name: str, what: str, owner: str, *, part: bool = True,
                   words: bool = True) -> str:
    """``name`` when it can name ``what`` in the printed equations and the state
    (:func:`unprintable_name`, ``words`` as there; with ``part``, not the multipliers' name
    either), else a :class:`~symgroupoid.CoordinateNameError` saying why."""
    from ._errors import CoordinateNameError

    why = unprintable_name(name, words)
    if why is None and part and is_multiplier_name(name):
        why = (f"it is written {latex_name(name)}, as the multipliers are (their state part "
               f"is {', '.join(map(repr, MULTIPLIER_NAMES))})")
    if why is not None:
        raise CoordinateNameError(f"{owner}: {what} {name!r} cannot be used: {why}; choose "
                                  f"another name")
    return name


def alias_words(pair: tuple[str, str]) -> str:
    """How two names of :func:`aliased_names` clash: "repeated" or "both written ..."."""
    a, b = pair
    return f"{a!r} is repeated" if a == b else \
        f"{a!r} and {b!r} are both written {latex_name(a)}, one symbol"


def subscripted(base_latex: str, offset: int) -> str:
    """``base`` with the step subscript, parenthesised when ``base`` already has one."""
    label = step_label(offset)
    if "_" in base_latex or "^" in base_latex:
        return f"({base_latex})_{{{label}}}"
    return f"{base_latex}_{{{label}}}"


def scalar_symbol(base_latex: str, offset: int) -> StepSymbol:
    """The coordinate ``base`` at step ``k + offset``."""
    return StepSymbol(subscripted(base_latex, offset))


def indexed_symbol(base_latex: str, offset: int, index: str) -> StepSymbol:
    """Component ``index`` of a vector/matrix quantity: ``(g_{k})_{12}``; a base that has a
    subscript of its own is parenthesised: ``((R_{1})_{k})_{12}``."""
    return StepSymbol(f"({subscripted(base_latex, offset)})_{{{index}}}")


class StageSymbol(StepSymbol):
    """A value of the Galerkin curve of the arrow g_{k+offset} at a quadrature node, in the
    papers' stage notation: the configuration Q_{k,i} or the velocity V_{k,i}
    (docs/conventions.md §22); printed by name, like every step symbol."""


def node_symbol(kind: str, offset: int, node: int, coordinate: str | None = None
                ) -> StageSymbol:
    """``Q_{k+offset,node}`` (``kind`` "Q") or ``V_{k+offset,node}`` of the arrow
    g_{k+offset}; with several coordinates, component ``coordinate`` (its LaTeX):
    ``(Q_{k,1})_{x}``."""
    name = f"{kind}_{{{step_label(offset)},{node}}}"
    return StageSymbol(name if coordinate is None else f"({name})_{{{coordinate}}}")


def stage_symbols(count: int, offset: int) -> list[StepSymbol]:
    """Internal stages ``(\\zeta_{k+offset})_a``, a = 1..count, of the arrow g_{k+offset}
    (docs/conventions.md §22)."""
    return [indexed_symbol(r"\zeta", offset, str(a + 1)) for a in range(count)]


def multiplier_symbols(count: int, offset: int) -> list[StepSymbol]:
    """Lagrange multipliers ``(\\lambda_{k+offset})_a``, a = 1..count."""
    return [indexed_symbol(r"\lambda", offset, str(a + 1)) for a in range(count)]
