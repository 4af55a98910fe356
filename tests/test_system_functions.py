"""``system.functions``: the Lagrangian and constraints on slot arrows, a public object."""

import sympy as sp

import symgroupoid as sg


def _pendulum_on_a_circle():
    """A point on the plane held on the circle |q| = ℓ (ψ), with a constraint φ on the step."""
    h, ell = sp.symbols("h ell", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("x y"))

    def L(g):
        (x0, y0), (x1, y1) = g.source, g.target
        return ((x1 - x0) ** 2 + (y1 - y0) ** 2) / (2 * h)

    def phi(g):
        return [g.target[0] - g.source[0] - h]

    return sg.DiscreteSystem(G, L, constraints=phi, parameters=[h, ell], name="circle",
                             holonomic=lambda q: [q[0] ** 2 + q[1] ** 2 - ell ** 2])


def test_functions_is_public_and_exported():
    assert sg.SystemFunctions is sg.derivation.SystemFunctions
    assert "SystemFunctions" in sg.__all__ and "SystemFunctions" in sg.derivation.__all__
    system = _pendulum_on_a_circle()
    assert isinstance(system.functions, sg.SystemFunctions)
    assert system._fs is system.functions  # the deprecated alias


def test_functions_hold_the_lagrangian_and_constraints_on_the_slot():
    system = _pendulum_on_a_circle()
    fs = system.functions
    (slot,) = fs.slots
    x0, y0, x1, y1 = slot
    h, ell = system.parameters
    assert sp.simplify(fs.lagrangian - ((x1 - x0) ** 2 + (y1 - y0) ** 2) / (2 * h)) == 0
    # Φ = (φ, ψ∘α): the user's constraint, then ψ at the source node
    assert fs.n_holonomic == 1 == system.n_holonomic
    assert len(fs.constraints) == 2 == system.n_constraints
    assert sp.expand(fs.constraints[0] - (x1 - x0 - h)) == 0
    assert sp.expand(fs.constraints[1] - (x0 ** 2 + y0 ** 2 - ell ** 2)) == 0
    # the step's rows on its newest term: φ, then ψ at the target β(s₀)
    assert sp.expand(fs.rows[1] - (x1 ** 2 + y1 ** 2 - ell ** 2)) == 0
    a, b = sp.symbols("a b")
    assert fs.at_base((a, b)) == [a ** 2 + b ** 2 - ell ** 2]


def test_nonholonomic_and_second_order_systems_have_functions():
    h = sp.Symbol("h", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))
    second = sg.SecondOrderSystem(
        G, lambda g1, g2: (g2.target[0] - 2 * g2.source[0] + g1.source[0]) ** 2 / h ** 3,
        parameters=[h], name="acc")
    assert len(second.functions.slots) == 2
    G3 = sg.PairGroupoid(sg.EuclideanSpace("x y z"))

    def kinetic(g):
        return sum((b - a) ** 2 for a, b in zip(g.source, g.target)) / (2 * h)

    def psi(g):
        return [g.target[2] - g.source[2] - h * (g.target[0] - g.source[0])]

    rolling = sg.NonholonomicSystem(G3, kinetic, psi, [[1, 0, h], [0, 1, 0]], parameters=[h],
                                    name="nh")
    assert isinstance(rolling.functions, sg.SystemFunctions)
    x0, y0, z0, x1, y1, z1 = rolling.functions.slots[0]
    assert sp.expand(rolling.functions.constraints[0] - (z1 - z0 - h * (x1 - x0))) == 0
    assert rolling.functions.n_holonomic == 0
