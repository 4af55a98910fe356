"""``bvp``: a discrete two-point problem from a JSON file of boundary data (a forced
system's inputs from ``--inputs``, one row per term of the action: docs/conventions.md §20)."""

from __future__ import annotations

import argparse

from .._arguments import counted
from ..runtime import solve_boundary_value
from ..verification import verify_stationary
from ._common import derive, say
from ._inputs import boundary_problem, input_table, parameters, parse_count
from ._output import check_format, write_solution


def run_bvp(args: argparse.Namespace) -> int:
    problem = boundary_problem(args.problem)
    out = check_format(args.output)
    max_iterations = parse_count(args.max_iterations, "max-iterations")
    derived = derive(args.system)
    params = parameters(derived.source, args.params, extra=problem["params"])
    inputs = _problem_inputs(args, derived, problem["steps"])
    say(f"{derived.step.name}: derived in {derived.seconds:.2f} s")
    solution = solve_boundary_value(derived.step, problem["start"], problem["end"],
                                    problem["steps"], guess=problem["guess"], params=params,
                                    inputs=inputs, max_iterations=max_iterations)
    say(f"{derived.step.name}: {solution.steps} steps, converged in "
        f"{counted(solution.iterations, 'iteration')} ({solution.method}) to "
        f"|F|∞ = {solution.residual_norm:.1e} ({solution.seconds:.2f} s)")
    say("|F|∞ by iteration: " + ", ".join(f"{v:.1e}" for v in solution.history))
    say(f"cost Σ L_d = {solution.cost:.12g}; second-order condition: {solution.kind}")
    status = 0
    if args.check:
        report = verify_stationary(solution, derived.system)
        verdict = "yes" if report else "NO"
        principle = ("the discrete Lagrange–d'Alembert principle (forced)"
                     if getattr(derived.system, "forces", None) is not None
                     else "the discrete action")
        say(f"critical point of {principle}: {verdict} (dS/dt extrapolated "
            f"{report.extrapolated:.1e}, terms {report.scale:.1e})")
        status = 0 if report else 1
    if out is not None:
        write_solution(out, solution)
        say(f"wrote {out}")
    return status


def _problem_inputs(args: argparse.Namespace, derived, steps: int):
    """The inputs of the problem's N − a + 1 terms (a the order) from ``--inputs``, as
    ``simulate`` reads them (:func:`input_table`, docs/cli.md)."""
    terms = steps - derived.step.order + 1
    return input_table(getattr(args, "inputs", None),
                       [str(u) for u in getattr(derived.system, "inputs", ())],
                       derived.step.name, terms, "term of the action",
                       "row t: the inputs of the term starting at arrow t",
                       f"the {terms} terms of {steps} steps")
