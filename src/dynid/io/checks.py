"""Data checks on channels, with errors that say what, where and what to do.

- `check_channels`: every needed channel is in the file (`MissingChannelError`).
- `check_time`: time stamps finite and strictly increasing (`TimeBaseError`).
- `check_finite`: no NaN or infinite value (`GapError`).
- `check_gaps`: no hole in the time stamps, i.e. no step above `factor` x the
  channel's median step (`GapError`).
- `check_channel`: the three above, in that order.
- `check_saturation`: spans stuck at a range limit (`SaturationWarning`, not an error).
- `check_length`: enough samples for a zero-phase filter (`RecordTooShortError`).

Messages name the file, the file line (text formats), the channel, the sample index
(0-based, in the channel's own samples) and its time in s.
"""

from __future__ import annotations

import difflib
import math
import numbers
import warnings
from collections.abc import Collection, Mapping, Sequence
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ..signals import SignalError, border_samples
from .errors import GapError, MissingChannelError, RecordTooShortError, SaturationWarning, TimeBaseError

if TYPE_CHECKING:
    from .channel import Channel

_SHOWN = 5  # offending samples or spans listed in a message


class Span(NamedTuple):
    """A stretch of samples of one channel: samples first..last (inclusive), times in s."""

    first: int
    last: int
    t_start: float
    t_end: float
    limit: float


def locate(source: str | None, channel: Channel | str | None, k: int | None = None, t: float | None = None) -> str:
    """ "file.csv, line 57, channel 'roll', sample 12 (t = 0.0192 s)" with the parts that are known."""
    parts = []
    if source:
        parts.append(str(source))
    name = channel if isinstance(channel, str) or channel is None else channel.name
    if k is not None and channel is not None and not isinstance(channel, str) and channel.lines is not None:
        parts.append(f"line {channel.line(k)}")
    if name is not None:
        parts.append(f"channel {name!r}")
    if k is not None:
        parts.append(f"sample {k}" + (f" (t = {t:.6g} s)" if t is not None and math.isfinite(t) else ""))
    return ", ".join(parts)


def _sample(channel: Channel, k: int) -> str:
    text = f"sample {k} (t = {float(channel.time[k]):.6g} s"
    if channel.lines is not None:
        text += f", line {channel.line(k)}"
    return text + ")"


def missing_error(
    needed: Sequence[str],
    available: Collection[str],
    *,
    source: str | None = None,
    skipped: Mapping[str, str] | None = None,
) -> MissingChannelError:
    """The error for the names of `needed` not in `available` (call when at least one is missing)."""
    have = list(available)
    missing = [n for n in needed if n not in available]
    folded = {a.casefold(): a for a in have}
    notes = []
    for n in missing:
        close = difflib.get_close_matches(n, have, n=3, cutoff=0.6)
        if n.casefold() in folded and folded[n.casefold()] not in close:
            close.insert(0, folded[n.casefold()])
        why = (skipped or {}).get(n)
        if why:
            notes.append(f"{n!r} (in the file but not read: {why})")
        elif close:
            notes.append(f"{n!r} (close: {', '.join(repr(c) for c in close)})")
        else:
            notes.append(repr(n))
    prefix = f"{source}: " if source else ""
    return MissingChannelError(
        f"{prefix}{len(missing)} channel(s) needed are not in the file: {'; '.join(notes)}. "
        f"Needed: {', '.join(needed)}. The file has {len(have)} channel(s): {', '.join(have) or '(none)'}. "
        "Fix the channel names (channel map) or use a file that logs them",
        needed=missing,
        available=have,
        source=source,
        channel=missing[0] if missing else None,
    )


def check_channels(
    needed: Sequence[str],
    available: Collection[str],
    *,
    source: str | None = None,
    skipped: Mapping[str, str] | None = None,
) -> None:
    """Raise `MissingChannelError` if any of `needed` is not in `available` (all missing listed at once)."""
    if any(n not in available for n in needed):
        raise missing_error(needed, available, source=source, skipped=skipped)


def check_time(channel: Channel, *, source: str | None = None) -> None:
    """The channel's time stamps are finite and strictly increasing, else `TimeBaseError`."""
    t = channel.time
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        k = int(bad[0])
        raise TimeBaseError(
            f"{locate(source, channel, k)}: time stamp is {t[k]} ({bad.size} non-finite time stamp(s) in all); "
            "fix the logger export or drop those samples",
            source=source,
            channel=channel.name,
            sample=k,
            line=channel.line(k),
        )
    step = np.diff(t)
    bad = np.flatnonzero(step <= 0.0)
    if bad.size:
        shown = []
        for i in bad[:_SHOWN]:
            k = int(i) + 1
            kind = "repeats" if step[i] == 0.0 else "goes back from"
            shown.append(f"{_sample(channel, k)} {kind} {_sample(channel, k - 1)}")
        k = int(bad[0]) + 1
        dup = int(np.count_nonzero(step[bad] == 0.0))
        raise TimeBaseError(
            f"{locate(source, channel, k, float(t[k]))}: time stamps are not strictly increasing: "
            f"{'; '.join(shown)}{' ...' if bad.size > _SHOWN else ''} "
            f"({dup} duplicated, {bad.size - dup} going backwards in all). "
            "Sort the samples by time and drop repeated stamps, or fix the logger's clock",
            source=source,
            channel=channel.name,
            sample=k,
            line=channel.line(k),
        )


def _runs(mask: NDArray[np.bool_]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """(starts, ends) of the runs of True in `mask`, ends exclusive."""
    padded = np.concatenate(([False], mask, [False])).astype(np.int8)
    edges = np.diff(padded)
    return np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)


def check_finite(channel: Channel, *, source: str | None = None) -> None:
    """The channel's values are all finite, else `GapError` naming the first bad sample and the runs."""
    bad = ~np.isfinite(channel.values)
    if not bad.any():
        return
    starts, ends = _runs(bad)
    t = channel.time
    shown = [
        f"samples {s}..{e - 1} (t = {float(t[s]):.6g}..{float(t[e - 1]):.6g} s)" if e - s > 1 else _sample(channel, s)
        for s, e in zip(starts[:_SHOWN], ends[:_SHOWN], strict=True)
    ]
    k = int(starts[0])
    raise GapError(
        f"{locate(source, channel, k, float(t[k]))}: value is {channel.values[k]}; "
        f"{int(bad.sum())} non-finite value(s) in {starts.size} run(s): {'; '.join(shown)}"
        f"{' ...' if starts.size > _SHOWN else ''}. Cut the record to a part without them, "
        "or fill short holes (interpolate) before use",
        source=source,
        channel=channel.name,
        sample=k,
        line=channel.line(k),
    )


def check_gaps(channel: Channel, factor: float = 2.0, *, source: str | None = None) -> None:
    """No step between time stamps above `factor` x the median step, else `GapError`.

    Call after `check_time` (the stamps must be increasing). Channels of fewer than
    3 samples are not judged.
    """
    if not (isinstance(factor, numbers.Real) and factor > 1.0):
        raise ValueError(f"gap factor must be a number > 1, got {factor!r}")
    t = channel.time
    if t.size < 3:
        return
    step = np.diff(t)
    typical = float(np.median(step))
    bad = np.flatnonzero(step > factor * typical)
    if not bad.size:
        return
    shown = [
        f"{float(step[i]):.6g} s between {_sample(channel, int(i))} and {_sample(channel, int(i) + 1)}"
        for i in bad[:_SHOWN]
    ]
    k = int(bad[0]) + 1
    raise GapError(
        f"{locate(source, channel, k, float(t[k]))}: {bad.size} gap(s) in the time stamps, the usual step being "
        f"{typical:.6g} s ({1.0 / typical:.6g} Hz): {'; '.join(shown)}{' ...' if bad.size > _SHOWN else ''}. "
        "Samples are missing there (logger drop-out?): use the part before or after the gap, "
        "or raise gap_factor if the channel is logged irregularly on purpose",
        source=source,
        channel=channel.name,
        sample=k,
        line=channel.line(k),
    )


def check_channel(
    channel: Channel,
    *,
    source: str | None = None,
    gap_factor: float | None = 2.0,
    checked_times: set[int] | None = None,
) -> None:
    """`check_time`, `check_finite`, then `check_gaps` (unless gap_factor is None).

    `checked_times`: ids of time arrays already checked (channels of one logging rate
    share one array); their time checks are skipped, and this channel's is added.
    """
    fresh = checked_times is None or id(channel.time) not in checked_times
    if fresh:
        check_time(channel, source=source)
    check_finite(channel, source=source)
    if fresh:
        if gap_factor is not None:
            check_gaps(channel, gap_factor, source=source)
        if checked_times is not None:
            checked_times.add(id(channel.time))


def check_saturation(
    channel: Channel,
    *,
    limits: tuple[float, float] | None = None,
    min_samples: int = 5,
    tol: float = 0.0,
    source: str | None = None,
    warn: bool = True,
) -> list[Span]:
    """Spans of at least `min_samples` consecutive samples at a range limit; warns if any.

    Parameters
    ----------
    channel : the channel, values in its file unit.
    limits : (low, high) range of the sensor, in the channel's unit. A sample is at
        a limit when value >= high - tol or value <= low + tol. None: the channel's
        own minimum and maximum, exactly (a clipped sensor repeats its limit value).
        Caution: a quantised signal sits on its extreme value for a few samples at a
        slow peak; give the sensor's range when it is known, or raise min_samples.
    min_samples : shortest run flagged ("more than a few samples").
    tol : tolerance on the limits, in the channel's unit.
    warn : issue one `SaturationWarning` listing the spans (time in s).

    Returns
    -------
    list of Span (first, last sample, t_start, t_end s, limit value), in time order.
    A channel constant over the whole record is returned as one span.
    """
    v = channel.values
    finite = np.isfinite(v)
    if not finite.any():
        return []
    if limits is None:
        lo, hi = float(np.min(v[finite])), float(np.max(v[finite]))
        tol = 0.0
    else:
        lo, hi = (float(x) for x in limits)
    spans: list[Span] = []
    for limit, mask in ((hi, v >= hi - tol), (lo, v <= lo + tol)):
        starts, ends = _runs(mask & finite)
        for s, e in zip(starts, ends, strict=True):
            if e - s >= min_samples:
                spans.append(Span(int(s), int(e - 1), float(channel.time[s]), float(channel.time[e - 1]), limit))
        if lo == hi:
            break
    spans.sort()
    if spans and warn:
        unit = f" {channel.unit}" if channel.unit else ""
        shown = [
            f"t = {sp.t_start:.6g}..{sp.t_end:.6g} s at {sp.limit:g}{unit} (samples {sp.first}..{sp.last})"
            for sp in spans[:_SHOWN]
        ]
        what = "constant over the whole record" if lo == hi else f"stuck at a range limit in {len(spans)} span(s)"
        warnings.warn(
            f"{locate(source, channel)}: {what}{' (range ' + repr((lo, hi)) + unit + ')' if limits else ''}: "
            f"{'; '.join(shown)}{' ...' if len(spans) > _SHOWN else ''}. The sensor may have saturated "
            "or dropped out there: check its range, or leave these spans out of the identification",
            SaturationWarning,
            stacklevel=2,
        )
    return spans


def check_length(
    n: int,
    fs: float,
    cutoff: float,
    order: int,
    *,
    tol: float = 1e-3,
    channel: str | None = None,
    source: str | None = None,
) -> int:
    """Check that `n` samples survive the zero-phase filter's border transients.

    Parameters
    ----------
    n : samples in the record.
    fs, cutoff, order : sample rate (Hz), cut-off (Hz) and order of the
        `dynid.signals.lowpass` that will condition the record.
    tol : as for `dynid.signals.border_samples`.

    Returns
    -------
    int, the border b (samples to trim at each end); n > 2 b is guaranteed.

    Raises
    ------
    RecordTooShortError
        n <= 2 b, with both counts in samples and in seconds and what to change.
    """
    try:
        border = border_samples(fs, cutoff, order, tol)
    except SignalError as exc:
        raise RecordTooShortError(f"{locate(source, channel)}: cannot size the filter borders: {exc}") from None
    if n <= 2 * border:
        where = locate(source, channel)
        raise RecordTooShortError(
            f"{where + ': ' if where else ''}record too short for the order-{order} low-pass at {cutoff:g} Hz: "
            f"it has {n} samples ({n / fs:.4g} s at {fs:g} Hz) but needs more than {2 * border} "
            f"({2 * border / fs:.4g} s): the filter transient spoils {border} samples at each end. "
            "Record a longer test, raise the cut-off or lower the order",
            source=source,
            channel=channel,
        )
    return border
