"""``simulate``: run the compiled stepper from an initial state; write and summarise the run."""

from __future__ import annotations

import argparse
import time

import numpy as np

from .._errors import NewtonDivergenceError, SingularJacobianError
from ..runtime import constraint_check
from ._common import derive, say, stepper, warn
from ._inputs import (
    initial_data,
    initial_origin,
    initial_state,
    parameters,
    parse_count,
    run_inputs,
)
from ._newton import newton_options
from ._output import check_format, write_trajectory

#: exit status after Ctrl-C (128 + SIGINT, as shells report it)
INTERRUPTED = 130


def conservation_lines(trajectory) -> list[str]:
    """Lines on the quantities a run should conserve (discrete energy, momenta, Noether
    quantities along the trajectory), for the summary of ``simulate``.

    This is the one place the summary asks for them; it returns [] while the library has
    no diagnostics of a trajectory to report.
    """
    return []


def constraint_lines(sim, traj) -> list[str]:
    """The largest |φ_i| over the kept states (every known arrow of every kept state),
    against the rounding level of evaluating φ_i there; [] for a system without
    constraints."""
    check = constraint_check(sim.equations)
    if not check.windows:
        return []
    p = sim.parameters(traj.parameters)
    values, levels = check.values(traj.states, p)
    if values.size == 0:
        return []
    row, column = np.unravel_index(int(np.argmax(values)), values.shape)
    worst, level = float(values[row, column]), float(levels[row, column])
    where = int(traj.step_indices[row])
    verdict = "within rounding" if worst <= level else "ABOVE the rounding level"
    return [f"largest constraint violation |φ|: {worst:.1e} (state {where}; rounding level "
            f"there {level:.1e}: {verdict})"]


def summary_lines(sim, traj, seconds: float) -> list[str]:
    """What the run did: steps and time, Newton iterations, residuals, constraints,
    conserved quantities."""
    steps = traj.steps
    per_step = f", {seconds / steps * 1e6:.2f} µs/step" if steps else ""
    lines = [f"{sim.name}: {steps} steps in {seconds:.2f} s{per_step} ({sim.backend} backend)"]
    kept = f"kept {len(traj)} states"
    lines.append(kept + (f" (state 0, every {traj.every}-th and the last)"
                         if traj.every > 1 else ""))
    if steps:
        its = traj.newton_iterations
        per = "step" if traj.every == 1 else "kept interval"
        lines.append(f"Newton iterations: {int(its.sum())} in all, {its.sum() / steps:.2f} per "
                     f"step, at most {int(its.max())} per {per}")
        lines.append(f"largest final residual |F|∞: {float(traj.residual_norms.max()):.1e}")
    lines += constraint_lines(sim, traj)
    lines += conservation_lines(traj)
    return lines


def _save_partial(out, sim, partial) -> str:
    """Write the states computed before a failure or an interruption; a note on it."""
    if out is None or partial is None or len(partial) < 2:
        return ""
    write_trajectory(out, sim, partial)
    return f"; the {len(partial)} states up to step {partial.step_indices[-1]} are in {out}"


def run_simulate(args: argparse.Namespace) -> int:
    out = check_format(args.output)
    steps = parse_count(args.steps, "steps")
    every = parse_count(args.every, "every", minimum=1)
    options = newton_options(args)
    derived = derive(args.system)
    built = stepper(derived, args.backend)
    sim = built.sim
    say(f"{sim.name}: derived in {derived.seconds:.2f} s; {built.describe()}")
    params = parameters(derived.source, args.params)
    data = initial_data(derived.source, args.initial, sim)
    state = initial_state(sim, data, params, project=args.project,
                          origin=initial_origin(args.initial))
    inputs = run_inputs(args.inputs, sim, steps)
    t0 = time.perf_counter()
    try:
        traj = sim.simulate(state, steps, params, every=every, options=options, inputs=inputs)
    except (SingularJacobianError, NewtonDivergenceError) as err:
        note = _save_partial(out, sim, getattr(err, "trajectory", None))
        if note:
            err.args = (f"{err}{note}",) + err.args[1:]
        raise
    except KeyboardInterrupt as interrupt:
        note = _save_partial(out, sim, getattr(interrupt, "trajectory", None))
        warn(f"symgroupoid: interrupted{note}")
        return INTERRUPTED
    seconds = time.perf_counter() - t0
    if out is not None:
        write_trajectory(out, sim, traj)
    for line in summary_lines(sim, traj, seconds):
        say(line)
    if out is not None:
        say(f"wrote {out}")
    return 0
