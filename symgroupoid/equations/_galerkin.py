"""Galerkin discrete Lagrangians with internal stages (docs/conventions.md §22).

A Galerkin discrete Lagrangian (Marsden–West §2.6.6; Hairer–Lubich–Wanner VI.6.3) replaces
the curve over one step [0, h] by a polynomial of degree M through control values at the
times d₀ h = 0 < d₁ h < … < d_M h = h and the action by a quadrature (nodes c_i h, weights
b_i h):

    L_d(q₀, q₁) = ext_{P₁, …, P_{M−1}} h Σ_i b_i L(q(c_i h), q̇(c_i h)),
    q(τh) = Σ_j ℓ_j(τ) P_j,   q̇(τh) = (1/h) Σ_j ℓ_j′(τ) P_j,   P₀ = q₀, P_M = q₁,

ℓ_j the Lagrange basis on the control times.  The interior control values are the internal
stages, written as deviations from the chord, P_j = q₀ + d_j (q₁ − q₀) + ζ_j (so that ζ = 0
is a first guess within O(h²)).  On a Lie group the curve is g(τh) = g₀·τ(ξ(τ)) through the
group's retraction τ, with ξ a polynomial in the Lie algebra (ξ(0) = 0, ξ(1) = τ⁻¹(g₀⁻¹g₁),
interior values d_j ξ(1) + ζ_j) and body velocity g⁻¹ġ = (1/h) dτ_{ξ}(ξ′) (the left
trivialised tangent of τ, exact; Bogfjellmo–Marthinsen's partitioned Lie group methods in
the retraction's chart).

- :func:`gauss_legendre_tableau`: M = s, control times j/s, the s Gauss–Legendre nodes:
  order 2s (the s-stage Gauss collocation method; Hairer–Lubich–Wanner VI Thm 6.4).
- :func:`lobatto_tableau`: M = s − 1, the s Lobatto nodes as control times and nodes:
  Lobatto IIIA–IIIB, order 2s − 2.

The nodes are exact (square roots) for up to three roots of a node polynomial, else numbers
with 40 significant digits (beyond double precision).  A scheme has at most
:data:`MAX_NODES` nodes.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import sympy as sp

from .._arguments import integer_argument

_tau = sp.Symbol("tau", real=True)
DIGITS = 40
EXACT = 3  # nodes written exactly up to this many roots (beyond: nested radicals)
#: the most nodes of a scheme: GaussLegendre(10) is of order 20 and LobattoIIIAB(10) of order
#: 18, whose errors are below double precision's rounding at any step h where the step's
#: Newton converges; the tables of more nodes take minutes to build (s = 12: ~1 min)
MAX_NODES = 10


@dataclass(frozen=True)
class GalerkinTableau:
    """Control times d_j (d₀ = 0, d_M = 1), quadrature nodes c_i and weights b_i on [0, 1],
    and the Lagrange basis on the control times at the nodes: ``values[i][j]`` = ℓ_j(c_i),
    ``slopes[i][j]`` = ℓ_j′(c_i)."""

    control: tuple
    nodes: tuple
    weights: tuple
    values: tuple
    slopes: tuple

    @property
    def interior(self) -> int:
        """The number of interior control values (internal stages per coordinate)."""
        return len(self.control) - 2


def _roots(poly: sp.Expr, count: int) -> list:
    """The ``count`` real roots of ``poly`` in τ, ascending: exact for up to three roots
    (square roots at most), else to :data:`DIGITS` digits."""
    if count <= EXACT:
        found = sp.roots(sp.Poly(poly, _tau))
        roots = [r for r, k in found.items() for _ in range(k)]
        if len(roots) == count and all(r.is_real for r in roots):
            return sorted(roots, key=float)
    numeric = sp.Poly(poly, _tau).nroots(n=DIGITS)
    return sorted((sp.Float(r, DIGITS) for r in numeric), key=float)


def _lagrange(points: list) -> list:
    """The Lagrange basis polynomials in τ on ``points``."""
    basis = []
    for j, pj in enumerate(points):
        ell = sp.S.One
        for i, pi in enumerate(points):
            if i != j:
                ell *= (_tau - pi) / (pj - pi)
        basis.append(sp.expand(ell))
    return basis


def _clean(value: sp.Expr) -> sp.Expr:
    """An exact value in expanded radical form (no numeric identification, which could
    change it); a numeric one to :data:`DIGITS` digits."""
    if value.has(sp.Float):
        return sp.Float(value, DIGITS)
    return sp.radsimp(sp.expand(value))


def _tableau(control: list, nodes: list) -> GalerkinTableau:
    ell = _lagrange(control)
    quad = _lagrange(nodes)
    weights = tuple(_clean(sp.integrate(q, (_tau, 0, 1))) for q in quad)
    values = tuple(tuple(_clean(e.subs(_tau, c)) for e in ell) for c in nodes)
    slopes = tuple(tuple(_clean(sp.diff(e, _tau).subs(_tau, c)) for e in ell) for c in nodes)
    return GalerkinTableau(tuple(control), tuple(nodes), weights, values, slopes)


def gauss_legendre_tableau(s: int) -> GalerkinTableau:
    """Degree-s polynomials at the control times j/s, s Gauss–Legendre nodes (order 2s);
    1 ≤ s ≤ :data:`MAX_NODES`."""
    return _gauss_legendre(integer_argument(s, "stages", minimum=1, maximum=MAX_NODES,
                                            owner="GaussLegendre"))


def lobatto_tableau(s: int) -> GalerkinTableau:
    """Degree-(s − 1) polynomials through the s Lobatto nodes 0, the roots of
    P′_{s−1}(2τ − 1), 1, with the Lobatto weights (order 2s − 2); 2 ≤ s ≤
    :data:`MAX_NODES`."""
    return _lobatto(integer_argument(s, "stages", minimum=2, maximum=MAX_NODES,
                                     owner="LobattoIIIAB"))


@functools.cache
def _gauss_legendre(s: int) -> GalerkinTableau:
    nodes = _roots(sp.legendre(s, 2 * _tau - 1), s)
    return _tableau([sp.Rational(j, s) for j in range(s + 1)], nodes)


@functools.cache
def _lobatto(s: int) -> GalerkinTableau:
    inner = _roots(sp.diff(sp.legendre(s - 1, 2 * _tau - 1), _tau), s - 2) if s > 2 else []
    nodes = [sp.S.Zero, *inner, sp.S.One]
    return _tableau(nodes, nodes)


__all__ = ["MAX_NODES", "GalerkinTableau", "gauss_legendre_tableau", "lobatto_tableau"]
