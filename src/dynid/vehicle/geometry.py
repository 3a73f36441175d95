"""Geometric data of a car for the paper's 42-frame template (SI units, radians).

Frame 6 (the chassis) has x6 UP, y6 to the RIGHT and z6 FORWARD (the paper's roll joint
acts about z6, so z6 is the longitudinal axis). Its origin O6 is on the line joining the
rear wheel centres, midway between them, at the height of the wheel centres in the
design position (all joint variables zero): the inertial unit sits there ("rear axle"
in the paper's Table 1). Positions below are coordinates in frame 6.
"""

from __future__ import annotations

import functools
import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import resources
from typing import Any

import numpy as np

from ..model.tree import ModelError
from ..shipped import DEMO_VEHICLE


class GeometryError(ModelError):
    """Car geometry that cannot give a usable model; the message names the field and the fix."""


@dataclass(frozen=True)
class AxleGeometry:
    """One axle (both corners mirror each other about the vertical longitudinal plane of frame 6).

    half_track: lateral distance of the wheel centres from the plane x6-z6, m (the paper's
      q7, q16, q25, q34, positive, along the outward lateral axis).
    position: z6 coordinate of the axle (forward positive), m. The paper's "half wheelbase"
      q8 is the distance of the axle from O6 along the outward longitudinal axis
      (forward for the front axle, rearward for the rear one).
    damper_lateral_tilt: front-view angle of the damper axis from x6, top inboard positive.
    damper_longitudinal_tilt: side-view angle of the damper axis from x6, top rearward positive.
      The wheel centre moves along this axis with the damper clearance (q9, ...).
    kingpin_inclination: front-view angle of the kingpin axis, top inboard positive.
    caster: side-view angle of the kingpin axis, top rearward positive.
    kingpin_offset: distance, at the wheel-centre height, from the wheel centre inboard to the
      kingpin axis (spindle length), m. The kingpin joint (q13, ...) turns the hub about that axis.
    """

    half_track: float
    position: float
    damper_lateral_tilt: float = 0.0
    damper_longitudinal_tilt: float = 0.0
    kingpin_inclination: float = 0.0
    caster: float = 0.0
    kingpin_offset: float = 0.0


@dataclass(frozen=True)
class CarGeometry:
    """What the template needs to place the 42 frames: a vehicle file gives it (`vehicle.description`), and
    `demo_geometry()` is the demo vehicle's, where a function is given none.

    wheel_radius: unloaded tire radius, m (195/65 R15: 0.317 m); the tire deflection q15 is
      counted from it (contact point at wheel_radius - q15 from the wheel centre).
    wheel_centre_height: x6 coordinate of the wheel centres in the design position, m
      (0: O6 at wheel-centre height).
    imu_position: inertial unit's position in frame 6, m (at O6 by default: the paper's
      accelerations are those of the rear axle). imu_axes: rotation from frame 6 to the
      unit's axes, rows = the unit's x, y, z in frame 6 (default ISO 8855: x forward,
      y left, z up). gnss_position: the GNSS/INS velocity's point in frame 6, m (None: the roof
      point `sensors.gnss_point` chooses); correvit_position, laser_positions (rear left, rear right, front
      left, front right): the Correvit's and the height lasers' points (None: `sensors.correvit_point` and
      `sensors.laser_point` choose). Used by sensor models, not by the dynamics.
    """

    front: AxleGeometry
    rear: AxleGeometry
    wheel_radius: float
    wheel_centre_height: float = 0.0
    imu_position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    imu_axes: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 1.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0))
    gnss_position: tuple[float, float, float] | None = None  # a GNSS/INS antenna's point in frame 6 (sensors)
    correvit_position: tuple[float, float, float] | None = None  # the Correvit's point in frame 6 (sensors)
    laser_positions: tuple[tuple[float, float, float], ...] | None = None  # the four lasers' points, corner order

    def __post_init__(self) -> None:
        validate(self)

    @property
    def wheelbase(self) -> float:
        return self.front.position - self.rear.position

    def axle(self, corner: int) -> AxleGeometry:
        return self.front if corner >= 2 else self.rear

    def wheel_centre(self, corner: int) -> np.ndarray:
        """Wheel centre of a corner (0 rear left, 1 rear right, 2 front left, 3 front right) in frame 6."""
        ax = self.axle(corner)
        return np.array([self.wheel_centre_height, side(corner) * ax.half_track, ax.position])


def file_geometry(data: Mapping[str, Any]) -> CarGeometry:
    """The geometry a vehicle file's tables give (`vehicle.description`'s keys, docs/vehicle.md): [axles], [wheels],
    [imu] and the sensors' points of [sensors]. The values as they are: `vehicle.description` checks a file (keys,
    ranges, messages naming the key) before it builds its geometry here."""
    axles, wheels, imu, sensors = data["axles"], data["wheels"], data.get("imu", {}), data.get("sensors", {})

    def axle(a: str, position: float) -> AxleGeometry:
        t = axles[a]
        deg = {k: math.radians(float(t.get(f"{k}_deg", 0.0)))
               for k in ("damper_lateral_tilt", "damper_longitudinal_tilt", "kingpin_inclination", "caster")}
        return AxleGeometry(half_track=float(t["half_track_m"]), position=position,
                            kingpin_offset=float(t.get("kingpin_offset_m", 0.0)), **deg)

    def point(v) -> tuple[float, ...] | None:
        return None if v is None else tuple(float(x) for x in v)

    lasers = sensors.get("laser_positions_m")
    return CarGeometry(front=axle("front", float(axles["wheelbase_m"])), rear=axle("rear", 0.0),
                       wheel_radius=float(wheels["radius_m"]), wheel_centre_height=float(wheels.get("centre_height_m",
                                                                                                   0.0)),
                       imu_position=point(imu.get("position_m", [0.0, 0.0, 0.0])),
                       imu_axes=tuple(point(r) for r in imu.get("axes", [[0.0, 0.0, 1.0], [0.0, -1.0, 0.0],
                                                                          [1.0, 0.0, 0.0]])),
                       gnss_position=point(sensors.get("gnss_position_m")),
                       correvit_position=point(sensors.get("correvit_position_m")),
                       laser_positions=None if lasers is None else tuple(point(r) for r in lasers))


@functools.cache
def demo_geometry() -> CarGeometry:
    """The demo vehicle's geometry, read from its shipped file (the one `dynid.shipped.DEMO_VEHICLE` names): the
    default of the functions that take a geometry, so that no car's numbers live in code."""
    path = resources.files("dynid.vehicle") / "vehicles" / f"{DEMO_VEHICLE}.toml"
    return file_geometry(tomllib.loads(path.read_text(encoding="utf-8")))


def side(corner: int) -> int:
    """+1 for a right-hand corner (along +y6), -1 for a left-hand one."""
    return 1 if corner % 2 else -1


def validate(g: CarGeometry) -> None:
    """Raise GeometryError for geometry that makes frames coincide or axes degenerate."""
    for name, ax in (("front", g.front), ("rear", g.rear)):
        if not all(math.isfinite(v) for v in vars(ax).values()):
            raise GeometryError(f"car geometry, {name} axle: every field must be a finite number; got {ax}")
        if ax.half_track < 0.05:
            raise GeometryError(
                f"car geometry, {name} axle: half_track = {ax.half_track} m makes the left and right wheel "
                f"centres coincide (or cross); give the half track, > 0.05 m (a saloon: about 0.75 m)"
            )
        for fld in ("damper_lateral_tilt", "damper_longitudinal_tilt", "kingpin_inclination", "caster"):
            v = getattr(ax, fld)
            if abs(v) >= math.radians(60.0):
                raise GeometryError(
                    f"car geometry, {name} axle: {fld} = {v} rad ({math.degrees(v):.1f}°) is not an axis "
                    f"close to the vertical; angles are in radians and must stay within ±60°"
                )
        if not 0.0 <= ax.kingpin_offset < ax.half_track:
            raise GeometryError(
                f"car geometry, {name} axle: kingpin_offset = {ax.kingpin_offset} m must be >= 0 and "
                f"smaller than the half track {ax.half_track} m"
            )
    if g.wheelbase < 0.5:
        raise GeometryError(
            f"car geometry: front axle at z6 = {g.front.position} m and rear axle at z6 = {g.rear.position} m "
            f"give a wheelbase of {g.wheelbase:.3g} m: the axles coincide or are swapped; the front axle "
            f"must be at least 0.5 m ahead of the rear one"
        )
    if not 0.1 <= g.wheel_radius <= 1.0:
        raise GeometryError(f"car geometry: wheel_radius = {g.wheel_radius} m; expected 0.1..1.0 m (unloaded radius)")
    R = np.asarray(g.imu_axes, dtype=float)
    if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0:
        raise GeometryError("car geometry: imu_axes must be a 3x3 rotation (rows: the unit's x, y, z in frame 6)")
