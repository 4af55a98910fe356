"""The memory a batch or a sweep holds, checked up front.

The states a batch keeps are allocated at once: :func:`check_memory` compares what they
need (:func:`run_bytes` per run) with :func:`available_memory` and raises a
:class:`~symgroupoid.TrajectoryTooLargeError` naming the sizes before any run starts (and
:func:`too_large` turns a failed allocation into the same error, never a raw
``MemoryError``).  A sweep with ``reduce`` holds its runs in parts of at most
:data:`BATCH_BYTES` of kept states (:func:`memory_plan`), so its memory grows with what is
kept, not with the trajectories.
"""

from __future__ import annotations

import os

from ._runs import batch_rows

#: kept states a part of a sweep's task holds at once with ``reduce`` (bytes; at least one run)
BATCH_BYTES = 1 << 24


def available_memory() -> int | None:
    """Bytes this process may still allocate at most: the machine's physical memory,
    lowered by what the address-space and data-segment limits (``ulimit -v``,
    ``ulimit -d``) leave beyond what is mapped already; None when unknown."""
    try:
        limit = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        limit = None
    try:
        import resource
    except ImportError:  # pragma: no cover - not POSIX
        return limit
    mapped = _mapped_bytes()
    for which, used in (("RLIMIT_AS", mapped[0]), ("RLIMIT_DATA", mapped[1])):
        soft = resource.getrlimit(getattr(resource, which))[0]
        if soft not in (resource.RLIM_INFINITY, -1) and soft > 0:
            room = max(soft - used, 0)
            limit = room if limit is None else min(limit, room)
    return limit if limit is None or limit > 0 else 0


def _mapped_bytes() -> tuple[int, int]:
    """(address space, data segment) this process has mapped, from /proc/self/statm
    (zeros where it cannot be read)."""
    try:
        with open("/proc/self/statm") as f:
            fields = f.read().split()
        page = os.sysconf("SC_PAGE_SIZE")
        return int(fields[0]) * page, int(fields[5]) * page
    except (OSError, ValueError, IndexError):
        return 0, 0


def run_bytes(sim, rows: int) -> int:
    """Bytes a run of a batch holds with ``rows`` kept states (states, Newton summaries and
    its share of the per-run arrays)."""
    return rows * (8 * sim.layout.n_known + 16) + 8 * (len(sim.equations.unknowns) + 6)


#: what to do when the kept states do not fit
KEEP_FEWER = "keep fewer with every=k, or reduce each run on the fly with sweep(..., reduce=...)"


def too_large(sim, runs: int, rows: int, steps: int, every: int, limit: int | None,
              held: str = "", failed: Exception | None = None,
               advice: str = KEEP_FEWER) -> Exception:
    from .._errors import TrajectoryTooLargeError

    needed = runs * run_bytes(sim, rows)
    if failed is not None:
        room = f"which could not be allocated ({type(failed).__name__}: {failed})"
    elif limit is not None:
        room = f"more than this process may allocate ({limit / 2**30:.1f} GiB)"
    else:
        room = "more than this process could allocate"
    return TrajectoryTooLargeError(
        f"{sim.name}: keeping {rows} states (steps={steps}, every={every}) of each of "
        f"{runs} runs{held} needs {needed / 2**30:.1f} GiB, {room}; {advice}")


def check_memory(sim, runs: int, rows: int, steps: int, every: int, held: str = "",
                 advice: str = KEEP_FEWER) -> None:
    """A :class:`TrajectoryTooLargeError` up front when ``runs`` runs of ``rows`` kept
    states would not fit in :func:`available_memory`."""
    limit = available_memory()
    if limit is not None and runs * run_bytes(sim, rows) > limit:
        raise too_large(sim, runs, rows, steps, every, limit, held, advice=advice)


def memory_plan(sim, steps: int, every: int, reduced: bool, total: int, mode: str,
                workers: int) -> int:
    """Runs per part of a task (held at once by a worker), after checking that what the
    sweep holds at once fits in memory (a :class:`TrajectoryTooLargeError` up front).

    Without ``reduce`` every trajectory comes back: all of them must fit.  With it, a part
    holds at most :data:`BATCH_BYTES` of kept states (at least one run); threads hold
    ``2·workers + 1`` parts at once (being simulated, waiting, being reduced), each worker
    process one."""
    rows = batch_rows(steps, every)
    if not reduced:
        check_memory(sim, total, rows, steps, every)
        return 1 << 62
    part = max(1, min(total, BATCH_BYTES // run_bytes(sim, rows)))
    held = {"thread": 2 * workers + 1, "process": workers}.get(mode, 1)
    runs = min(total, held * part)
    advice = ("reduce receives each run's whole trajectory: keep fewer states with every=k "
              "(or process a run this long on the fly with Simulator.stream)")
    if runs > part:
        advice += f", or use fewer workers (each holds a part of {part} run(s) at a time)"
    check_memory(sim, runs, rows, steps, every, held=" held at once", advice=advice)
    return part
