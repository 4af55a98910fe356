"""A kernel's cffi type table, kept as data: made from cffi's out-of-line ABI module (read,
never run), checked, and passed to ``_cffi_backend.FFI`` on load."""

from __future__ import annotations

import ast
import base64
from pathlib import Path

from ...codegen import KernelSource
from ._compiler import CompilationError


def ffi_module_source(kernel: KernelSource, name: str, directory: Path) -> str:
    """The source of cffi's out-of-line ABI module of ``kernel``'s declarations (``cdef``):
    Python that builds the ``ffi`` object (types, functions, constants) without parsing C.
    Only read, by :func:`type_table`; never run.

    Written through a scratch file in ``directory``, removed again.  A malformed ``cdef``
    raises :class:`CompilationError`.
    """
    import cffi
    from cffi.recompiler import make_py_source

    ffi = cffi.FFI()
    try:
        ffi.cdef(kernel.cdef)
    except cffi.CDefError as exc:
        raise CompilationError(f"{kernel.prefix}: the kernel's cffi declarations do not "
                               f"parse ({exc})", output=str(exc)) from exc
    path = directory / f"{name}.py"
    try:
        make_py_source(ffi, name, str(path))
        return path.read_text(encoding="ascii")
    finally:
        path.unlink(missing_ok=True)


#: the keyword arguments of ``_cffi_backend.FFI`` a kernel's type table may hold (cffi's
#: out-of-line ABI module; never ``_includes``, which would name other modules)
TYPE_TABLE_KEYWORDS = frozenset({"_version", "_types", "_globals", "_struct_unions",
                                 "_enums", "_typenames"})


#: how deeply the values of a type table nest (cffi's: a tuple of tuples of fields)
_TABLE_DEPTH = 4


def type_table(kernel: KernelSource, name: str, directory: Path) -> dict:
    """The cffi type table of ``kernel`` as JSON data: ``{"name": name, "<keyword>":
    value, ...}``, the literal arguments of the ``_cffi_backend.FFI(...)`` call of its
    out-of-line ABI module (:func:`ffi_module_source`), read with :func:`ast.literal_eval`
    (which evaluates literals only), bytes as ``{"b64": ...}``, tuples as lists."""
    source = ffi_module_source(kernel, name, directory)
    try:
        call = _ffi_call(ast.parse(source))
        arguments = {kw.arg: ast.literal_eval(kw.value) for kw in call.keywords}
        module = ast.literal_eval(call.args[0])
        if len(call.args) != 1 or module != name or set(arguments) - TYPE_TABLE_KEYWORDS:
            raise ValueError("unexpected arguments")
        table = {"name": module, **{k: _encoded(v, 0) for k, v in sorted(arguments.items())}}
        checked_table(table, name)
    except (SyntaxError, ValueError, TypeError, IndexError) as exc:
        raise CompilationError(f"{kernel.prefix}: cffi's type table of the kernel is not in "
                               f"the form this version reads ({exc}); cffi "
                               f"{_cffi_version()} may be too new", output=source) from exc
    return table


def _cffi_version() -> str:
    import cffi

    return cffi.__version__


def _ffi_call(tree: ast.Module) -> ast.Call:
    """The ``ffi = _cffi_backend.FFI(...)`` call of an out-of-line ABI module."""
    for node in tree.body:
        if (isinstance(node, ast.Assign) and len(node.targets) == 1
                and isinstance(node.targets[0], ast.Name) and node.targets[0].id == "ffi"
                and isinstance(node.value, ast.Call)):
            func = node.value.func
            if (isinstance(func, ast.Attribute) and func.attr == "FFI"
                    and isinstance(func.value, ast.Name) and func.value.id == "_cffi_backend"):
                return node.value
        elif not isinstance(node, ast.Import | ast.Expr):
            break
    raise ValueError("no ffi = _cffi_backend.FFI(...) call")


def _encoded(value, depth: int):
    """A literal of a type table as JSON data (see :func:`type_table`)."""
    if depth > _TABLE_DEPTH:
        raise ValueError("nested too deeply")
    if isinstance(value, bytes):
        return {"b64": base64.b64encode(value).decode("ascii")}
    if isinstance(value, tuple):
        return [_encoded(v, depth + 1) for v in value]
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    raise ValueError(f"a value of type {type(value).__name__}")


def _decoded(value, depth: int):
    """The inverse of :func:`_encoded`, accepting nothing else (``ValueError``)."""
    if depth > _TABLE_DEPTH:
        raise ValueError("nested too deeply")
    if isinstance(value, list):
        return tuple(_decoded(v, depth + 1) for v in value)
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    if isinstance(value, dict) and set(value) == {"b64"} and isinstance(value["b64"], str):
        return base64.b64decode(value["b64"].encode("ascii"), validate=True)
    raise ValueError(f"a value of type {type(value).__name__}")


def checked_table(table, name: str) -> dict:
    """The keyword arguments of ``_cffi_backend.FFI`` in a type table (data only, checked:
    ``ValueError`` for anything else)."""
    if not isinstance(table, dict) or table.get("name") != name:
        raise ValueError(f"not the type table of {name}")
    keywords = {k: _decoded(v, 0) for k, v in table.items() if k != "name"}
    if set(keywords) - TYPE_TABLE_KEYWORDS or "_types" not in keywords:
        raise ValueError(f"unexpected entries {sorted(set(keywords) - TYPE_TABLE_KEYWORDS)}")
    if not isinstance(keywords["_types"], bytes) or not isinstance(keywords.get("_version"), int):
        raise ValueError("_types must be bytes and _version an integer")
    return keywords


def ffi_of(table, name: str):
    """cffi's ``ffi`` object of a type table (:func:`type_table`), made by
    ``_cffi_backend.FFI`` from its checked data; ``ImportError`` when malformed."""
    import _cffi_backend

    try:
        return _cffi_backend.FFI(name, **checked_table(table, name))
    except Exception as exc:  # noqa: BLE001 - anything wrong in the type table
        raise ImportError(f"the cffi type table of {name} does not load: {exc}") from exc
