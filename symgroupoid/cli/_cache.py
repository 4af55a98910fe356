"""``cache info`` and ``cache clear``: the kernel cache of this user (``SYMGROUPOID_CACHE``);
``cache templates``: the kernel templates compiled once, beside them."""

from __future__ import annotations

import argparse
import time
from collections import defaultdict

from .._errors import CacheError
from ..codegen import precompile_templates
from ..runtime.toolchain import cache_info, clear_cache
from ._common import say


def size_text(n: int) -> str:
    for unit in ("bytes", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} GiB"  # pragma: no cover


def shown_path(path) -> str:
    """A path as printed on one line: as it is, or quoted with escapes when it holds a
    character that is not printable (a newline would split the line)."""
    text = str(path)
    return text if text.isprintable() else repr(text)


def run_info(args: argparse.Namespace) -> int:
    info = cache_info()
    say(f"kernel cache: {shown_path(info.root)}")
    if not info.exists:
        say("  (empty: not created yet)")
        return 0
    if info.refused is not None:
        say(f"  NOT USED: {info.refused}")
        return 1
    say(f"  {len(info.kernels)} kernels, {size_text(info.size)}; {info.index_entries} index "
        f"entries; {info.leftovers} items in tmp/")
    by_system: dict[str, list] = defaultdict(list)
    for kernel in info.kernels:
        by_system[kernel.system].append(kernel)
    if by_system:
        width = max(len("system"), *map(len, by_system))
        say(f"  {'system':<{width}}  kernels  size        newest")
        for system in sorted(by_system):
            kernels = by_system[system]
            newest = time.strftime("%Y-%m-%d %H:%M",
                                   time.localtime(max(k.modified for k in kernels)))
            size = size_text(sum(k.size for k in kernels))
            say(f"  {system:<{width}}  {len(kernels):>7}  {size:<10}  {newest}")
    if info.bad:
        say(f"  {len(info.bad)} bad (never loaded, rebuilt on use; 'symgroupoid cache clear "
            f"--bad' removes them):")
        for kernel in info.bad:
            say(f"    {kernel.key} ({kernel.system}): {kernel.problem}")
    if info.bad_locks:
        say(f"  {len(info.bad_locks)} lock files that are links or not files (a build of "
            f"their kernel stops with a CacheError; 'symgroupoid cache clear' removes them): "
            f"{', '.join(info.bad_locks)}")
    return 0


def run_clear(args: argparse.Namespace) -> int:
    bad = bool(getattr(args, "bad", False))
    result = clear_cache(bad_only=bad)
    say(f"kernel cache: {shown_path(result.root)}")
    say(f"  removed {result.removed} {'bad ' if bad else ''}kernels "
        f"({size_text(result.freed)}) and {result.index_entries} index entries")
    if result.bad_locks:
        say(f"  removed {result.bad_locks} lock files that were links or not files")
    if result.busy:
        say(f"  left {len(result.busy)} being built by another process: "
            f"{', '.join(result.busy)}")
    if result.failed:
        shown = ", ".join(result.failed[:3]) + (", …" if len(result.failed) > 3 else "")
        raise CacheError(f"{result.root}: could not remove {len(result.failed)} entries "
                         f"({shown}): the cache, or these files, cannot be changed by this "
                         f"user (permissions, a read-only file system, immutable files)")
    return 0


def run_templates(args: argparse.Namespace) -> int:
    directory, kept = precompile_templates()
    say(f"kernel templates compiled: {kept} in {directory}")
    return 0
