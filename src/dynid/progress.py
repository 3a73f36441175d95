"""Progress messages that a front end can show as a bar, and notices for steps that are only sometimes slow.

Every long computation reports through a `progress` callable taking one message (a str). A step repeated a known
number of times (segments, optimisation starts) reports a `Count`: a str like any other message, so that a
caller that prints or collects strings sees the same text, and a terminal can draw one bar with an ETA from
its `done` and `total` instead of a line per step (`dynid.cli.progress`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager


class Count(str):
    """A progress message that is also a count: `done` of `total` steps of `what` ("segments"), its text as
    given (by default "what done/total"); `unit` of a step for a bar ("segment", "s"); `note`: what the current
    step is doing, shown beside a bar."""

    what: str
    done: float
    total: float
    unit: str
    note: str

    def __new__(cls, what: str, done: float, total: float, text: str | None = None, *, unit: str = "",
                note: str = "") -> Count:
        self = super().__new__(cls, text if text is not None else f"{what} {done:g}/{total:g}")
        self.what, self.done, self.total, self.unit, self.note = what, done, total, unit, note
        return self

    def prefixed(self, prefix: str) -> Count:
        """The same count, its text and step name prefixed (a campaign's "[name] ")."""
        return Count(prefix + self.what, self.done, self.total, prefix + str(self), unit=self.unit, note=self.note)


@contextmanager
def notice_if_slow(seconds: float, message: str, say: Callable[[str], None]) -> Iterator[None]:
    """Say `message` if the block is still running after `seconds`: a step that is slow only the first time (a
    cache to fill) is announced when it is, and silent when the cache makes it quick."""
    timer = threading.Timer(seconds, say, args=(message,))
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        timer.cancel()


__all__ = ["Count", "notice_if_slow"]
