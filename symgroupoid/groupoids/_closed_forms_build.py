"""Writes ``groupoids/_closed_forms.py``: the per-class templates of the matrix groups
(``_matrix_templates``) with the Cayley retraction, as the exact trees their derivation gives.

A new process then evaluates the stored text instead of deriving each template again (the
Cayley map's ``factor``, SymPy's products of symbolic matrices: about 0.14 s of every first
3D chain derivation).  The tests derive every template again and require the stored one to
be equal, and the file to be what this module writes; after a change of a group's structure
maps, of a retraction or of SymPy, run ``make closed-forms``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import sympy as sp
from sympy.printing.repr import ReprPrinter

from . import _matrix_templates as mg
from ._se2 import SE2
from ._se3 import SE3
from ._so2 import SO2
from ._so3 import SO3

#: the groups whose templates are stored, in the order they are written
GROUPS: tuple[type, ...] = (SO2, SO3, SE2, SE3)
#: the maps of ``_matrix_templates._instantiated`` that are stored
MAPS: tuple[str, ...] = ("translated_retraction", "increment_coordinates")
RETRACTION = "cayley"
PATH = Path(__file__).with_name("_closed_forms.py")


class _PlaceholderPrinter(ReprPrinter):
    """``srepr`` with the template's placeholders printed as ``P[i]`` (any other symbol
    that is a Dummy is an error: it could not be rebuilt in another process)."""

    def __init__(self, placeholders: Sequence[sp.Symbol]):
        super().__init__()
        self._index = {s: i for i, s in enumerate(placeholders)}

    def _print_Symbol(self, expr, **kwargs):
        if expr in self._index:
            return f"P[{self._index[expr]}]"
        if isinstance(expr, sp.Dummy):
            raise ValueError(f"a template holds the foreign placeholder {expr!r}")
        return super()._print_Symbol(expr, **kwargs)

    _print_Dummy = _print_Symbol

    def _print_args_in_order(self, expr, **kwargs):
        """A sum or product with its arguments in their stored order (``srepr`` sorts them
        for display, and an unevaluated rebuild keeps the order it is given)."""
        return f"{type(expr).__name__}({', '.join(self._print(a) for a in expr.args)})"

    _print_Add = _print_Mul = _print_args_in_order


def derived_templates() -> list[tuple[str, object, tuple]]:
    """(key, template, placeholders) of every stored template, derived (never read from the
    stored file)."""
    out = []
    for cls in GROUPS:
        x = mg._dtau_dummies(cls)
        out.append((f"{cls.__name__}.cayley", mg._direct_cayley(cls, x), x))
    for cls in GROUPS:
        group = cls("g", retraction=RETRACTION)
        for name in MAPS:
            size = group.arrow_dim + (group.rank if name == "translated_retraction"
                                      else group.arrow_dim)
            placeholders = tuple(sp.Dummy(f"a{i}") for i in range(size))
            out.append((f"{cls.__name__}.{RETRACTION}.{name}",
                        mg._direct_map(group, name, placeholders), placeholders))
    for m in sorted({cls.rotation_block for cls in GROUPS}):
        entries = {(i, j): sp.Dummy(f"q{i}{j}") for i in range(m) for j in range(m)}
        out.append((f"renormalised.{m}", mg._direct_renormalised(entries, m),
                    tuple(entries.values())))
    return out


def source() -> str:
    """The text of ``_closed_forms.py``."""
    lines = ["# ruff: noqa: E501  (one expression tree per line)",
             '"""Stored templates of the matrix groups (written by _closed_forms_build.py;',
             'do not edit: run ``make closed-forms``)."""', "", "FORMS = {"]
    for key, template, placeholders in derived_templates():
        text = _PlaceholderPrinter(placeholders).doprint(template)
        lines.append(f"    {key!r}: {text!r},")
    lines.append("}")
    return "\n".join(lines) + "\n"


def write(path: Path = PATH) -> bool:
    """Write the file (atomically); True when it changed."""
    text = source()
    if path.is_file() and path.read_text(encoding="utf-8") == text:
        return False
    partial = path.with_suffix(".partial")
    partial.write_text(text, encoding="utf-8")
    partial.replace(path)
    return True


if __name__ == "__main__":
    print(("wrote " if write() else "unchanged ") + str(PATH))
