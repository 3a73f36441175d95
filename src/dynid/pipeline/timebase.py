"""A robot test's files on one uniform clock: time columns, repeated rows, jitter, gaps, two clocks, a window.

Each file is read once. A file with a time column is used on its own stamps (an `fs` in the
test's config must then agree with them); a file without one needs the test's `fs`. Per time
base (a file's rows): rows with identical stamps are averaged into one sample; stamps going
back, or a hole longer than `max_gap` sample periods, are refused with the file, line, sample
and time. The clock is q's own stamps when they are uniform, else a uniform clock at q's rate;
it is cut to the span every file covers and to the test's `start`..`end`, and every channel
not already on it is interpolated onto it (`dynid.io.align`: cubic for q, linear for tau).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from ..io import Channel, DataError, FileFormatError, GapError, Recording, TimeBaseError, align, read_recording
from ..io.align import InterpSpec
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


def read_test_file(path: Path, fs: float | None, test: str, config: Path,
                   channels: list[str] | None = None) -> tuple[Recording, bool]:
    """The file (only `channels`, when given), and whether its samples carry their own time stamps (a time
    column)."""
    rec, timed = opened(lambda fs: read_recording(path, fs=fs, channels=channels), path, fs, test, config)
    for ch in rec.channels.values():
        if ch.values.size < 2:  # a header and no data: nothing to filter or differentiate
            raise FileFormatError(f"{path}: channel {ch.name!r} has {ch.values.size} sample(s); test {test!r} needs "
                                  "a record (is the file empty or cut short?)", source=str(path))
    return rec, timed


def stream(chans: list[Channel], source: str, timed: bool, max_gap: float,
           window: tuple[float | None, float | None] = (None, None)) -> Stream:
    """The channels (one time base) with repeated stamps averaged, checked for stamps going back and holes;
    with a window (start, end), only the rows from just before start to just after end."""
    t, lines = chans[0].time, chans[0].lines
    offset = 0  # of the first row kept, for messages
    if timed and window != (None, None) and t.size > 2:
        margin = 2 * max_gap * float(np.median(np.abs(np.diff(t))))
        lo = -np.inf if window[0] is None else window[0] - margin
        hi = np.inf if window[1] is None else window[1] + margin
        inside = np.flatnonzero((t >= lo) & (t <= hi))
        if inside.size and (inside[0] > 0 or inside[-1] < t.size - 1):
            rows = slice(int(inside[0]), int(inside[-1]) + 1)
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
    # lean on memory: an hour's stamps are millions of samples, and the planning pass of a long file holds only them
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
    su = np.diff(tu) if repeated else step
    h = float(np.median(su))
    big = np.flatnonzero(su > max_gap * h)
    if big.size:
        i = int(big[0])
        k = int(first[i + 1]) if first is not None else i + 1
        raise GapError(
            f"{_where(source, lines, k, float(t[k]), offset)}: no sample for {su[i] * 1e3:.4g} ms before it (from "
            f"t = {float(tu[i]):.6g} s), {su[i] / h:.3g} sample periods at {1 / h:.6g} Hz, over max_gap = {max_gap:g} "
            f"({big.size} such gap(s) in all). Keep to a part of the test without it (start, end in the test) or "
            "raise max_gap in the test if interpolating across it is acceptable",
            source=source, sample=offset + k, line=None if lines is None else int(lines[k]))
    # each step rounded to whole periods on its own: the count over the whole record (span / median step) is off
    # by several under a realistic jitter (10 % of the step over thousands of samples), which skews the rate
    periods = np.rint(su / h)
    consecutive = bool(np.all(periods == 1.0))
    slots = np.empty(tu.size)
    slots[0] = 0.0
    np.cumsum(periods, out=slots[1:])
    del periods
    # the logger's clock: the stamps' least-squares line t = t0 + h slot, in closed form about the means
    s_mean, t_mean = float(slots.mean()), float(tu.mean())
    centred = slots - s_mean
    h = float(centred @ (tu - t_mean) / (centred @ centred))
    del centred
    t0 = t_mean - h * s_mean
    jitter = slots * h  # then tu - t0 - slots h, in place
    np.subtract(tu, jitter, out=jitter)
    jitter -= t0
    worst = float(max(jitter.max(), -jitter.min()))
    uniform = bool(worst <= UNIFORM * h and consecutive)
    return Stream(source, timed, tu, {c.name: c for c in chans}, h, uniform, t0, repeated,
                  float(np.sqrt(jitter @ jitter / jitter.size)), worst, float(np.max(su)))


def on_one_clock(
    wanted: dict[str, tuple[Path, list[str]]],
    fs: float | None,
    *,
    test: str,
    config: Path,
    start: float | None = None,
    end: float | None = None,
    max_gap: float = 10.0,
    say: Callable[[str], None] = lambda _m: None,
) -> tuple[float, dict[str, list[Channel]]]:
    """{quantity: (file, channel names)} -> (rate, {quantity: channels on one uniform clock, file units}).

    The first quantity sets the clock (module docstring)."""
    records: dict[Path, tuple[Recording, bool]] = {}
    streams: list[Stream] = []
    home: dict[tuple[str, str], Stream] = {}
    for quantity, (path, names) in wanted.items():
        if path not in records:
            records[path] = read_test_file(path, fs, test, config)
        rec, timed = records[path]
        for name in names:
            ch = rec.channel(name)
            s = next((s for s in streams if s.source == rec.label and name in s.channels), None)
            if s is None:
                same = [c for c in rec.channels.values() if c.time is ch.time or np.array_equal(c.time, ch.time)]
                needed = {n for _, (p, ns) in wanted.items() if p == path for n in ns}
                s = stream([c for c in same if c.name in needed], rec.label, timed, max_gap, (start, end))
                streams.append(s)
                if timed:
                    say(f"{test}: {s.report()}")
            home[quantity, name] = s
    for s in streams:
        if s.timed and fs is not None and abs(1 / s.h - fs) > RATE_TOLERANCE * fs:
            raise DataError(
                f"{config}: test {test!r} gives fs = {fs:g} Hz but the time column of {s.source} says "
                f"{1 / s.h:.6g} Hz (step {s.h * 1e3:.6g} ms): remove fs from the test (the time column is used), or "
                "correct it (a time column in ms needs its unit in the header, e.g. \"time [ms]\")", source=s.source)
    ref = home[next(iter(wanted)), wanted[next(iter(wanted))][1][0]]
    first = np.ceil((ref.t[0] - ref.t0) / ref.h)
    clock = ref.t if ref.uniform else ref.t0 + ref.h * np.arange(first, np.floor((ref.t[-1] - ref.t0) / ref.h) + 1)
    lo, hi = max(s.t[0] for s in streams), min(s.t[-1] for s in streams)
    if lo > hi:
        spans = "; ".join(f"{q} ({p}) covers {home[q, ns[0]].t[0]:.6g}..{home[q, ns[0]].t[-1]:.6g} s"
                          for q, (p, ns) in wanted.items())
        raise DataError(f"{config}: test {test!r}: the files do not overlap in time: {spans}. Are they from the "
                        "same test, and stamped by the same clock?")
    tol = 1e-9 * max(abs(hi), ref.h)
    for k, v in (("start", start), ("end", end)):
        if v is not None and not lo - tol <= v <= hi + tol:
            raise DataError(f"{config}: test {test!r}: {k} = {v:g} s is outside the record, which covers "
                            f"{lo:.6g}..{hi:.6g} s (in every file); give a time inside it")
    a = lo if start is None else max(lo, start)
    b = hi if end is None else min(hi, end)
    clock = clock[(clock >= a - tol) & (clock <= b + tol)]
    clock = clock[(clock >= lo) & (clock <= hi)]
    if len(streams) > 1 and (ref.t[0] < lo - tol or ref.t[-1] > hi + tol):
        say(f"{test}: the files overlap over {lo:.6g}..{hi:.6g} s: that span is used")
    specs = [InterpSpec(f"{q}:{n}", home[q, n].channels[n], "cubic" if q == "q" else "linear")
             for q, (_, ns) in wanted.items() for n in ns]
    if any(not s.uniform or not (s.t is ref.t or np.array_equal(s.t, ref.t)) for s in streams):
        say(f"{test}: every channel on one uniform {1 / ref.h:.6g} Hz clock, {clock.size} samples "
            f"({clock[0]:.6g}..{clock[-1]:.6g} s)")
    al = align(specs, t=clock, source=ref.source, gap_factor=None)
    out = {q: [Channel(n, home[q, n].channels[n].unit, al[f"{q}:{n}"], al.t) for n in ns]
           for q, (_, ns) in wanted.items()}
    return (_rate(ref.h) if ref.timed or fs is None else fs), out


def _rate(h: float) -> float:
    """1 / h, snapped to its 9 significant digits when within 1e-9 of them (1000.0000000000002 -> 1000)."""
    rate = 1.0 / h
    snapped = float(f"{rate:.9g}")
    return snapped if abs(snapped - rate) <= 1e-9 * rate else rate
