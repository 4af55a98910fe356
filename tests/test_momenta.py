"""Legendre transforms, Noether quantities and the discrete Lie–Poisson form (seed 000 §3.3,
§4.2, §6.1; docs/conventions.md §3, §5)."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from conftest import newton, predicted

import symgroupoid as sg


def _cay(x) -> np.ndarray:
    M = np.array(sg.SO3("tmp").cayley([sp.Float(v) for v in x]).tolist(), float)
    return M


def test_pair_groupoid_legendre_is_minus_d1_and_d2():
    """docs/conventions.md §3: on Q×Q, F⁻L = −D₁L and F⁺L = D₂L, for an arbitrary L."""
    Q = sg.EuclideanSpace("x y")
    F = sp.Function("L")
    system = sg.DiscreteSystem(sg.PairGroupoid(Q),
                               lambda g: F(*g.source, *g.target), name="pair")
    leg = system.legendre()
    x0, y0, x1, y1 = leg.arrow
    Lx = F(x0, y0, x1, y1)
    assert [sp.simplify(a - b) for a, b in zip(leg.minus, [-Lx.diff(x0), -Lx.diff(y0)])] == [0, 0]
    assert [sp.simplify(a - b) for a, b in zip(leg.plus, [Lx.diff(x1), Lx.diff(y1)])] == [0, 0]


def test_legendre_transforms_match_on_solutions(plate_ball, plate_ball_step):
    """F⁺L(g_k, λ_k) = F⁻L(g_{k+1}, λ_{k+1}) on a solved plate-ball step (multipliers in)."""
    system, _ = plate_ball
    step = plate_ball_step
    params = [0.1, 1.0, 0.5, 0.3]
    rng = np.random.default_rng(3)
    W = _cay(rng.uniform(-0.2, 0.2, 3))
    known = np.concatenate([[0.1, 0.2, 0.13, 0.18], W.ravel(), rng.normal(size=3)])
    u = newton(step, predicted(step, known, params), known, params)
    nxt = step.advance(u, known, params)
    leg = system.legendre()
    _, plus_k = leg.evaluate(known[:13], known[13:], params)
    minus_k1, _ = leg.evaluate(nxt[:13], nxt[13:], params)
    assert np.allclose(plus_k, minus_k1, rtol=1e-10, atol=1e-10)
    assert not np.allclose(plus_k, 0)


def _simulate(step, known, params, n):
    states = [np.asarray(known, float)]
    for _ in range(n):
        k = states[-1]
        u = newton(step, predicted(step, k, params), k, params)
        states.append(step.advance(u, k, params))
    return states


@pytest.mark.slow
def test_heavy_top_vertical_rotation_is_a_noether_symmetry(heavy_top, heavy_top_step):
    """Seed 000 Thm 4.9: the section X(Γ) = Γ (rotation about the vertical) is a symmetry,
    and its quantity is conserved along a computed trajectory; a body axis is not."""
    system, _ = heavy_top
    vertical = system.noether(lambda q: list(q))
    assert vertical.is_symmetry
    assert not system.noether(0).is_symmetry
    params = [0.05, 1.0, 9.81, 0.3, 1.0, 1.3, 0.7]
    Gamma = np.array([0.3, -0.2, 0.9])
    Gamma /= np.linalg.norm(Gamma)
    known = np.concatenate([Gamma, _cay([0.02, -0.05, 0.08]).ravel()])
    states = _simulate(heavy_top_step, known, params, 60)
    values = [vertical.evaluate(s, [], params) for s in states]
    assert np.ptp(values) < 1e-10 * max(1.0, abs(values[0]))
    body = system.noether(0)
    drift = [body.evaluate(s, [], params) for s in states]
    assert np.ptp(drift) > 1e-6  # the body-axis quantity really changes


def _rigid_body(constrained: bool):
    h = sp.Symbol("h", positive=True)
    c = sp.Symbol("c")
    J = sp.diag(sp.Rational(1, 2), sp.Rational(3, 4), 1)
    G = sg.SO3("W")
    phi = (lambda g: [h * (g.coordinates[2] / h - c)]) if constrained else None
    return sg.DiscreteSystem(G, lambda g: (g.matrix * J).trace() / h, constraints=phi,
                             parameters=[h, c], name="rigid_body"), h, c


def _on_group(expr, G, offsets=(0, 1)):
    subs = {}
    for o in offsets:
        x = sp.symbols(f"x{o}_1:4", real=True)
        subs.update(dict(zip(G.named_fibre(o), G.fibre_chart(x))))
    return sp.cancel(sp.together(expr.xreplace(subs)))


@pytest.mark.slow
def test_lie_poisson_equals_euler_lagrange_on_so3():
    """Seed 000 §6.1: μ_{k+1} + λ_{k+1}Φ_{k+1} − Ad*_{g_k}(μ_k + λ_kΦ_k) is minus the DEL
    residual X⃖[L+λ_kφ](g_k) − X⃗[L+λ_{k+1}φ](g_{k+1}), identically on SO(3); the
    constraints φ(g_{k+1}) = 0 are common to both."""
    for constrained in (False, True):
        system, h, c = _rigid_body(constrained)
        step, lp = system.euler_lagrange(), system.lie_poisson()
        assert len(lp.residuals) == len(step.residuals)
        rank = system.groupoid.rank
        for i, (a, b) in enumerate(zip(lp.residuals, step.residuals)):
            same = a - b if i >= rank else a + b  # constraint rows are shared verbatim
            assert _on_group(same, system.groupoid) == 0


def test_lie_poisson_reconstruction_reproduces_the_step():
    """Stepping the momentum form (update + reconstruction) gives the DEL trajectory."""
    system, h, c = _rigid_body(False)
    step, lp = system.euler_lagrange(), system.lie_poisson()
    params = [0.1, 0.0]
    W = _cay([0.05, -0.03, 0.04])
    states = _simulate(step, W.ravel(), params, 5)
    leg = system.legendre()
    m = leg.evaluate(states[0], [], params)[0]
    recon = lp.reconstruction
    ad = sp.lambdify([list(system.groupoid.named_fibre(0)), lp.momentum_symbols], lp.update)
    m = np.asarray(ad(states[0], m), float).ravel()  # m_1 = Ad*_{W_0} μ(W_0)
    for k in range(1, 5):
        u = newton(recon, np.zeros(3), m, params)
        W_next = recon.advance(u, m, params)  # next momentum m_{k+1}
        W_k = np.array(sg.SO3("W").cayley([sp.Float(v) for v in u]).tolist(), float)
        assert np.allclose(W_k.ravel(), states[k], atol=1e-11)
        m = W_next


def test_a_section_on_a_matrix_group_receives_the_matrix():
    """On the pair groupoid of SO(3) a holonomic constraint receives the base point as a
    matrix (docs/conventions.md §15), a section received the tuple of its nine entries, so
    ``lambda R: [R[2, 0], R[2, 1], R[2, 2]]`` failed with a wrapped TypeError.  A section
    (and a quasi-invariance function) now receives the matrix too; flat indexing ``q[6]``
    still reads the same entry, so both forms give the same quantity."""
    e3 = sp.Matrix([0, 0, 1])

    def L(a):
        return (sp.diag(1, 2, 3) * a.source.T * a.target).trace() \
            - 3 * (e3.T * a.source * e3)[0, 0]

    top = sg.DiscreteSystem(sg.PairGroupoid(sg.SO3("R")), L, name="top")
    received = []

    def vertical(R):
        received.append(type(R))
        return [R[2, 0], R[2, 1], R[2, 2]]

    as_matrix = top.noether(vertical, f=lambda R: 0 * R[0, 0])
    as_tuple = top.noether(lambda q: [q[6], q[7], q[8]])
    assert received and all(issubclass(t, sp.MatrixBase) for t in received)
    assert as_matrix.is_symmetry and as_tuple.is_symmetry
    assert as_matrix.expr == as_tuple.expr  # the same coefficients, the same quantity
    assert not top.noether(lambda R: [R[0, 0], R[0, 1], R[0, 2]]).is_symmetry


def test_a_section_on_a_product_base_receives_the_flat_coordinates():
    """On SO(3) × SO(3) a holonomic constraint receives one matrix per factor and a section
    the 18 coordinates in one tuple (the documented form); a section written per factor
    failed with "'StepSymbol' object is not subscriptable" alone, and now says how the
    point is given."""
    def L(a):
        (R1, R2), (S1, S2) = a.source, a.target
        return (R1.T * S1).trace() + (R2.T * S2).trace() + (S1.T * S2).trace()

    two = sg.DiscreteSystem(sg.PairGroupoid(sg.SO3("R1") * sg.SO3("R2")), L, name="two")
    assert two.noether(lambda q: [q[6], q[7], q[8], q[15], q[16], q[17]]).is_symmetry
    with pytest.raises(sg.CallableError, match=r"18 coordinates in one flat tuple \(the "
                                               r"factors' 9, 9, in order"):
        two.noether(lambda q: [*q[0][2, :], *q[1][2, :]])


# --- the symmetry check of large defects -------------------------------------------------------

def _large_sum(G, extra=0):
    """A sum of 400 rational terms in the arrow's coordinates that cancels (plus ``extra``)."""
    (x0, y0), (x1, y1) = G.source(G.named_arrow(0)), G.target(G.named_arrow(0))
    terms = [(x0 + k * y1) / (1 + x1**2 + k * y0**2) for k in range(1, 201)]
    return sp.Add(*terms) - sp.Add(*[t.expand() for t in terms]) + extra, (x0, y0, x1, y1)


def test_a_large_defect_is_decided_without_counting_its_operations(monkeypatch):
    """A defect far above the symbolic check's size is decided at random arrows alone: its
    operations are not counted (sympy.count_ops walks the whole tree, a minute on the
    defect of a midpoint step on SO(3) with a potential), and the verdict is the same."""
    G = sg.PairGroupoid(sg.EuclideanSpace("x y"))
    zero, arrow = _large_sum(G)
    counted = []
    real_count = sp.count_ops
    monkeypatch.setattr(sp, "count_ops", lambda e, *a, **k: counted.append(e) or real_count(e))
    ok, how = sg.derivation.vanishing_check(zero, G, arrow)
    assert ok and how.startswith("numerical") and not counted
    nonzero, _ = _large_sum(G, extra=arrow[0] * 1e-6)
    assert sg.derivation.vanishing_check(nonzero, G, arrow) == (False, "nonzero at a random arrow")
    x, y = arrow[0], arrow[1]
    small = sp.Mul(x, 1 + y, evaluate=False) - x - x * y  # zero once expanded
    assert sg.derivation.vanishing_check(small, G, arrow)[1] == "symbolic" and counted


def test_a_defect_the_graph_does_not_take_is_undecided():
    """A defect in a function that neither the expression graph nor NumPy evaluates (a
    Bessel function) is undecided, not a crash (lambdify's NameError before)."""
    G = sg.PairGroupoid(sg.EuclideanSpace("x y"))
    zero, arrow = _large_sum(G)
    bessel = sp.besselj(0, arrow[0])
    ok, how = sg.derivation.vanishing_check(zero + bessel * 1e-3, G, arrow)
    assert not ok and how.startswith("undecided")
