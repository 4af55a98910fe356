"""The command line's numeric inputs: ``--params`` text, initial states and boundary data.

Values are read here only as far as their *form* goes (text → numbers, JSON → lists); every
check of their *content* — parameter names and assumptions, shapes, group membership,
constraints, counts — is the library's own (runtime/_validate.py), so a malformed value gets
the same message on the command line as in Python.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import stat
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .._arguments import integer_argument
from .._errors import DomainError, SymgroupoidError
from ._errors import InputError
from ._system_file import SystemFile

#: keys of an initial state given by a configuration and a discrete momentum (``inputs``:
#: those of the first arrow, for a system with inputs)
MOMENTUM_KEYS = ("configuration", "momentum", "inputs")
#: keys of an initial state given by a configuration and a velocity (a discretised
#: ContinuousSystem: Simulator.from_velocity)
VELOCITY_KEYS = ("configuration", "velocity", "inputs")
#: keys of a boundary-value problem file
BOUNDARY_KEYS = ("start", "end", "steps", "params", "guess")


def parse_number(text: str, what: str) -> float:
    """A real number from text (``0.01``, ``1e-3``, ``-2``), or :class:`InputError`; only
    decimal numbers (:func:`_numeric`): Python's ``float`` also reads ``1_0`` as 10, a typo
    of ``1.0``."""
    if not _numeric(text.strip()):
        raise InputError(f"{what}: {text!r} is not a number")
    try:
        return float(text)
    except ValueError:
        raise InputError(f"{what}: {text!r} is not a number") from None


def parse_count(text: str, name: str, minimum: int = 0) -> int:
    """A count from text by the library's rule for counts (``1e7`` accepted, ``2.5`` and
    ``-5`` refused; :func:`~symgroupoid._arguments.integer_argument`)."""
    try:
        value: float | int = int(text) if "_" not in text else parse_number(text, f"--{name}")
    except ValueError:
        value = parse_number(text, f"--{name}")
    return integer_argument(value, f"--{name}", minimum=minimum)


def parse_params(text: str | None) -> dict[str, float]:
    """``"h=0.01, g=9.81"`` → ``{"h": 0.01, "g": 9.81}``.

    Each item is ``name=value``; names may not repeat.  Whether the names are the system's
    parameters, and the values allowed, is checked where they are used.
    """
    if text is None:
        return {}
    out: dict[str, float] = {}
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        name, sep, value = item.partition("=")
        name, value = name.strip(), value.strip()
        if not sep or not name or not value:
            raise InputError(f"--params: {item!r} is not of the form name=value "
                             f"(e.g. --params h=0.01,k=1)")
        if name in out:
            raise InputError(f"--params: {name} given twice")
        out[name] = parse_number(value, f"--params {name}")
    return out


def parameters(source: SystemFile, text: str | None, extra: Mapping | None = None) -> dict:
    """Parameter values: the file's ``PARAMS``, then ``extra`` (e.g. a boundary file's
    ``params``), then ``--params``, each overriding the one before by name."""
    merged: dict = {}
    for label, values in ((f"{source.path.name}: PARAMS", source.convention("PARAMS")),
                          ("params", extra)):
        if values is None:
            continue
        if not isinstance(values, Mapping):
            raise InputError(f"{label} must map parameter names to values, got "
                             f"{type(values).__name__}")
        merged.update({str(k): v for k, v in values.items()})
    merged.update(parse_params(text))
    return merged


# --- files --------------------------------------------------------------------------------------

def read_json(path: str | Path, what: str):
    """The JSON value in ``path`` (``what`` names the option in messages)."""
    if not str(path).strip():
        raise InputError(f"{what}: empty (give a JSON file, the JSON text itself or, for "
                         f"--initial, a saved trajectory)")
    path = Path(path)
    text = read_text_file(path, what, JSON_LIMIT, "a JSON file")
    return parse_json(text, f"{what} {path}")


#: the largest JSON file (an initial state, boundary data) and CSV table of inputs the
#: command line reads: a state is a few numbers per coordinate; /dev/zero is not a file
JSON_LIMIT, CSV_LIMIT = 16 * 2**20, 256 * 2**20


def checked_input_file(path: Path, what: str, limit: int, kind: str) -> None:
    """An :class:`InputError` unless ``path`` is a regular file of at most ``limit`` bytes
    (a device or a FIFO would be read without end or block)."""
    try:
        _check_regular(os.stat(path), path, what, limit, kind)
    except FileNotFoundError:
        raise InputError(f"{what} {path}: no such file") from None
    except OSError as exc:
        raise InputError(f"{what} {path}: cannot be read ({exc})") from None


def _check_regular(info: os.stat_result, path: Path, what: str, limit: int, kind: str) -> None:
    if not stat.S_ISREG(info.st_mode):
        raise InputError(f"{what} {path}: not a regular file (give {kind})")
    if info.st_size > limit:
        raise InputError(f"{what} {path}: {info.st_size} bytes, more than the "
                         f"{_size(limit)} the command line reads as {kind}")


def _size(limit: int) -> str:
    return f"{limit // 2**20} MiB" if limit >= 2**20 else f"{limit} bytes"


def read_text_file(path: Path, what: str, limit: int, kind: str) -> str:
    """The text of the regular file ``path`` of at most ``limit`` bytes, a byte-order mark
    dropped: opened without blocking (a FIFO), then checked on the descriptor it was
    opened as (:func:`checked_input_file`'s rules, with nothing swapped in between)."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0)
                     | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise InputError(f"{what} {path}: no such file") from None
    except OSError as exc:
        raise InputError(f"{what} {path}: cannot be read ({exc})") from None
    try:  # before a file object: Python refuses to make one of a directory's descriptor
        _check_regular(os.fstat(fd), path, what, limit, kind)
    except BaseException:
        os.close(fd)
        raise
    with open(fd, "rb") as fh:
        try:
            data = fh.read(limit + 1)
        except OSError as exc:
            raise InputError(f"{what} {path}: cannot be read ({exc})") from None
    if len(data) > limit:  # grown since it was looked at
        raise InputError(f"{what} {path}: more than the {_size(limit)} the command line reads "
                         f"as {kind}")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"{what} {path}: cannot be read ({exc})") from None


def parse_json(text: str, what: str):
    """The JSON value of ``text`` (``what`` names it in messages); finite numbers only."""
    try:
        return json.loads(text, parse_constant=_refuse_constant,
                          object_pairs_hook=_once_each)
    except json.JSONDecodeError as exc:
        raise InputError(f"{what}: not valid JSON: {exc.msg} (line {exc.lineno}, "
                         f"column {exc.colno})") from None
    except ValueError as exc:
        raise InputError(f"{what}: {exc}") from None
    except RecursionError:
        raise InputError(f"{what}: nested deeper than any input of the command line (a "
                         f"state is a few levels of lists)") from None


def _once_each(pairs: list) -> dict:
    """A JSON object whose keys are all different (a part given twice would silently take
    the last value)."""
    out: dict = {}
    for key, value in pairs:
        if key in out:
            raise ValueError(f"{key!r} is given twice")
        out[key] = value
    return out


def _refuse_constant(name: str):
    raise ValueError(f"{name} is not a number JSON allows (values must be finite)")


def _saved_state(path: Path, sim):
    """The last state of a trajectory written by ``simulate -o FILE.npz`` (or
    ``Trajectory.save``) for this system: its state columns must be this system's, not
    merely as many (:func:`~symgroupoid.runtime.read_trajectory`)."""
    from .._errors import TrajectoryFileError
    from ..runtime import read_trajectory

    try:
        data = read_trajectory(path, sim.layout, list(sim.parameter_names), label=str(path))
    except TrajectoryFileError as err:
        raise InputError(f"--initial {err}") from None
    return data.states[-1]


def initial_data(source: SystemFile, path: str | None, sim):
    """The initial-state value: ``--initial`` (a JSON file, the JSON text itself when it
    starts with ``{`` or ``[``, or a saved trajectory's last state, which must be one of
    ``sim``'s) else the file's ``INITIAL``; None when neither is given."""
    if path is None:
        return source.convention("INITIAL")
    if path.lstrip().startswith(("{", "[")):
        return parse_json(path, "--initial")
    if Path(path).suffix == ".npz":
        checked_input_file(Path(path), "--initial", 2**62, "a trajectory .npz")
        return _saved_state(Path(path), sim)
    return read_json(path, "--initial")


def initial_origin(path: str | None) -> str:
    """How messages name where an initial state came from: ``--initial``, else the system
    file's ``INITIAL``."""
    return "--initial" if path is not None else "the file's INITIAL"


def initial_state(sim, data, params, *, origin: str = "--initial", project: bool = False
                  ) -> np.ndarray:
    """The flat initial state of ``sim`` from ``data`` (see docs/cli.md):

    - a mapping of named state parts (``{"x": [0, 0.01], "g": [[…]], "lambda": […]}``),
      as :meth:`Simulator.state` reads them;
    - ``{"configuration": …, "momentum": […]}``: :meth:`Simulator.from_momentum`;
    - ``{"configuration": …, "velocity": […]}``: :meth:`Simulator.from_velocity` (a system
      discretised from a ContinuousSystem);
    - a list: the flat state, ordered as ``step.knowns``.
    """
    if data is None:
        raise InputError(f"{sim.name}: no initial state: give --initial FILE.json, or "
                         f"define INITIAL in the system file")
    sim.parameters(params)  # (their errors are the parameters', not the state's)
    with named_by(origin):
        return _initial_state(sim, data, params, origin, project)


@contextlib.contextmanager
def named_by(origin: str):
    """The library's errors about a value the command line read from ``origin``
    (``--initial``, ``--inputs U.csv``) name it first: ``--initial: spring: unknown state
    part 'x'; …`` where the library's message begins with the system's name.  The error is
    the same object, of the same class, with that message."""
    try:
        yield
    except SymgroupoidError as err:
        if err.args and isinstance(err.args[0], str) and not err.args[0].startswith(origin):
            err.args = (f"{origin}: {err.args[0]}", *err.args[1:])
        raise


def _initial_state(sim, data, params, origin: str, project: bool) -> np.ndarray:
    """:func:`initial_state` once the parameters are checked."""
    if isinstance(data, Mapping) and "velocity" in data:
        configuration, velocity = velocity_data(data, origin)
        return sim.from_velocity(configuration, velocity, params,
                                 inputs=first_inputs(sim, data, origin))
    if isinstance(data, Mapping) and "momentum" in data:
        extra = sorted(set(map(str, data)) - set(MOMENTUM_KEYS))
        if extra:
            raise InputError(f"{origin}: a state from a momentum has only the keys "
                             f"{_listed(MOMENTUM_KEYS)}; got also {', '.join(extra)}")
        return sim.from_momentum(data.get("configuration"), data["momentum"], params,
                                 inputs=first_inputs(sim, data, origin))
    if isinstance(data, (str, bytes, int, float, bool)):
        raise InputError(f"{origin}: an initial state is an object of named parts, "
                         f"{{\"configuration\": …, \"momentum\": […]}}, or a list; got "
                         f"{type(data).__name__} {data!r}")
    if project:  # --project: onto the constraints first (Simulator.project_initial)
        return sim.project_initial(data, params)
    try:
        return sim.state(data, params)
    except DomainError as err:
        if not getattr(err, "violated", None):  # (the constraints, not e.g. a parameter)
            raise
        raise DomainError(f"{err} (on the command line: --project)") from None


def velocity_data(data: Mapping, origin: str = "--initial") -> tuple:
    """(configuration, velocity) of an initial state ``{"configuration": …, "velocity":
    […]}``; the configuration may be omitted when the base is a point."""
    extra = sorted(set(map(str, data)) - set(VELOCITY_KEYS))
    if extra:
        raise InputError(f"{origin}: a state from a velocity has only the keys "
                         f"{_listed(VELOCITY_KEYS)}; got also {', '.join(extra)}")
    return data.get("configuration"), data["velocity"]


def first_inputs(sim, data: Mapping, origin: str = "--initial"):
    """The ``inputs`` of an initial state from a momentum or a velocity: those of its first
    arrow, required for a system with inputs (None for one without)."""
    names = list(sim.layout.input_names)
    if "inputs" not in data:
        if names:
            raise InputError(f"{origin}: {sim.name} has inputs ({', '.join(names)}): an "
                             f"initial state from a momentum or a velocity needs those of "
                             f"its first arrow, \"inputs\": [{', '.join(names)}]")
        return None
    return data["inputs"]


def _listed(keys) -> str:
    return ", ".join(f"'{k}'" for k in keys)


#: the first bytes of every .npy file (NumPy's format, any version)
_NPY_MAGIC = b"\x93NUMPY"


def read_inputs(path: str | None, names: list[str]) -> np.ndarray | None:
    """The input sequence of a forced system's run from ``--inputs`` (docs/cli.md): a
    ``.npy`` array (read without pickles) or a ``.csv`` table of numbers, one row per step
    (row j: the inputs of the arrow step j computes) and one column per input, with an
    optional first row naming the columns, which must then be the system's inputs in
    order (``names``).  Its shape and values are checked by the library
    (:meth:`Simulator.simulate`'s ``inputs=``); None without the option."""
    if path is None:
        return None
    file = Path(path)
    if file.suffix not in (".npy", ".csv"):
        raise InputError(f"--inputs {file}: the file name must end in .npy or .csv")
    if file.suffix == ".npy":
        checked_input_file(file, "--inputs", 2**62, "a .npy array")
        try:
            with open(file, "rb") as fh:
                magic = fh.read(len(_NPY_MAGIC))
        except OSError as exc:
            raise InputError(f"--inputs {file}: cannot be read ({exc})") from None
        if magic != _NPY_MAGIC:
            raise InputError(f"--inputs {file}: not a .npy array (it does not start with "
                             f"NumPy's header: write one with numpy.save, or give the "
                             f"numbers as a .csv table)")
        from ..runtime import check_claimed_size, claimed_bytes

        with open(file, "rb") as fh:  # a header claiming more than the file: crafted
            claimed = claimed_bytes(fh, f"--inputs {file}", "the array")
            check_claimed_size(claimed, os.fstat(fh.fileno()).st_size,
                               f"--inputs {file}", "the array")
        try:
            return np.load(file, allow_pickle=False)
        except (OSError, ValueError) as exc:
            why = ("it holds Python objects (pickled data), which are never loaded: save an "
                   "array of numbers" if "pickle" in str(exc) else str(exc))
            raise InputError(f"--inputs {file}: cannot be read ({why})") from None
    text = read_text_file(file, "--inputs", CSV_LIMIT, "a CSV table (larger: a .npy array)")
    lines = [line for line in text.splitlines()
             if line.strip() and not line.lstrip().startswith("#")]
    if lines and not _numeric(lines[0].split(",")[0].strip()):
        header = [cell.strip() for cell in lines.pop(0).split(",")]
        if not all(cell.isidentifier() for cell in header):
            raise InputError(f"--inputs {file}: the first row ({', '.join(header)}) is "
                             f"neither the inputs' names nor decimal numbers separated by "
                             f"commas")
        if header != names:
            raise InputError(f"--inputs {file}: the header names the columns "
                             f"{', '.join(header)}; the system's inputs are "
                             f"{', '.join(names) or 'none'} (in that order)")
    rows = [[cell.strip() for cell in line.split(",")] for line in lines]
    for j, row in enumerate(rows):
        for cell in row:
            if not _numeric(cell):
                raise InputError(f"--inputs {file}: row {j} (step {j}): {cell!r} is not a "
                                 f"number")
    if len({len(row) for row in rows}) > 1:
        raise InputError(f"--inputs {file}: the rows have different numbers of columns")
    if not rows:
        raise InputError(f"--inputs {file}: holds no rows of inputs (one row per step, one "
                         f"column per input: {', '.join(names) or 'none'})")
    return np.array([[float(cell) for cell in row] for row in rows], dtype=float)


def run_inputs(path: str | None, sim, steps: int) -> np.ndarray | None:
    """The inputs of a run of ``steps`` steps from ``--inputs`` (docs/cli.md):
    :func:`input_table` with one row per step."""
    return input_table(path, list(sim.layout.input_names), sim.name, steps, "step",
                       "row j: the inputs of the arrow step j computes", f"--steps {steps}")


def input_table(path: str | None, names: list[str], owner: str, rows: int, per: str,
                meaning: str, wanted: str) -> np.ndarray | None:
    """The inputs of ``rows`` rows (one ``per`` step, or term of the action) from
    ``--inputs``, required for a system with inputs (``names``): a table of at least
    ``rows`` rows gives its first ``rows`` (a file may hold a longer sequence), a single row
    is held constant for every one; anything else goes to the library's checks
    (:meth:`Simulator.simulate`'s ``inputs=``).  ``meaning`` says what a row is and
    ``wanted`` how many rows the command asks for, in messages."""
    if path is not None and not names:
        raise InputError(f"--inputs {path}: {owner} has no inputs (its forces, if any, "
                         f"read none)")
    inputs = read_inputs(path, names)
    if inputs is None:
        if names:
            raise InputError(f"{owner} has inputs ({', '.join(names)}): give their "
                             f"sequence with --inputs U.npy|U.csv, one row per {per} (at "
                             f"least {wanted} rows; {meaning}), or one row held constant")
        return None
    if inputs.ndim == 1 and len(names) == 1 and inputs.shape[0] > 1:
        inputs = inputs[:, None]  # one input: a sequence of its values is a column
    _finite_inputs(inputs, path, names, per)
    if inputs.ndim == 2 and inputs.shape[1] != len(names):
        raise InputError(f"--inputs {path}: {inputs.shape[1]} column"
                         f"{'s' if inputs.shape[1] != 1 else ''} for the "
                         f"{len(names)} input{'s' if len(names) != 1 else ''} of {owner} "
                         f"({', '.join(names) or 'none'}): one column per input, one row "
                         f"per {per}")
    if inputs.ndim == 2 and inputs.shape[0] == 1:
        return inputs[0]
    if inputs.ndim == 2 and inputs.shape[0] > rows:
        return inputs[:rows]
    if inputs.ndim == 2 and inputs.shape[0] < rows:
        raise InputError(f"--inputs {path}: {inputs.shape[0]} rows for {wanted}: "
                         f"give at least {rows} rows ({meaning}; the first {rows} of a "
                         f"longer table are used), or a single row held for every {per}")
    return inputs


def _finite_inputs(inputs: np.ndarray, path: str, names: list[str], per: str) -> None:
    """A non-finite value of ``--inputs`` named by its file, input and row (the library
    refuses it too, naming only the system)."""
    if inputs.dtype.kind not in "fiu" or inputs.ndim not in (1, 2) or not names:
        return  # (the library's checks name the rest)
    table = inputs[None, :] if inputs.ndim == 1 else inputs
    if table.shape[1] != len(names):
        return
    bad = np.argwhere(~np.isfinite(table))
    if len(bad):
        row, column = (int(v) for v in bad[0])
        raise DomainError(f"--inputs {path}: input {names[column]} in row {row} (the "
                          f"{per} {row}) is {table[row, column]}; inputs must be finite")


#: a decimal number as a CSV cell holds it (Python's float() also reads 1_0 as 10)
_DECIMAL = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?|[+-]?(inf|infinity|nan)",
                      re.IGNORECASE)


def _numeric(text: str) -> bool:
    return _DECIMAL.fullmatch(text) is not None


def boundary_problem(path: str) -> dict:
    """The boundary-value problem in a JSON file: ``start``, ``end``, ``steps`` (required),
    ``params`` and ``guess`` (optional)."""
    data = read_json(path, "bvp")
    if not isinstance(data, dict):
        raise InputError(f"bvp {path}: expected an object with the keys "
                         f"{', '.join(BOUNDARY_KEYS)}; got {type(data).__name__}")
    unknown = sorted(set(data) - set(BOUNDARY_KEYS))
    if unknown:
        raise InputError(f"bvp {path}: unknown key(s) {', '.join(unknown)}; the keys are "
                         f"{', '.join(BOUNDARY_KEYS)}")
    missing = [k for k in ("start", "end", "steps") if k not in data]
    if missing:
        raise InputError(f"bvp {path}: missing {', '.join(missing)}")
    guess = data.get("guess")
    if isinstance(guess, dict):
        extra = sorted(set(guess) - {"arrows", "multipliers"})
        if extra or "arrows" not in guess:
            raise InputError(f"bvp {path}: a guess object has the keys 'arrows' and "
                             f"(optionally) 'multipliers'")
        guess = (guess["arrows"], guess["multipliers"]) if "multipliers" in guess \
            else guess["arrows"]
    steps = integer_argument(data["steps"], "steps", minimum=0, owner=f"bvp {path}")
    return {"start": data["start"], "end": data["end"], "steps": steps,
            "params": data.get("params"), "guess": guess}
