"""How `dynid` shows progress on stderr.

On a terminal: each counted step (segments, optimisation starts, simulated seconds: a `dynid.progress.Count`)
is one bar with its ETA, redrawn in place, and the other messages are printed above it. Otherwise (a log file,
a pipe, a CI job): plain lines only, a count printed every tenth of the way with the time left, never a
carriage return.
"""

from __future__ import annotations

import sys
import time
from typing import Any, TextIO

from ..progress import Count

# when the output is not a terminal, a count prints a line every tenth of the way, PLAIN_EVERY_S apart at least
# (a step done in seconds prints only its last line), and its last line
PLAIN_STEPS = 10
PLAIN_EVERY_S = 10.0


def _duration(seconds: float) -> str:
    """'45 s', '3 min 20 s', '1 h 05 min': a time left as a person reads it."""
    s = round(seconds)
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


class _Step:
    """What is drawn of one counted step: its bar (terminal), or when it started and the last tenth printed."""

    def __init__(self, bar: Any, done: float) -> None:
        self.bar = bar
        self.t0 = self.said = time.perf_counter()
        self.done0 = done  # the steps already done when it was first reported: the rate counts those after
        self.shown = -1


class Reporter:
    """A `progress` callable for the pipeline's messages (module doc). stream: where to write (None: sys.stderr
    at each call); tty: draw bars (None: when the stream is a terminal). Counts of different steps (a campaign's
    configs on a cluster) have a bar each."""

    def __init__(self, stream: TextIO | None = None, tty: bool | None = None) -> None:
        self.stream = stream
        self.tty = tty
        self._steps: dict[str, _Step] = {}
        self._ended: set[str] = set()  # steps whose last count was shown: a repeat of it is not a new step

    @property
    def out(self) -> TextIO:
        return self.stream if self.stream is not None else sys.stderr

    def _terminal(self) -> bool:
        if self.tty is not None:
            return self.tty
        isatty = getattr(self.out, "isatty", None)
        return bool(isatty and isatty())

    def __call__(self, msg: str) -> None:
        if isinstance(msg, Count):
            self._count(msg)
        else:
            self.line(f"· {msg}")

    def line(self, text: str) -> None:
        """A line of text, printed above the bars being drawn."""
        bar = next((s.bar for s in self._steps.values() if s.bar is not None), None)
        if bar is not None:
            bar.write(text, file=self.out)
        else:
            print(text, file=self.out, flush=True)

    def _count(self, c: Count) -> None:
        if c.done >= c.total and c.what in self._ended:
            return
        self._ended.discard(c.what)
        step = self._steps.get(c.what)
        if step is None:
            step = self._steps[c.what] = _Step(_tqdm(c, self.out) if self._terminal() else None, c.done)
        if step.bar is not None:
            step.bar.update(c.done - step.bar.n)
            if c.note:
                step.bar.set_postfix_str(c.note)
        else:
            self._plain(c, step)
        if c.done >= c.total:
            self.close(c.what)
            self._ended.add(c.what)

    def _plain(self, c: Count, step: _Step) -> None:
        tenth = int(PLAIN_STEPS * c.done / c.total) if c.total > 0 else PLAIN_STEPS
        now = time.perf_counter()
        if c.done < c.total and (tenth <= step.shown or now - step.said < PLAIN_EVERY_S):
            return
        step.shown, step.said = tenth, now
        share = f"{100 * c.done / c.total:.0f} %" if c.total > 0 else ""
        rate = (c.done - step.done0) / (now - step.t0) if now > step.t0 and c.done > step.done0 else None
        when = ""
        if rate and c.done < c.total:
            when = f"about {_duration((c.total - c.done) / rate)} left"
        elif rate:
            when = _duration(c.done / rate)  # the whole step's time, its first part timed at the same rate
        print(f"· {c} ({', '.join(x for x in (share, when) if x)})", file=self.out, flush=True)

    def close(self, what: str | None = None) -> None:
        """End the bar of `what` (None: every bar); a bar stays on screen at its last state."""
        for key in [what] if what is not None else list(self._steps):
            step = self._steps.pop(key, None)
            if step is not None and step.bar is not None:
                step.bar.close()


def _tqdm(c: Count, out: TextIO) -> Any:
    try:
        from tqdm import tqdm  # start-up: tqdm, only once a bar is drawn
    except ImportError:  # a plain line now and then instead
        return None
    return tqdm(total=c.total, initial=c.done, desc=c.what, unit=c.unit or "it", file=out, leave=True,
                dynamic_ncols=True, mininterval=0.5)


report = Reporter()  # the command's own: its messages and bars on stderr


__all__ = ["Reporter", "report"]
