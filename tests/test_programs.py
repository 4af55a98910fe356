"""Programs are the contract between the symbolic side and the evaluators: the runtime derives
nothing, and the window action is assembled once (docs/architecture.md)."""

from __future__ import annotations

import ast
import pathlib

import numpy as np
import sympy as sp

import symgroupoid as sg
from symgroupoid.derivation import WindowAction
from symgroupoid.equations import momentum_program, window_programs

RUNTIME = pathlib.Path(sg.__file__).parent / "runtime"
GRAPH_BUILDING = {"Graph", "from_sympy", "gradient", "forward", "jacobian", "lambdify"}
#: nothing is allowed: the groupoids' numerics (logarithms, geodesics) are their methods
ALLOWED: set = set()


def _offences(path: pathlib.Path) -> list[tuple[str, str]]:
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and "derivation" in node.module:
            out.append((path.name, f"imports {node.module}"))
        elif isinstance(node, ast.ImportFrom):
            out += [(path.name, a.name) for a in node.names if a.name in GRAPH_BUILDING]
        elif isinstance(node, ast.Attribute) and node.attr in GRAPH_BUILDING:
            out.append((path.name, node.attr))
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) \
                and node.func.id in GRAPH_BUILDING:
            out.append((path.name, node.func.id))
    return out


def test_the_runtime_derives_nothing():
    offences = [o for p in sorted(RUNTIME.glob("*.py")) for o in _offences(p)
                if o not in ALLOWED]
    assert offences == []


def test_window_programs_are_the_window_action():
    """The boundary-value junction program evaluates the SymPy junction variation of the same
    WindowAction (a constrained first-order system on a pair groupoid)."""
    h = sp.Symbol("h", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("x y"))

    def L(a):
        (x0, y0), (x1, y1) = a.source, a.target
        return ((x1 - x0) ** 2 + (y1 - y0) ** 2) / (2 * h) - h * sp.cos(x0) * y1

    def phi(a):
        return [a.target[0] ** 2 + a.target[1] ** 2 - 1]

    system = sg.DiscreteSystem(G, L, constraints=phi, parameters=[h], name="contract")
    programs = window_programs(system)
    action = WindowAction(G, system._fs)
    slots = action.slots("v")
    variation = action.variation(slots)
    rng = np.random.default_rng(5)
    coords = {o: rng.normal(size=G.arrow_dim) for o in action.offsets}
    lams = {s: rng.normal(size=action.m) for s in action.starts}
    f = programs.junction.numpy_function(["junction"], ["a"])
    inputs = np.concatenate([*(coords[o] for o in action.offsets),
                             *(lams[s] for s in action.starts), [0.1]])
    values = f(inputs)[0][:G.rank]
    sub = {h: 0.1}
    for o in action.offsets:
        sub.update(zip(slots[o], coords[o]))
    for s in action.starts:
        sub.update(zip(action.multipliers(s), lams[s]))
    expected = [float(e.xreplace(sub)) for e in variation]
    assert np.allclose(values, expected, rtol=1e-12, atol=1e-12)


def test_from_momentum_program_solves_the_momentum_equations():
    """The from-momentum program's Jacobian is the derivative of its residual (central
    differences), the residual F⁻L(g₁) − p₀ in the fibre chart of α(g₁)."""
    h = sp.Symbol("h", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("x"))
    system = sg.DiscreteSystem(G, lambda a: (a.target[0] - a.source[0]) ** 2 / (2 * h)
                               - h * a.source[0] ** 4 / 4, parameters=[h], name="quartic")
    step = system.euler_lagrange()
    program = momentum_program(step).program
    FJ = program.numpy_function(["F", "J"], ["z", "q", "p", "params"])
    z, q, p, params = np.array([0.3]), np.array([0.2]), np.array([0.7]), np.array([0.1])
    F, J = FJ(z, q, p, params)
    e = 1e-6
    Fp, _ = FJ(z + e, q, p, params)
    Fm, _ = FJ(z - e, q, p, params)
    assert np.allclose(J, (Fp - Fm) / (2 * e), rtol=1e-7)


def test_an_opaque_function_evaluates_on_batches_in_numpy():
    """A function NumPy lacks (erf, gamma: SymPy prints them as the math module's, which
    takes scalars) in a program evaluated on a batch of points, as the NumPy form of a
    boundary-value window is: element by element, the values of C's erf and tgamma (the
    kernels'); it raised "only 0-dimensional arrays can be converted" before."""
    import math

    from symgroupoid.ir import Graph, Program, from_sympy

    x = sp.Symbol("x", real=True)
    g = Graph()
    node = from_sympy(g, x * sp.erf(x) + sp.gamma(1 + x**2), {x: g.input(x)}, "test")
    f = Program(g, {"x": [x]}, {"y": [node]}).numpy_function(["y"], ["x"])
    xs = np.linspace(-2.0, 2.0, 9)
    (batch,) = f(xs[None, :])
    assert batch.shape == (1, 9)
    expected = [v * math.erf(v) + math.gamma(1 + v * v) for v in xs]
    assert batch[0].tolist() == expected
    assert f(xs[:1])[0].tolist() == expected[:1]
