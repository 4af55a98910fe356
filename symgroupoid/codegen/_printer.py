"""C99 printing of SymPy expressions with every symbol mapped to a C name (see
:mod:`symgroupoid.ir._c`, where the printer lives so that the expression graph's opaque and
special functions print with it too)."""

from ..ir import KernelCPrinter, UnmappedSymbolError, print_c

__all__ = ["KernelCPrinter", "UnmappedSymbolError", "print_c"]
