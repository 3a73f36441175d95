"""Units of measurement files, converted to SI once, at the file boundary.

The table is multiplicative: value_SI = factor * value (no unit here needs an offset;
temperatures are not in it). The SI unit strings returned are plain ASCII:

    rad, rad/s, rad/s^2, m, m/s, m/s^2, N, N*m, kg, A, s, Hz, Pa, 1 (dimensionless)

Spelling is forgiving where it cannot be ambiguous: surrounding brackets ("[deg]"),
superscripts ("m/s²" = "m/s^2" = "m/s2"), product signs ("N·m" = "N.m" = "N*m" =
"N m" = "Nm"), "sec" for "s", the micro sign, and letter case when only one unit of
the table matches ("KM/H", "Deg", "RPM"). Choices a vehicle engineer expects:

- "g" is the standard gravity 9.80665 m/s^2 (accelerometers), never the gram;
- "%" is the fraction 0.01 (dimensionless "1"), "-", "" and "1" are dimensionless;
- "rpm", "rev/s" ("tr/s", "tr/min" in French) are angular rates, converted to rad/s.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import FileFormatError, UnknownUnitError

STANDARD_GRAVITY = 9.80665  # m/s^2, by definition (3rd CGPM, 1901)

_DEG = math.pi / 180.0
_REV = 2.0 * math.pi

# SI unit -> {spelling: factor}. The first spelling of each group is the SI one.
_GROUPS: dict[str, dict[str, float]] = {
    "rad": {"rad": 1.0, "mrad": 1e-3, "deg": _DEG, "°": _DEG, "degree": _DEG, "degrees": _DEG},
    "rad/s": {
        "rad/s": 1.0,
        "mrad/s": 1e-3,
        "deg/s": _DEG,
        "°/s": _DEG,
        "degree/s": _DEG,
        "degrees/s": _DEG,
        "dps": _DEG,
        "rpm": _REV / 60.0,
        "rev/min": _REV / 60.0,
        "r/min": _REV / 60.0,
        "tr/min": _REV / 60.0,
        "rev/s": _REV,
        "r/s": _REV,
        "tr/s": _REV,
        "rps": _REV,
    },
    "rad/s^2": {"rad/s^2": 1.0, "deg/s^2": _DEG, "°/s^2": _DEG},
    "m": {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "km": 1e3, "um": 1e-6},
    "m/s": {
        "m/s": 1.0,
        "mm/s": 1e-3,
        "cm/s": 1e-2,
        "km/h": 1.0 / 3.6,
        "kph": 1.0 / 3.6,
        "kmh": 1.0 / 3.6,
        "km/hr": 1.0 / 3.6,
        "mph": 0.44704,  # international mile 1609.344 m per hour
    },
    "m/s^2": {"m/s^2": 1.0, "mm/s^2": 1e-3, "g": STANDARD_GRAVITY},
    "N": {"N": 1.0, "kN": 1e3, "daN": 10.0},
    "N*m": {"N*m": 1.0, "Nm": 1.0, "kN*m": 1e3, "kNm": 1e3, "daN*m": 10.0, "N*mm": 1e-3, "Nmm": 1e-3},
    "kg": {"kg": 1.0},
    "A": {"A": 1.0, "mA": 1e-3},  # a motor's current (drive gains: tau_m = g i)
    "s": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0, "h": 3600.0},
    "Hz": {"Hz": 1.0, "kHz": 1e3},
    "Pa": {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "bar": 1e5, "mbar": 1e2},
    "1": {"1": 1.0, "-": 1.0, "": 1.0, "%": 0.01},
}

_TABLE: dict[str, tuple[float, str]] = {
    spelling: (factor, si) for si, group in _GROUPS.items() for spelling, factor in group.items()
}
_FOLDED: dict[str, list[str]] = {}
for _key in _TABLE:
    _FOLDED.setdefault(_key.casefold(), []).append(_key)

_SUPERSCRIPTS = {"²": "^2", "³": "^3", "µ": "u", "μ": "u", "⋅": "*", "·": "*", "×": "*"}


def normalize_unit(unit: str) -> str:
    """The unit spelled the way the table spells it (not yet checked against the table).

    "[deg/s]" -> "deg/s", "m/s²" -> "m/s^2", "N.m" -> "N*m", "deg/sec" -> "deg/s".
    """
    u = str(unit).strip()
    while len(u) >= 2 and (u[0], u[-1]) in (("[", "]"), ("(", ")"), ("{", "}")):
        u = u[1:-1].strip()
    for old, new in _SUPERSCRIPTS.items():
        u = u.replace(old, new)
    u = u.replace("**", "^")
    u = re.sub(r"\s*/\s*", "/", u)
    u = re.sub(r"\bsecs?\b", "s", u)
    u = re.sub(r"/s(\d)$", r"/s^\1", u)  # m/s2 -> m/s^2
    # A product sign between two letters: ".", "*", spaces or "-".
    u = re.sub(r"(?<=[A-Za-z])\s*[.*\- ]\s*(?=[A-Za-z])", "*", u)
    return u


def _lookup(unit: str) -> tuple[float, str] | None:
    if unit in _TABLE:
        return _TABLE[unit]
    norm = normalize_unit(unit)
    if norm in _TABLE:
        return _TABLE[norm]
    candidates = _FOLDED.get(norm.casefold(), [])
    if len(candidates) == 1:
        return _TABLE[candidates[0]]
    return None


def known_units() -> dict[str, tuple[str, ...]]:
    """The accepted spellings, grouped by the SI unit they convert to: {si: (spelling, ...)}."""
    return {si: tuple(group) for si, group in _GROUPS.items()}


def _known_text() -> str:
    parts = []
    for si, group in _GROUPS.items():
        spellings = ", ".join(repr(s) if s in ("", "-") else s for s in group)
        parts.append(f"[{si}] {spellings}")
    return "; ".join(parts)


# what a quantity's SI unit is called in an error message
_KIND = {"rad": "an angle", "rad/s": "an angular rate", "rad/s^2": "an angular acceleration", "m": "a length",
         "m/s": "a speed", "m/s^2": "an acceleration", "N": "a force", "N*m": "a torque", "kg": "a mass",
         "A": "a current", "s": "a time", "Hz": "a frequency", "Pa": "a pressure", "1": "a pure number"}


def unit_factor(
    unit: str | None, *, channel: str | None = None, source: str | None = None, expect: tuple[str, ...] | None = None
) -> tuple[float, str]:
    """(factor, SI unit) such that value_SI = factor * value for a value in `unit`.

    expect: the SI units the quantity may have (e.g. ("rad", "m") for a joint position); a unit of another
    dimension, or no unit at all (None or ""), is then an error: taking degrees for radians, or a speed for
    a position, would give a wrong answer without a word.

    Raises `UnknownUnitError` naming the channel, the unit, close spellings and every
    known unit.
    """
    if expect is not None and (unit is None or (isinstance(unit, str) and not unit.strip())) and "1" not in expect:
        kinds = " or ".join(f"{_KIND.get(e, e)} ({e})" for e in expect)
        raise UnknownUnitError(
            f"{_where(source, channel)}no unit: the file gives none and the config sets none; this channel is "
            f"{kinds}: give its unit in the file's header (name [unit]) or in the config's [channels] "
            "(unit = \"deg\", ...)", unit=None, source=source, channel=channel)
    if not isinstance(unit, str):
        raise UnknownUnitError(
            f"{_where(source, channel)}unit must be a string, not {unit!r}", unit=None, source=source, channel=channel
        )
    found = _lookup(unit)
    if found is not None:
        if expect is not None and found[1] not in expect:
            kinds = " or ".join(f"{_KIND.get(e, e)} ({e})" for e in expect)
            raise UnknownUnitError(
                f"{_where(source, channel)}unit {unit!r} is {_KIND.get(found[1], found[1])} ({found[1]}), but this "
                f"channel is {kinds}: fix the unit in the file's header or the config's [channels]",
                unit=unit, source=source, channel=channel)
        return found
    close = difflib.get_close_matches(normalize_unit(unit), list(_TABLE), n=3, cutoff=0.6)
    hint = f" Did you mean {', '.join(repr(c) for c in close)}?" if close else ""
    raise UnknownUnitError(
        f"{_where(source, channel)}unknown unit {unit!r}.{hint} Known units (by SI unit): {_known_text()}. "
        "Give the channel's unit in the channel map (unit = ...) or fix the file",
        unit=unit,
        source=source,
        channel=channel,
    )


def to_si(
    values: ArrayLike, unit: str | None, *, channel: str | None = None, source: str | None = None,
    expect: tuple[str, ...] | None = None,
) -> tuple[NDArray[np.float64], str]:
    """Convert values in `unit` to SI.

    Parameters
    ----------
    values : array (...), in `unit`.
    unit : a unit string as written in a file ("deg", "km/h", "N·m", "g", ...).
    channel, source : names used in the error message only.
    expect : the SI units the quantity may have (`unit_factor`).

    Returns
    -------
    (array of the shape of `values`, float64, new memory; the SI unit string).

    Raises
    ------
    UnknownUnitError
        the unit is not in the table (the message lists the known ones).
    """
    factor, si = unit_factor(unit, channel=channel, source=source, expect=expect)
    out = np.array(values, dtype=np.float64)  # a copy: the caller's array is never scaled in place
    if factor != 1.0:
        out *= factor
    return out, si


def same_unit(a: str, b: str) -> bool:
    """True if both spellings are known and mean the same unit (same SI unit and factor)."""
    fa, fb = _lookup(a), _lookup(b)
    return fa is not None and fa == fb


# "name [unit]" or "name (unit)": how dynid's CSV header writes a unit, and what pandas keeps as the column name
_NAME_UNIT = re.compile(r"^(?P<name>.*?\S)\s*(?:\[(?P<u1>[^\[\]]*)\]|\((?P<u2>[^()]*)\))\s*$")


def split_unit(label: str) -> tuple[str, str]:
    """A column name and the unit written in it: 'roll [deg]' -> ('roll', 'deg'); 'speed (km/h)' -> ('speed',
    'km/h'); 'Fz' -> ('Fz', ''). The one rule for a unit in a name, in every file format."""
    label = label.strip()
    m = _NAME_UNIT.match(label)
    if m is None:
        return label, ""
    unit = m.group("u1") if m.group("u1") is not None else m.group("u2")
    return m.group("name").strip(), unit.strip()


def name_and_unit(raw: str, stored: str, source: str = "") -> tuple[str, str]:
    """The channel of a column or channel named `raw` whose file gives the unit `stored` ("" if none): its name
    and unit, a unit written in the name (`split_unit`) taken as a CSV header's is.

    In formats whose names also carry indices and notes (MDF array elements "x[0]", "acc (filtered)"), a bracket
    counts as a unit only if it holds a known unit that is not an integer; otherwise it stays part of the name.
    A unit in the name that contradicts the file's own unit for it is a `FileFormatError` naming both."""
    name, written = split_unit(raw)
    if not written or written.isdigit() or _lookup(written) is None:
        return raw.strip(), stored.strip()
    if stored.strip() and written != stored.strip() and not same_unit(written, stored):
        raise FileFormatError(
            f"{_where(source, raw)}its name says the unit is {written!r} but the file gives {stored.strip()!r} for "
            f"it; rename the column (or channel) to {name!r} or fix the unit it is stored with",
            source=source or None, channel=raw)
    return name, stored.strip() or written


def channel_names(columns: Sequence[tuple[str, str]], source: str = "") -> list[tuple[str, str]]:
    """`name_and_unit` of each (raw name, stored unit), checking that no two columns give the same channel
    ('yaw [deg]' and 'yaw'): a `FileFormatError` naming both."""
    out: list[tuple[str, str]] = []
    seen: dict[str, str] = {}
    for raw, stored in columns:
        name, unit = name_and_unit(raw, stored, source)
        if name in seen:
            raise FileFormatError(f"{_where(source, None)}the columns {seen[name]!r} and {raw!r} both give the "
                                  f"channel {name!r}; rename one", source=source or None, channel=name)
        seen[name] = raw
        out.append((name, unit))
    return out


def _where(source: str | None, channel: str | None) -> str:
    parts = []
    if source:
        parts.append(str(source))
    if channel:
        parts.append(f"channel {channel!r}")
    return (", ".join(parts) + ": ") if parts else ""
