"""``demo`` (the tour behind ``make demo``) and ``generate`` (the seed systems' C kernels)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._common import say


def generate_seed_kernels(outdir: str | Path) -> list[Path]:
    """Emit ``<name>.c``/``<name>.h`` of every seed system into ``outdir``; return the paths."""
    from ..codegen import emit_c
    from ..systems import SEED_SYSTEMS

    outdir = Path(outdir)
    written: list[Path] = []
    for name, make in SEED_SYSTEMS.items():
        written.extend(emit_c(make().euler_lagrange(), outdir / name))
    return written


def run_generate(args: argparse.Namespace) -> int:
    for path in generate_seed_kernels(args.outdir):
        say(str(path))
    return 0


def run_demo(args: argparse.Namespace) -> int:
    from .._demo import run_demo as tour

    return tour()
