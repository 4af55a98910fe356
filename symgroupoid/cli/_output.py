"""Writing results: trajectories and boundary-value solutions as ``.npz`` or ``.csv``.

Files are written to a temporary file beside the target and renamed into place, so a
reader never sees a half-written file and an interrupted write leaves the old one.

``.npz`` (NumPy ``np.load``) holds the arrays under their names (see docs/cli.md); ``.csv``
has one header line and one row per kept state (trajectory) or per arrow (solution),
numbers written with 17 significant digits (they read back exactly).
"""

from __future__ import annotations

import csv
import io
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ._errors import InputError

FORMATS = (".npz", ".csv")
#: names of the fixed arrays of a trajectory file (a state part with one of these names is
#: stored as ``part_<name>``)
TRAJECTORY_KEYS = ("states", "step_indices", "newton_iterations", "residual_norms",
                   "columns", "parameter_names", "parameter_values", "every", "backend")


def check_format(path: str | None, option: str = "-o") -> Path | None:
    """The output path, refused up front (before any work) unless it ends in .npz or .csv
    and its directory exists."""
    if path is None:
        return None
    out = Path(path)
    if out.suffix not in FORMATS:
        raise InputError(f"{option} {path}: the file name must end in .npz or .csv")
    if not out.parent.is_dir():
        raise InputError(f"{option} {path}: the directory {out.parent} does not exist")
    return out


def _atomic(path: Path, write: Callable[[io.IOBase], None], binary: bool) -> None:
    fd, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "wb" if binary else "w", **({} if binary else
                                                       {"newline": "", "encoding": "utf-8"})) as f:
            write(f)
        os.chmod(temporary, 0o666 & ~_umask())
        os.replace(temporary, path)
    except BaseException:
        try:
            os.unlink(temporary)
        except FileNotFoundError:
            pass
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _number(x: float) -> str:
    return format(float(x), ".17g")


# --- trajectories -------------------------------------------------------------------------------

def trajectory_columns(sim) -> list[str]:
    """A name for every entry of the flat state (``x (step k-1)``, ``g[0, 2]``, …)."""
    return [sim.layout.describe(i) for i in range(sim.layout.n_known)]


def trajectory_arrays(sim, traj) -> dict[str, np.ndarray]:
    names = list(traj.parameters)
    arrays = {
        "states": traj.states, "step_indices": traj.step_indices,
        "newton_iterations": traj.newton_iterations, "residual_norms": traj.residual_norms,
        "columns": np.array(trajectory_columns(sim)),
        "parameter_names": np.array(names, dtype=str),
        "parameter_values": np.array([traj.parameters[n] for n in names], float),
        "every": np.array(traj.every), "backend": np.array(traj.backend)}
    for key in traj.keys():
        label = "lambda" if key in ("λ", "multipliers") else key
        arrays[f"part_{label}" if label in TRAJECTORY_KEYS else label] = traj[key]
    return arrays


def write_trajectory(path: Path, sim, traj) -> None:
    """``traj`` to ``path`` (.npz: every array; .csv: step, state columns, Newton data)."""
    if path.suffix == ".npz":
        arrays = trajectory_arrays(sim, traj)
        _atomic(path, lambda f: np.savez(f, **arrays), binary=True)
        return
    header = ["step", *trajectory_columns(sim), "newton_iterations", "residual_norm"]

    def write(f) -> None:
        out = csv.writer(f)
        out.writerow(header)
        for k, state in enumerate(traj.states):
            tail = ["", ""] if k == 0 else [str(int(traj.newton_iterations[k - 1])),
                                             _number(traj.residual_norms[k - 1])]
            out.writerow([str(int(traj.step_indices[k])), *map(_number, state), *tail])

    _atomic(path, write, binary=False)


# --- boundary-value solutions -------------------------------------------------------------------

def _parts(solution) -> dict[str, np.ndarray]:
    G = solution.system.groupoid
    return {name: solution[name] for name in G.symbols_by_name(0)}


def write_solution(path: Path, solution) -> None:
    """A :class:`BoundaryValueSolution` to ``path``.

    .npz: ``arrows`` (N, arrow_dim), ``multipliers``, ``controls``, ``history`` (|F|∞ per
    iteration), ``iterations``, ``residual_norm``, and each named part of the arrows
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
