"""A sweep's jobs on a Dask cluster (``sweep(..., client=...)``).

A worker process that dies takes with it every task it was running or holding, and Dask
counts the death against each of them (a task's *suspicious* count; ``KilledWorker`` past
``distributed.scheduler.allowed-failures``).  A run whose ``reduce`` ends its process
(``os._exit``, a crash in the user's code) therefore implicates the runs that shared its
worker.  So the jobs run in two waves:

1. every job, a few in flight per worker; a job that a death implicates (its suspicious
   count, read from the scheduler, or ``KilledWorker`` where the scheduler does not answer)
   is cancelled at once, split into its runs and set aside;
2. once no task of the first wave runs on any worker (a cancelled task runs on until it
   returns), the runs set aside, one at a time, alone on the cluster, where a death can only
   be the run's own: the first one records it :data:`WORKER_DIED`; the others complete.

So no run is blamed for another's death, and each culprit costs about two worker restarts,
not Dask's four per try (a worker that dies just after it started may not be restarted by
its nanny: every death avoided keeps the cluster alive).  While it waits, the sweep watches
the cluster: when it has lost the workers it had during the sweep (or deaths have left it
without any) for :data:`NO_WORKERS_WAIT` seconds it raises :class:`ClusterLostError`
(carrying the runs done), rather than wait for ever; a cluster that has had no workers yet
(one still starting, an adaptive or queued one) only gets a warning.
"""

from __future__ import annotations

import collections
import pickle
import time
import uuid
import warnings

from ._executors import POLL, WORKER_DIED, ClusterLostError, dumps, run_job

#: tasks in flight per worker thread at most
IN_FLIGHT_PER_WORKER = 4
#: how long a cluster may have no workers before the sweep says so (seconds)
NO_WORKERS_WAIT = 60.0
#: the scheduler's failures in a row to answer after which deaths are known from
#: ``KilledWorker`` alone
REFUSALS = 20
#: how long the second wave waits for workers that cannot say what they run (seconds)
SETTLE_UNKNOWN = 10.0
#: how long the first fetch of a task's result waits before the cluster is looked at again
#: (seconds; doubled for each fetch of the same result): short, because while a fetch
#: waits for a result lost with its worker, Dask may run a culprit again and again
FETCH_WAIT = 0.2


def _hold(payload: bytes):
    return pickle.loads(payload)


def _killed_worker(exc: BaseException) -> bool:
    return type(exc).__name__ == "KilledWorker"


def _run_job_sent(task, job):
    """:func:`run_job` on a Dask worker, whose reduced values are checked to pickle there:
    a value that does not is a ``ReduceError`` naming its run (Dask's own error names no
    run)."""
    result = run_job(task, job)
    if getattr(result, "values", None) is not None:
        try:
            dumps(result.values)
        except Exception:  # noqa: BLE001 - any value that does not travel
            named = result.unsendable(dumps)
            if named is not None:
                raise named from None
            raise
    return result


def _cluster_state(keys: list, dask_scheduler=None) -> tuple[list, list, int]:
    """On the scheduler: the keys among ``keys`` that a worker's death implicated, those
    that no worker may run (pinned to a worker that left without a death), and the threads
    of the running workers."""
    tasks = [dask_scheduler.tasks[k] for k in keys if k in dask_scheduler.tasks]
    implicated = [t.key for t in tasks if getattr(t, "suspicious", 0) > 0]
    stranded = [t.key for t in tasks if t.state == "no-worker" and t.key not in implicated]
    return implicated, stranded, sum(w.nthreads for w in dask_scheduler.running)


class _Watch:
    """The cluster as the sweep sees it: implicated tasks, and how long it has had no
    workers."""

    def __init__(self, client):
        self.client = client
        self.threads = sum(client.nthreads().values())  # of the running workers, last seen
        self.asks = True  # the scheduler answers run_on_scheduler
        self.refusals = 0  # its failures in a row (a worker's death may fail one call)
        self.seen = self.threads > 0  # the cluster had workers during the sweep
        self.deaths = 0  # tasks a death implicated
        self.since: float | None = None  # when the cluster was last seen without workers
        self.warned = False

    def implicated(self, keys: list) -> tuple[set, set]:
        """(the keys of ``keys`` a worker's death implicated, those no worker may run; none
        where the scheduler does not say); checks the workers as it goes."""
        found, stranded, threads = [], [], None
        if self.asks:
            try:
                found, stranded, threads = self.client.run_on_scheduler(_cluster_state, keys)
                self.refusals = 0
            except Exception:  # noqa: BLE001 - a scheduler that refuses: KilledWorker only
                self.refusals += 1
                self.asks = self.refusals < REFUSALS
        if threads is None:
            threads = sum(self.client.nthreads().values())
        self.threads = threads
        self.seen = self.seen or threads > 0
        self._workers(threads)
        return set(found), set(stranded)

    def worker(self) -> str | None:
        """A running worker to pin a task to, where the scheduler answers (so that a task
        left without one is seen), else None."""
        workers = sorted(self.client.nthreads()) if self.asks else []
        return workers[0] if workers else None

    def in_flight(self) -> int:
        """How many tasks to keep in flight: a few per thread of the workers last seen (a
        cluster that grows, an adaptive one, gets more)."""
        return IN_FLIGHT_PER_WORKER * max(1, self.threads)

    def _workers(self, threads: int) -> None:
        now = time.monotonic()
        if threads:
            self.since, self.warned = None, False
            return
        self.since = self.since or now
        if now - self.since < NO_WORKERS_WAIT:
            return
        if self.deaths or self.seen:
            raise ClusterLostError(
                f"the Dask cluster has had no workers for {NO_WORKERS_WAIT:g} s since it "
                f"lost those that ran this sweep (a reduce that ends its process, a crash, "
                f"or workers stopped), and none came back.  The runs done are in this "
                f"error's .result")
        if not self.warned:
            self.warned = True
            warnings.warn(f"sweep: the Dask cluster has had no workers for "
                          f"{NO_WORKERS_WAIT:g} s; waiting for some (Ctrl-C keeps the runs "
                          f"done)", RuntimeWarning, stacklevel=2)


def run_dask(task, jobs: list, receive, client) -> None:
    """The jobs on a Dask cluster (see the module docstring); each result to ``receive``.
    The shared task is itself a task (recomputed if the workers holding it are lost);
    results are gathered as soon as they are computed; Ctrl-C cancels what is in flight."""
    token = uuid.uuid4().hex[:12]
    held = client.submit(_hold, dumps(task), key=f"symgroupoid-task-{token}", pure=False)
    watch = _Watch(client)
    aside: list = []

    def set_aside(job, why):
        aside.extend(job.split() or [job])

    def died(job, why):
        receive(job.lost(WORKER_DIED, f"its Dask worker died while running it alone on "
                                      f"the cluster ({why})"))

    try:
        _wave(client, held, token, jobs, watch.in_flight, receive, set_aside, watch)
        if aside:
            _settle(client, f"symgroupoid-chunk-{token}", watch)
        _wave(client, held, token, aside, lambda: 1, receive, died, watch, pin=True)
    finally:
        held.release()


#: the states of a task a worker has done with (any other: it runs, or may still start; a
#: cancelled task runs on until it returns, and the worker hears of a cancellation late)
_DONE_STATES = frozenset({"memory", "error", "released", "forgotten"})


def _running_tasks(prefix: str, dask_worker=None) -> list:
    """On a worker: the keys starting with ``prefix`` of the tasks it runs or may start."""
    tasks = dask_worker.state.tasks
    return [str(k) for k, ts in tasks.items()
            if str(k).startswith(prefix) and ts.state not in _DONE_STATES]


def _settle(client, prefix: str, watch: _Watch) -> None:
    """Wait until no task of this sweep (keys starting with ``prefix``) runs on any worker.

    A cancelled task is not stopped: a job set aside in the first wave may still be running
    its ``reduce``, and if that ends its worker during the second wave, the run then alone on
    the cluster would be blamed.  Workers that cannot say are waited for at most
    :data:`SETTLE_UNKNOWN` seconds."""
    unknown_since = None
    while True:
        try:
            busy = client.run(_running_tasks, prefix, on_error="raise")
        except Exception:  # noqa: BLE001 - a worker dying meanwhile, an older distributed
            unknown_since = unknown_since or time.monotonic()
            if time.monotonic() - unknown_since > SETTLE_UNKNOWN:
                return
        else:
            unknown_since = None
            if not any(busy.values()):
                return
        watch.implicated([])  # the cluster is still watched for lost workers
        time.sleep(POLL)


def _wave(client, held, token: str, jobs: list, limit, receive, implicated,
          watch: _Watch, pin: bool = False) -> None:
    """``jobs`` on the cluster, at most ``limit()`` in flight: each result to ``receive``, each
    job a worker's death implicated to ``implicated(job, why)`` (cancelled); any other
    error raised.  The scheduler is asked about deaths at most every :data:`POLL`
    seconds.  ``pin``: each job runs on one worker only, so that its worker's death leaves it
    waiting (and seen) rather than run at once on the next worker, which it would kill too;
    a job whose worker left without dying is sent again."""
    from distributed import wait

    todo = collections.deque(jobs)
    live: dict = {}
    patience: dict = {}
    asked = time.monotonic()

    def drop(key, why):
        future, job = live.pop(key)
        watch.deaths += 1
        client.cancel([future])
        future.release()
        implicated(job, why)

    try:
        while todo or live:
            while todo and len(live) < limit():
                job = todo.popleft()
                where = watch.worker() if pin else None
                future = client.submit(
                    _run_job_sent, held, job, pure=False,
                    key=f"symgroupoid-chunk-{token}-{uuid.uuid4().hex[:12]}",
                    workers=None if where is None else [where], allow_other_workers=False)
                live[future.key] = (future, job)
            try:
                wait([f for f, _ in live.values()], timeout=POLL, return_when="FIRST_COMPLETED")
            except TimeoutError:
                pass
            for key in [k for k, (f, _) in live.items() if f.done()]:
                _collect(key, live, receive, drop, patience)
            if time.monotonic() - asked >= POLL:
                asked = time.monotonic()
                found, stranded = watch.implicated(list(live))
                for key in found:
                    drop(key, "a worker died while it was running or queued there")
                for key in stranded & set(live):
                    future, job = live.pop(key)
                    client.cancel([future])
                    todo.appendleft(job)
    except BaseException:
        client.cancel([f for f, _ in live.values()])
        raise


def _collect(key, live: dict, receive, drop, patience: dict) -> None:
    """The done task ``key``: its result received, a ``KilledWorker`` dropped, any other
    error raised.  A result whose worker died before it was fetched is computed again: the
    fetch waits ``patience[key]`` seconds (doubled each time) and leaves it to the next
    round, so that the cluster is still watched meanwhile."""
    future, _ = live[key]
    if future.status == "error" and _killed_worker(future.exception()):
        drop(key, str(future.exception()))
        return
    wait = patience.get(key, FETCH_WAIT)
    try:
        result = future.result(timeout=wait)  # raises the task's error (or a cancellation)
    except TimeoutError:
        patience[key] = 2 * wait
        return
    del live[key]
    patience.pop(key, None)
    future.release()
    receive(result)


__all__ = ["IN_FLIGHT_PER_WORKER", "NO_WORKERS_WAIT", "run_dask"]
