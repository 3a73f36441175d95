"""Two schedulers of one graph: map a pure function over jobs, fold each key's results by a tree of `combine`.

The fold's shape depends only on the jobs' order (pairs of neighbours, level by level), never on
which job finished first or where it ran, so this machine's threads and a Dask cluster give the
same answer to the last bit on the same CPU (and to round-off across CPUs).

- `LocalScheduler(workers)`: threads on this machine (NumPy, SciPy and the compiled kernels release
  the GIL; BLAS kept to one thread inside each); at most 2 x workers jobs in flight, their results
  folded as they arrive (`_Fold`), so memory follows the segments being worked on, not the file.
  One worker is the calling thread itself, the jobs in their order; a `Staged` function's first stage
  of the next job runs on a second thread meanwhile.
  Made, it sets this process's C heap up for them (`heap.tune_threads`, `heap.arrow_system_pool`: one
  arena kept whole during a map, pyarrow on it), before the plan's reads and the threads start, and drops the
  shared libraries' pages the imports touched (`heap.release_library_pages`); again at a map's start and once
  its first job is done (the compiled kernels the map uses loaded by then).
- `DaskScheduler(address)`: a dask.distributed cluster ("local" starts a LocalCluster on this
  machine); the jobs are small (a segment's time window of a file the workers can reach), the
  workers read their data themselves, and the fold runs on the workers too. A worker lost
  mid-run has its tasks recomputed by Dask from the same jobs: the result does not change.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Hashable, Sequence
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass
from functools import cache
from typing import Any, Generic, Protocol, TypeVar

from threadpoolctl import threadpool_limits

from ..io.errors import MissingDependencyError
from ..progress import Count
from .heap import arrow_system_pool, release_library_pages, trim_heap, tune_threads

J = TypeVar("J")
R = TypeVar("R")
M = TypeVar("M")
Progress = Callable[[str], None]


class Scheduler(Protocol):
    def map_reduce(self, fn: Callable[[J], R], jobs: Sequence[J], key: Callable[[J], Hashable],
                   combine: Callable[[R, R], R], progress: Progress | None = None) -> dict[Hashable, R]: ...


@dataclass(frozen=True)
class Staged(Generic[J, M, R]):
    """A job's function in two stages, finish(job, first(job), ready): called, it is that function (any scheduler;
    ready does nothing); a one-worker `LocalScheduler` runs the next job's first stage on a second thread from the
    moment this job's finish calls ready() (its largest arrays freed; or once it returns, if it never calls it),
    the finishes on the calling thread in the jobs' order (the same bits): a first stage that reads and the tail
    of a finish that computes on its own threads overlap, one job's first-stage output held ahead."""

    first: Callable[[J], M]
    finish: Callable[[J, M, Callable[[], None]], R]

    def __call__(self, job: J) -> R:
        return self.finish(job, self.first(job), _nothing)


def _nothing() -> None:
    pass


def tree_fold(items: list, combine: Callable[[Any, Any], Any]) -> Any:
    """((a b) (c d)) (e ...): neighbours combined level by level (a depth of log2 n, a fixed shape)."""
    while len(items) > 1:
        items = [combine(items[i], items[i + 1]) if i + 1 < len(items) else items[i] for i in range(0, len(items), 2)]
    return items[0]


def _by_key(jobs: Sequence, key: Callable) -> dict[Hashable, list[int]]:
    groups: dict[Hashable, list[int]] = {}
    for i, j in enumerate(jobs):
        groups.setdefault(key(j), []).append(i)
    return groups


@cache
def _heap_for_threads() -> None:
    """The C heap set up once per process for the threads' jobs (`heap`), pyarrow's reads on it, and the imports'
    library pages dropped (LLVM's initialisers' among them, ~50 MB of a robot run's resident set)."""
    tune_threads()
    arrow_system_pool()
    release_library_pages()


class LocalScheduler:
    """This machine's cores (module doc)."""

    def __init__(self, workers: int | None = None) -> None:
        self.workers = max(1, workers or min(2, os.cpu_count() or 1))
        _heap_for_threads()

    def __repr__(self) -> str:
        return f"{self.workers} local thread(s)"

    def close(self) -> None:
        """Nothing to release (the threads live for one map)."""

    def map_reduce(self, fn, jobs, key, combine, progress=None):
        say = progress or (lambda _m: None)
        folds = {k: _Fold(idx, combine) for k, idx in _by_key(jobs, key).items()}
        of = {i: folds[k] for k, idx in _by_key(jobs, key).items() for i in idx}
        done = 0
        release_library_pages()  # what the plan touched (a robot's first compiled call: ~28 MB of LLVM's)
        if self.workers == 1:  # on the calling thread: its heap (glibc's arena) is the one the plan left free space in
            with threadpool_limits(limits=1, user_api="blas"), ThreadPoolExecutor(1) as ahead:
                staged = isinstance(fn, Staged) and len(jobs) > 1
                nxt = [ahead.submit(fn.first, jobs[0])] if staged else []
                for i, job in enumerate(jobs):
                    if not staged:
                        out = fn(job)
                    else:  # this job's first stage, done ahead; the next one's started once the finish is ready
                        got = nxt.pop().result()

                        def ready(i: int = i) -> None:
                            if not nxt and i + 1 < len(jobs):
                                nxt.append(ahead.submit(fn.first, jobs[i + 1]))

                        out = fn.finish(job, got, ready)
                        del got  # not held while the next job's first stage is awaited
                        ready()
                    of[i].put(i, out)
                    del out
                    done += 1
                    if done == 1:  # the kernels the jobs call are loaded: LLVM's pages that loading touched dropped
                        release_library_pages()
                    say(Count("segments", done, len(jobs), f"segments done {done}/{len(jobs)}", unit="segment"))
            trim_heap()  # as below
            return {k: fold.result() for k, fold in folds.items()}
        with ThreadPoolExecutor(self.workers) as pool, threadpool_limits(limits=1, user_api="blas"):
            running: dict = {}
            todo = iter(range(len(jobs)))
            for i in todo:
                running[pool.submit(fn, jobs[i])] = i
                if len(running) < 2 * self.workers:
                    continue
                finished, _ = wait(running, return_when=FIRST_COMPLETED)
                for f in finished:
                    j = running.pop(f)
                    of[j].put(j, f.result())
                    done += 1
                    if done == 1:  # as above
                        release_library_pages()
                    say(Count("segments", done, len(jobs), f"segments done {done}/{len(jobs)}", unit="segment"))
            for f in list(running):
                j = running.pop(f)
                of[j].put(j, f.result())
                done += 1
                say(Count("segments", done, len(jobs), f"segments done {done}/{len(jobs)}", unit="segment"))
        # the jobs' freed arrays handed back once, after the map, not every few jobs: on one arena with fixed
        # thresholds the next job reuses them, and a trim made it fault them in afresh (an hour of car data on 2
        # threads: 245k page faults trimmed every 8th job, 66k once a map; peak 0.73 -> 0.76 GB, 3 h 0.85 GB)
        trim_heap()
        return {k: fold.result() for k, fold in folds.items()}


class _Fold:
    """`tree_fold` of one key's results as they arrive: the results in the jobs' order are pushed on a stack of
    (level, partial), two of one level combined at once (a binary counter), the rest combined from the top at the
    end; the shape is tree_fold's for any count (pairs of neighbours level by level, an odd one carried up), so the
    answer is the same bits. A result that arrives before its predecessors waits for them: held are the results in
    flight and the stack (log2 of the count), not every job's (a car's partial holds its least squares' factors)."""

    def __init__(self, order: Sequence[int], combine: Callable[[Any, Any], Any]) -> None:
        self.order, self.combine = list(order), combine
        self.next = 0  # position in order of the next result to push
        self.waiting: dict[int, Any] = {}
        self.stack: list[tuple[int, Any]] = []

    def put(self, i: int, result: Any) -> None:
        self.waiting[i] = result
        while self.next < len(self.order) and self.order[self.next] in self.waiting:
            value, level = self.waiting.pop(self.order[self.next]), 0
            self.next += 1
            while self.stack and self.stack[-1][0] == level:
                value, level = self.combine(self.stack.pop()[1], value), level + 1
            self.stack.append((level, value))

    def result(self) -> Any:
        value = self.stack.pop()[1]
        while self.stack:
            value = self.combine(self.stack.pop()[1], value)
        return value


class DaskScheduler:
    """A dask.distributed cluster (module doc): address "local" (a LocalCluster of `workers` single-threaded
    processes on this machine) or a scheduler's address ("tcp://host:8786")."""

    def __init__(self, address: str = "local", workers: int | None = None) -> None:
        try:
            from dask.distributed import Client, LocalCluster  # optional: distributed (the dask extra)
        except ImportError:
            raise MissingDependencyError("Running on a Dask cluster needs dask.distributed: "
                                         "pip install distributed (dynid's 'dask' extra)") from None
        self.address = address
        from .dask_worker import MallocTuning  # optional: distributed (dask_worker imports it)

        if address == "local":
            self._cluster = LocalCluster(n_workers=workers or min(2, os.cpu_count() or 1), threads_per_worker=1,
                                         processes=True, dashboard_address=None, host="127.0.0.1")
            self.client = Client(self._cluster)
        else:
            self._cluster = None
            self.client = Client(address, timeout="30s")
        self.client.register_plugin(MallocTuning())

    def __repr__(self) -> str:
        n = len(self.client.scheduler_info().get("workers", {}))
        return f"Dask cluster {self.address} ({n} worker(s))"

    def close(self) -> None:
        self.client.close()
        if self._cluster is not None:
            self._cluster.close()

    def __enter__(self) -> DaskScheduler:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def map_reduce(self, fn, jobs, key, combine, progress=None):
        from dask.distributed import as_completed  # optional: distributed (the dask extra)

        say = progress or (lambda _m: None)
        # a lost worker's tasks are recomputed by the scheduler from the same jobs; an exception in a job (bad data)
        # is the same on any worker, so it is not retried
        futures = self.client.map(fn, list(jobs), pure=False)
        out = {}
        for k, idx in _by_key(jobs, key).items():  # the fold, submitted at once: combines run as parts arrive
            level = [futures[i] for i in idx]
            while len(level) > 1:  # the same fixed shape as tree_fold, run where the parts are
                level = [self.client.submit(combine, level[i], level[i + 1], pure=False)
                         if i + 1 < len(level) else level[i] for i in range(0, len(level), 2)]
            out[k] = level[0]
        where = repr(self)
        for done, _ in enumerate(as_completed(futures), 1):
            say(Count("segments", done, len(jobs), f"segments done {done}/{len(jobs)} on {where}", unit="segment"))
        return dict(zip(out, self.client.gather(list(out.values())), strict=True))


# the schemes dask.distributed connects to (distributed.comm's registry; http is the dashboard's, not a scheduler's)
DASK_SCHEMES = ("tcp", "tls", "ucx", "ws", "wss", "inproc")
_ADDRESS_HELP = ("give \"local\" (a Dask cluster on this machine), a Dask scheduler's address such as "
                 "\"tcp://10.0.0.5:8786\", or leave it out for this machine's threads")


def address_problem(address: str) -> str | None:
    """Why `address` is no scheduler dynid can use, with the fix (None: "local" or a Dask scheduler's address
    scheme://host:port, the scheme optional). Checked where the address is read, before any work starts."""
    text = address.strip()
    if text == "local":
        return None
    if text.lower() in ("local", "localcluster", "threads", "thread", "this machine", "none", "default"):
        hint = ("write it in lower case: \"local\" (a Dask cluster on this machine)" if text.lower() == "local" else
                "this machine's threads are the default: leave the scheduler out (or give \"local\" for a Dask "
                "cluster on this machine)")
        return f"{address!r} is not a scheduler; {hint}"
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    scheme = scheme.lower()
    if scheme in ("http", "https"):
        return (f"{address!r} is a web address (the Dask dashboard's, usually port 8787), not the scheduler's; give "
                "the scheduler's address, tcp://HOST:8786 (printed by dask scheduler as \"Scheduler at\")")
    if scheme not in DASK_SCHEMES:
        return f"{address!r}: unknown scheme {scheme!r} (Dask's: {', '.join(DASK_SCHEMES)}); {_ADDRESS_HELP}"
    if scheme == "inproc":
        return None
    host, colon, port = rest.rstrip("/").rpartition(":")
    if not colon or not host or not port.isdigit() or not 0 < int(port) < 65536 or "/" in host:
        return f"{address!r} is not \"local\" nor a scheduler's address HOST:PORT; {_ADDRESS_HELP}"
    return None


def scheduler_for(address: str | None, workers: int | None = None) -> LocalScheduler | DaskScheduler:
    """None: this machine's threads; "local" or an address: Dask."""
    return LocalScheduler(workers) if not address else DaskScheduler(address, workers)
