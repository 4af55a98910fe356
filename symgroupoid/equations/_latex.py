"""LaTeX in the papers' notation, by SymPy printer type dispatch.

Step symbols print as their names (x_{k+1}, (g_{k})_{12}, (\\lambda_{k+1})_{1}); matrix
entries are 1-based; diagonal constant matrices print as diag(…); traces as tr(…).
"""

from __future__ import annotations

import sympy as sp
from sympy.printing.latex import LatexPrinter


class GroupoidLatexPrinter(LatexPrinter):
    """SymPy's LaTeX printer, extended for step-indexed symbols and matrix parts."""

    def __init__(self, settings=None):
        super().__init__({"mul_symbol": None, **(settings or {})})

    def _print_StepSymbol(self, expr) -> str:
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
        return f"\\operatorname{{tr}}\\left({self._print(expr.arg)}\\right)"

    def _print_ImmutableDenseMatrix(self, expr) -> str:
        rows, cols = expr.shape
        if rows == cols and expr.is_diagonal():
            entries = ", ".join(self._print(expr[i, i]) for i in range(rows))
            return f"\\operatorname{{diag}}\\left({entries}\\right)"
        return super()._print_MatrixBase(expr)

    _print_NamedMatrix = _print_ImmutableDenseMatrix


def latex(expr) -> str:
    """LaTeX of an expression in the papers' notation."""
    return GroupoidLatexPrinter().doprint(expr)


def equation_lines(step) -> list[str]:
    """One ``0 &= …`` line per residual (the matrix form when available)."""
    forms = step.structured if step.structured is not None else step.residuals
    return [f"0 &= {latex(r)}" for r in forms]


def step_latex(step, document: bool = False) -> str:
    """An ``align`` environment of the step equations, or a standalone document."""
    body = "\\begin{align}\n" + " \\\\\n".join(equation_lines(step)) + "\n\\end{align}"
    if not document:
        return body
    return ("\\documentclass{article}\n\\usepackage{amsmath,amssymb}\n\\begin{document}\n"
            f"% {step.name}: {len(step)} equations in {len(step.unknowns)} unknowns\n"
            f"{body}\n\\end{{document}}\n")
