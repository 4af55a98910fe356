"""Second-order discrete Euler–Lagrange equations (seed 001 §3.1, §3.2, Remark 9), from the
same junction variation as first order."""

from __future__ import annotations

import pytest
import sympy as sp

import symgroupoid as sg


def _pair_points(step, name, offsets):
    return [step.symbol(name, o) for o in offsets]


def test_pair_groupoid_eq16_arbitrary_lagrangian():
    """Seed 001 eq. (16): D₃L(q_{k-2},q_{k-1},q_k) + D₂L(q_{k-1},q_k,q_{k+1})
    + D₁L(q_k,q_{k+1},q_{k+2}) = 0, for an arbitrary L on R²."""
    Q = sg.EuclideanSpace("x y")
    F = sp.Function("L")
    system = sg.SecondOrderSystem(
        sg.PairGroupoid(Q), lambda a, b: F(*a.source, *a.target, *b.target), name="eq16")
    step = system.euler_lagrange()
    assert [str(u) for u in step.unknowns] == ["x_{k+2}", "y_{k+2}"]
    x = _pair_points(step, "x", range(-2, 3))
    y = _pair_points(step, "y", range(-2, 3))
    pts = list(zip(x, y))

    def Lat(i):
        return F(*pts[i], *pts[i + 1], *pts[i + 2])

    for j, v in enumerate((x[2], y[2])):
        expected = Lat(0).diff(v) + Lat(1).diff(v) + Lat(2).diff(v)
        assert sp.simplify(step.residuals[j] - expected) == 0


def test_constrained_pair_groupoid_remark9():
    """Seed 001 Remark 9 (pair groupoid): D₁[L+λΦ] + D₂[L+λΦ] + D₃[L+λΦ] at the three
    windows through q_k, each window with its own multiplier, and Φ = 0 on the newest."""
    Q = sg.EuclideanSpace("q")
    F, P = sp.Function("L"), sp.Function("Phi")
    system = sg.SecondOrderSystem(
        sg.PairGroupoid(Q), lambda a, b: F(a.source[0], a.target[0], b.target[0]),
        constraints=lambda a, b: [P(a.source[0], a.target[0], b.target[0])], name="remark9")
    step = system.euler_lagrange()
    q = _pair_points(step, "q", range(-2, 3))
    lam = {o: step.symbol("lambda", o)[0] for o in (-1, 0, 1)}

    def term(s):  # window starting at q_{k+s-1}, multiplier λ_{k+s}
        args = q[s + 1:s + 4]
        return F(*args) + lam[s] * P(*args)

    expected = sum(term(s).diff(q[2]) for s in (-1, 0, 1))
    assert sp.simplify(step.residuals[0] - expected) == 0
    assert sp.simplify(step.residuals[1] - P(q[2], q[3], q[4])) == 0
    assert step.unknowns == [q[4], lam[1]]
    assert lam[-1] in step.knowns and lam[0] in step.knowns


def _explicit_group_derivative(L, slots, which, side, E):
    """d/dt L(…, g e^{tE} or e^{tE} g, …) at 0 via ∂L/∂g_ij (gE)_ij — written out here."""
    g = slots[which]
    V = g * E if side == "left" else E * g
    return sum(sp.diff(L, g[i, j]) * V[i, j] for i in range(3) for j in range(3))


def test_second_order_euler_poincare_so3():
    """Seed 001 §3.1.2: 0 = ℓ*_{g_k}D₁L(g_k,g_{k+1}) + ℓ*_{g_k}D₂L(g_{k-1},g_k)
    − r*_{g_{k+1}}D₂L(g_k,g_{k+1}) − r*_{g_{k+1}}D₁L(g_{k+1},g_{k+2})."""
    J1, J2 = sp.diag(1, 2, 3), sp.diag(2, 1, 1)
    W = sg.SO3("W")

    def L(a, b):
        return (a.matrix * J1).trace() * (b.matrix * J2).trace() + (a.matrix * b.matrix).trace()

    step = sg.SecondOrderSystem(W, L, name="ep2").euler_lagrange()
    g = {o: W.named_matrix(o) for o in (-1, 0, 1, 2)}

    def Lg(a, b):
        return (a * J1).trace() * (b * J2).trace() + (a * b).trace()

    for s, E in enumerate(sg.SO3.basis_matrices()):
        expected = (_explicit_group_derivative(Lg(g[0], g[1]), g, 0, "left", E)
                    + _explicit_group_derivative(Lg(g[-1], g[0]), g, 0, "left", E)
                    - _explicit_group_derivative(Lg(g[0], g[1]), g, 1, "right", E)
                    - _explicit_group_derivative(Lg(g[1], g[2]), g, 1, "right", E))
        assert sp.expand(step.residuals[s] - expected) == 0


def test_second_order_action_groupoid_composability():
    """Seed 001 §3.1.3: on P×H the window is (q, h_{k-1}), (q h_{k-1}, h_k), … — the sources
    of later arrows are the action of earlier ones, and the unknown is h_{k+2} only."""
    G = sg.ActionGroupoid(sg.EuclideanSpace.vector("p", 3), sg.SO3("W"),
                          lambda p, W: tuple(W.T * sp.Matrix(p)))

    def L(a, b):  # the last term couples the two rotations: the step is regular
        D = sp.diag(1, 2, 3)
        return (a.point[2] * (b.matrix * D).trace() + sum(b.point)
                + (a.matrix.T * b.matrix * D).trace())

    step = sg.SecondOrderSystem(G, L, name="action2").euler_lagrange()
    assert len(step.unknowns) == 3 and len(step.residuals) == 3
    arrows = step.arrows
    W = {o: G.group.named_matrix(o) for o in (-1, 0, 1, 2)}
    p = sp.Matrix(step.symbol("p", "k-1"))
    expected_source = W[0].T * (W[-1].T * p)
    assert sp.expand(sp.Matrix(arrows[1][:3]) - expected_source) == sp.zeros(3, 1)
    free = set().union(*(r.free_symbols for r in step.residuals))
    assert free <= set(step.knowns) | set(G.group.named_fibre(2))


def test_second_order_legendre_on_pair_groupoid():
    """Higher-order discrete Legendre transforms on Q×Q, window q_{k-1}, …, q_{k+2} with
    L_a = L(q_{k-1}, q_k, q_{k+1}), L_b = L(q_k, q_{k+1}, q_{k+2}):
    F⁺L = (∂L_a/∂q_{k+1} + ∂L_b/∂q_{k+1}, ∂L_b/∂q_{k+2}) (momenta at q_{k+1}, q_{k+2}),
    F⁻L = (−∂L_a/∂q_{k-1}, −∂L_a/∂q_k − ∂L_b/∂q_k) (momenta at q_{k-1}, q_k); equating
    F⁺ of one window with F⁻ of the window two arrows later is eq. (16) twice."""
    Q = sg.EuclideanSpace("q")
    F = sp.Function("L")
    system = sg.SecondOrderSystem(sg.PairGroupoid(Q),
                                  lambda a, b: F(a.source[0], a.target[0], b.target[0]))
    leg = system.legendre()
    qm1, q0, q1, q2 = (Q.point(o)[0] for o in (-1, 0, 1, 2))
    assert set(leg.arrow) == {qm1, q0, q1, q2}
    La, Lb = F(qm1, q0, q1), F(q0, q1, q2)
    expect_plus = [La.diff(q1) + Lb.diff(q1), Lb.diff(q2)]
    expect_minus = [-La.diff(qm1), -La.diff(q0) - Lb.diff(q0)]
    assert all(sp.simplify(a - b) == 0 for a, b in zip(leg.plus, expect_plus))
    assert all(sp.simplify(a - b) == 0 for a, b in zip(leg.minus, expect_minus))


@pytest.mark.slow
def test_second_order_compiles_and_starts_from_a_momentum(tmp_path, monkeypatch):
    """Seed 001 §3: a second-order step compiles and simulates like a first-order one, and
    (velocity-like arrow, momentum) initial data reproduce a trajectory: the momentum of the
    window (g₀, g₁, g₂) of a computed trajectory gives back g₁, g₂."""
    import numpy as np

    monkeypatch.setenv("SYMGROUPOID_CACHE", str(tmp_path))
    h = sp.Symbol("h", positive=True)
    W = sg.SO3("W")

    def L(a, b):
        xa, xb = a.coordinates / h, b.coordinates / h
        acc = (xb - xa) / h
        return h * ((acc.T * acc)[0, 0] + (xa.T * sp.diag(1, 2, 3) * xa)[0, 0]) / 2

    system = sg.SecondOrderSystem(W, L, parameters=[h], name="so3_second_order")
    step = system.euler_lagrange()
    sim = step.compile()
    cay = [np.array(W.cayley([sp.Float(v) for v in x]).tolist(), float).ravel()
           for x in ([0.01, 0.02, 0.0], [0.012, 0.018, 0.003], [0.013, 0.017, 0.005])]
    state = np.concatenate(cay)
    traj = sim.simulate(state, 20, [0.05])
    numpy_sim = sg.compile_step(step, backend="numpy")
    assert np.allclose(numpy_sim.simulate(state, 20, [0.05]).states, traj.states, atol=1e-12)
    leg = system.legendre()
    s5 = traj.states[5]
    momentum = leg.evaluate(s5, [], [0.05])[0]
    rebuilt = sim.from_momentum(s5[:9], momentum, [0.05])
    assert np.allclose(rebuilt, s5, atol=1e-11)


def test_second_order_action_groupoid_equations():
    """Seed 001 §3.1.3 on P×H with p·W = Wᵀp: the residual is
    X⃖-part: d/dt [L(g_{k-1}, g_k h) + L(g_k h, h⁻¹g_{k+1})] on the g_k slots and the
    X⃗-part on the g_{k+1} slots, with the action groupoid's fields written out here from
    docs/conventions.md §1: X⃖ moves (p, W) ↦ (p, W(I + tE)), X⃗ moves (p, W) ↦ (p·(I + tE),
    (I − tE)W) with a minus sign — independently of the library's derived fields."""
    G = sg.ActionGroupoid(sg.EuclideanSpace.vector("p", 3), sg.SO3("W"),
                          lambda p, W: tuple(W.T * sp.Matrix(p)))
    J = sp.diag(1, 2, 3)

    def Lf(pa, Wa, pb, Wb):
        return pa[2] * (Wb * J).trace() + (Wa * Wb).trace() * pb[0]

    step = sg.SecondOrderSystem(
        G, lambda a, b: Lf(a.point, a.matrix, b.point, b.matrix), name="act2").euler_lagrange()
    arrows = step.arrows
    parts = {o: (sp.Matrix(arrows[o][:3]), G.group.matrix(arrows[o][3:])) for o in (-1, 0, 1, 2)}
    t = sp.Symbol("t")
    for s, E in enumerate(sg.SO3.basis_matrices()):
        H = sp.eye(3) + t * E
        (pm, Wm), (p0, W0), (p1, W1), (p2, W2) = (parts[o] for o in (-1, 0, 1, 2))
        left = Lf(pm, Wm, p0, W0 * H) + Lf(p0, W0 * H, p1, W1)
        right = Lf(p0, W0, H.T * p1, (sp.eye(3) - t * E) * W1)  # p·(I+tE) = (I+tE)ᵀp
        right += Lf(H.T * p1, (sp.eye(3) - t * E) * W1, p2, W2)
        expected = sp.diff(left, t).subs(t, 0) + sp.diff(right, t).subs(t, 0)
        assert sp.expand(step.residuals[s] - expected) == 0
