"""The car's chassis equations in ISO 8855 terms: what the report shows them as (one axis convention on every page).

The car's free joints 1..6 (`vehicle.template`) are the paper's: translations along its ground frame (x0 to the
right and y0 forward at the start, z0 up), then yaw about z0, pitch about the car's horizontal right axis and
roll about the chassis' forward axis z6. Their equation groups keep the paper's names (x, y, z, yaw, pitch, roll:
results.json, the terminal); the report shows them in ISO 8855 axes instead: the earth-fixed X_E (ahead at the
start), Y_E (left at the start) and Z_E (up), the intermediate Y (horizontal, left) for pitch and the vehicle x
(forward) for roll. Two of them change sign: Y_E = -x0 and pitch about the left axis is minus the moment about
the right one. The report reads these by the run's kind (report.tables.equation_axes), as it reads the car's
presentation: a robot's run does not import them.
"""

from __future__ import annotations

from dataclasses import dataclass


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


# the terminal validation table's note under a car's chassis equations (report.tables.validation_table)
TABLE_NOTE = ("  (chassis equations in ISO 8855 axes; results.json names them as the paper does: Y_E force = -x, "
              "X_E force = y, Z_E force = z, pitch moment = -pitch)")

__all__ = ["CHASSIS_AXES", "ISO_TEXT", "TABLE_NOTE", "ChassisAxis"]
