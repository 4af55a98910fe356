"""Command line: ``python -m symgroupoid <command>``.

Commands
--------
generate OUTDIR   emit the C kernels of the seed systems (plate-ball, heavy top, rigid body)
                  into OUTDIR as ``<name>.c``/``<name>.h``
demo              a short tour of the library
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path


def generate_seed_kernels(outdir: str | Path) -> list[Path]:
    """Emit ``<name>.c``/``<name>.h`` of every seed system into ``outdir``; return the paths."""
    from .codegen import emit_c
    from .systems import SEED_SYSTEMS

    outdir = Path(outdir)
    written: list[Path] = []
    for name, make in SEED_SYSTEMS.items():
        written.extend(emit_c(make().euler_lagrange(), outdir / name))
    return written


def _generate(args: argparse.Namespace) -> int:
    for path in generate_seed_kernels(args.outdir):
        print(path)
    return 0


def _demo(args: argparse.Namespace) -> int:
    from ._demo import run_demo

    return run_demo()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="symgroupoid", description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    gen = commands.add_parser("generate", help="emit the C kernels of the seed systems")
    gen.add_argument("outdir", help="output directory (created if missing)")
    gen.set_defaults(run=_generate)
    demo = commands.add_parser("demo", help="a short tour of the library")
    demo.set_defaults(run=_demo)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``python -m symgroupoid`` and the ``symgroupoid`` script."""
    args = build_parser().parse_args(argv)
    return args.run(args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
