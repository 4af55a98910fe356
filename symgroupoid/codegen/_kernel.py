"""From a :class:`StepEquations` to straight-line C: the bodies of the kernel functions.

Each kernel function is a *block*: common subexpressions (SymPy ``cse``, canonical order,
temporaries named by position) followed by output assignments.  Residual and Jacobian
share one ``cse`` over

    [fibre reconstruction f = τ(x), residuals F(f, x, λ; known, p), Jacobian ∂F/∂(x, λ)],

where the Jacobian is the chain rule through the α-fibre chart,
∂F/∂x = (∂F/∂f)(∂f/∂x), exactly as :meth:`StepEquations.jacobian` builds it.  The fibre
variables are computed once as named intermediates; statements are then ordered so that
every local is defined before use, and only statements the outputs need are kept.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field

import sympy as sp

from ._printer import KernelCPrinter

_C_KEYWORDS = frozenset(
    "auto break case char const continue default do double else enum extern float for goto "
    "if inline int long register restrict return short signed sizeof static struct switch "
    "typedef union unsigned void volatile while _Bool _Complex _Imaginary".split())


def c_identifier(name: str) -> str:
    """A safe C identifier prefix from a system name.

    Lower-cased; every run of characters outside ``[A-Za-z0-9_]`` becomes ``_``; a leading
    digit, an empty result or a C keyword gets the prefix ``sg_``.
    """
    ident = re.sub(r"[^A-Za-z0-9_]+", "_", name.strip()).strip("_").lower()
    if not ident or ident[0].isdigit() or ident in _C_KEYWORDS:
        ident = f"sg_{ident}".rstrip("_") if ident else "sg_system"
    return ident


@dataclass
class Block:
    """Straight-line C for one kernel function: local definitions then output stores."""

    locals: list[str] = field(default_factory=list)  # "const double t3 = …;"
    stores: list[str] = field(default_factory=list)  # "F[0] = …;"


@dataclass
class _Statement:
    symbol: sp.Symbol
    expr: sp.Expr
    order: int


def _ordered(statements: list[_Statement], outputs: Sequence[sp.Expr]) -> list[_Statement]:
    """Statements the outputs need, each after the locals it reads (stable order)."""
    by_symbol = {s.symbol: s for s in statements}
    needed: set = set()
    stack = [sym for e in outputs for sym in e.free_symbols if sym in by_symbol]
    while stack:
        sym = stack.pop()
        if sym in needed:
            continue
        needed.add(sym)
        stack.extend(d for d in by_symbol[sym].expr.free_symbols if d in by_symbol)
    pending = sorted((s for s in statements if s.symbol in needed), key=lambda s: s.order)
    done: set = set()
    out: list[_Statement] = []
    while pending:
        for i, s in enumerate(pending):
            if all(d in done for d in s.expr.free_symbols if d in by_symbol):
                out.append(pending.pop(i))
                done.add(s.symbol)
                break
        else:  # pragma: no cover - cse output is acyclic
            raise RuntimeError("cyclic intermediate definitions")
    return out


def build_block(outputs: Sequence[tuple[str, sp.Expr]], names: dict,
                intermediates: Sequence[tuple[sp.Symbol, sp.Expr]] = (),
                local_prefix: str = "f") -> Block:
    """C for ``target = expr`` stores, with shared subexpressions eliminated.

    ``intermediates`` are named quantities (e.g. the fibre variables f = τ(x)) that the
    outputs are written in; they take part in the same ``cse`` and become locals
    ``{local_prefix}0, {local_prefix}1, …`` when (and only when) an output needs them.
    """
    inter = list(intermediates)
    exprs = [sp.sympify(e) for _, e in inter] + [sp.sympify(e) for _, e in outputs]
    temps = sp.numbered_symbols("_cse", cls=sp.Symbol, real=True)
    replacements, reduced = sp.cse(exprs, symbols=temps, order="canonical")
    table = dict(names)
    statements: list[_Statement] = []
    for i, (sym, e) in enumerate(replacements):
        table[sym] = f"t{i}"
        statements.append(_Statement(sym, e, i))
    for j, ((sym, _), e) in enumerate(zip(inter, reduced)):
        table[sym] = f"{local_prefix}{j}"
        statements.append(_Statement(sym, e, len(replacements) + j))
    out_exprs = reduced[len(inter):]
    printer = KernelCPrinter(table)
    block = Block()
    for s in _ordered(statements, out_exprs):
        block.locals.append(f"const double {table[s.symbol]} = {printer.doprint(s.expr)};")
    for (target, _), e in zip(outputs, out_exprs):
        block.stores.append(f"{target} = {printer.doprint(e)};")
    return block


@dataclass
class KernelBlocks:
    """The bodies of the generated kernel functions, plus sizes and names."""

    reconstruct: Block
    residual: Block
    residual_jacobian: Block
    predict: Block
    next_knowns: Block
    n_fibre: int


def _array_names(step) -> dict:
    names = {s: f"u[{i}]" for i, s in enumerate(step.unknowns)}
    names |= {s: f"known[{i}]" for i, s in enumerate(step.knowns)}
    names |= {s: f"p[{i}]" for i, s in enumerate(step.parameters)}
    return names


def kernel_blocks(step) -> KernelBlocks:
    """All function bodies of the kernel of ``step`` (deterministic for equal input)."""
    names = _array_names(step)
    recon = [(f, step.reconstruction[f]) for f in step.fibre_unknowns
             if f in step.reconstruction]
    n_u = len(step.unknowns)
    F = [(f"F[{i}]", r) for i, r in enumerate(step.residuals)]
    J = step.jacobian()
    JF = [(f"J[{i * n_u + j}]", J[i, j]) for i in range(J.rows) for j in range(J.cols)]
    return KernelBlocks(
        reconstruct=build_block([(f"fibre[{j}]", e) for j, (_, e) in enumerate(recon)], names),
        residual=build_block(F, names, recon),
        residual_jacobian=build_block(F + JF, names, recon),
        predict=build_block([(f"u[{i}]", e) for i, e in enumerate(step.prediction)], names),
        next_knowns=build_block(
            [(f"known_next[{i}]", e) for i, e in enumerate(step.next_knowns)], names),
        n_fibre=len(recon),
    )
