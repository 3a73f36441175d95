"""The channel map: which file channel gives each model quantity, in which unit, how calibrated.

From the `[channels]` table of an identification config (TOML), one entry per model
quantity:

    [channels]
    roll  = { channel = "IMU_Roll", unit = "deg" }
    speed = { channel = "VehSpeed", unit = "km/h", interp = "linear" }
    z9    = { channel = "Clearance_RL", unit = "mm", scale = 1.02, offset = -12.5, sign = -1 }
    q     = { channels = ["Joint_1", "Joint_2"], unit = "rad" }   # a vector quantity
    ay    = "Acc_Y"                                                 # file's own unit

Keys: `channel` (or `channels`, a list, for a quantity with one channel per
component), `unit` (overrides the file's unit; needed when the file gives none),
`scale` (default 1), `offset` (default 0, in `unit`), `sign` (+1 or -1, default +1),
`interp` ("cubic" default, or "linear" for channels with steps). `scale`, `offset`
and `sign` may be lists, one per channel of `channels`.

The conversion, done once, here:

    value_SI = sign * to_si(scale * value_in_file + offset, unit)

i.e. scale and offset calibrate the file's number into `unit` (the unit written in
the same entry), then the unit is converted to SI, then the sign flips the axis
convention if the sensor's differs from the model's. (Computed as one multiply-add,
gain = sign * factor * scale and shift = sign * factor * offset, so a one-hour
channel is allocated once; a channel needing no change is passed as a read-only view.)
"""

from __future__ import annotations

import math
import numbers
import os
import tomllib
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..textfiles import TextEncodingError, read_utf8
from .align import KINDS, Aligned, InterpSpec, align
from .checks import check_channel, locate
from .errors import DataError, MappingError, UnitOverrideWarning, UnknownUnitError
from .recording import Channel, Recording
from .units import same_unit, unit_factor

KEYS = ("channel", "channels", "unit", "scale", "offset", "sign", "interp")


@dataclass(frozen=True)
class QuantitySpec:
    """One entry of the channel map (see the module docstring); per-channel tuples have one item per channel."""

    quantity: str
    channels: tuple[str, ...]
    unit: str | None
    scale: tuple[float, ...]
    offset: tuple[float, ...]
    sign: tuple[float, ...]
    interp: str = "cubic"
    vector: bool = False  # given as `channels = [...]`: values (n, k) even for k = 1


class ChannelMap:
    """Model quantity -> file channel(s) with unit, scale, offset, sign; converts to SI once.

    Build with `ChannelMap.from_dict` or `ChannelMap.from_toml`.
    """

    def __init__(self, specs: Mapping[str, QuantitySpec], source: str = "channel map") -> None:
        self.specs = dict(specs)
        self.source = source

    def __repr__(self) -> str:
        return f"ChannelMap({self.source!r}, quantities={list(self.specs)})"

    @property
    def quantities(self) -> tuple[str, ...]:
        return tuple(self.specs)

    # -- building -------------------------------------------------------------------------

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "channel map") -> ChannelMap:
        """From {quantity: entry} (module docstring); errors name `source` and the quantity."""
        if not isinstance(data, Mapping):
            raise MappingError(f"{source}: expected a table of quantity = {{ channel = ..., unit = ... }}")
        specs = {}
        for quantity, entry in data.items():
            specs[str(quantity)] = _parse_entry(str(quantity), entry, source)
        if not specs:
            raise MappingError(f"{source}: the channel map is empty")
        return cls(specs, source)

    @classmethod
    def from_toml(cls, path: str | os.PathLike[str], table: str | None = "channels") -> ChannelMap:
        """From a TOML file, its `[channels]` table (or the whole file when `table` is None)."""
        path = Path(path)
        try:
            data = tomllib.loads(read_utf8(path))
        except OSError as exc:
            raise MappingError(f"{path}: cannot read the channel map ({exc.strerror})", source=str(path)) from None
        except TextEncodingError as exc:
            raise MappingError(f"{path}: the channel map is {exc}", source=str(path)) from None
        except tomllib.TOMLDecodeError as exc:
            raise MappingError(f"{path}: not valid TOML: {exc}", source=str(path)) from None
        if table is not None:
            if table not in data:
                raise MappingError(f"{path}: no [{table}] table (the channel map)", source=str(path))
            data = data[table]
        return cls.from_dict(data, source=f"{path} [{table}]" if table else str(path))

    # -- using ----------------------------------------------------------------------------

    def channels_needed(self, quantities: Sequence[str] | None = None) -> list[str]:
        """File channels the quantities need, in map order, each once."""
        out: list[str] = []
        for q in self._select(quantities):
            out += [c for c in self.specs[q].channels if c not in out]
        return out

    def si_channels(
        self, recording: Recording, quantities: Sequence[str] | None = None, *, gap_factor: float | None = 2.0
    ) -> dict[str, list[Channel]]:
        """{quantity: [Channel in SI, one per file channel]} after the data checks.

        The SI channels keep the file channel's time base (same array) and lines; their
        name is the quantity (with "[i]" for component i of a vector quantity).
        """
        qs = self._select(quantities)
        recording.require(self.channels_needed(qs))
        out = {}
        checked: set[int] = set()
        for q in qs:
            spec = self.specs[q]
            chans = []
            si_units = set()
            for i, name in enumerate(spec.channels):
                raw = recording.channel(name)
                check_channel(raw, source=recording.label, gap_factor=gap_factor, checked_times=checked)
                unit = self._unit(spec, raw, recording.label)
                factor, si = unit_factor(unit, channel=f"{name!r} (quantity {q!r})", source=recording.label)
                values = _convert(raw.values, spec.scale[i], spec.offset[i], factor, spec.sign[i])
                si_units.add(si)
                key = f"{q}[{i}]" if spec.vector else q
                chans.append(Channel(key, si, values, raw.time, raw.lines))
            if len(si_units) > 1:
                raise MappingError(
                    f"{self.source}: quantity {q!r}: its channels have units of different kinds "
                    f"({', '.join(sorted(si_units))} in SI); give one unit for all with unit = ...",
                    source=recording.label,
                )
            out[q] = chans
        return out

    def apply(
        self, recording: Recording, quantities: Sequence[str] | None = None, *, gap_factor: float | None = 2.0
    ) -> dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]]:
        """{quantity: (t, values)} in SI, each on its channel's own time base.

        t is (n,) s; values (n,), or (n, k) for a quantity given by k `channels` (which
        must then share a time base; otherwise use `aligned`).
        """
        out = {}
        for q, chans in self.si_channels(recording, quantities, gap_factor=gap_factor).items():
            if not self.specs[q].vector:
                out[q] = (chans[0].time, chans[0].values)
                continue
            base = chans[0].time
            for ch in chans[1:]:
                if ch.time.shape != base.shape or not np.array_equal(ch.time, base):
                    raise DataError(
                        f"{recording.label}: quantity {q!r}: channels {self.specs[q].channels[0]!r} and "
                        f"{self.specs[q].channels[chans.index(ch)]!r} have different time bases; "
                        "use ChannelMap.aligned(recording, fs=...) to put them on one clock",
                        source=recording.label,
                    )
            out[q] = (base, np.column_stack([ch.values for ch in chans]))
        return out

    def aligned(
        self,
        recording: Recording,
        fs: float | None = None,
        t: ArrayLike | None = None,
        quantities: Sequence[str] | None = None,
        *,
        gap_factor: float | None = 2.0,
    ) -> Aligned:
        """The quantities in SI on one clock (as `Recording.aligned`), keyed by quantity.

        Values are (M,) per quantity, (M, k) for a vector quantity; `units` are SI.
        """
        si = self.si_channels(recording, quantities, gap_factor=gap_factor)
        specs = [InterpSpec(ch.name, ch, self.specs[q].interp) for q, chans in si.items() for ch in chans]
        # The checks ran on the file channels already; an SI channel has the same stamps.
        lined = align(specs, fs=fs, t=t, source=recording.label, gap_factor=gap_factor)
        values, units = {}, {}
        for q, chans in si.items():
            if self.specs[q].vector:
                values[q] = np.column_stack([lined[ch.name] for ch in chans])
            else:
                values[q] = lined[q]
            units[q] = chans[0].unit
        return Aligned(lined.t, values, units, recording.label)

    # -- helpers --------------------------------------------------------------------------

    def _select(self, quantities: Sequence[str] | None) -> list[str]:
        if quantities is None:
            return list(self.specs)
        if isinstance(quantities, str):
            quantities = [quantities]
        unknown = [q for q in quantities if q not in self.specs]
        if unknown:
            raise MappingError(
                f"{self.source}: quantity(ies) not in the channel map: {', '.join(unknown)}; "
                f"the map has: {', '.join(self.specs)}"
            )
        return list(quantities)

    def _unit(self, spec: QuantitySpec, raw: Channel, source: str) -> str:
        if spec.unit is None:
            if raw.unit.strip() == "":
                raise UnknownUnitError(
                    f"{locate(source, raw)}: the file gives no unit for this channel (quantity {spec.quantity!r}); "
                    f'add unit = "..." to the entry of {spec.quantity!r} in {self.source} '
                    '("-" if it is dimensionless)',
                    unit="",
                    source=source,
                    channel=raw.name,
                )
            return raw.unit
        if raw.unit.strip() and not same_unit(raw.unit, spec.unit) and raw.unit.strip() != spec.unit.strip():
            warnings.warn(
                f"{locate(source, raw)}: the file says the unit is {raw.unit!r}, {self.source} says {spec.unit!r} "
                f"for quantity {spec.quantity!r}; using {spec.unit!r} as the channel map says",
                UnitOverrideWarning,
                stacklevel=4,
            )
        return spec.unit


def _convert(raw: NDArray[np.float64], scale: float, offset: float, factor: float, sign: float) -> NDArray[np.float64]:
    """sign * factor * (scale * raw + offset), in one new array (a read-only view of raw when it is the identity)."""
    gain = sign * factor * scale
    shift = sign * factor * offset
    if gain == 1.0 and shift == 0.0:
        view = raw.view()
        view.flags.writeable = False
        return view
    out = raw * gain
    if shift != 0.0:
        out += shift
    return out


def _number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
        raise MappingError(f"{what} must be a finite number, not {value!r}")
    return float(value)


def _per_channel(value: Any, n: int, what: str, check) -> tuple[float, ...]:
    if isinstance(value, Sequence) and not isinstance(value, str):
        if len(value) != n:
            raise MappingError(f"{what} has {len(value)} item(s) but the entry has {n} channel(s)")
        return tuple(check(v, f"{what}[{i}]") for i, v in enumerate(value))
    return (check(value, what),) * n


def _sign(value: Any, what: str) -> float:
    if isinstance(value, bool) or value not in (1, -1):
        raise MappingError(f"{what} must be +1 or -1, not {value!r}")
    return float(value)


def _scale(value: Any, what: str) -> float:
    x = _number(value, what)
    if x == 0.0:
        raise MappingError(f"{what} must not be 0")
    return x


def _parse_entry(quantity: str, entry: Any, source: str) -> QuantitySpec:
    what = f"{source}: quantity {quantity!r}"
    if isinstance(entry, str):
        entry = {"channel": entry}
    if not isinstance(entry, Mapping):
        raise MappingError(f"{what}: expected a channel name or {{ channel = ..., unit = ... }}, not {entry!r}")
    unknown = [k for k in entry if k not in KEYS]
    if unknown:
        raise MappingError(f"{what}: unknown key(s) {', '.join(map(repr, unknown))}; allowed: {', '.join(KEYS)}")
    if ("channel" in entry) == ("channels" in entry):
        raise MappingError(f'{what}: give exactly one of channel = "name" or channels = ["a", "b", ...]')
    vector = "channels" in entry
    chans = entry["channels"] if vector else [entry["channel"]]
    if (
        isinstance(chans, str)
        or not isinstance(chans, Sequence)
        or not chans
        or not all(isinstance(c, str) and c for c in chans)
    ):
        raise MappingError(f"{what}: channel names must be non-empty strings, got {chans!r}")
    n = len(chans)
    unit = entry.get("unit")
    if unit is not None:
        if not isinstance(unit, str):
            raise MappingError(f"{what}: unit must be a string, not {unit!r}")
        unit_factor(unit, channel=f"{chans[0]!r} (quantity {quantity!r})", source=source)  # unknown -> error now
    interp = entry.get("interp", "cubic")
    if interp not in KINDS:
        raise MappingError(f"{what}: interp must be 'cubic' or 'linear', not {interp!r}")
    return QuantitySpec(
        quantity=quantity,
        channels=tuple(chans),
        unit=unit,
        scale=_per_channel(entry.get("scale", 1.0), n, f"{what}: scale", _scale),
        offset=_per_channel(entry.get("offset", 0.0), n, f"{what}: offset", _number),
        sign=_per_channel(entry.get("sign", 1), n, f"{what}: sign", _sign),
        interp=interp,
        vector=vector,
    )
