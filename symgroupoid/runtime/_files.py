"""Trajectories as files: ``Trajectory.save`` / ``Trajectory.load`` and the command line's
``simulate -o`` / ``--initial`` share this code.

Files are written to a temporary file beside the target and renamed into place, so a reader
never sees a half-written file and an interrupted write leaves the old one.

- ``.npz`` (``numpy.load``): ``states`` (rows × knowns), ``step_indices``,
  ``newton_iterations``, ``residual_norms``, ``columns`` (a name for each state entry:
  ``x (step k-1)``, ``g[0, 2]``, ``lambda[0]``), ``parameter_names``, ``parameter_values``,
  ``every``, ``backend``, ``system`` (the name of the system that wrote it), and each
  named part as ``Trajectory[name]`` gives it (a part whose name clashes with these keys is
  stored as ``part_<name>``).  Only numbers and
  strings: a file is read with ``allow_pickle=False``, so loading one never runs code.
- ``.csv``: a header ``step, <columns>, newton_iterations, residual_norm``, then one row per
  kept state (the first row's Newton columns empty), numbers with 17 significant digits, so
  they read back exactly (no parameter values: :meth:`Trajectory.load` asks for them).

A file is read back for a system only when its ``columns`` are that system's (names and
order of the state's entries), not merely as many, and (.npz) its ``system`` is that
system's name: another system's trajectory of the same width and columns (the same
continuous system under another scheme) is a :class:`TrajectoryFileError`.
"""

from __future__ import annotations

import csv
import io
import os
import stat
import tempfile
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .._arguments import path_argument
from .._errors import DomainError, OutputError, TrajectoryFileError
from ..codegen import current_umask

#: the suffixes of trajectory files
TRAJECTORY_FORMATS = (".npz", ".csv")
#: names of the fixed arrays of a trajectory file (a state part with one of these names is
#: stored as ``part_<name>``)
TRAJECTORY_KEYS = ("states", "step_indices", "newton_iterations", "residual_norms",
                   "columns", "parameter_names", "parameter_values", "every", "backend")
#: the array naming the system that wrote a trajectory (.npz; files of earlier versions have
#: none, and are matched by their columns and parameters alone)
SYSTEM_KEY = "system"
_CSV_TAIL = ("newton_iterations", "residual_norm")


# --- writing ------------------------------------------------------------------------------------

#: characters of the target's name that its temporary file's name begins with (mkstemp adds
#: 8 to make it unique): a legal name of up to 255 characters must leave room for them
TEMPORARY_PREFIX = 64


def atomic_write(path: Path, write: Callable[[io.IOBase], None], binary: bool) -> None:
    """Write ``path`` through ``write(file)`` into a temporary file beside it, renamed into
    place at the end (permissions those of the file it replaces, else a new file's under
    the umask).  A failure of the file
    system (full disk, no permission, the target a directory) is an
    :class:`~symgroupoid.OutputError` naming ``path``; the temporary file is removed.
    A symbolic link is replaced, never written through (the file it names may lie outside
    what the caller meant to write); an existing file without write permission is an
    :class:`~symgroupoid.OutputError` (the rename would replace it where ``open`` would
    refuse)."""
    try:
        mode = path.lstat().st_mode
    except OSError:
        mode = None
    if mode is not None and stat.S_ISREG(mode) and not mode & 0o222:
        raise OutputError(f"{str(path)!r} cannot be written: it is read-only (mode "
                          f"{stat.S_IMODE(mode):o})")
    try:
        fd, temporary = tempfile.mkstemp(prefix=f".{path.name[:TEMPORARY_PREFIX]}.",
                                         dir=path.parent)
    except OSError as exc:
        raise OutputError(f"{str(path)!r} cannot be written: {exc.strerror or exc}") from None
    try:
        with os.fdopen(fd, "wb" if binary else "w", **({} if binary else
                                                       {"newline": "", "encoding": "utf-8"})) as f:
            write(f)
        kept = mode is not None and stat.S_ISREG(mode)  # an existing file keeps its mode
        os.chmod(temporary, stat.S_IMODE(mode) if kept else 0o666 & ~current_umask())
        os.replace(temporary, path)
    except BaseException as exc:
        try:
            os.unlink(temporary)
        except FileNotFoundError:
            pass
        if isinstance(exc, OSError):
            raise OutputError(f"{str(path)!r} cannot be written: "
                              f"{exc.strerror or exc}") from None
        raise


def number_text(x: float) -> str:
    """A float with 17 significant digits (it reads back exactly)."""
    return format(float(x), ".17g")


def state_columns(layout) -> list[str]:
    """A name for every entry of the flat state (``x (step k-1)``, ``g[0, 2]``, …)."""
    return [layout.describe(i) for i in range(layout.n_known)]


def _legacy_columns(layout) -> list[str]:
    """The state columns as earlier versions named them: the slot of the inputs to come,
    u_{k+1}, as ``known[i]``."""
    upcoming = set(getattr(layout, "upcoming_index", np.zeros(0, dtype=np.int64)).tolist())
    return [f"known[{i}]" if i in upcoming else layout.describe(i)
            for i in range(layout.n_known)]


def trajectory_arrays(traj) -> dict[str, np.ndarray]:
    """The arrays of a trajectory's ``.npz`` file (see the module docstring)."""
    names = list(traj.parameters)
    arrays = {
        "states": traj.states, "step_indices": traj.step_indices,
        "newton_iterations": traj.newton_iterations, "residual_norms": traj.residual_norms,
        "columns": np.array(state_columns(traj._layout), dtype=str),
        "parameter_names": np.array(names, dtype=str),
        "parameter_values": np.array([traj.parameters[n] for n in names], float),
        "every": np.array(traj.every), "backend": np.array(traj.backend),
        SYSTEM_KEY: np.array(traj._layout.step_name)}
    for key in traj.keys():
        label = "lambda" if key in ("λ", "multipliers") else key
        reserved = label in TRAJECTORY_KEYS or label == SYSTEM_KEY
        arrays[f"part_{label}" if reserved else label] = traj[key]
    return arrays


def output_problem(out: Path) -> str | None:
    """Why ``out`` cannot be written, known before any work (its directory does not exist,
    it is a directory, its name is too long for the file system), or None."""
    try:
        if not out.parent.is_dir():
            if out.parent.exists():
                return f"{str(out.parent)!r} is not a directory"
            return f"the directory {str(out.parent)!r} does not exist"
        return "it is a directory" if out.is_dir() else None
    except OSError as exc:  # (a name longer than the file system's, …)
        return exc.strerror or str(exc)


def output_path(path, owner: str) -> Path:
    """``path`` checked before anything is written: a path ending in .npz or .csv whose
    directory exists."""
    out = path_argument(path, "path", owner=owner)
    if os.fspath(path).endswith(("/", os.sep)):
        raise OutputError(f"{owner}: the trajectory cannot be written to {os.fspath(path)!r}: "
                          f"it names a directory (it ends in a separator); name the file")
    if out.suffix not in TRAJECTORY_FORMATS:
        raise DomainError(f"{owner}: path {str(out)!r} must end in .npz or .csv")
    problem = output_problem(out)
    if problem is not None:
        raise OutputError(f"{owner}: the trajectory cannot be written to {str(out)!r}: "
                          f"{problem}")
    return out


def save_trajectory(traj, path: Path) -> None:
    """``traj`` to ``path`` (.npz: every array; .csv: step, state columns, Newton data)."""
    if path.suffix == ".npz":
        arrays = trajectory_arrays(traj)
        atomic_write(path, lambda f: np.savez(f, **arrays), binary=True)
        return
    header = ["step", *state_columns(traj._layout), *_CSV_TAIL]

    def write(f) -> None:
        out = csv.writer(f)
        out.writerow(header)
        for k, state in enumerate(traj.states):
            tail = ["", ""] if k == 0 else [str(int(traj.newton_iterations[k - 1])),
                                             number_text(traj.residual_norms[k - 1])]
            out.writerow([str(int(traj.step_indices[k])), *map(number_text, state), *tail])

    atomic_write(path, write, binary=False)


# --- reading ------------------------------------------------------------------------------------

class TrajectoryData:
    """What a trajectory file holds, checked against a system's state layout; ``system``:
    the name of the system that wrote it, None where the file does not say (.csv, files of
    earlier versions)."""

    def __init__(self, states, step_indices, iterations, norms, parameters, every, backend,
                 system: str | None = None):
        self.states, self.step_indices = states, step_indices
        self.iterations, self.norms = iterations, norms
        self.parameters, self.every, self.backend = parameters, every, backend
        self.system = system


def read_trajectory(path, layout, parameter_names: list[str], *,
                    label: str | None = None) -> TrajectoryData:
    """The trajectory in ``path`` (.npz or .csv), for the system of ``layout``: its columns
    must be that system's state columns (names and order), its parameters (.npz) that
    system's parameters; anything else — a missing or damaged file, missing or malformed
    arrays, non-finite states — is a :class:`TrajectoryFileError` naming the file
    (``label``: how; default the system's name and the path)."""
    path = path_argument(path, "path", owner=layout.step_name)
    label = f"{layout.step_name}: {str(path)!r}" if label is None else label
    if path.suffix not in TRAJECTORY_FORMATS:
        raise TrajectoryFileError(f"{label}: a trajectory file ends in .npz or .csv")
    if not path.is_file():
        what = ("no such file" if not os.path.lexists(path) else
                "not a regular file (a directory, a FIFO or a device)" if path.exists() else
                "a link to nothing")
        raise TrajectoryFileError(f"{label}: {what}")
    reader = _read_npz if path.suffix == ".npz" else _read_csv
    data, columns = reader(path, label)
    expected = state_columns(layout)
    if columns == _legacy_columns(layout):  # (files of earlier versions: same layout)
        columns = expected
    if columns != expected:
        raise TrajectoryFileError(_column_mismatch(label, columns, expected))
    if data.system is not None and data.system != layout.step_name:
        raise TrajectoryFileError(f"{label}: it is a run of the system {data.system!r}, not of "
                                  f"{layout.step_name!r} (same state columns, other "
                                  f"equations: another scheme, forces or parameters); a "
                                  f"trajectory continues only with the system that wrote it")
    rows = len(data.states) if data.states.ndim == 2 else 0
    if data.states.shape != (rows, layout.n_known) or rows < 1:
        raise TrajectoryFileError(f"{label}: its states have shape {data.states.shape}, "
                                  f"not (rows ≥ 1, {layout.n_known})")
    if not (data.step_indices.shape == (rows,) and data.iterations.shape == (rows - 1,)
            and data.norms.shape == (rows - 1,)):
        raise TrajectoryFileError(
            f"{label}: its arrays disagree: {rows} states, {data.step_indices.shape[0]} step "
            f"indices, {data.iterations.shape[0]} iteration counts and "
            f"{data.norms.shape[0]} residual norms (a trajectory has one index per state and "
            f"one count and norm per interval)")
    if not np.isfinite(data.states).all():
        raise TrajectoryFileError(f"{label}: its states have non-finite entries")
    gaps = np.diff(data.step_indices)
    if not (gaps > 0).all():
        raise TrajectoryFileError(f"{label}: its step indices do not increase")
    if data.step_indices[0] < 0:
        raise TrajectoryFileError(f"{label}: its step indices begin at step "
                                  f"{int(data.step_indices[0])}; a run's steps are counted "
                                  f"from 0")
    if rows > 1 and ((gaps[:-1] != data.every).any() or gaps[-1] > data.every):
        raise TrajectoryFileError(
            f"{label}: its step indices are not those of a run keeping every {data.every} "
            f"steps (each {data.every} after the last, the final one at most)")
    if (data.iterations < 0).any():
        raise TrajectoryFileError(f"{label}: its Newton iteration counts must be ≥ 0")
    if not (np.isfinite(data.norms) & (data.norms >= 0)).all():
        raise TrajectoryFileError(f"{label}: its residual norms must be finite and ≥ 0 (a "
                                  f"kept state solved its step)")
    if data.parameters is not None and list(data.parameters) != list(parameter_names):
        raise TrajectoryFileError(
            f"{label}: its parameters are {', '.join(data.parameters) or 'none'}, this "
            f"system's {', '.join(parameter_names) or 'none'}: it holds another system's "
            f"trajectory")
    return data


def _column_mismatch(label: str, columns: list[str], expected: list[str]) -> str:
    if len(columns) != len(expected):
        what = f"{len(columns)} state columns, this system's states have {len(expected)}"
    else:
        i = next(i for i, (a, b) in enumerate(zip(columns, expected)) if a != b)
        what = (f"state column {i} is {columns[i]!r} where this system has {expected[i]!r} "
                f"(the same width, another layout)")
    return (f"{label}: the file holds another system's trajectory: {what}; a trajectory "
            f"continues only with the system that wrote it")


def claimed_bytes(f, label: str, what: str) -> int:
    """The bytes the .npy header at the start of the binary file ``f`` says its array holds
    (its shape times its item size), read without reading the array; a
    :class:`TrajectoryFileError` when it is no .npy header."""
    try:
        version = np.lib.format.read_magic(f)
        read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                else np.lib.format.read_array_header_2_0)
        shape, _, dtype = read(f)
    except (OSError, ValueError, EOFError) as exc:
        raise TrajectoryFileError(f"{label}: {what} has no readable .npy header ({exc})") \
            from None
    count = 1
    for n in shape:
        count *= int(n)
    return count * dtype.itemsize


def check_claimed_size(claimed: int, held: int, label: str, what: str) -> None:
    """A :class:`TrajectoryFileError` when an array's header claims more bytes than its
    file holds (a crafted header: NumPy would allocate the claim first) or than this process
    can allocate (a compressed archive that expands beyond memory)."""
    from ._memory import available_memory

    if claimed > held:
        raise TrajectoryFileError(f"{label}: {what} claims {claimed:,} bytes in its header but "
                                  f"holds {held:,}: the file is damaged or crafted")
    room = available_memory()
    if room is not None and claimed > room:
        raise TrajectoryFileError(f"{label}: {what} holds {claimed:,} bytes, more than the "
                                  f"{room:,} this process can allocate")


def _check_members(path: Path, label: str) -> None:
    """Every array of the trajectory .npz at ``path`` claims at most what it holds
    (:func:`check_claimed_size`), checked before NumPy allocates any."""
    try:
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():
                if not info.filename.endswith(".npy"):
                    continue
                with archive.open(info) as f:
                    claimed = claimed_bytes(f, label, f"its array {info.filename!r}")
                check_claimed_size(claimed, info.file_size, label,
                                   f"its array {info.filename!r}")
    except (OSError, EOFError, RuntimeError, zipfile.BadZipFile) as exc:
        raise TrajectoryFileError(f"{label}: cannot be read as .npz ({exc})") from None


def _read_npz(path: Path, label: str) -> tuple[TrajectoryData, list[str]]:
    _check_members(path, label)
    try:
        archive = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, RuntimeError, zipfile.BadZipFile) as exc:
        # (RuntimeError: zipfile's unsupported compression or encryption)
        raise TrajectoryFileError(f"{label}: cannot be read as .npz ({exc})") from None
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise TrajectoryFileError(f"{label}: not an .npz archive of arrays")
    with archive:
        missing = [k for k in TRAJECTORY_KEYS if k not in archive.files]
        if missing:
            raise TrajectoryFileError(
                f"{label}: no {', '.join(repr(k) for k in missing)} "
                f"array{'s' if len(missing) > 1 else ''} (not a trajectory written by "
                f"symgroupoid: Trajectory.save or simulate -o)")
        try:
            arrays = {k: archive[k] for k in TRAJECTORY_KEYS}
            system = archive[SYSTEM_KEY] if SYSTEM_KEY in archive.files else None
        except (OSError, ValueError, EOFError, RuntimeError, zipfile.BadZipFile) as exc:
            raise TrajectoryFileError(f"{label}: its arrays cannot be read ({exc})") from None
    columns = _strings(arrays["columns"], "columns", label)
    names = _strings(arrays["parameter_names"], "parameter_names", label)
    values = _numbers(arrays["parameter_values"], "parameter_values", label)
    if values.shape != (len(names),) or not np.isfinite(values).all():
        raise TrajectoryFileError(f"{label}: parameter_values must hold one finite number per "
                                  f"parameter name ({len(names)})")
    every = _numbers(arrays["every"], "every", label)
    if every.shape != () or not np.isfinite(every) or not every >= 1 or every != int(every):
        raise TrajectoryFileError(f"{label}: every must be an integer ≥ 1, got {every}")
    backend = arrays["backend"]
    if backend.dtype.kind != "U" or backend.shape != ():
        raise TrajectoryFileError(f"{label}: backend must be a string, got an array of dtype "
                                  f"{backend.dtype} and shape {backend.shape}")
    backend = str(backend)
    # the writing system's name: a string; another array under that key is a state part
    # named "system" of a file from before the name was recorded (matched by its columns)
    system = str(system) if system is not None and system.dtype.kind == "U" \
        and system.shape == () else None
    data = TrajectoryData(
        _numbers(arrays["states"], "states", label),
        _integers(arrays["step_indices"], "step_indices", label),
        _integers(arrays["newton_iterations"], "newton_iterations", label),
        _numbers(arrays["residual_norms"], "residual_norms", label),
        dict(zip(names, values.tolist())), int(every), backend, system)
    return data, columns


def _strings(array: np.ndarray, name: str, label: str) -> list[str]:
    if array.dtype.kind != "U" or array.ndim != 1:
        raise TrajectoryFileError(f"{label}: {name} must be a list of strings, got an array "
                                  f"of dtype {array.dtype} and shape {array.shape}")
    return [str(s) for s in array]


def _numbers(array: np.ndarray, name: str, label: str) -> np.ndarray:
    if array.dtype.kind not in "iuf" or (name == "states" and array.ndim != 2) or (
            name in ("residual_norms", "parameter_values") and array.ndim != 1):
        raise TrajectoryFileError(f"{label}: {name} must hold real numbers (a "
                                  f"{'table' if name == 'states' else 'list'} of them), got "
                                  f"dtype {array.dtype} and shape {array.shape}")
    return np.array(array, dtype=float)


def _integers(array: np.ndarray, name: str, label: str) -> np.ndarray:
    if array.dtype.kind not in "iu" or array.ndim != 1:
        raise TrajectoryFileError(f"{label}: {name} must be a list of integers, got dtype "
                                  f"{array.dtype} and shape {array.shape}")
    if array.dtype.kind == "u" and array.size and int(array.max()) > np.iinfo(np.int64).max:
        raise TrajectoryFileError(f"{label}: {name} holds {int(array.max())}, beyond the "
                                  f"64-bit integers a trajectory counts in (it would wrap "
                                  f"to a negative number)")
    return np.array(array, dtype=np.int64)


def _read_csv(path: Path, label: str) -> tuple[TrajectoryData, list[str]]:
    try:
        with open(path, newline="", encoding="utf-8") as f:
            text = f.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise TrajectoryFileError(f"{label}: cannot be read as .csv ({exc})") from None
    if text and not text.endswith(("\r\n", "\n")):
        # every row the library writes ends its line: a last line without its end was cut
        # (inside its last number, 4.5797e-15 read as 4.57)
        raise TrajectoryFileError(f"{label}: the file ends inside its last row: it was cut "
                                  f"short (a .csv cut exactly at a line's end cannot be told "
                                  f"from a shorter run; .npz files are checked whole)")
    try:
        rows = list(csv.reader(io.StringIO(text, newline="")))
    except csv.Error as exc:
        raise TrajectoryFileError(f"{label}: cannot be read as .csv ({exc})") from None
    if not rows or len(rows[0]) < 3 or rows[0][0] != "step" or \
            tuple(rows[0][-2:]) != _CSV_TAIL:
        raise TrajectoryFileError(f"{label}: not a trajectory written by symgroupoid (the "
                                  f"header is step, <state columns>, newton_iterations, "
                                  f"residual_norm)")
    columns = rows[0][1:-2]
    body = rows[1:]
    if not body or any(len(r) != len(rows[0]) for r in body):
        raise TrajectoryFileError(f"{label}: every row must have the {len(rows[0])} columns "
                                  f"of the header, and there must be at least one")
    grouped = next((v for r in body for v in r if "_" in v), None)
    if grouped is not None:  # float() reads 0_5 as 5: a typo of 0.5 would load as 5
        raise TrajectoryFileError(f"{label}: a value is not a number ({grouped!r}: digits "
                                  f"grouped by '_' are not read)")
    try:
        steps = np.array([int(r[0]) for r in body], dtype=np.int64)
        states = np.array([[float(v) for v in r[1:-2]] for r in body], dtype=float)
        iterations = np.array([int(r[-2]) for r in body[1:]], dtype=np.int64)
        norms = np.array([float(r[-1]) for r in body[1:]], dtype=float)
    except ValueError as exc:
        raise TrajectoryFileError(f"{label}: a value is not a number ({exc})") from None
    except OverflowError:
        raise TrajectoryFileError(f"{label}: a step index or iteration count is beyond the "
                                  f"range of a 64-bit integer") from None
    every = int(steps[1] - steps[0]) if len(steps) > 1 else 1
    return TrajectoryData(states, steps, iterations, norms, None, max(every, 1), ""), columns
