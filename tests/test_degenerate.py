"""Degenerate systems are caught when their equations are derived, never stepped.

A step F(u; k, p) = 0 determines its unknowns only where ∂F/∂u is invertible (seed 000
Thm 2.16: L regular; docs/conventions.md §4).  ``euler_lagrange()`` (and ``lie_poisson()``)
raise :class:`DegenerateSystemError` naming the equations or unknowns involved and the cause:
null Lagrangians (all DEL identically zero), constraints that vanish identically, equations
without unknowns, unknowns in no equation, multipliers that no equation determines (a
constraint on the arrow's target only), dependent constraints, and Lagrangians that are not
regular — on first-order, second-order, nonholonomic and Lie–Poisson steps.  Valid systems,
including badly scaled ones and ones that are not finite at some points, are not rejected.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg

# the causes are public; _sampling and default_layout are not: the diagnosis's numeric
# sampling (its points, what counts as evidence) is checked directly, below what
# euler_lagrange() shows, and has no public face
from symgroupoid.equations import (
    DEPENDENT_CONSTRAINTS,
    IDENTICALLY_ZERO,
    NO_UNKNOWN,
    NOT_REGULAR,
    UNDETERMINED_MULTIPLIER,
    UNUSED_UNKNOWN,
    _sampling,
)
from symgroupoid.equations._findings import default_layout
from symgroupoid.systems import discrete_inertia, heavy_top, plate_ball, rigid_body

h, a, ell = sp.symbols("h a ell", positive=True)
I1, I2, I3 = sp.symbols("I1 I2 I3", positive=True)
DEL1 = "equation 1 (the DEL along X_1)"


def pair(names: str = "q") -> sg.PairGroupoid:
    return sg.PairGroupoid(sg.EuclideanSpace(names))


def kinetic(g) -> sp.Expr:
    """(h/2)|(q₁ − q₀)/h|², regular."""
    return sum((b - c) ** 2 for c, b in zip(g.source, g.target)) / (2 * h)


def degenerate(make) -> sg.DegenerateSystemError:
    """The error raised by ``make().euler_lagrange()``."""
    with pytest.raises(sg.DegenerateSystemError) as info:
        make().euler_lagrange()
    return info.value


def line(lagrangian, **kwargs) -> sg.DiscreteSystem:
    kwargs.setdefault("parameters", [h, a])
    return sg.DiscreteSystem(pair(), lagrangian, name="line", **kwargs)


# --- null Lagrangians: every DEL is 0 = 0 --------------------------------------------------------

NULL_LAGRANGIANS = {
    "(q1^2 - q0^2)/2h": lambda g: (g.target[0] ** 2 - g.source[0] ** 2) / (2 * h),
    "a (q1 - q0)/h": lambda g: a * (g.target[0] - g.source[0]) / h,
    "python float": lambda g: 1.5,
    "numpy scalar": lambda g: np.float64(1.5),
    "sympy number": lambda g: sp.Rational(3, 2),
    "zero": lambda g: 0,
}


@pytest.mark.parametrize("case", sorted(NULL_LAGRANGIANS))
def test_null_lagrangian_is_rejected(case: str) -> None:
    """A null Lagrangian (constant or a difference f(β(g)) − f(α(g))) has DEL 0 = 0: the
    error says so, names the equation and the cause, and lists the finding."""
    err = degenerate(lambda: line(NULL_LAGRANGIANS[case]))
    assert err.causes == (IDENTICALLY_ZERO,)
    assert str(err).startswith("line: the step equations cannot determine the step")
    assert f"{DEL1} reads 0 = 0" in str(err)
    assert "null Lagrangian" in str(err)
    assert err.findings[0].equations == (DEL1,)


def test_rigid_body_with_zero_inertia() -> None:
    """The Moser–Veselov L = −tr(J_d W)/h with I = 0 is L = 0: all three DEL vanish; the
    Lie–Poisson reconstruction (μ(g_{k+1}) = m_{k+1}) has no unknown in any equation."""
    Jd = discrete_inertia(0, 0, 0)
    system = sg.DiscreteSystem(sg.SO3("W"), lambda g: -(Jd * g.matrix).trace() / h,
                               parameters=[h], name="rigid_body")
    err = degenerate(lambda: system)
    assert err.causes == (IDENTICALLY_ZERO,)
    assert "equation 3 (the DEL along X_3)" in str(err) and "zero inertia" in str(err)
    with pytest.raises(sg.DegenerateSystemError,
                       match="^rigid_body_reconstruction: .*enter no equation") as lp:
        system.lie_poisson()
    assert UNUSED_UNKNOWN in lp.value.causes
    assert len(lp.value.findings[-1].unknowns) == 3


def test_heavy_top_with_zero_inertia() -> None:
    """Action groupoid: with I = 0 only the potential −h m g l Γ·e is left; its DEL involve the
    known Γ_{k+1} = W_kᵀ Γ_k but not the unknown W_{k+1}."""
    mgl = sp.Symbol("mgl", positive=True)
    G = sg.ActionGroupoid(sg.EuclideanSpace.vector("Gamma", 3), sg.SO3("W"),
                          lambda p, W: tuple(W.T * sp.Matrix(p)))
    Jd = discrete_inertia(0, 0, 0)
    err = degenerate(lambda: sg.DiscreteSystem(
        G, lambda g: -(Jd * g.matrix).trace() / h - h * mgl * g.point[2],
        parameters=[h, mgl], name="top"))
    assert UNUSED_UNKNOWN in err.causes
    assert all(f"(\\tau^{{-1}} W_{{k+1}})_{{{i}}}" in str(err) for i in (1, 2, 3))


# --- non-finite and complex expressions ----------------------------------------------------------

@pytest.mark.parametrize("lagrangian, message", [
    (lambda g: sp.nan, r"the Lagrangian is nan \(not a number\)$"),
    (lambda g: float("nan") * g.target[0], r"the Lagrangian is nan"),
    (lambda g: kinetic(g) + float("inf"), r"the Lagrangian is oo \(infinity\)$"),
    (lambda g: kinetic(g) - np.float64("inf"), r"the Lagrangian is -oo \(minus infinity\)$"),
    (lambda g: kinetic(g) + sp.zoo * g.target[0],
     r"the Lagrangian contains zoo \(complex infinity\) in the term zoo\*q_\{k\}$"),
    (lambda g: kinetic(g) + sp.I * g.source[0],
     r"the Lagrangian contains I \(the imaginary unit.*\) in the term I\*q_\{k-1\}$"),
    (lambda g: kinetic(g) + sp.log(-2) * g.target[0],
     r"the Lagrangian contains I .* in the term q_\{k\}\*\(log\(2\) \+ I\*pi\)$"),
    (lambda g: kinetic(g) + np.complex128(1j) * g.target[0],
     r"the Lagrangian contains I .* in the term 1\.0\*I\*q_\{k\}$"),
])
def test_non_finite_or_complex_lagrangian_rejected_at_construction(lagrangian,
                                                                   message: str) -> None:
    """nan, ±oo, zoo and I (also from Python/NumPy floats) are rejected when the system is
    constructed, naming the value and the term of L that contains it."""
    with pytest.raises(sg.InvalidExpressionError, match=r"^line: " + message):
        line(lagrangian)


def test_non_finite_constraint_names_its_entry() -> None:
    """In a constraint list the entry is named."""
    with pytest.raises(sg.InvalidExpressionError,
                       match=r"^line: the constraints \(entry 1\) is nan \(not a number\)$"):
        line(kinetic, constraints=lambda g: [g.target[0] - g.source[0],
                                             g.target[0] + np.float64("nan") * g.source[0]])
    with pytest.raises(sg.InvalidExpressionError,
                       match=r"^line: the constraints \(entry 0\) contains oo \(infinity\) in "
                             r"the term oo\*q_\{k\}$"):
        line(kinetic, constraints=lambda g: [g.source[0] + sp.oo * g.target[0]])


def test_imaginary_unit_that_cancels_is_accepted() -> None:
    """(q + i)(q − i) = q² + 1 is real: only an I that survives expansion is rejected."""
    step = line(lambda g: kinetic(g) + (g.target[0] + sp.I) * (g.target[0] - sp.I)
                ).euler_lagrange()
    assert not any(r.has(sp.I) for r in step.residuals)


# --- constraints ---------------------------------------------------------------------------------

def plane(constraints, names: str = "x y", **kwargs) -> sg.DiscreteSystem:
    return sg.DiscreteSystem(pair(names), kinetic, constraints=constraints, parameters=[h, ell],
                             name="plane", **kwargs)


@pytest.mark.parametrize("zero", [lambda g: 0 * g.target[0], lambda g: sp.S.Zero,
                                  lambda g: g.target[0] - g.target[0]])
def test_identically_zero_constraint(zero) -> None:
    """A constraint that is identically 0 constrains nothing and leaves its multiplier
    undetermined; the error names the constraint and the multiplier."""
    err = degenerate(lambda: plane(lambda g: [g.target[0] - g.source[0] - h, zero(g)]))
    assert err.causes == (IDENTICALLY_ZERO,)
    assert "The constraint φ_2 is identically zero" in str(err)
    assert err.findings[0].equations == ("equation 4 (φ_2 = 0)",)
    assert err.findings[0].unknowns == ("(\\lambda_{k+1})_{2}",)


@pytest.mark.parametrize("factor", [1, 2, -sp.Rational(1, 3)])
def test_duplicate_constraints_are_dependent(factor) -> None:
    """φ₂ = c·φ₁: the constraint rows of the Jacobian are dependent; the message names
    φ_1 and φ_2 and does not blame the Lagrangian."""
    err = degenerate(lambda: plane(
        lambda g: [g.target[0] - g.source[0] - h, factor * (g.target[0] - g.source[0] - h)],
        names="x y z"))
    assert err.causes == (DEPENDENT_CONSTRAINTS,)
    assert "constraints φ_1 and φ_2 are dependent" in str(err)
    assert "not regular" not in str(err)
    assert set(err.findings[0].unknowns) == {"(\\lambda_{k+1})_{1}", "(\\lambda_{k+1})_{2}"}


def test_one_constraint_the_sum_of_two_others() -> None:
    """φ₃ = φ₁ + φ₂ with φ₄ independent: exactly φ_1, φ_2, φ_3 are named."""
    def phi(g):
        (x0, y0, z0, _), (x1, y1, z1, w1) = g.source, g.target
        f1, f2 = x1 - x0 - h, y1 * y0 - 1
        return [f1, f2, f1 + f2, z1 - z0 + w1]

    err = degenerate(lambda: sg.DiscreteSystem(pair("x y z w"), kinetic, constraints=phi,
                                               parameters=[h], name="four"))
    assert err.causes == (DEPENDENT_CONSTRAINTS,)
    assert "constraints φ_1, φ_2 and φ_3 are dependent" in str(err)


def test_target_only_constraint_leaves_its_multiplier_undetermined() -> None:
    """φ = |q₁|² − ℓ² depends only on β(g): X⃗[φ] = 0, so λ_{k+1} enters no equation.  The
    message names the multiplier and points to the holonomic= argument."""
    err = degenerate(lambda: plane(lambda g: [g.target[0] ** 2 + g.target[1] ** 2 - ell**2]))
    assert err.causes == (UNDETERMINED_MULTIPLIER,)
    assert err.findings[0].unknowns == ("(\\lambda_{k+1})_{1}",)
    text = str(err)
    assert "(\\lambda_{k+1})_{1} of φ_1 enters no equation" in text
    assert "depends only on the target β(g)" in text
    assert "DiscreteSystem(..., holonomic=lambda q: [...])" in text
    assert "later version" not in text and "docs/conventions.md §15" in text
    assert "not regular" not in text


def test_target_only_combination_of_constraints() -> None:
    """φ₁ − φ₂ = |q₁|² − 1 is a target-only combination: the multiplier columns are
    dependent (found numerically), both multipliers are named."""
    err = degenerate(lambda: plane(lambda g: [
        g.target[0] ** 2 + g.target[1] ** 2 - 1 + (g.target[0] - g.source[0]),
        g.target[0] - g.source[0]]))
    assert err.causes == (UNDETERMINED_MULTIPLIER,)
    assert "multipliers (\\lambda_{k+1})_{1} and (\\lambda_{k+1})_{2} of φ_1 and φ_2" in str(err)


def test_difference_form_of_a_target_constraint_is_regular_and_keeps_it() -> None:
    """The form the message suggests, φ = ψ(β(g)) − ψ(α(g)), derives a regular step and keeps
    ψ(q) = |q|² − ℓ² at 0 along a simulated pendulum (Marsden–West holonomic DEL with
    multiplier λ_k − λ_{k+1})."""
    def psi(q):
        return q[0] ** 2 + q[1] ** 2 - ell**2

    system = sg.DiscreteSystem(
        pair("x y"), lambda g: kinetic(g) - h * g.target[1],
        constraints=lambda g: [psi(g.target) - psi(g.source)], parameters=[h, ell],
        name="pendulum")
    sim = system.euler_lagrange().compile(backend="numpy")
    th0, th1 = 0.3, 0.31
    traj = sim.simulate({"x": (np.sin(th0), np.sin(th1)), "y": (-np.cos(th0), -np.cos(th1)),
                         "lambda": [0.0]}, steps=40, params={"h": 0.05, "ell": 1.0})
    radius = traj["x"] ** 2 + traj["y"] ** 2
    assert np.max(np.abs(radius - 1.0)) < 1e-10
    assert np.max(np.abs(traj["x"])) > 0.2  # it swings


# --- equations without unknowns, unknowns without equations --------------------------------------

def test_lagrangian_of_the_source_only() -> None:
    """L(q₀): the DEL 2q_k = 0 involves no unknown and q_{k+1} enters no equation; the message
    says exactly that (it is not blamed on regularity)."""
    err = degenerate(lambda: line(lambda g: g.source[0] ** 2))
    assert err.causes == (NO_UNKNOWN, UNUSED_UNKNOWN)
    text = str(err)
    assert "(1) Equation 1 (the DEL along X_1) involves none of the unknowns (2*q_{k} = 0)" in text
    assert "(2) The unknown q_{k+1} enters no equation" in text
    assert "not regular" not in text


def test_coordinate_missing_from_the_lagrangian() -> None:
    """L = (x₁ − x₀)²/2h on R²: nothing involves y; found as an equation without unknowns
    and the unknown y_{k+1} in no equation."""
    err = degenerate(lambda: sg.DiscreteSystem(
        pair("x y"), lambda g: (g.target[0] - g.source[0]) ** 2 / (2 * h), parameters=[h]))
    assert err.findings[0].cause == IDENTICALLY_ZERO
    assert "(1) Equation 2 (the DEL along X_2) reads 0 = 0" in str(err)
    assert "y_{k+1} enters no equation" in str(err)


# --- numerically singular: not regular -----------------------------------------------------------

def test_lagrangian_that_is_not_regular() -> None:
    """L = ((x₁ − x₀) + (y₁ − y₀))²/2h: the Jacobian has rank 1 at every point; both DEL and
    both unknowns are named and the cause is the Lagrangian's regularity."""
    err = degenerate(lambda: sg.DiscreteSystem(
        pair("x y"), lambda g: (sum(g.target) - sum(g.source)) ** 2 / (2 * h), parameters=[h],
        name="sheared"))
    assert err.causes == (NOT_REGULAR,)
    f = err.findings[0]
    assert f.equations == (DEL1, "equation 2 (the DEL along X_2)")
    assert f.unknowns == ("x_{k+1}", "y_{k+1}")
    assert "rank 1 of 2" in str(err) and "not regular (seed 000 Thm 2.16)" in str(err)


@pytest.mark.parametrize("system", ["trig identity", "tr(WᵀW) on SO(3)"])
def test_numerically_zero_equations(system: str) -> None:
    """Residuals that are not syntactically 0 but vanish (sin² + cos² − 1; tr(WᵀW) = 3 on
    SO(3)) are found numerically: rounding noise is told from small genuine values by how
    it changes under a tiny move of the point."""
    if system == "trig identity":
        def make():
            return line(lambda g: (g.target[0] - g.source[0]) ** 2 * (
                sp.sin(g.source[0]) ** 2 + sp.cos(g.source[0]) ** 2 - 1))
    else:
        def make():
            return sg.DiscreteSystem(sg.SO3("W"), lambda g: (g.matrix.T * g.matrix).trace())
    step_residuals = make()._fs.lagrangian
    assert step_residuals != 0
    err = degenerate(make)
    assert err.causes == (IDENTICALLY_ZERO,)


# --- valid systems are not rejected --------------------------------------------------------------

@pytest.mark.parametrize("make", [plate_ball, heavy_top, rigid_body])
def test_seed_systems_pass(make) -> None:
    """The seed systems derive: the diagnosis finds nothing."""
    step = make().euler_lagrange()
    assert _sampling.numeric_findings(step, default_layout(step)) == []


def test_badly_scaled_valid_system_passes() -> None:
    """A Lagrangian with a coefficient 1e-34 in one direction is regular: small is not
    zero."""
    step = sg.DiscreteSystem(pair("x y"), lambda g: 1e-34 * (g.target[0] - g.source[0]) ** 2
                             + (g.target[1] - g.source[1]) ** 2).euler_lagrange()
    assert len(step.unknowns) == 2
    sg.DiscreteSystem(sg.SO3("W"), lambda g: -1e-34 * (sp.diag(1, 2, 3) * g.matrix).trace()
                      ).euler_lagrange()


def test_ill_conditioned_valid_system_passes() -> None:
    """A stiff penalty 10⁸·((x₁ − x₀) + (y₁ − y₀))² on top of a kinetic energy is regular
    (condition number ~10⁹ after equilibration): only a numerically exact rank deficiency
    (σ_min/σ_max below 10⁻¹²; rounding gives ~10⁻¹⁷) counts as singular."""
    step = sg.DiscreteSystem(pair("x y"), lambda g: kinetic(g) + 1e8 * (
        sum(g.target) - sum(g.source)) ** 2, parameters=[h]).euler_lagrange()
    assert len(step.unknowns) == 2


def test_points_where_the_step_is_not_finite_are_no_evidence() -> None:
    """L + √(q₁ − 5) is not finite at the sampled points (q ∈ (−1, 1)): nothing is concluded
    and the (valid, for q > 5) system derives; a degenerate one is still caught
    structurally."""
    step = line(lambda g: kinetic(g) + sp.sqrt(g.target[0] - 5)).euler_lagrange()
    assert _sampling.sample(step, 3, 0) == []
    with pytest.raises(sg.DegenerateSystemError):
        line(lambda g: sp.sqrt(g.target[0] - 5) - sp.sqrt(g.source[0] - 5)).euler_lagrange()


def test_abstract_lagrangian_is_not_evaluated() -> None:
    """An undefined function L_d(q₀, q₁) cannot be evaluated numerically: only the structural
    checks apply."""
    F = sp.Function("L_d")
    step = sg.DiscreteSystem(pair(), lambda g: F(*g.coords)).euler_lagrange()
    assert not _sampling.numeric(step)


def test_diagnosis_is_deterministic() -> None:
    """Fixed seed: the same system gives the same findings."""
    def make():
        return sg.DiscreteSystem(pair("x y"), lambda g: (sum(g.target) - sum(g.source)) ** 2,
                                 name="sheared")
    assert str(degenerate(make)) == str(degenerate(make))


# --- second order --------------------------------------------------------------------------------

def second(lagrangian, constraints=None, names: str = "x y") -> sg.SecondOrderSystem:
    return sg.SecondOrderSystem(pair(names), lagrangian, constraints=constraints,
                                parameters=[h, ell], name="second")


def acceleration(g1, g2) -> sp.Expr:
    """|q₂ − 2q₁ + q₀|²/(2h³): a regular second-order Lagrangian."""
    return sum((c - 2 * b + a0) ** 2 for a0, b, c in zip(g1.source, g1.target, g2.target)) / (
        2 * h**3)


def test_second_order_null_lagrangian() -> None:
    """L(g₁, g₂) = f(q₂) − f(q₀) is null on G₂."""
    err = degenerate(lambda: second(lambda g1, g2: g2.target[0] ** 3 - g1.source[0] ** 3))
    assert err.causes[0] == IDENTICALLY_ZERO
    assert "the DEL along X_1" in str(err)


def test_first_order_lagrangian_as_second_order() -> None:
    """L(g₁, g₂) = L₁(g₁) does not involve g_{k+2}: its coordinates enter no equation."""
    err = degenerate(lambda: second(lambda g1, g2: kinetic(g1)))
    assert UNUSED_UNKNOWN in err.causes
    assert "x_{k+2} and y_{k+2} enter no equation" in str(err)


def test_second_order_target_only_constraint() -> None:
    """Φ(g₁, g₂) = |β(g₂)|² − ℓ²: λ_{k+1} enters no equation (second order, seed 001
    eq. (18)); the holonomic form is named, the first-order workaround is not."""
    err = degenerate(lambda: second(
        acceleration, lambda g1, g2: [g2.target[0] ** 2 + g2.target[1] ** 2 - ell**2]))
    assert err.causes == (UNDETERMINED_MULTIPLIER,)
    assert "(\\lambda_{k+1})_{1} of Φ_1 enters no equation" in str(err)
    assert "holonomic=lambda q" in str(err) and "ψ(β(g)) − ψ(α(g))" not in str(err)


def test_second_order_dependent_constraints() -> None:
    """Φ₂ = 2Φ₁ on G₂."""
    def phi(g1, g2):
        f = g2.target[0] - 2 * g1.target[0] + g1.source[0] + h * g2.target[1]
        return [f, 2 * f]

    err = degenerate(lambda: second(acceleration, phi, names="x y z"))
    assert err.causes == (DEPENDENT_CONSTRAINTS,)
    assert "constraints Φ_1 and Φ_2 are dependent" in str(err)


def test_second_order_regular_system_passes() -> None:
    step = second(acceleration).euler_lagrange()
    assert step.order == 2


# --- nonholonomic --------------------------------------------------------------------------------

def nonholonomic(lagrangian, constraints, distribution) -> sg.NonholonomicSystem:
    return sg.NonholonomicSystem(pair("x y z"), lagrangian, constraints, distribution,
                                 parameters=[h], name="nh")


def test_nonholonomic_dependent_constraints() -> None:
    """ψ₂ = 3ψ₁ defining M_c: the constraint rows are dependent (docs/conventions.md §10)."""
    def psi(g):
        f = g.target[2] - g.source[2] - h * (g.target[0] - g.source[0])
        return [f, 3 * f]

    err = degenerate(lambda: nonholonomic(kinetic, psi, [[0, 1, 0]]))
    assert err.causes == (DEPENDENT_CONSTRAINTS,)
    assert "constraints ψ_1 and ψ_2 are dependent" in str(err)
    assert "equation 2 (ψ_1 = 0)" in err.findings[0].equations


def test_nonholonomic_null_lagrangian() -> None:
    """A null Lagrangian along D_c: the DEL along the D_c basis read 0 = 0."""
    err = degenerate(lambda: nonholonomic(
        lambda g: sum(b - c for c, b in zip(g.source, g.target)),
        lambda g: [g.target[2] - g.source[2] - h * (g.target[0] - g.source[0])],
        [[1, 0, 0], [0, 1, 0]]))
    assert err.causes[0] == IDENTICALLY_ZERO
    assert ("equation 1 (the DEL along the D_c basis element 1) and equation 2 (the DEL along "
            "the D_c basis element 2) read 0 = 0") in str(err)


def test_nonholonomic_valid_system_passes() -> None:
    step = nonholonomic(kinetic,
                        lambda g: [g.target[2] - g.source[2] - h * (g.target[0] - g.source[0])],
                        [[1, 0, h], [0, 1, 0]]).euler_lagrange()
    assert len(step.unknowns) == 3


# --- Lie–Poisson ---------------------------------------------------------------------------------

def test_lie_poisson_of_a_regular_rigid_body_passes() -> None:
    eqs = rigid_body().lie_poisson()
    assert len(eqs.reconstruction.unknowns) == 3


def test_rigid_body_blind_to_one_axis() -> None:
    """L = −tr(J_d W)/h with J_d = diag(0, 0, 1) = −W₃₃/h does not change under rotations about
    e₃ (X⃖₃ and X⃗₃ of W₃₃ vanish): the third DEL reads 0 = 0, and in Lie–Poisson form the
    third momentum equation is μ₃ = 0, a condition on the known momentum."""
    Jd = sp.diag(0, 0, 1)
    system = sg.DiscreteSystem(sg.SO3("W"), lambda g: -(Jd * g.matrix).trace() / h,
                               parameters=[h], name="flat")
    err = degenerate(lambda: system)
    assert err.causes == (IDENTICALLY_ZERO,)
    assert "Equation 3 (the DEL along X_3) reads 0 = 0" in str(err)
    with pytest.raises(sg.DegenerateSystemError, match=r"^flat_reconstruction: ") as info:
        system.lie_poisson()
    assert info.value.causes == (NO_UNKNOWN,)
    assert "Equation 3 (μ + λ·Φ = m_{k+1} along E_3) involves none of the unknowns" in str(
        info.value)
