"""Newton options on the command line (``simulate``): ``--tol``, ``--max-iterations``, …"""

from __future__ import annotations

import argparse

from .._arguments import real_argument
from ..runtime import NewtonOptions
from ._inputs import parse_count, parse_number

#: (option, NewtonOptions field, help) of the real-valued options
_REAL = (
    ("--tol", "tol_step", "estimated error at which Newton stops, relative to each unknown "
                          "(default 1e-16: the rounding floor decides)"),
    ("--tol-residual", "tol_residual", "absolute |F|_inf at which Newton stops (default 0: "
                                       "off)"),
    ("--floor-factor", "floor_factor", "factor of the rounding floors (default 8)"),
    ("--trust-factor", "trust_factor", "trust region of a step, in motions of the last steps "
                                       "(default 10; 0 turns the branch-jump check off)"),
)


def add_newton_options(parser: argparse.ArgumentParser) -> None:
    """The options of :class:`~symgroupoid.NewtonOptions` as ``--tol``, ``--tol-residual``,
    ``--max-iterations``, ``--floor-factor``, ``--trust-factor`` and ``--no-extrapolate``."""
    group = parser.add_argument_group("Newton's method (NewtonOptions)")
    for option, _, text in _REAL:
        group.add_argument(option, metavar="X", help=text)
    group.add_argument("--max-iterations", metavar="N",
                       help="updates per Newton solve (default 50)")
    group.add_argument("--no-extrapolate", action="store_true",
                       help="start every step from the step's prediction instead of "
                            "extrapolating the last solutions")


def newton_options(args: argparse.Namespace) -> NewtonOptions | None:
    """The :class:`~symgroupoid.NewtonOptions` the command line sets (None: the defaults);
    a value out of range is the library's named error, naming the option."""
    given = {}
    for option, field, _ in _REAL:
        text = getattr(args, field_of(option))
        if text is not None:
            given[field] = real_argument(parse_number(text, option), option, minimum=0.0)
    if args.max_iterations is not None:
        given["max_iterations"] = parse_count(args.max_iterations, "max-iterations")
    if args.no_extrapolate:
        given["extrapolate"] = False
    return NewtonOptions(**given) if given else None


def field_of(option: str) -> str:
    """The argparse destination of ``--an-option``: ``an_option``."""
    return option.lstrip("-").replace("-", "_")
