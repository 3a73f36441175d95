"""The logger's own sensor dynamics: what each channel went through before it was written, hence how far it lags.

A logger writes each channel late by its sensors' and its own filters: a band limit delays a slow signal by
its group delay, a sensor sampling slower than the logger holds each value for a while, a bus or a processor
adds a fixed latency. The estimator undoes them (`estimate.compensate`: the band limit's phase exactly, the
hold and the latency by a shift) so that the two sides of Y = W X describe the same instant: an inertial unit
25 ms late against the force transducers is several degrees of phase at 0.5 Hz, enough to move an inertia by
half.

The vehicle file declares them in `[sensors.dynamics]` (docs/vehicle.md):

    [sensors.dynamics]
    default = "table1"                          # the paper's Table-1 suite (the default), or "none"
    "wft_*" = "none"                            # a pattern: already aligned by the logger
    imu = { bandwidth_hz = 10, rate_hz = 125 }  # a group (imu, correvit, gnss, clearances, wheel_angles,
                                                # lasers, wft, steering_wheel): its channels
    imu_yaw_rate = { bandwidth_hz = 20, order = 4, delay_ms = 5 }   # one channel

An entry is "table1" (the channel's Table-1 band limit and rate, `sensors.py`), "none" (no delay: the logger
aligned it) or a table of `bandwidth_hz` (the -3 dB frequency of a Butterworth low-pass; absent: no band
limit), `order` (of that Butterworth, default 2), `rate_hz` (the sensor's own sample rate, each value held
until the next; absent: the logger's rate) and `delay_ms` (a pure delay: transport, processing). A channel
takes its own entry, else its group's, else the pattern's that matches it, else `default`; two patterns
matching one channel are an error.

`GROUPS` are the channel groups a key may name, each the channels one device (or one band of it) writes; the
identification estimates the delay of some of them relative to the wheel force transducers, the REFERENCE
(`pipeline/delays.py`).
"""

from __future__ import annotations

import fnmatch
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from ..model.files import did_you_mean
from ..model.tree import ModelError
from .sensors import SensorChannel, SensorSuite

TABLE1 = "table1"
NONE = "none"
ENTRY_KEYS = ("bandwidth_hz", "order", "rate_hz", "delay_ms")
MAX_DELAY_MS = 500.0  # a channel half a second late is a clock or a unit slip, not a sensor
MAX_ORDER = 10

# group -> (what it is, the channel-name prefixes it holds); the wheel force transducers (and the wheel speeds,
# the same device) are the reference the others' delays are estimated against
DEVICES: dict[str, tuple[str, tuple[str, ...]]] = {
    "imu": ("inertial unit", ("imu_",)),
    "correvit": ("Correvit", ("correvit_",)),
    "gnss": ("GNSS/INS velocity", ("gnss_",)),
    "clearances": ("damper clearances (cameras or potentiometers)", ("clearance_",)),
    "wheel_angles": ("steering and camber cameras", ("steer_", "camber_")),
    "lasers": ("height lasers", ("laser_height_",)),
}
REFERENCE = ("wft", ("wheel force transducers and wheel speeds", ("wft_", "wheel_speed_")))
GROUPS = {**DEVICES, REFERENCE[0]: REFERENCE[1], "steering_wheel": ("steering-wheel encoder", ("steering_wheel",))}


class DynamicsError(ModelError):
    """A `[sensors.dynamics]` entry that cannot be used: the message names the key and the fix."""


@dataclass(frozen=True)
class ChannelDynamics:
    """What the logger did to one channel: a Butterworth band limit (bandwidth Hz, None: none; order), a sample
    and hold at the sensor's `rate` (Hz, None: the logger's), a pure `delay` (s). source: where it was declared."""

    bandwidth: float | None = None
    order: int = 2
    rate: float | None = None
    delay: float = 0.0
    source: str = NONE

    @classmethod
    def table1(cls, channel: SensorChannel) -> ChannelDynamics:
        """The channel's Table-1 sensor (sensors.py): a 2nd-order Butterworth at its bandwidth, held at its rate."""
        return cls(channel.bandwidth, 2, channel.rate, 0.0, TABLE1)

    def lag(self, fs: float) -> float:
        """Low-frequency delay (s) on a logger at fs Hz: the band limit's group delay at zero frequency,
        1 / (2 pi f_c sin(pi / 2n)) for an n-th order Butterworth (sqrt(2) / (2 pi f_c) for the 2nd order),
        plus the mean age of a held value when the sensor samples slower than the logger, plus the pure delay."""
        out = self.delay + self.band_delay()
        if self.rate is not None:
            # a value held from the sensor's sample until the next is read on the logger's ticks: its age is
            # uniform over 0, 1/fs, ..., 1/rate - 1/fs, mean (1/rate - 1/fs) / 2 -- continuous in fs, so a time
            # column's rounding (fs = 625.0000000000688 for a 625 Hz sensor) gives no spurious delay
            out += max(0.0, 0.5 * (1.0 / self.rate - 1.0 / fs))
        return out

    def band_delay(self) -> float:
        """The band limit's group delay at zero frequency (s; 0 without one)."""
        if self.bandwidth is None:
            return 0.0
        return 1.0 / (2 * math.pi * self.bandwidth * math.sin(math.pi / (2 * self.order)))

    def describe(self, fs: float) -> str:
        """In words, on a logger at fs Hz."""
        if self.source == NONE:
            return "none (aligned by the logger)"
        parts = []
        if self.bandwidth is not None:
            parts.append(f"{self.bandwidth:g} Hz band limit (Butterworth, order {self.order})")
        if self.rate is not None and self.rate < fs:
            parts.append(f"sampled at {self.rate:g} Hz and held")
        if self.delay:
            parts.append(f"{1e3 * self.delay:g} ms pure delay")
        return ", ".join(parts) or "no delay"


@dataclass(frozen=True)
class LoggerDynamics:
    """Each channel's declared dynamics (name -> ChannelDynamics) and the file's `default`."""

    channels: Mapping[str, ChannelDynamics]
    default: str = TABLE1
    declared: tuple[str, ...] = field(default=())  # the file's keys other than default, in its order

    def lags(self, fs: float) -> dict[str, float]:
        """name -> low-frequency delay (s) of every channel on a logger at fs Hz."""
        return {n: d.lag(fs) for n, d in self.channels.items()}

    def summary(self, fs: float) -> list[str]:
        """One line per group of channels sharing the same dynamics: what was declared and the delay."""
        over = f", overridden: {', '.join(self.declared)}" if self.declared else ""
        out = [f"Sensor dynamics ([sensors.dynamics] default {self.default!r}{over}), delay at {fs:g} Hz:"]
        rows: dict[tuple, list[str]] = {}
        for n, d in self.channels.items():
            rows.setdefault((d.describe(fs), round(d.lag(fs), 9)), []).append(n)
        for (what, lag), names in rows.items():
            out.append(f"  {1e3 * lag:7.2f} ms  {what}: {_compact(names)}")
        return out


def _compact(names: list[str]) -> str:
    """Channel names, a device's run written as its prefix: "wft_* (24)"."""
    out, seen = [], set()
    for _, prefixes in GROUPS.values():
        for p in prefixes:
            mine = [n for n in names if n.startswith(p)]
            if len(mine) > 2:
                out.append(f"{p}* ({len(mine)})")
                seen.update(mine)
    out += [n for n in names if n not in seen]
    return ", ".join(out)


def group_channels(group: str, names) -> list[str]:
    """The channels of `names` in a group of GROUPS."""
    prefixes = GROUPS[group][1]
    return [n for n in names if n.startswith(prefixes)]


def table1_dynamics(suite: SensorSuite) -> LoggerDynamics:
    """Every channel of the suite with its Table-1 dynamics (what dynid assumed before loggers declared theirs)."""
    return LoggerDynamics({c.name: ChannelDynamics.table1(c) for c in suite})


def parse_dynamics(table: object, suite: SensorSuite, where: str) -> LoggerDynamics:
    """[sensors.dynamics] of a vehicle file checked against the channels the car carries (module doc)."""
    sec = "[sensors.dynamics]"
    if not isinstance(table, dict):
        raise DynamicsError(f"{where}: {sec} must be a table, e.g. default = \"table1\" and \"wft_*\" = \"none\"; "
                            f"got {table!r}")
    names = list(suite.names)
    default = table.get("default", TABLE1)
    if default not in (TABLE1, NONE):
        raise DynamicsError(f"{where}: {sec} default = {default!r} must be \"table1\" (the paper's Table-1 sensors) "
                            "or \"none\" (every channel already aligned by the logger)")
    out = {c.name: _entry(default, c, where, f"{sec} default") for c in suite}
    exact, groups, patterns = {}, {}, {}
    for key, spec in table.items():
        if key == "default":
            continue
        if not isinstance(key, str) or not key:
            raise DynamicsError(f"{where}: {sec}: empty key")
        if key in names:
            exact[key] = spec
        elif key in GROUPS:
            members = group_channels(key, names)
            if not members:
                raise DynamicsError(f"{where}: {sec} {key}: this car carries no {GROUPS[key][0]} "
                                    f"({', '.join(p + '*' for p in GROUPS[key][1])}); remove the entry")
            groups[key] = spec
        elif any(ch in key for ch in "*?["):
            if not fnmatch.filter(names, key):
                raise DynamicsError(f"{where}: {sec} {key!r} matches no channel of this car; channels: "
                                    f"{', '.join(names)}")
            patterns[key] = spec
        else:
            hint = did_you_mean(key, names + list(GROUPS) + ["default"])
            raise DynamicsError(f"{where}: {sec}: unknown channel {key!r};{hint or ''} keys are default, a channel "
                                f"of this car, a group ({', '.join(GROUPS)}) or a pattern such as \"wft_*\"")
    # the most specific entry wins: a channel, then its group, then a pattern (two patterns on one channel: error)
    by_pattern: dict[str, str] = {}
    for key in patterns:
        for n in fnmatch.filter(names, key):
            if n in by_pattern and n not in exact:
                raise DynamicsError(f"{where}: {sec}: the patterns {by_pattern[n]!r} and {key!r} both match {n}: "
                                    f"give {n} its own entry, or narrow one pattern")
            by_pattern[n] = key
    for n, key in by_pattern.items():
        out[n] = _entry(patterns[key], suite[n], where, f"{sec} {key!r}")
    for key, spec in groups.items():
        for n in group_channels(key, names):
            out[n] = _entry(spec, suite[n], where, f"{sec} {key}")
    for n, spec in exact.items():
        out[n] = _entry(spec, suite[n], where, f"{sec} {n}")
    return LoggerDynamics(out, default, tuple(k for k in table if k != "default"))


def _entry(spec: object, channel: SensorChannel, where: str, what: str) -> ChannelDynamics:
    if spec == TABLE1:
        return ChannelDynamics.table1(channel)
    if spec == NONE:
        return ChannelDynamics()
    if not isinstance(spec, dict):
        raise DynamicsError(f"{where}: {what} = {spec!r} must be \"table1\", \"none\" or a table such as "
                            "{ bandwidth_hz = 10, rate_hz = 125, delay_ms = 2 }")
    unknown = [k for k in spec if k not in ENTRY_KEYS]
    if unknown:
        hint = did_you_mean(unknown[0], ENTRY_KEYS)
        raise DynamicsError(f"{where}: {what}: unknown key {unknown[0]!r};{hint or ''} keys: "
                            f"{', '.join(ENTRY_KEYS)}")
    if not spec:
        raise DynamicsError(f"{where}: {what} = {{}} declares nothing: give bandwidth_hz, rate_hz or delay_ms, or "
                            "\"none\"")

    def number(key: str, lo: float, hi: float) -> float | None:
        if key not in spec:
            return None
        v = spec[key]
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or not lo <= v <= hi:
            raise DynamicsError(f"{where}: {what}: {key} = {v!r} must be a number in {lo:g}..{hi:g}"
                                + (" (milliseconds)" if key.endswith("_ms") else " (Hz)" if key.endswith("_hz")
                                   else ""))
        return float(v)

    bandwidth = number("bandwidth_hz", 1e-3, 1e6)
    if bandwidth is not None and bandwidth <= 0:
        raise DynamicsError(f"{where}: {what}: bandwidth_hz must be > 0")
    order = spec.get("order", 2)
    if isinstance(order, bool) or not isinstance(order, int) or not 1 <= order <= MAX_ORDER:
        raise DynamicsError(f"{where}: {what}: order = {order!r} must be a whole number 1..{MAX_ORDER} (of the "
                            "Butterworth band limit)")
    if "order" in spec and bandwidth is None:
        raise DynamicsError(f"{where}: {what}: order without bandwidth_hz: give the band limit's -3 dB frequency")
    rate = number("rate_hz", 1e-3, 1e6)
    if rate is not None and rate <= 0:
        raise DynamicsError(f"{where}: {what}: rate_hz must be > 0")
    delay = number("delay_ms", 0.0, MAX_DELAY_MS)
    return ChannelDynamics(bandwidth, order, rate, 1e-3 * (delay or 0.0), "declared")


__all__ = ["DEVICES", "GROUPS", "REFERENCE", "ChannelDynamics", "DynamicsError", "LoggerDynamics",
           "group_channels", "parse_dynamics", "table1_dynamics"]
