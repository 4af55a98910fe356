"""Bad input is reported with a clear error that names the system (or groupoid) and the
offending object: undeclared symbols, malformed constraints, a user groupoid whose section
count is not its fibre dimension, more constraints than unknowns, user callables that raise,
and groupoid-axiom failures (reported with the failing arrows)."""

from __future__ import annotations

import pytest
import sympy as sp

import symgroupoid as sg

h, m = sp.symbols("h m", positive=True)
stray, zeta = sp.symbols("stray zeta")


def line() -> sg.PairGroupoid:
    return sg.PairGroupoid(sg.EuclideanSpace("q"))


def kinetic(g) -> sp.Expr:
    """L(q₀, q₁) = (m/2) h ((q₁ − q₀)/h)²."""
    return m * h / 2 * ((g.target[0] - g.source[0]) / h) ** 2


def system(**kwargs) -> sg.DiscreteSystem:
    args = dict(groupoid=line(), lagrangian=kinetic, parameters=[h, m], name="oscillator")
    args.update(kwargs)
    return sg.DiscreteSystem(**args)


# --- undeclared symbols ----------------------------------------------------------------------

def test_undeclared_symbols_in_lagrangian_are_named() -> None:
    """Free symbols that are neither coordinates nor parameters are listed by name."""
    with pytest.raises(sg.UndeclaredSymbolError,
                       match=r"oscillator: the Lagrangian uses symbol\(s\) stray, zeta that are "
                             r"neither coordinates .* parameters=\[\.\.\.\]"):
        system(lagrangian=lambda g: kinetic(g) + stray * zeta * g.target[0])


def test_undeclared_symbol_in_constraints_is_named() -> None:
    """The same check for the constraint functions φᵃ (seed 000 §3.3)."""
    with pytest.raises(sg.UndeclaredSymbolError,
                       match=r"oscillator: the constraints uses symbol\(s\) zeta "):
        system(constraints=lambda g: [g.target[0] - zeta])


def test_declared_parameter_is_accepted() -> None:
    """The same expression is accepted once the symbol is declared."""
    s = system(constraints=lambda g: [g.target[0] - zeta], parameters=[h, m, zeta])
    assert s.n_constraints == 1


def test_coordinate_lookalike_symbol_is_rejected() -> None:
    """A plain Symbol named like a coordinate is not the coordinate (it is undeclared)."""
    q = sp.Symbol("q")
    with pytest.raises(sg.UndeclaredSymbolError, match=r"symbol\(s\) q "):
        system(lagrangian=lambda g: kinetic(g) + q**2)


# --- parameters given as strings or with other assumptions -------------------------------------

def test_string_parameter_says_to_pass_symbols() -> None:
    """parameters=["h"]: the message says to pass SymPy symbols and shows the symbol L uses."""
    with pytest.raises(sg.ParameterDeclarationError,
                       match=r"^oscillator: parameters must be SymPy symbols, not strings: got "
                             r"'h' — pass the symbols the expressions use, e\.g\. h = "
                             r"sympy\.Symbol\('h', positive=True\) and parameters=\[h\]; the "
                             r"Lagrangian uses Symbol\('h', positive=True\): pass that Symbol "
                             r"object$") as info:
        system(parameters=["h", m])
    assert isinstance(info.value, sg.UndeclaredSymbolError)  # still an undeclared symbol


def test_unused_string_parameter_is_rejected_too() -> None:
    with pytest.raises(sg.ParameterDeclarationError,
                       match=r"not strings: got 'zeta' — pass the symbols"):
        system(parameters=[h, m, "zeta"])


def test_parameter_that_is_not_a_symbol() -> None:
    with pytest.raises(sg.ParameterDeclarationError,
                       match=r"oscillator: parameters must be SymPy symbols; got 2\*h \(Mul\)"):
        system(parameters=[2 * h, m])


def test_parameter_declared_with_other_assumptions() -> None:
    """L uses Symbol("h", positive=True), the declared parameter is Symbol("h"): the names
    match but the assumptions differ — both are shown."""
    with pytest.raises(sg.ParameterDeclarationError,
                       match=r"^oscillator: the Lagrangian uses Symbol\('h', positive=True\) but "
                             r"the declared symbol is Symbol\('h'\): the names match but the "
                             r"assumptions differ"):
        system(parameters=[sp.Symbol("h"), m])
    with pytest.raises(sg.ParameterDeclarationError,
                       match=r"the constraints uses Symbol\('zeta', real=True\) but the declared "
                             r"symbol is Symbol\('zeta', positive=True\)"):
        system(constraints=lambda g: [g.target[0] - sp.Symbol("zeta", real=True)],
               parameters=[h, m, sp.Symbol("zeta", positive=True)])


# --- malformed constraints and Lagrangians ------------------------------------------------------

@pytest.mark.parametrize("constraints, message", [
    (lambda g: g.target[0] - 1, r"constraints must return a list of scalar expressions, got Add"),
    (lambda g: sp.eye(2), r"constraints returned a 2×2 matrix; return a list of scalars"),
    (lambda g: [sp.Matrix([1, g.target[0]])],
     r"constraints \(entry 0\) returned a 2×1 matrix; it must be a scalar — constraints must "
     r"be a list of scalars"),
    (lambda g: [g.target[0], [g.source[0]]],
     r"constraints \(entry 1\) returned a list; it must be a scalar"),
    (lambda g: [None], r"constraints \(entry 0\) returned None, not a scalar"),
    (lambda g: {"a": g.target[0]}, r"must return a list of scalar expressions, got dict"),
])
def test_constraints_must_be_a_list_of_scalars(constraints, message: str) -> None:
    """φ must be a list (or column) of scalar expressions φ¹, …, φᵐ (seed 000 §3.3)."""
    with pytest.raises(sg.ShapeError, match=r"^oscillator: .*" + message):
        system(constraints=constraints)


def test_column_matrix_of_constraints_is_accepted() -> None:
    """A column matrix is a list of scalars."""
    s = system(groupoid=sg.PairGroupoid(sg.EuclideanSpace("x y")),
               lagrangian=lambda g: sum((b - a) ** 2 for a, b in zip(g.source, g.target)),
               constraints=lambda g: sp.Matrix([g.target[0] - g.target[1]]))
    assert s.n_constraints == 1


def test_constraints_given_as_a_list_not_a_function() -> None:
    """Constraints are functions of the arrow; a list of expressions is rejected up front."""
    with pytest.raises(sg.CallableError,
                       match=r"oscillator: the constraints must be a function of the arrow .*"
                             r"got a list"):
        system(constraints=[sp.Symbol("q") - 1])


@pytest.mark.parametrize("lagrangian, message", [
    (lambda g: [kinetic(g)], r"the Lagrangian returned a list; it must be a scalar"),
    (lambda g: sp.Matrix([kinetic(g), 1]), r"the Lagrangian returned a 2×1 matrix"),
])
def test_lagrangian_must_be_a_scalar(lagrangian, message: str) -> None:
    """L: G → R returns one scalar expression."""
    with pytest.raises(sg.ShapeError, match=r"^oscillator: " + message):
        system(lagrangian=lagrangian)


def test_more_constraints_than_unknowns() -> None:
    """Seed 000 §3.3: N = {φᵃ = 0} needs fewer constraints than fibre dimensions."""
    with pytest.raises(sg.ShapeError,
                       match=r"oscillator: 2 constraints but only 1 unknown fibre coordinates "
                             r"per step on .*; more constraints than unknowns"):
        system(constraints=lambda g: [g.target[0] - 1, g.source[0] + g.target[0]])


def test_not_a_groupoid() -> None:
    """A system is built on a Groupoid, not on its base manifold."""
    with pytest.raises(TypeError, match="oscillator: groupoid must be a symgroupoid Groupoid"):
        system(groupoid=sg.EuclideanSpace("q"))


# --- user callables that raise ------------------------------------------------------------------

def test_lagrangian_that_raises_is_wrapped() -> None:
    """The error names the system and what was being evaluated, and chains the cause."""
    with pytest.raises(sg.CallableError,
                       match=r"oscillator: evaluating the Lagrangian on symbolic arrows raised "
                             r"AttributeError: .*'matrix'") as info:
        system(lagrangian=lambda g: (g.matrix * 2).trace())
    assert isinstance(info.value.__cause__, AttributeError)


def test_constraint_that_raises_is_wrapped() -> None:
    """An exception inside φ is reported with the system name and "constraints"."""
    def phi(g):
        raise ZeroDivisionError("rod length is zero")

    with pytest.raises(sg.CallableError,
                       match=r"oscillator: evaluating the constraints on symbolic arrows raised "
                             r"ZeroDivisionError: rod length is zero"):
        system(constraints=phi)


def _defined(check: bool = False, **overrides) -> sg.DefinedGroupoid:
    """The pair groupoid of R by hand, with maps replaced; the construction-time axiom check
    is off unless asked for, so that later stages can be exercised."""
    maps = dict(source=lambda a: (a[0],), target=lambda a: (a[1],),
                multiply=lambda a, b: (a[0], b[1]), identity=lambda q: (q[0], q[0]),
                inverse=lambda a: (a[1], a[0]), sections=lambda q, t: [(q[0], q[0] + t)])
    names = dict(base_names=["q"], fibre_names=["q"])
    for key in ("base_names", "fibre_names"):
        if key in overrides:
            names[key] = overrides.pop(key)
    maps.update(overrides)
    return sg.DefinedGroupoid("hand-made line", **names, **maps, check=check)


def test_user_structure_map_that_raises_is_wrapped() -> None:
    """A DefinedGroupoid's structure map that raises is reported with the groupoid's name and
    the map, whether it surfaces in a derivation or in check_axioms."""
    G = _defined(multiply=lambda a, b: (a[0], b[2]))
    with pytest.raises(sg.CallableError,
                       match=r"hand-made line: the multiply map raised IndexError"):
        sg.DiscreteSystem(G, lambda g: g.coords[1] ** 2).euler_lagrange()
    with pytest.raises(sg.CallableError, match=r"hand-made line: the multiply map raised"):
        sg.check_axioms(G)


def test_user_structure_map_with_wrong_length() -> None:
    """A structure map returning the wrong number of coordinates is named, with the count."""
    G = _defined(target=lambda a: (a[1], a[0]))
    with pytest.raises(sg.ShapeError,
                       match=r"hand-made line: the target map returned 2 coordinates; "
                             r"a base point has 1"):
        sg.check_axioms(G)


def test_section_curve_that_raises_is_wrapped() -> None:
    """The section curves are evaluated when the groupoid is defined; errors name it."""
    with pytest.raises(sg.CallableError,
                       match=r"hand-made line: section_curves raised IndexError"):
        _defined(sections=lambda q, t: [(q[0], q[1] + t)])


# --- user groupoid: sections vs fibre dimension -------------------------------------------------

def test_too_many_sections() -> None:
    """A basis of sections of AG has as many elements as the α-fibre dimension."""
    with pytest.raises(sg.ShapeError,
                       match=r"hand-made line: 2 section curves given but the α-fibres have "
                             r"dimension 1; a basis of sections needs exactly 1"):
        _defined(sections=lambda q, t: [(q[0], q[0] + t), (q[0], q[0] + 2 * t)])


def test_too_few_sections() -> None:
    """Fewer section curves than fibre dimensions is reported the same way."""
    with pytest.raises(sg.ShapeError,
                       match=r"hand-made line: 1 section curves given but the α-fibres have "
                             r"dimension 2"):
        _defined(fibre_names=["q", "z"],
                 multiply=lambda a, b: (a[0], b[1], a[2] + b[2]),
                 identity=lambda q: (q[0], q[0], 0), inverse=lambda a: (a[1], a[0], -a[2]))


def test_section_curve_of_wrong_length() -> None:
    """Each section curve is a curve of arrows (as many coordinates as an arrow)."""
    with pytest.raises(sg.ShapeError,
                       match=r"hand-made line: section curve 0 has 3 coordinates, arrows have 2"):
        _defined(sections=lambda q, t: [(q[0], q[0] + t, t)])


# --- axiom failures -----------------------------------------------------------------------------

def test_axiom_failure_names_the_arrows() -> None:
    """check_axioms reports the violated axiom and the arrows it fails for (seed 000 Def. 2.1)."""
    G = _defined(inverse=lambda a: (a[1], 2 * a[0]))
    with pytest.raises(sg.AxiomError,
                       match=r"^hand-made line: α\(a⁻¹\) = β\(a\), β\(a⁻¹\) = α\(a\) fails for "
                             r"a=\(-?\d\.\d+(e-?\d+)?, -?\d\.\d+(e-?\d+)?\)$"):
        sg.check_axioms(G)


# --- step API misuse ----------------------------------------------------------------------------

def test_unknown_symbol_name_lists_known_names() -> None:
    """``step.symbol`` with an unknown name or step label says what is available."""
    step = system().euler_lagrange()
    with pytest.raises(sg.InputNameError, match=r"oscillator: no coordinate named 'x'; known "
                                                r"names: q, lambda"):
        step.symbol("x", "k")
    with pytest.raises(sg.ShapeError, match=r"step must look like 'k', 'k\+1' or 'k-1'"):
        step.symbol("q", "next")


def test_missing_parameter_in_evaluate() -> None:
    """Numeric evaluation names the parameters missing from a parameter dict."""
    step = system().euler_lagrange()
    with pytest.raises(sg.ParameterError, match=r"oscillator.evaluate: missing parameter m"):
        step.evaluate([0.1], [0.0, 0.05], {"h": 0.1})
