"""Writing results: trajectories and boundary-value solutions as ``.npz`` or ``.csv``.

Files are written to a temporary file beside the target and renamed into place, so a
reader never sees a half-written file and an interrupted write leaves the old one.

``.npz`` (NumPy ``np.load``) holds the arrays under their names (see docs/cli.md); ``.csv``
has one header line and one row per kept state (trajectory) or per arrow (solution),
numbers written with 17 significant digits (they read back exactly).
"""

from __future__ import annotations

import csv
import os
from pathlib import Path

import numpy as np

from ..runtime import TRAJECTORY_FORMATS, output_problem, save_trajectory
from ..runtime import atomic_write as _atomic
from ..runtime import number_text as _number
from ._errors import InputError

__all__ = ["check_format", "write_solution", "write_trajectory"]


def check_format(path: str | None, option: str = "-o") -> Path | None:
    """The output path, refused up front (before any work) unless it ends in .npz or .csv,
    its directory exists and it is not a directory itself."""
    if path is None:
        return None
    out = Path(path)
    if path.endswith(("/", os.sep)):
        raise InputError(f"{option} {path}: names a directory (it ends in a separator); name "
                         f"the file to write")
    if out.suffix not in TRAJECTORY_FORMATS:
        raise InputError(f"{option} {path}: the file name must end in .npz or .csv")
    problem = output_problem(out)
    if problem is not None:
        raise InputError(f"{option} {path}: {problem}")
    return out


# --- trajectories (the library's own format: symgroupoid/runtime/_files.py) ---------------------

def write_trajectory(path: Path, sim, traj) -> None:
    """``traj`` to ``path`` (.npz: every array; .csv: step, state columns, Newton data), as
    :meth:`Trajectory.save` writes it."""
    save_trajectory(traj, path)


# --- boundary-value solutions -------------------------------------------------------------------

def _parts(solution) -> dict[str, np.ndarray]:
    G = solution.system.groupoid
    return {name: solution[name] for name in G.symbols_by_name(0)}


def write_solution(path: Path, solution) -> None:
    """A :class:`BoundaryValueSolution` to ``path``.

    .npz: ``arrows`` (N, arrow_dim), ``multipliers``, ``controls``, ``history`` (|F|∞ per
    iteration), ``iterations``, ``residual_norm``, with internal stages ``stages`` (N,
    n_stages: each arrow's ζ, docs/conventions.md §22), and each named part of the arrows
    (``x``: the target point of every arrow, ``g``: every arrow's matrix, …).
    .csv: one row per arrow k = 1 … N: its named parts, then its multipliers when the
    arrow starts an action term.
    """
    parts = _parts(solution)
    if path.suffix == ".npz":
        arrays = {"arrows": solution.arrows, "multipliers": solution.multipliers,
                  "controls": solution.controls, "history": np.array(solution.history),
                  "iterations": np.array(solution.iterations),
                  "residual_norm": np.array(solution.residual_norm)}
        if getattr(solution, "stages", None) is not None:
            arrays["stages"] = solution.stages
        for name, values in parts.items():
            arrays[f"part_{name}" if name in arrays else name] = values
        _atomic(path, lambda f: np.savez(f, **arrays), binary=True)
        return
    flat = {n: v.reshape(len(v), -1) for n, v in parts.items()}
    header = ["k"]
    for name, values in parts.items():
        shape = values.shape[1:]
        header += [name] if not shape else [f"{name}[{', '.join(map(str, i))}]"
                                            for i in np.ndindex(*shape)]
    m = solution.multipliers.shape[1] if solution.multipliers.ndim == 2 else 0
    header += [f"lambda[{a}]" for a in range(m)]

    def write(f) -> None:
        out = csv.writer(f)
        out.writerow(header)
        for k in range(len(solution.arrows)):
            row = [str(k + 1)]
            for values in flat.values():
                row += map(_number, values[k])
            if m:
                row += (map(_number, solution.multipliers[k]) if k < len(solution.multipliers)
                        else [""] * m)
            out.writerow(row)

    _atomic(path, write, binary=False)
