"""Data health of one channel, scanned block by block: clipped plateaus, spikes, values out of range, dead channels.

A logger file can be read, stamped and complete and still lie: a sensor saturated (its values sit on a
flat top for part of the test), a spike (one sample far from its neighbours), a sensor that never moved.
Least squares takes them as data and answers with confidence (a yaw rate clipped at its 70th percentile
moved the car's yaw inertia by 12 %). `ChannelScan` finds them from the values alone, fed in time order
one block at a time (memory follows the block, not the file), and says what each finding is, where (time
span, in the file's time base) and what to do.

What is judged, per channel (values in the channel's unit):

- out of range: a value beyond the sensor's declared range (`limits`): the sensor cannot give it.
- clipped at the declared range: runs of `min_samples` or more samples at a limit.
- clipped by the shape of the data (no range declared, or a logger limit below it): a run of identical
  values at the block's highest or lowest value, longer than `min_run` and than eight of the channel's
  own holds, ENTERED AND LEFT AT SPEED: the values two holds before and after the run differ from it by
  more than `KINK` noise deviations plus a resolution step (one side, or farther, flags the noise-free
  files' rests: a step steer's yaw rate leaves 0 at speed); OR NOISY BESIDE
  IT: the `NEAR` holds before or after the run turn back at `REVERSALS` of their steps or more, so that
  noise would have moved the value had the sensor been free to follow (a slow ramp clipped). A signal
  that comes to rest on its extreme (a car stopping, a noise-free file) approaches it slowly and without
  noise: not a clip.
- clipped, seen from the count: at least `MANY` holds, and `SHARE` of the samples, at exactly the block's
  highest or lowest value, in a channel of `LEVELS` distinct values or more. A noisy sensor reaches its
  extreme once or a few times (on the demo's files, two seeds, at most 9 holds for a channel of 20 levels
  or more; a steering wheel held still at a 0.1 deg resolution, on fewer levels, 39 times); a
  clipped one stays there whenever the truth is beyond it, its noise pulling it below now and then (the
  flat top broken into short runs, which the rule above misses). A noise-free signal of few levels
  (an attitude on two or three 0.05 deg steps) is not judged.
- spikes: a value that jumps away from its neighbours and straight back: in the series of the channel's
  distinct consecutive values (a held sensor's holds merged), a step up then down (or down then up) each
  larger than `SPIKE` times the 99th percentile of the channel's step sizes. A band-limited signal turns
  smoothly (its steps shrink at a peak); noise makes both steps large only by chance: on the demo's
  files, noisy and noise-free, the largest such pair is 1.6 times the 99th percentile, and with Gaussian
  noise a pair above 5 times it (13 deviations of a step) never happens. A spike of two samples or more
  on an unheld channel is not seen.
- dead: one value over the whole test.
- boolean: a channel that should be continuous (`continuous`: a joint's position or torque) reading 0 and 1
  and nothing else over the whole test: a digital channel (a Parquet boolean column, a brake switch) mapped
  where a measurement belongs.

The holds: a logger samples a slow sensor at its own rate and holds each value (a 125 Hz inertial unit on
a 625 Hz clock repeats each value 5 times); the typical hold is the median length of the runs of identical
values, and plateaus and spikes are counted in holds so that a held signal is judged as the sensor gave it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

ERROR = "error"  # the identification stops: its answer would be wrong
WARNING = "warning"  # listed: the answer may be affected near the span
NOTE = "note"  # listed: the pipeline takes care of it
SEVERE_SHARE = 0.05  # a channel clipped (or out of range) on this share of its samples or more stops the run
SPIKE = 5.0  # a spike's two steps, in 99th percentiles of the channel's step sizes
# a spike farther from its neighbours than this many times the span of the rest of its block is no measurement (a
# corrupt sample, a logger's error code): an error, not a warning (a 1e6 N.m sample among torques of 10 N.m)
WILD = 10.0
KINK = 4.0  # noise deviations between a plateau and the signal a few holds before or after it
NEAR, REVERSALS = 20, 0.4  # holds beside a plateau read for noise, the share of their steps that turn back
MANY, SHARE, LEVELS = 20, 0.05, 20  # holds and share of the samples at one extreme, in a channel of so many levels
_SHOWN = 3  # spans listed in a finding's text


@dataclass(frozen=True)
class Finding:
    """One thing wrong with a channel (or a group of channels) of one test.

    channel: the file's channel name (several joined by " and " for a wiring finding); kind: "out of
    range", "clipped", "spike", "dead", "swapped", "gravity", "weight"; severity: ERROR (the run stops),
    WARNING or NOTE (the pipeline takes care of it); t_start, t_end: s, in the file's time base, the first
    and last sample concerned; share: of the channel's samples concerned (0..1); detail: what was seen;
    fix: what to do."""

    channel: str
    kind: str
    severity: str
    t_start: float
    t_end: float
    detail: str
    fix: str
    share: float = 0.0

    def text(self, source: str | None = None) -> str:
        """One line: "<source>: channel 'x': <detail>, t = a..b s: <fix>"."""
        where = f"{source}: " if source else ""
        return (f"{where}channel {self.channel!r}: {self.detail}, t = {self.t_start:.6g}..{self.t_end:.6g} s: "
                f"{self.fix}")

    def as_dict(self) -> dict:
        return {"channel": self.channel, "kind": self.kind, "severity": self.severity,
                "t_start": self.t_start, "t_end": self.t_end, "share": self.share, "detail": self.detail,
                "fix": self.fix}


def _runs(mask: NDArray[np.bool_]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """(starts, ends) of the runs of True in `mask`, ends exclusive."""
    edges = np.diff(np.concatenate(([0], mask.view(np.int8), [0])))
    return np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)


def holds(x: NDArray[np.float64]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """(starts, lengths) of the runs of identical consecutive values of x."""
    if x.size == 0:
        return np.empty(0, np.intp), np.empty(0, np.intp)
    new = np.empty(x.size, dtype=bool)
    new[0] = True
    np.not_equal(x[1:], x[:-1], out=new[1:])
    starts = np.flatnonzero(new)
    if starts.size == x.size:  # no value held (a noisy or fast channel): the common case, without the arithmetic
        return starts, np.ones(x.size, dtype=np.intp)
    return starts, np.diff(starts, append=x.size)


def _held(x: NDArray[np.float64]) -> tuple[NDArray[np.intp] | None, NDArray[np.intp] | None]:
    """`holds(x)` of a non-empty x, or (None, None) when no value is held (every hold one sample, the usual noisy
    channel): its index arrays (the starts 0..n-1, the lengths all 1) not built, a third of a channel's scan."""
    new = np.empty(x.size, dtype=bool)
    new[0] = True
    np.not_equal(x[1:], x[:-1], out=new[1:])
    if np.count_nonzero(new) == x.size:
        return None, None
    starts = np.flatnonzero(new)
    return starts, np.diff(starts, append=x.size)


def noise_deviation(x: NDArray[np.float64], resolution: float = 0.0) -> float:
    """Robust standard deviation of x's noise, in x's unit; at least `resolution`: 1.4826 x the median absolute
    deviation of the second differences of its holds, over sqrt(6) (a second difference holds three samples'
    noise, weighted 1, -2, 1; the signal's slope drops out, its curvature between holds is far below the noise)."""
    starts, _ = holds(x)
    d2 = np.diff(x[starts], 2)
    sigma = 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / math.sqrt(6.0) if d2.size > 2 else 0.0
    return max(sigma, resolution)


@dataclass
class _Spans:
    """Spans (t_start, t_end) of one kind in a channel, with the samples they hold, in what a finding says of them
    alone (a long log of a spiky channel finds thousands: none held beyond these): their count, the first
    `_SHOWN` in time order and the last, the `_SHOWN` + 1 first of the values read there as the finding writes them
    (`suffix`: the unit), and the farthest from 0 (the first of the farthest, in the order added)."""

    suffix: str = ""
    count: int = 0
    samples: int = 0
    first: list[tuple[float, float]] = field(default_factory=list)  # sorted
    last: tuple[float, float] | None = None
    levels: list[str] = field(default_factory=list)  # distinct, sorted
    top: float | None = None

    def add(self, t0: float, t1: float, n: int, value: float) -> None:
        self.count += 1
        self.samples += n
        self.first = sorted([*self.first, (t0, t1)])[:_SHOWN]
        self.last = (t0, t1) if self.last is None else max(self.last, (t0, t1))
        self.levels = sorted({*self.levels, f"{value:g}{self.suffix}"})[:_SHOWN + 1]
        if self.top is None or abs(value) > abs(self.top):
            self.top = value

    def copy(self) -> _Spans:
        return _Spans(self.suffix, self.count, self.samples, list(self.first), self.last, list(self.levels), self.top)

    def merged(self, other: _Spans) -> _Spans:
        """self's spans then other's."""
        top = self.top if other.top is None or (self.top is not None and abs(other.top) <= abs(self.top)) else other.top
        last = max((s for s in (self.last, other.last) if s is not None), default=None)
        levels = sorted({*self.levels, *other.levels})[:_SHOWN + 1]
        return _Spans(self.suffix, self.count + other.count, self.samples + other.samples,
                      sorted(self.first + other.first)[:_SHOWN], last, levels, top)


class ChannelScan:
    """The health of one channel from its blocks, fed in time order (`add`), judged at the end (`findings`).

    name, unit: the file's; limits: the sensor's declared (low, high) range in the channel's unit (None:
    not declared); resolution: its quantisation step (0: unknown); still: for a channel that may read one value
    over a whole test (a steering wheel on a straight line, a wheel that does not steer), what to check then
    (a constant channel is then a warning; None: an error, a dead sensor); min_run: the shortest clipped plateau, in
    samples (default: 0.1 s at 625 Hz; a clip shorter than that hardly matters once low-passed); continuous: the
    quantity takes any value (a position, a torque), so a channel of 0s and 1s alone is a digital one (an error)."""

    def __init__(self, name: str, unit: str = "", limits: tuple[float, float] | None = None,
                 resolution: float = 0.0, still: str | None = None, min_run: int = 62, min_samples: int = 5,
                 continuous: bool = False) -> None:
        self.name, self.unit, self.limits = name, unit, limits
        self.continuous = continuous
        self.binary = continuous  # every value so far 0 or 1 (judged for a continuous quantity only)
        self.zeros_and_ones = (False, False)  # whether a 0 and a 1 were seen
        self.resolution, self.still = float(resolution), still
        self.min_run, self.min_samples = int(min_run), int(min_samples)
        self.n = 0
        self.first_value: float | None = None
        self.constant = True
        self.t_first = self.t_last = float("nan")
        u = f" {unit}" if unit else ""  # as the findings write a value
        self.out = _Spans(u)
        self.at_limit = _Spans(u)
        self.plateau = _Spans(u)
        self.spikes = _Spans(u)
        self.wild = _Spans(u)  # spikes beyond any value the rest of the channel has (WILD)
        self.span = (float("inf"), float("-inf"))  # the rest's extent (0.1 %..99.9 % of each block)

    def add(self, t: NDArray[np.float64], x: NDArray[np.float64]) -> None:
        """One block of the channel: its time stamps (s) and values (the channel's unit), (n,) each."""
        t, x = np.asarray(t, dtype=float), np.asarray(x, dtype=float)
        if x.size == 0:
            return
        # the extremes, which the range and the plateaus need, tell whether every value is finite (min and max
        # propagate NaN; an infinity is one of them): one pass, not an isfinite pass and its all()
        lo, hi = float(x.min()), float(x.max())
        if not (math.isfinite(lo) and math.isfinite(hi)):
            keep = np.isfinite(x)  # non-finite values are the time-base checks' business
            t, x = t[keep], x[keep]
            if x.size == 0:
                return
            lo, hi = float(x.min()), float(x.max())
        if self.binary:
            zero, one = x == 0.0, x == 1.0
            self.binary = bool(np.all(zero | one))
            seen = self.zeros_and_ones
            self.zeros_and_ones = (seen[0] or bool(zero.any()), seen[1] or bool(one.any()))
        starts, lengths = _held(x)  # None: no value held
        # one value over the block: nothing but the range to judge in it (blocks may come in any order: the channel
        # is constant when every block is, at one value)
        still = starts is not None and starts.size == 1
        self.constant = self.constant and still and (self.first_value is None or float(x[0]) == self.first_value)
        if self.first_value is None or t[0] < self.t_first:
            self.first_value, self.t_first = float(x[0]), float(t[0])
        self.t_last = max(float(t[-1]), self.t_last) if self.n else float(t[-1])
        self.n += x.size
        self._limits(t, x, lo, hi)
        if still or x.size < 3:
            return
        y = x if starts is None else x[starts]  # the holds' values (every value of x: its extremes too)
        self._plateaus(t, x, y, starts, lengths, lo, hi)
        self._spikes(t, x, y, starts)

    def merge(self, other: ChannelScan) -> ChannelScan:
        """A new scan of both scans' blocks (blocks of the same channel that do not overlap in time; in either
        order): what one scan fed with every block in time order finds."""
        out = ChannelScan(self.name, self.unit, self.limits, self.resolution, self.still, self.min_run,
                          self.min_samples, self.continuous)
        if not (self.n and other.n):
            src = self if self.n else other
            out.__dict__.update({**src.__dict__, "out": src.out.copy(), "at_limit": src.at_limit.copy(),
                                 "plateau": src.plateau.copy(), "spikes": src.spikes.copy(), "wild": src.wild.copy()})
            return out
        a, b = (self, other) if self.t_first <= other.t_first else (other, self)
        out.n = a.n + b.n
        out.first_value, out.t_first, out.t_last = a.first_value, a.t_first, max(a.t_last, b.t_last)
        out.constant = a.constant and b.constant and a.first_value == b.first_value
        out.binary = a.binary and b.binary
        out.zeros_and_ones = (a.zeros_and_ones[0] or b.zeros_and_ones[0], a.zeros_and_ones[1] or b.zeros_and_ones[1])
        for kind in ("out", "at_limit", "plateau", "spikes", "wild"):
            setattr(out, kind, getattr(a, kind).merged(getattr(b, kind)))
        out.span = (min(a.span[0], b.span[0]), max(a.span[1], b.span[1]))
        return out

    def _limits(self, t: NDArray[np.float64], x: NDArray[np.float64], x_min: float, x_max: float) -> None:
        if self.limits is None:
            return
        lo, hi = self.limits
        if lo < x_min and x_max < hi:  # the usual block: nowhere near the range
            return
        s, e = _runs((x > hi) | (x < lo))
        for a, b in zip(s, e, strict=True):
            self.out.add(float(t[a]), float(t[b - 1]), int(b - a), float(x[a:b][np.argmax(np.abs(x[a:b]))]))
        for limit, mask in ((hi, x == hi), (lo, x == lo)):
            s, e = _runs(mask)
            for a, b in zip(s, e, strict=True):
                if b - a >= self.min_samples:
                    self.at_limit.add(float(t[a]), float(t[b - 1]), int(b - a), limit)

    def _plateaus(self, t, x, y, starts, lengths, bottom: float, top: float) -> None:
        """bottom, top: x's (and so y's) extremes; starts, lengths: x's holds (None: no value held)."""
        ranged = set(self.limits or ())  # values at the declared range are counted there
        # seen from the count (the distinct values counted only for a candidate: a sort per channel is not free; x's
        # count is y's when no value is held)
        many = set()
        for v in {top, bottom} - ranged:
            held = np.count_nonzero(y == v)
            if held >= MANY and (held if y is x else np.count_nonzero(x == v)) >= SHARE * x.size:
                many.add(v)
        clipped = many if many and np.unique(y).size >= LEVELS else set()
        if starts is None:  # no value held: every hold one sample
            hold = 1
        else:
            counts = np.cumsum(np.bincount(lengths))  # the median hold, from the lengths' histogram (no sort)
            hold = max(1, int(np.searchsorted(counts, (lengths.size + 1) // 2)))
        longest = max(self.min_run, 8 * hold)
        if starts is None:  # every hold one sample: none as long as 8 holds
            long = np.empty(0, np.intp)
        else:
            long = np.flatnonzero(lengths >= longest)  # seen from the shape
            long = long[(y[long] == top) | (y[long] == bottom)]
        if long.size:
            gap = 2 * hold + 1  # samples before and after a plateau where the approach is read
            jump = KINK * noise_deviation(x, self.resolution) + self.resolution
        for k in long:
            a, n = int(starts[k]), int(lengths[k])
            v = float(x[a])
            if v in clipped or v in ranged:
                continue
            # a clip is run into and out of: at speed on both sides (a plateau at either end of the block is not
            # judged so: a noise-free record starting at rest leaves it at speed)
            inside = a - gap >= 0 and a + n - 1 + gap < x.size
            kink = inside and min(abs(v - x[a - gap]), abs(v - x[a + n - 1 + gap])) > jump
            if kink or _noisy(y[max(0, k - NEAR):k]) or _noisy(y[k + 1:k + 1 + NEAR]):
                clipped.add(v)
        for v in sorted(clipped):
            # every sample at a clipped value is clipped; those closer than a plateau's length make one span
            at = np.flatnonzero(x == v)
            for run in np.split(at, np.flatnonzero(np.diff(at) > self.min_run) + 1):
                self.plateau.add(float(t[run[0]]), float(t[run[-1]]), run.size, v)

    def _spikes(self, t, x, y, starts) -> None:
        if y.size < 4:
            return
        step = np.diff(y)
        size = np.abs(step)
        # a spike is a pair of steps that turn back, the smaller larger than SPIKE times the steps' 99th percentile.
        # The percentile (a partial sort) only when a pair could be one: when 1 % of the steps or more reach a
        # SPIKE-th of a bound on the pairs, so does the percentile (what np.quantile interpolates between is then at
        # or above it), and no pair exceeds SPIKE times it. The bounds: the largest step, then the largest pair
        top = size.size - math.floor(0.99 * (size.size - 1))  # steps at or above the percentile's lower neighbour

        def below(bound: float) -> bool:
            return bound <= 2 * self.resolution or np.count_nonzero(size >= bound / SPIKE * (1 + 1e-9)) >= top

        if below(float(size.max())):
            return
        sign = np.signbit(step)
        pair = np.where(sign[:-1] != sign[1:], np.minimum(size[:-1], size[1:]), 0.0)
        if below(float(pair.max())):
            return
        big = SPIKE * float(np.quantile(size, 0.99))
        hit = np.flatnonzero((pair > big) & (pair > 2 * self.resolution))
        if hit.size:
            lo, hi = (float(v) for v in np.quantile(y, [0.001, 0.999]))
            self.span = (min(self.span[0], lo), max(self.span[1], hi))
            width = max(hi - lo, self.resolution, np.finfo(float).tiny)
        for k in hit + 1:
            a = int(k if starts is None else starts[k])  # the hold's samples (one when none is held)
            b = a + 1 if starts is None else int(starts[k + 1]) if k + 1 < starts.size else x.size
            self.spikes.add(float(t[a]), float(t[b - 1]), b - a, float(y[k]))
            if abs(y[k] - 0.5 * (y[k - 1] + y[k + 1])) > WILD * width:
                self.wild.add(float(t[a]), float(t[b - 1]), b - a, float(y[k]))

    def findings(self) -> list[Finding]:
        """What the blocks fed show (module doc), errors first."""
        if self.n == 0:
            return []
        u = f" {self.unit}" if self.unit else ""
        out = []
        if self.binary and all(self.zeros_and_ones):  # a digital channel: nothing else about it means anything
            return [Finding(self.name, "boolean", ERROR, self.t_first, self.t_last,
                            "reads 0 and 1 and nothing else over the test (a boolean or digital channel), where "
                            "a continuous measurement belongs",
                            "map this quantity to the sensor's own channel in [channels], or export the "
                            "measurement instead of its flag", 1.0)]
        if self.constant and self.n > 1:
            if self.still is not None:
                out.append(Finding(self.name, "dead", WARNING, self.t_first, self.t_last,
                                   f"reads {self.first_value:g}{u} throughout", self.still, 1.0))
            else:
                out.append(Finding(self.name, "dead", ERROR, self.t_first, self.t_last,
                                   f"reads {self.first_value:g}{u} throughout (a dead or disconnected sensor)",
                                   "check the sensor and its wiring, or map this quantity to a working channel in "
                                   "[channels]", 1.0))
            return out
        for spans, kind, what in ((self.out, "out of range", "beyond the sensor's declared range {lim}"),
                                  (self.at_limit, "clipped", "at the sensor's declared range {lim}"),
                                  (self.plateau, "clipped", "flat at its extreme")):
            if not spans.samples:
                continue
            share = spans.samples / self.n
            severe = share >= SEVERE_SHARE or kind == "out of range"
            lim = f"({self.limits[0]:g}..{self.limits[1]:g}{u})" if self.limits else ""
            level = spans.levels
            detail = (f"{what.format(lim=lim)} on {spans.samples} sample(s), {100 * share:.3g} % of the test "
                      f"({', '.join(level[:_SHOWN])}{', ...' if len(level) > _SHOWN else ''}), in "
                      f"{spans.count} span(s) ({_listed(spans)})")
            if kind == "out of range":
                fix = ("the sensor cannot give these values: a corrupt sample or a wrong unit or scale; cut the test "
                       "(start, end) to leave them out, or fix the export")
            elif severe:
                fix = ("the sensor saturated: the identification would take the flat tops as data; use a sensor "
                       "range that covers the test, or cut the test (start, end) to a part without them")
            else:
                fix = "short saturations: check the sensor's range; estimates may be biased if they grow"
            out.append(Finding(self.name, kind, ERROR if severe else WARNING, spans.first[0][0], spans.last[1],
                               detail, fix, share))
        if self.wild.samples:
            sp = self.wild
            out.append(Finding(
                self.name, "spike", ERROR, sp.first[0][0], sp.last[1],
                f"{sp.count} spike(s) far beyond the rest of the channel ({_listed(sp)}; up to "
                f"{sp.top:g}{u}, the rest within {self.span[0]:g}..{self.span[1]:g}{u})",
                "no sensor reads that: a corrupt sample or a logger's error code; fix or remove the sample in the "
                "file (its neighbours' mean), or cut the test (start, end) to leave it out", sp.samples / self.n))
        elif self.spikes.samples:
            sp = self.spikes
            out.append(Finding(
                self.name, "spike", WARNING, sp.first[0][0], sp.last[1],
                f"{sp.count} spike(s) ({_listed(sp)}; up to {sp.top:g}{u})",
                "a spike is low-passed into a bump of the equations around it: cut the test (start, end) to leave "
                "it out, or replace the sample by its neighbours' mean in the file", sp.samples / self.n))
        return sorted(out, key=lambda f: f.severity != ERROR)


def _noisy(y: NDArray[np.float64]) -> bool:
    """Whether the holds y show noise: their steps change sign at least `REVERSALS` of the time (white noise:
    two in three; a noise-free signal only at its peaks)."""
    step = np.sign(np.diff(y))
    return step.size >= NEAR // 2 and float(np.mean(step[1:] != step[:-1])) >= REVERSALS


def _listed(spans: _Spans) -> str:
    shown = [f"t = {a:.6g} s" if a == b else f"t = {a:.6g}..{b:.6g} s" for a, b in spans.first]
    return "; ".join(shown) + (" ..." if spans.count > _SHOWN else "")


__all__ = ["ERROR", "NOTE", "SEVERE_SHARE", "WARNING", "ChannelScan", "Finding", "holds", "noise_deviation"]
