"""The seed example systems, ready-made (their kernels are shipped in ``generated/``).

- ``plate_ball``: a ball rolling on a rotating plate, R²×R²×SO(3) ⇉ R² with three
  constraints (seed 000 §6.2, docs/conventions.md §6);
- ``heavy_top``: the heavy top on the action groupoid S²×SO(3) ⇉ S², Γ·W = WᵀΓ,
  L(Γ, W) = −(1/h) tr(J_d W) − h m g l Γ·e, J_d = ½ tr(I) I₃ − I (docs/conventions.md §9);
- ``rigid_body``: the Moser–Veselov rigid body on SO(3), L(W) = −(1/h) tr(J_d W);
- ``satellite_wheel`` (``satellite_with_wheel()``): an axisymmetric body with a reaction
  wheel on SO(3) × SO(2), the wheel's motor torque an input (docs/conventions.md §20), the
  kernel of the closed-loop C program ``examples/embed/closed_loop.c``.

Two families of multibody systems, sized by the number of bodies n, measure how derivation
and code generation scale (``benchmarks/scaling.py``):

- ``planar_chain(n)``: the planar n-link pendulum in angle coordinates on the pair groupoid
  of Rⁿ, midpoint discrete Lagrangian;
- ``spherical_chain(n)``: n rigid bodies joined by spherical joints, the first pinned, under
  gravity — the Lie group variational integrator of Lee, Leok and McClamroch, written on
  the pair groupoid of SO(3)ⁿ; ``spherical_chain_increments(n)`` is the same system in
  increment coordinates (:class:`TrivialisedPairGroupoid`), whose state keeps each body's
  increment F_i − I, so that its Noether momenta stay at the rounding floor over long runs;
- ``planar_chain(n, forced=True)``, ``spherical_chain(n, forced=True)``: the same chains
  driven by a torque input at every joint and damped in every joint (docs/conventions.md
  §20).

Systems with holonomic constraints ψ(q) = 0 on the configuration space
(docs/conventions.md §15): ``spherical_pendulum()``, ``link_chain(n)`` (a planar chain in
Cartesian coordinates), ``spherical_chain_maximal(n)`` (``spherical_chain(n)`` in maximal
coordinates: each body's attitude and centre, joined by ball-joint constraints) and
``tilted_top()`` (the symmetric heavy top with its nutation held
fixed, on S² × SO(3) ⇉ S²).

Each system declares its time step (``time_step=h``), the parameter its discrete energy
E_d = −∂L_d/∂h differentiates by (docs/conventions.md §19).

The sign of the rigid-body Lagrangian is the one that makes its kinetic part positive:
with W = cay(ξ), tr(J_d W) = tr J_d − ½ ξᵀ I ξ + O(|ξ|³), so −tr(J_d W)/h = ξᵀIξ/(2h) + const.
The discrete Euler–Lagrange equations are linear in L, so the opposite sign gives the same
equations (and the same regularity near the identity); only the sign of the momenta changes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import sympy as sp

from ._arguments import (
    MAX_DIMENSION,
    callable_argument,
    flag_argument,
    integer_argument,
    sequence_argument,
    shown_value,
)
from ._errors import DomainError, InputTypeError, ShapeError
from .equations import DiscreteSystem, body_torque, joint_torque, rayleigh_damping
from .groupoids import (
    SO2,
    SO3,
    ActionGroupoid,
    Arrow,
    EuclideanSpace,
    Groupoid,
    NamedMatrix,
    PairGroupoid,
    ProductGroupoid,
    TrivialisedPairGroupoid,
)


def plate_ball() -> DiscreteSystem:
    """Ball of radius r rolling without slipping on a plate rotating at rate Ω.

    Parameters ``h, r, Omega, c``; c fixes the rotation about the vertical axis per step.
    This is the optimal-control model of seed 000 §6.2 (cost ½|v|², no rotational inertia):
    its flow is constrained variational dynamics, not nonholonomic rolling, and its solutions
    can escape to infinity.  The steps approximate that flow while the rotation per step is
    small, hΩ|q|/r ≪ 1; at hΩ|q|/r ≈ 1 it reaches π/2 and the discrete solution leaves the
    continuous one (docs/conventions.md §12).
    """
    h, r, omega, c = sp.symbols("h r Omega c", positive=True)
    G = PairGroupoid(EuclideanSpace("x y")) * SO3("g")
    E1, E2, E3 = SO3.basis_matrices()

    def L(g):
        (x0, y0), (x1, y1) = g[0].source, g[0].target
        return h / 2 * (((x1 - x0) / h) ** 2 + ((y1 - y0) / h) ** 2)

    def phi(g):
        (x0, y0), (x1, y1) = g[0].source, g[0].target
        W = g[1].matrix
        return [h * ((y1 - y0) / h - r / (2 * h) * (W * E1).trace() - omega * (x1 + x0) / 2),
                h * ((x1 - x0) / h + r / (2 * h) * (W * E2).trace() + omega * (y1 + y0) / 2),
                h * (c + (W * E3).trace() / (2 * h))]

    return DiscreteSystem(G, L, constraints=phi, parameters=[h, r, omega, c],
                          name="plate_ball", time_step=h)


def inertia_symbols() -> tuple:
    """Principal moments of inertia I1, I2, I3 (positive symbols)."""
    return sp.symbols("I1 I2 I3", positive=True)


def discrete_inertia(I1, I2, I3) -> sp.Matrix:
    """J_d = ½ tr(I) I₃ − I for I = diag(I1, I2, I3), printed as J_d; each moment a SymPy
    expression (``inertia_symbols()``) or a finite number at least 0."""
    inertia = sp.diag(*[_moment(m, name) for m, name in ((I1, "I1"), (I2, "I2"), (I3, "I3"))])
    return NamedMatrix(inertia.trace() / 2 * sp.eye(3) - inertia, name="J_d")


def _moment(value, name: str) -> sp.Expr:
    """A principal moment of inertia: a real SymPy expression, or a finite number at least 0
    (an :class:`InputTypeError` for a string or a container, a :class:`DomainError` for NaN,
    an infinity, a complex or a negative number; 0 is a degenerate body, which the
    derivation diagnoses)."""
    if isinstance(value, (str, bytes, bool, np.bool_)) or np.ndim(value) != 0:
        raise InputTypeError(f"discrete_inertia: {name} must be a SymPy expression or a "
                             f"number, got {type(value).__name__} {value!r}")
    try:
        moment = sp.sympify(value, strict=True)
    except (sp.SympifyError, TypeError):
        raise InputTypeError(f"discrete_inertia: {name} must be a SymPy expression or a "
                             f"number, got {type(value).__name__} {value!r}") from None
    if not isinstance(moment, sp.Expr) or moment.has(sp.nan, sp.zoo, sp.oo, -sp.oo) \
            or moment.is_extended_real is False:
        raise DomainError(f"discrete_inertia: {name} must be real and finite, got {moment}")
    if moment.is_number and moment.is_negative:
        raise DomainError(f"discrete_inertia: {name} must not be negative (a moment of "
                          f"inertia), got {moment}")
    return moment


def heavy_top() -> DiscreteSystem:
    """The heavy top; parameters ``h, mgl, I1, I2, I3`` (mgl = m g l)."""
    h, mgl = sp.symbols("h mgl", positive=True)
    I1, I2, I3 = inertia_symbols()
    Jd = discrete_inertia(I1, I2, I3)
    G = ActionGroupoid(EuclideanSpace.vector("Gamma", 3), SO3("W"),
                       lambda p, W: tuple(W.T * sp.Matrix(p)))

    def L(g):
        gamma = g.point
        return -(Jd * g.matrix).trace() / h - h * mgl * gamma[2]

    return DiscreteSystem(G, L, parameters=[h, mgl, I1, I2, I3], name="heavy_top",
                          time_step=h)


def rigid_body() -> DiscreteSystem:
    """The Moser–Veselov free rigid body; parameters ``h, I1, I2, I3``."""
    h = sp.Symbol("h", positive=True)
    I1, I2, I3 = inertia_symbols()
    Jd = discrete_inertia(I1, I2, I3)

    def L(g):
        return -(Jd * g.matrix).trace() / h

    return DiscreteSystem(SO3("W"), L, parameters=[h, I1, I2, I3], name="rigid_body",
                          time_step=h)


def satellite_with_wheel() -> DiscreteSystem:
    """An axisymmetric body (inertia I, I, I3) with a reaction wheel (inertia Iw) spinning
    about its third axis, driven by the motor torque ``tau`` between them, an input
    (docs/conventions.md §20); parameters ``h, I, I3, Iw``.

    On SO(3) × SO(2): W is the body's attitude increment over a step (R_{k+1} = R_k W_k, as
    for ``rigid_body``) and V the wheel's turn relative to the body.  L_d is the rigid body's
    −tr(J_d W)/h plus the wheel's Iw s²/(2h), s = (W₂₁ − W₁₂)/2 + V₂₁ its absolute turn about
    the axis.  The motor torque acts on the relative angle, f⁻ = f⁺ = (h/2)·τ on the fourth
    basis section (``body_torque``), and the body reacts: the total angular momentum about the
    axis is conserved, the wheel's changes by the motor's impulse (the forced Noether
    theorem).  The wheel controls the body's rotation about the axis only.
    """
    h = sp.Symbol("h", positive=True)
    I12, I3, Iw = sp.symbols("I I3 Iw", positive=True)
    tau = sp.Symbol("tau", real=True)
    Jd = discrete_inertia(I12, I12, I3)
    G = ProductGroupoid(SO3("W"), SO2("V"))

    def L(g):
        W, V = g[0].matrix, g[1].matrix
        spin = (W[1, 0] - W[0, 1]) / 2 + V[1, 0]  # the wheel's absolute turn over a step
        return -(Jd * W).trace() / h + Iw / (2 * h) * spin**2

    return DiscreteSystem(G, L, parameters=[h, I12, I3, Iw], inputs=[tau],
                          forces=body_torque([0, 0, 0, tau], h), time_step=h,
                          name="satellite_wheel")


def planar_chain(n: int, forced: bool = False) -> DiscreteSystem:
    """The planar n-link pendulum in angle coordinates θ₁, …, θₙ; parameters ``h, g``.

    Unit point masses at the tips of unit massless links; θ_j is the angle of link j from
    the downward vertical, so tip i is at (x_i, y_i) = Σ_{j≤i} (sin θ_j, −cos θ_j) and moves
    with v_i = Σ_{j≤i} θ̇_j (cos θ_j, sin θ_j).  The continuous Lagrangian is

        L(θ, θ̇) = Σᵢ ½ |vᵢ|² − g Σᵢ yᵢ,

    and the discrete one is its midpoint rule on the pair groupoid Rⁿ × Rⁿ ⇉ Rⁿ
    (no constraints):

        L_d(θ⁰, θ¹) = h · L((θ⁰ + θ¹)/2, (θ¹ − θ⁰)/h).

    The step solves D₂L_d(θ_{k−1}, θ_k) + D₁L_d(θ_k, θ_{k+1}) = 0 for θ_{k+1}
    (docs/conventions.md §2).

    ``forced=True``: the chain driven by a torque u_j at every joint j (joint 1 between the
    pivot and link 1, joint j between links j − 1 and j; inputs ``u1, …, un``) and damped in
    every joint (parameters ``h, g, c``).  The joint torque u_j turns link j by +u_j and
    link j − 1 by −u_j (equal and opposite: internal to the chain, except at the pivot); the
    dissipation function D = (c/2) Σⱼ (θ̇_j − θ̇_{j−1})², θ̇₀ = 0, damps the relative rates.
    The generalised force is

        Q_j(θ, θ̇, u) = u_j − u_{j+1} − ∂D/∂θ̇_j        (u_{n+1} = 0),

    discretised by the midpoint rule, f⁻ = f⁺ = (h/2)·Q((θ⁰ + θ¹)/2, (θ¹ − θ⁰)/h, u), with
    :func:`~symgroupoid.body_torque` at the pivot, :func:`~symgroupoid.joint_torque` at the
    other joints and :func:`~symgroupoid.rayleigh_damping` (docs/conventions.md §20).  With
    u = 0 and c = 0 the steps are bitwise those of the unforced chain.
    """
    n = integer_argument(n, "n", minimum=1, maximum=MAX_DIMENSION, owner="planar_chain")
    forced = flag_argument(forced, "forced", owner="planar_chain")
    h, grav = sp.symbols("h g", positive=True)
    G = PairGroupoid(EuclideanSpace([f"theta{j}" for j in range(1, n + 1)]))

    def L(g):
        mid = [(a + b) / 2 for a, b in zip(g.source, g.target)]
        rate = [(b - a) / h for a, b in zip(g.source, g.target)]
        vx = vy = y = kinetic = potential = sp.Integer(0)
        for theta, omega in zip(mid, rate):
            vx += omega * sp.cos(theta)
            vy += omega * sp.sin(theta)
            y -= sp.cos(theta)
            kinetic += (vx**2 + vy**2) / 2
            potential += grav * y
        return h * (kinetic - potential)

    if not forced:
        return DiscreteSystem(G, L, parameters=[h, grav], name=f"planar_chain_{n}",
                              time_step=h)
    c = sp.Symbol("c", nonnegative=True)
    u = sp.symbols(f"u1:{n + 1}", real=True)

    def dissipation(q, v):
        return c / 2 * sum((b - a) ** 2 for a, b in zip([0, *v[:-1]], v))

    parts = [body_torque([u[0]] + [0] * (n - 1), h),
             *(joint_torque(n, [j], [j - 1], [u[j]], h) for j in range(1, n)),
             rayleigh_damping(dissipation, h)]
    return DiscreteSystem(G, L, parameters=[h, grav, c], forces=summed_forces(parts),
                          inputs=list(u), name=f"forced_planar_chain_{n}", time_step=h)


def summed_forces(parts: Sequence[Callable]) -> Callable:
    """The forces ``g -> (f_minus, f_plus)`` that add those of ``parts`` component by
    component (the Lagrange–d'Alembert terms are linear in the forces)."""

    parts = [callable_argument(part, f"parts[{i}]", owner="summed_forces")
             for i, part in enumerate(sequence_argument(parts, "parts", owner="summed_forces"))]

    def forces(g):
        pairs = [part(g) for part in parts]
        return ([sum(c, sp.S.Zero) for c in zip(*(m for m, _ in pairs))],
                [sum(c, sp.S.Zero) for c in zip(*(p for _, p in pairs))])

    return forces


#: body-frame vectors of the spherical chain: joint i → joint i+1, and joint i → centre of
#: mass of body i (unit bodies hanging along −e₃ at R = I)
CHAIN_LINK = (0, 0, -1)
CHAIN_CENTRE = (0, 0, sp.Rational(-1, 2))


def chain_inertia(i: int) -> sp.Matrix:
    """Principal inertia of body i (1-based): diag(1 + i/10, 6/5 + i/10, 1/2 + i/20)."""
    i = integer_argument(i, "i", minimum=1, maximum=MAX_DIMENSION, owner="chain_inertia")
    return sp.diag(1 + sp.Rational(i, 10), sp.Rational(6, 5) + sp.Rational(i, 10),
                   sp.Rational(1, 2) + sp.Rational(i, 20))


def attitude_groupoid(n: int) -> tuple[Groupoid, Callable[[Arrow], list]]:
    """The pair groupoid of n attitudes, SO(3)ⁿ × SO(3)ⁿ ⇉ SO(3)ⁿ, and a reader of its arrows.

    An arrow is (R_k, R_{k+1}) — every body's attitude at two consecutive steps — and a step
    solves for the Cayley coordinates of each body's increment R_{i,k}ᵀR_{i,k+1}
    (docs/conventions.md §1).  The reader maps an arrow to the list of (R_{i,k}, R_{i,k+1}).
    """
    n = integer_argument(n, "n", minimum=1, maximum=MAX_DIMENSION, owner="attitude_groupoid")
    space = SO3("R1") if n == 1 else ProductGroupoid(*[SO3(f"R{i}") for i in range(1, n + 1)])
    G = PairGroupoid(space)

    def read(g) -> list:
        a, b = g.source, g.target
        if n == 1:
            return [(a, b)]
        return list(zip(a, b))

    return G, read


def centres_of_mass(R: Sequence[sp.Matrix]) -> list[sp.Matrix]:
    """c_i = Σ_{j<i} R_j ℓ + R_i ρ: centres of mass of a chain pinned at the origin."""
    link, centre = sp.Matrix(CHAIN_LINK), sp.Matrix(CHAIN_CENTRE)
    out, joint = [], sp.zeros(3, 1)
    R = [_matrix3(Ri, f"R[{i}]", "centres_of_mass")
         for i, Ri in enumerate(sequence_argument(R, "R", owner="centres_of_mass"))]
    for Ri in R:
        out.append(joint + Ri * centre)
        joint = joint + Ri * link
    return out


def spherical_chain(n: int, forced: bool = False) -> DiscreteSystem:
    """n rigid bodies in a chain joined by spherical joints under gravity; parameters ``h, g``.

    Body 1 is pinned at the origin; body i has unit mass, attitude R_i ∈ SO(3), principal
    inertia J_i = :func:`chain_inertia` (i), the body-frame vector ℓ = (0, 0, −1) from its
    joint to the next one and ρ = (0, 0, −½) from its joint to its centre of mass, so

        c_i(R) = Σ_{j<i} R_j ℓ + R_i ρ.

    One step moves R_{i,k} to R_{i,k+1} = R_{i,k} F_i.  The discrete Lagrangian (the Lie
    group variational integrator of Lee, Leok and McClamroch: rotational part in F_i,
    translational kinetic energy of the centres of mass by the difference quotient,
    gravity by the trapezoid rule) is

        L_d = Σᵢ [ (1/h) tr((I₃ − F_i) J_{d,i})
                   + (1/(2h)) |c_i(R_{k+1}) − c_i(R_k)|²
                   − (h/2) g e₃·(c_i(R_k) + c_i(R_{k+1})) ],   J_{d,i} = ½ tr(J_i) I₃ − J_i.

    The groupoid is :func:`attitude_groupoid` (n), the pair groupoid of SO(3)ⁿ; the unknowns
    of a step are the Cayley coordinates of F_{i,k+1} = R_{i,k}ᵀR_{i,k+1}
    (docs/conventions.md §1–§2).

    ``forced=True``: the chain driven by a torque at every joint (inputs ``uj_1, uj_2,
    uj_3``: the torque u_j that joint j applies to body j, in body j's frame along E₁, E₂,
    E₃; joint 1 is the pivot) and damped in every joint (parameters ``h, g, c``).  Joint j
    applies the spatial torque T_j = R_j u_j − c (ω_j − ω_{j−1}) to body j and −T_j to
    body j − 1 (equal and opposite: internal to the chain, except at the pivot, where
    ω₀ = 0); ω_i = vee(R_{i,k+1}R_{i,k}ᵀ − R_{i,k}R_{i,k+1}ᵀ)/(2h) is body i's spatial
    angular velocity over the step.  The discrete forces are the body-frame torques at the
    two ends of the arrow, held over the step as :func:`~symgroupoid.body_torque` holds
    them (docs/conventions.md §20):

        f⁻_i = (h/2) R_{i,k}ᵀ (T_i − T_{i+1})|_{R_k},
        f⁺_i = (h/2) R_{i,k+1}ᵀ (T_i − T_{i+1})|_{R_{k+1}},   T_{n+1} = 0,

    where R_j u_j is taken at the same attitudes as the frame.  f⁺(g_k) and f⁻(g_{k+1})
    both map the spatial torques into the frames of the junction's attitudes R_{k+1}, so the
    joints j ≥ 2 cancel along any rotation of the whole chain: about the vertical (a
    symmetry of L_d) only the pivot's torque T₁ changes the angular momentum, by
    (h/2) e₃·(T₁(g_k) + T₁(g_{k+1})) at R_{k+1} per step.  The bodies' frames differ, so
    :func:`~symgroupoid.joint_torque` (equal components on both bodies) does not apply.
    With u = 0 and c = 0 the steps are those of the unforced chain to rounding (not
    bitwise: the compacted program factors the damping's monomials together with the
    Lagrangian's, and rounds those sums in another order).
    """
    n = integer_argument(n, "n", minimum=1, maximum=MAX_DIMENSION, owner="spherical_chain")
    forced = flag_argument(forced, "forced", owner="spherical_chain")
    h, grav = sp.symbols("h g", positive=True)
    G, read = attitude_groupoid(n)
    up = sp.Matrix([0, 0, 1])
    Jd = [chain_inertia(i).trace() / 2 * sp.eye(3) - chain_inertia(i) for i in range(1, n + 1)]

    def L(g):
        bodies = read(g)
        before = centres_of_mass([Ra for Ra, _ in bodies])
        after = centres_of_mass([Rb for _, Rb in bodies])
        rotational = sum(((sp.eye(3) - Ra.T * Rb) * J).trace()
                         for (Ra, Rb), J in zip(bodies, Jd))
        kinetic = sum(((b - a).T * (b - a))[0, 0] for a, b in zip(before, after)) / 2
        potential = sum((up.T * (a + b))[0, 0] for a, b in zip(before, after)) * grav / 2
        return (rotational + kinetic) / h - h * potential

    if not forced:
        return DiscreteSystem(G, L, parameters=[h, grav], name=f"spherical_chain_{n}",
                              time_step=h)
    c = sp.Symbol("c", nonnegative=True)
    u = [sp.Matrix(sp.symbols(f"u{j}_1:4", real=True)) for j in range(1, n + 1)]

    def forces(g):
        bodies = read(g)
        # body i's angular velocity over the step in its own frame, at either end:
        # R_aᵀω_i = R_bᵀω_i = vee(F_i − F_iᵀ)/(2h), F_i = R_aᵀR_b (the increment L reads)
        spin = [vee(Ra.T * Rb - Rb.T * Ra) / (2 * h) for Ra, Rb in bodies]
        return tuple(chain_torques(R, u, spin, c, h) for R in zip(*bodies))

    return DiscreteSystem(G, L, parameters=[h, grav, c], forces=forces,
                          inputs=[x for uj in u for x in uj], time_step=h,
                          name=f"forced_spherical_chain_{n}")


def _matrix3(value, name: str, owner: str) -> sp.Matrix:
    """``value`` as a 3 × 3 SymPy matrix (a SymPy matrix or matrix expression as it is; a
    NumPy matrix or nested lists converted), or a :class:`ShapeError`."""
    if isinstance(value, (sp.MatrixBase, sp.MatrixExpr)) and value.shape == (3, 3):
        return value
    if isinstance(value, (np.ndarray, list, tuple)):
        try:
            matrix = sp.Matrix(value)
        except (ValueError, TypeError, sp.SympifyError, sp.matrices.ShapeError):
            matrix = None
        if matrix is not None and matrix.shape == (3, 3):
            return matrix
    raise ShapeError(f"{owner}: {name} must be a 3 × 3 matrix, got {type(value).__name__} "
                     f"{shown_value(value)}")


def vee(M: sp.Matrix) -> sp.Matrix:
    """(M₃₂, M₁₃, M₂₁): the vector of a skew-symmetric 3×3 matrix, vee(x̂) = x."""
    M = _matrix3(M, "M", "vee")
    return sp.Matrix([M[2, 1], M[0, 2], M[1, 0]])


def chain_torques(R: Sequence[sp.Matrix], u: Sequence[sp.Matrix], spin: Sequence[sp.Matrix],
                  c: sp.Symbol, h: sp.Symbol) -> list:
    """(h/2) R_iᵀ(T_i − T_{i+1}) for every body i, one component per E_a, at attitudes R:
    the joint torques T_j = R_j u_j − c (ω_j − ω_{j−1}) of :func:`spherical_chain` (forced),
    from the bodies' angular velocities in their own frames, ``spin`` Ω_j = R_jᵀω_j: with
    A_ij = R_iᵀR_j, R_iᵀT_i = u_i − c (Ω_i − A_{i,i−1}Ω_{i−1}) and R_iᵀT_{i+1} =
    A_{i,i+1}(u_{i+1} − c Ω_{i+1}) + c Ω_i (R_iᵀR_i = I on the group)."""
    out: list = []
    for i, Ri in enumerate(R):
        net = u[i] - c * spin[i]
        if i > 0:
            net += c * (Ri.T * R[i - 1]) * spin[i - 1]
        if i + 1 < len(R):
            net -= (Ri.T * R[i + 1]) * (u[i + 1] - c * spin[i + 1]) + c * spin[i]
        out += list(h / 2 * net)
    return out


def spherical_chain_increments(n: int) -> DiscreteSystem:
    """:func:`spherical_chain` (n) in increment coordinates; parameters ``h, g``.

    The groupoid is the product of :class:`TrivialisedPairGroupoid` (``SO3("R_i")``,
    increment ``"F_i"``): an arrow carries every body's attitude R_{i,k} and the offset
    F_{i,k} − I of its increment F_{i,k} = R_{i,k}ᵀR_{i,k+1}, and a step solves for the
    Cayley coordinates of F_{i,k+1}, as :func:`spherical_chain` does.  The same discrete
    Lagrangian, written through the increments so that nothing cancels:

        L_d = Σᵢ [ (1/h) tr((I₃ − F_i) J_{d,i}) + (1/(2h)) |Δc_i|²
                   − (h/2) g e₃·(2 c_i(R_k) + Δc_i) ],
        Δc_i = c_i(R_{k+1}) − c_i(R_k) = Σ_{j<i} R_j (F_j − I) ℓ + R_i (F_i − I) ρ.

    A state is given as ``{"R1": R_{1,0}, "F1": R_{1,0}ᵀR_{1,1}, …}`` (docs/conventions.md
    §18).
    """
    n = integer_argument(n, "n", minimum=1, maximum=MAX_DIMENSION,
                         owner="spherical_chain_increments")
    h, grav = sp.symbols("h g", positive=True)
    factors = [TrivialisedPairGroupoid(SO3(f"R{i}"), f"F{i}") for i in range(1, n + 1)]
    G = factors[0] if n == 1 else ProductGroupoid(*factors)
    up, link, centre = sp.Matrix([0, 0, 1]), sp.Matrix(CHAIN_LINK), sp.Matrix(CHAIN_CENTRE)
    Jd = [chain_inertia(i).trace() / 2 * sp.eye(3) - chain_inertia(i) for i in range(1, n + 1)]

    def L(g):
        arrows = [g] if n == 1 else list(g)
        rotational = kinetic = potential = sp.S.Zero
        joint, moved = sp.zeros(3, 1), sp.zeros(3, 1)  # Σ_{j<i} R_j ℓ and Σ_{j<i} R_j D_j ℓ
        for a, J in zip(arrows, Jd):
            R, D = a.source, a.increment - sp.eye(3)
            rotational += ((sp.eye(3) - a.increment) * J).trace()
            dc = moved + R * (D * centre)
            kinetic += (dc.T * dc)[0, 0] / 2
            potential += (up.T * (2 * (joint + R * centre) + dc))[0, 0] / 2
            joint, moved = joint + R * link, moved + R * (D * link)
        return (rotational + kinetic) / h - h * grav * potential

    return DiscreteSystem(G, L, parameters=[h, grav],
                          name=f"spherical_chain_increments_{n}", time_step=h)


# --- holonomic constraints on the configuration space (docs/conventions.md §15) -------------

def spherical_pendulum() -> DiscreteSystem:
    """A unit mass on a sphere of radius ℓ under gravity; parameters ``h, ell, g``.

    Pair groupoid of R³, L_d(q₀, q₁) = |q₁ − q₀|²/(2h) − (h/2) g (z₀ + z₁) (trapezoidal
    gravity), holonomic ψ(q) = |q|² − ℓ².  The step solves
    D₂L_d(q_{k−1}, q_k) + D₁L_d(q_k, q_{k+1}) + λ·∇ψ(q_k) = 0, ψ(q_{k+1}) = 0 (SHAKE).
    Rotations about the vertical, X(q) = (−y, x, 0), are tangent to the sphere and leave
    L_d invariant: their Noether quantity, the angular momentum about the vertical, is
    conserved.
    """
    h, ell = sp.symbols("h ell", positive=True)
    grav = sp.Symbol("g", nonnegative=True)
    G = PairGroupoid(EuclideanSpace("x y z"))

    def L(g):
        (x0, y0, z0), (x1, y1, z1) = g.source, g.target
        return ((x1 - x0) ** 2 + (y1 - y0) ** 2 + (z1 - z0) ** 2) / (2 * h) \
            - h * grav * (z0 + z1) / 2

    return DiscreteSystem(G, L, parameters=[h, ell, grav], name="spherical_pendulum",
                          holonomic=lambda q: [q[0] ** 2 + q[1] ** 2 + q[2] ** 2 - ell**2],
                          time_step=h)


def link_chain(n: int) -> DiscreteSystem:
    """A planar chain of n unit point masses joined by rigid massless links, the first
    pinned at the origin, in Cartesian coordinates; parameters ``h, g, l1, …, ln``.

    Pair groupoid of R²ⁿ (x1, y1, …, xn, yn), L_d = Σᵢ |p_i¹ − p_i⁰|²/(2h) − (h/2) g (y_i⁰ +
    y_i¹), holonomic ψ_i(p) = |p_i − p_{i−1}|² − l_i² (p₀ = 0).  Rotations about the pivot
    are tangent to the constraint set; with g = 0 their Noether quantity (the angular
    momentum) is conserved.
    """
    n = integer_argument(n, "n", minimum=1, maximum=MAX_DIMENSION, owner="link_chain")
    h = sp.Symbol("h", positive=True)
    grav = sp.Symbol("g", nonnegative=True)
    lengths = sp.symbols(f"l1:{n + 1}", positive=True)
    names = " ".join(f"x{i} y{i}" for i in range(1, n + 1))
    G = PairGroupoid(EuclideanSpace(names))

    def L(g):
        a, b = g.source, g.target
        kinetic = sum((v - u) ** 2 for u, v in zip(a, b)) / (2 * h)
        return kinetic - h * grav * sum(a[2 * i + 1] + b[2 * i + 1] for i in range(n)) / 2

    def psi(q):
        points = [(0, 0)] + [(q[2 * i], q[2 * i + 1]) for i in range(n)]
        return [(points[i][0] - points[i - 1][0]) ** 2 + (points[i][1] - points[i - 1][1]) ** 2
                - lengths[i - 1] ** 2 for i in range(1, n + 1)]

    return DiscreteSystem(G, L, parameters=[h, grav, *lengths], name=f"link_chain_{n}",
                          holonomic=psi, time_step=h)


def spherical_chain_maximal(n: int) -> DiscreteSystem:
    """:func:`spherical_chain` (n) in maximal coordinates; parameters ``h, g``.

    Every body i has its own attitude R_i ∈ SO(3) and centre of mass c_i = (x_i, y_i, z_i);
    the groupoid is the product of the pair groupoids of SO(3) and R³, one of each per body,
    and the spherical joints are holonomic constraints (docs/conventions.md §15): joint i,
    at R_i(−ρ) from c_i, is body i − 1's point at R_{i−1}(ℓ − ρ) from c_{i−1} (the origin
    for i = 1),

        ψ_i(q) = c_i − R_i ρ − (c_{i−1} + R_{i−1}(ℓ − ρ)),   c_0 + R_0(ℓ − ρ) := 0,

    three scalar constraints per joint.  The discrete Lagrangian is :func:`spherical_chain`'s
    with c_i an unknown of its own,

        L_d = Σᵢ [ (1/h) tr((I₃ − R_{i,k}ᵀR_{i,k+1}) J_{d,i}) + (1/(2h)) |c_{i,k+1} − c_{i,k}|²
                   − (h/2) g e₃·(c_{i,k} + c_{i,k+1}) ],

    which on the constraint set equals it, so both give the same trajectory (to Newton's
    tolerance) from the same initial arrow.  A step has 9n unknowns (the Cayley coordinates
    of each body's increment, its new centre and three multipliers per joint) where
    :func:`spherical_chain` has 3n, but each couples only neighbouring bodies: from 16
    bodies the kernel factors the step's Jacobian in band form (kl = ku = 9) and a step costs
    O(n) instead of O(n³) (docs/notes/performance.md, "Long chains").
    """
    n = integer_argument(n, "n", minimum=1, maximum=MAX_DIMENSION,
                         owner="spherical_chain_maximal")
    h, grav = sp.symbols("h g", positive=True)
    G = ProductGroupoid(*[factor for i in range(1, n + 1) for factor in (
        PairGroupoid(SO3(f"R{i}")), PairGroupoid(EuclideanSpace(f"x{i} y{i} z{i}")))])
    up, link, centre = sp.Matrix([0, 0, 1]), sp.Matrix(CHAIN_LINK), sp.Matrix(CHAIN_CENTRE)
    Jd = [chain_inertia(i).trace() / 2 * sp.eye(3) - chain_inertia(i) for i in range(1, n + 1)]

    def bodies(points) -> list:
        """(R_i, c_i) of every body from the factors' points."""
        points = list(points)
        return [(points[2 * i], sp.Matrix(points[2 * i + 1])) for i in range(n)]

    def L(g):
        arrows = list(g)
        before = bodies(a.source for a in arrows)
        after = bodies(a.target for a in arrows)
        total = sp.S.Zero
        for (Ra, ca), (Rb, cb), J in zip(before, after, Jd):
            total += (((sp.eye(3) - Ra.T * Rb) * J).trace() / h
                      + ((cb - ca).T * (cb - ca))[0, 0] / (2 * h)
                      - h * grav * (up.T * (ca + cb))[0, 0] / 2)
        return total

    def joints(q) -> list:
        out, joint = [], sp.zeros(3, 1)
        for R, c in bodies(q):
            out += list(c - R * centre - joint)
            joint = c + R * (link - centre)
        return out

    return DiscreteSystem(G, L, parameters=[h, grav], holonomic=joints, time_step=h,
                          name=f"spherical_chain_maximal_{n}")


def tilted_top() -> DiscreteSystem:
    """The heavy top with its nutation held fixed; parameters ``h, mgl, I1, I2, I3, c``.

    The heavy top of :func:`heavy_top` on S² × SO(3) ⇉ S² with the holonomic constraint
    ψ(Γ) = Γ₃ − c on the base (Γ the vertical in the body frame, c the cosine of the fixed
    tilt).  The anchor ρ(E_a)(Γ) = d/dt (e^{tE_a})ᵀΓ = Γ × e_a makes the multiplier enter
    the equations of E₁ and E₂ (dψ(ρ(E₁)) = −Γ₂, dψ(ρ(E₂)) = Γ₁) and not that of E₃, which
    is tangent to the circle Γ₃ = c: for a symmetric top (I₁ = I₂) the spin about the
    symmetry axis is a Noether quantity.
    """
    h, mgl, c = sp.symbols("h mgl c", positive=True)
    I1, I2, I3 = inertia_symbols()
    Jd = discrete_inertia(I1, I2, I3)
    G = ActionGroupoid(EuclideanSpace.vector("Gamma", 3), SO3("W"),
                       lambda p, W: tuple(W.T * sp.Matrix(p)))

    def L(g):
        return -(Jd * g.matrix).trace() / h - h * mgl * g.point[2]

    return DiscreteSystem(G, L, parameters=[h, mgl, I1, I2, I3, c], name="tilted_top",
                          holonomic=lambda gamma: [gamma[2] - c], time_step=h)


#: the systems whose kernels are shipped in ``generated/`` (``python -m symgroupoid generate``)
SEED_SYSTEMS: dict[str, Callable[[], DiscreteSystem]] = {
    "plate_ball": plate_ball, "heavy_top": heavy_top, "rigid_body": rigid_body,
    "satellite_wheel": satellite_with_wheel}
