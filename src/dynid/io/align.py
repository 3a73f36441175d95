"""Channels on their own time bases onto one common clock (`align`, `Aligned`).

The clock is either given (`t`), or uniform at `fs` over the span every channel
covers (`dynid.signals.common_clock`), or, with neither, the channels' shared time
base when they have one, else the fastest channel's own time stamps inside the span
every channel covers.
Each channel is interpolated with `dynid.signals.resample`: "cubic" for smooth
channels, "linear" for channels with steps. Channels that share a time base are
interpolated together; a channel already on the clock is copied, not interpolated.
Every channel is checked first (time base, NaN, gaps), so errors name the file and
channel rather than an anonymous array.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..signals import SignalError, common_clock, resample
from .checks import check_channel, locate
from .errors import DataError, TimeBaseError

if TYPE_CHECKING:
    from .channel import Channel

KINDS = ("cubic", "linear")


@dataclass(frozen=True)
class InterpSpec:
    """One output of `align`: the key it is stored under, the channel, the interpolation kind."""

    name: str
    channel: Channel
    kind: str = "cubic"


@dataclass(frozen=True, eq=False)
class Aligned:
    """Channels on one clock.

    Attributes
    ----------
    t : array (M,), s, the common clock.
    values : dict name -> array (M,) (or (M, k) for a quantity of k channels). A channel
        already on the clock is given as a read-only view of its samples (no copy):
        copy it before changing it in place.
    units : dict name -> unit string of the values (the file's unit, or SI after a ChannelMap).
    source : the file the channels came from, for messages.
    """

    t: NDArray[np.float64]
    values: dict[str, NDArray[np.float64]]
    units: dict[str, str]
    source: str | None = None

    def __getitem__(self, name: str) -> NDArray[np.float64]:
        try:
            return self.values[name]
        except KeyError:
            raise KeyError(f"{name!r} was not aligned; aligned: {', '.join(self.values)}") from None

    def __contains__(self, name: object) -> bool:
        return name in self.values

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.values)

    @property
    def fs(self) -> float | None:
        """The clock's rate, Hz, if the clock is uniform (to 1e-9 relative), else None."""
        if self.t.size < 2:
            return None
        step = np.diff(self.t)
        h = float(np.mean(step))
        if h > 0.0 and float(np.max(np.abs(step - h))) <= 1e-9 * max(h, abs(float(self.t[-1]))):
            return 1.0 / h
        return None

    def stack(self, names: Sequence[str] | None = None) -> NDArray[np.float64]:
        """The values as one (M, C) array, columns in the order of `names` (default: all)."""
        names = self.names if names is None else names
        return np.column_stack([self[n] for n in names])


def parse_specs(
    names_or_specs: str | Sequence[str | tuple[str, str]] | Mapping[str, str], default: str = "cubic"
) -> list[tuple[str, str]]:
    """[(name, kind), ...] from a name, names, (name, kind) pairs or a mapping name -> kind."""
    if isinstance(names_or_specs, str):
        items: list = [names_or_specs]
    elif isinstance(names_or_specs, Mapping):
        items = list(names_or_specs.items())
    else:
        items = list(names_or_specs)
    out: list[tuple[str, str]] = []
    for item in items:
        if isinstance(item, str):
            pair = (item, default)
        elif isinstance(item, Sequence) and len(item) == 2 and all(isinstance(x, str) for x in item):
            pair = (item[0], item[1])
        else:
            raise DataError(f"cannot read {item!r} as a channel name or a (name, kind) pair")
        if pair[1] not in KINDS:
            raise DataError(f"channel {pair[0]!r}: interpolation kind must be 'cubic' or 'linear', not {pair[1]!r}")
        out.append(pair)
    if not out:
        raise DataError("no channel asked for")
    names = [n for n, _ in out]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise DataError(f"channel(s) asked for twice: {', '.join(dup)}")
    return out


def _same_base(a: NDArray[np.float64], b: NDArray[np.float64]) -> bool:
    return a is b or (a.shape == b.shape and bool(np.array_equal(a, b)))


def _slice_of(base: NDArray[np.float64], clock: NDArray[np.float64]) -> slice | None:
    """The slice of `base` equal to `clock` (then no interpolation is needed), or None."""
    if base.size < clock.size or clock.size == 0:
        return None
    i0 = int(np.searchsorted(base, clock[0]))
    part = slice(i0, i0 + clock.size)
    if i0 + clock.size <= base.size and np.array_equal(base[part], clock):
        return part
    return None


def _clock(chans: Sequence[Channel], fs: float | None, t: ArrayLike | None, source: str | None) -> NDArray[np.float64]:
    if fs is not None and t is not None:
        raise DataError("give either fs (a uniform clock) or t (the times), not both")
    if t is not None:
        clock = np.asarray(t, dtype=np.float64)
        if clock.ndim != 1 or clock.size == 0:
            raise DataError(f"t must be a non-empty 1-D array of times in s, got shape {clock.shape}")
        bad = np.flatnonzero(~np.isfinite(clock))
        if bad.size:
            raise TimeBaseError(f"t[{int(bad[0])}] = {clock[bad[0]]} is not a finite time", sample=int(bad[0]))
        back = np.flatnonzero(np.diff(clock) <= 0.0)
        if back.size:
            k = int(back[0]) + 1
            raise TimeBaseError(
                f"t must be strictly increasing: t[{k}] = {clock[k]!r} s after t[{k - 1}] = {clock[k - 1]!r} s",
                sample=k,
            )
        for ch in chans:
            t0, t1 = ch.span
            if clock[0] < t0 or clock[-1] > t1:
                raise DataError(
                    f"{locate(source, ch)}: covers {t0:.6g}..{t1:.6g} s, not the clock asked for "
                    f"({float(clock[0]):.6g}..{float(clock[-1]):.6g} s); interpolation does not extrapolate: "
                    "restrict t to the channels' common span, or pass fs to get a clock inside it",
                    source=source,
                    channel=ch.name,
                )
        return clock
    starts = [ch.span[0] for ch in chans]
    ends = [ch.span[1] for ch in chans]
    if max(starts) > min(ends):
        late = chans[int(np.argmax(starts))]
        early = chans[int(np.argmin(ends))]
        raise DataError(
            f"{source + ': ' if source else ''}the channels do not overlap in time: {late.name!r} starts at "
            f"{max(starts):.6g} s, after {early.name!r} ends at {min(ends):.6g} s",
            source=source,
        )
    if fs is None:
        if all(_same_base(ch.time, chans[0].time) for ch in chans):
            return chans[0].time.copy()
        # The fastest channel's own stamps inside the common span: that channel (and any
        # sharing its base) is then copied, not interpolated.
        fastest = max((ch for ch in chans if ch.time.size >= 2), key=lambda ch: ch.rate)
        lo, hi = np.searchsorted(fastest.time, [max(starts), min(ends)], side="left")
        hi = hi + 1 if hi < fastest.time.size and fastest.time[hi] == min(ends) else hi
        clock = fastest.time[lo:hi].copy()
        if clock.size == 0:
            raise DataError(f"{source + ': ' if source else ''}the channels share no time span", source=source)
        return clock
    try:
        return common_clock([ch.time for ch in chans], fs)
    except SignalError as exc:
        raise DataError(f"{source + ': ' if source else ''}cannot build the clock: {exc}", source=source) from None


def align(
    specs: Sequence[InterpSpec],
    *,
    fs: float | None = None,
    t: ArrayLike | None = None,
    source: str | None = None,
    gap_factor: float | None = 2.0,
) -> Aligned:
    """Resample the channels of `specs` onto one clock (see the module docstring).

    Parameters
    ----------
    specs : what to align, each with its output key and interpolation kind.
    fs : Hz, or t : (M,) s, or neither (module docstring).
    source : file name for messages.
    gap_factor : as for `check_gaps`; None skips the gap check.

    Returns
    -------
    Aligned with `values[spec.name]` of shape (M,), in the channel's unit.
    """
    if not specs:
        raise DataError("no channel asked for")
    checked: set[int] = set()
    for s in specs:
        check_channel(s.channel, source=source, gap_factor=gap_factor, checked_times=checked)
    clock = _clock([s.channel for s in specs], fs, t, source)
    values: dict[str, NDArray[np.float64]] = {}
    # Group by (time base, kind) so that one spline is built per group.
    groups: list[tuple[NDArray[np.float64], str, list[InterpSpec]]] = []
    for s in specs:
        for base, kind, members in groups:
            if kind == s.kind and _same_base(base, s.channel.time):
                members.append(s)
                break
        else:
            groups.append((s.channel.time, s.kind, [s]))
    for base, kind, members in groups:
        part = _slice_of(base, clock)
        if part is not None:
            for s in members:
                view = s.channel.values[part]  # no copy: a read-only view of the channel
                view.flags.writeable = False
                values[s.name] = view
            continue
        stacked = np.column_stack([s.channel.values for s in members])
        try:
            out = resample(base, stacked, clock, kind=kind)
        except SignalError as exc:
            names = ", ".join(repr(s.channel.name) for s in members)
            raise DataError(
                f"{source + ': ' if source else ''}channel(s) {names}: cannot interpolate: {exc}",
                source=source,
                channel=members[0].channel.name,
            ) from None
        for i, s in enumerate(members):
            values[s.name] = np.ascontiguousarray(out[:, i])
    ordered = {s.name: values[s.name] for s in specs}
    return Aligned(clock, ordered, {s.name: s.channel.unit for s in specs}, source)
