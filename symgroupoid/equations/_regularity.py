"""Derivation-time diagnosis of step equations that cannot determine a step.

A step F(u; k, p) = 0 determines its unknowns u (chart coordinates of the newest arrow, then
the multipliers λ_{k+1}) near a solution exactly when the step Jacobian ∂F/∂u is invertible.
For a first-order constrained system (seed 000 §3.3; docs/conventions.md §4) it has the blocks

    ∂F/∂u = [ A  B ]    A = ∂(DEL)/∂x,   B = ∂(DEL)/∂λ_{k+1} = −X⃗[φ](g_{k+1}),
            [ C  0 ]    C = ∂φ(g_{k+1})/∂x,

and regularity of L (seed 000 Thm 2.16: F⁻L, F⁺L local diffeomorphisms) is its invertibility.
:func:`diagnose` finds, before any step is taken,

- residuals that are identically zero (a null Lagrangian: constant, zero, or a difference
  f(β(g)) − f(α(g)); a constraint that is identically zero), structurally or numerically;
- residuals that involve no unknown, and unknowns that enter no residual (a multiplier whose
  constraint depends only on the target of the arrow, so that X⃗[φ] = 0);
- a Jacobian singular at every one of several random admissible points, classified as
  dependent constraints (rows of C), undetermined multipliers (columns of B), or else a
  Lagrangian that is not regular, naming the rows and columns of the null spaces.

The residuals are analytic in the unknowns, the knowns and the parameters, so a determinant
that vanishes at several random points of an open set vanishes identically; a regular point
anywhere clears the system.  Points where the residuals are not finite are not evidence and
are replaced by others.  The points come from a fixed seed, so the diagnosis is deterministic.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from .._errors import CoordinateNameError, DegenerateLagrangianWarning, DegenerateSystemError
from ..derivation._limit import parameter_value
from ..groupoids._user import RESERVED_NAMES

#: causes reported in :attr:`DegenerateSystemError.findings`
IDENTICALLY_ZERO = "identically zero"
NO_UNKNOWN = "involves no unknown"
UNUSED_UNKNOWN = "unknown enters no equation"
UNDETERMINED_MULTIPLIER = "undetermined multiplier"
DEPENDENT_CONSTRAINTS = "dependent constraints"
NOT_REGULAR = "not regular"

_SMALL = 1e-8     # rows this small (relative to max(1, the largest entry)) may be noise
_NUDGE = 1e-7     # relative move of the inputs that tells rounding noise from a function
_RANK = 1e-12     # singular values below this fraction of the largest one are zero
_SUPPORT = 1e-3   # weight of a row/column in a null space that counts it as involved
_POINTS = 3       # random points that must all agree before anything is concluded
_ATTEMPTS = 12    # points tried at most (non-finite ones are skipped)
_SIMPLIFY_NODES = 400  # rows of at most this many graph nodes are checked for zero exactly

HOLONOMIC_HINT = (
    "a constraint on configurations belongs on the configuration space: give it as "
    "DiscreteSystem(..., holonomic=lambda q: [...]) for constraints ψ(q) on the base point q "
    "(docs/conventions.md §15), whose multiplier is determined with the next arrow")


@dataclass(frozen=True)
class Finding:
    """One reason why the step cannot be solved."""

    cause: str
    equations: tuple[str, ...]
    unknowns: tuple[str, ...]
    text: str


@dataclass
class Layout:
    """How to name the rows and columns of a step: equation labels, which rows are
    constraints (with their names) and which unknowns are their multipliers."""

    labels: list[str]
    unknowns: list[str]
    constraint_rows: list[int] = field(default_factory=list)
    constraint_names: list[str] = field(default_factory=list)
    multiplier_columns: list[int] = field(default_factory=list)
    order: int = 1

    def constraint_of_row(self, i: int) -> str | None:
        if i in self.constraint_rows:
            return self.constraint_names[self.constraint_rows.index(i)]
        return None


def default_layout(step, section_labels: Sequence[str] | None = None,
                   constraint_letter: str | None = None,
                   constraint_rows: Sequence[int] | None = None) -> Layout:
    """Rows: one per basis section (``section_labels``, default "the DEL along X_i"), then
    the constraints (the last ``step.n_constraints`` rows unless ``constraint_rows`` is given)
    named φ_a (Φ_a for second order, or ``constraint_letter``) and the holonomic ones ψ_a;
    multipliers: the last ``step.n_constraints`` unknowns."""
    n, m = len(step), step.n_constraints
    rows = list(constraint_rows) if constraint_rows is not None else list(range(n - m, n))
    letter = constraint_letter or ("Φ" if step.order == 2 else "φ")
    held = getattr(step, "n_holonomic", 0)
    names = ([f"{letter}_{a + 1}" for a in range(len(rows) - held)]
             + [f"ψ_{a + 1}" for a in range(held)])
    free = [i for i in range(n) if i not in rows]
    if section_labels is None:
        section_labels = [f"the DEL along X_{s + 1}" for s in range(len(free))]
    labels = [""] * n
    for i, text in zip(free, section_labels):
        labels[i] = f"equation {i + 1} ({text})"
    for i, name in zip(rows, names):
        labels[i] = f"equation {i + 1} ({name} = 0)"
    u = len(step.unknowns)
    return Layout(labels=labels, unknowns=[str(s) for s in step.unknowns],
                  constraint_rows=rows, constraint_names=names,
                  multiplier_columns=list(range(u - m, u)), order=step.order)


def diagnose(step, layout: Layout | None = None, *, points: int = _POINTS,
             seed: int = 0) -> None:
    """Raise :class:`DegenerateSystemError` if ``step`` cannot determine its unknowns.

    Structural checks first (exact zeros, symbols that do not occur); then ``points`` random
    admissible points (see :func:`random_point`) through ``step.evaluate``.
    """
    layout = layout or default_layout(step)
    findings = structural_findings(step, layout)
    if not findings:
        findings = numeric_findings(step, layout, points, seed)
    if findings:
        raise DegenerateSystemError(_message(step, findings), findings=tuple(findings))


def _message(step, findings: Sequence[Finding]) -> str:
    texts = [f.text[:1].upper() + f.text[1:] for f in findings]
    body = " ".join(f"({i + 1}) {t}" for i, t in enumerate(texts)) if len(texts) > 1 else texts[0]
    return (f"{step.name}: the step equations cannot determine the step, so no simulation "
            f"could solve them. {body}")


# --- structural checks ------------------------------------------------------------------------

def _unknown_symbols(step) -> list[set] | None:
    """For each unknown, the symbols of the residuals through which it enters: itself and
    the fibre variables whose chart expression (``step.reconstruction``) involves it; None
    when the step does not expose its chart."""
    reconstruction = getattr(step, "reconstruction", None)
    if reconstruction is None:
        return None
    out = []
    for u in step.unknowns:
        syms = {u}
        syms |= {f for f, e in reconstruction.items() if u in sp.sympify(e).free_symbols}
        out.append(syms)
    return out


def program_of(step):
    """The step's program over the expression graph, or None when the step is symbolic
    only (it uses undefined functions or other expressions code cannot evaluate)."""
    from .._errors import UnsupportedExpressionError

    try:
        return step.program
    except (UnsupportedExpressionError, AttributeError):
        return None


def structural_findings(step, layout: Layout) -> list[Finding]:
    """Residuals that are exactly 0, residuals free of every unknown, unknowns in no
    residual — read off the program's graph (which unknown inputs each residual node
    depends on); for a symbolic-only step, off its SymPy residuals."""
    program = program_of(step)
    if program is not None:
        return _graph_findings(step, program, layout)
    return _sympy_findings(step, layout)


def _graph_findings(step, program, layout: Layout) -> list[Finding]:
    from ..ir import to_sympy

    g = program.graph
    F = program.outputs["F"]
    unknown_nodes = [g.inputs.get(u) for u in step.unknowns]
    reached = [set(g.reachable([r])) for r in F]
    samples = sample(step, _POINTS, 0)
    numeric = len(samples) == _POINTS
    small = (np.all([_small_residuals(s_) for s_ in samples], axis=0) if numeric
             else np.ones(len(F), dtype=bool))
    vanish = (np.all([_zero_residuals(s_) for s_ in samples], axis=0) if numeric
              else np.zeros(len(F), dtype=bool))

    def is_zero(i: int) -> bool:
        """Exactly zero: structurally; or, for a row that is numerically small everywhere
        sampled, as a SymPy expression when it is small enough to simplify (tr(S E) = 0
        for a symmetric S and a skew E, which the graph does not cancel), else by the
        numeric test that tells rounding noise from a small value."""
        if F[i] == g.zero:
            return True
        if not small[i]:
            return False
        if len(reached[i]) <= _SIMPLIFY_NODES:
            return sp.expand(to_sympy(g, [F[i]])[0]) == 0
        return bool(vanish[i])

    zero = [i for i in range(len(F)) if is_zero(i)]
    idle = [i for i in range(len(F)) if i not in zero
            and not any(n is not None and n in reached[i] for n in unknown_nodes)]
    unused = [j for j, n in enumerate(unknown_nodes)
              if n is None or not any(n in r for r in reached)]
    shown = {}
    for i in idle:
        if len(reached[i]) <= 200:
            shown[i] = to_sympy(g, [F[i]])[0]
    return compose(layout, zero, idle, unused, shown)


def _sympy_findings(step, layout: Layout) -> list[Finding]:
    residuals = [sp.sympify(r) for r in step.residuals]
    zero = [i for i, r in enumerate(residuals) if r == 0]
    through = _unknown_symbols(step)
    if through is None:
        return compose(layout, zero, [], [])
    every = set().union(*through)
    free = [r.free_symbols for r in residuals]
    idle = [i for i in range(len(residuals)) if i not in zero and not free[i] & every]
    unused = [j for j, syms in enumerate(through) if not any(f & syms for f in free)]
    return compose(layout, zero, idle, unused, {i: residuals[i] for i in idle})


# --- composing findings ----------------------------------------------------------------------

def _names(items: Sequence[str]) -> str:
    items = list(items)
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def _verb(items: Sequence, one: str, many: str) -> str:
    return one if len(items) == 1 else many


def _short(expr) -> str:
    text = str(expr)
    return text if len(text) <= 80 else text[:77] + "..."


def compose(layout: Layout, zero: Sequence[int], idle: Sequence[int],
            unused: Sequence[int], shown: dict | None = None) -> list[Finding]:
    """Findings from rows that vanish, rows without unknowns and unknowns without rows."""
    out: list[Finding] = []
    crow = set(layout.constraint_rows)
    zero_eq = [i for i in zero if i not in crow]
    zero_c = [i for i in zero if i in crow]
    n_eq = len(layout.labels) - len(crow)
    if zero_eq:
        out.append(_zero_equations(layout, zero_eq, all_of_them=len(zero_eq) == n_eq))
    if zero_c:
        out.append(_zero_constraints(layout, zero_c))
    idle_eq = [i for i in idle if i not in crow]
    idle_c = [i for i in idle if i in crow]
    if idle_eq:
        out.append(_idle_equations(layout, idle_eq, shown or {}))
    if idle_c:
        out.append(_idle_constraints(layout, idle_c))
    if len(zero) == len(layout.labels):
        return out  # nothing is left for an unknown to enter
    explained = {layout.multiplier_columns[layout.constraint_rows.index(i)]
                 for i in zero_c if layout.multiplier_columns}
    mcols = set(layout.multiplier_columns)
    chart = [j for j in unused if j not in mcols]
    lam = [j for j in unused if j in mcols and j not in explained]
    if chart:
        out.append(_unused_chart(layout, chart))
    if lam:
        out.append(_undetermined(layout, lam))
    return out


def _zero_equations(layout: Layout, rows: Sequence[int], all_of_them: bool) -> Finding:
    eqs = tuple(layout.labels[i] for i in rows)
    if all_of_them:
        text = (f"The Euler–Lagrange equations vanish identically: {_names(eqs)} "
                f"{_verb(eqs, 'reads', 'read')} 0 = 0. The discrete Lagrangian is a null "
                "Lagrangian — a constant, zero (e.g. a rigid body with zero inertia), or a "
                "difference f(β(g)) − f(α(g)) such as a·(q₁ − q₀)/h or (q₁² − q₀²)/(2h) — "
                "and determines no motion.")
    else:
        text = (f"{_names(eqs)} {_verb(eqs, 'reads', 'read')} 0 = 0: the discrete Lagrangian "
                "and the constraints do not change along these sections, so nothing "
                "determines the motion in these directions.")
    return Finding(IDENTICALLY_ZERO, eqs, (), text)


def _zero_constraints(layout: Layout, rows: Sequence[int]) -> Finding:
    names = [layout.constraint_of_row(i) for i in rows]
    lam = tuple(layout.unknowns[layout.multiplier_columns[layout.constraint_rows.index(i)]]
                for i in rows if layout.multiplier_columns)
    one = len(names) == 1
    text = (f"The constraint{'' if one else 's'} {_names(names)} "
            f"{_verb(names, 'is', 'are')} identically zero: "
            + ("it constrains nothing" if one else "they constrain nothing")
            + (f" and {'leaves its multiplier' if one else 'leave their multipliers'} "
               f"{_names(lam)} undetermined" if lam else "")
            + f"; remove {'it' if one else 'them'}.")
    return Finding(IDENTICALLY_ZERO, tuple(layout.labels[i] for i in rows), lam, text)


def _idle_equations(layout: Layout, rows: Sequence[int], shown: dict) -> Finding:
    eqs = tuple(layout.labels[i] for i in rows)
    exprs = "; ".join(f"{_short(shown[i])} = 0" for i in rows if i in shown)
    text = (f"{_names(eqs)} {_verb(eqs, 'involves', 'involve')} none of the unknowns"
            + (f" ({exprs})" if exprs else "")
            + ": a condition on the known state, not an equation for the step. The discrete "
            "Lagrangian does not depend on the unknown arrow in these directions (e.g. it "
            "depends on the source α(g) or the target β(g) of the arrow only).")
    return Finding(NO_UNKNOWN, eqs, (), text)


def _idle_constraints(layout: Layout, rows: Sequence[int]) -> Finding:
    names = [layout.constraint_of_row(i) for i in rows]
    newest = "g_{k+2}" if layout.order == 2 else "g_{k+1}"
    why = ("(the unknown arrow moves its target β in no direction that changes ψ)"
           if all(n.startswith("ψ") for n in names) else
           "(e.g. it depends only on the source α(g) of the arrow)")
    text = (f"The constraint{'s' if len(names) > 1 else ''} {_names(names)} "
            f"{_verb(names, 'does', 'do')} not depend on the unknown arrow {newest} "
            f"{why}: it restricts the known state, not the step, and its multiplier is not "
            "determined.")
    return Finding(NO_UNKNOWN, tuple(layout.labels[i] for i in rows), (), text)


def _unused_chart(layout: Layout, cols: Sequence[int]) -> Finding:
    names = tuple(layout.unknowns[j] for j in cols)
    text = (f"The unknown{'s' if len(names) > 1 else ''} {_names(names)} "
            f"{_verb(names, 'enters', 'enter')} no equation: the discrete Lagrangian and the "
            "constraints do not vary with "
            f"{'it' if len(names) == 1 else 'them'}, so nothing determines "
            f"{'it' if len(names) == 1 else 'them'}.")
    return Finding(UNUSED_UNKNOWN, (), names, text)


def _undetermined(layout: Layout, cols: Sequence[int], dependent: bool = False) -> Finding:
    names = tuple(layout.unknowns[j] for j in cols)
    phis = [layout.constraint_names[layout.multiplier_columns.index(j)] for j in cols]
    plural = len(names) > 1
    if dependent:
        head = (f"The multipliers {_names(names)} of {_names(phis)} are not determined by "
                "the equations: a combination of these constraints is unchanged")
    else:
        head = (f"The multiplier{'s' if plural else ''} {_names(names)} of {_names(phis)} "
                f"{_verb(names, 'enters', 'enter')} no equation, so nothing determines "
                f"{'them' if plural else 'it'}: {_verb(names, 'its', 'each')} constraint is "
                "unchanged")
    if all(p.startswith("ψ") for p in phis):
        text = (f"{head} as the junction node moves (dψ(ρ(X)) = 0 for every basis section X, "
                "ρ the anchor): the sections do not move the base point in a direction that "
                "changes ψ, so ψ does not constrain the motion; remove it, or check that it "
                "depends on coordinates of the base point the sections move.")
    else:
        text = (f"{head} under the variation at the junction (X⃗[φ] = 0 at the arrow it "
                "constrains), which happens when a constraint depends only on the target β(g) "
                f"of the arrow, as φ = |q₁|² − ℓ² does; {HOLONOMIC_HINT}.")
    return Finding(UNDETERMINED_MULTIPLIER, (), names, text)


# --- numeric checks -------------------------------------------------------------------------

def random_point(step, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(unknowns, knowns, parameters) at random: the known arrows composable and drawn by the
    groupoid (group parts in the group), other knowns (multipliers, momenta) standard normal,
    parameters by :func:`parameter_value`, and the unknowns near the step's prediction."""
    G = step.groupoid
    arrows = step.arrows
    offsets = sorted(arrows)
    values: dict = {}
    previous = None
    for o in offsets[:-1]:
        a = G.random_arrow(rng) if previous is None else G.random_arrow(rng, G.target(previous))
        names, nums = (arrows[o], a) if previous is None else (G.fibre_of(arrows[o]),
                                                               G.fibre_of(a))
        values.update({s: float(v) for s, v in zip(names, nums) if isinstance(s, sp.Symbol)})
        previous = a
    knowns = np.array([values[s] if s in values else rng.normal() for s in step.knowns])
    params = np.array([parameter_value(s, rng) for s in step.parameters])
    guess = _prediction(step, knowns, params)
    n_chart = len(step.unknowns) - step.n_constraints
    chart = np.asarray(G.random_chart(rng), float)
    if chart.shape != (n_chart,):
        chart = rng.uniform(-0.5, 0.5, n_chart)
    delta = np.concatenate([0.2 * chart, 0.2 * rng.normal(size=step.n_constraints)])
    return guess + delta, knowns, params


def _prediction(step, knowns: np.ndarray, params: np.ndarray) -> np.ndarray:
    """The step's prediction of the unknowns at these knowns (0 where it is not a finite
    number, and everywhere when the step has none): from its program's ``predict`` output
    when it has one (NumPy, no SymPy evaluation), else from the SymPy expressions."""
    prediction = list(getattr(step, "prediction", []))
    if len(prediction) != len(step.unknowns):
        return np.zeros(len(step.unknowns))
    program = program_of(step)
    if program is not None and "predict" in program.outputs:
        with np.errstate(all="ignore"):
            guess = program.numpy_function(["predict"], ["known", "p"])(knowns, params)[0]
        return np.where(np.isfinite(guess), guess, 0.0)
    at = {s: sp.Float(v) for s, v in zip(step.knowns, knowns)}
    return np.array([_number(e, at) for e in prediction])


def _number(expr, at: dict) -> float:
    try:
        value = complex(sp.sympify(expr).xreplace(at).evalf())
    except (TypeError, ValueError, ZeroDivisionError):
        return 0.0
    return value.real if np.isfinite(value.real) and value.imag == 0 else 0.0


def numeric(step) -> bool:
    """Whether the residuals can be evaluated numerically: the step has a program (no
    undefined functions such as an abstract L_d(…), no unevaluated derivatives)."""
    return program_of(step) is not None


@dataclass
class Sample:
    """F and J at a random point, and at the same point with every input moved by a relative
    ``_NUDGE``: a genuine value moves by about that fraction, rounding noise by ~100 %."""

    F: np.ndarray
    J: np.ndarray
    F_nudged: np.ndarray
    J_nudged: np.ndarray


def _evaluate(step, u, k, p) -> tuple[np.ndarray, np.ndarray]:
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        F, J = step.evaluate(u, k, p)
    return np.asarray(F, float), np.asarray(J, float)


def sample(step, points: int, seed: int) -> list[Sample]:
    """:class:`Sample` at ``points`` random points where everything is finite (fewer if
    not found).

    A point whose state cannot be drawn, or where F or J is not finite, is replaced by
    another; if ``step.evaluate`` itself fails (a function NumPy cannot evaluate), there is
    no numeric evidence at all and nothing is returned.  The samples of a step are drawn
    once (the structural and the numeric checks read the same ones).
    """
    memo = getattr(step, "__dict__", {}).setdefault("_regularity_samples", {})
    if (points, seed) not in memo:
        memo[(points, seed)] = _draw_samples(step, points, seed)
    return list(memo[(points, seed)])


def _draw_samples(step, points: int, seed: int) -> list[Sample]:
    rng = np.random.default_rng(seed)
    out: list[Sample] = []
    attempts = 0
    while len(out) < points and attempts < _ATTEMPTS:
        drawn = []
        while len(drawn) < points - len(out) and attempts < _ATTEMPTS:
            attempts += 1
            try:
                u, k, p = random_point(step, rng)
            except (ArithmeticError, ValueError, TypeError):
                continue
            nudge = [x * (1 + _NUDGE * rng.uniform(-1, 1, np.shape(x))) for x in (u, k, p)]
            drawn.append(((u, k, p), tuple(nudge)))
        if not drawn:
            break
        try:
            values = _evaluate_points(step, [d[0] for d in drawn] + [d[1] for d in drawn])
        except Exception:  # noqa: BLE001 - no numeric evidence; the structural checks stand
            return []
        for i in range(len(drawn)):
            both = values[i] + values[len(drawn) + i]
            if all(np.all(np.isfinite(v)) for v in both):
                out.append(Sample(*both))
    return out


def _evaluate_points(step, points: list) -> list[tuple[np.ndarray, np.ndarray]]:
    """(F, J) at each (u, k, p) of ``points``: a step's program walked once for all of them
    (:func:`symgroupoid.ir.interpret`, no code compiled), else ``step.evaluate`` per point."""
    from ..ir import interpret
    from ._step import StepEquations

    program = program_of(step)
    if type(step).evaluate is not StepEquations.evaluate or program is None:
        return [_evaluate(step, *point) for point in points]
    U, K, P = (np.stack([np.asarray(pt[i], float) for pt in points], axis=-1)
               for i in range(3))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        F, J = interpret(program, ["F", "J"], ["u", "known", "p"], U, K, P)
    J = J.reshape((len(step), len(step.unknowns), len(points)))
    return [(F[:, b], J[:, :, b]) for b in range(len(points))]


def _vanishing(value: np.ndarray, nudged: np.ndarray, scale: float) -> np.ndarray:
    """Rows (of a vector or matrix) that are zero up to rounding: exactly zero, or small
    (≤ _SMALL·max(1, scale)) and changing by more than 10 % under the relative nudge of the
    inputs — rounding noise, where a genuine function of that size would move by ~_NUDGE."""
    value, nudged = np.atleast_2d(value.T).T, np.atleast_2d(nudged.T).T
    size = np.linalg.norm(value, axis=1)
    change = np.linalg.norm(nudged - value, axis=1)
    small = size <= _SMALL * max(1.0, scale)
    return (size == 0) | (small & (change > 0.1 * size))


def _zero_rows(s: Sample) -> np.ndarray:
    return _vanishing(s.J, s.J_nudged, float(np.max(np.abs(s.J), initial=0.0)))


def _zero_columns(s: Sample) -> np.ndarray:
    return _vanishing(s.J.T, s.J_nudged.T, float(np.max(np.abs(s.J), initial=0.0)))


def _small_residuals(s: Sample) -> np.ndarray:
    """Residuals at most _SMALL relative to the sample's scale (candidates for zero)."""
    scale = float(max(np.max(np.abs(s.F), initial=0.0), np.max(np.abs(s.J), initial=0.0)))
    return np.abs(s.F) <= _SMALL * max(1.0, scale)


def _zero_residuals(s: Sample) -> np.ndarray:
    scale = float(max(np.max(np.abs(s.F), initial=0.0), np.max(np.abs(s.J), initial=0.0)))
    return _vanishing(s.F, s.F_nudged, scale)


def _equilibrated(J: np.ndarray) -> np.ndarray:
    r = np.linalg.norm(J, axis=1)
    J = J / np.where(r > 0, r, 1.0)[:, None]
    c = np.linalg.norm(J, axis=0)
    return J / np.where(c > 0, c, 1.0)[None, :]


def _null_spaces(J: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """Numerical rank of the equilibrated J and bases of its left and right null spaces."""
    U, s, Vt = np.linalg.svd(_equilibrated(J))
    rank = int(np.sum(s > _RANK * s[0])) if s.size and s[0] > 0 else 0
    return rank, U[:, rank:], Vt[rank:].T


def _support(basis: np.ndarray) -> set[int]:
    return set(np.flatnonzero(np.linalg.norm(basis, axis=1) > _SUPPORT).tolist())


def numeric_findings(step, layout: Layout, points: int = _POINTS,
                     seed: int = 0) -> list[Finding]:
    """Zero rows/columns and rank deficiency of the Jacobian, each required at every sampled
    point; nothing is concluded from fewer than ``points`` finite samples."""
    if not numeric(step):
        return []
    samples = sample(step, points, seed)
    n = len(layout.labels)
    if len(samples) < points or any(s.J.shape != (n, n) for s in samples):
        return []
    zero_rows = np.all([_zero_rows(s) for s in samples], axis=0)
    zero_cols = np.all([_zero_columns(s) for s in samples], axis=0)
    if zero_rows.any() or zero_cols.any():
        vanish = np.all([_zero_residuals(s) for s in samples], axis=0)
        rows = np.flatnonzero(zero_rows)
        zero = [int(i) for i in rows if vanish[i]]
        idle = [int(i) for i in rows if not vanish[i]]
        return compose(layout, zero, idle, [int(j) for j in np.flatnonzero(zero_cols)])
    spaces = [_null_spaces(s.J) for s in samples]
    if any(rank == n for rank, _, _ in spaces):
        return []
    return [_classify(layout, samples, spaces)]


def _classify(layout: Layout, samples, spaces) -> Finding:
    """Dependent constraint rows, then dependent multiplier columns, else not regular."""
    rows, cols = layout.constraint_rows, layout.multiplier_columns
    if rows:
        sub = [_null_spaces(s.J[rows, :]) for s in samples]
        if all(rank < len(rows) for rank, _, _ in sub):
            involved = sorted(set().union(*(_support(left) for _, left, _ in sub)))
            names = [layout.constraint_names[i] for i in involved]
            lam = tuple(layout.unknowns[cols[i]] for i in involved) if cols else ()
            text = (f"The constraints {_names(names)} are dependent (their derivatives on the "
                    "unknown arrow are linearly dependent at every sampled point), so the "
                    "constraint set is not cut out by independent equations"
                    + (f" and the multipliers {_names(lam)} are not determined" if lam else "")
                    + "; remove the redundant constraints.")
            return Finding(DEPENDENT_CONSTRAINTS, tuple(layout.labels[rows[i]]
                                                        for i in involved), lam, text)
    if cols:
        sub = [_null_spaces(s.J[:, cols]) for s in samples]
        if all(rank < len(cols) for rank, _, _ in sub):
            involved = sorted(set().union(*(_support(right) for _, _, right in sub)))
            return _undetermined(layout, [cols[i] for i in involved], dependent=True)
    rank = max(r for r, _, _ in spaces)
    unknowns = sorted(set().union(*(_support(right) for _, _, right in spaces)))
    equations = sorted(set().union(*(_support(left) for _, left, _ in spaces)))
    eqs = tuple(layout.labels[i] for i in equations)
    names = tuple(layout.unknowns[j] for j in unknowns)
    on = " on the constraint set" if rows else ""
    text = (f"The step Jacobian is singular at every sampled point (rank {rank} of "
            f"{len(layout.labels)}): the discrete Lagrangian is not regular{on} (seed 000 "
            f"Thm 2.16); the dependent equations are {_names(eqs)}, and the unknowns "
            f"{_names(names)} are not determined along the null directions.")
    return Finding(NOT_REGULAR, eqs, names, text)


# --- entry point for the systems --------------------------------------------------------------

def check_coordinate_names(step) -> None:
    """A coordinate named like the multipliers' key would make ``step.symbol`` ambiguous."""
    names = set(step.groupoid.symbols_by_name(0))
    clash = sorted(names & set(RESERVED_NAMES))
    if clash:
        raise CoordinateNameError(
            f"{step.name}: the coordinate name {clash[0]!r} of {step.groupoid.name} is "
            f"reserved for the multipliers ({', '.join(map(repr, RESERVED_NAMES))} all name "
            "λ in step.symbol); rename the coordinate")


def check_step(step, *, distribution: int | None = None, lie_poisson: bool = False,
               time_steps: Sequence = ()) -> None:
    """The derivation-time checks of a system's step: coordinate names, then
    :func:`diagnose` with the rows named for the kind of step, then :func:`check_kinetic`
    with the candidate step parameters ``time_steps``.

    ``distribution``: dim D_c of a nonholonomic step (its first rows are the DEL along the
    basis of D_c, the rest the constraints ψ defining M_c, docs/conventions.md §10);
    ``lie_poisson``: the reconstruction step of the Lie–Poisson form (seed 000 §6.1).
    """
    check_coordinate_names(step)
    if distribution is not None:
        n = len(step)
        layout = default_layout(
            step, [f"the DEL along the D_c basis element {a + 1}" for a in range(distribution)],
            constraint_letter="ψ", constraint_rows=range(distribution, n))
    elif lie_poisson:
        rank = len(step) - step.n_constraints
        layout = default_layout(
            step, [f"μ + λ·Φ = m_{{k+1}} along E_{a + 1}" for a in range(rank)])
    else:
        layout = default_layout(step)
    diagnose(step, layout)
    check_kinetic(step, layout, time_steps)


# --- the continuous limit: a degenerate kinetic energy (docs/conventions.md §19) -------------

#: cause reported in :attr:`DegenerateSystemError.findings` for a degenerate kinetic energy
DEGENERATE_KINETIC = "degenerate kinetic energy"

_KINETIC_RANK = 1e-10  # singular values of the leading term below this fraction are zero
_GYROSCOPIC = 1e-6     # an order-h⁰ block below this fraction of the step's scale vanishes
_FLOOR = 1e-11         # rows/columns below this fraction of the largest are not rescaled


@dataclass
class LeadingTerms:
    """The step Jacobian at a state of step h near the identity, restricted to the
    constraint directions: h·Yᵀ(∂F/∂x)Z = R₀ + h R₁ + h² R₂ + … (Y ⊥ the constraint forces,
    Z tangent to the constraints).  R₀ = −(the velocity Hessian of the continuous limit) in
    section × chart coordinates; ``left``/``right`` span its null spaces, ``chart`` maps
    the columns of Z back to the step's unknowns."""

    R0: np.ndarray
    R1: np.ndarray
    scale: float
    rank: int
    left: np.ndarray
    right: np.ndarray
    chart: list
    Z: np.ndarray

    @property
    def size(self) -> int:
        return self.R0.shape[1]

    def first_order_regular(self) -> bool:
        """Whether the order-h⁰ block on the null spaces, leftᵀ R₁ right, is invertible."""
        block = self.left.T @ self.R1 @ self.right
        if block.size == 0:
            return False
        sv = np.linalg.svd(block, compute_uv=False)
        return bool(sv[-1] > _GYROSCOPIC * self.scale)


def check_kinetic(step, layout: Layout, time_steps: Sequence) -> None:
    """Refuse (or warn about) a degenerate kinetic energy (docs/conventions.md §19).

    ``time_steps``: the step parameter (the declared one, or those the continuous limit
    identifies; None for a time groupoid's own t₁ − t₀); nothing is checked without one, and
    with several the kinetic energy must be degenerate for each.  At three points (q, v)
    (:func:`~symgroupoid.derivation._limit.limit_points`) the step is evaluated at the state
    g_k = g_h(q, v) with the step at h (on a time groupoid the time row and unknown left out),
    for the scales h of :data:`~symgroupoid.derivation._limit.SCALES`, and h·∂F/∂x is
    extrapolated to its leading term R₀, restricted to the constraint directions.  R₀ is
    minus the velocity Hessian ∂²L/∂v² of the continuous limit: on Q×Q, ∂F/∂q_{k+1} =
    D₁D₂L_d(q_k, q_{k+1}) = −M/h + O(1).  Rank deficient at every point: a
    :class:`DegenerateSystemError` naming the direction, unless the order-h⁰ term (the
    velocity-linear part of L) is invertible on the null directions, which is a
    :class:`DegenerateLagrangianWarning`.
    """
    if step.order != 1 or not time_steps or not numeric(step):
        return
    found = [_degenerate_terms(step, layout, t) for t in time_steps]
    if any(terms is None for terms in found):
        return  # no evidence, or regular with some step
    terms, time_step = found[0], time_steps[0]
    first = terms[0]
    null = first.Z @ first.right
    unknowns = [layout.unknowns[j] for j in first.chart]
    shown = _directions(null, [_velocity_name(u) for u in unknowns])
    weight = np.linalg.norm(null, axis=1)
    involved = tuple(u for u, w in zip(unknowns, weight) if w > _SUPPORT * weight.max())
    on = " restricted to the constraint directions" if layout.constraint_rows else ""
    head = (f"the velocity Hessian ∂²L/∂v² of the continuous limit L(q, v) = "
            f"lim_{{h→0}} L_d(g_h(q, v))/h{on} is singular along {shown} (rank "
            f"{first.rank} of {first.size} at every sampled point; the step h is "
            f"{time_step if time_step is not None else 't₁ − t₀'})")
    if all(t.first_order_regular() for t in terms):
        warnings.warn(DegenerateLagrangianWarning(
            f"{step.name}: {head}; velocity-linear terms of L make the step regular along it "
            f"(the continuous equations are of first order there), and the two-step discrete "
            f"flow carries parasitic modes beside the motion (docs/conventions.md §19)"),
            stacklevel=6)  # the caller of euler_lagrange() (through its two decorators)
        return
    text = (f"The kinetic energy is degenerate: {head}. The step equations determine that "
            f"direction only through the potential, at order h, so along it the discrete flow "
            f"has a period-2 mode that does not die out (it grows), and no solution "
            f"approximates a motion as h → 0 (docs/conventions.md §19). Give L a kinetic "
            f"energy along {shown}, or constrain the motion along it (constraints= or "
            f"holonomic=).")
    finding = Finding(DEGENERATE_KINETIC, (), involved, text)
    raise DegenerateSystemError(f"{step.name}: the discrete Lagrangian has no regular "
                                f"continuous limit, so its steps approximate no motion. {text}",
                                findings=(finding,))


def _degenerate_terms(step, layout: Layout, time_step) -> list[LeadingTerms] | None:
    """The leading terms at the sampled points when R₀ is rank deficient at each of them;
    None when it is regular at one, or a point gives no evidence."""
    from ..derivation._limit import limit_points

    timed = step.groupoid.timed
    terms = []
    for point in limit_points(step.groupoid, step.parameters):
        leading = _leading_terms(step, layout, point, time_step, timed)
        if leading is None or leading.rank == leading.size:
            return None
        terms.append(leading)
    return terms or None


def _small_step_state(step, point, h: float, time_step) -> tuple | None:
    """(unknowns, knowns, parameters) at g_k = g_h(q, v), with the step parameter at h, the
    multipliers 0 and the unknown arrow at the step's constant-velocity prediction."""
    G = step.groupoid
    try:
        arrow = G.numeric_fibre_arrow(point.q, point.x0 + h * point.v)
    except (ArithmeticError, ValueError, TypeError):
        return None
    first = sorted(step.arrows)[0]
    values = {s: float(v) for s, v in zip(step.arrows[first], arrow)
              if isinstance(s, sp.Symbol)}
    knowns = np.array([values.get(s, 0.0) for s in step.knowns])
    params = np.array(point.p, float)
    if time_step is not None:
        params[list(step.parameters).index(time_step)] = h
    guess = np.array(_prediction(step, knowns, params), float)
    if step.n_constraints:
        guess[-step.n_constraints:] = 0.0
    return guess, knowns, params


def _leading_terms(step, layout: Layout, point, time_step, timed: bool) -> LeadingTerms | None:
    from ..derivation._limit import SCALES, extrapolate

    states = [_small_step_state(step, point, h, time_step) for h in SCALES]
    if any(s is None for s in states):
        return None
    try:
        values = _evaluate_points(step, states)
    except Exception:  # noqa: BLE001 - no numeric evidence
        return None
    if not all(np.all(np.isfinite(J)) for _, J in values):
        return None
    crows, mcols = layout.constraint_rows, layout.multiplier_columns
    free = [i for i in range(len(layout.labels)) if i not in crows][int(timed):]
    chart = [j for j in range(len(layout.unknowns)) if j not in mcols][int(timed):]
    A = [h * J[np.ix_(free, chart)] for h, (_, J) in zip(SCALES, values)]
    A0 = extrapolate(A, SCALES)
    A1 = extrapolate([(a - A0) / h for a, h in zip(A, SCALES)], SCALES)
    A2 = extrapolate([((a - A0) / h - A1) / h for a, h in zip(A, SCALES)], SCALES)
    Y = _null(_unit_columns([J[np.ix_(free, mcols)] for _, J in values]).T, len(free))
    Z = _null(_unit_columns([J[np.ix_(crows, chart)].T for _, J in values]).T, len(chart))
    R0, R1 = Y.T @ A0 @ Z, Y.T @ A1 @ Z
    scale = max(np.linalg.norm(A0, 2), np.linalg.norm(A1, 2), np.linalg.norm(A2, 2))
    rank, left, right = _leading_null_spaces(R0)
    return LeadingTerms(R0, R1, float(scale), rank, left, right, chart, Z)


def _unit_columns(blocks: list) -> np.ndarray:
    """The columns of a block at h → 0, as directions: each column normalised at every
    scale and extrapolated (a column that is zero at every scale is left out)."""
    from ..derivation._limit import SCALES, extrapolate

    norms = np.array([np.linalg.norm(b, axis=0) for b in blocks])
    keep = np.all(norms > 0, axis=0)
    return extrapolate([b[:, keep] / n[keep] for b, n in zip(blocks, norms)], SCALES)


def _null(rows: np.ndarray, n: int) -> np.ndarray:
    """An orthonormal basis (columns) of the vectors of length n orthogonal to ``rows``."""
    if rows.size == 0:
        return np.eye(n)
    _, sv, Vt = np.linalg.svd(rows)
    rank = int(np.sum(sv > 1e-8 * sv[0])) if sv.size and sv[0] > 0 else 0
    return Vt[rank:].T


def _leading_null_spaces(R: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """Rank of R after equilibration (rows and columns below :data:`_FLOOR` of the largest
    are not rescaled: they are rounding of zeros), and unit bases of its left and right
    null spaces in R's own coordinates."""
    if R.size == 0:
        return 0, np.zeros((R.shape[0], 0)), np.zeros((R.shape[1], 0))
    dr = _scaling(np.linalg.norm(R, axis=1))
    dc = _scaling(np.linalg.norm(dr[:, None] * R, axis=0))
    U, sv, Vt = np.linalg.svd(dr[:, None] * R * dc[None, :])
    rank = int(np.sum(sv > _KINETIC_RANK * sv[0])) if sv[0] > 0 else 0
    left, right = dr[:, None] * U[:, rank:], dc[:, None] * Vt[rank:].T
    left = left / np.linalg.norm(left, axis=0, keepdims=True) if left.size else left
    right = right / np.linalg.norm(right, axis=0, keepdims=True) if right.size else right
    return rank, left, right


def _scaling(norms: np.ndarray) -> np.ndarray:
    """1/norm for the rows (or columns) above :data:`_FLOOR` of the largest, 1/largest for
    the others (1 when all are zero)."""
    top = float(norms.max(initial=0.0))
    if top == 0:
        return np.ones_like(norms)
    return 1.0 / np.where(norms > _FLOOR * top, norms, top)


def _velocity_name(unknown: str) -> str:
    """The chart velocity of an unknown: ``x_{k+1}`` → ``v_x``; other names → ``d/dt(…)``
    with the step label removed."""
    import re

    base = re.sub(r"_\{k[+-]?\d*\}", "", unknown)
    return f"v_{base}" if re.fullmatch(r"[A-Za-z]\w*", base) else f"d/dt {base}"


def _directions(null: np.ndarray, names: list[str]) -> str:
    """The null space spanned by the columns of ``null``, readable: every direction, or the
    rows of the reduced row echelon form of its basis, each as a combination."""
    n, k = null.shape
    if k >= n:
        return f"every direction ({', '.join(names)})"
    rows = null.T.copy()
    r = 0
    for col in range(n):
        if r == k:
            break
        pivot = r + int(np.argmax(np.abs(rows[r:, col])))
        if abs(rows[pivot, col]) < 1e-8 * np.abs(rows).max():
            continue
        rows[[r, pivot]] = rows[[pivot, r]]
        rows[r] /= rows[r, col]
        for i in range(k):
            if i != r:
                rows[i] -= rows[i, col] * rows[r]
        r += 1
    return " and ".join(_combination(row, names) for row in rows[:r])


def _combination(vector: np.ndarray, names: list[str]) -> str:
    """A direction as a readable combination, ``v_x − v_y`` or ``2 v_x − v_y`` (the first
    coefficient positive; whole numbers when the ratios are simple fractions)."""
    from fractions import Fraction
    from math import lcm

    vector = np.asarray(vector, float)
    top = np.abs(vector).max()
    if top == 0:
        return "0"
    first = next(c for c in vector if abs(c) > 1e-6 * top)
    vector = vector / (top if first > 0 else -top)
    vector[np.abs(vector) <= 1e-6] = 0.0
    fractions = [Fraction(float(c)).limit_denominator(12) for c in vector]
    if all(abs(float(f) - c) < 1e-6 for f, c in zip(fractions, vector)):
        vector = vector * lcm(*(f.denominator for f in fractions))
        vector = np.round(vector)
    terms = []
    for c, name in zip(vector, names):
        if c == 0:
            continue
        size = f"{abs(c):.0f}" if float(c).is_integer() else f"{abs(c):.3g}"
        terms.append(("−" if c < 0 else "+", name if size == "1" else f"{size} {name}"))
    return terms[0][1] + "".join(f" {s} {t}" for s, t in terms[1:])
