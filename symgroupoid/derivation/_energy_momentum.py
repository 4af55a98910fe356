"""The momentum- and energy-preserving nonholonomic integrator (seed 002, last slides:
Ferraro, Iglesias and Martín de Diego; docs/conventions.md §14).

Inputs: a discrete Lagrangian L: G → R, a bundle metric G_c on AG (a rank × rank symmetric
positive-definite matrix in the section basis, possibly depending on the base point) and a
constraint distribution D ⊂ AG.  With AG = D ⊕ D⊥ (G_c-orthogonal) the step g_k → g_{k+1} is

    X⃖_a[L](g_k) − X⃗_a[L](g_{k+1}) = 0   for X_a ∈ D,
    X⃖_α[L](g_k) + X⃗_α[L](g_{k+1}) = 0   for X_α ∈ D⊥,

all sections taken at x_k = β(g_k) = α(g_{k+1}) (the slide prints the index α on both lines;
the second belongs to D⊥).  In momenta, ⟨F⁺L(g_k) − F⁻L(g_{k+1}), X⟩ = 0 on D and
⟨F⁺L(g_k) + F⁻L(g_{k+1}), X⟩ = 0 on D⊥: F⁻L(g_{k+1}) is the G_c-reflection of F⁺L(g_k) in D,
so ‖F⁻L(g_{k+1})‖ = ‖F⁺L(g_k)‖ in the dual metric at x_k, the D-components of the momentum
are continuous, and the constraint holds on the average of the two momenta.

Each block is a linear condition on all of D (resp. D⊥), so any bases give the same
solutions; the orthonormal adapted basis of the method is one choice.  Here D's basis is the
user's, and D⊥'s is the nullspace of C·G_c (C: D's coefficient rows) with denominators
cleared.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from .._errors import DomainError, ShapeError
from .._lambdify import NUMPY_MODULES
from ..groupoids import Groupoid, ParameterValues
from ._assembly import WindowAction
from ._callables import as_matrix, call_user, check_symbols, check_values
from ._momenta import legendre_forms
from ._step import (
    DerivedStep,
    SystemFunctions,
    _distribution_coefficients,
    _node,
    chart_of,
    next_map,
    tidy,
    window,
    window_arrows,
)

#: the methods of a nonholonomic step: Hölder's, or the energy–momentum correction
NONHOLONOMIC_METHODS = ("holder", "energy_momentum")


def metric_at(name: str, G: Groupoid, metric, q: Sequence) -> sp.Matrix:
    """G_c at the base point q: a rank × rank symmetric matrix (constant or callable)."""
    value = call_user(name, "metric", metric, tuple(q)) if callable(metric) else metric
    if value is None:
        raise DomainError(f"{name}: the energy–momentum method needs metric=G_c, a bundle "
                          f"metric on AG (a {G.rank}×{G.rank} matrix in the section basis)")
    M = as_matrix(name, "metric", value)
    if M.shape != (G.rank, G.rank):
        raise ShapeError(f"{name}: the metric is {M.shape[0]}×{M.shape[1]}; the algebroid has "
                         f"rank {G.rank}")
    check_values(name, "metric", M)
    if any(sp.expand(e) != 0 for e in M - M.T):
        raise DomainError(f"{name}: the metric G_c is not symmetric: {M.tolist()}")
    return M


def adapted_rows(name: str, G: Groupoid, distribution: Sequence, metric,
                 parameters: Sequence, q: Sequence) -> tuple[list, list]:
    """Coefficient rows of bases of D and of its G_c-orthogonal complement D⊥ at q.

    Checked at random values of q and the parameters: G_c positive definite, D of full rank.
    """
    C = sp.Matrix(_distribution_coefficients(name, G, distribution, q))
    Gm = metric_at(name, G, metric, q)
    check_symbols(name, "metric", list(Gm), q, parameters)
    r = C.rows
    if r == 0 or r >= G.rank:
        raise ShapeError(f"{name}: D must have dimension between 1 and rank − 1 = "
                         f"{G.rank - 1}; {r} elements given")
    _check_numerically(name, C, Gm, q)
    complement = [_cleared(v) for v in (C * Gm).nullspace()]
    if len(complement) != G.rank - r:
        raise ShapeError(f"{name}: D⊥ has dimension {len(complement)}, expected "
                         f"{G.rank - r} (are the elements of D independent?)")
    return [list(row) for row in C.tolist()], [list(v) for v in complement]


def _cleared(v: sp.Matrix) -> sp.Matrix:
    """v times the lcm of its entries' denominators (a polynomial vector, same direction)."""
    entries = [sp.together(e) for e in v]
    denominators = [sp.fraction(e)[1] for e in entries]
    scale = sp.lcm(denominators) if len(denominators) > 1 else denominators[0]
    return sp.Matrix([sp.cancel(e * scale) for e in entries])


def check_metric(name: str, G: Groupoid, metric, parameters: Sequence) -> None:
    """G_c checked as the energy–momentum method checks it (a symmetric rank × rank matrix
    in the base point and the parameters, positive definite at random values of them), for
    a system that keeps it for :meth:`conserved_quantities` without stepping by it."""
    q = G.target(window_arrows(G, window(1)[0])[0])
    Gm = metric_at(name, G, metric, q)
    check_symbols(name, "metric", list(Gm), q, parameters)
    _check_numerically(name, sp.eye(G.rank), Gm, q)


def _check_numerically(name: str, C: sp.Matrix, Gm: sp.Matrix, q: Sequence) -> None:
    rng = np.random.default_rng(0)
    free = sorted((C.free_symbols | Gm.free_symbols), key=lambda s: s.name)
    for _ in range(3):
        values = ParameterValues(rng=rng)
        sub = {s: sp.Float(v) for s, v in zip(free, rng.uniform(-1.0, 1.0, len(free)))
               if s in set(q)}
        sub.update({s: sp.Float(values.value(s)) for s in free if s not in sub})
        Cn = np.array(C.xreplace(sub).evalf().tolist(), dtype=float)
        Gn = np.array(Gm.xreplace(sub).evalf().tolist(), dtype=float)
        if np.linalg.matrix_rank(Cn) != C.rows:
            raise ShapeError(f"{name}: the elements of D are linearly dependent at "
                             f"{_show(sub)}")
        if np.linalg.eigvalsh(Gn).min() <= 0:
            at = f" at {_show(sub)}" if sub else ""
            raise DomainError(f"{name}: the metric G_c is not positive definite{at}: "
                              f"eigenvalues {np.linalg.eigvalsh(Gn).tolist()}")


def _show(sub: dict) -> str:
    return ", ".join(f"{s}={float(v):.4g}" for s, v in sorted(sub.items(), key=lambda kv:
                                                             str(kv[0])))


def window_halves(G: Groupoid, fs: SystemFunctions) -> tuple[list, list]:
    """X⃖_b[L](g_k) and X⃗_b[L](g_{k+1}) in the step's named coordinates (SymPy): the halves
    of :class:`~symgroupoid.derivation.WindowAction` without multipliers."""
    action = WindowAction(G, fs)
    A = action.slots("w")
    lhs, rhs = action.halves(A, multipliers=False)
    sub = action.naming(A, action.named_arrows())
    return [tidy(e.xreplace(sub)) for e in lhs], [tidy(e.xreplace(sub)) for e in rhs]


def energy_momentum_step(name: str, G: Groupoid, fs: SystemFunctions, distribution: Sequence,
                         metric, parameters: Sequence) -> DerivedStep:
    """The step of the energy–momentum method (module docstring): rank equations in the chart
    coordinates of g_{k+1}, no multipliers, no discrete constraint submanifold."""
    from ._window import window_graph

    if fs.constraints:
        raise ShapeError(f"{name}: the energy–momentum method imposes the constraints through "
                         f"D⊥ (on average) and takes no discrete constraint submanifold; pass "
                         f"constraints=None")
    arrows = window_arrows(G, window(1)[0])
    q = G.target(arrows[0])
    on_d, on_perp = adapted_rows(name, G, distribution, metric, parameters, q)

    def graph():
        wg = window_graph(name, G, fs, parameters, multipliers=False)
        g = wg.graph
        minus = [g.sub(a, b) for a, b in zip(wg.left_rows, wg.right_rows)]
        plus = [g.add(a, b) for a, b in zip(wg.left_rows, wg.right_rows)]
        rows = [_combination(wg, c, minus, name) for c in on_d]
        rows += [_combination(wg, c, plus, name) for c in on_perp]
        wg.residuals = rows
        return wg

    def symbolic() -> list:
        left, right = window_halves(G, fs)
        minus = [a - b for a, b in zip(left, right)]
        plus = [a + b for a, b in zip(left, right)]
        return ([tidy(sum((c * d for c, d in zip(row, minus)), sp.S.Zero)) for row in on_d]
                + [tidy(sum((c * d for c, d in zip(row, plus)), sp.S.Zero))
                   for row in on_perp])

    fibre, chart, cmap = chart_of(G, 1)
    g0, g1 = arrows[0], arrows[1]
    return DerivedStep(
        name=name, groupoid=G, order=1, knowns=list(g0),
        fibre_unknowns=fibre, chart_unknowns=chart, chart_map=cmap, multipliers_next=[],
        next_knowns=[sp.sympify(c).xreplace(next_map(G, fibre, cmap))
                     for c in G.renormalised_arrow(g1)],
        parameters=list(parameters),
        n_constraints=0, offsets=(0, 1), arrows=arrows,
        prediction=list(G.predict_chart(g0)), symbolic=symbolic, graph=graph,
        n_equations=G.rank)


def _combination(wg, coefficients: Sequence, rows: Sequence[int], name: str) -> int:
    g = wg.graph
    terms = [g.mul(_node(wg, c, name), r) for c, r in zip(coefficients, rows)
             if sp.sympify(c) != 0]
    return g.add(*terms) if terms else g.zero


@dataclass
class ConservedQuantities:
    """What the energy–momentum method conserves, as functions of the arrow g_k.

    ``energy`` = ½⟨F⁺L(g), G_c(β(g))⁻¹ F⁺L(g)⟩ and ``momenta[a]`` = ⟨F⁺L(g), X_a(β(g))⟩
    for the basis X_a of D.  The method maps ‖F⁺L(g_k)‖ to ‖F⁻L(g_{k+1})‖ and the
    D-components likewise, so the energy is conserved when ‖F⁻L(g)‖_{α(g)} = ‖F⁺L(g)‖_{β(g)}
    for every arrow, and J_a when ⟨F⁻L(g), X_a(α(g))⟩ = ⟨F⁺L(g), X_a(β(g))⟩ (a horizontal
    Noether symmetry).  ``energy_check`` and ``momentum_checks[a]`` say how that identity was
    established: ``"symbolic"``, ``"numeric"`` (on random arrows: it uses the manifold's
    equations, e.g. RᵀR = I) or ``"fails"``.
    """

    energy: sp.Expr
    momenta: list
    energy_check: str
    momentum_checks: list
    arrow: tuple
    parameters: list

    @property
    def energy_conserved(self) -> bool:
        return self.energy_check != "fails"

    @property
    def momentum_conserved(self) -> list[bool]:
        return [c != "fails" for c in self.momentum_checks]

    def __repr__(self) -> str:
        momenta = ", ".join(self.momentum_checks) or "none"
        return (f"<ConservedQuantities: energy ({self.energy_check}), "
                f"{len(self.momenta)} momenta ({momenta})>")

    def evaluate(self, arrows, params: Sequence) -> tuple[np.ndarray, np.ndarray]:
        """(energy (N,), momenta (N, r)) at the rows of ``arrows`` (flat coordinates)."""
        f = sp.lambdify([list(self.arrow), list(self.parameters)],
                        [self.energy] + list(self.momenta), NUMPY_MODULES)
        X = np.atleast_2d(np.asarray(arrows, float))
        out = f(list(X.T), np.asarray(params, float))
        n = X.shape[0]
        cols = [np.broadcast_to(np.asarray(v, float), (n,)) for v in out]
        return cols[0].copy(), np.stack(cols[1:], axis=1)


def conserved_quantities(name: str, G: Groupoid, fs: SystemFunctions, distribution: Sequence,
                         metric: Callable | Sequence, parameters: Sequence
                         ) -> ConservedQuantities:
    """The energy and D-momenta of the method at the named arrow g_k (see
    :class:`ConservedQuantities`)."""
    forms = legendre_forms(G, SystemFunctions(fs.slots, fs.lagrangian, []))
    g = forms.arrow
    qa, qb = G.source(g), G.target(g)
    pm, pp = sp.Matrix(forms.minus), sp.Matrix(forms.plus)
    Ga, Gb = metric_at(name, G, metric, qa), metric_at(name, G, metric, qb)
    energy = (pp.T * Gb.inv() * pp)[0, 0] / 2
    defect = (pm.T * Ga.inv() * pm)[0, 0] / 2 - energy
    rows_a = _distribution_coefficients(name, G, distribution, qa)
    rows_b = _distribution_coefficients(name, G, distribution, qb)
    momenta = [sum((c * p for c, p in zip(row, pp)), sp.S.Zero) for row in rows_b]
    defects = [sum((c * p for c, p in zip(ra, pm)), sp.S.Zero) - J
               for ra, J in zip(rows_a, momenta)]
    checks = [_identity_check(G, d, g) for d in [defect] + defects]
    return ConservedQuantities(energy, momenta, checks[0], checks[1:], tuple(g),
                               list(parameters))


def _identity_check(G: Groupoid, e: sp.Expr, arrow: tuple, samples: int = 6) -> str:
    """``"symbolic"`` if e ≡ 0 is proven, ``"numeric"`` if e vanishes at random arrows
    (relative to the size of its terms), else ``"fails"``."""
    e = sp.sympify(e)
    if e == 0 or sp.expand(e) == 0:
        return "symbolic"
    free = sorted(e.free_symbols - set(arrow), key=lambda s: s.name)
    terms = sp.Add.make_args(sp.expand(e))
    f = sp.lambdify([list(arrow), free], [e, sum((abs(t) for t in terms), sp.S.Zero)],
                    NUMPY_MODULES)
    rng = np.random.default_rng(0)
    for _ in range(samples):
        p = ParameterValues(rng=rng).vector(free)
        value, size = (float(v) for v in f(np.asarray(G.random_arrow(rng), float), p))
        if not np.isfinite(value) or abs(value) > 1e-9 * (1.0 + size):
            return "fails"
    return "numeric"
