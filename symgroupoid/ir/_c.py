"""C99 printing of SymPy expressions with every symbol mapped to a C name.

The printer never manipulates printed strings: symbols are looked up in a table
(symbol → C lvalue such as ``u[3]``, ``known[0]``, ``p[1]`` or a local ``t12``), and the
number types and powers are printed by their own ``_print_X`` methods.
"""

from __future__ import annotations

from collections.abc import Mapping

import sympy as sp
from sympy.printing.c import C99CodePrinter

#: integer powers up to this size are printed as products (exact, faster than pow)
MAX_UNROLLED_POWER = 4


class UnmappedSymbolError(KeyError):
    """An expression uses a symbol that has no C name in the printer's table."""


class KernelCPrinter(C99CodePrinter):
    """C99 printer for kernels: symbols through a table, doubles at full precision.

    Parameters
    ----------
    names : mapping from SymPy symbols to C expressions (array accesses or locals).
    """

    def __init__(self, names: Mapping[sp.Symbol, str]):
        super().__init__({"precision": 17})
        self._names = dict(names)

    # --- symbols --------------------------------------------------------------------------
    def _print_Symbol(self, expr: sp.Symbol) -> str:
        try:
            return self._names[expr]
        except KeyError:
            raise UnmappedSymbolError(
                f"symbol {expr.name!r} has no C name (not an unknown, known, parameter or "
                f"intermediate of this kernel)") from None

    _print_Dummy = _print_Symbol

    def _print_StepSymbol(self, expr) -> str:
        return self._print_Symbol(expr)

    # --- numbers --------------------------------------------------------------------------
    def _print_Integer(self, expr: sp.Integer) -> str:
        return f"{int(expr)}.0"

    def _print_Rational(self, expr: sp.Rational) -> str:
        return f"{int(expr.p)}.0/{int(expr.q)}.0"

    def _print_Float(self, expr: sp.Float) -> str:
        return repr(float(expr))

    def _print_Half(self, expr) -> str:
        return "0.5"

    # --- powers ---------------------------------------------------------------------------
    def _print_Pow(self, expr: sp.Pow) -> str:
        base, exp = expr.base, expr.exp
        if exp.is_Integer and 2 <= abs(int(exp)) <= MAX_UNROLLED_POWER:
            b = self.parenthesize(base, sp.printing.precedence.PRECEDENCE["Mul"] + 1)
            product = "*".join([b] * abs(int(exp)))
            return f"({product})" if exp > 0 else f"(1.0/({product}))"
        return super()._print_Pow(expr)


def print_c(expr: sp.Expr, names: Mapping[sp.Symbol, str]) -> str:
    """The C99 text of ``expr`` with symbols named by ``names``."""
    return KernelCPrinter(names).doprint(expr)


def c_of_sympy(expr: sp.Expr, names: Mapping[sp.Symbol, str]) -> str:
    """C99 text of a (small) SymPy expression, symbols named by ``names`` (no free names)."""
    return KernelCPrinter(names).doprint(expr)
