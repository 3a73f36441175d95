"""Numbers as an engineer writes them: a value rounded to its uncertainty, and the unit of a parameter.

Rounding (GUM 7.2.6 practice): the uncertainty to two significant digits, the value to the same decimal
place, so no digit is printed that the data do not support.
"""

from __future__ import annotations

import math
import re

PRISMATIC = 1

_INERTIAL_UNITS = {"XX": "kg·m²", "XY": "kg·m²", "XZ": "kg·m²", "YY": "kg·m²", "YZ": "kg·m²", "ZZ": "kg·m²",
                   "MX": "kg·m", "MY": "kg·m", "MZ": "kg·m", "M": "kg"}
# joint terms: (revolute, prismatic)
_JOINT_UNITS = {"IA": ("kg·m²", "kg"), "FV": ("N·m·s/rad", "N·s/m"), "FS": ("N·m", "N"), "OFF": ("N·m", "N"),
                "K": ("N·m/rad", "N/m"), "KQ": ("N·m/rad²", "N/m²"), "KFY": ("1/N", "1/(N·m)"),
                **dict.fromkeys(("FVPL", "FVPH", "FVNL", "FVNH"), ("N·m·s/rad", "N·s/m"))}
_GAIN = re.compile(r"^G\d+$")  # a drive gain of a current channel (pipeline.sources.gain_names): motor side
GAIN_UNIT = "N·m/A"
_NAME = re.compile(r"^(XX|XY|XZ|YY|YZ|ZZ|MX|MY|MZ|M|IA|FVPL|FVPH|FVNL|FVNH|FV|FS|OFF|KQ|KFY|K)(\d+)$")


def _finite(x: float | None) -> bool:
    return x is not None and isinstance(x, int | float) and math.isfinite(x)


def decimals(sigma: float, digits: int = 2) -> int | None:
    """The decimal place to round to: `digits` significant digits of sigma (negative: tens, hundreds...);
    None when sigma is 0, negative or not finite (nothing to round to)."""
    if not _finite(sigma) or sigma <= 0:
        return None
    d = digits - 1 - math.floor(math.log10(sigma))
    # 0.0996 to two digits is 0.10: one digit fewer once rounding carries into the next power of ten
    if round(sigma, d) >= 10 ** (digits - d):
        d -= 1
    return d


def fixed(x: float | None, d: int | None, fallback: str = ".6g") -> str:
    """x rounded to d decimals (d < 0: to tens, hundreds...); no "-0"; `fallback` format when d is None;
    "" for a missing or non-finite x."""
    if not _finite(x):
        return ""
    if d is None:
        return format(float(x), fallback)
    r = round(float(x), d)
    if r == 0:
        r = 0.0  # -0.0 -> 0.0
    return f"{r:.{max(d, 0)}f}"


def round_to_uncertainty(value: float | None, sigma: float | None, digits: int = 2) -> tuple[str, str]:
    """(value, sigma) as strings: sigma to `digits` significant digits, the value to the same decimal place.
    sigma 0 or missing: the value with 6 significant digits and sigma "0" or ""."""
    d = decimals(sigma, digits) if _finite(sigma) else None
    if d is None:
        s = "0" if _finite(sigma) and sigma == 0 else ""
        return fixed(value, None), s
    return fixed(value, d), fixed(sigma, d)


def parameter_unit(name: str, tree=None) -> str:
    """The SI unit of a (base) parameter from its kind and its joint's type (revolute or prismatic); a
    coupling's from its kind and its first joint. "" when unknown (e.g. a name of no standard form)."""
    if _GAIN.match(name):
        return GAIN_UNIT
    m = _NAME.match(name)
    if m:
        kind, j = m.group(1), int(m.group(2))
        if kind in _INERTIAL_UNITS:
            return _INERTIAL_UNITS[kind]
        return _JOINT_UNITS[kind][_is_prismatic(tree, j)]
    for c in getattr(tree, "couplings", ()) or ():
        if c.name == name and c.kind in _JOINT_UNITS:
            return _JOINT_UNITS[c.kind][_is_prismatic(tree, min(c.coeffs))]
    return ""


def _is_prismatic(tree, j: int) -> int:
    if tree is None:
        return 0
    frame = next((f for f in tree.frames if f.j == j), None)
    return int(frame is not None and frame.sigma == PRISMATIC)


def force_unit(prismatic: bool) -> str:
    """The unit of a joint's generalized force."""
    return "N" if prismatic else "N·m"


__all__ = ["decimals", "fixed", "force_unit", "parameter_unit", "round_to_uncertainty"]
