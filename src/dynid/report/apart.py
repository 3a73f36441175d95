"""A part of the report computed in a forked process while this one builds the rest (the figures: most of a
warm demo's report is matplotlib drawing and PNG encoding, one core's work).

`Apart(fn)` forks at once where it can (Linux, this process of one thread: another thread's locks would stay held
in the child's copy) and the child returns fn()'s value pickled through a pipe; `.result()` collects it. Where it
cannot fork, or the child fails or dies, fn() runs here at `.result()`, so the outcome (an error included) is
what calling fn() here gives, only earlier. An Apart dropped uncollected (the caller raised) kills its child.
"""

from __future__ import annotations

import contextlib
import gc
import os
import pickle
import signal
import sys
import threading
import weakref
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from typing import Generic, TypeVar

T = TypeVar("T")

_HELD = {signal.SIGINT, signal.SIGTERM}


class Apart(Generic[T]):
    """fn() in a forked child, started now; result() its value (or fn() here: module doc)."""

    def __init__(self, fn: Callable[[], T]) -> None:
        self.fn = fn
        self.pid: int | None = None
        self.fd = -1
        if not can_fork():
            return
        r, w = os.pipe()

        def child() -> None:  # its value down the pipe
            signal.pthread_sigmask(signal.SIG_SETMASK, held)  # Ctrl-C and TERM let through, as before the job
            os.close(r)
            data = pickle.dumps(fn(), protocol=pickle.HIGHEST_PROTOCOL)
            with os.fdopen(w, "wb") as out:
                out.write(data)

        # Ctrl-C and TERM held until the child is this job's to kill: raised in between, they left it running
        held = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD)
        try:
            pid = fork(child)
            os.close(w)
            self.pid, self.fd = pid, r
            self._reap = weakref.finalize(self, _kill, pid, r)  # dropped uncollected: no child left running
        finally:
            try:
                signal.pthread_sigmask(signal.SIG_SETMASK, held)  # a signal held meanwhile is raised here
            except BaseException:
                self.cancel()  # at once: the caller never gets this job, and may remove what the child writes into
                raise

    def result(self) -> T:
        if self.pid is not None:
            pid, self.pid = self.pid, None
            self._reap.detach()
            with os.fdopen(self.fd, "rb") as f:
                data = f.read()
            _, status = os.waitpid(pid, 0)
            if status == 0:
                return pickle.loads(data)
        return self.fn()  # no fork, or the child failed: here (its error, if any, raised here)

    def cancel(self) -> None:
        """The child killed and reaped now, its value dropped (the caller raised and will not ask for it: a child
        still writing files after the caller has removed their folder would leave them behind)."""
        if self.pid is not None:
            self.pid = None
            self._reap()


def can_fork() -> bool:
    """Whether this process may fork: Linux, and one thread (another thread's locks would stay held in the child's
    copy, where nothing frees them)."""
    return sys.platform.startswith("linux") and threading.active_count() == 1


def fork(child: Callable[[], object], locks: Sequence[AbstractContextManager] = ()) -> int:
    """Fork (where can_fork()); the child runs child() and leaves at once (os._exit: 0, or 1 when it raised; no atexit,
    no buffered output flushed twice); returns the child's pid. locks: held across the fork, so that no other thread
    holds one in the child's copy (pipeline.first_run: Numba's compiler lock, the generated modules' loader)."""
    # Ctrl-C and TERM held across the fork: their handlers raise, and a raise inside the fork's own hooks
    # (logging's lock release) is printed as an ignored exception with its traceback (a run killed while
    # writing its report, tests/cli/test_output_folder.py); they are delivered once the child is accounted for
    held = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD)
    # this process's objects out of the child's garbage collections (the gc module's advice for a fork): a
    # collection writes into every object it scans, which copies each page of the inherited heap in the child;
    # a warm quick demo's report ~1.8 -> ~1.5 s CPU, this process and its child (benchmarks/bench_report.py)
    ours = gc.get_freeze_count() == 0  # another's freeze left as it is
    gc.freeze()
    pid = -1
    try:
        with contextlib.ExitStack() as stack:
            for lock in locks:
                stack.enter_context(lock)
            pid = os.fork()
        if pid == 0:  # the child (the locks' copies released above, as in this process)
            code = 1
            try:
                signal.pthread_sigmask(signal.SIG_SETMASK, held)
                child()
                code = 0
            finally:
                os._exit(code)
        return pid
    finally:  # this process's (the child left above)
        if ours:
            gc.unfreeze()
        try:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)  # a signal held across the fork is raised here
        except BaseException:  # ... before the caller has the pid: the child killed, not left running unknown
            if pid > 0:
                _kill(pid, -1)
            raise


def _kill(pid: int, fd: int) -> None:
    with contextlib.suppress(OSError):
        os.kill(pid, signal.SIGKILL)
    if fd >= 0:
        os.close(fd)
    with contextlib.suppress(OSError):
        os.waitpid(pid, 0)


__all__ = ["Apart", "can_fork", "fork"]
