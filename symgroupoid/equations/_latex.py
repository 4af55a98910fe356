"""LaTeX in the papers' notation, by SymPy printer type dispatch."""

from __future__ import annotations

import sympy as sp
from sympy.printing.latex import LatexPrinter


class GroupoidLatexPrinter(LatexPrinter):
    """SymPy's LaTeX printer, extended for step-indexed symbols."""

    def _print_StepSymbol(self, expr) -> str:
        return expr.name


def latex(expr) -> str:
    """LaTeX of an expression in the papers' notation."""
    return GroupoidLatexPrinter({"mul_symbol": None}).doprint(expr)


def equation_lines(step) -> list[str]:
    """One ``0 &= …`` line per residual (the structured form when available)."""
    forms = step.structured if step.structured is not None else step.residuals
    return [f"0 &= {latex(r)}" for r in forms]


def step_latex(step, document: bool = False) -> str:
    body = "\\begin{align}\n" + " \\\\\n".join(equation_lines(step)) + "\n\\end{align}"
    if not document:
        return body
    return ("\\documentclass{article}\n\\usepackage{amsmath}\n\\begin{document}\n"
            f"% {step.name}: {len(step)} equations in {len(step.unknowns)} unknowns\n"
            f"{body}\n\\end{{document}}\n")


__all__ = ["GroupoidLatexPrinter", "latex", "step_latex", "equation_lines", "sp"]
