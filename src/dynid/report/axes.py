"""The car's chassis equations in ISO 8855 terms, for the report (one axis convention on every page).

The car's free joints 1..6 (`vehicle.template`) are the paper's: translations along its ground frame (x0 to the
right and y0 forward at the start, z0 up), then yaw about z0, pitch about the car's horizontal right axis and
roll about the chassis' forward axis z6. Their equation groups keep the paper's names (x, y, z, yaw, pitch, roll:
results.json, the terminal); the report shows them in ISO 8855 axes instead: the earth-fixed X_E (ahead at the
start), Y_E (left at the start) and Z_E (up), the intermediate Y (horizontal, left) for pitch and the vehicle x
(forward) for roll. Two of them change sign: Y_E = -x0 and pitch about the left axis is minus the moment about
the right one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ChassisAxis:
    """One chassis equation in ISO 8855 terms: its name, the sign from the paper's generalized force to the ISO
    one, and what the paper calls it."""

    label: str
    sign: float
    paper: str


CHASSIS_AXES: dict[str, ChassisAxis] = {
    "x": ChassisAxis("Y_E force", -1.0, "x: joint 1, force along x0 (right at the start)"),
    "y": ChassisAxis("X_E force", 1.0, "y: joint 2, force along y0 (ahead at the start)"),
    "z": ChassisAxis("Z_E force", 1.0, "z: joint 3, force along z0 (up)"),
    "yaw": ChassisAxis("yaw moment", 1.0, "yaw: joint 4, moment about z0 (up)"),
    "pitch": ChassisAxis("pitch moment", -1.0, "pitch: joint 5, moment about the car's horizontal right axis"),
    "roll": ChassisAxis("roll moment", 1.0, "roll: joint 6, moment about z6 (the chassis' forward axis)"),
}

ISO_TEXT = ("Chassis equations in ISO 8855 axes: forces along the earth-fixed X_E (the car's heading at the start of "
            "the test, forward), Y_E (left at the start) and Z_E (up); the yaw moment about Z_E, the pitch moment "
            "about the horizontal Y axis (left), the roll moment about the vehicle's x axis (forward). The paper "
            "writes them in its ground frame (x0 right, y0 forward, z0 up) as the equations of its joints 1 to 6, "
            "named x, y, z, yaw, pitch, roll in results.json: Y_E force = −x, X_E force = y, pitch moment = −pitch.")


def axis_label(group: str) -> str:
    """The name the report gives an equation group: the ISO 8855 one for a chassis equation, else the group's."""
    axis = CHASSIS_AXES.get(group)
    return axis.label if axis else group


def iso_sign(group: str) -> float:
    """The factor from an equation group's signal (the paper's sign) to the report's (ISO 8855): -1 or 1."""
    axis = CHASSIS_AXES.get(group)
    return axis.sign if axis else 1.0


def to_iso(group: str, *signals: np.ndarray) -> tuple[np.ndarray, ...]:
    """The signals of an equation group in the report's (ISO 8855) sign."""
    s = iso_sign(group)
    return tuple(np.asarray(x) if s == 1.0 else s * np.asarray(x) for x in signals)


__all__ = ["CHASSIS_AXES", "ISO_TEXT", "ChassisAxis", "axis_label", "iso_sign", "to_iso"]
