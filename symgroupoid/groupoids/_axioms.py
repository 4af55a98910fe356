"""Numerical verification of the groupoid axioms on random arrows."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import sympy as sp

from .._errors import AxiomError
from ._base import Groupoid


def _num(v: Sequence) -> np.ndarray:
    return np.array([float(sp.N(c)) for c in v], dtype=float)


def _close(a: Sequence, b: Sequence, tol: float) -> bool:
    a, b = _num(a), _num(b)
    return a.shape == b.shape and bool(np.allclose(a, b, atol=tol, rtol=tol))


def check_axioms(G: Groupoid, samples: int = 5, seed: int = 0, tol: float = 1e-9) -> None:
    """Check the groupoid axioms of ``G`` on random composable arrows.

    Verified: α, β of products; associativity; left and right identities; inverses;
    α∘ε = β∘ε = id; section curves lie in the α-fibre through ε(q) and their velocities are
    α-vertical and linearly independent (as many as the fibre dimension); the fibre chart
    lands in the α-fibre.  Raises :class:`AxiomError` naming the axiom and the arrows.
    """
    rng = np.random.default_rng(seed)
    t = sp.Dummy("t", real=True)
    for _ in range(samples):
        a = G.random_arrow(rng)
        b = G.random_arrow(rng, G.target(a))
        c = G.random_arrow(rng, G.target(b))
        _pair_checks(G, a, b, c, tol)
        q = G.random_base_point(rng)
        _identity_checks(G, q, tol)
        _section_checks(G, q, t, tol)


def _fail(G: Groupoid, axiom: str, **arrows) -> AxiomError:
    """An :class:`AxiomError` naming the axiom and showing the failing arrows (or base point).

    The exception also carries ``.axiom`` and ``.arrows`` (name → tuple of floats) so that a
    caller can reproduce the failure.
    """
    values = {k: tuple(float(c) for c in _num(v)) for k, v in arrows.items()}
    shown = ", ".join(f"{k}=({', '.join(f'{c:.6g}' for c in v)})" for k, v in values.items())
    err = AxiomError(f"{G.name}: {axiom} fails for {shown}")
    err.axiom, err.arrows = axiom, values
    return err


def _pair_checks(G, a, b, c, tol):
    ab = G.multiply(a, b)
    if not _close(G.source(ab), G.source(a), tol):
        raise _fail(G, "α(ab) = α(a)", a=a, b=b)
    if not _close(G.target(ab), G.target(b), tol):
        raise _fail(G, "β(ab) = β(b)", a=a, b=b)
    if not _close(G.multiply(ab, c), G.multiply(a, G.multiply(b, c)), tol):
        raise _fail(G, "associativity (ab)c = a(bc)", a=a, b=b, c=c)
    if not _close(G.multiply(G.identity(G.source(a)), a), a, tol):
        raise _fail(G, "left identity ε(α(a))·a = a", a=a)
    if not _close(G.multiply(a, G.identity(G.target(a))), a, tol):
        raise _fail(G, "right identity a·ε(β(a)) = a", a=a)
    ai = G.inverse(a)
    if not _close(G.source(ai), G.target(a), tol) or not _close(G.target(ai), G.source(a), tol):
        raise _fail(G, "α(a⁻¹) = β(a), β(a⁻¹) = α(a)", a=a)
    if not _close(G.multiply(a, ai), G.identity(G.source(a)), tol):
        raise _fail(G, "a·a⁻¹ = ε(α(a))", a=a)
    if not _close(G.multiply(ai, a), G.identity(G.target(a)), tol):
        raise _fail(G, "a⁻¹·a = ε(β(a))", a=a)


def _identity_checks(G, q, tol):
    e = G.identity(q)
    if not _close(G.source(e), q, tol) or not _close(G.target(e), q, tol):
        raise _fail(G, "α(ε(q)) = β(ε(q)) = q", q=q)


def _section_checks(G, q, t, tol):
    curves = G._curves(q, t)
    vel = []
    for i, h in enumerate(curves):
        h0 = [sp.sympify(c).subs(t, 0) for c in h]
        if not _close(h0, G.identity(q), tol):
            raise _fail(G, f"section {i}: h(0) = ε(q)", q=q)
        ht = [sp.sympify(c).subs(t, sp.Rational(3, 10)) for c in h]
        if not _close(G.source(ht), q, tol):
            raise _fail(G, f"section {i}: h(t) in the α-fibre of q", q=q)
        vel.append(_num([sp.sympify(c).diff(t).subs(t, 0) for c in h]))
    if vel and np.linalg.matrix_rank(np.array(vel), tol=1e-8) != len(vel):
        raise _fail(G, "section velocities at ε(q) are linearly independent", q=q)
    rng = np.random.default_rng(1)
    x = [sp.Float(v) for v in G.random_chart(rng)]
    arrow = G.arrow_from(q, G.fibre_chart(x, q))
    if not _close(G.source(arrow), q, tol):
        raise _fail(G, "the fibre chart lands in the α-fibre of q", q=q)
