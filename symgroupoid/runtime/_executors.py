"""Where the tasks of a sweep run: this thread, worker threads, worker processes, Dask.

A sweep is a list of *jobs* (runs grouped into tasks) and a shared *task* object that knows
how to compute a job in two halves: ``task.simulate(job, stop)`` (the kernel's work, which
releases the GIL; ``stop()`` is asked between kernel calls) and ``task.finish(job, raw,
cut)`` (``reduce`` run by run, and the packing of the result).  :func:`run_job` is both halves
on a worker, in parts of at most ``task.batch_runs`` runs so that a worker holds the states of
one part at a time.  Every executor hands the results to ``receive`` as they come, in this
thread, so that what is done is kept whatever happens next.

- ``serial``: this thread.  ``thread``: ``workers`` threads simulate, this thread reduces
  (a reduce that hangs is interrupted by Ctrl-C like any Python code; the workers are told to
  stop and end within a kernel call).  Nothing is pickled; the user's ``__main__`` is never
  imported again.
- ``process``: worker processes started with ``python -c`` (they import symgroupoid and
  take the parent's ``sys.path``, never the user's script: a script needs no
  ``if __name__ == "__main__":`` guard).  A job whose worker dies is split into its runs,
  each run again on a fresh worker; a run that kills its worker again is recorded with
  status :data:`WORKER_DIED`.  A job over its ``timeout`` has its worker killed, its runs
  recorded :data:`TIMED_OUT`.  Ctrl-C kills the workers (and a worker whose parent is gone
  ends itself).
- ``dask``: a ``distributed.Client`` (``_dask.py``): a job that a worker's death implicates
  is split into its runs, which run again one at a time once the other jobs are done: a
  run that kills its worker alone on the cluster is recorded :data:`WORKER_DIED`.

Ctrl-C (``KeyboardInterrupt``) propagates after the workers are stopped; the runs received
until then are in the sweep's partial result.
"""

from __future__ import annotations

import collections
import os
import pickle
import queue
import signal
import subprocess
import sys
import threading
import time
import traceback

from .._errors import SymgroupoidError
from ..stepper import Status

#: the statuses of runs stopped from outside (not kernel statuses): Ctrl-C, a task that
#: exceeded the sweep's ``timeout``, a worker process that died while running it (also alone)
INTERRUPTED, TIMED_OUT, WORKER_DIED = Status.INTERRUPTED, Status.TIMED_OUT, Status.WORKER_DIED
#: how often a waiting executor looks at its workers (seconds)
POLL = 0.1
#: how long Ctrl-C waits for the worker threads to finish their kernel call (seconds)
STOP_WAIT = 1.0


class WorkerProcessError(SymgroupoidError, RuntimeError):
    """A worker process could not start or could not load the sweep's task."""


class ClusterLostError(SymgroupoidError, RuntimeError):
    """A sweep's Dask cluster lost its workers to deaths and did not get them back; the
    exception's ``result`` is the partial :class:`SweepResult` of the runs done."""


def run_job(task, job, stop=None):
    """A job on a worker: simulated and finished part by part (at most ``task.batch_runs``
    runs each), so that the states of one part are held at a time."""
    return task.merge([task.finish(part, task.simulate(part, stop))
                       for part in job.parts(task.batch_runs)])


def execute(mode: str, task, jobs: list, receive, *, workers: int, timeout: float | None,
            client=None) -> None:
    """Run ``jobs`` on the executor ``mode``; each result goes to ``receive``."""
    if mode == "dask":
        from ._dask import run_dask

        run_dask(task, jobs, receive, client)
    elif mode == "process":
        _ProcessPool(task, workers, timeout).run(jobs, receive)
    elif mode == "thread" and workers > 1 and len(jobs) > 1:
        _run_threads(task, jobs, receive, workers, timeout)
    else:
        _run_serial(task, jobs, receive, timeout)


def _deadline_stop(timeout: float | None, cancel: threading.Event | None = None):
    """A ``stop()`` for one job: true once ``cancel`` is set or ``timeout`` seconds
    passed; its ``timed_out`` attribute tells which."""
    deadline = None if timeout is None else time.monotonic() + timeout

    def stop() -> bool:
        if cancel is not None and cancel.is_set():
            return True
        if deadline is not None and time.monotonic() > deadline:
            stop.timed_out = True
            return True
        return False

    stop.timed_out = False
    return stop


def _run_serial(task, jobs: list, receive, timeout: float | None) -> None:
    for job in jobs:
        for part in job.parts(task.batch_runs):
            stop = _deadline_stop(timeout)
            # (the part's states are an argument only: freed once finished)
            receive(task.finish(part, task.simulate(part, stop),
                                TIMED_OUT if stop.timed_out else None))


# --- threads ----------------------------------------------------------------------------------

def _run_threads(task, jobs: list, receive, workers: int, timeout: float | None) -> None:
    """``workers`` threads simulate the jobs; this thread finishes (reduces) them as they
    come, at most ``workers`` simulated jobs waiting (so memory stays bounded)."""
    todo = collections.deque(jobs)
    lock = threading.Lock()
    cancel = threading.Event()
    done: queue.Queue = queue.Queue(maxsize=workers)

    def hand_over(item) -> None:
        while not cancel.is_set():
            try:
                done.put(item, timeout=POLL)
                return
            except queue.Full:
                continue

    def worker() -> None:
        while not cancel.is_set():
            with lock:
                if not todo:
                    return
                job = todo.popleft()
            stop = _deadline_stop(timeout, cancel)
            try:
                raw = task.simulate(job, stop)
            except BaseException as exc:  # noqa: BLE001 - raised again on the calling thread
                hand_over(("error", job, exc, None))
                return
            hand_over(("done", job, raw, stop.timed_out))
            del raw  # (not held while the next job is simulated)

    threads = [threading.Thread(target=worker, daemon=True, name=f"symgroupoid-sweep-{i}")
               for i in range(min(workers, len(jobs)))]
    for thread in threads:
        thread.start()
    try:
        for _ in range(len(jobs)):
            kind, job, payload, timed_out = _next_item(done, threads)
            if kind == "error":
                raise payload
            result = task.finish(job, payload, TIMED_OUT if timed_out else None)
            del payload  # (the states, once reduced)
            receive(result)
    finally:
        cancel.set()
        limit = time.monotonic() + STOP_WAIT
        for thread in threads:  # each ends within a kernel call
            thread.join(max(0.0, limit - time.monotonic()))


def _next_item(done: queue.Queue, threads: list):
    while True:
        try:
            return done.get(timeout=POLL)
        except queue.Empty:
            if not any(t.is_alive() for t in threads) and done.empty():
                raise RuntimeError("internal error: the sweep's worker threads ended "
                                   "without a result") from None


# --- worker processes -------------------------------------------------------------------------

#: a worker process's program: no user code until the task arrives; SIGINT ignored (the
#: parent decides, and a terminal's Ctrl-C reaches the whole process group)
BOOT = """\
import pickle, signal, sys
signal.signal(signal.SIGINT, signal.SIG_IGN)
from multiprocessing.connection import Connection
conn = Connection(int(sys.argv[1]))
sys.path[:] = pickle.loads(conn.recv_bytes())
from symgroupoid.runtime._executors import serve
serve(conn)
"""


def dumps(obj) -> bytes:
    """``obj`` pickled for another process: with cloudpickle when installed (lambdas and
    functions of the user's script travel by value), else with pickle."""
    try:
        import cloudpickle
    except ImportError:
        return pickle.dumps(obj)
    return cloudpickle.dumps(obj)


def serve(conn) -> None:
    """A worker process: load the task (then say ``ready``), run jobs until told to stop or
    the parent is gone."""
    _watch_parent(os.getppid())
    task, failure = None, None
    while True:
        try:
            message = pickle.loads(conn.recv_bytes())
        except (EOFError, OSError):
            return
        if message[0] == "stop":
            return
        if message[0] == "task":
            try:
                task = pickle.loads(message[1])
                conn.send_bytes(pickle.dumps(("ready",)))
            except BaseException as exc:  # noqa: BLE001 - sent to the parent
                failure = _portable(exc, traceback.format_exc())
                conn.send_bytes(pickle.dumps(("error", *failure)))
            continue
        try:
            reply = ("done", run_job(task, message[1]))
        except BaseException as exc:  # noqa: BLE001 - sent to the parent
            reply = ("error", *_portable(exc, traceback.format_exc()))
        try:
            conn.send_bytes(dumps(reply))
        except Exception as exc:  # noqa: BLE001 - a result that does not pickle
            explain = getattr(reply[-1], "unsendable", None) if reply[0] == "done" else None
            named = explain(dumps) if explain is not None else None
            conn.send_bytes(pickle.dumps(("error", *_portable(named or exc,
                                                             traceback.format_exc()))))


def _portable(exc: BaseException, text: str) -> tuple:
    """(the exception, if it pickles, else None; its traceback text)."""
    try:
        pickle.loads(pickle.dumps(exc))
        return exc, text
    except Exception:  # noqa: BLE001 - any exception that does not travel
        return None, text


def _watch_parent(parent: int) -> None:
    """End this worker when its parent is gone (killed, or exited without stopping it)."""

    def watch() -> None:
        while True:
            time.sleep(0.5)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, daemon=True, name="symgroupoid-parent-watch").start()


class _Worker:
    """One worker process, its end of the connection and the job it runs."""

    def __init__(self, payload: bytes):
        import multiprocessing

        mine, theirs = multiprocessing.Pipe()
        fd = theirs.fileno()
        try:
            self.process = subprocess.Popen([sys.executable, "-c", BOOT, str(fd)],
                                            pass_fds=(fd,), stdin=subprocess.DEVNULL)
        except OSError as exc:
            mine.close()
            raise WorkerProcessError(f"a sweep worker process could not be started "
                                     f"({sys.executable}): {exc}") from exc
        finally:
            theirs.close()
        self.conn = mine
        self.job = None
        self.ready = False
        self.started = 0.0
        self.conn.send_bytes(pickle.dumps(list(sys.path)))
        self.conn.send_bytes(pickle.dumps(("task", payload)))

    def submit(self, job) -> None:
        self.conn.send_bytes(pickle.dumps(("job", job)))
        self.job, self.started = job, time.monotonic()

    def running_for(self) -> float:
        """Seconds the job has run (from the later of its submission and the worker's
        loading of the task)."""
        return time.monotonic() - self.started if self.ready else 0.0

    def kill(self) -> int:
        """SIGKILL and reap; the return code."""
        if self.process.poll() is None:
            self.process.kill()
        code = self.process.wait()
        self.conn.close()
        return code


def _death(code: int | None) -> str:
    if code is not None and code < 0:
        try:
            return f"killed by signal {-code} ({signal.Signals(-code).name})"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


class _ProcessPool:
    """Jobs on worker processes, one job per worker at a time."""

    def __init__(self, task, workers: int, timeout: float | None):
        try:
            self.payload = dumps(task)
        except (pickle.PicklingError, TypeError, AttributeError) as exc:
            if isinstance(exc, SymgroupoidError):
                raise
            from ._pickle import NotPortableError

            raise NotPortableError(
                f"the sweep's task (its simulator or system, and reduce) cannot be sent to "
                f"worker processes: {type(exc).__name__}: {exc}; use executor='thread' (nothing "
                f"is sent), or make reduce a function of a module you import") from exc
        self.workers, self.timeout = workers, timeout
        self.pool: list[_Worker] = []

    def run(self, jobs: list, receive) -> None:
        todo = collections.deque(jobs)
        finished = False
        try:
            self.pool = [_Worker(self.payload) for _ in range(min(self.workers, len(todo)))]
            while todo or any(w.job is not None for w in self.pool):
                for w in list(self.pool):
                    if w.job is None and todo:
                        self._submit(w, todo.popleft())
                self._wait(todo, receive)
            finished = True
        finally:
            self._end(finished)

    def _end(self, politely: bool) -> None:
        """Every worker ended and reaped: asked to stop (after a complete sweep), else (an
        error, Ctrl-C) killed at once."""
        if politely:
            for w in self.pool:
                try:
                    w.conn.send_bytes(pickle.dumps(("stop",)))
                except OSError:
                    pass
            limit = time.monotonic() + 5.0
            for w in self.pool:
                try:
                    w.process.wait(max(0.0, limit - time.monotonic()))
                except subprocess.TimeoutExpired:
                    pass
        for w in self.pool:
            w.kill()
        self.pool = []

    def _fresh(self, w: _Worker) -> _Worker:
        """A new worker in the place of ``w`` (killed and reaped); ``w``'s return code is
        kept as ``w.code``."""
        w.code = w.kill()
        fresh = _Worker(self.payload)
        self.pool[self.pool.index(w)] = fresh
        return fresh

    def _submit(self, w: _Worker, job) -> None:
        try:
            w.submit(job)
        except OSError:  # the worker is gone: a fresh one takes the job
            self._fresh(w).submit(job)

    def _wait(self, todo, receive) -> None:
        from multiprocessing.connection import wait

        listening = {w.conn: w for w in self.pool if w.job is not None or not w.ready}
        for conn in wait(list(listening), timeout=POLL):
            w = listening[conn]
            try:
                reply = pickle.loads(conn.recv_bytes())
            except (EOFError, OSError):
                self._died(w, todo, receive)
                continue
            if reply[0] == "ready":
                w.ready = True
                w.started = time.monotonic()
                continue
            job, w.job = w.job, None
            if reply[0] == "error":
                _raise_remote(reply[1], reply[2])
            receive(reply[1])
        if self.timeout is not None:
            for w in list(self.pool):
                if w.job is not None and w.running_for() > self.timeout:
                    job = w.job
                    self._fresh(w)
                    receive(job.lost(TIMED_OUT, f"its task exceeded timeout={self.timeout:g} "
                                                f"s (its worker process was stopped)"))

    def _died(self, w: _Worker, todo, receive) -> None:
        """``w`` died: before loading the task, an error; running a job, the job's runs one
        by one on fresh workers, or, for a single run, its death recorded."""
        job, ready = w.job, w.ready
        self._fresh(w)
        if not ready:
            raise WorkerProcessError(
                f"a sweep worker process ended before it loaded the sweep's task "
                f"({_death(w.code)}; its error output, if any, is above)")
        if job is None:
            return
        parts = job.split()
        for part in reversed(parts):
            todo.appendleft(part)
        if not parts:
            receive(job.lost(WORKER_DIED, f"its worker process died while running it "
                                          f"({_death(w.code)})"))


def _raise_remote(exc: BaseException | None, text: str):
    if exc is not None:
        raise exc
    raise WorkerProcessError(f"a sweep worker raised an exception that cannot be sent "
                             f"back:\n{text}")


__all__ = ["ClusterLostError", "INTERRUPTED", "TIMED_OUT", "WORKER_DIED", "WorkerProcessError",
           "execute", "run_job"]
