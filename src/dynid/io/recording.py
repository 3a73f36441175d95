"""`Recording`: a file's channels (each a `Channel`, one logged signal on its own time base).

Values stay in the file's unit here (the unit string is kept as written); conversion to
SI happens once, in `to_si` / `ChannelMap.apply`. Each channel keeps its own time base:
a vehicle logger records the inertial unit, the clearances and the wheels at different
rates, and `Recording.aligned` puts the ones needed onto one clock.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from numpy.typing import ArrayLike

from . import checks
from .align import Aligned, InterpSpec, align, parse_specs
from .channel import Channel
from .errors import DataError


@dataclass(eq=False)
class Recording:
    """The channels of one measurement file.

    Attributes
    ----------
    source : Path or None
        The file read (None for a recording built in memory).
    channels : dict name -> Channel, in file order.
    metadata : dict str -> str, what the file says about itself (format, start time, ...).
    skipped : dict name -> reason
        Columns or variables of the file that are not numeric channels (text, matrices),
        so that "channel missing" errors can say why.
    """

    source: Path | None
    channels: dict[str, Channel]
    metadata: dict[str, str] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.source is not None:
            self.source = Path(self.source)
        for key, ch in self.channels.items():
            if key != ch.name:
                raise DataError(f"channel stored under {key!r} is named {ch.name!r}", channel=ch.name)

    @classmethod
    def from_channels(
        cls, channels: Sequence[Channel], source: str | Path | None = None, metadata: Mapping[str, str] | None = None
    ) -> Recording:
        """A recording of the given channels (names must be unique)."""
        out: dict[str, Channel] = {}
        for ch in channels:
            if ch.name in out:
                raise DataError(f"two channels are named {ch.name!r}", channel=ch.name)
            out[ch.name] = ch
        return cls(None if source is None else Path(source), out, dict(metadata or {}))

    @property
    def label(self) -> str:
        """The file name used in messages."""
        return str(self.source) if self.source is not None else "<recording in memory>"

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.channels)

    def __contains__(self, name: object) -> bool:
        return name in self.channels

    def __iter__(self) -> Iterator[str]:
        return iter(self.channels)

    def __len__(self) -> int:
        return len(self.channels)

    def channel(self, name: str) -> Channel:
        """The channel called `name`; `MissingChannelError` listing close names and all names if absent."""
        ch = self.channels.get(name)
        if ch is None:
            raise checks.missing_error([name], self.channels, source=self.label, skipped=self.skipped)
        return ch

    def require(self, names: Sequence[str]) -> None:
        """Raise one `MissingChannelError` listing every name of `names` the file lacks."""
        checks.check_channels(list(names), self.channels, source=self.label, skipped=self.skipped)

    def check(self, names: Sequence[str] | None = None, *, gap_factor: float | None = 2.0) -> None:
        """Run the data checks (time base, NaN, gaps) on `names` (all channels by default).

        Raises the first `TimeBaseError` / `GapError` found, in channel order.
        """
        names = self.names if names is None else list(names)
        self.require(names)
        checked: set[int] = set()
        for name in names:
            checks.check_channel(self.channels[name], source=self.label, gap_factor=gap_factor, checked_times=checked)

    def saturation(
        self,
        names: Sequence[str] | None = None,
        *,
        limits: Mapping[str, tuple[float, float]] | None = None,
        min_samples: int = 5,
    ) -> dict[str, list[checks.Span]]:
        """Spans where channels sit at a range limit, with a `SaturationWarning` per channel flagged.

        `limits` maps a channel name to its sensor range (low, high) in the file's unit;
        channels without one are judged against their own minimum and maximum.
        Returns {name: spans} for the flagged channels only.
        """
        names = self.names if names is None else list(names)
        self.require(names)
        limits = dict(limits or {})
        out = {}
        for name in names:
            spans = checks.check_saturation(
                self.channels[name], limits=limits.get(name), min_samples=min_samples, source=self.label
            )
            if spans:
                out[name] = spans
        return out

    def aligned(
        self,
        names_or_specs: str | Sequence[str | tuple[str, str]] | Mapping[str, str],
        fs: float | None = None,
        t: ArrayLike | None = None,
        *,
        kind: str = "cubic",
        gap_factor: float | None = 2.0,
    ) -> Aligned:
        """The channels asked for, resampled onto one clock (values stay in the file's unit).

        Parameters
        ----------
        names_or_specs : a name, a sequence of names or of (name, kind) pairs, or a
            mapping name -> kind; kind is "cubic" (smooth channels) or "linear" (steps).
        fs : Hz, build a uniform clock at fs over the span every requested channel covers.
        t : array (M,), s, use these times instead (each channel must cover them).
            With neither: the channels' own time base if they all share one, else the
            fastest channel's own time stamps inside the span every channel covers.
        kind : default interpolation for names given without one.
        gap_factor : a time step above gap_factor x the channel's median step is a
            gap (`GapError`); None skips that check.

        Returns
        -------
        Aligned: `.t` (M,) s, `[name]` (M,) in the channel's unit, `.units`.

        Interpolation does not low-pass: going to a clock coarser than a channel's own,
        low-pass it first (`dynid.signals.lowpass`) or what lies above the new Nyquist
        frequency aliases.
        """
        specs = parse_specs(names_or_specs, kind)
        self.require([name for name, _ in specs])
        chans = [InterpSpec(name, self.channels[name], how) for name, how in specs]
        return align(chans, fs=fs, t=t, source=self.label, gap_factor=gap_factor)
