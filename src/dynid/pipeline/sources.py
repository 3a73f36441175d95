"""What a car test reads, planned once and read a segment at a time.

`plan_car_test` makes one pass over a logger file that keeps only its time stamps (a few bytes
per sample whatever the number of channels): per time base (a logging rate) the stamps are
checked as `timebase.stream` checks them (stamps going back, holes over `max_gap`, repeated
stamps, jitter), the clock of the fastest channels is chosen and cut to the span every channel
covers and the test's start..end, and the clock is split into overlapping segments. The plan is
small and picklable: with a file index (`dynid.io.windows`), any process that can reach the
file reads one segment's time window itself (`read_segment`), so peak memory follows the
segment's length, not the file's. A Parquet file's clock that is its own stamps is not held by
the plan (8 bytes a sample) but left in the file (`FileClock`), a segment's read back with it; a
Parquet log of one time base is checked a row group at a time (`_stream_in_blocks`: the planning
pass's memory a block's, whatever the log's length), any other file's stamps held whole.

On a file whose channels share one uniform clock (a logger's usual export) a segment's samples
are the file's own, bit for bit; on jittered or multi-rate files each segment is resampled onto
its slice of the uniform clock from the samples around it (a margin of several steps each side).
"""

from __future__ import annotations

import bisect
import dataclasses
import math
import re
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from ..dynamics import load_model
from ..io import Channel, DataError, FileFormatError, align, format_of, to_si, unit_factor
from ..io.align import InterpSpec
from ..io.rosbag_format import first_joints, is_bag
from ..io.units import same_unit
from ..io.windows import FileIndex, index_file, one_time_base, read_window, stamp_blocks, stamp_rows, time_bases
from ..model.tree import PRISMATIC, ModelError, Tree
from .config import ConfigError, IdentifyConfig, TestSpec
from .heap import arrow_system_pool
from .robot import DataJoints, data_joints
from .timebase import RATE_TOLERANCE, UNIFORM, Stream, _rate, opened, stream

Progress = Callable[[str], None]
# steps of the slowest base read beyond a window's ends, besides the longest hole the plan allows: a not-a-knot cubic's
# end effect decays by ~0.27 a knot, so 20 knots leave 1e-11 of the local interpolation error (8 left 3e-5)
MARGIN_STEPS = 20


def window_margin(max_gap: float, steps: Sequence[float]) -> float:
    """Seconds read beyond a window's ends: MARGIN_STEPS samples even across a hole of max_gap periods."""
    return (MARGIN_STEPS + float(np.ceil(max_gap))) * max(steps)


@dataclass(frozen=True)
class CarTestPlan:
    """One test's file, channels and clock, and its segments (clock sample ranges, overlapping by the filter's
    borders). `clock` stays with the client (a Parquet file's stays in the file: `FileClock`); a segment's job
    carries its own slice."""

    test: str
    role: str
    index: FileIndex
    file_names: tuple[str, ...]  # the channels read from the file
    quantity_names: dict[str, str]  # quantity (the suite's channel) -> file channel
    factors: dict[str, float]  # quantity -> factor to SI
    clock: NDArray[np.float64] | FileClock  # the file's own stamps stay in the file (`FileClock`)
    fs: float
    timed: bool
    max_gap: float
    base_steps: tuple[float, ...]  # each time base's step, s (their number tells a multi-rate file)
    segments: tuple[tuple[int, int], ...]
    # each segment's first and last stamp, s (taken while the plan held the clock): where its window's read starts
    # and ends without its stamps, and the parts of the test the segments' health answers for
    spans: tuple[tuple[float, float], ...] = ()

    @property
    def samples(self) -> int:
        return int(self.clock.size)


@dataclass(frozen=True)
class SegmentWindow:
    """What one segment reads: the file, its channels, and its slice of the clock (a `FileClock`'s still in the
    file: `clock_read` reads it, `read_segment` too)."""

    test: str
    index: FileIndex
    file_names: tuple[str, ...]
    quantity_names: dict[str, str]
    factors: dict[str, float]
    clock: NDArray[np.float64] | FileClock
    fs: float  # the test's rate (the same for every segment)
    timed: bool
    max_gap: float
    margin: float  # s
    first: int = 0  # the clock slice's first sample in the test (messages name the test's samples)
    # the slice's first and last stamp when the plan knows them (a segment's): a file's clock then read after the
    # window, from the blocks that read decoded, not by a read of its own (each opens the file)
    span: tuple[float, float] | None = None

    def read(self) -> dict[str, NDArray[np.float64]]:
        """{quantity: values on the clock slice, SI}."""
        return read_segment(self)


def _time_bases(index: FileIndex, names: Sequence[str], test: str
                ) -> tuple[list[tuple[list[str], NDArray, NDArray | None]], dict[str, str]]:
    """`time_bases` of the file, each channel's unit, and a channel without two samples refused."""
    bases = time_bases(index, names)
    counts = dict.fromkeys(names, 0)
    for members, t, _ in bases:
        for n in members:
            counts[n] = t.size
    for name, n in counts.items():
        if n < 2:  # a header and no data: nothing to filter or differentiate
            raise FileFormatError(f"{index.path}: channel {name!r} has {n} sample(s); test {test!r} needs a record "
                                  "(is the file empty or cut short?)", source=index.path)
    return bases, {n: index.units.get(n, "") for n in names}


def _test_clock(ref, streams: Sequence, cfg: IdentifyConfig, spec: TestSpec, record: str, covered: str,
                apart: Callable[[], str]) -> NDArray[np.float64]:
    """The test's clock: the reference base's stamps when uniform, else a uniform clock at its rate, cut to the
    span every base covers and to the test's start..end. Bases that do not overlap (apart(): their spans), or a
    start or end outside the record, are refused."""
    lo, hi = max(s.t[0] for s in streams), min(s.t[-1] for s in streams)
    if lo > hi:
        raise DataError(f"{cfg.path}: test {spec.name!r}: {apart()}", source=ref.source)
    tol = 1e-9 * max(abs(hi), ref.h)
    for key, v in (("start", spec.start), ("end", spec.end)):
        if v is not None and not lo - tol <= v <= hi + tol:
            raise DataError(f"{cfg.path}: test {spec.name!r}: {key} = {v:g} s is outside {record}, which covers "
                            f"{lo:.6g}..{hi:.6g} s ({covered}); give a time inside it", source=ref.source)
    a = lo if spec.start is None else max(lo, spec.start)
    b = hi if spec.end is None else min(hi, spec.end)
    h = ref.h
    if isinstance(ref.t, FileClock):  # its rows in the cut, from the blocks at its ends (the stamps increase)
        return _rows_between(ref.t, max(a - tol, lo), min(b + tol, hi))
    clock = ref.t if ref.uniform else ref.t0 + h * np.arange(np.ceil((ref.t[0] - ref.t0) / h),
                                                             np.floor((ref.t[-1] - ref.t0) / h) + 1)
    return clock[(clock >= max(a - tol, lo)) & (clock <= min(b + tol, hi))]


def channel_unit(cfg: IdentifyConfig, quantity: str, channel: str, file_unit: str, source: str) -> str:
    """The unit a channel is read in: the config's [channels] unit, else the file's. A config unit that contradicts
    the file's own is refused (deg over a file's rad scaled a robot's inertias by 57 with a 0.02 % residual), unless
    the entry says unit_over_file = true (the file's header is what is wrong)."""
    spec = cfg.channels.get(quantity)
    if spec is None or spec.unit is None:
        return file_unit
    if file_unit.strip() and not spec.unit_over_file and _contradict(file_unit, spec.unit):
        raise ConfigError(f"{source}: channel {channel!r} is in {file_unit!r} by the file, in {spec.unit!r} by "
                          f"{cfg.path} [channels.{quantity}]: remove that unit to read the file's, or, if the file's "
                          "header is what is wrong, add unit_over_file = true to that entry")
    return spec.unit


def _contradict(a: str, b: str) -> bool:
    """Two known units of one kind that differ (deg and rad); unknown or of different kinds (the config's unit is
    then checked against the quantity, with its own message): no."""
    try:
        (fa, sa), (fb, sb) = unit_factor(a), unit_factor(b)
    except DataError:
        return False
    return sa == sb and not same_unit(a, b) and not math.isclose(fa, fb, rel_tol=1e-12)


def plan_car_test(cfg: IdentifyConfig, spec: TestSpec, wanted: Sequence[str], units: dict[str, str],
                  segment_s: float | None, border: Callable[[float], int], progress: Progress | None = None
                  ) -> CarTestPlan:
    """The test's file indexed and its clock planned (module doc). wanted: the sensor suite's quantities;
    units: each quantity's own unit (its dimension is what the file's channel must have); segment_s: the
    segments' length, s (None: one segment); border(fs): the filter's border in samples, by which consecutive
    segments overlap at each end."""
    say = progress or (lambda _m: None)
    path = spec.files["channels"]
    renamed = {q: (c.channels[0], c.unit) for q, c in cfg.channels.items()}
    in_file = {q: renamed.get(q, (q, None))[0] for q in wanted}
    names = list(dict.fromkeys(in_file.values()))
    given = None if format_of(path) == "mdf" else spec.fs  # an MDF file's channels always carry their time stamps
    index, timed = opened(lambda fs: index_file(path, channels=names, fs=fs), path, given, spec.name, cfg.path)
    label = str(path)
    # a Parquet log of one time base is checked a block at a time, its clock left in the file; else (or where
    # that pass answers None) its stamps are held whole
    in_blocks = _stream_in_blocks(index, label, spec.max_gap, (spec.start, spec.end)) if (
        timed and index.rows > 2 and one_time_base(index, names)) else None
    if in_blocks is None:
        streams, file_units = _streams_held(index, names, spec.name, label, timed, spec.max_gap, (spec.start, spec.end))
    else:
        streams, file_units = [(names, in_blocks[0])], {n: index.units.get(n, "") for n in names}
    if timed:
        for members, s in streams:
            listed = ", ".join(members[:3]) + (", ..." if len(members) > 3 else "")
            say(f"{spec.name}: {s.report()}" + (f" ({len(members)} channels: {listed})" if len(streams) > 1 else ""))
    fastest = min(s.h for _, s in streams)  # the clock: the fastest channels' (the most of them at one rate)
    ref = max(((m, s) for m, s in streams if s.h <= fastest * (1 + 1e-6)), key=lambda ms: len(ms[0]))[1]
    h = ref.h
    if timed and spec.fs is not None and abs(1 / h - spec.fs) > RATE_TOLERANCE * spec.fs:
        raise DataError(
            f"{cfg.path}: test {spec.name!r} gives fs = {spec.fs:g} Hz but the time stamps of {label} say "
            f"{1 / h:.6g} Hz (step {h * 1e3:.6g} ms): remove fs from the test (the time stamps are used), or correct "
            "it (a time column in ms needs its unit in the header, e.g. \"time [ms]\")", source=label)
    clock = _test_clock(ref, [s for _, s in streams], cfg, spec, f"the record {label}", "every channel",
                        lambda: "the channels do not overlap in time: " + "; ".join(
                            f"{', '.join(m[:2])}, ... cover {s.t[0]:.6g}..{s.t[-1]:.6g} s" for m, s in streams))
    if clock.size < 2:
        raise DataError(f"{cfg.path}: test {spec.name!r}: no two samples of {label} between start and end "
                        f"({spec.start}..{spec.end} s at {1 / h:.6g} Hz): widen the window", source=label)
    if len(streams) > 1:
        rates = ", ".join(f"{1 / s.h:.6g} Hz ({len(m)})" for m, s in sorted(streams, key=lambda ms: ms[1].h))
        say(f"{spec.name}: channels at several rates in {label}: {rates}; every channel interpolated onto the "
            f"{1 / h:.6g} Hz clock of the fastest, {clock.size} samples ({clock[0]:.6g}..{clock[-1]:.6g} s)")
    elif not ref.uniform:
        say(f"{spec.name}: every channel on one uniform {1 / h:.6g} Hz clock, {clock.size} samples "
            f"({clock[0]:.6g}..{clock[-1]:.6g} s)")
    steps = tuple(s.h for _, s in streams)
    # the file's stamps let go once the clock is cut from them (a copy), and the median's differences partitioned
    # in place: the plan's pass peaked at 4 arrays of the log's length here (0.43 GB at 6 h of 625 Hz)
    streams.clear()
    del ref, s
    factors = {}
    for q, name in in_file.items():
        unit = channel_unit(cfg, q, name, file_units.get(name, ""), label)
        expect = (unit_factor(units[q])[1],) if q in units else None
        factors[q] = unit_factor(unit, channel=name, source=label, expect=expect)[0]
    if not isinstance(clock, FileClock):
        fs = 1.0 / float(np.median(np.diff(clock), overwrite_input=True))
    elif in_blocks is not None and (clock.first, clock.size) == (in_blocks[0].t.first, in_blocks[0].t.size):
        fs = 1.0 / in_blocks[1]  # the clock is the whole base: its steps' median is the base's
    else:
        fs = 1.0 / _median_step(clock)
    if cfg.car is not None:
        _below_nyquist(cfg, spec, cfg.car.cutoff, fs, timed, label)
    N = clock.size
    bd = border(fs)
    step = N if segment_s is None else max(int(segment_s * fs), 4 * bd)
    segments = tuple((s, min(N, s + step + 2 * bd)) for s in range(0, max(N - 2 * bd, 1), step))
    ends = clock_at(clock, [k for lo, hi in segments for k in (lo, hi - 1)]).tolist()
    spans = tuple(zip(ends[::2], ends[1::2], strict=True))
    # a Parquet file's stamps left in it: the plan's size not the log's length's
    kept = clock if isinstance(clock, FileClock) else _file_clock(index, clock)
    return CarTestPlan(spec.name, spec.role, index, tuple(names), in_file, factors, clock if kept is None else kept,
                       fs, timed, spec.max_gap, steps, segments, spans)


def _streams_held(index: FileIndex, names: list[str], test: str, label: str, timed: bool, max_gap: float,
                  window: tuple[float | None, float | None]) -> tuple[list[tuple[list[str], Stream]], dict[str, str]]:
    """Each time base of the file checked (`timebase.stream`) on its stamps held whole: [(members, Stream)], and
    each channel's unit."""
    streams = []
    bases, file_units = _time_bases(index, names, test)
    while bases:  # each base's stamps let go with its stream's (a stream holds them, or its merged ones)
        members, t, lines = bases.pop(0)
        clock_only = Channel("time", "s", t, t, lines)  # the stamps stand for the base's channels in the checks
        streams.append((members, stream([clock_only], label, timed, max_gap, window)))
    return streams, file_units


# distinct steps counted exactly: a logger's clock takes few (its step and the stamps' float rounding: 26 in the 13.5 M
# steps of 6 h at 625 Hz); a log of more (a jittered clock: not uniform, its clock resampled) has its stamps held whole
DISTINCT_STEPS = 4096


class _StepCounts:
    """The time steps of a log as {value: count}: their median the bits of np.median's (the middle value, or the
    mean of the two middle ones) in O(distinct values) memory."""

    def __init__(self) -> None:
        self.counts: dict[float, int] = {}
        self.n = 0

    def add(self, steps: NDArray[np.float64]) -> bool:
        """Counted; False past DISTINCT_STEPS distinct values."""
        values, counts = np.unique(steps, return_counts=True)
        if values.size > DISTINCT_STEPS:  # a jittered clock: told at its first block, not counted
            return False
        for v, c in zip(values.tolist(), counts.tolist(), strict=True):
            self.counts[v] = self.counts.get(v, 0) + c
        self.n += steps.size
        return len(self.counts) <= DISTINCT_STEPS

    def median(self) -> float:
        order = sorted(self.counts.items())

        def kth(k: int) -> float:  # the k-th smallest, from 0
            seen = 0
            for v, c in order:
                seen += c
                if k < seen:
                    return v
            raise IndexError(k)

        m = self.n // 2
        return kth(m) if self.n % 2 else (kth(m - 1) + kth(m)) / 2


def _stamp_steps(index: FileIndex, lo: int, hi: int) -> Iterator[tuple[int, NDArray, NDArray]]:
    """(first row, stamps, the steps into them) of the rows lo..hi a block at a time (the first row's step left
    out: a block's steps follow from the previous block's last stamp)."""
    last = None
    for row, t in stamp_blocks(index, lo, hi):
        if t.size:
            steps = np.diff(t) if last is None else np.diff(t, prepend=last)
            last = t[-1]
            yield row, t, steps


def _stream_in_blocks(index: FileIndex, label: str, max_gap: float, window: tuple[float | None, float | None]
                      ) -> tuple[Stream, float] | None:
    """`timebase.stream` of a Parquet file's one time base from passes over its blocks, its stamps left in the file
    (the Stream's t a `FileClock`), and the median step: O(blocks) memory whatever the log's length. None where
    that stream would not be the file's own uniform clock (stamps not finite, going back or repeated, a hole, a
    skipped sample, steps of over DISTINCT_STEPS values, jitter): the caller then checks the stamps held whole, as
    before (the same errors, the same resampled clock). The same numbers as `stream`'s but the fitted line's,
    whose sums are taken in blocks (the whole-array dot's bits depend on BLAS's threads: 1 and 2 differ)."""
    a, z = 0, index.rows  # the rows checked: the window's, as `stream` cuts them
    if window != (None, None):
        counts = _StepCounts()
        for _, t, steps in _stamp_steps(index, 0, z):
            if not (np.isfinite(t).all() and (steps >= 0.0).all() and counts.add(steps)):
                return None
        margin = 2 * max_gap * counts.median()
        lo = -np.inf if window[0] is None else window[0] - margin
        hi = np.inf if window[1] is None else window[1] + margin
        # the stamps checked finite and increasing: each block's extremes (the index's) are its ends
        cut = _rows_between(FileClock(index, 0, z), lo, hi)
        if cut.size:  # else no stamp in the window: `stream` keeps every row (the test's start, end refused)
            a, z = cut.first, cut.first + cut.size
    n = z - a
    if n < 3:
        return None
    # the clock's line t = t0 + h k over the slots k = 0..n-1 (every step one period, checked below), in closed form
    # about the slots' mean (n - 1) / 2 (exact): sum((k - mean) t) taken about the first stamp (the same sum: the
    # centred slots sum to 0), in this pass
    counts, sums, cds, least, largest = _StepCounts(), [], [], np.inf, -np.inf
    s_mean, origin = (n - 1) / 2, None
    for r, t, steps in _stamp_steps(index, a, z):
        if not (np.isfinite(t).all() and counts.add(steps)):
            return None
        origin = float(t[0]) if origin is None else origin
        sums.append(float(np.sum(t)))
        cds.append(float(np.sum((np.arange(r - a, r - a + t.size) - s_mean) * (t - origin))))
        if steps.size:
            least, largest = min(least, float(steps.min())), max(largest, float(steps.max()))
    h_step = counts.median()
    # rint(step / h) is monotonic in the step: every step one period when the least and the largest are
    periods = (np.rint(least / h_step), np.rint(largest / h_step))
    if not (least > 0.0 and largest <= max_gap * h_step and periods == (1.0, 1.0)):
        return None
    t_mean = math.fsum(sums) / n
    cc = float(Fraction(n * (n * n - 1), 12))  # the centred slots' squares' sum, exactly rounded
    cd = math.fsum(cds)
    h = cd / cc
    t0 = t_mean - h * s_mean
    worst, squares = 0.0, []
    for r, t, _ in _stamp_steps(index, a, z):
        jitter = t - np.arange(r - a, r - a + t.size) * h  # `stream`'s order: t - slot h - t0
        jitter -= t0
        worst = max(worst, float(jitter.max()), float(-jitter.min()))
        squares.append(float(np.sum(jitter * jitter)))  # numpy's own sum: no BLAS threads' order
    if not worst <= UNIFORM * h:
        return None
    return Stream(label, True, FileClock(index, a, n), {}, h, True, t0, 0, math.sqrt(math.fsum(squares) / n), worst,
                  largest), h_step


def _rows_between(clock: FileClock, lo: float, hi: float) -> FileClock:
    """The rows of a file's clock (its stamps increasing) whose stamps are within lo..hi, from the blocks that hold
    its first and last: `clock[(clock >= lo) & (clock <= hi)]` left in the file."""
    parts = []  # the blocks' (first row, rows, least and largest stamp) within the clock's rows
    row = 0
    for b in clock.index.blocks:
        r0, r1 = max(row, clock.first), min(row + b.rows, clock.first + clock.size)
        if r0 < r1:
            parts.append((r0, r1, b.t_min, b.t_max))
        row += b.rows
    first = next((r + int(np.searchsorted(stamp_rows(clock.index, r, e, store=False), lo))
                  for r, e, _, t1 in parts if t1 >= lo), clock.first + clock.size)
    end = next((r + int(np.searchsorted(stamp_rows(clock.index, r, e, store=False), hi, side="right"))
                for r, e, t0, _ in reversed(parts) if t0 <= hi), clock.first)
    return clock.cut(first - clock.first, max(first, end) - clock.first)


def _median_step(clock: FileClock) -> float:
    """np.median of a file's clock's steps, counted a block at a time (the clock cut from a base of few)."""
    counts = _StepCounts()
    for _, _, steps in _stamp_steps(clock.index, clock.first, clock.first + clock.size):
        counts.add(steps)
    return counts.median()


def _below_nyquist(cfg: IdentifyConfig, spec: TestSpec, cutoff: float, fs: float, timed: bool, file: str) -> None:
    """The [conditioning] cutoff must be below the test's Nyquist frequency: refused naming the config, the file and
    its sample rate, with the likely slip (a time column in ms read as s; an fs in kHz)."""
    if cutoff < fs / 2:
        return
    lower = f"lower the cut-off below {fs / 2:.6g} Hz"
    if timed and fs <= 2.0:  # steps of 0.5 s or more: a logger's ms (or µs) read as s
        why = (f"{file}'s time stamps step by {1 / fs:.6g} s ({fs:.6g} Hz): is its time column in ms? give its unit "
               f"in the header (\"time [ms]\"), else {lower}")
    elif timed:
        why = f"{file}'s time stamps step by {1 / fs:.6g} s ({fs:.6g} Hz); {lower}"
    else:
        why = f"the test's fs = {fs:g} Hz (no time column in {file}): give fs in Hz (not kHz), else {lower}"
    raise ConfigError(f"{cfg.path}: [conditioning] cutoff = {cutoff:g} Hz is not below the Nyquist frequency "
                      f"fs/2 = {fs / 2:.6g} Hz of test {spec.name!r}: {why}")


def segment_window(plan: CarTestPlan, lo: int, hi: int) -> SegmentWindow:
    """What the segment lo..hi of the plan's clock reads (picklable, small: its clock slice, or its rows of the
    file's, and the index)."""
    margin = window_margin(plan.max_gap, plan.base_steps)
    k = bisect.bisect_left(plan.segments, (lo, hi))  # the segments in order: a segment's window knows its span
    span = plan.spans[k] if k < len(plan.spans) and plan.segments[k] == (lo, hi) else None
    return SegmentWindow(plan.test, plan.index, plan.file_names, plan.quantity_names, plan.factors,
                         _clock_cut(plan.clock, lo, hi), plan.fs, plan.timed, plan.max_gap, margin, lo, span)


def segment_edges(plan: CarTestPlan) -> list[tuple[float, float, bool]]:
    """The part of the test each segment answers for (its data health): (t_start, t_end, end included), from its
    first stamp to the next segment's first; the last to the test's end."""
    n = len(plan.segments)
    return [(a, plan.spans[i + 1][0] if i + 1 < n else b, i + 1 == n) for i, (a, b) in enumerate(plan.spans)]


def read_segment(w: SegmentWindow, si: bool = True, file_samples: dict[str, Channel] | None = None
                 ) -> dict[str, NDArray[np.float64]]:
    """{quantity: values on the window's clock slice, SI (or the file's unit)}: the file's samples around the slice,
    repeated stamps merged, each channel not already on the clock interpolated onto it (cubic). file_samples: a dict
    to receive {file channel: its samples as read (file unit, own stamps; the slice's, or around it when
    interpolated)}, the data health's scan (`pipeline.health.segment_health`). A channel whose factor to SI is 1 is
    given as read, not multiplied (x * 1.0 is x to the bit): a read-only view where it is the file's samples (the
    product's fresh array cost a sixth of a segment's read, in page faults)."""
    al = _resampled(w.index, w.file_names, w.clock, w.margin, w.timed, w.first, lambda _n: "cubic", file_samples,
                    w.span)
    return {q: al[name] * w.factors[q] if si and w.factors[q] != 1.0 else al[name]
            for q, name in w.quantity_names.items()}


def _resampled(index: FileIndex, names: Sequence[str], clock: NDArray[np.float64] | FileClock, margin: float,
               timed: bool, first: int, kind: Callable[[str], str], file_samples: dict[str, Channel] | None = None,
               span: tuple[float, float] | None = None):
    """The channels on the clock slice (`dynid.io.align`), from the window of the file around it: per time base,
    repeated stamps merged (the plan checked the stamps: no gap is refused here, where a window's own median step
    could differ), the samples on the clock used as they are, the others interpolated (kind(name)); the samples
    used put in file_samples when given. span: the clock's first and last stamp, if known (a file's clock is then
    read after the window, from the blocks it decoded)."""
    if span is None and isinstance(clock, FileClock):
        clock = clock[0:clock.size]
    a, b = span if span is not None else (float(clock[0]), float(clock[-1]))
    rec = read_window(index, list(names), a - margin, b + margin)
    clock = clock[0:clock.size] if isinstance(clock, FileClock) else clock
    specs, exact = [], True
    with _samples_of_the_test(first, True):
        for members in _shared_bases(rec, names):
            s = stream(members, rec.label, timed, np.inf, fit=False)  # the plan fitted the base's clock
            cut = _on_clock(s, clock)
            exact = exact and cut is not None
            specs += [InterpSpec(n, c, kind(n)) for n, c in (cut or s.channels).items()]
            if file_samples is not None:
                file_samples.update(cut or s.channels)
    with _samples_of_the_test(first, exact):
        return align(specs, t=clock, source=rec.label, gap_factor=None)


@contextmanager
def _samples_of_the_test(first: int, exact: bool) -> Iterator[None]:
    """A bad sample found in a window named by its sample in the whole test. The window counts from 0: on the
    clock (exact) its count is shifted by the slice's first sample; a channel being interpolated counts its own
    file rows from the window's margin, so the count is dropped and the time (and line) name the sample."""
    try:
        yield
    except DataError as exc:
        if exc.sample is None or (exact and not first):
            raise
        if exact:
            text = re.sub(r"\bsample (\d+)", lambda m: f"sample {int(m.group(1)) + first}", str(exc))
            exc.sample += first
        else:
            text = re.sub(r"\bsample \d+ \(t = ([^)]*)\)", r"t = \1", str(exc))
            text = re.sub(r"\bsample \d+", "a sample", text)
            exc.sample = None
        exc.args = (text,)
        raise


def _shared_bases(rec, names: Sequence[str]) -> list[list[Channel]]:
    """The recording's channels `names`, grouped by their time stamps."""
    bases: list[list[Channel]] = []
    for name in names:
        ch = rec.channel(name)
        base = next((b for b in bases if b[0].time is ch.time or np.array_equal(b[0].time, ch.time)), None)
        if base is None:
            bases.append([ch])
        else:
            base.append(ch)
    return bases


def _on_clock(s, clock: NDArray[np.float64]) -> dict[str, Channel] | None:
    """A stream's channels cut to the clock's samples when every clock instant is one of its stamps (used as they
    are, bit for bit), else None (to be interpolated)."""
    t = s.t
    k0 = int(np.searchsorted(t, clock[0]))
    if np.array_equal(t[k0:k0 + clock.size], clock):  # the usual case, consecutive stamps: no search of each instant
        rows = slice(k0, k0 + clock.size)
    else:
        k = np.searchsorted(t, clock)
        rows = (slice(int(k[0]), int(k[-1]) + 1) if k[-1] < t.size and np.array_equal(t[np.minimum(k, t.size - 1)],
                                                                                        clock) else None)
    if rows is not None:
        # one time array (and one lines array) shared by the channels, as in the stream: `align` checks a
        # time base once per array, not once per channel
        tr, lines = t[rows], {}
        return {n: Channel(n, c.unit, c.values[rows], tr,
                           None if c.lines is None else lines.setdefault(id(c.lines), c.lines[rows]))
                for n, c in s.channels.items()}
    return None


# ----------------------------------------------------------------------------------- a clock left in its file
@dataclass(frozen=True)
class FileClock:
    """A clock that is the rows first..first + size of a Parquet file's stamps, read back from the file when asked
    (`io.windows.stamp_rows`: the same bits) instead of held whole: 8 bytes a sample (29 MB an hour at 1 kHz) kept
    by the plan and by the jobs cut from it while the map runs. Sliced, a window's stamps (an array); `cut`, a
    window of it still in the file."""

    index: FileIndex
    first: int
    size: int

    def __len__(self) -> int:
        return self.size

    def __getitem__(self, key: int | slice) -> NDArray[np.float64] | float:
        if isinstance(key, slice):
            lo, hi, step = key.indices(self.size)
            if step != 1:
                raise IndexError("a file's clock is read in contiguous windows")
            return stamp_rows(self.index, self.first + lo, self.first + max(lo, hi))
        k = key + self.size if key < 0 else key
        if not 0 <= k < self.size:
            raise IndexError(f"sample {key} of a clock of {self.size}")
        return float(stamp_rows(self.index, self.first + k, self.first + k + 1, store=False)[0])

    def cut(self, lo: int, hi: int) -> FileClock:
        return FileClock(self.index, self.first + lo, max(0, hi - lo))

    def at(self, samples: Sequence[int]) -> NDArray[np.float64]:
        """The stamps of the given samples (any order, negative from the end), each block holding one of them
        decoded once: a pass over the file's stamps, not one a sample (each sample's block is decoded whole)."""
        k = np.asarray(samples, dtype=np.int64)
        k = np.where(k < 0, k + self.size, k)
        if k.size and not (k.min() >= 0 and k.max() < self.size):
            raise IndexError(f"samples {list(samples)} of a clock of {self.size}")
        rows, out = k + self.first, np.empty(k.size)
        if not k.size:
            return out
        # the file opened once for them all (each open parses its footer)
        for row, part in stamp_blocks(self.index, int(rows.min()), int(rows.max()) + 1,
                                      only=lambda r, n: bool(((rows >= r) & (rows < r + n)).any())):
            inside = (rows >= row) & (rows < row + part.size)
            out[inside] = part[rows[inside] - row]
        return out


def clock_at(clock: NDArray[np.float64] | FileClock, samples: Sequence[int]) -> NDArray[np.float64]:
    """The clock's stamps of the given samples (a plan's segment edges): from a `FileClock`, in one pass."""
    return clock.at(samples) if isinstance(clock, FileClock) else clock[np.asarray(samples, dtype=np.int64)]


def _file_clock(index: FileIndex, clock: NDArray[np.float64]) -> FileClock | None:
    """The clock as rows of the file's stamps when it is (every stamp compared, a block at a time), else None."""
    if index.format != "parquet" or clock.size < 2:
        return None
    start = 0  # the clock's first row among the file's stamps
    for b in index.blocks:  # the block holding the clock's first stamp
        if b.rows and b.t_min <= clock[0] <= b.t_max:
            head = stamp_rows(index, start, start + b.rows, store=False)
            at = np.flatnonzero(head == clock[0])
            if at.size != 1:
                return None
            start += int(at[0])
            break
        start += b.rows
    else:
        return None
    # 16 blocks' stamps compared at a time, a bounded part of the clock (a read opens the file: a block at a time took
    # 2.6 s of a 6 h plan's 3.9 when each opening parsed the footer, which io.windows now keeps)
    step = 16 * max(b.rows for b in index.blocks)
    for lo in range(0, clock.size, step):
        hi = min(clock.size, lo + step)
        if not np.array_equal(stamp_rows(index, start + lo, start + hi, store=False), clock[lo:hi]):
            return None
    return FileClock(index, start, int(clock.size))


def _clock_cut(clock: NDArray[np.float64] | FileClock, lo: int, hi: int) -> NDArray[np.float64] | FileClock:
    """The clock's samples lo..hi: a file's clock stays in the file, a held one is sliced (a view)."""
    return clock.cut(lo, hi) if isinstance(clock, FileClock) else clock[lo:hi]


def clock_window(plan: RobotTestPlan, lo: int, hi: int) -> RobotTestPlan:
    """The plan cut to its clock's samples lo..hi (a job's window): a file's clock stays in the file."""
    return dataclasses.replace(plan, clock=_clock_cut(plan.clock, lo, hi), first=plan.first + lo)


Clocked = TypeVar("Clocked", "RobotTestPlan", "SegmentWindow")


def clock_read(plan: Clocked) -> Clocked:
    """The plan or window with its clock's stamps in memory (a window's, read from the file when a `FileClock`)."""
    if not isinstance(plan.clock, FileClock):
        return plan
    return dataclasses.replace(plan, clock=plan.clock[0:plan.clock.size])


# -------------------------------------------------------------------------------------------------- a robot's test
@dataclass(frozen=True)
class RobotTestPlan:
    """One robot test's files (q and its effort, tau or current; one file or two) and their clock (q's); cut to the
    samples a chunk reads (`first` onwards), what a chunk's job carries."""

    test: str
    role: str
    indexes: dict[str, FileIndex]  # quantity -> its file's index
    channels: dict[str, tuple[str, ...]]  # quantity -> its channels, one per joint
    units: dict[str, tuple[str, ...]]  # quantity -> each channel's unit (the config's, else the file's)
    clock: NDArray[np.float64] | FileClock  # the file's own stamps stay in the file (`FileClock`)
    fs: float
    timed: bool
    max_gap: float
    margin: float  # s, read beyond a window's ends (`window_margin`)
    first: int = 0  # a window's: its clock's first sample in the test

    @property
    def samples(self) -> int:
        return int(self.clock.size)

    @property
    def effort(self) -> str:
        """'current' (motor currents) or 'tau' (joint torques)."""
        return "current" if "current" in self.channels else "tau"


def plan_robot_test(cfg: IdentifyConfig, spec: TestSpec, progress: Progress | None = None) -> RobotTestPlan:
    """The robot test's files indexed and its clock planned (`timebase`'s rules: q's stamps set the clock, cut to
    the span every file covers and to start..end), from a pass over the time stamps only."""
    say = progress or (lambda _m: None)
    arrow_system_pool()  # before the first Parquet read: pyarrow's own allocator kept its arenas' pages (~30 MB)
    indexes: dict[str, FileIndex] = {}
    by_file: dict[Path, FileIndex] = {}
    streams: dict[str, list] = {}  # quantity -> [(members, Stream)] of its file's bases holding its channels
    timed = True
    reported: set[tuple[Path, tuple[str, ...]]] = set()
    bases: dict[Path, list] = {}  # file -> its time bases [(members, stamps, lines)]
    planned: dict[tuple[Path, int], Stream] = {}  # (file, base) -> its Stream
    bag = _bag_channels(cfg, spec, say) if is_bag(spec.files["q"]) or is_bag(spec.files[cfg.effort]) else None
    quantities = ("q", cfg.effort) if bag is None else ("q", "tau")
    chans = {q: tuple(cfg.channels[q].channels) for q in quantities} if bag is None else bag[1]
    if bag is not None:
        by_file[spec.files["q"]] = bag[0]
    for quantity in quantities:
        path = spec.files[quantity]
        names = list(chans[quantity])
        if path not in by_file:
            wanted = [n for q in quantities if spec.files[q] == path for n in chans[q]]
            by_file[path], timed = opened(lambda fs, p=path, w=wanted: index_file(p, channels=list(dict.fromkeys(w)),
                                                                                 fs=fs),
                                          path, spec.fs, spec.name, cfg.path)
        index = indexes[quantity] = by_file[path]
        if path not in bases:  # once per file: q and tau in one file share its stamps (29 MB an hour at 1 kHz)
            bases[path] = _time_bases(index, list(dict.fromkeys(n for q in quantities if spec.files[q] == path
                                                                for n in chans[q])), spec.name)[0]
        streams[quantity] = []
        for i, (members, t, lines) in enumerate(bases[path]):
            if not set(members) & set(names):
                continue
            if (path, i) not in planned:
                planned[path, i] = stream([Channel("time", "s", t, t, lines)], str(path), timed, spec.max_gap,
                                          (spec.start, spec.end))
            s = planned[path, i]
            streams[quantity].append((members, s))
            if timed and (path, tuple(members)) not in reported:
                reported.add((path, tuple(members)))
                say(f"{spec.name}: {s.report()}")
    every = [s for q in streams for _, s in streams[q]]
    for s in every:
        if s.timed and spec.fs is not None and abs(1 / s.h - spec.fs) > RATE_TOLERANCE * spec.fs:
            raise DataError(
                f"{cfg.path}: test {spec.name!r} gives fs = {spec.fs:g} Hz but the time column of {s.source} says "
                f"{1 / s.h:.6g} Hz (step {s.h * 1e3:.6g} ms): remove fs from the test (the time column is used), or "
                "correct it (a time column in ms needs its unit in the header, e.g. \"time [ms]\")", source=s.source)
    first_q = chans["q"][0]
    ref = next(s for m, s in streams["q"] if first_q in m)
    clock = _test_clock(ref, every, cfg, spec, "the record", "in every file", lambda: (
        "the files do not overlap in time: " + "; ".join(f"{q} ({spec.files[q]}) covers {s.t[0]:.6g}..{s.t[-1]:.6g} s"
                                                          for q in streams for _, s in streams[q][:1])
        + ". Are they from the same test, and stamped by the same clock?"))
    lo, hi = max(s.t[0] for s in every), min(s.t[-1] for s in every)
    tol = 1e-9 * max(abs(hi), ref.h)
    if len(every) > 1 and (ref.t[0] < lo - tol or ref.t[-1] > hi + tol):
        say(f"{spec.name}: the files overlap over {lo:.6g}..{hi:.6g} s: that span is used")
    if any(not s.uniform or not np.array_equal(s.t, ref.t) for s in every):
        say(f"{spec.name}: every channel on one uniform {1 / ref.h:.6g} Hz clock, {clock.size} samples "
            f"({clock[0]:.6g}..{clock[-1]:.6g} s)")
    fs = _rate(ref.h) if ref.timed or spec.fs is None else spec.fs
    _below_nyquist(cfg, spec, cfg.conditioning.cutoff, fs, ref.timed, str(spec.files["q"]))
    units = bag[2] if bag is not None else {
        q: tuple(channel_unit(cfg, q, n, indexes[q].units.get(n, ""), str(spec.files[q]))
                 for n in cfg.channels[q].channels) for q in quantities}
    margin = window_margin(spec.max_gap, [s.h for s in every])
    kept = _file_clock(indexes["q"], clock)
    return RobotTestPlan(spec.name, spec.role, indexes, chans, units, clock if kept is None else kept, fs, timed,
                         spec.max_gap, margin)


def config_joints(cfg: IdentifyConfig, tree: Tree) -> DataJoints:
    """The joints a robot config's data give (`robot.data_joints`): as many as its [transmission] q has rows, else
    its [channels] q has channels, else its ROS 2 bags name (`_bag_joints`); the others (a gripper not logged)
    held still."""
    k = (cfg.transmission["q"].shape[0] if "q" in cfg.transmission
         else len(cfg.channels["q"].channels) if "q" in cfg.channels else _bag_joints(cfg, tree))
    # a transmission's rows are the joints it gives: name it when its count is the one that does not match
    source = (f"{cfg.path}: [transmission] q ({k} rows)" if "q" in cfg.transmission
              else f"{cfg.path}: [channels.q] ({k} channels)" if "q" in cfg.channels else str(cfg.path))
    try:
        return data_joints(tree, k, cfg.joints, source)
    except ModelError as exc:
        raise ConfigError(str(exc)) from None


def _bag_joints(cfg: IdentifyConfig, tree: Tree) -> int:
    """The joint columns a config's ROS 2 bags give (a robot config without [channels]): the selected joints'
    count, else the model's joints with an equation that its first bag's first message names. When that is all
    of them less the joints others mimic (a gripper not logged), those are held still; any other count reads all
    of them, and the bag's test says which one the messages lack (`sources.plan_robot_test`)."""

    bag = next((t for t in cfg.tests if is_bag(t.files["q"])), None)
    if bag is None:
        return tree.n
    if cfg.joints is not None:
        return len(cfg.joints)
    named = set(first_joints(bag.files["q"], topic=bag.topic))
    k = sum(tree.joint_names.get(j) in named for j in tree.equations)
    masters = {m.master for m in tree.mimic.values()}
    return k if k == len(tree.equations) - len(masters) else len(tree.equations)


def _bag_channels(cfg: IdentifyConfig, spec: TestSpec, say: Progress
                  ) -> tuple[FileIndex, dict[str, tuple[str, ...]], dict[str, tuple[str, ...]]]:
    """A ROS 2 bag test's index, and its q and tau channels: each model joint's position and effort, matched by the
    names of the model's [joints] table, in SI by the joint's type (REP 103: rad or m, N·m or N)."""

    path = spec.files["q"]
    label = str(path)
    if cfg.effort == "current":
        raise ConfigError(f"{cfg.path}: test {spec.name!r} reads the ROS 2 bag {label}, whose JointState effort is "
                          "the joint torque (REP 103), but the config reads motor currents ([channels] current): "
                          "remove [channels] current and [drive], or give the currents in a table file")
    if spec.files.get("tau") != path:
        raise ConfigError(f"{cfg.path}: test {spec.name!r} reads q from {spec.files['q']} and tau from "
                          f"{spec.files.get('tau')}; a ROS 2 bag holds both: give file = \"{path.name}\"")
    index = index_file(path, topic=spec.topic)
    topic = index.info("topic")
    say(f"{spec.name}: {path.name}, topic {topic}: {index.rows} messages")
    joints = config_joints(cfg, load_model(cfg.model).tree)
    tree, columns = joints.tree, joints.columns  # the joints the data give, in column order
    model = cfg.model if isinstance(cfg.model, str) else Path(cfg.model).name
    in_bag = index.info("joints")
    unnamed = [j for j in columns if j not in tree.joint_names]
    if unnamed:
        raise ConfigError(f"{cfg.path}: test {spec.name!r} reads the bag {label}, whose joints go by name, but the "
                          f"model {model} names no joint for frame(s) {', '.join(map(str, unnamed))}: add a [joints] "
                          f"table to it (1 = \"{in_bag[0] if in_bag else 'joint name'}\", ...)")
    names = [tree.joint_names[j] for j in columns]
    known = set(tree.joint_names.values()) | set(tree.frozen)  # a joint held still may be in the messages
    ignored = set(spec.ignore_joints)
    extra = [j for j in in_bag if j not in known and j not in ignored]
    if extra:
        raise ConfigError(f"{cfg.path}: test {spec.name!r}: joint {extra[0]!r} of {label} (topic {topic}) is not a "
                          f"joint of the model {model} (its joints: {', '.join(names)}); add ignore_joints = "
                          f"{_toml_list(extra)} to the test, or name it in the model's [joints] table")
    missing = [j for j in names if j not in in_bag]
    if missing:
        raise ConfigError(f"{cfg.path}: test {spec.name!r}: the model {model}'s joint {missing[0]!r} is not in the "
                          f"messages of {label} (topic {topic}; joints there: {', '.join(in_bag)}); make the "
                          "model's [joints] table use the bag's names, record that joint, or choose the identified "
                          "joints with [model] joints = [...] (the others are held still)")
    have = set(index.names)
    for field, quantity in (("position", "q"), ("effort", "tau")):
        lacking = [j for j in names if f"{j}.{field}" not in have]
        if lacking:
            raise ConfigError(f"{cfg.path}: test {spec.name!r}: the messages of {label} (topic {topic}) have no "
                              f"{field} for joint {lacking[0]!r} (its {field} arrays are empty); {quantity} needs "
                              f"it: record a JointState with {field}")
    chans = {"q": tuple(f"{j}.position" for j in names), "tau": tuple(f"{j}.effort" for j in names)}
    prismatic = [tree.frames[j - 1].sigma == PRISMATIC for j in columns]
    units = {"q": tuple("m" if p else "rad" for p in prismatic), "tau": tuple("N" if p else "N*m" for p in prismatic)}
    keep = set(chans["q"]) | set(chans["tau"])
    index = dataclasses.replace(index, channels=tuple((n, u) for n, u in index.channels if n in keep))
    return index, chans, units


def _toml_list(names: Sequence[str]) -> str:
    return "[" + ", ".join(f'"{n}"' for n in names) + "]"


def transmitted(cfg: IdentifyConfig, q: np.ndarray, tau: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The joints' q and tau from the channels' (SI): q = Nq q_file + q_offset, tau = Nt tau_file."""
    shapes = {"q": (n, q.shape[1]), "q_offset": (n,), "tau": (n, tau.shape[1])}
    for key, m in cfg.transmission.items():
        if m.shape != shapes[key]:
            raise ConfigError(f"{cfg.path}: [transmission] {key} is {' x '.join(map(str, m.shape))}; it must be "
                              f"{' x '.join(map(str, shapes[key]))} ({n} joints of the model"
                              + ("" if key == "q_offset" else f", {shapes[key][1]} channels of {key} in [channels]")
                              + ")")
    if "q" in cfg.transmission:
        q = q @ cfg.transmission["q"].T
    if "q_offset" in cfg.transmission:
        q = q + cfg.transmission["q_offset"]
    if "tau" in cfg.transmission:
        tau = tau @ cfg.transmission["tau"].T
    for name, a in (("q", q), ("tau", tau)):
        if a.shape[1] != n:
            after = f" after [transmission] {name}" if name in cfg.transmission else ""
            raise ConfigError(f"{cfg.path}: [channels.{name}] gives {a.shape[1]} channels{after}; the model has {n} "
                              f"joints: list one channel per joint (or map them with [transmission] {name})")
    return q, tau


def driven(cfg: IdentifyConfig, q: np.ndarray, effort: np.ndarray, n: int
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The joints' q, the joint torques known from the effort channels (SI) and, with identified drive gains, each
    gain's column on the joint side, (N, n, channels):

    - torques: tau = Nt tau_file (`transmitted`), no columns;
    - currents with known gains: the motor torques g * i, then tau = Nt (g * i), no columns;
    - currents with a gain identified: the joint torque Nt diag(i) g is linear in the gains, so every channel's gain
      is a parameter with the column -Nt[:, k] i_k (W X - Nt diag(i) g = 0); the known gains' columns are moved to
      the right-hand side by the estimator (`known`), and the torque known here is 0."""
    if cfg.effort != "current":
        return (*transmitted(cfg, q, effort, n), None)
    gains = np.array(cfg.drive.gains)
    if not cfg.drive.identified:
        return (*transmitted(cfg, q, effort * gains, n), None)
    q, tau = transmitted(cfg, q, np.zeros_like(effort), n)
    Nt = cfg.transmission.get("tau", np.eye(effort.shape[1]))
    return q, tau, -effort[:, None, :] * Nt[None, :, :]


def gain_names(cfg: IdentifyConfig) -> list[str]:
    """The drive gains' parameter names, G1.. in the order of [channels] current (empty without identified gains)."""
    if cfg.drive is None or not cfg.drive.identified:
        return []
    return [f"G{k}" for k in range(1, len(cfg.drive.gains) + 1)]


def read_robot_window(plan: RobotTestPlan, lo: int, hi: int) -> dict[str, NDArray[np.float64]]:
    """{"q": (hi - lo, channels), "tau" or "current": ...} in SI: the clock samples lo..hi of the test, each channel
    from its file's samples around them, interpolated where not on the clock (cubic for q, linear for the effort)."""

    clock = np.asarray(plan.clock[lo:hi])
    out = {}
    effort = ("current", "linear", ("A",)) if plan.effort == "current" else ("tau", "linear", ("N*m", "N"))
    for quantity, kind, expect in (("q", "cubic", ("rad", "m")), effort):
        index, names = plan.indexes[quantity], list(plan.channels[quantity])
        al = _resampled(index, names, clock, plan.margin, plan.timed, plan.first + lo, lambda _n, k=kind: k)
        out[quantity] = np.stack([to_si(al[n], u, channel=n, source=str(index.path), expect=expect)[0]
                                  for n, u in zip(names, plan.units[quantity], strict=True)], axis=1)
    return out
