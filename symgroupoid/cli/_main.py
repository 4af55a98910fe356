"""The ``symgroupoid`` command: parser, dispatch, exit statuses.

Exit statuses: 0 success; 1 an error (a :class:`~symgroupoid.SymgroupoidError`, a file that
cannot be read or written) or a failed check, reported as one line
``symgroupoid: error: …`` on stderr (``--debug``: the traceback instead; any other exception
is a defect, reported the same way as an "internal error"); 2 a malformed command line
(usage on stderr); 130 interrupted (Ctrl-C).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from .._errors import SymgroupoidError
from .._progress import set_default
from .._version import __version__
from ._boundary import run_bvp
from ._cache import run_clear, run_info, run_templates
from ._common import BACKENDS
from ._derive import run_derive, run_emit
from ._newton import add_newton_options
from ._seeds import run_demo, run_generate
from ._simulate import INTERRUPTED, run_simulate
from ._verify import run_verify

SYSTEM_HELP = ("FILE.py[:NAME]: a Python file defining a DiscreteSystem, SecondOrderSystem or "
               "NonholonomicSystem (or a function returning one); NAME picks one when the "
               "file defines several")

EPILOG = """\
A system file may also define PARAMS (parameter values by name), INITIAL (an initial state),
NOETHER (the Noether quantities verify checks) and HORIZON (the final time of verify's order
measurement of a discretised ContinuousSystem); options given here take precedence.

Initial states (--initial FILE.json or the JSON text itself, or INITIAL):
  {"x": [0.0, 0.01], "g": [[1,0,0],[0,1,0],[0,0,1]], "lambda": [0, 0, 0]}
      named state parts, as Simulator.state reads them: a pair-groupoid coordinate as two
      consecutive values, a group part as its matrix, the multipliers as "lambda"
  {"configuration": {"x": 0, "y": 0}, "momentum": [0.1, 0.05, 0.0, 0.0, 0.0]}
      a base point and a discrete momentum (Simulator.from_momentum)
  {"configuration": {"theta": 0.3}, "velocity": [0.5]}
      a configuration and a velocity (body velocity on a group) of a discretised
      ContinuousSystem (Simulator.from_velocity)
  [0.0, 0.01, ...]          the flat state, ordered as the step's knowns
  traj.npz                  the last state of a run written by simulate -o traj.npz

Boundary data (bvp FILE.json):
  {"start": ..., "end": ..., "steps": 100, "params": {"h": 0.01}, "guess": ...}
      start/end: configurations (points as lists, matrices as lists of rows, products as a
      list with one entry per factor); second order: [c0, c1] and [cN-1, cN]; guess
      (optional): the N arrows, or {"arrows": [...], "multipliers": [...]}

Exit status: 0 success, 1 error or failed check (one line on stderr; --debug for the
traceback), 2 malformed command line, 130 interrupted.  Details: docs/cli.md."""


def path_text(text: str) -> str:
    """A file or directory option: text without NUL characters (no file name holds one);
    refused as a malformed command line (status 2)."""
    if "\0" in text:
        raise argparse.ArgumentTypeError(f"{text!r} is not a path: it contains a NUL "
                                         f"character")
    return text


def _debug_option(parser: argparse.ArgumentParser, default) -> None:
    parser.add_argument("--debug", action="store_true", default=default,
                        help="on an error, show the Python traceback instead of one line")


def _system_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("system", metavar="FILE.py[:NAME]", type=path_text, help=SYSTEM_HELP)


def _runtime_options(parser: argparse.ArgumentParser, stepper: bool = True) -> None:
    parser.add_argument("--params", metavar="NAME=VALUE,...",
                        help="parameter values, e.g. h=0.01,k=1 (over the file's PARAMS)")
    if stepper:
        parser.add_argument("--initial", metavar="STATE", type=path_text,
                            help="initial state: FILE.json (see below), a trajectory .npz, or the "
                                 "JSON itself ('{\"x\": [0, 0.01]}')")
        parser.add_argument("--project", action="store_true",
                            help="move the initial state onto the constraints first "
                                 "(Simulator.project_initial: a state typed to a few digits)")
        parser.add_argument("--backend", choices=BACKENDS, default="auto",
                            help="C kernel (c), NumPy (numpy), or C when a compiler exists "
                                 "(auto)")


def _command(commands, name: str, run, help: str, description: str | None = None,
             epilog: bool = False) -> argparse.ArgumentParser:
    parser = commands.add_parser(  # no abbreviated options: --step is not taken for --steps
        name, help=help, description=description or help, allow_abbrev=False,
        epilog=EPILOG if epilog else None, formatter_class=argparse.RawDescriptionHelpFormatter)
    _debug_option(parser, argparse.SUPPRESS)
    parser.set_defaults(run=run)
    return parser


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="symgroupoid", formatter_class=argparse.RawDescriptionHelpFormatter,
        allow_abbrev=False,
        description="Discrete Lagrangian mechanics on Lie groupoids: derive the equations of a\n"
                    "system file, emit C, simulate, solve boundary-value problems, verify.",
        epilog=EPILOG)
    parser.add_argument("--version", action="version", version=f"symgroupoid {__version__}")
    _debug_option(parser, False)
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    derive = _command(commands, "derive", run_derive,
                      "print the discrete Euler–Lagrange equations as LaTeX, with sizes and "
                      "times")
    _system_options(derive)
    derive.add_argument("--document", metavar="OUT.tex", type=path_text,
                        help="write a standalone LaTeX document instead of printing")
    derive.add_argument("--pdf", action="store_true",
                        help="also run pdflatex on the document; without --document only NAME.pdf "
                             "is written (the document is typeset in a private directory)")

    emit = _command(commands, "emit", run_emit, "write the C99 kernel (NAME.c, NAME.h)")
    _system_options(emit)
    emit.add_argument("-o", "--output", required=True, metavar="DIR", type=path_text,
                      help="output directory (created if missing)")
    emit.add_argument("--name", help="file name stem (default: the system's name)")
    emit.add_argument("--prefix", help="prefix of the C identifiers (default: the system's "
                                       "name)")
    emit.add_argument("--latex", action="store_true",
                      help="list each residual in LaTeX in the source's opening comment (small "
                           "systems; builds the SymPy residuals, as long as the derivation)")

    simulate = _command(commands, "simulate", run_simulate,
                        "run the compiled stepper and summarise the run", epilog=True)
    _system_options(simulate)
    simulate.add_argument("--steps", required=True, help="number of steps (1e6 is accepted)")
    simulate.add_argument("--every", default="1",
                          help="keep state 0, every k-th state and the last (default 1)")
    _runtime_options(simulate)
    simulate.add_argument("-o", "--output", metavar="TRAJ.npz|TRAJ.csv", type=path_text,
                          help="write the kept states")
    simulate.add_argument("--inputs", metavar="U.npy|U.csv", type=path_text,
                          help="a forced system's inputs: one row per step (row j: the "
                               "inputs of the arrow step j computes), one column per input")
    add_newton_options(simulate)

    bvp = _command(commands, "bvp", run_bvp,
                   "solve a discrete two-point (optimal control) problem", epilog=True)
    _system_options(bvp)
    bvp.add_argument("problem", metavar="BOUNDARY.json", type=path_text,
                     help="start, end, steps (and optionally params, guess)")
    _runtime_options(bvp, stepper=False)
    bvp.add_argument("--max-iterations", default="30", help="Newton iteration cap (default 30)")
    bvp.add_argument("--check", action="store_true",
                     help="check the solution against the discrete action (verify_stationary)")
    bvp.add_argument("-o", "--output", metavar="SOLUTION.npz|SOLUTION.csv", type=path_text,
                     help="write the arrows, multipliers and named parts")
    bvp.add_argument("--inputs", metavar="U.npy|U.csv", type=path_text,
                     help="a forced system's inputs: one row per term of the action (first "
                          "order: row k the inputs of the arrow g_k, k = 0 … N-1), one column "
                          "per input")

    verify = _command(commands, "verify", run_verify,
                      "check Jacobian, kernel, variational principle and Noether quantities",
                      epilog=True)
    _system_options(verify)
    _runtime_options(verify)
    verify.add_argument("--steps", default="20", help="length of the short run (default 20)")
    verify.add_argument("--inputs", metavar="U.npy|U.csv", type=path_text,
                        help="a forced system's inputs for the short run: one row per step, "
                             "one column per input (as for simulate)")
    verify.add_argument("--points", default="5", help="random points of the kernel checks")
    verify.add_argument("--horizon", metavar="T",
                        help="final time of the order measurement of a discretised "
                             "ContinuousSystem (default: the file's HORIZON, else steps·h)")
    verify.add_argument("--seed", default="0", help="seed of the random points")
    verify.add_argument("--no-sympy", action="store_true",
                        help="skip the comparison with the SymPy residuals (large systems)")

    cache = _command(commands, "cache", None, "the kernel cache ($SYMGROUPOID_CACHE)")
    actions = cache.add_subparsers(dest="action", required=True, metavar="ACTION")
    _command(actions, "info", run_info, "where the cache is and what it holds")
    clear = _command(actions, "clear", run_clear, "remove the cached kernels")
    clear.add_argument("--bad", action="store_true",
                       help="remove only the bad entries (damaged, truncated, untrusted)")
    _command(actions, "templates", run_templates,
             "compile the kernel templates once, beside them (done by make's setup)")

    demo = _command(commands, "demo", run_demo, "a short tour of the library")
    del demo
    generate = _command(commands, "generate", run_generate,
                        "emit the C kernels of the seed systems (plate-ball, heavy top, rigid "
                        "body) and of the satellite with a reaction wheel")
    generate.add_argument("outdir", type=path_text, help="output directory (created if missing)")
    return parser


def _fail(message: str) -> int:
    text = " ".join(message.split()) or "failed"
    print(f"symgroupoid: error: {text}", file=sys.stderr, flush=True)
    return 1


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; return its exit status (see the module docstring)."""
    args = build_parser().parse_args(argv)
    previous = set_default(True)  # progress of long work: always on here
    try:
        return args.run(args)
    except SymgroupoidError as err:
        if args.debug:
            raise
        return _fail(str(err))
    except OSError as err:
        if args.debug:
            raise
        where = f"{err.filename}: " if err.filename else ""
        return _fail(f"{where}{err.strerror or err}")
    except KeyboardInterrupt:
        if args.debug:
            raise
        print("symgroupoid: interrupted", file=sys.stderr, flush=True)
        return INTERRUPTED
    except Exception as err:  # a defect of the library: still one line, never a traceback
        if args.debug:
            raise
        return _fail(f"internal error ({type(err).__name__}: {err}); this is a defect of "
                     f"symgroupoid: please report it with the output of --debug")
    finally:
        set_default(previous)
