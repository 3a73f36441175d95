"""A logger's time base checked and its clock fitted (`stream`), and a test file opened with or without a time
column (`opened`); `sources` plans every test with them.

A file with a time column is used on its own stamps (an `fs` in the test's config must then agree
with them); a file without one needs the test's `fs`. Per time base (channels logged together):
rows with identical stamps are averaged into one sample; stamps going back, or a hole longer than
`max_gap` sample periods, are refused with the file, line, sample and time; the stamps' least-
squares line is the logger's clock, and the base is uniform when every stamp is within 1e-3 of a
step of it (else `sources` resamples it onto that clock).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from ..io import Channel, DataError, FileFormatError, GapError, TimeBaseError
from ..io.checks import locate

T = TypeVar("T")
RATE_TOLERANCE = 0.01  # relative: a config fs and a time column further apart than this disagree
UNIFORM = 1e-3  # stamps within this fraction of a step of a uniform clock are used as they are


@dataclass
class Stream:
    """Channels of one file on one time base, repeated stamps merged: the base's nominal step and quality."""

    source: str
    timed: bool  # from a time column (False: rows at the config's fs)
    t: NDArray[np.float64]
    channels: dict[str, Channel]
    h: float
    uniform: bool
    t0: float = 0.0  # the uniform clock's origin: t0 + k h
    repeated: int = 0
    jitter_rms: float = 0.0
    jitter_max: float = 0.0
    largest_gap: float = 0.0

    def report(self) -> str:
        ms = 1e3
        text = (f"{self.source}: time column, {self.t.size} samples at {1 / self.h:.6g} Hz; {self.repeated} "
                f"repeated row(s) (identical time stamps) averaged; jitter {self.jitter_rms * ms:.3g} ms RMS, "
                f"{self.jitter_max * ms:.3g} ms max; largest gap {self.largest_gap * ms:.3g} ms "
                f"({self.largest_gap / self.h:.3g} sample periods)")
        return text if self.uniform else text + "; resampled onto a uniform clock"


def _where(source: str, lines: NDArray[np.int64] | None, k: int, t: float, offset: int = 0) -> str:
    text = locate(source, None, offset + k, t)
    return text if lines is None else text.replace(", sample", f", line {int(lines[k])}, sample", 1)


def opened(open_file: Callable[..., T], path: Path, fs: float | None, test: str, config: Path) -> tuple[T, bool]:
    """open_file(fs=...) of a test's file (read whole, or indexed), and whether its samples carry their own time
    stamps: a file without a time column needs the config's fs; with one, the stamps are used (and fs, if given,
    is checked against them by the caller)."""
    try:
        return open_file(fs=fs), fs is None
    except FileFormatError as exc:
        if fs is None:
            if "no time column" in str(exc):
                raise FileFormatError(f"{exc}. Or give the rate in the config: fs = ... (Hz) in test {test!r} of "
                                      f"{config}", source=str(path)) from None
            raise
        try:
            return open_file(fs=None), True
        except DataError:
            raise exc from None


def stream(chans: list[Channel], source: str, timed: bool, max_gap: float,
           window: tuple[float | None, float | None] = (None, None), fit: bool = True) -> Stream:
    """The channels (one time base) with repeated stamps averaged, checked for stamps going back and holes;
    with a window (start, end), only the rows from just before start to just after end. fit: False for a window of
    a base the plan fitted already (a segment's read): the stamps checked (finite, not going back) and repeated ones
    merged, no hole looked for and no clock fitted (h NaN, not uniform: a third of a segment's read)."""
    t, lines = chans[0].time, chans[0].lines
    offset = 0  # of the first row kept, for messages
    if timed and window != (None, None) and t.size > 2:
        steps = np.diff(t)
        margin = 2 * max_gap * float(np.median(np.abs(steps, out=steps), overwrite_input=True))  # no copies
        del steps
        lo = -np.inf if window[0] is None else window[0] - margin
        hi = np.inf if window[1] is None else window[1] + margin
        inside = (t >= lo) & (t <= hi)  # its first and last True, without their indices (8 bytes a sample)
        a, z = int(np.argmax(inside)), t.size - 1 - int(np.argmax(inside[::-1]))
        if inside[a] and (a > 0 or z < t.size - 1):
            rows = slice(a, z + 1)
            offset = rows.start
            chans = [Channel(c.name, c.unit, c.values[rows], t[rows], None if lines is None else lines[rows])
                     for c in chans]
            t, lines = chans[0].time, chans[0].lines
    if not timed or t.size < 3:
        h = float(t[1] - t[0]) if t.size > 1 else 1.0
        return Stream(source, timed, t, {c.name: c for c in chans}, h, True, float(t[0]) if t.size else 0.0)
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        k = int(bad[0])
        raise TimeBaseError(f"{_where(source, lines, k, np.nan, offset)}: time stamp is {t[k]}; fix the logger "
                            "export or keep to a part of the test without it (start, end)", source=source,
                            sample=offset + k)
    step = np.diff(t)
    back = np.flatnonzero(step < 0.0)
    if back.size:
        k = int(back[0]) + 1
        raise TimeBaseError(
            f"{_where(source, lines, k, float(t[k]), offset)}: time goes back from {float(t[k - 1]):.6g} s "
            f"(sample {offset + k - 1}) "
            f"to {float(t[k]):.6g} s ({back.size} such step(s) in all): the time stamps must not decrease. Sort the "
            "rows by time or fix the logger's clock, or keep to a part before or after it (start, end in the test)",
            source=source, sample=offset + k, line=None if lines is None else int(lines[k]))
    # lean on memory: an hour's stamps are millions of samples (29 MB), and the planning pass of a long file holds
    # only them; beside them at most two arrays of their size live at once (the median's steps, then the fit's two
    # centred vectors), the rest is computed over blocks of BLOCK steps
    up = step > 0.0
    repeated = t.size - 1 - int(np.count_nonzero(up))
    first = None  # the first row of each stamp, where rows repeat one
    if repeated:  # rows with one stamp: one sample, their mean
        first = np.flatnonzero(np.concatenate(([True], up)))
        counts = np.diff(np.append(first, t.size))[:, None]
        merged = np.add.reduceat(np.column_stack([c.values for c in chans]), first, axis=0) / counts
        t_lines = None if lines is None else lines[first]
        chans = [Channel(c.name, c.unit, merged[:, i], t[first], t_lines) for i, c in enumerate(chans)]
    del up
    tu = chans[0].time
    if tu.size < 2:  # every row has one stamp: no clock to read a rate from
        raise TimeBaseError(f"{_where(source, lines, 0, float(t[0]), offset)}: all {t.size} time stamps are "
                            f"{float(t[0]):.6g} s: the time column does not advance; fix the logger export (is it "
                            "the right column?), or drop the time column and give the test's fs",
                            source=source, sample=offset)
    if not fit:
        return Stream(source, timed, chans[0].time, {c.name: c for c in chans}, float("nan"), False,
                      float(t[0]), repeated)
    su = np.diff(tu) if repeated else step
    del step
    largest = float(np.max(su))
    h_step = h = float(np.median(su, overwrite_input=True))  # in place: the same order statistics, no copy
    del su
    big_at, big_n = -1, 0  # the first step over max_gap periods (an index of tu's steps), and their count
    for a, b in _blocks(tu.size - 1):
        over = np.flatnonzero(np.diff(tu[a:b + 1]) > max_gap * h)
        if over.size and big_at < 0:
            big_at = a + int(over[0])
        big_n += over.size
    if big_n:
        i = big_at
        gap = float(tu[i + 1] - tu[i])
        k = int(first[i + 1]) if first is not None else i + 1
        raise GapError(
            f"{_where(source, lines, k, float(t[k]), offset)}: no sample for {gap * 1e3:.4g} ms before it (from "
            f"t = {float(tu[i]):.6g} s), {gap / h:.3g} sample periods at {1 / h:.6g} Hz, over max_gap = {max_gap:g} "
            f"({big_n} such gap(s) in all). Keep to a part of the test without it (start, end in the test) or "
            "raise max_gap in the test if interpolating across it is acceptable",
            source=source, sample=offset + k, line=None if lines is None else int(lines[k]))
    # each step rounded to whole periods on its own: the count over the whole record (span / median step) is off
    # by several under a realistic jitter (10 % of the step over thousands of samples), which skews the rate
    slots = np.empty(tu.size)
    consecutive = _slots(tu, h_step, slots)
    # the logger's clock: the stamps' least-squares line t = t0 + h slot, in closed form about the means
    s_mean, t_mean = float(slots.mean()), float(tu.mean())
    centred = np.subtract(slots, s_mean, out=slots)  # the slots again below, from the stamps
    dev = tu - t_mean
    h = float(centred @ dev / (centred @ centred))
    del centred, dev
    t0 = t_mean - h * s_mean
    _slots(tu, h_step, slots)
    jitter = np.multiply(slots, h, out=slots)  # then tu - t0 - slots h, in place
    np.subtract(tu, jitter, out=jitter)
    jitter -= t0
    worst = float(max(jitter.max(), -jitter.min()))
    uniform = bool(worst <= UNIFORM * h and consecutive)
    return Stream(source, timed, tu, {c.name: c for c in chans}, h, uniform, t0, repeated,
                  float(np.sqrt(jitter @ jitter / jitter.size)), worst, largest)


BLOCK = 1 << 16  # steps per block of the passes over the stamps (512 KiB of float64)


def _blocks(n: int) -> list[tuple[int, int]]:
    """[a, b) ranges of BLOCK steps covering n steps (a block's steps are diff(tu[a:b + 1]))."""
    return [(a, min(a + BLOCK, n)) for a in range(0, n, BLOCK)]


def _slots(tu: NDArray[np.float64], h: float, out: NDArray[np.float64]) -> bool:
    """Each stamp's slot of the clock, into out: 0, then the running sum of the steps rounded to periods of h;
    whether every step is one period. The running sum continues across blocks as np.cumsum over the whole: the
    periods are whole numbers, so every partial sum is exact whatever the grouping."""
    out[0] = 0.0
    consecutive = True
    for a, b in _blocks(tu.size - 1):
        periods = np.rint(np.diff(tu[a:b + 1]) / h)
        consecutive = consecutive and bool(np.all(periods == 1.0))
        np.cumsum(periods, out=out[a + 1:b + 1])
        out[a + 1:b + 1] += out[a]
    return consecutive


def _rate(h: float) -> float:
    """1 / h, snapped to its 9 significant digits when within 1e-9 of them (1000.0000000000002 -> 1000)."""
    rate = 1.0 / h
    snapped = float(f"{rate:.9g}")
    return snapped if abs(snapped - rate) <= 1e-9 * rate else rate
