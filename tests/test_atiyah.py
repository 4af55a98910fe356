"""Atiyah groupoids (Q × Q)/H ⇉ S (seed 002; docs/conventions.md §13): structure maps derived
from Q and H (left and right actions, connection-adapted chart), the quotient map, Elroy's
beanie reduced by SE(2), and the ball on a rotating table on (R² × SO(3))²/SO(3)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from _lie_pairs import LieGroupPair
from conftest import load_example
from kernel_support import isolated_cache  # noqa: F401  (isolated_cache: autouse fixture)

import symgroupoid as sg

ROOT = Path(__file__).resolve().parents[1]


def _beanie_atiyah(c):
    return sg.AtiyahGroupoid((sg.SE2("g"), sg.EuclideanSpace("psi")), sg.SE2,
                             connection=lambda s0, s1: (c * (s1[0] - s0[0]), 0, 0))


def test_locked_frame_product_is_the_seeds_twisted_product():
    """(ψ₀, ψ₁, u, Ω₃)(ψ₁, ψ₂, u′, Ω₃′) = (ψ₀, ψ₂, u + R(Ω₃ − cΔψ)u′, Ω₃ + Ω₃′), derived
    from 𝒜(ψ₀, ψ₁) = exp(c(ψ₁ − ψ₀)E_θ) with c symbolic."""
    c = sp.Symbol("c", positive=True)
    A = _beanie_atiyah(c)
    rng = np.random.default_rng(0)
    for cv in (0.3, 0.8):
        for _ in range(4):
            a = A.random_arrow(rng)
            b = A.random_arrow(rng, A.target(a))
            ab = np.array([float(sp.sympify(v).subs(c, cv)) for v in A.multiply(a, b)])
            om, om2 = np.arctan2(a[5], a[2]), np.arctan2(b[5], b[2])
            ang = om - cv * (a[1] - a[0])
            R = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
            u = np.array([a[4], a[7]]) + R @ np.array([b[4], b[7]])
            expected = [a[0], b[1], np.cos(om + om2), -np.sin(om + om2), u[0],
                        np.sin(om + om2), np.cos(om + om2), u[1]]
            assert np.allclose(ab, expected, atol=1e-13)


@pytest.mark.parametrize("action,twisted", [("left", True), ("right", False)])
def test_groupoid_axioms(action, twisted):
    """The other two of (left, right) × (twisted, not): the registry's groupoids
    (test_groupoid_properties.py) hold left untwisted and right twisted."""
    connection = (lambda s0, s1: (0.3 * (s1[0] - s0[0]) + 0.1 * (s1[1] ** 2 - s0[1] ** 2),
                                  0.2 * (s1[1] - s0[1]), 0)) if twisted else None
    A = sg.AtiyahGroupoid((sg.EuclideanSpace("x y"), sg.SO3("W")), sg.SO3, action=action,
                          connection=connection)
    assert (A.base_dim, A.rank, A.arrow_dim) == (2, 5, 13)
    sg.check_axioms(A, samples=3)


@pytest.mark.parametrize("action", ["left", "right"])
def test_orbits_compose_and_invert(action):
    """[(q₀, q₁)][(q₁, q₂)] = [(q₀, q₂)] and [(q₀, q₁)]⁻¹ = [(q₁, q₀)], with W = h₀⁻¹h₁ (left)
    or h₁h₀⁻¹ (right)."""
    A = sg.AtiyahGroupoid((sg.SO3("W"), sg.EuclideanSpace("s")), sg.SO3, action=action,
                          connection=lambda s0, s1: (0, 0, 0.4 * (s1[0] - s0[0])))
    rng = np.random.default_rng(1)
    K = sg.SO3("t")

    def point():
        R = K.fibre_chart([sp.Float(v) for v in rng.uniform(-1, 1, 3)])
        return tuple(float(v) for v in R) + (float(rng.uniform(-1, 1)),)

    def num(v):
        return np.array([float(x) for x in v])

    q0, q1, q2 = point(), point(), point()
    a, b = A.orbit(q0, q1), A.orbit(q1, q2)
    assert np.allclose(num(A.multiply(a, b)), num(A.orbit(q0, q2)), atol=1e-13)
    assert np.allclose(num(A.inverse(a)), num(A.orbit(q1, q0)), atol=1e-13)
    h0, h1 = (np.array(q[:9]).reshape(3, 3) for q in (q0, q1))
    W = h0.T @ h1 if action == "left" else h1 @ h0.T
    increment = np.array(A.view(a).increment.evalf().tolist(), float)
    assert np.allclose(increment, W, atol=1e-13)
    assert np.allclose(num(A.configuration_after(q0, a)), q1, atol=1e-13)


def test_quotient_map_is_a_morphism_with_symbolic_parameters():
    """π of Elroy's beanie with c symbolic: Def. 4.1 holds for random values of c; the
    section σ pulls back to a right inverse, Φ∘σ = id."""
    c = sp.Symbol("c", positive=True)
    A = _beanie_atiyah(c)
    P = LieGroupPair(sg.SE2, point="q") * sg.PairGroupoid(sg.EuclideanSpace("psi"))
    pi = A.quotient_map_from(P)
    assert pi.parameters == [c] and pi.has_section
    sg.check_morphism(pi)
    rng = np.random.default_rng(2)
    a = A.random_arrow(rng)
    back = [float(sp.sympify(v).subs(c, 0.7)) for v in pi(pi.section(a))]
    assert np.allclose(back, [float(sp.sympify(v).subs(c, 0.7)) for v in a], atol=1e-13)


def test_construction_errors_name_the_problem():
    with pytest.raises(sg.ShapeError, match="exactly one factor of the acting group SE2"):
        sg.AtiyahGroupoid((sg.SO3("W"), sg.EuclideanSpace("x")), sg.SE2)
    with pytest.raises(sg.ShapeError, match="found 2"):
        sg.AtiyahGroupoid((sg.SO3("W"), sg.SO3("V")), sg.SO3)
    with pytest.raises(TypeError, match="shape space must be a product of EuclideanSpaces"):
        sg.AtiyahGroupoid((sg.SO3("W"), sg.SE2("g")), sg.SO3)
    with pytest.raises(ValueError, match="action must be one of"):
        sg.AtiyahGroupoid((sg.SO3("W"),), sg.SO3, action="both")
    with pytest.raises(ValueError, match="𝒜\\(s, s\\) = I"):
        sg.AtiyahGroupoid((sg.SO3("W"), sg.EuclideanSpace("s")), sg.SO3,
                          connection=lambda s0, s1: (0, 0, s1[0] + s0[0]))
    with pytest.raises(sg.ShapeError, match="Lie-algebra coordinates"):
        sg.AtiyahGroupoid((sg.SO3("W"), sg.EuclideanSpace("s")), sg.SO3,
                          connection=lambda s0, s1: (s1[0] - s0[0],))
    with pytest.raises(sg.CallableError, match="the connection raised"):
        sg.AtiyahGroupoid((sg.SO3("W"), sg.EuclideanSpace("s")), sg.SO3,
                          connection=lambda s0, s1: s0[5])
    A = _beanie_atiyah(0.5)
    with pytest.raises(sg.ShapeError, match="pair groupoid's base has 2 coordinates"):
        A.quotient_map_from(sg.PairGroupoid(sg.EuclideanSpace("x y")))


def test_atiyah_of_a_group_by_itself_is_the_group():
    """(H × H)/H ⇉ point: the same step equations as the Lie group H."""
    from symgroupoid import systems

    rb = systems.rigid_body()
    A = sg.AtiyahGroupoid((sg.SO3("W"),), sg.SO3)
    assert (A.base_dim, A.rank) == (0, 3)
    reduced = sg.DiscreteSystem(A, rb.lagrangian, parameters=rb.parameters)
    got, expected = reduced.euler_lagrange().residuals, rb.euler_lagrange().residuals
    assert all(sp.expand(a - b) == 0 for a, b in zip(got, expected))


@pytest.mark.slow
def test_elroys_beanie_reduced_trajectory_is_the_reduction_of_the_unreduced_one():
    """Compiled kernels: the reduced trajectory equals π of the unreduced one to 1e-12; it
    satisfies the discrete Lagrange–Poincaré equations with the rotation angle cΔψ − Ω₃ (the
    seed's printed +(Ω₃ + cΔψ) fails); the I₂ printing of the continuous equations is the
    limit; the reconstruction from it is the unreduced trajectory."""
    eb = load_example("elroys_beanie")
    full, pi, reduced = eb.systems()
    params, steps = eb.PARAMS, 300
    traj = full.euler_lagrange().compile().simulate(eb.initial_state(), steps, params)
    projected = reduced.project(traj, params)
    run = reduced.euler_lagrange().compile().simulate(projected[0], steps, params)
    assert np.abs(run.states - projected).max() < 1e-12
    assert np.ptp(projected[:, 4]) > 0.1  # the bodies translate
    right = eb.lagrange_poincare_defects(run.states, params)
    assert max(right.values()) < 1e-13
    assert eb.lagrange_poincare_defects(run.states, params, printed=True)["Omega_12"] > 1e-4
    ok, misprint = eb.continuous_defects(run.states, params)
    assert ok < 0.05 * misprint
    back = reduced.reconstruct(run, traj.states[0], params)
    assert np.abs(back - traj.states).max() < 1e-10
    # the printed equations are those of the derived step, in LaTeX
    tex = reduced.euler_lagrange().latex()
    assert "\\psi_{k+1}" in tex and "(g_{k+1})_{13}" in tex


@pytest.mark.slow
def test_elroys_beanie_kernel_is_deterministic_and_strict_c99(tmp_path):
    """The reduced step's C code is byte-identical under different hash seeds and compiles as
    strict C99 (nothing about the Atiyah groupoid is special-cased in code generation)."""
    eb = load_example("elroys_beanie")
    here = tmp_path / "here" / "beanie"
    here.parent.mkdir()
    eb.systems()[2].euler_lagrange().emit_c(here)
    script = ("import sys; sys.path.insert(0, 'examples'); import elroys_beanie as eb; "
              "_, _, r = eb.systems(); r.euler_lagrange().emit_c(sys.argv[1])")
    seed = "987" if os.environ.get("PYTHONHASHSEED") != "987" else "1"
    there = tmp_path / "there" / "beanie"
    there.parent.mkdir()
    subprocess.run([sys.executable, "-c", script, str(there)], check=True, cwd=ROOT,
                   env=dict(os.environ, PYTHONHASHSEED=seed, PYTHONPATH=str(ROOT)))
    outs = [here, there]
    for ext in (".c", ".h"):
        a, b = (Path(str(o) + ext).read_bytes() for o in outs)
        assert a == b
    if shutil.which("cc"):
        result = subprocess.run(["cc", "-std=c99", "-pedantic", "-O2", "-Wall", "-Wextra",
                                 "-Werror", "-c", str(outs[0]) + ".c", "-o",
                                 str(tmp_path / "beanie.o")], capture_output=True, text=True)
        assert result.returncode == 0, result.stderr


def test_rolling_ball_on_the_atiyah_groupoid_satisfies_the_printed_equations():
    """The seed's ball on a rotating table on (R² × SO(3))²/SO(3) (right action): the compiled
    trajectory satisfies the printed equations, and equals the one of the same equations on
    R² × R² × SO(3) with the product W W′."""
    rb = load_example("rolling_ball_atiyah")
    params, steps = rb.PARAMS, 3000
    state = rb.initial_state(params)
    step = rb.ball(rb.atiyah_groupoid(), rb.on_atiyah).euler_lagrange()
    traj = step.compile().simulate(state, steps, params)
    assert rb.printed_defects(traj.states, traj["x"], traj["y"], params) < 1e-13
    product = sg.PairGroupoid(sg.EuclideanSpace("x y")) * sg.SO3("W")
    other = rb.ball(product, rb.on_product).euler_lagrange().compile()
    assert np.abs(other.simulate(state, steps, params).states - traj.states).max() < 1e-12


def test_quotient_map_property_builds_on_the_pair_groupoid_of_q():
    """``A.quotient_map`` is π on ``PairGroupoid(Q)``; where the pair groupoid of Q cannot be
    built, the error says to use ``quotient_map_from``."""
    A = sg.AtiyahGroupoid(sg.SO3("W"), sg.SO3)
    try:
        sg.PairGroupoid(A.configuration_space)
    except (TypeError, ValueError):
        with pytest.raises(TypeError, match="quotient_map_from"):
            A.quotient_map  # noqa: B018
    else:
        sg.check_morphism(A.quotient_map, samples=2)


def test_q_with_a_shape_space_in_every_form():
    """(Q = EuclideanSpace("s") * SO3("R") was refused, "found 0" factors of SO3: the group
    was wrapped as a factor of a product manifold; and with Q given as a tuple of factors
    ``quotient_map`` could not build PairGroupoid(Q).)  The product in either order and the
    tuple give the same Atiyah groupoid, and π is a morphism."""
    forms = [sg.EuclideanSpace("s") * sg.SO3("R"), (sg.EuclideanSpace("s"), sg.SO3("R"))]
    for Q in forms:
        A = sg.AtiyahGroupoid(Q, sg.SO3)
        assert A.shape_space.names == ("s",) and A.configuration_dim == 10
        sg.check_morphism(A.quotient_map, samples=2)
    A = sg.AtiyahGroupoid(sg.SO3("R") * sg.EuclideanSpace("s"), sg.SO3)
    sg.check_morphism(A.quotient_map, samples=2)
