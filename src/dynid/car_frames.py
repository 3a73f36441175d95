"""The car template's frame numbers (vehicle/template.py builds the frames and says what each one is): the chassis is
frame 6 and corner k (0 rear left, 1 rear right, 2 front left, 3 front right) uses frames 7+9k .. 15+9k; the corners'
tags in channel names. A leaf, so that code which must not load the vehicle layer (a config's reader, the data health
checks: on a robot's path too) names a corner and its frames through the same helpers as the car's own modules."""

from __future__ import annotations

CHASSIS = 6
CORNER_TAGS = ("rl", "rr", "fl", "fr")  # corner k's tag in channel names (wft_rl_Fz, wheel_speed_fr, ...)
CORNER_FRAMES = 9  # a corner's: half track, half wheelbase, damper, steering, camber, caster, kingpin, wheel, tire


def base(corner: int) -> int:
    """First frame (half track) of a corner: 7, 16, 25, 34."""
    return CHASSIS + 1 + CORNER_FRAMES * corner


def damper(corner: int) -> int:
    return base(corner) + 2


def wheel(corner: int) -> int:
    return base(corner) + 7


def tire(corner: int) -> int:
    return base(corner) + 8


def tabulated(corner: int) -> tuple[int, int, int, int]:
    """Steering, camber, caster, kingpin frames of a corner."""
    b = base(corner)
    return (b + 3, b + 4, b + 5, b + 6)


DAMPERS = tuple(damper(k) for k in range(4))  # 9, 18, 27, 36
WHEELS = tuple(wheel(k) for k in range(4))  # 14, 23, 32, 41
TIRES = tuple(tire(k) for k in range(4))  # 15, 24, 33, 42
