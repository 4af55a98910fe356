"""System files: a Python file defining a discrete system, named as ``FILE.py[:NAME]``.

The file is imported as a module from its path (its directory first on ``sys.path`` while it
is imported, so it can import its neighbours; ``if __name__ == "__main__":`` blocks do not
run).  The system is

- with ``:NAME``: the attribute NAME — a :class:`~symgroupoid.DiscreteSystem`,
  :class:`~symgroupoid.SecondOrderSystem` or :class:`~symgroupoid.NonholonomicSystem`, or a
  function called without arguments that returns one;
- without: the one system object the module defines at top level; if it defines none, the
  one function annotated to return a system (``def pendulum() -> sg.DiscreteSystem:``).
  Anything else — none, or several — is an error listing what the file offers.

Optional top-level names give the commands their defaults (options on the command line
take precedence):

- ``PARAMS``: parameter values by name, ``{"h": 0.01, "k": 1.0}``;
- ``INITIAL``: an initial state, in any of the forms ``--initial`` reads (docs/cli.md);
- ``NOETHER``: the Noether quantities ``verify`` checks — a list whose entries are a
  section (a basis index, a list of coefficients, or a function of the base point
  returning them) or a dict ``{"name": ..., "section": ..., "f": ...}`` (``f``: the
  quasi-invariance function of seed 000 Def. 4.8, default 0);
- ``ABBREVIATIONS``: names ``derive`` prints for parts of the equations, as
  ``StepEquations.latex(abbreviations=...)`` takes them (docs/latex.md).
"""

from __future__ import annotations

import hashlib
import importlib.util
import inspect
import sys
import typing
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

from .._errors import SymgroupoidError
from ..equations import DiscreteSystem, NonholonomicSystem
from ._errors import SystemFileError

SYSTEM_TYPES = (DiscreteSystem, NonholonomicSystem)
_SYSTEM_TYPE_NAMES = ("DiscreteSystem", "SecondOrderSystem", "NonholonomicSystem",
                      "ReducedSystem")
WHAT = "a DiscreteSystem, SecondOrderSystem or NonholonomicSystem"


@dataclass
class SystemFile:
    """The imported file, the name of the system chosen and the system."""

    path: Path
    module: ModuleType
    name: str
    system: object

    def convention(self, key: str, default=None):
        """A top-level default of the file (``PARAMS``, ``INITIAL``, ``NOETHER``,
        ``ABBREVIATIONS``)."""
        return getattr(self.module, key, default)

    @property
    def label(self) -> str:
        return f"{self.path.name}:{self.name}"


def split_target(text: str) -> tuple[Path, str | None]:
    """``FILE.py:NAME`` → (FILE.py, NAME); ``FILE.py`` → (FILE.py, None)."""
    head, sep, tail = text.rpartition(":")
    if sep and head and tail.isidentifier():
        return Path(head), tail
    return Path(text), None


def _module_name(path: Path) -> str:
    digest = hashlib.sha256(str(path).encode()).hexdigest()[:12]
    stem = "".join(c if c.isalnum() else "_" for c in path.stem)
    return f"_symgroupoid_system_{stem}_{digest}"


def _user_failure(path: Path, doing: str, exc: BaseException) -> SystemFileError:
    text = str(exc).strip().splitlines()
    detail = f": {text[0]}" if text else ""
    return SystemFileError(f"{path}: {doing} raised {type(exc).__name__}{detail} "
                           f"(--debug shows the traceback)")


def import_file(path: Path) -> ModuleType:
    """Import the Python file at ``path`` as a fresh module."""
    path = path.expanduser()
    if not path.exists():
        raise SystemFileError(f"{path}: no such file")
    if not path.is_file():
        raise SystemFileError(f"{path}: not a file")
    path = path.resolve()
    name = _module_name(path)
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise SystemFileError(f"{path}: cannot be imported as Python (name it FILE.py)")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    folder = str(path.parent)
    sys.path.insert(0, folder)
    try:
        spec.loader.exec_module(module)
    except SymgroupoidError:
        sys.modules.pop(name, None)
        raise
    except SystemExit as exc:
        sys.modules.pop(name, None)
        raise SystemFileError(f"{path}: importing it called exit({exc.code!r})") from exc
    except Exception as exc:
        sys.modules.pop(name, None)
        raise _user_failure(path, "importing it", exc) from exc
    finally:
        try:
            sys.path.remove(folder)
        except ValueError:
            pass
    return module


def _returns_system(function) -> bool:
    """Whether ``function`` is annotated to return a system."""
    try:
        hint = typing.get_type_hints(function).get("return")
    except Exception:  # an annotation that does not resolve: read its text
        hint = None
        text = function.__annotations__.get("return")
        if isinstance(text, str):
            return text.rsplit(".", 1)[-1].strip() in _SYSTEM_TYPE_NAMES
    return isinstance(hint, type) and issubclass(hint, SYSTEM_TYPES)


def _takes_no_arguments(function) -> bool:
    try:
        signature = inspect.signature(function)
    except (TypeError, ValueError):
        return False
    return all(p.default is not p.empty or p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
               for p in signature.parameters.values())


def _public(module: ModuleType) -> list[tuple[str, object]]:
    return [(k, v) for k, v in vars(module).items() if not k.startswith("_")]


def _zero_argument_functions(module: ModuleType) -> list[tuple[str, object]]:
    return [(k, v) for k, v in _public(module)
            if inspect.isfunction(v) and v.__module__ == module.__name__
            and _takes_no_arguments(v)]


def _offer(module: ModuleType) -> str:
    """What the module offers, for messages."""
    systems = [k for k, v in _public(module) if isinstance(v, SYSTEM_TYPES)]
    functions = [k for k, _ in _zero_argument_functions(module)]
    parts = []
    if systems:
        parts.append(f"systems: {', '.join(systems)}")
    if functions:
        parts.append(f"functions without arguments: {', '.join(functions)}")
    imported = [k for k, v in _public(module) if inspect.isfunction(v)
                and v.__module__ != module.__name__ and _takes_no_arguments(v)
                and _returns_system(v)]
    if imported:  # not offered by themselves (the library's own functions are imported too)
        parts.append(f"imported from other modules: {', '.join(imported)} (name one: "
                     f"FILE.py:{imported[0]})")
    return "; ".join(parts) if parts else "no systems and no functions without arguments"


def _call(path: Path, name: str, function) -> object:
    if not _takes_no_arguments(function):
        raise SystemFileError(f"{path}: {name} needs arguments; name a system or a function "
                              f"without arguments that returns one")
    try:
        system = function()
    except SymgroupoidError:
        raise
    except Exception as exc:
        raise _user_failure(path, f"calling {name}()", exc) from exc
    if not isinstance(system, SYSTEM_TYPES):
        raise SystemFileError(f"{path}: {name}() returned {type(system).__name__}, not {WHAT}")
    return system


def _named(path: Path, module: ModuleType, name: str) -> object:
    if not hasattr(module, name):
        raise SystemFileError(f"{path} defines no {name!r} ({_offer(module)})")
    value = getattr(module, name)
    if isinstance(value, SYSTEM_TYPES):
        return value
    if callable(value):
        return _call(path, name, value)
    raise SystemFileError(f"{path}: {name} is a {type(value).__name__}, not {WHAT} or a "
                          f"function returning one")


def _unique(path: Path, module: ModuleType) -> tuple[str, object]:
    seen: dict[int, str] = {}
    for key, value in _public(module):
        if isinstance(value, SYSTEM_TYPES):
            seen.setdefault(id(value), key)
    if len(seen) == 1:
        name = next(iter(seen.values()))
        return name, getattr(module, name)
    if len(seen) > 1:
        names = ", ".join(f"{path.name}:{k}" for k in seen.values())
        raise SystemFileError(f"{path} defines several systems; choose one: {names}")
    factories = [k for k, v in _zero_argument_functions(module) if _returns_system(v)]
    if len(factories) == 1:
        return factories[0], _call(path, factories[0], getattr(module, factories[0]))
    if len(factories) > 1:
        names = ", ".join(f"{path.name}:{k}" for k in factories)
        raise SystemFileError(f"{path} defines several functions returning a system; "
                              f"choose one: {names}")
    raise SystemFileError(
        f"{path} defines no system: expected {WHAT} at top level, or a function annotated "
        f"to return one; or name it as {path.name}:NAME ({_offer(module)})")


def load_system(target: str) -> SystemFile:
    """Import ``FILE.py[:NAME]`` and pick its system (see the module docstring)."""
    path, name = split_target(target)
    module = import_file(path)
    if name is None:
        name, system = _unique(path, module)
    else:
        system = _named(path, module, name)
    return SystemFile(Path(module.__file__ or path), module, name, system)
