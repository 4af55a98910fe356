"""Hostile input at the command line: ``symgroupoid.cli.main([...])``.

Every command (``simulate``, ``verify``, ``bvp``, ``derive``, ``emit``, ``cache``) gets system
files that do not parse, raise, exit, define no system or several, define junk ``PARAMS``,
``INITIAL`` or ``NOETHER``, or are not files; option texts that are not numbers, counts out
of range, ``--params`` of every malformed form; ``--initial`` and boundary-value files with
arbitrary JSON (junk keys, strings, NaN spelled out, nested lists, huge numbers) or bytes
that are not JSON or not an ``.npz``; output paths that cannot be written.

The contract (docs/cli.md): exit status 0 (and the output file written when asked for), 1
with exactly one line ``symgroupoid: error: …`` on stderr that is not an "internal error"
(any other exception is a defect the command line still reports in one line), or 2 for a
malformed command line (argparse's usage and error).  Never a traceback.  The NumPy backend
is used throughout (``SYMGROUPOID_BACKEND=numpy``): no C build per example.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from _hostile import (
    PROFILES,
    TALLY,
    Defect,
    profile,
    scratch_cwd,  # noqa: F401  (autouse fixture)
)
from hypothesis import given
from hypothesis import strategies as st
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    REPO,
    isolated_cache,
    module_cache_root,
    shared_kernels,
)

from symgroupoid.cli import main

SPRING = REPO / "examples" / "cli" / "spring.py"

#: system files a hostile user passes (written into the scratch working directory)
SYSTEM_FILES = {
    "syntax.py": "def (:\n",
    "raises.py": "raise RuntimeError('boom')\n",
    "exits.py": "import sys\nsys.exit(3)\n",
    "empty.py": "",
    "nothing.py": "x = 1\n",
    "binary.py": b"\0\0\xff",
    "two.py": "from spring import *\nother = spring\n",
    "junk_params.py": "from spring import *\nPARAMS = 'h=1'\n",
    "bad_params.py": "from spring import *\nPARAMS = {'h': 'a', 'zeta': 1}\n",
    "junk_initial.py": "from spring import *\nINITIAL = 3\n",
    "bad_initial.py": "from spring import *\nINITIAL = {'q': [float('nan'), 1]}\n",
    "junk_noether.py": "from spring import *\nNOETHER = [object(), {'section': 'x'}]\n",
    "factory.py": ("import symgroupoid as sg\nfrom spring import spring as _s\n"
                   "def make() -> sg.DiscreteSystem:\n    return 3\n"),
    "keyerror.py": "from spring import *\nimport os\nos.environ['__missing__']\n",
}
TARGETS = ["spring.py", "spring.py:spring", "spring.py:PARAMS", "spring.py:nope",
           "spring.py:", "missing.py", "folder.py", "", ":", "spring", "notes.txt",
           *SYSTEM_FILES, "factory.py:make"]

numbers_text = st.one_of(
    st.sampled_from(["10", "1e3", "-1", "2.5", "nan", "inf", "-inf", "1e400", "", " 5 ",
                     "5_0", "0x10", "１０", "1e-3", "9" * 30, "0", "1.0", "--", "3 4"]),
    st.text(max_size=4))
param_text = st.one_of(
    st.sampled_from(["h=0.1", "h=", "=1", "h=1,h=2", "h=nan", "zeta=1", "h=1e400",
                     "h=-1", "k=1e308,h=1e-300", "h=0.1,,k=2", "h:0.1", "h=1j", ",", "h=0.1 k=1",
                     "H=0.1", "h=0.05,k=1e400"]),
    st.text(max_size=8))

json_values = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-10**30, 10**30),
              st.floats(allow_nan=False, allow_infinity=False), st.text(max_size=4)),
    lambda inner: st.one_of(st.lists(inner, max_size=4),
                            st.dictionaries(st.text(max_size=6), inner, max_size=4)),
    max_leaves=8)


@st.composite
def initial_files(draw) -> str:
    """An --initial file: valid JSON states, near-valid ones, any JSON, or junk bytes."""
    kind = draw(st.sampled_from(["valid", "near", "json", "text", "npz", "missing",
                                 "directory"]))
    if kind == "missing":
        return "absent.json"
    if kind == "directory":
        return "."
    if kind == "npz":
        name = draw(st.sampled_from(["junk.npz", "states.npz", "wide.npz", "other.npz",
                                     "own.npz"]))
        if name == "junk.npz":
            Path(name).write_bytes(draw(st.binary(max_size=40)))
        elif name == "states.npz":
            np.savez(name, states=np.array([[0.1, 0.2]]))
        elif name in ("other.npz", "own.npz"):  # a trajectory file of the same width: of
            q = "p" if name == "other.npz" else "q"  # another system (p), or of this one
            np.savez(name, states=np.array([[1.0, 0.999], [0.999, 0.997]]),
                     step_indices=np.array([0, 1]), newton_iterations=np.array([2]),
                     residual_norms=np.array([1e-16]),
                     columns=np.array([f"{q} (step k-1)", q]),
                     parameter_names=np.array(["h", "k"]),
                     parameter_values=np.array([0.05, 4.0]), every=np.array(1),
                     backend=np.array("c"))
        else:
            np.savez(name, states=np.zeros((2, 5)), other=np.ones(3))
        return name
    name = "initial.json"
    if kind == "valid":
        data = draw(st.sampled_from([{"q": [1.0, 0.999]}, [1.0, 0.999],
                                     {"configuration": {"q": 1.0}, "momentum": [0.1]}]))
        Path(name).write_text(json.dumps(data))
    elif kind == "near":
        data = draw(st.sampled_from([
            {"q": [1.0]}, {"q": [1.0, "a"]}, {"q": [[1.0, 2.0]]}, {"x": [1.0, 2.0]},
            {"q": [1.0, 0.9], "lambda": [1]}, {"configuration": {"q": "a"}, "momentum": [1]},
            {"configuration": {"q": 1.0}, "momentum": [1, 2]}, {"momentum": [1]},
            {"configuration": None, "momentum": None}, [1.0, 2.0, 3.0], [], "q", 3,
            {"q": [1e308, -1e308]}, {"q": [1, 2], "extra": 1}]))
        Path(name).write_text(json.dumps(data))
    elif kind == "json":
        Path(name).write_text(json.dumps(draw(json_values)))
    else:
        Path(name).write_bytes(draw(st.sampled_from(
            [b"{", b"NaN", b'{"q": [NaN, 1]}', b'{"q": [Infinity, 1]}', b"\xff\xfe",
             b'{"q": [1e999, 1]}', b""])))
    return name


@st.composite
def boundary_files(draw) -> str:
    name = "problem.json"
    kind = draw(st.sampled_from(["valid", "field", "json", "text"]))
    problem = {"start": 0.0, "end": 1.0, "steps": 6, "params": {"h": 0.05, "k": 4.0}}
    if kind == "field":
        key = draw(st.sampled_from(["start", "end", "steps", "params", "guess", "extra"]))
        problem[key] = draw(st.one_of(json_values, st.sampled_from(
            [[0.0, 1.0], "a", -3, 2.5, 1e300, {"arrows": [[0, 1]]},
             {"arrows": [[0.0, 0.1]] * 6, "multipliers": [[1]]}, [[0.0, 0.2]] * 6])))
        if draw(st.booleans()):
            problem.pop(key, None)
    elif kind == "json":
        problem = draw(json_values)
    if kind == "text":
        Path(name).write_bytes(draw(st.sampled_from([b"{", b'{"start": NaN}', b"[]"])))
    else:
        Path(name).write_text(json.dumps(problem))
    return name


outputs = st.sampled_from(["out.npz", "out.csv", "out.txt", "missing/out.npz", "",
                           "folder.py/out.npz", "spring.py/x.csv", "out"])


@st.composite
def command_lines(draw) -> list[str]:
    command = draw(st.sampled_from(["simulate", "simulate", "verify", "bvp", "derive", "emit",
                                    "cache", "junk"]))
    target = draw(st.sampled_from(TARGETS))
    if command == "simulate":
        argv = ["simulate", target, "--steps", draw(numbers_text)]
        if draw(st.booleans()):
            argv += ["--every", draw(numbers_text)]
        if draw(st.booleans()):
            argv += ["--params", draw(param_text)]
        if draw(st.booleans()):
            argv += ["--initial", draw(initial_files())]
        if draw(st.booleans()):
            argv += ["-o", draw(outputs)]
    elif command == "verify":
        argv = ["verify", target, "--steps", draw(numbers_text), "--points",
                draw(st.sampled_from(["2", "0", "-1", "x", "1e9"])), "--seed",
                draw(st.sampled_from(["0", "-1", "1.5", "2e20", "x"])), "--no-sympy"]
        if draw(st.booleans()):
            argv += ["--params", draw(param_text)]
        if draw(st.booleans()):
            argv += ["--initial", draw(initial_files())]
    elif command == "bvp":
        argv = ["bvp", target, draw(st.one_of(boundary_files(), st.just("absent.json"))),
                "--max-iterations", draw(numbers_text)]
        if draw(st.booleans()):
            argv += ["--params", draw(param_text)]
        if draw(st.booleans()):
            argv += ["-o", draw(outputs)]
        if draw(st.booleans()):
            argv += ["--check"]
    elif command == "derive":
        argv = ["derive", target]
        if draw(st.booleans()):
            argv += ["--document", draw(st.sampled_from(["eq.tex", "missing/eq.tex", "",
                                                         "folder.py", "spring.py/e.tex"]))]
    elif command == "emit":
        argv = ["emit", target, "-o", draw(st.sampled_from(["outdir", "", "spring.py",
                                                            "a\0b", "folder.py/x"]))]
        if draw(st.booleans()):
            argv += ["--name", draw(st.sampled_from(["", "k", "../k", "a/b", "é", "..."]))]
        if draw(st.booleans()):
            argv += ["--prefix", draw(st.sampled_from(["", "int", "1x", "a b", "é"]))]
    elif command == "cache":
        argv = ["cache", *draw(st.sampled_from([["info"], ["clear"], ["clear", "--bad"],
                                                 ["purge"], [""], ["info", "--bad"]]))]
    else:
        argv = draw(st.lists(st.text(max_size=6), max_size=4))
    return argv


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            status = main(argv)
        except SystemExit as exit_:
            status = exit_.code if isinstance(exit_.code, int) else 1
    return status, out.getvalue(), err.getvalue()


def judge_cli(argv: list[str]) -> None:
    """The exit status and stderr of one command line against the contract."""
    counts = TALLY["command line"]
    counts.tried += 1
    try:
        status, out, err = run_cli(argv)
    except BaseException as exc:  # noqa: BLE001 - anything escaping main is a defect
        counts.defects += 1
        raise Defect(f"{argv}: main raised {type(exc).__name__}: {exc}") from exc
    lines = [line for line in err.splitlines() if line.strip()]
    problem = None
    if "Traceback" in err:
        problem = "a traceback on stderr"
    elif status == 0:
        for i, arg in enumerate(argv[:-1]):
            if arg == "-o" and argv[0] in ("simulate", "bvp") and not Path(argv[i + 1]).is_file():
                problem = f"exit 0 without writing {argv[i + 1]}"
    elif status == 1:
        errors = [line for line in lines if line.startswith("symgroupoid: error:")]
        if len(errors) != 1 or lines[-1] != errors[0]:
            problem = f"exit 1 without exactly one closing error line: {lines[-3:]}"
        elif "internal error" in errors[0]:
            problem = errors[0]
    elif status == 2:
        if not any("usage:" in line for line in lines) or "error:" not in lines[-1]:
            problem = f"exit 2 without argparse's usage and error: {lines[-3:]}"
    else:
        problem = f"exit status {status}"
    if problem is not None:
        counts.defects += 1
        raise Defect(f"symgroupoid {' '.join(map(repr, argv))}: {problem}\n{err[-1500:]}")
    if status == 0:
        counts.valid += 1
    else:
        counts.clear += 1


@pytest.fixture
def system_files(monkeypatch):
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "numpy")
    shutil.copy(SPRING, "spring.py")
    Path("folder.py").mkdir()
    Path("notes.txt").write_text("not python")
    for name, text in SYSTEM_FILES.items():
        Path(name).write_bytes(text if isinstance(text, bytes) else text.encode())
    monkeypatch.syspath_prepend(str(Path.cwd()))


@pytest.mark.parametrize("run", PROFILES)
def test_command_lines(system_files, run):
    @profile(run, 14, 300)
    @given(argv=command_lines())
    def prop(argv):
        judge_cli(argv)

    prop()


def test_an_unexpected_exception_is_one_line_not_a_traceback(system_files, monkeypatch):
    """A defect inside a command still ends in one line (and --debug shows it raw)."""
    def broken(args):
        raise TypeError("an internal mistake")

    monkeypatch.setattr("symgroupoid.cli._main.run_simulate", broken)
    status, out, err = run_cli(["simulate", "spring.py", "--steps", "3"])
    assert status == 1 and "Traceback" not in err
    assert err.strip().splitlines() == ["symgroupoid: error: internal error (TypeError: an "
                                        "internal mistake); this is a defect of symgroupoid: "
                                        "please report it with the output of --debug"]
    with pytest.raises(TypeError, match="an internal mistake"):
        main(["simulate", "spring.py", "--steps", "3", "--debug"])


@pytest.mark.usefixtures("shared_kernels")  # the examples' systems, built once
@pytest.mark.parametrize("initial, message", [
    ("[" * 5000 + "]" * 5000, "nested deeper than any input"),
    ('{"q": [1.0, 0.999], "q": [5.0, 5.1]}', "'q' is given twice"),
    ('{"q": [true, 0.999]}', "a bool among them")])
def test_initial_json_that_would_be_misread_is_refused(initial, message, capsys):
    """Deep nesting was an internal error (RecursionError); a key given twice took the last
    value; a JSON true in a list of numbers was read as 1.0."""
    shutil.copy(SPRING, "spring.py")
    assert main(["simulate", "spring.py", "--steps", "3", "--initial", initial]) == 1
    err = capsys.readouterr().err
    assert message in err and "internal error" not in err, err


def test_a_boundary_file_with_a_key_given_twice_is_refused(capsys):
    shutil.copy(SPRING, "spring.py")
    Path("b.json").write_text('{"start": 0.0, "end": 1.0, "steps": 20, "start": 5.0}')
    assert main(["bvp", "spring.py", "b.json"]) == 1
    assert "'start' is given twice" in capsys.readouterr().err


@pytest.mark.usefixtures("shared_kernels")  # the examples' systems, built once
def test_a_csv_with_a_byte_order_mark_and_an_empty_initial(capsys):
    """A spreadsheet's "CSV UTF-8" starts with a byte-order mark: its header read
    "\\ufeffu", and the message said the columns \\ufeffu were not the inputs u; an empty
    --initial was read as the directory '.'."""
    shutil.copy(REPO / "examples" / "cli" / "driven_spring.py", "driven_spring.py")
    Path("U.csv").write_bytes(b"\xef\xbb\xbfu\n0.1\n")
    assert main(["simulate", "driven_spring.py", "--steps", "3", "--inputs", "U.csv",
                 "--backend", "numpy"]) == 0
    shutil.copy(SPRING, "spring.py")
    capsys.readouterr()
    assert main(["simulate", "spring.py", "--steps", "3", "--initial", ""]) == 1
    err = capsys.readouterr().err
    assert "--initial: empty" in err and "'.'" not in err, err


@pytest.mark.usefixtures("shared_kernels")  # the examples' systems, built once
def test_inputs_for_a_system_without_inputs_are_refused(capsys):
    """The message said "the system's inputs are none (in that order)"."""
    shutil.copy(SPRING, "spring.py")
    Path("U.csv").write_text("0.1\n0.2\n")
    assert main(["simulate", "spring.py", "--steps", "2", "--inputs", "U.csv"]) == 1
    err = capsys.readouterr().err
    assert "has no inputs" in err and "in that order" not in err, err


@pytest.mark.usefixtures("shared_kernels")  # the examples' systems, built once
@pytest.mark.parametrize("option", ["--initial", "--inputs", "boundary"])
def test_a_device_or_a_fifo_is_not_read_as_an_input_file(option, capsys):
    """``--initial /dev/zero`` read until the out-of-memory killer ended the process (a
    FIFO would block for ever); so did a boundary file.  Only regular files are read, up to
    a size."""
    shutil.copy(REPO / "examples" / "cli" / "driven_spring.py", "driven_spring.py")
    os.mkfifo("pipe.csv")
    for source in ("/dev/zero", "pipe.csv"):
        if option == "boundary":
            args = ["bvp", "driven_spring.py", source]
        elif option == "--inputs":
            args = ["simulate", "driven_spring.py", "--steps", "2", "--inputs", source]
        else:
            args = ["simulate", "driven_spring.py", "--steps", "2", "--initial", source]
        if option == "--inputs" and source == "/dev/zero":
            continue  # (its name has no .csv/.npy suffix: refused for that, first)
        assert main(args) == 1
        err = capsys.readouterr().err
        assert "not a regular file" in err and "Traceback" not in err, err


@pytest.mark.usefixtures("shared_kernels")  # the examples' systems, built once
def test_an_input_file_larger_than_the_limit_is_refused(capsys, monkeypatch):
    monkeypatch.setattr("symgroupoid.cli._inputs.JSON_LIMIT", 100)
    shutil.copy(SPRING, "spring.py")
    Path("big.json").write_text("[" + ", ".join(["0.0"] * 100) + "]")
    assert main(["simulate", "spring.py", "--steps", "2", "--initial", "big.json"]) == 1
    assert "more than the 100 bytes" in capsys.readouterr().err


@pytest.mark.usefixtures("shared_kernels")  # the examples' systems, built once
@pytest.mark.parametrize(("content", "message"), [
    ("", "holds no rows of inputs"),
    ("u\n", "holds no rows of inputs"),
    ("1_0\n", "neither the inputs' names nor decimal numbers"),  # float() read it as 10
    ("0.1\n1_0\n", "row 1 (step 1): '1_0' is not a number"),
    ("0x1p-3\n", "neither the inputs' names nor decimal numbers"),
    ("0.1;0.2\n", "neither the inputs' names nor decimal numbers"),
])
def test_csv_inputs_are_decimal_numbers(content, message, capsys):
    """(An empty table was reported as "got shape (0,)", ``1_0`` was read as 10, and a
    first row of hexadecimal or semicolon-separated numbers as a header naming columns.)"""
    shutil.copy(REPO / "examples" / "cli" / "driven_spring.py", "driven_spring.py")
    Path("U.csv").write_text(content)
    assert main(["simulate", "driven_spring.py", "--steps", "2", "--inputs", "U.csv",
                 "--backend", "numpy"]) == 1
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err, err


@pytest.mark.usefixtures("shared_kernels")  # the examples' systems, built once
def test_a_pickled_npy_is_refused_without_advice_to_unpickle(capsys):
    shutil.copy(REPO / "examples" / "cli" / "driven_spring.py", "driven_spring.py")
    np.save("U.npy", np.array([{"u": 1}], dtype=object), allow_pickle=True)
    assert main(["simulate", "driven_spring.py", "--steps", "2", "--inputs", "U.npy"]) == 1
    err = capsys.readouterr().err
    assert "never loaded" in err and "allow_pickle" not in err, err


def test_a_bad_initial_in_the_file_is_not_blamed_on_the_option(capsys):
    """(The file's own INITIAL, with no --initial given, was reported as "--initial: …".)"""
    text = (REPO / "examples" / "cli" / "pendulum_order4.py").read_text()
    Path("pendulum.py").write_text(text.replace('"velocity": [0.5]}',
                                                '"velocity": [0.5], "extra": 1}'))
    assert main(["simulate", "pendulum.py", "--steps", "2", "--backend", "numpy"]) == 1
    err = capsys.readouterr().err
    assert "the file's INITIAL: a state from a velocity" in err and "--initial" not in err, err


@pytest.mark.usefixtures("shared_kernels")  # the examples' systems, built once
@pytest.mark.parametrize("option", ["--initial", "--inputs", "boundary"])
def test_a_directory_is_not_read_as_an_input_file(option, capsys):
    """A directory named where a file is read printed "symgroupoid: error: 3: Is a
    directory" (Python refused a file object of its descriptor before the regular-file
    check), naming neither the option nor the path."""
    shutil.copy(REPO / "examples" / "cli" / "driven_spring.py", "driven_spring.py")
    Path("U.csv").write_text("0.1\n")
    Path("folder.json").mkdir()
    Path("folder.csv").mkdir()
    args = {"--initial": ["simulate", "driven_spring.py", "--steps", "2", "--inputs", "U.csv",
                          "--initial", "folder.json"],
            "--inputs": ["simulate", "driven_spring.py", "--steps", "2", "--inputs",
                         "folder.csv"],
            "boundary": ["bvp", "driven_spring.py", "folder.json", "--inputs", "U.csv"]}[option]
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "folder" in err and "not a regular file" in err and "Is a directory" not in err, err


@pytest.mark.usefixtures("shared_kernels")  # the examples' systems, built once
def test_npy_inputs_are_read_as_csv_inputs_are(capsys):
    """A one-dimensional .npy of one input's values is a column, and a longer one gives its
    first N rows as a longer CSV table does (it was refused, "got shape (10,)"); a file
    named .npy that is not one is said to be so (it was reported as pickled data)."""
    shutil.copy(REPO / "examples" / "cli" / "driven_spring.py", "driven_spring.py")
    values = np.linspace(0.0, 1.0, 10)
    np.save("long.npy", values)
    np.savetxt("long.csv", values)
    outputs = []
    for name in ("long.npy", "long.csv"):
        assert main(["simulate", "driven_spring.py", "--steps", "5", "--inputs", name,
                     "--backend", "numpy", "-o", f"{name}.npz"]) == 0
        outputs.append(np.load(f"{name}.npz")["states"])
    np.testing.assert_array_equal(*outputs)
    capsys.readouterr()
    Path("text.npy").write_text("0.1\n0.2\n")
    assert main(["simulate", "driven_spring.py", "--steps", "2", "--inputs", "text.npy"]) == 1
    err = capsys.readouterr().err
    assert "not a .npy array" in err and "pickled" not in err, err


@pytest.mark.parametrize("steps, message", [
    ('"10"', "steps must be an integer, got str"), ("null", "steps must be an integer"),
    ("[10]", "steps must be an integer"), ("2.5", "steps must be an integer")])
def test_boundary_steps_are_checked_before_any_arithmetic(steps, message, capsys):
    """"steps": "10" (or null, a list) was an internal error (TypeError in the inputs'
    count); 1e1, a form counts allow, solves as 10."""
    shutil.copy(REPO / "examples" / "cli" / "driven_spring.py", "driven_spring.py")
    Path("U.csv").write_text("0.1\n")
    Path("b.json").write_text(f'{{"start": [0.0], "end": [1.0], "steps": {steps}}}')
    assert main(["bvp", "driven_spring.py", "b.json", "--inputs", "U.csv"]) == 1
    err = capsys.readouterr().err
    assert message in err and "internal error" not in err, err
    Path("b.json").write_text('{"start": [0.0], "end": [1.0], "steps": 1e1}')
    assert main(["bvp", "driven_spring.py", "b.json", "--inputs", "U.csv"]) == 0


def test_cache_info_says_a_cache_path_that_is_a_file_is_not_used(monkeypatch, capsys):
    """It reported "(empty: not created yet)", exit 0, where compile() refused the path."""
    Path("cachefile").write_text("not a cache")
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(Path("cachefile").resolve()))
    assert main(["cache", "info"]) == 1
    assert "NOT USED: it is not a directory" in capsys.readouterr().out


@pytest.mark.usefixtures("shared_kernels")  # the examples' systems, built once
def test_an_npy_whose_header_claims_more_than_the_file_is_refused(capsys):
    """A header claiming 10¹⁵ inputs made NumPy allocate 7 PiB: "internal error
    (MemoryError …)"."""
    import io

    shutil.copy(REPO / "examples" / "cli" / "driven_spring.py", "driven_spring.py")
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": "<f8", "fortran_order": False, "shape": (10**15,)})
    Path("U.npy").write_bytes(header.getvalue() + bytes(64))
    assert main(["simulate", "driven_spring.py", "--steps", "2", "--inputs", "U.npy"]) == 1
    err = capsys.readouterr().err
    assert "claims 8,000,000,000,000,000 bytes" in err and "internal error" not in err, err


@pytest.mark.usefixtures("shared_kernels")  # the examples' systems, built once
def test_errors_about_the_initial_state_and_the_inputs_name_their_option(capsys):
    """The library's refusals of a state or an input read from a file named only the
    system ("driven_spring: unknown state part 'x'", "input u of step 0 is nan"): on the
    command line they name the option first; a parameter's error is not blamed on it."""
    shutil.copy(REPO / "examples" / "cli" / "driven_spring.py", "driven_spring.py")
    np.save("U.npy", np.array([[0.1], [np.nan], [0.2]]))
    run = ["simulate", "driven_spring.py", "--steps", "3", "--backend", "numpy"]
    assert main([*run, "--inputs", "U.npy"]) == 1
    err = capsys.readouterr().err
    assert "--inputs U.npy: input u in row 1 (the step 1) is nan" in err, err
    np.save("U.npy", np.array([[0.1]]))
    assert main([*run, "--inputs", "U.npy", "--initial", '{"x": [1]}']) == 1
    err = capsys.readouterr().err
    assert "--initial: driven_spring: unknown state part 'x'" in err, err
    assert main([*run, "--inputs", "U.npy", "--initial", '{"q": [0, 0.1], "u": [0]}',
                 "--params", "h=-1"]) == 1
    err = capsys.readouterr().err
    assert "parameter h is declared positive" in err and "--initial" not in err, err


@pytest.mark.parametrize("argv", [["simulate", str(SPRING), "--steps", "5", "--param", "h=0.1"],
                                  ["derive", str(SPRING), "--doc", "x.tex"]])
def test_abbreviated_options_are_refused(argv, capsys):
    """(``--param h=0.1`` was taken for ``--params``, ``--doc`` for ``--document``: an
    abbreviation that a later option would make ambiguous.)  A malformed command line is
    status 2."""
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    assert "unrecognized arguments" in capsys.readouterr().err


def test_generate_into_a_file_says_it_is_not_a_directory(tmp_path, capsys):
    """(It said "cannot write afile/plate_ball.h: File exists".)"""
    (tmp_path / "afile").write_text("mine")
    assert main(["generate", str(tmp_path / "afile" / "out")]) == 1
    err = capsys.readouterr().err
    assert f"{tmp_path / 'afile'} is not a directory" in err
    assert (tmp_path / "afile").read_text() == "mine"
