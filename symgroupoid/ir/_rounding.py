"""Rounding-error bounds of computed values: the floor a residual cannot go below.

For a value computed by the straight-line program (its operations in the order the
generated code performs them), running error analysis (Wilkinson; Higham, *Accuracy and
Stability of Numerical Algorithms*, §3.3) bounds, to first order in the unit roundoff u, the
error of the computed value by u·E, where E is built alongside the value:

- an input is exact: E = 0 (or E = |x| when it is itself a rounded value); a constant that
  is not exactly a double: E = |c|;
- a sum a₁ + … + a_n evaluated left to right: E = Σ E(a_k) + Σ_{m ≥ 2} |a₁ + … + a_m|
  (each partial sum is rounded once);
- a product a₁ ⋯ a_n: E = Σ_k |Π_{j≠k} a_j|·E(a_k) + (n − 1)|a₁ ⋯ a_n|;
- a power or an elementary function f(x): E = Σ_k |∂f/∂x_k|·E(x_k) + c·|f|, with c the
  roundings of its evaluation (repeated products for integer powers; one for a library
  function, which is correctly rounded to within an ulp or so).

Unlike the magnitude of the terms, E does not count the difference of nearby inputs as an
error (x₁ − x₀ of nearby numbers is exact), so it stays tight when a residual is written in
increments of coordinates far from zero.  Newton's method compares |F_i| with
ε·(E_i + Σ_j |J_ij||u_j|) — the second term is the residual's change when the unknowns are
rounded — to stop at the floor, whatever the scale of the equations.

The step kernels' Newton iteration needs a floor that costs no more code than the residual
itself: :func:`term_magnitude` S, the size of the terms each residual is built from, with
ε·S as the scale of the noise of its evaluation (|F_i| cannot be brought below the rounding
of the largest intermediate value it is computed from, e.g. a position x_{k+1} = x_k + Δ far
from the origin in (x_{k+1} − x_k)/h).
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from ._ad import _product_partials, partial
from ._functions import ELEMENTARY
from ._graph import ADD, CONST, INPUT, MUL, POW, Graph


def _exact_double(value: sp.Expr) -> bool:
    """Whether a constant is exactly a double (an integer or a dyadic rational in range)."""
    if value.is_Integer:
        return abs(int(value)) <= 2**53
    if value.is_Rational:
        q = int(value.q)
        return q & (q - 1) == 0 and abs(int(value.p)) <= 2**53
    return False


def rounding_error(g: Graph, outputs: Sequence[int], perturbed: Sequence[int] = ()
                   ) -> list[int]:
    """Nodes computing E(o) for every output (see the module docstring): the error of the
    computed output is at most about ε·E(o) (ε = 2u, the machine epsilon).  ``perturbed``:
    input nodes that carry a rounding of their own (E = |x|: stored coordinates that are
    the result of earlier arithmetic), so E also bounds the output's change when they are
    rounded; the other inputs are exact."""
    absolute = ELEMENTARY[sp.Abs]
    perturbed = frozenset(perturbed)

    def abs_(n: int) -> int:
        return g.func(absolute, n)

    err: dict = {}
    op, args, data = g.op, g.args, g.data
    for n in g.reachable(outputs):
        o = op[n]
        a = args[n]
        if o == INPUT:
            err[n] = abs_(n) if n in perturbed else g.zero
        elif o == CONST:
            err[n] = g.zero if _exact_double(data[n]) else g.const(abs(data[n]))
        elif o == ADD:
            partial_sums, running = [], a[0]
            for x in a[1:]:
                running = g.add(running, x)
                partial_sums.append(abs_(running))
            err[n] = g.add(*[err[x] for x in a], *partial_sums)
        elif o == MUL:
            cofactors = _product_partials(g, n)
            propagated = [g.mul(abs_(c), err[x]) for c, x in zip(cofactors, a)
                          if err[x] != g.zero]
            err[n] = g.add(*propagated, g.mul(g.const(len(a) - 1), abs_(n)))
        else:
            roundings = (abs(int(data[n])) if o == POW and data[n].is_Integer else 1)
            propagated = [g.mul(abs_(partial(g, n, k)), err[x])
                          for k, x in enumerate(a) if err[x] != g.zero]
            err[n] = g.add(*propagated, g.mul(g.const(roundings), abs_(n)))
    return [err[o] for o in outputs]



def _product_size(g: Graph, factors: Sequence[int], size: dict, depends) -> int:
    """S(a₁ ⋯ a_n) = Π_known S(a_j) · Σ_k S(a_k) Π_{j≠k} |a_j| (k, j over the factors that
    depend on the varying inputs; a known factor's S is its |value|).  Not Π S(a_k): where a
    factor is a difference of large terms (S(a) ≫ |a|, as a velocity (q₁ − q₀)/(t₁ − t₀) at
    |t| ≈ 100), the product of the sizes overstates the rounding of v² a millionfold, and a
    floor test on it took a residual of 2·10⁻³ for rounding."""
    absolute = ELEMENTARY[sp.Abs]
    known = [size[x] for x in factors if x not in depends]
    varying = [x for x in factors if x in depends]
    terms = [g.mul(size[x], *[g.func(absolute, y) for y in varying[:k] + varying[k + 1:]])
             for k, x in enumerate(varying)]
    return g.mul(*known, g.add(*terms))


def term_magnitude(g: Graph, outputs: Sequence[int], varying: Sequence[int]) -> list[int]:
    """Nodes computing S(o) for every output, the size of the terms it is built from.

    A node that does not depend on the ``varying`` inputs (the unknowns of a Newton solve)
    has S = |value|: its rounding is the same at every iterate, so it shifts the computed
    root but adds no noise to the residual.  The others propagate the magnitudes of their
    arguments:

    - a sum a₁ + … + a_n: S = Σ S(a_k) (every partial sum is at most that large);
    - a product a₁ ⋯ a_n: S = Π_known |a_j| · Σ_k S(a_k) Π_{j≠k} |a_j|, k and j over the
      varying factors (the first-order propagation of each factor's rounding, as the product
      is evaluated: the factors are computed, then multiplied);
    - a positive integer power a^m: S = m |a|^(m−1) S(a);
    - any other power or elementary function f(x): S = |f| + Σ_k |∂f/∂x_k|·S(x_k) (the
      function's value and its first-order sensitivity to its arguments' magnitudes).

    ε·S(o) is, up to a factor of the order of the depth of the program, the rounding noise
    of the computed o as the varying inputs move (a first-order estimate, like
    :func:`rounding_error`, but one node per node of the program rather than several: the
    step kernels evaluate it beside the residual).  It counts the knowns and parameters
    through every term they enter with the unknowns.
    """
    absolute = ELEMENTARY[sp.Abs]
    order = g.reachable(outputs)
    depends = g.dependents(varying, order)
    size: dict = {}
    op, args, data = g.op, g.args, g.data
    for n in order:
        o = op[n]
        a = args[n]
        if n not in depends:
            size[n] = g.func(absolute, n) if o != CONST else g.const(abs(data[n]))
        elif o == INPUT:
            size[n] = g.func(absolute, n)
        elif o == ADD:
            size[n] = g.add(*[size[x] for x in a])
        elif o == MUL:
            size[n] = _product_size(g, a, size, depends)
        elif o == POW and data[n].is_Integer and data[n] > 0:
            m = int(data[n])
            size[n] = g.mul(g.const(m), g.pow(g.func(absolute, a[0]), m - 1), size[a[0]])
        else:
            sensitivities = [g.mul(g.func(absolute, partial(g, n, k)), size[x])
                             for k, x in enumerate(a)]
            size[n] = g.add(g.func(absolute, n), *sensitivities)
    return [size[o] for o in outputs]
