"""Legendre transforms, Noether quantities and the discrete Lie–Poisson form.

All are built from the same invariant derivations as the Euler–Lagrange equations:

- F⁻L and F⁺L in the section basis (seed 000 §3.3; docs/conventions.md §3), multiplier terms
  included:  ⟨F⁻L(g, λ), X⟩ = X⃗[L + λ·φ](g),  ⟨F⁺L(g, λ), X⟩ = X⃖[L + λ·φ](g);
- Noether (seed 000 Def. 4.8, Thm 4.9): X is a symmetry when
  ⟨F⁻L, X(α(g))⟩ + f(α(g)) = ⟨F⁺L, X(β(g))⟩ + f(β(g)), and then
  F_X = ⟨F⁺L, X(β(g))⟩ + f(β(g)) is conserved;
- Lie groups (seed 000 §6.1): μ = r*_g dL = X⃗[L], Φᵃ = X⃗[φᵃ] and
  μ_{k+1} + λ_{k+1}·Φ_{k+1} = Ad*_{g_k}(μ_k + λ_k·Φ_k).
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from .._errors import (
    CallableError,
    DomainError,
    InputTypeError,
    ShapeError,
    UnsupportedExpressionError,
    UnsupportedFeatureError,
)
from .._sizes import ops_at_most
from .._symbols import indexed_symbol, multiplier_symbols
from ..groupoids import Groupoid, ProductGroupoid
from ..ir import Graph, Program, from_sympy
from ._callables import (
    as_scalar,
    as_scalar_list,
    call_user,
    check_finite_real,
    check_symbols,
)
from ._junction import slot, slot_substitution
from ._step import (
    DerivedStep,
    SystemFunctions,
    chart_of,
    named,
    next_arrow,
    shifted,
    tidy,
)


@dataclass
class LegendreForms:
    """F⁻L and F⁺L at the named arrow g_{k+offset} with multipliers λ_{k+offset}.

    ``minus_nodes``, ``plus_nodes``: the base points each block of rank components sits
    at, in ``arrow``'s coordinates (None: α(g) and β(g) of a first-order arrow; second
    order: α(A₀), β(A₀) and β(A₁), β(A₂) of the window, :func:`second_order_legendre_forms`);
    ``window``: the number of arrows ``arrow`` holds (1, or 3 for a second-order window)."""

    minus: list
    plus: list
    arrow: tuple
    multipliers: list
    minus_nodes: list | None = None
    plus_nodes: list | None = None
    window: int = 1


def legendre_forms(G: Groupoid, fs: SystemFunctions, offset: int = 0) -> LegendreForms:
    """Both discrete Legendre transforms in the section basis (seed 000 §3.3); for a
    second-order system see :func:`second_order_legendre_forms`."""
    if len(fs.slots) == 2:
        return second_order_legendre_forms(G, fs, offset)
    lam = multiplier_symbols(len(fs.constraints), offset)
    A = slot(G, "l")
    F = shifted(fs, [A], lam)
    g = named(G, offset, False)
    sub = slot_substitution(A, g)
    minus = [tidy(e.xreplace(sub)) for e in G.apply_right(F, A)]
    plus = [tidy(e.xreplace(sub)) for e in G.apply_left(F, A)]
    return LegendreForms(minus, plus, g, lam)


def second_order_legendre_forms(G: Groupoid, fs: SystemFunctions,
                                offset: int = 0) -> LegendreForms:
    """Second-order momenta on a window of three composable arrows (A₀, A₁, A₂), terms
    T₀ = [L + λ_{k}·Φ](A₀, A₁), T₁ = [L + λ_{k+1}·Φ](A₁, A₂) (seed 001 §4; for Q×Q the
    transforms of higher-order discrete mechanics).  Each momentum is the part of a junction
    variation that comes from one side of a cut in the sequence of terms:

    - F⁺ (cut after T₁, momentum at A₂ from the past):
      ( var_{(A₁,A₂)}[T₀ + T₁],  X⃖_{A₂}[T₁] );
    - F⁻ (cut before T₀, momentum at A₀ from the future):
      ( X⃗_{A₀}[T₀],  −var_{(A₀,A₁)}[T₀ + T₁] ),

    so that F⁺L(g_{k-1}, g_k, g_{k+1}) = F⁻L(g_{k+1}, g_{k+2}, g_{k+3}) is the pair of
    second-order DEL at the junctions (g_k, g_{k+1}) and (g_{k+1}, g_{k+2}).  Initial data
    (g₀, p₀) determine g₁, g₂ through F⁻L(g₀, g₁, g₂) = p₀.
    """
    m = len(fs.constraints)
    A = [slot(G, f"m{i}_") for i in range(3)]
    T0 = shifted(fs, [A[0], A[1]], multiplier_symbols(m, offset))
    T1 = shifted(fs, [A[1], A[2]], multiplier_symbols(m, offset + 1))
    plus = ([a - b for a, b in zip(G.apply_left(T0 + T1, A[1]), G.apply_right(T1, A[2]))]
            + G.apply_left(T1, A[2]))
    minus = (G.apply_right(T0, A[0])
             + [b - a for a, b in zip(G.apply_left(T0, A[0]), G.apply_right(T0 + T1, A[1]))])
    arrows = [named(G, offset, False)]
    for o in (1, 2):
        arrows.append(next_arrow(G, arrows[-1], offset + o, False))
    sub: dict = {}
    for a, g in zip(A, arrows):
        sub.update(slot_substitution(a, g))
    # the window's coordinates without repetition, laid out as a second-order step's state
    flat = tuple(arrows[0]) + tuple(G.named_fibre(offset + 1)) + tuple(
        G.named_fibre(offset + 2))
    lam = multiplier_symbols(m, offset) + multiplier_symbols(m, offset + 1)
    # F⁻'s blocks sit at α(A₀), β(A₀); F⁺'s at β(A₁), β(A₂) (the window's four nodes)
    nodes = [tuple(G.source(arrows[0]))] + [tuple(G.target(a)) for a in arrows]
    return LegendreForms([tidy(e.xreplace(sub)) for e in minus],
                         [tidy(e.xreplace(sub)) for e in plus], flat, lam,
                         nodes[:2], nodes[2:], 3)


def section_coefficients(G: Groupoid, section, q: Sequence, parameters: Sequence = ()
                         ) -> list[sp.Expr]:
    """Coefficients X^a(q) of a section in the basis: an index, a list or a callable of q.

    A list (or what the callable returns) holds ``G.rank`` real, finite scalar expressions
    in the base coordinates q and ``parameters``; anything else — a string, a boolean, a
    nested list, nan, oo, I, an undeclared symbol — is a :class:`~symgroupoid.ShapeError` or
    :class:`~symgroupoid.InvalidExpressionError` naming the section.
    """
    if isinstance(section, (np.datetime64, np.timedelta64)):  # integers to `numbers`
        raise ShapeError(f"{G.name}: a section is a basis index, a list of {G.rank} "
                         f"coefficients or a function of q; got {type(section).__name__} "
                         f"{section!r}")
    if isinstance(section, numbers.Integral) and not isinstance(section, (bool, np.bool_)):
        if not 0 <= int(section) < G.rank:
            raise DomainError(f"{G.name}: section index {section} out of range "
                              f"0..{G.rank - 1}")
        return [sp.S.One if a == int(section) else sp.S.Zero for a in range(G.rank)]
    if callable(section):
        coeffs = _called(G, "section", section, q)
    elif isinstance(section, (bool, np.bool_, numbers.Number)) or section is None:
        raise ShapeError(f"{G.name}: a section is a basis index (an integer 0…{G.rank - 1}), "
                         f"a list of {G.rank} coefficients or a function of the base point "
                         f"returning them; got {type(section).__name__} {section!r}")
    else:
        coeffs = section
    if isinstance(coeffs, np.ndarray):
        coeffs = coeffs.tolist()
    if isinstance(coeffs, (str, bytes)) or any(isinstance(c, (str, bytes))
                                              for c in _items(coeffs)):
        raise ShapeError(f"{G.name}: a section is a basis index, a list of {G.rank} "
                         f"coefficients or a function of the base point returning them; "
                         f"got {coeffs!r} (strings are not coefficients)")
    coeffs = as_scalar_list(G.name, "section", coeffs)
    if len(coeffs) != G.rank:
        raise ShapeError(f"{G.name}: a section needs {G.rank} coefficients, got {len(coeffs)}")
    for a, c in enumerate(coeffs):
        check_finite_real(G.name, f"section (coefficient {a})", c)
    check_symbols(G.name, "section", coeffs, _coordinates(q), parameters)
    return coeffs


def section_point(G: Groupoid, q: Sequence):
    """The base point a section (or a quasi-invariance function) receives: its coordinates
    as a tuple, or, where the base is a matrix group (the pair groupoid of a Lie group), its
    matrix, as a holonomic constraint receives it (``G.base_view``); a matrix also reads
    ``q[i]`` as its i-th entry row by row, so a section written for the tuple still reads
    the same numbers."""
    view = G.base_view(tuple(q)) if G is not None else None
    return view if isinstance(view, sp.MatrixBase) else tuple(q)


def _called(G: Groupoid | None, what: str, function, q: Sequence, name: str = ""):
    """``function`` called on the base point it receives (:func:`section_point`); where it
    fails on a base that is a product, the :class:`CallableError` says how that point is
    given there: its coordinates in one flat tuple, not one base point per factor as a
    holonomic constraint receives them (on SO(3) × SO(3), ``q[0][2, 0]`` fails and ``q[6]``
    reads the first factor's entry (3, 1))."""
    try:
        owner = name or (G.name if G is not None else "")
        return call_user(owner, what, function, section_point(G, q))
    except CallableError as err:
        view = G.base_view(tuple(q)) if G is not None else None
        if not isinstance(view, tuple) or all(isinstance(p, sp.Basic) and not
                                              isinstance(p, sp.MatrixBase) for p in view):
            raise
        sizes = ", ".join(str(len(p)) for p in view)
        raise CallableError(
            f"{err}; on a product base the {what} receives the base point's "
            f"{len(q)} coordinates in one flat tuple (the factors' {sizes}, in order, a "
            f"matrix's entries row by row), not one base point per factor as a holonomic "
            f"constraint receives them") from err


def _coordinates(q: Sequence) -> set:
    """The arrow coordinates a base point q = α(g) or β(g) is written in."""
    return set().union(*(sp.sympify(c).free_symbols for c in q))


def _items(value) -> list:
    return list(value) if isinstance(value, (list, tuple)) else []


def _base_function(f, q: Sequence, name: str = "", parameters: Sequence = (),
                   G: Groupoid | None = None) -> sp.Expr:
    """f(q) of a quasi-invariance function (callable or expression), checked as a section's
    coefficients are."""
    if f is None or (not callable(f) and isinstance(f, (int, float)) and f == 0):
        return sp.S.Zero
    value = _called(G, "quasi-invariance function f", f, q, name) if callable(f) else f
    if isinstance(value, (str, bytes)):
        raise ShapeError(f"{name}: the quasi-invariance function f must give an expression, "
                         f"got the string {value!r}")
    expr = as_scalar(name, "quasi-invariance function f", value)
    check_finite_real(name, "quasi-invariance function f", expr)
    check_symbols(name, "quasi-invariance function f", [expr], _coordinates(q), parameters)
    return expr


@dataclass
class NoetherForms:
    """F_X = ⟨F⁺L, X(β(g))⟩ + f(β(g)) and the symmetry defect (zero for a symmetry);
    ``window``: the arrows ``arrow`` holds (3 for a second-order window)."""

    quantity: sp.Expr
    defect: sp.Expr
    arrow: tuple
    multipliers: list
    window: int = 1


def _paired(G: Groupoid, section, nodes: Sequence, values: Sequence,
            parameters: Sequence) -> sp.Expr:
    """Σ_i ⟨block i of ``values``, X(nodes[i])⟩: each block of rank components paired with
    the section at the base point it sits at."""
    out = sp.S.Zero
    for i, q in enumerate(nodes):
        X = section_coefficients(G, section, q, parameters)
        out += sum((c * v for c, v in zip(X, values[i * G.rank:(i + 1) * G.rank])), sp.S.Zero)
    return out


def noether_ends(G: Groupoid, section, f, parameters: Sequence, arrow: Sequence
                 ) -> tuple[list, sp.Expr, list, sp.Expr]:
    """(X(α(g)), f(α(g)), X(β(g)), f(β(g))) of a first-order arrow with coordinates
    ``arrow``: the section's coefficients and the quasi-invariance function at both ends,
    checked as :func:`noether_forms` checks them (the pairing with F∓L is then taken
    elsewhere, e.g. on the expression graph)."""
    before, after = G.source(tuple(arrow)), G.target(tuple(arrow))
    return (section_coefficients(G, section, before, parameters),
            _base_function(f, before, G.name, parameters, G),
            section_coefficients(G, section, after, parameters),
            _base_function(f, after, G.name, parameters, G))


def noether_forms(G: Groupoid, forms: LegendreForms, section, f=None,
                  parameters: Sequence = ()) -> NoetherForms:
    """The Noether quantity of ``section`` (seed 000 Thm 4.9) and its symmetry defect;
    ``parameters``: the symbols the section and ``f`` may use besides the base point.

    First order: F_X = ⟨F⁺L, X(β(g))⟩ + f(β(g)), defect ⟨F⁻L, X(α(g))⟩ + f(α(g)) − F_X.
    Second order (docs/conventions.md §20), on the window (A₀, A₁, A₂) with nodes
    n₀ = α(A₀), n₁ = β(A₀), n₂ = β(A₁), n₃ = β(A₂): F_X = ⟨F⁺L, (X(n₂), X(n₃))⟩ + f(n₂) —
    the change of the terms before the cut after (A₁, A₂) when the nodes n₂, n₃ they share
    with the terms after it move along X — and the defect ⟨F⁻L, (X(n₀), X(n₁))⟩ + f(n₀) −
    F_X, which is the change of L(A₀, A₁) + L(A₁, A₂) when every node moves along X (minus
    f(n₀) − f(n₂)): zero for all windows iff each pair term is invariant."""
    g = forms.arrow
    before = forms.minus_nodes or [G.source(g)]
    after = forms.plus_nodes or [G.target(g)]
    fa, fb = (_base_function(f, q, G.name, parameters, G) for q in (before[0], after[0]))
    lhs = _paired(G, section, before, forms.minus, parameters) + fa
    rhs = _paired(G, section, after, forms.plus, parameters) + fb
    return NoetherForms(rhs, lhs - rhs, g, forms.multipliers, forms.window)


#: random arrows at which a symmetry defect is evaluated; relative size of a defect that
#: counts as rounding (the defect is a difference of sums evaluated in floating point)
NOETHER_SAMPLES = 8
NOETHER_RELATIVE_DEFECT = 1e-9
#: defects up to this many operations are also simplified symbolically
SYMBOLIC_CHECK_OPS = 200


def is_identically_zero(expr: sp.Expr, G: Groupoid, arrow: tuple) -> bool:
    """Whether ``expr`` (a function on G written in ``arrow``'s coordinates, with other
    symbols such as multipliers and parameters free) vanishes on G; see
    :func:`vanishing_check`."""
    return vanishing_check(expr, G, arrow)[0]


def vanishing_check(expr: sp.Expr, G: Groupoid, arrow: tuple, window: int = 1
                    ) -> tuple[bool, str]:
    """Whether ``expr`` vanishes on G (``window`` > 1: on the composable sequences of that
    many arrows, ``arrow`` holding the first arrow's coordinates and each later arrow's
    fibre variables, as a second-order window does), and how that was decided.

    First at :data:`NOETHER_SAMPLES` random arrows of G itself (``G.random_arrow``: on a
    matrix-group base the base points are rotations, not arbitrary 3×3 arrays), with random
    values of the other symbols: a defect above :data:`NOETHER_RELATIVE_DEFECT` times the
    size of its terms there is a counterexample.  A defect that passes and has at most
    :data:`SYMBOLIC_CHECK_OPS` operations is then simplified symbolically, with matrix-group
    fibres parametrised by the fibre chart.  Larger defects, and those the simplification
    cannot decide (a base that is a group, whose points it treats as arbitrary arrays), are
    decided by the samples on G.
    """
    expr = sp.sympify(expr)
    if expr == 0:
        return True, "identically zero"
    sampled = _sampled_defect(expr, G, arrow, window)
    if sampled is False:
        return False, "nonzero at a random arrow"
    if ops_at_most(expr, SYMBOLIC_CHECK_OPS):
        q = tuple(sp.Dummy(f"q{i}", real=True) for i in range(G.base_dim))
        x = tuple(sp.Dummy(f"x{i}", real=True) for i in range(G.rank))
        on_group = last = tuple(G.arrow_from(q, G.fibre_chart(x, q)))
        for j in range(1, window):  # each later arrow from the target of the one before
            y = tuple(sp.Dummy(f"x{j}_{i}", real=True) for i in range(G.rank))
            fibre = tuple(G.fibre_chart(y, G.target(last)))
            last = tuple(G.arrow_from(G.target(last), fibre))
            on_group += fibre
        e = expr.xreplace(dict(zip(arrow, on_group)))
        if sp.simplify(sp.cancel(sp.together(e))) == 0:
            return True, "symbolic"
    if sampled is None:
        return False, "undecided: no random arrow gave a finite value"
    return True, (f"numerical: zero to {NOETHER_RELATIVE_DEFECT:g} relative at "
                  f"{NOETHER_SAMPLES} random arrows of {G.name}")


def _random_window(G: Groupoid, rng: np.random.Generator, window: int) -> list:
    """A random arrow's coordinates, then the fibre variables of ``window`` − 1 random
    arrows each composable after the one before."""
    last = tuple(G.random_arrow(rng))
    out = list(last)
    for _ in range(1, window):
        last = tuple(G.random_arrow(rng, source=[float(c) for c in G.target(last)]))
        out += [float(c) for c in G.fibre_of(last)]
    return out


def _sampled_defect(expr: sp.Expr, G: Groupoid, arrow: tuple, window: int = 1
                    ) -> bool | None:
    """True: |expr| is at rounding level at every usable random arrow (window of
    ``window`` composable arrows); False: it is not at one of them; None: no random arrow
    gave a finite real value."""
    others = sorted(expr.free_symbols - set(arrow), key=sp.default_sort_key)
    rng = np.random.default_rng(20260)
    points, values = [], []
    for _ in range(NOETHER_SAMPLES):
        points.append(_random_window(G, rng, window))
        values.append(rng.uniform(0.5, 1.5, len(others)))
    # the terms' values, summed and their sizes summed here: SymPy's Abs of each term would
    # try to decide its sign symbolically (minutes for the defect of a midpoint step on SE(2))
    terms = _term_values(list(sp.Add.make_args(expr)), list(arrow), others, points, values)
    usable = 0
    for row in terms:
        if row is None:
            continue
        defect, size = sum(row), sum(abs(t) for t in row)
        if not (np.isfinite(defect) and np.isfinite(size)) or abs(complex(defect).imag) > 0:
            continue
        usable += 1
        if abs(complex(defect).real) > NOETHER_RELATIVE_DEFECT * max(size, 1e-300):
            return False
    return True if usable else None


def _term_values(terms: list, arrow: list, others: list, points: list, values: list) -> list:
    """The values of ``terms`` at each sample (``points[i]`` for ``arrow``, ``values[i]``
    for ``others``): one row per sample, None where a term cannot be evaluated there.

    On the expression graph, all samples at once (:class:`symgroupoid.ir.Program`: shared
    subexpressions once, no ``cse`` pass — a minute on the Noether defect of a midpoint step
    on SO(3) with a potential); a value off the real line is NaN there.  A function the
    graph does not take (a Bessel function: nor does NumPy) leaves every sample
    unusable: the check is then undecided."""
    g = Graph()
    symbols = {s: g.input(s) for s in (*arrow, *others)}
    memo: dict = {}
    try:
        nodes = [from_sympy(g, t, symbols, "the Noether defect", memo) for t in terms]
    except UnsupportedExpressionError:
        return [None] * len(points)
    program = Program(graph=g, inputs={"arrow": arrow, "others": others},
                      outputs={"terms": nodes})
    f = program.numpy_function(["terms"], ["arrow", "others"])
    (table,) = f(np.array(points, float).T, np.array(values, float).reshape(len(points), -1).T)
    return [list(column) for column in table.T]


#: Gröbner bases are computed for at most this many holonomic constraints (their cost grows
#: steeply: a planar chain of five links, ten quadrics, takes minutes) and for defects of at
#: most this many operations; larger checks report "not verified"
GROEBNER_CONSTRAINTS = 2
GROEBNER_OPS = 400


def vanishes_on_restriction(expr: sp.Expr, G: Groupoid, arrow: tuple,
                            fs: SystemFunctions) -> bool:
    """Whether ``expr`` vanishes on N = G|_M = {g : ψ(α(g)) = 0 = ψ(β(g))}, M = {ψ = 0} the
    holonomic constraint set (docs/conventions.md §15): the numerator of ``expr``, with the
    arrow parametrised as in :func:`is_identically_zero`, reduces to 0 modulo a Gröbner basis
    of the numerators of ψ(α(g)), ψ(β(g)) (every free symbol a polynomial variable).  A
    sufficient condition, tried for at most GROEBNER_CONSTRAINTS constraints and defects of
    at most GROEBNER_OPS operations; False otherwise and when the expressions are not
    polynomial there."""
    if not 0 < fs.n_holonomic <= GROEBNER_CONSTRAINTS or not ops_at_most(expr, GROEBNER_OPS):
        return False
    q = tuple(sp.Dummy(f"q{i}", real=True) for i in range(G.base_dim))
    x = tuple(sp.Dummy(f"x{i}", real=True) for i in range(G.rank))
    on_group = tuple(G.arrow_from(q, G.fibre_chart(x, q)))
    e = sp.sympify(expr).xreplace(dict(zip(arrow, on_group)))
    ideal = fs.at_base(q) + fs.at_base(G.target(on_group))
    numerators = [sp.fraction(sp.together(f))[0] for f in [e, *ideal]]
    gens = sorted(set().union(*(f.free_symbols for f in numerators)), key=str)
    try:
        basis = sp.groebner([sp.expand(f) for f in numerators[1:]], *gens, order="grevlex")
        _, remainder = basis.reduce(sp.expand(numerators[0]))
    except (sp.PolynomialError, sp.polys.polyerrors.CoercionFailed,
            sp.polys.polyerrors.GeneratorsError, sp.polys.polyerrors.DomainError):
        return False
    return sp.expand(remainder) == 0


def momentum_symbols(rank: int, offset: int) -> list:
    """(μ_{k+offset})_a: discrete momenta in g*."""
    return [indexed_symbol(r"\mu", offset, str(a + 1)) for a in range(rank)]


@dataclass
class LiePoissonForms:
    """The discrete constrained Lie–Poisson equations and their reconstruction step."""

    momentum: list          # μ(g_k) + λ_k·Φ(g_k)
    update: list            # Ad*_{g_k} m_k (next momentum from m_k)
    residuals: list         # μ_{k+1} + λ_{k+1}Φ_{k+1} − Ad*_{g_k}(μ_k + λ_kΦ_k), φ(g_{k+1})
    reconstruction: DerivedStep
    momentum_symbols: list


def lie_poisson_forms(name: str, G: Groupoid, fs: SystemFunctions,
                      parameters: Sequence) -> LiePoissonForms:
    """Seed 000 §6.1 for a matrix Lie group G."""
    if not G.is_lie_group:
        if isinstance(G, ProductGroupoid) and all(f.is_lie_group for f in G.factors):
            raise UnsupportedFeatureError(
                f"{name}: the Lie–Poisson form is derived for one matrix Lie group (seed 000 "
                f"§6.1: Ad* of its matrix); {G.name} is a product of Lie groups, which it "
                f"does not take yet: derive the step with euler_lagrange()")
        raise InputTypeError(f"{name}: the Lie–Poisson form needs a Lie group, not {G.name}")
    m, r = len(fs.constraints), G.rank
    now, nxt = legendre_forms(G, fs, 0), legendre_forms(G, fs, 1)
    g0 = now.arrow
    fibre1, chart1, cmap = chart_of(G, 1)
    g1 = next_arrow(G, g0, 1, False)
    to_g1 = dict(zip(nxt.arrow, g1))
    mu1 = [e.xreplace(to_g1) for e in nxt.minus]
    ad_star = G.Ad_star(G.matrix(g0))
    pulled = list(ad_star * sp.Matrix(now.minus))
    phi1 = [phi.xreplace(slot_substitution(fs.slots[0], g1)) for phi in fs.constraints]
    residuals = [sp.expand(a - b) for a, b in zip(mu1, pulled)] + phi1

    m1 = momentum_symbols(r, 1)
    recon_res = [sp.expand(a - b) for a, b in zip(mu1, m1)] + phi1
    ad_star1 = G.Ad_star(G.matrix(g1).xreplace(cmap))
    next_momentum = list(ad_star1 * sp.Matrix(m1))
    lam1 = multiplier_symbols(m, 1)
    recon = DerivedStep(
        name=f"{name}_reconstruction", groupoid=G, order=1, residuals=recon_res,
        knowns=list(m1), fibre_unknowns=fibre1, chart_unknowns=chart1, chart_map=cmap,
        multipliers_next=lam1, next_knowns=[sp.expand(e) for e in next_momentum],
        parameters=list(parameters), n_constraints=m, offsets=(1, 1), arrows={1: g1},
        prediction=[sp.S.Zero] * r + [sp.S.Zero] * m)
    m0 = momentum_symbols(r, 0)
    update = list(ad_star * sp.Matrix(m0))
    return LiePoissonForms(now.minus, update, residuals, recon, m0)

