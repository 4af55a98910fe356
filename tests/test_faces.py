"""The packages reach each other through their faces (docs/architecture.md): no module imports
another package's private module, and imports run down the layers except the documented
conveniences that look up."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import symgroupoid

PACKAGE = Path(symgroupoid.__file__).parent
#: the layers of docs/architecture.md; the top-level modules (plotting, diagnostics, ...) are 6
LAYERS = {"ir": 0, "groupoids": 1, "derivation": 2, "equations": 3, "codegen": 4, "runtime": 5,
          "cli": 6}
#: shared leaves every layer may use (errors, argument checks, symbols, ...)
LEAVES = {"_arguments", "_collector", "_errors", "_lambdify", "_parameters", "_progress",
          "_rational", "_sizes", "_symbols", "_version", "stepper"}
#: the conveniences that look up (docs/architecture.md): importer → the package it calls
CONVENIENCES = {("equations._step", "codegen"), ("equations._step", "runtime"),
                ("runtime._trajectory", "plotting")}


def _module_imports():
    """(importer, imported module) for every import in the package, relative to it."""
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE).with_suffix("").parts)
        is_face = parts[-1] == "__init__"
        if is_face:
            parts = parts[:-1]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.level:
                base = parts if is_face else parts[:-1]
                base = base[:len(base) - (node.level - 1)]
                target = base + (node.module.split(".") if node.module else [])
                names = [target + [a.name] for a in node.names]
                yield ".".join(parts) or "symgroupoid", [target, *names] if target else names
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.startswith("symgroupoid."):
                        yield ".".join(parts) or "symgroupoid", [alias.name.split(".")[1:]]


def _package(parts) -> str:
    return parts[0] if parts else ""


def test_no_module_imports_another_package_s_private_module():
    found = set()
    for importer, targets in _module_imports():
        home = importer.split(".")[0]
        for target in targets:
            private = [p for p in target[1:] if p.startswith("_") and not p.startswith("__")]
            if private and _package(target) != home:
                found.add(f"{importer} imports {'.'.join(target)}")
    assert not found, sorted(found)


def test_imports_run_down_the_layers_but_for_the_documented_conveniences():
    found = set()
    for importer, targets in _module_imports():
        home = importer.split(".")[0]
        below = LAYERS.get(home, 6 if home not in LEAVES else -1)
        for target in targets:
            there = _package(target)
            if there in LEAVES or there == home or not there:
                continue
            if LAYERS.get(there, 6) > below and (importer, there) not in CONVENIENCES:
                found.add(f"{importer} imports {'.'.join(target)}")
    assert not found, sorted(found)


def test_import_symgroupoid_loads_no_optional_or_file_modules():
    """The faces keep the lazy imports: the C toolchain, figures, workers and the trajectory
    files load when first used."""
    code = ("import sys, symgroupoid; print(sorted(m for m in ('cffi', 'matplotlib', 'dask', "
            "'zipfile', 'csv', 'symgroupoid.runtime._files') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"


def test_the_runtime_face_gives_the_trajectory_files_on_first_use(tmp_path):
    from symgroupoid import runtime
    from symgroupoid.runtime import TRAJECTORY_FORMATS, number_text, read_trajectory

    assert TRAJECTORY_FORMATS == (".npz", ".csv")
    assert number_text(0.1) == "0.10000000000000001"
    assert read_trajectory.__module__ == "symgroupoid.runtime._files"
    assert set(runtime.__all__) >= {"read_trajectory", "save_trajectory", "atomic_write"}
    with pytest.raises(AttributeError, match="no attribute 'not_a_name'"):
        runtime.not_a_name  # noqa: B018


# --- the tests reach the package through its faces too -----------------------------------------

TESTS = Path(__file__).resolve().parent


def _private_import_lines(path: Path) -> list[int]:
    """Lines of ``path``'s imports of the package that reach inside: a module path with a
    part starting with ``_``, or a ``_name`` taken from a public module."""
    lines = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("symgroupoid"):
            parts = node.module.split(".")[1:]
            names = [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            parts = [p for a in node.names if a.name.startswith("symgroupoid.")
                     for p in a.name.split(".")[1:]]
            names = []
        else:
            continue
        if any(p.startswith("_") and not p.startswith("__") for p in [*parts, *names]):
            lines.append(node.lineno)
    return lines


def test_at_most_one_test_file_in_ten_reaches_inside_and_says_why():
    """White-box tests of one unit live in one file for that unit, which says at its first
    private import, in a comment just above it, why it reaches inside; every other test file
    uses the names of the faces."""
    files = sorted(TESTS.glob("test_*.py"))
    inside = {path.name: lines for path in files if (lines := _private_import_lines(path))}
    assert 10 * len(inside) <= len(files), sorted(inside)
    for name, lines in inside.items():
        source = (TESTS / name).read_text(encoding="utf-8").splitlines()
        assert source[min(lines) - 2].lstrip().startswith("#"), (
            f"tests/{name}:{min(lines)}: say why the test reaches inside, in a comment above "
            "its first private import")
