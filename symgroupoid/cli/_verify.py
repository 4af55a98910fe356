"""``verify``: independent checks of a system's equations, kernel and conservation laws.

1. The exact Jacobian (the step program) against central differences of the residual.
2. The compiled kernel's residual and Jacobian against the NumPy evaluation of the program.
3. The kernel's residual against the residuals derived independently in SymPy.
4. The variational principle on a short run (:func:`~symgroupoid.verify_stationary`).
5. Each Noether quantity the system file declares (``NOETHER``): the section verified to be
   a symmetry (seed 000 Def. 4.8) and the quantity conserved along the short run
   (Thm 4.9).
6. For a system discretised from a :class:`~symgroupoid.ContinuousSystem`: the observed
   order of its scheme next to the theoretical one (docs/conventions.md §21, §22), from
   the initial configuration and velocity the file names (``INITIAL = {"configuration":
   …, "velocity": […]}``) over the horizon ``HORIZON`` (default: the short run's, N·h),
   with N, 2N and 4N steps against the same scheme with 32N.  The row passes when the
   fitted order is within ORDER_TOLERANCE of the scheme's, fails when it is not and the
   two local orders (N/2N, 2N/4N) agree with each other within twice that (the errors are
   asymptotic and show another order), and is skipped otherwise: errors that are not yet
   asymptotic, or fewer than three above the rounding floor, measure no order.

Points for 1–3 are the states of the short run with the unknowns drawn at random around the
step's prediction, so every chart is evaluated where it is defined.  Each comparison is
relative to the size of its row: ``scale_i = |F_i| + max_j |J_ij|·max(1, |u_j|)``.
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .._errors import SymgroupoidError
from ..convergence import ORDER_FLOOR, REFERENCE_FACTOR, measure_order
from ..equations import DiscreteSystem
from ..ir import Graph, Program, from_sympy
from ..verification import verify_stationary
from ._common import derive, say, stepper
from ._errors import InputError
from ._inputs import (
    first_inputs,
    initial_data,
    initial_origin,
    initial_state,
    parameters,
    parse_count,
    parse_number,
    run_inputs,
    velocity_data,
)

#: relative tolerance of the Jacobian against central differences (their truncation and
#: rounding errors are ~1e-10 of the row's size; a wrong entry is of the order of the entry)
JACOBIAN_TOLERANCE = 1e-6
#: relative tolerance of the compiled kernel against the NumPy evaluation of the same program
KERNEL_TOLERANCE = 1e-9
#: relative tolerance of the kernel against the independent SymPy residuals
SYMPY_TOLERANCE = 1e-8
#: a Noether quantity F is conserved when max_k |F_k − F_0| ≤ this × max(1, max_k |F_k|)
NOETHER_TOLERANCE = 1e-8
#: relative spread of the random unknowns around the prediction
SPREAD = 0.1
#: an observed order passes within this of the scheme's (the criterion of the issue's tests)
ORDER_TOLERANCE = 0.1
#: the step counts of the order measurement, in multiples of --steps
ORDER_MULTIPLES = (1, 2, 4)
#: a default horizon whose errors are at the rounding floor is lengthened up to this many
#: times, by this factor each
LENGTHEN_TRIES, LENGTHEN_FACTOR = 3, 4.0
#: errors of N … 4N steps within this factor of each other do not shrink with N (a scheme
#: of order 1 would divide them by 4): the runs' accumulated rounding, however large
FLAT_ERRORS = 2.0


@dataclass
class Check:
    """One row of the table: ``passed`` True, False, or None (skipped)."""

    name: str
    passed: bool | None
    detail: str

    @property
    def result(self) -> str:
        return {True: "pass", False: "FAIL", None: "skip"}[self.passed]


def _row_scale(F: np.ndarray, J: np.ndarray, u: np.ndarray) -> np.ndarray:
    return np.abs(F) + np.max(np.abs(J) * np.maximum(1.0, np.abs(u)), axis=1,
                              initial=0.0) + 1e-300


def sample_points(sim, states: np.ndarray, p: np.ndarray, count: int,
                  rng: np.random.Generator) -> list[tuple[np.ndarray, np.ndarray]]:
    """(unknowns, known state) pairs: ``count`` states of the run, unknowns random around
    the step's prediction from each."""
    count = min(count, len(states))  # at most every state once (--points 1e9 allocates nothing)
    rows = np.unique(np.linspace(0, len(states) - 1, count).round().astype(int))
    points = []
    for r in rows:
        known = np.asarray(states[r], float)
        u0 = sim.kernel.predict(known, p)
        u = u0 + SPREAD * (np.abs(u0) + 0.01) * rng.standard_normal(len(u0))
        points.append((u, known))
    return points


def _guarded(name: str, check, *args) -> Check:
    """``check(*args)``, or the failed check ``name`` saying why it could not be computed
    (``step.evaluate`` refuses a point near the run where F or J is not finite)."""
    try:
        return check(*args)
    except SymgroupoidError as err:
        return Check(name, False, str(err))


def jacobian_check(step, points, p) -> Check:
    """The exact Jacobian against central differences of the residual (NumPy program)."""
    residual = step.program.numpy_function(["F"], ["u", "known", "p"])
    worst = 0.0
    for u, known in points:
        F, J = step.evaluate(u, known, p)
        n = len(u)
        delta = np.cbrt(np.finfo(float).eps) * np.maximum(1.0, np.abs(u))
        shifts = np.zeros((n, 2 * n))
        shifts[np.arange(n), 2 * np.arange(n)] = delta
        shifts[np.arange(n), 2 * np.arange(n) + 1] = -delta
        (Fs,) = residual(u[:, None] + shifts, known, p)
        differences = (Fs[:, 0::2] - Fs[:, 1::2]) / (2 * delta)
        error = np.abs(differences - J) * np.maximum(1.0, np.abs(u))
        worst = max(worst, float(np.max(error / _row_scale(F, J, u)[:, None], initial=0.0)))
    return Check("Jacobian vs finite differences", worst <= JACOBIAN_TOLERANCE,
                 f"{len(points)} points, largest relative error {worst:.1e} "
                 f"(tolerance {JACOBIAN_TOLERANCE:g})")


def kernel_check(sim, points, p) -> Check:
    """The compiled kernel's F and J against the NumPy evaluation of the step program."""
    name = "compiled C vs NumPy program"
    if sim.backend != "c":
        return Check(name, None, f"the {sim.backend} backend is the NumPy program itself")
    worst = 0.0
    for u, known in points:
        Fc, Jc = sim.kernel.residual_jacobian(u, known, p)
        Fn, Jn = sim.equations.evaluate(u, known, p)
        scale = _row_scale(Fn, Jn, u)
        error = np.maximum(np.abs(Fc - Fn),
                           np.max(np.abs(Jc - Jn) * np.maximum(1.0, np.abs(u)), axis=1,
                                  initial=0.0))
        worst = max(worst, float(np.max(error / scale, initial=0.0)))
    return Check(name, worst <= KERNEL_TOLERANCE,
                 f"residual and Jacobian, largest relative difference {worst:.1e} "
                 f"(tolerance {KERNEL_TOLERANCE:g})")


def _sympy_residuals(step):
    """The residuals derived in SymPy (``step.residuals_in_unknowns()``) as a NumPy function
    of columns (u, known, p): their trees read once into an expression graph (shared
    subtrees once; :func:`~symgroupoid.ir.from_sympy`), not through ``lambdify``, whose
    printing of the millions of operations of a Galerkin step on a group took minutes."""
    g = Graph()
    symbols = {s: g.input(s) for s in (*step.unknowns, *step.knowns, *step.parameters)}
    memo: dict = {}
    nodes = [from_sympy(g, e, symbols, f"{step.name}: the SymPy residual {i + 1}", memo)
             for i, e in enumerate(step.residuals_in_unknowns())]
    inputs = {"u": list(step.unknowns), "known": list(step.knowns), "p": list(step.parameters)}
    return Program(g, inputs, {"F": nodes}).numpy_function(["F"], ["u", "known", "p"])


def sympy_check(sim, points, p) -> Check:
    """The kernel's residual against the residuals derived in SymPy (an independent
    derivation: the junction variation of the action in SymPy, not the graph)."""
    step = sim.equations
    name = f"{'compiled C' if sim.backend == 'c' else 'NumPy backend'} vs SymPy residuals"
    residuals = _sympy_residuals(step)
    worst = 0.0
    for u, known in points:
        Fk = sim.kernel.residual(u, known, p)
        with np.errstate(all="ignore"):
            (Fs,) = residuals(np.asarray(u, float)[:, None], np.asarray(known, float)[:, None],
                              np.asarray(p, float)[:, None])
            Fs = np.asarray(Fs, float).ravel()
        _, J = step.evaluate(u, known, p)
        worst = max(worst, float(np.max(np.abs(Fk - Fs) / _row_scale(Fs, J, u), initial=0.0)))
    ok = bool(np.isfinite(worst)) and worst <= SYMPY_TOLERANCE
    return Check(name, ok, f"largest relative difference {worst:.1e} "
                           f"(tolerance {SYMPY_TOLERANCE:g})")


def stationarity_check(system, traj) -> Check:
    """verify_stationary on the short run: the discrete action's critical point, or for a
    forced system the discrete Lagrange–d'Alembert principle (docs/conventions.md §20), for
    a nonholonomic (Hölder) system along D_c (§10)."""
    name = f"variational principle ({traj.steps} steps)"
    if not isinstance(system, DiscreteSystem) and getattr(system, "method", "") != "holder":
        return Check(name, None, "the energy–momentum equations are not the critical points "
                                 "of an action")
    report = verify_stationary(traj, system)
    if system.functions.forces is not None:
        return Check(name, bool(report), f"Lagrange–d'Alembert: dS/dt + W along a random "
                                         f"variation {report.extrapolated:.1e} (forces' work "
                                         f"W {report.work:.1e}, terms {report.scale:.1e})")
    return Check(name, bool(report), f"dS/dt along a random variation {report.extrapolated:.1e} "
                                     f"(terms {report.scale:.1e})")


@dataclass
class Declared:
    name: str
    section: object
    f: object


def declared_noether(source) -> list[Declared]:
    """The file's ``NOETHER`` list (see :mod:`symgroupoid.cli._system_file`)."""
    raw = source.convention("NOETHER", [])
    label = f"{source.path.name}: NOETHER"
    if raw is None:
        return []
    if isinstance(raw, (str, bytes, Mapping)) or not isinstance(raw, (list, tuple)):
        raise InputError(f"{label} must be a list of sections or of dicts with 'section', "
                         f"got {type(raw).__name__}")
    out = []
    for i, entry in enumerate(raw):
        if isinstance(entry, Mapping):
            extra = sorted(set(map(str, entry)) - {"name", "section", "f"})
            if extra or "section" not in entry:
                raise InputError(f"{label}[{i}]: a dict entry has the keys 'section' "
                                 f"(required), 'name' and 'f'")
            out.append(Declared(str(entry.get("name", f"NOETHER[{i}]")), entry["section"],
                                entry.get("f")))
        else:
            name = f"section {entry}" if isinstance(entry, int) else f"NOETHER[{i}]"
            out.append(Declared(name, entry, None))
    return out


def _state_positions(step, quantity) -> np.ndarray | None:
    """Where the quantity's arguments (the coordinates of g_k, then λ_k) sit in the
    step's known state; None when they are not all there."""
    position = {s: i for i, s in enumerate(step.knowns)}
    needed = [*quantity.arrow, *quantity.multipliers]
    if all(s in position for s in needed):
        return np.array([position[s] for s in needed], dtype=int)
    return None


def noether_check(system, step, declared: Declared, traj, p) -> Check:
    """Symmetry (symbolic) and conservation along the run of one declared quantity."""
    name = f"Noether: {declared.name}"
    if step.order != 1:
        return Check(name, None, "Noether quantities are checked for first-order systems only")
    try:
        quantity = system.noether(declared.section, declared.f)
    except SymgroupoidError as exc:  # a failed row: the other checks still run and report
        return Check(name, False, f"cannot be built: {exc}")
    except Exception as exc:
        return Check(name, False, f"cannot be built: {type(exc).__name__}: {exc}")
    index = _state_positions(step, quantity)
    if index is None:
        return Check(name, None, "its arrows are not the known arrows of the state")
    a, m = len(quantity.arrow), len(quantity.multipliers)
    if system.stages:  # F_X at the stages ζ* of every state (docs/conventions.md §22)
        values = np.asarray(quantity.along(traj), float)
    else:
        values = np.array([quantity.evaluate(x[:a], x[a:a + m], p)
                           for x in np.asarray(traj.states)[:, index]])
    tolerance = NOETHER_TOLERANCE * max(1.0, float(np.max(np.abs(values))))
    how = quantity.verification
    how = (how.replace("symbolic", "symbolically", 1) if how.startswith("symbolic")
           else f"({how})")
    symmetry = f"symmetry verified {how}" if quantity.is_symmetry else \
        f"NOT verified to be a symmetry {how}"
    if quantity.impulse_form is not None:  # forced: J changes by the forces' impulse (§20)
        gap = float(np.max(np.abs(np.diff(values) - quantity.impulse(traj)), initial=0.0))
        ok = quantity.is_symmetry and gap <= tolerance
        return Check(name, ok, f"{symmetry}; J_(k+1) - J_k = impulse to {gap:.1e} over "
                               f"{len(values) - 1} steps (tolerance {tolerance:.0e})")
    drift = float(np.max(np.abs(values - values[0])))
    ok = quantity.is_symmetry and drift <= tolerance
    return Check(name, ok, f"{symmetry}; value {values[0]:.6g}, drift {drift:.1e} over "
                           f"{len(values)} states (tolerance {tolerance:.0e})")


def _scheme_name(scheme) -> str:
    return scheme if isinstance(scheme, str) else f"{type(scheme).__name__}({scheme.stages})"


def horizon(source, text: str | None, default: float) -> float:
    """The final time of the order measurement: ``--horizon``, else the file's ``HORIZON``,
    else ``default``; a finite positive number."""
    if text is not None:
        value, what = parse_number(text, "--horizon"), "--horizon"
    else:
        raw, what = source.convention("HORIZON"), f"{source.path.name}: HORIZON"
        if raw is None:
            return default
        if isinstance(raw, bool) or not isinstance(raw, (int, float, np.integer, np.floating)):
            raise InputError(f"{what} must be a number (the final time of the order "
                             f"measurement), got {type(raw).__name__} {raw!r}")
        value = float(raw)
    if not np.isfinite(value) or value <= 0:
        raise InputError(f"{what} must be a finite positive time, got {value!r}")
    return value


def order_horizon(source, params: dict, steps: int, text: str | None) -> float | None:
    """The horizon T of the order measurement of a discretised ContinuousSystem (checked
    before any run), None for other systems."""
    origin = getattr(source.system, "continuous", None)
    if origin is None:
        if text is not None:
            raise InputError(f"--horizon: {source.label} is not discretised from a "
                             f"ContinuousSystem; there is no order to measure")
        return None
    return horizon(source, text, steps * float(params[str(origin.step)]))


def _measured(sim, data, params: dict, T: float, counts: list, origin) -> tuple:
    """The order report over the horizon T and its (h, error) pairs above the floor."""
    step = str(origin.step)  # (the file's value of it: each run sets it to T/N)
    params = {name: value for name, value in params.items() if name != step}
    report = measure_order(sim, velocity_data(data), params, T, counts,
                           expected=origin.order, inputs=first_inputs(sim, data))
    floor = ORDER_FLOOR * max(1.0, report.reference_norm)
    return report, [(h, e) for h, e in zip(report.step_sizes, report.errors) if e > floor]


def _still(report) -> bool:
    """No configuration of the measured runs is farther from the first than the rounding
    floor: nothing moves at these steps."""
    return (report.motion is not None
            and report.motion <= ORDER_FLOOR * max(1.0, report.reference_norm))


def order_check(source, sim, data, params: dict, steps: int, T: float | None,
                lengthen: bool = False) -> Check | None:
    """The observed order of a discretised ContinuousSystem's scheme against its
    theoretical order over the horizon T (None for other systems); see the module
    docstring.  With ``lengthen`` (T is the default, N·h) a horizon whose errors are at
    the rounding floor is lengthened up to :data:`LENGTHEN_TRIES` times by
    :data:`LENGTHEN_FACTOR` (the same step counts, so a larger h at the same cost), while
    its runs succeed."""
    origin = getattr(source.system, "continuous", None)
    if origin is None or T is None:
        return None
    name = f"order of {_scheme_name(origin.scheme or origin.rule)}"
    if not (isinstance(data, Mapping) and "velocity" in data):
        return Check(name, None, "needs an initial configuration and velocity: set INITIAL "
                                 "= {\"configuration\": ..., \"velocity\": [...]} in the "
                                 "file (or give it with --initial)")
    step = str(origin.step)
    counts = [steps * m for m in ORDER_MULTIPLES]
    try:
        report, used = _measured(sim, data, params, T, counts, origin)
    except SymgroupoidError as err:
        return Check(name, False, f"the runs failed: {err}")
    default, tries = T, LENGTHEN_TRIES if lengthen else 0
    while len(used) < 2 and any(report.errors) and tries and not _still(report):
        tries -= 1
        try:
            report, used = _measured(sim, data, params, T * LENGTHEN_FACTOR, counts, origin)
        except SymgroupoidError:  # a step too large for Newton: the last horizon stands
            break
        T *= LENGTHEN_FACTOR
    longer = (f" (the default horizon {default:g} lengthened: its errors were at the "
              f"rounding floor)" if T != default else "")
    where = (f"{step} = T/N, N = {', '.join(map(str, counts))}, T = {T:g}{longer}, errors "
             f"{', '.join(f'{e:.1e}' for e in report.errors)} against N = "
             f"{REFERENCE_FACTOR * counts[-1]}")
    if not any(report.errors):
        return Check(name, None, f"theoretical {origin.order}; the errors are exactly 0 "
                                 f"({where}): the scheme is exact on this motion, or at this "
                                 f"{step} (far beyond the motion's time scales) nothing "
                                 f"moves; the order cannot be measured here")
    if len(used) < 2 and _still(report):
        return Check(name, None, f"theoretical {origin.order}; nothing moves: no "
                                 f"configuration of the runs is farther than "
                                 f"{report.motion:.1e} from the first, the rounding ({where}):"
                                 f" at this {step} (far beyond the motion's time scales) the "
                                 f"order cannot be measured; set a shorter HORIZON")
    if len(used) < 2:
        return Check(name, None, f"theoretical {origin.order}; the errors are at the "
                                 f"rounding floor ({where}): set a longer HORIZON or a "
                                 f"larger {step}")
    if max(e for _, e in used) < FLAT_ERRORS * min(e for _, e in used):
        return Check(name, None, f"theoretical {origin.order}; the errors do not shrink "
                                 f"with N ({where}): they are the rounding the runs "
                                 f"accumulate over their steps, not the scheme's error: set "
                                 f"fewer --steps (a larger {step}) or a longer HORIZON")
    logs = np.log([[h, e] for h, e in used])
    observed = float(np.polyfit(logs[:, 0], logs[:, 1], 1)[0])
    if abs(observed - origin.order) <= ORDER_TOLERANCE:
        return Check(name, True, f"observed {observed:.2f}, theoretical {origin.order}; "
                                 f"{where}")
    local = np.diff(logs[:, 1]) / np.diff(logs[:, 0])
    if len(used) < 3 or np.ptp(local) > 2 * ORDER_TOLERANCE:
        return Check(name, None, f"theoretical {origin.order}; not measured: the errors "
                                 f"above the rounding floor are not in the asymptotic range "
                                 f"(local orders {', '.join(f'{o:.2f}' for o in local)}"
                                 f"{' from one pair of step sizes' if len(used) < 3 else ''}: "
                                 f"{where}); at order {origin.order} the range between the "
                                 f"steps too large for it and the floor may be narrower than "
                                 f"N … 4N: set a HORIZON or --steps between them")
    return Check(name, False, f"observed {observed:.2f} (local orders "
                              f"{', '.join(f'{o:.2f}' for o in local)}, consistent with each "
                              f"other), theoretical {origin.order}; {where} (tolerance "
                              f"{ORDER_TOLERANCE:g})")


def table(checks: list[Check]) -> list[str]:
    width = max(len("check"), *(len(c.name) for c in checks))
    lines = [f"{'check':<{width}}  result  detail"]
    lines += [f"{c.name:<{width}}  {c.result:<6}  {c.detail}" for c in checks]
    return lines


def run_verify(args: argparse.Namespace) -> int:
    steps = parse_count(args.steps, "steps", minimum=2)
    count = parse_count(args.points, "points", minimum=1)
    seed = parse_count(args.seed, "seed")
    derived = derive(args.system)
    sim = stepper(derived, args.backend).sim
    step, system = derived.step, derived.system
    params = parameters(derived.source, args.params)
    p = sim.parameters(params)
    T = order_horizon(derived.source, params, steps, args.horizon)
    data = initial_data(derived.source, args.initial, sim)
    state = initial_state(sim, data, params, project=args.project,
                          origin=initial_origin(args.initial))
    inputs = run_inputs(args.inputs, sim, steps)
    declared = declared_noether(derived.source) if isinstance(system, DiscreteSystem) else []
    checks: list[Check] = []
    traj = None
    try:
        traj = sim.simulate(state, steps, params, inputs=inputs)
        states = traj.states
    except SymgroupoidError as err:
        checks.append(Check(f"short run ({steps} steps)", False, str(err)))
        states = state[None]
    points = sample_points(sim, states, p, count, np.random.default_rng(seed))
    checks.append(_guarded("Jacobian vs finite differences", jacobian_check, step, points, p))
    checks.append(_guarded("compiled C vs NumPy program", kernel_check, sim, points, p))
    if args.no_sympy:
        checks.append(Check("kernel vs SymPy residuals", None, "--no-sympy"))
    else:
        checks.append(_guarded("kernel vs SymPy residuals", sympy_check, sim, points, p))
    if traj is not None:
        checks.append(stationarity_check(system, traj))
        checks += [noether_check(system, step, d, traj, p) for d in declared]
    order = order_check(derived.source, sim, data, params, steps, T,
                        lengthen=args.horizon is None
                        and derived.source.convention("HORIZON") is None)
    if order is not None:
        checks.append(order)
    failed = sum(c.passed is False for c in checks)
    for line in table(checks):
        say(line)
    ran = sum(c.passed is not None for c in checks)
    say(f"{step.name}: {ran - failed} of {ran} checks passed" +
        (f", {len(checks) - ran} skipped" if len(checks) > ran else ""))
    return 1 if failed else 0
