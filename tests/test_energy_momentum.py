"""The momentum- and energy-preserving nonholonomic integrator (seed 002, last slides;
docs/conventions.md §14): its equations, its conserved quantities over 10⁵ compiled steps,
its independence of the bases of D and D⊥, the role of the metric, and input errors."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from conftest import load_example
from kernel_support import (  # noqa: F401  (module_cache: autouse fixture)
    module_cache,
    module_cache_root,
    needs_cc,
)

import symgroupoid as sg
from symgroupoid.derivation import WindowAction


@pytest.fixture(scope="module")
def example():
    return load_example("nonholonomic_energy_momentum")


def test_equations_are_the_d_and_d_perp_blocks(example):
    """Rows = C(X⃖ − X⃗) on D, then B(X⃖ + X⃗) on D⊥ with B G_c Cᵀ = 0."""
    em, _ = example.systems()
    step = em.euler_lagrange()
    G = em.groupoid
    action = WindowAction(G, em.functions)  # X⃖_b[L](g_k), X⃗_b[L](g_{k+1}), no multipliers
    slots = action.slots("w")
    named = action.naming(slots, action.named_arrows())
    left, right = ([e.xreplace(named) for e in half]
                   for half in action.halves(slots, multipliers=False))
    q = G.target(step.arrows[0])
    sin_y = q[2]
    on_d = [[1, sin_y, 0], [0, 0, 1]]
    on_perp = [[-sin_y, 1, 0]]  # the G_c-orthogonal complement (G_c = I)
    expected = ([sum(c * (a - b) for c, a, b in zip(row, left, right)) for row in on_d]
                + [sum(c * (a + b) for c, a, b in zip(row, left, right)) for row in on_perp])
    assert len(step) == 3 and step.n_constraints == 0
    assert all(sp.expand(a - b) == 0 for a, b in zip(step.residuals, expected))


@needs_cc
def test_energy_and_momentum_are_kept_over_1e5_compiled_steps(example):
    """ż = sin(y)ẋ on R² × S¹: the energy ½‖F⁺L‖² and p_y = ⟨F⁺L, ∂y⟩ stay within 1e-10 of
    their initial values over 10⁵ steps; the D-momentum of ∂x + sin(y)∂z is not conserved
    (not a symmetry), and the conserved quantities say so."""
    em, _ = example.systems()
    cq = em.conserved_quantities()
    assert (cq.energy_check, cq.momentum_checks) == ("numeric", ["fails", "numeric"])
    sim = em.euler_lagrange().compile()
    assert sim.backend == "c"
    p = example.PARAMS
    traj = sim.simulate(example.initial_arrow(p), 100_000, p)
    E, J = cq.evaluate(traj.states, [p["h"]])
    assert np.abs(E - E[0]).max() < 1e-10
    assert np.abs(J[:, 1] - J[0, 1]).max() < 1e-10
    assert np.ptp(J[:, 0]) > 1e-3  # the other D-momentum does change
    assert np.ptp(traj.states[:, 0]) > 1e-4  # the direction of motion turns


def test_holder_method_does_not_keep_the_energy(example):
    """The comparison of the example: over 2·10⁴ steps the Hölder method's energy error is
    > 1e-8 (its discrete constraint is not the momentum-consistent one), the energy–momentum
    method's < 1e-12."""
    _, _, errors = example.run(20_000)
    assert errors["particle_energy_momentum"][0].max() < 1e-12
    assert errors["particle_holder"][0].max() > 1e-8


def test_solutions_do_not_depend_on_the_basis_of_d(example):
    """Another basis of D — unit X₁ + 2X₂ and X₂ − X₁ — gives the same motion."""
    G = example.groupoid()

    def first(q):
        s = q[2]
        norm = sp.sqrt(1 + s**2 + 4)
        return [1 / norm, s / norm, 2 / norm]

    other = sg.NonholonomicSystem(G, example.lagrangian, None,
                                  [first, lambda q: [-1, -q[2], 1]], parameters=[example.h],
                                  method="energy_momentum", metric=sp.eye(3))
    em, _ = example.systems(G)
    p = example.PARAMS
    known = example.initial_arrow(p)
    sims = [s.euler_lagrange().compile() for s in (em, other)]
    a, b = (sim.simulate(known, 50, p).states for sim in sims)
    assert np.abs(a - b).max() < 1e-13


def test_the_metric_defines_the_split_and_the_energy(example):
    """With G_c = diag(1, 4, 1) the complement D⊥ changes, so does the motion; the energy of
    that metric is kept, the Euclidean one is not."""
    G = example.groupoid()
    metric = sp.diag(1, 4, 1)
    other = sg.NonholonomicSystem(G, example.lagrangian, None, example.DISTRIBUTION,
                                  parameters=[example.h], method="energy_momentum",
                                  metric=metric)
    em, _ = example.systems(G)
    p = example.PARAMS
    traj = other.euler_lagrange().compile().simulate(example.initial_arrow(p), 5000, p)
    base = em.euler_lagrange().compile().simulate(example.initial_arrow(p), 5000, p)
    assert np.abs(traj.states - base.states).max() > 1e-6
    own, _ = other.conserved_quantities().evaluate(traj.states, [p["h"]])
    euclid, _ = em.conserved_quantities().evaluate(traj.states, [p["h"]])
    assert np.abs(own - own[0]).max() < 1e-12
    assert np.abs(euclid - euclid[0]).max() > 1e-8


def test_ball_on_a_fixed_table_keeps_energy_and_the_three_d_momenta():
    """The seed's ball (Ω = 0) with G_c = diag(m, m, I, I, I) on the Atiyah groupoid: the
    energy and the momenta of s₅, r s₁ + s₄, r s₂ − s₃ are conserved identities, and from a
    state on M′_c the method coincides with the Hölder one."""
    rb = load_example("rolling_ball_atiyah")
    system = sg.NonholonomicSystem(rb.atiyah_groupoid(), rb.on_atiyah(rb.lagrangian), None,
                                   rb.D_C, parameters=[rb.h, rb.m, rb.inertia, rb.r, rb.Om],
                                   method="energy_momentum",
                                   metric=sp.diag(rb.m, rb.m, rb.inertia, rb.inertia,
                                                  rb.inertia))
    cq = system.conserved_quantities()
    assert cq.energy_conserved and all(cq.momentum_conserved)
    p = dict(rb.PARAMS, Omega=0.0)
    state = rb.initial_state(p)
    traj = system.euler_lagrange().compile().simulate(state, 3000, p)
    E, J = cq.evaluate(traj.states, [p[str(s)] for s in system.parameters])
    assert np.abs(E - E[0]).max() < 1e-10 * E[0]
    assert np.abs(J - J[0]).max() < 1e-10 * np.abs(J[0]).max()
    # started on M′_c, the Hölder method makes the same steps: for the homogeneous sphere
    # F⁺L = F⁻L on every arrow and M′_c is where the D⊥-components of the momentum vanish
    holder = rb.ball(rb.atiyah_groupoid(), rb.on_atiyah).euler_lagrange().compile()
    assert np.abs(holder.simulate(state, 3000, p).states - traj.states).max() < 1e-10


def test_input_errors(example):
    G = example.groupoid()
    kw = dict(parameters=[example.h], method="energy_momentum")
    L, D = example.lagrangian, example.DISTRIBUTION
    with pytest.raises(ValueError, match="needs metric=G_c"):
        sg.NonholonomicSystem(G, L, None, D, **kw)
    with pytest.raises(sg.ShapeError, match="no discrete constraint submanifold"):
        sg.NonholonomicSystem(G, L, example.discrete_constraint, D, metric=sp.eye(3), **kw)
    with pytest.raises(ValueError, match="not symmetric"):
        sg.NonholonomicSystem(G, L, None, D, metric=[[1, 1, 0], [0, 1, 0], [0, 0, 1]], **kw)
    with pytest.raises(ValueError, match="not positive definite"):
        sg.NonholonomicSystem(G, L, None, D, metric=sp.diag(1, -1, 1), **kw)
    with pytest.raises(sg.ShapeError, match="the algebroid has rank 3"):
        sg.NonholonomicSystem(G, L, None, D, metric=sp.eye(2), **kw)
    with pytest.raises(sg.ShapeError, match="linearly dependent"):
        sg.NonholonomicSystem(G, L, None, [[1, 0, 0], [2, 0, 0]], metric=sp.eye(3), **kw)
    with pytest.raises(sg.ShapeError, match="between 1 and rank"):
        sg.NonholonomicSystem(G, L, None, [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
                              metric=sp.eye(3), **kw)
    with pytest.raises(ValueError, match="method must be one of"):
        sg.NonholonomicSystem(G, L, None, D, parameters=[example.h], method="rattle")


def test_undeclared_symbols_in_the_metric_or_the_distribution(example):
    """(A symbol neither a parameter nor the base point's, in G_c or in D, passed the
    constructor and escaped from euler_lagrange() as a bare ValueError of the program.)"""
    G = example.groupoid()
    L, D = example.lagrangian, example.DISTRIBUTION
    stray = sp.Symbol("zz", positive=True)
    with pytest.raises(sg.UndeclaredSymbolError, match="metric uses symbol.* zz"):
        sg.NonholonomicSystem(G, L, None, D, parameters=[example.h], method="energy_momentum",
                              metric=sp.diag(stray, 1, 1))
    bad = [lambda q: [1, q[2] * stray, 0], [0, 0, 1]]
    for method, metric, constraints in (("energy_momentum", sp.eye(3), None),
                                        ("holder", None, example.discrete_constraint)):
        with pytest.raises(sg.UndeclaredSymbolError, match="distribution element 0 .*zz"):
            sg.NonholonomicSystem(G, L, constraints, bad, parameters=[example.h],
                                  method=method, metric=metric)
