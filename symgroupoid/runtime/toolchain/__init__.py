"""The toolchain: kernels built into shared libraries (the C compiler, cffi) and the on-disk
kernel cache that keeps them.

Building: :mod:`._compiler` (which compiler, its command lines and environment),
:mod:`._flags` (optimisation levels and translation units), :mod:`._cffi_build` (one
build), :mod:`._type_table` and :mod:`._library` (loading), :mod:`._openmp`,
:mod:`._step_kernel` (a step's C and its cache keys), :mod:`._kernels` (built into the cache
and loaded from it).  The cache: :mod:`._roots`, :mod:`._trust`, :mod:`._atomic`,
:mod:`._locks`, :mod:`._writable`, :mod:`._sweep`, :mod:`._entries`, :mod:`._kernel_cache`,
:mod:`._maintenance` (``symgroupoid cache info|clear``).

A kernel is plain C99 without Python headers: it is compiled and linked by one run of the C
compiler into ``<module>.so`` and loaded with ``ffi.dlopen``.  Its cffi type table (the
declarations of ``cdef.j2``, parsed once when the kernel is built) is kept as data: the
literal arguments of cffi's out-of-line ABI constructor ``_cffi_backend.FFI`` (bytes,
integers and tuples of them, ``_type_table.type_table``), checked and passed to it on load
(:func:`ffi_of`), so loading a built kernel parses no C and runs no code from the cache.
A library is checked before it is installed or loaded (:func:`library_defect`: a complete
ELF shared object whose segments and sections lie inside the file), so a truncated one is
never mapped (which would end the process with SIGBUS).
Compared with a Python extension (API mode), a build needs no Python headers, no setuptools
and no wrapper translation unit (about 0.5 s less at small kernels); a call costs about 1 µs
more, which no entry point notices (each call does at least a Newton step).

Layout under the cache root (``$SYMGROUPOID_CACHE``, else ``$XDG_CACHE_HOME/symgroupoid``,
else ``~/.cache/symgroupoid``)::

    index/<input key>.json     symbolic inputs → source key (lets a warm load skip codegen)
    kernels/<source key>/      one built kernel: the shared library, its C source and
                               manifest.json with the SHA-256 of the library file and the
                               library's cffi type table (data, with its own SHA-256)
    locks/<source key>.lock    held (``flock``) by the one process building that kernel
    locks/<source key>.lease   the same where the file system has no ``flock`` (``O_EXCL``)
    tmp/                       build directories ``build-<source key>-<pid>-<host>-*``,
                               renamed into kernels/ when complete
    probes/                    the compiler's OpenMP support, once per compiler

The *source key* hashes the generated C, the compiler flags, the build environment
(``$CC``, ``$CPPFLAGS``, ``$CFLAGS``, ``$LDFLAGS``) and the Python/cffi ABI; the *input key*
hashes the symbolic step (SymPy ``srepr``), the code generator and the same ABI, flags and
environment.  A kernel directory appears atomically (``rename`` of a finished directory)
and is verified against its manifest before loading; a damaged one is removed and rebuilt.

What is trusted (the cache holds code this process runs, so it is checked as ssh checks
its keys):

* The root, and each of its directories (``index``, ``kernels``, ``locks``, ``tmp``,
  ``probes``), must belong to this user (or to root) and must not be writable by group or
  others; its directories must not be symbolic links (the root itself may be reached
  through one).  Otherwise the cache is refused with a :class:`CacheError` naming the path,
  the reason and the fix.  Files and directories the cache makes get the umask's mode less
  group and other write permission.
* A kernel directory, its manifest and its library must be of the same owners, not
  writable by others, and no links; the library must be a complete ELF shared object
  (:func:`library_defect`).  Anything else is a bad entry: never loaded, rebuilt.
* No cache file holds Python: the manifest is JSON, the type table plain data (bytes and
  integers) that cffi's ``FFI`` constructor takes; the index and probes hold names and
  booleans.  The kernel templates' compiled code is kept with the package, not here.
* ``SYMGROUPOID_SHARED_CACHE`` names a read-only cache another account provides (a kernel
  cache that account built): it is read after this user's own cache, never written, swept
  or cleared; it is trusted when it and everything read from it belongs to the owner of its
  root (or to root) and nobody else can write it.

Concurrency and failures:

* Processes that miss the same kernel serialise on its lock: one compiles, the others wait
  (up to ``SYMGROUPOID_LOCK_TIMEOUT`` seconds, default 600), re-check the manifest and load.
  The kernel releases an ``flock`` when its holder dies, so a killed builder blocks nobody.
* Where ``flock`` fails (NFS mounted ``nolock``: ENOLCK; Lustre ``noflock``: ENOSYS;
  EOPNOTSUPP), the lock is a lease file created with ``O_EXCL`` holding the builder's pid
  and host: others wait while that process lives (on another host: up to the timeout),
  then build too.  No lock is needed for correctness: every process builds in its own
  directory and publishes it with one ``rename``, keeping an entry another process
  published first.
* A build directory is named after its key, process and host.  It is removed on a later
  use of the cache only when its builder is certainly gone: its key's ``flock`` is free, or
  (without ``flock``) its process no longer runs on this host, or it is older than an hour.
* Only names the cache makes are ever removed (32-hex keys, ``build-``/``trash-``/
  ``probe-`` leftovers, its temporary files), and only after an ``lstat``: a link is
  removed as a link, never followed.
* The root is marked as a kernel cache (``CACHEDIR.TAG``) when it is created, or when
  found empty or holding only a cache layout (the directories above with hash-named
  entries: a cache written before roots were marked); a directory holding anything else
  is never written into, swept or cleared (it is treated as unwritable, below), so a cache
  variable pointed at ``$HOME`` or a project cannot delete a file.
* ``index``, ``kernels``, ``locks`` or ``tmp`` found as a file is removed and recreated (in
  a root marked just now: moved aside as ``<name>.displaced-*``).
  A cache root that cannot be written (read-only, not a directory, ``$HOME`` unwritable)
  is still read, and kernels built by this process go to a private temporary directory
  (one :class:`RuntimeWarning` naming the path and the reason; removed at exit).
* A write that fails (a full disk) is a :class:`CacheError` naming the cache directory.
"""

from ._atomic import read_json, remove_tree, write_json_atomic
from ._cffi_build import build_extension, module_name
from ._compiler import (
    NUMPY_HINT,
    CompilationError,
    CompilerNotFoundError,
    build_command,
    build_environment,
    compiler_command,
    find_compiler,
)
from ._digests import abi_tag, file_sha256, sha256_of, table_sha256
from ._entries import entry_defect
from ._flags import (
    BLOCK_LEVEL,
    COLD_LEVEL,
    DEFAULT_FLAGS,
    LARGE_PROGRAM,
    SMALL_STEP,
    block_weight,
    optimisation_flags,
    translation_units,
    unit_flags,
)
from ._isa import (
    VECTOR_ISA_ENV,
    VECTOR_ISAS,
    VectorISAError,
    missing_instructions,
    processor_features,
    vector_flags,
)
from ._kernel_cache import KernelCache
from ._kernels import (
    STATS,
    build_cached,
    build_step,
    kernel_source_of,
    load_cached,
    load_step,
    rebuild_step,
)
from ._library import library_defect, load_extension
from ._locks import exclusive, key_busy
from ._maintenance import CachedKernel, CacheInfo, ClearedCache, cache_info, clear_cache
from ._openmp import OPENMP_FLAG, default_flags, openmp_available, start_openmp_probe
from ._roots import INTERNAL, MANIFEST, absolute_root, cache_root, shared_root
from ._step_kernel import (
    codegen_digest,
    codegen_sources,
    fingerprint,
    input_key,
    source_key_of,
    step_flags,
    step_kernel,
    step_operations,
)
from ._sweep import GRACE, sweep
from ._trust import trusted
from ._type_table import TYPE_TABLE_KEYWORDS, ffi_of
from ._writable import prepared, writable_root

__all__ = [
    "BLOCK_LEVEL", "COLD_LEVEL", "DEFAULT_FLAGS", "GRACE", "INTERNAL", "LARGE_PROGRAM",
    "MANIFEST", "NUMPY_HINT", "OPENMP_FLAG", "SMALL_STEP", "STATS", "TYPE_TABLE_KEYWORDS",
    "CacheInfo", "CachedKernel", "ClearedCache", "CompilationError", "CompilerNotFoundError",
    "KernelCache", "VECTOR_ISAS", "VECTOR_ISA_ENV", "VectorISAError", "abi_tag",
    "absolute_root", "block_weight", "build_cached",
    "build_command", "build_environment", "build_extension", "build_step", "cache_info",
    "cache_root", "clear_cache", "codegen_digest", "codegen_sources", "compiler_command",
    "default_flags", "entry_defect", "exclusive", "ffi_of", "file_sha256", "find_compiler",
    "fingerprint", "input_key", "kernel_source_of", "key_busy", "library_defect",
    "load_cached", "load_extension", "load_step", "missing_instructions", "module_name",
    "openmp_available", "rebuild_step",
    "optimisation_flags", "prepared", "processor_features", "read_json", "remove_tree",
    "sha256_of", "shared_root",
    "source_key_of", "start_openmp_probe", "step_flags", "step_kernel", "step_operations",
    "sweep", "table_sha256", "translation_units", "trusted", "unit_flags", "vector_flags",
    "writable_root",
    "write_json_atomic",
]
