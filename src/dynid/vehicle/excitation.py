"""Which tests excite which of the car's parameters: the hint under an unidentifiable or uncertain estimate
(the terminal's error and the report's flag legend)."""

from __future__ import annotations

# which standard test excites what (the paper's tests and ISO manoeuvres)
_EXCITATION = (
    (("XX6", "XY6", "XZ6", "MX6"), "roll: a sine steer at speed or a double lane change (ISO 3888-2)"),
    (("YY6", "MZ6"), "pitch: straight-line braking and acceleration"),
    (("ZZ6", "YZ6", "MY6"), "yaw: a sine steer or a step steer (ISO 7401)"),
    (("M6",), "vertical and longitudinal loads: braking, a speed change, a bumpy stretch"),
    (("K9", "K18", "K27", "K36", "FV9", "FV18", "FV27", "FV36", "FS9", "FS18", "FS27", "FS36"),
     "suspension travel in both directions: a sine steer (roll), braking (pitch), a bumpy stretch (heave)"),
    (("OFF9", "OFF18", "OFF27", "OFF36"), "any test: the static preload is always present"),
    (("karf", "karr"), "roll: a sine steer or a spiral to a high lateral acceleration"),
    (("K15", "K24", "K33", "K42"), "load transfer: braking (front/rear), cornering (left/right)"),
)


def excitation_hint(names: list[str]) -> str:
    """Which tests would excite the given parameters (for an unidentifiable-parameter error)."""
    lines = []
    for params, test in _EXCITATION:
        hit = [n for n in names if n in params]
        if hit:
            lines.append(f"  {', '.join(hit)}: {test}")
    wheels = [n for n in names if n[:2] in ("XX", "YY", "ZZ") and n[2:] in ("14", "23", "32", "41")]
    if wheels:
        lines.append(f"  {', '.join(wheels)}: steering that turns the wheels quickly (a step steer, a slalom), "
                     "or declare them known (their effect is small)")
    return "tests that would excite them:\n" + "\n".join(lines) if lines else ""
