"""The identification config (TOML): model, tests and their roles, channels, conditioning, method.

    [model]
    example = "tx40"                 # or file = "robot.toml" (relative to this config),
                                     # or template = "peugeot406" (a car: see below)

    [[tests]]
    name = "exciting trajectory"
    role = "identify"                # or "validate" (cross-validation only)
    fs = 5000.0                      # sample rate when the files have no time column (with one: optional,
                                     # checked against it)
    start = 2.0                      # optional: s, the part of the test used (the files' time base)
    end = 58.0
    max_gap = 10                     # optional: longest hole in the time stamps, sample periods (default 10)
    files = { q = "pos.csv", tau = "torques.csv" }

    [channels]                       # quantity -> channels, one per joint, with the file's unit
    q = { channels = ["Joint_1", "Joint_2"], unit = "rad" }
    tau = { channels = ["Joint_1", "Joint_2"], unit = "N.m" }

    [transmission]                   # optional: joint = matrix @ channels (+ offset)
    q = [["1/32", 0], [0, "1/32"]]
    q_offset = [0, "-pi/2"]
    tau = [[32, 0], [0, 32]]

    [conditioning]
    cutoff = 25.0                    # Hz, zero-phase Butterworth on positions
    order = 4
    border = 0.1                     # s trimmed at each end (default: the filter transient)
    decimate = [10, 10]
    min_speed = { 1 = 0.05 }         # rows of joint 1 dropped where |qd1| < 0.05

    [identification]
    method = "wls"                   # or "ols"
    known = { IA1 = 0.36 }           # fixed parameters: their contribution moves to Y
    poor_factor = 20.0               # the paper's rule: %σ > 20 x the smallest %σ ("paper rule" column)
    flag_percent = 2.5               # "uncertain": total σ above 2.5 % of the parameter's scale (the flag to act on)

    [reference]                      # optional: a published base-parameter table to compare with
    file = "published.csv"
    names = { Izz = "ZZ" }
    combinations = { fvm6 = "1024*fvm6" }

A car (template = "peugeot406") reads one logger file per test with the channels of
`dynid.vehicle.sensors` (`file = "sine.csv"`, and optionally `truth = "sine.json"`, the
simulator's sidecar with the true parameters), estimates the 42 joints from them and
assembles the paper's 14 equations:

    [channels]                       # only where the file's names differ from the suite's
    imu_yaw_rate = { channel = "GyroZ", unit = "deg/s" }

    [conditioning]
    cutoff = 4.0                     # Hz, on every signal (the paper: ~3 Hz, order 5-8)
    order = 4
    decimate = [5, 10]
    attitude_crossover = 0.2         # Hz: inclinometers below, integrated gyros above
    segment = 60.0                   # s: long tests are processed in overlapping segments (bounded memory)
    compensate_delays = true         # advance each channel by its sensor's delay (band limit, hold); false
                                     # for channels a logger already aligned
    min_speed = 0.01                 # m/s: damper rows left out where |clearance rate| is below (dry
                                     # friction is undefined at reversal); or { 9 = 0.01, 27 = 0.02 }; 0: none

    [identification]
    method = "wls"                   # or "iv": IDIM-IV, instruments from the suspensions simulated with the
    iv_passes = 2                    # last estimate, driven by the measured loads (vehicle.instruments)
    base = "generic"                 # "generic" (the paper's 48) or "car" (44, see vehicle.equations)
    aero = true                      # the aerodynamic wrench of the template's tables in Y

    [uncertainty]                    # optional: the sensors' zero offsets (1 sigma, each channel's unit),
    offsets = { imu_az = 0.01, laser_height_rl = 0.5 }   # propagated to the estimates (%σ total)
    segments = 2                     # segments per test on which their effect is evaluated

Every error names the config file and the key, and says what is expected.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..model import ModelError
from ..model.files import parse_number, read_toml
from .robot import Conditioning


class ConfigError(ModelError):
    """A config that cannot be used, naming the file and key."""


@dataclass(frozen=True)
class TestSpec:
    name: str
    role: str
    files: dict[str, Path]
    fs: float | None
    truth: Path | None = None
    start: float | None = None  # s, in the files' time base: the part of the test used
    end: float | None = None
    max_gap: float = 10.0  # sample periods: a longer hole in the time stamps is refused


@dataclass(frozen=True)
class ChannelSpec:
    channels: tuple[str, ...]
    unit: str | None


@dataclass(frozen=True)
class CarSettings:
    """The car's conditioning and options (see the module doc)."""

    cutoff: float = 4.0
    order: int = 4
    decimate: tuple[int, ...] = (5, 10)
    attitude_crossover: float = 0.2
    segment: float = 60.0
    compensate_delays: bool = True
    min_speed: dict[int, float] = field(default_factory=lambda: dict.fromkeys(DAMPER_FRAMES, 0.01))
    base: str = "generic"
    aero: bool = True
    offsets: dict[str, float] = field(default_factory=dict)  # channel -> 1-sigma zero offset, channel unit
    offset_segments: int = 2
    iv_passes: int = 2  # method = "iv": simulate with the last estimate and re-estimate, this many times


@dataclass(frozen=True)
class IdentifyConfig:
    path: Path
    model: str | Path
    tests: tuple[TestSpec, ...]
    channels: dict[str, ChannelSpec]
    transmission: dict[str, np.ndarray] = field(default_factory=dict)
    conditioning: Conditioning = field(default_factory=Conditioning)
    method: str = "wls"
    known: dict[str, float] = field(default_factory=dict)
    poor_factor: float = 20.0
    flag_percent: float = 2.5
    reference: dict[str, Any] | None = None
    car: CarSettings | None = None

    @property
    def kind(self) -> str:
        return "car" if self.car is not None else "robot"


_TEST_KEYS = {"name", "role", "fs", "files", "file", "truth", "start", "end", "max_gap"}
_TOP = {"model", "tests", "channels", "transmission", "conditioning", "identification", "reference", "uncertainty"}


def load_config(path: str | Path) -> IdentifyConfig:
    path = Path(path)
    data = read_toml(path, "config", ConfigError)
    here = path.resolve().parent

    def err(key: str, msg: str) -> ConfigError:
        return ConfigError(f"{path}: [{key}] {msg}")

    unknown = set(data) - _TOP
    if unknown:
        raise ConfigError(f"{path}: unknown section(s) {sorted(unknown)}; sections: {sorted(_TOP)}")
    m = data.get("model", {})
    car = None
    if "template" in m:
        model: str | Path = str(m["template"])
        car = _car_settings(data, err)
    elif "example" in m:
        model: str | Path = str(m["example"])
    elif "file" in m:
        model = here / m["file"]
    else:
        raise err("model", "give example = \"tx40\" (a shipped model), file = \"model.toml\" "
                           "or template = \"peugeot406\"")

    if "uncertainty" in data and car is None:
        raise err("uncertainty", "sensor offsets are propagated for the car template only; remove the section")
    tests = []
    for i, t in enumerate(data.get("tests", []), start=1):
        key = f"tests {i}"
        if car is not None:
            if not isinstance(t.get("file"), str):
                raise err(key, "needs file = \"test.csv\" (one logger file with the sensor suite's channels)")
            if {"start", "end", "max_gap"} & set(t):
                raise err(key, "start, end and max_gap are for robot tests; cut the car's logger file instead")
            t = {**t, "files": {"channels": t["file"]}}
        if not isinstance(t.get("files"), dict) or not t["files"]:
            raise err(key, "needs files = { quantity = \"file\", ... }")
        role = t.get("role", "identify")
        if role not in ("identify", "validate"):
            raise err(key, f"role = {role!r}; use \"identify\" or \"validate\"")
        files = {q: here / f for q, f in t["files"].items()}
        for q, f in files.items():
            if not f.exists():
                raise err(key, f"file for {q!r} not found: {f}")
        extra = set(t) - _TEST_KEYS
        if extra:
            raise err(key, f"unknown key(s) {sorted(extra)}; keys: {', '.join(sorted(_TEST_KEYS))}")
        fs = t.get("fs")
        if fs is not None and not _number(fs, lambda v: v > 0):
            raise err(key, f"fs = {fs!r}; give the sample rate in Hz (a positive number)")
        window = {k: t.get(k) for k in ("start", "end")}
        for k, v in window.items():
            if v is not None and not _number(v):
                raise err(key, f"{k} = {v!r}; give a time in s (a number, in the files' time base)")
        if None not in window.values() and not window["start"] < window["end"]:
            raise err(key, f"start = {window['start']!r} s is not before end = {window['end']!r} s")
        max_gap = t.get("max_gap", 10.0)
        if not _number(max_gap, lambda v: v >= 1):
            raise err(key, f"max_gap = {max_gap!r}; give the longest hole allowed in the time stamps, in sample "
                           "periods (a number >= 1)")
        truth = here / t["truth"] if "truth" in t else None
        if truth is not None and not truth.exists():
            raise err(key, f"truth file not found: {truth}")
        tests.append(TestSpec(str(t.get("name", f"test {i}")), role, files, None if fs is None else float(fs), truth,
                              *(None if v is None else float(v) for v in window.values()), float(max_gap)))
    if not any(t.role == "identify" for t in tests):
        raise err("tests", "at least one test must have role = \"identify\"")

    channels = {}
    for q, spec in data.get("channels", {}).items():
        if car is not None:  # a renamed sensor channel: { channel = "...", unit = "..." }
            if not isinstance(spec, dict) or "channel" not in spec:
                raise err(f"channels.{q}", "expected { channel = \"name in the file\", unit = \"...\" }")
            channels[q] = ChannelSpec((spec["channel"],), spec.get("unit"))
            continue
        if not isinstance(spec, dict) or "channels" not in spec:
            raise err(f"channels.{q}", "expected { channels = [...], unit = \"...\" }")
        channels[q] = ChannelSpec(tuple(spec["channels"]), spec.get("unit"))

    transmission = {}
    for k, v in data.get("transmission", {}).items():
        try:
            transmission[k] = np.array(
                [[parse_number(x, k) for x in row] if isinstance(row, list) else parse_number(row, k) for row in v])
        except ModelError as exc:
            raise err("transmission", str(exc)) from None

    c = {} if car is not None else data.get("conditioning", {})
    extra = set(c) - {"cutoff", "order", "border", "decimate", "min_speed"}
    if extra:
        raise err("conditioning", f"unknown key(s) {sorted(extra)}")
    decimate = c.get("decimate", [10, 10])
    cond = Conditioning(
        cutoff=float(c.get("cutoff", 25.0)),
        order=int(c.get("order", 4)),
        border=None if c.get("border") is None else float(c["border"]),
        decimate=tuple(int(x) for x in (decimate if isinstance(decimate, list) else [decimate])),
        min_speed={int(k): float(v) for k, v in c.get("min_speed", {}).items()},
    )
    ident = data.get("identification", {})
    method = str(ident.get("method", "wls")).lower()
    if method not in ("ols", "wls", "iv"):
        raise err("identification", f"method = {method!r}; use \"ols\", \"wls\" or \"iv\" (a car)")
    if method == "iv" and car is None:
        raise err("identification", "method = \"iv\" takes its instruments from a simulation of the car's "
                  "suspensions driven by the measured loads; a robot has none here: use \"wls\"")
    ref = data.get("reference")
    if ref is not None:
        if "file" not in ref:
            raise err("reference", "needs file = \"published.csv\"")
        ref = {**ref, "file": here / ref["file"]}
        if not ref["file"].exists():
            raise err("reference", f"file not found: {ref['file']}")
    return IdentifyConfig(
        path=path, model=model, tests=tuple(tests), channels=channels, transmission=transmission,
        conditioning=cond, method=method, known={k: float(v) for k, v in ident.get("known", {}).items()},
        poor_factor=float(ident.get("poor_factor", 20.0)), flag_percent=_positive(ident, "flag_percent", 2.5, err),
        reference=ref, car=car,
    )


def _car_settings(data: dict, err) -> CarSettings:
    c = data.get("conditioning", {})
    extra = set(c) - {"cutoff", "order", "decimate", "attitude_crossover", "segment", "compensate_delays",
                      "min_speed"}
    if extra:
        raise err("conditioning", f"unknown key(s) {sorted(extra)} for a car")
    ident = data.get("identification", {})
    base = str(ident.get("base", "generic"))
    if base not in ("generic", "car"):
        raise err("identification", f"base = {base!r}; use \"generic\" (the paper's 48) or \"car\"")
    d = c.get("decimate", [5, 10])
    offsets, segments = _offsets(data.get("uncertainty", {}), err)
    return CarSettings(
        cutoff=float(c.get("cutoff", 4.0)), order=int(c.get("order", 4)),
        decimate=tuple(int(x) for x in (d if isinstance(d, list) else [d])),
        attitude_crossover=float(c.get("attitude_crossover", 0.2)), segment=float(c.get("segment", 60.0)),
        compensate_delays=_flag(c, "compensate_delays", True, err), min_speed=_car_min_speed(c, err),
        base=base, aero=bool(ident.get("aero", True)), offsets=offsets, offset_segments=segments,
        iv_passes=_iv_passes(ident, err),
    )


def _iv_passes(ident: dict, err) -> int:
    n = ident.get("iv_passes", 2)
    if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= 10:
        raise err("identification", f"iv_passes = {n!r}: give a whole number from 1 to 10 (IDIM-IV passes: "
                  "simulate the suspensions with the last estimate, re-estimate)")
    return n


DAMPER_FRAMES = (9, 18, 27, 36)


def _car_min_speed(c: dict, err) -> dict[int, float]:
    """[conditioning] min_speed for a car: one speed (m/s) for the four dampers, or { 9 = 0.01, ... }."""
    raw = c.get("min_speed", 0.01)
    table = dict.fromkeys(DAMPER_FRAMES, raw) if isinstance(raw, int | float) and not isinstance(raw, bool) else raw
    if not isinstance(table, dict):
        raise err("conditioning", f"min_speed = {raw!r}; use a speed in m/s (0.01) or {{ 9 = 0.01, 27 = 0.02 }}")
    out = {}
    for k, v in table.items():
        if str(k) not in {str(d) for d in DAMPER_FRAMES} or isinstance(v, bool) or not isinstance(v, int | float) \
                or v < 0:
            raise err("conditioning", f"min_speed: {k} = {v!r}; keys are the damper frames "
                      f"{', '.join(map(str, DAMPER_FRAMES))}, values speeds >= 0 in m/s")
        out[int(k)] = float(v)
    return out


def _number(value, ok=lambda v: True) -> bool:
    """A finite int or float (not a bool) for which `ok` holds."""
    return (not isinstance(value, bool) and isinstance(value, int | float) and bool(np.isfinite(value))
            and bool(ok(value)))


def _positive(table: dict, key: str, default: float, err) -> float:
    value = table.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
        raise err("identification", f"{key} = {value!r}; use a positive number")
    return float(value)


def _flag(table: dict, key: str, default: bool, err) -> bool:
    value = table.get(key, default)
    if not isinstance(value, bool):
        raise err("conditioning", f"{key} = {value!r}; use true or false")
    return value


def _offsets(u: dict, err) -> tuple[dict[str, float], int]:
    """[uncertainty] offsets = { channel = 1-sigma zero offset in the channel's unit }, segments = n."""
    from ..vehicle.estimate import required_channels

    extra = set(u) - {"offsets", "segments"}
    if extra:
        raise err("uncertainty", f"unknown key(s) {sorted(extra)}; keys: offsets, segments")
    raw = u.get("offsets", {})
    if not isinstance(raw, dict):
        raise err("uncertainty", "offsets must be a table { channel = 1-sigma zero offset in its unit, ... }")
    known = required_channels(spin=False)
    offsets = {}
    for name, v in raw.items():
        if name not in known:
            raise err("uncertainty", f"offsets: no channel {name!r} among the sensor suite's; channels: "
                                     f"{', '.join(known)}")
        try:
            value = parse_number(v, f"offsets.{name}")
        except ModelError as exc:
            raise err("uncertainty", str(exc)) from None
        if not np.isfinite(value) or value < 0:
            raise err("uncertainty", f"offsets.{name} = {v!r}: give a standard deviation >= 0 in the channel's unit")
        if value > 0:
            offsets[name] = value
    segments = u.get("segments", 2)
    if isinstance(segments, bool) or not isinstance(segments, int) or segments < 1:
        raise err("uncertainty", f"segments = {segments!r}: give a whole number >= 1 (segments per test on which "
                                 "the offsets' effect is evaluated)")
    return offsets, segments
