"""The driver's manoeuvres: parameterised, documented, checked against the tire's adhesion.

Each manoeuvre starts with the car at rest attitude, rolling straight at `speed`, and
holds that speed with a PI controller driving the front wheels (equal torque left and
right: an open differential), unless it brakes. The steering-wheel angle follows the
manoeuvre's target through a steering robot (2nd-order, 8 Hz, damping 0.8).

  sine     the paper's identification test: sine steering at 90 km/h, 0.5 Hz, amplitude
           giving `lateral_acceleration` (4 m/s^2) by the linear bicycle model's frequency
           response at that frequency; the amplitude grows over the first period; from 2 s; 20 s.
  braking  the paper's cross-validation test: straight line at 100 km/h, brakes applied at
           1.5 s over 0.3 s for `deceleration` (6 m/s^2: total torque m a R), `front_share`
           0.7 of it on the front wheels; released below 5 km/h; 10 s.
  spiral   constant speed 70 km/h, steering wheel increased at `rate` 4 deg/s from 2 s up to
           `max_angle` 200 deg: through the linear range to the limit of adhesion; 30 s.
  step     ISO 7401 step steer: 80 km/h, steering wheel step to the angle giving 4 m/s^2 in
           steady state, 0.15 s rise (quintic), at 2 s; 8 s.
  lane     after ISO 3888-2 (severe lane change): sections 12 m (entry), 13.5 m, 11 m
           (side lane), 12.5 m, 12 m (exit) after 2 s of straight driving; the path-following
           driver (0.6 s preview, pure pursuit) follows a quintic centreline from the middle
           of each lane to the next, offset 3.52 m (the standard's lane offset for a 1.78 m
           wide car). The standard is run near the limit with drivers using the lane widths;
           this smooth path needs 0.0058 v^2 m/s^2 peak lateral acceleration (50 km/h: 6.3).
  accel    straight-line acceleration (after ISO 21994's straight line, driven): from `speed` 30 km/h, the
           speed target ramps at `acceleration` 3 m/s^2 (over `ramp` 0.3 s) from 2 s up to `final_speed`
           100 km/h, the force m a fed forward to the PI controller; front-wheel drive; 12 s.
  fishhook after the NHTSA fishhook (roll-rate feedback replaced by a fixed dwell): 80 km/h, steering wheel
           to the angle giving `lateral_acceleration` 5 m/s^2 in steady state at `rate` 720 deg/s, held
           `dwell` 0.25 s, to the opposite angle at the same rate, held `hold` 3 s, back to 0; from 2 s; 10 s.
  random   random steer (ISO 7401's random input): 80 km/h, `components` 20 sines at k `frequency` / 20
           (k = 1..20, `frequency` 2 Hz the highest) with Schroeder's phases (a flat spectrum of low crest
           factor), RMS steering-wheel angle giving `lateral_acceleration` 3 m/s^2 RMS in steady state; from
           2 s; 20 s.
  static   standing still (speed 0): settling under gravity.
  table    a steering-robot file played back (`table_manoeuvre`): the steering-wheel angle and the longitudinal
           acceleration demand sampled every `step` s from t = 0; the speed target is `speed` plus the demand's
           integral, the demand fed forward (m a R) to the speed controller, whose negative torque brakes the
           wheels (`front_share` on the front axle).

Speeds and accelerations a manoeuvre cannot reach on the tires (beyond 0.8 of the peak
friction at the static load) raise ManoeuvreError, as do unknown names and parameters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .kernel import M_ACCEL, M_BRAKE, M_CONST, M_FISHHOOK, M_LANE, M_RANDOM, M_SINE, M_SPIRAL, M_STEP, M_TABLE

NMAN = 10


class ManoeuvreError(ValueError):
    """A manoeuvre that does not exist, or that the car cannot drive (named, with what to do)."""


DEFAULTS: dict[str, dict[str, float]] = {
    "sine": {"speed": 90.0, "duration": 20.0, "frequency": 0.5, "lateral_acceleration": 4.0, "start": 2.0},
    "braking": {"speed": 100.0, "duration": 10.0, "deceleration": 6.0, "front_share": 0.7, "start": 1.5,
                "ramp": 0.3, "release_speed": 5.0},
    "spiral": {"speed": 70.0, "duration": 30.0, "rate": 4.0, "max_angle": 200.0, "start": 2.0},
    "step": {"speed": 80.0, "duration": 8.0, "lateral_acceleration": 4.0, "rise": 0.15, "start": 2.0},
    "lane": {"speed": 50.0, "duration": 8.0, "offset": 3.52, "preview": 0.6, "start": 2.0},
    "accel": {"speed": 30.0, "duration": 12.0, "acceleration": 3.0, "final_speed": 100.0, "ramp": 0.3, "start": 2.0},
    "fishhook": {"speed": 80.0, "duration": 10.0, "lateral_acceleration": 5.0, "rate": 720.0, "dwell": 0.25,
                 "hold": 3.0, "start": 2.0},
    "random": {"speed": 80.0, "duration": 20.0, "lateral_acceleration": 3.0, "frequency": 2.0, "components": 20.0,
               "start": 2.0},
    "static": {"speed": 0.0, "duration": 3.0, "start": 0.0},
}
UNITS = {"speed": "km/h", "duration": "s", "frequency": "Hz", "lateral_acceleration": "m/s^2", "start": "s",
         "deceleration": "m/s^2", "front_share": "1", "ramp": "s", "release_speed": "km/h", "rate": "deg/s",
         "max_angle": "deg", "rise": "s", "offset": "m", "preview": "s", "acceleration": "m/s^2",
         "final_speed": "km/h", "dwell": "s", "hold": "s", "components": "1", "step": "s"}
LANE_SECTIONS = (12.0, 13.5, 11.0, 12.5, 12.0)


@dataclass(frozen=True)
class Manoeuvre:
    """A named manoeuvre with its parameters (units in UNITS: km/h, s, deg, m/s^2)."""

    name: str
    params: dict[str, float] = field(default_factory=dict)
    # a table manoeuvre's samples (3, n): steering-wheel angle (rad), acceleration demand (m/s^2), speed target (m/s)
    table: np.ndarray | None = field(default=None, compare=False, repr=False)

    @property
    def speed(self) -> float:
        """m/s."""
        return self.params["speed"] / 3.6

    @property
    def duration(self) -> float:
        return self.params["duration"]


def manoeuvre(name: str, **params: float | None) -> Manoeuvre:
    """A manoeuvre by name with defaults for the parameters not given (None = default)."""
    if name not in DEFAULTS:
        raise ManoeuvreError(f"unknown manoeuvre {name!r}; choose one of {', '.join(DEFAULTS)}")
    given = {k: v for k, v in params.items() if v is not None}
    bad = sorted(set(given) - set(DEFAULTS[name]))
    if bad:
        raise ManoeuvreError(f"manoeuvre {name!r} has no parameter {', '.join(bad)}; "
                             f"parameters: {', '.join(f'{k} [{UNITS[k]}]' for k in DEFAULTS[name])}")
    p = {**DEFAULTS[name], **{k: float(v) for k, v in given.items()}}
    for k, v in p.items():
        if not math.isfinite(v):
            raise ManoeuvreError(f"manoeuvre {name!r}: {k} = {v} is not a finite number; give a number (--{k})")
    if p["duration"] <= 0:
        raise ManoeuvreError(f"manoeuvre {name!r}: duration = {p['duration']} s must be positive")
    if not 0.0 <= p["speed"] <= 180.0 or (name != "static" and p["speed"] < 10.0):
        raise ManoeuvreError(f"manoeuvre {name!r}: speed = {p['speed']} km/h; use 10..180 km/h "
                             "(0 only for 'static')")
    positive = [k for k in ("acceleration", "ramp", "rate", "frequency", "components") if k in p and p[k] <= 0]
    if positive:
        raise ManoeuvreError(f"manoeuvre {name!r}: {positive[0]} = {p[positive[0]]:g} {UNITS[positive[0]]} must be "
                             "positive")
    if name == "random" and (p["components"] != round(p["components"]) or p["components"] > 100):
        raise ManoeuvreError(f"random: components = {p['components']:g}; give a whole number 1..100")
    if name == "accel" and not p["speed"] < p["final_speed"] <= 180.0:
        raise ManoeuvreError(f"accel: final_speed = {p['final_speed']:g} km/h must be above speed = {p['speed']:g} "
                             "km/h and at most 180")
    if name == "braking" and not 0.0 <= p["front_share"] <= 1.0:
        raise ManoeuvreError(f"braking: front_share = {p['front_share']} must be within 0..1")
    return Manoeuvre(name, p)


def table_manoeuvre(step: float, steering_wheel, acceleration, speed: float, front_share: float = 0.7
                    ) -> Manoeuvre:
    """A steering-robot file as a manoeuvre: the steering-wheel angle (rad) and the longitudinal acceleration demand
    (m/s^2, negative: braking) sampled every `step` s from t = 0, starting straight at `speed` km/h; the speed
    target integrates the demand (trapezoids) and must stay within 10..180 km/h."""
    h = np.asarray(steering_wheel, dtype=float).reshape(-1)
    a = np.asarray(acceleration, dtype=float).reshape(-1)
    if h.size != a.size or h.size < 2:
        raise ManoeuvreError(f"table: {h.size} steering-wheel and {a.size} acceleration samples; give the same "
                             "number, at least 2")
    if not (step > 0 and np.all(np.isfinite(h)) and np.all(np.isfinite(a))):
        raise ManoeuvreError("table: the step must be positive and every sample a finite number")
    if not 0.0 <= front_share <= 1.0:
        raise ManoeuvreError(f"table: front_share = {front_share} must be within 0..1")
    v = speed / 3.6 + np.concatenate([[0.0], np.cumsum(0.5 * (a[1:] + a[:-1]) * step)])
    if 3.6 * v.min() < 10.0 or 3.6 * v.max() > 180.0:
        raise ManoeuvreError(f"table: the speed target spans {3.6 * v.min():.0f}..{3.6 * v.max():.0f} km/h; keep "
                             "it within 10..180 km/h (less braking or acceleration)")
    params = {"speed": float(speed), "duration": step * (h.size - 1), "start": 0.0, "step": float(step),
              "front_share": float(front_share)}
    return Manoeuvre("table", params, np.vstack([h, a, v]))


def lane_path(offset: float, start_distance: float) -> tuple[float, float, float, float]:
    """(s1, s2, s3, s4): the centreline's transitions along y0, from the middle of one lane to the next."""
    e, t1, side, t2, _ = LANE_SECTIONS
    s1 = start_distance + e / 2
    s2 = start_distance + e + t1 + side / 2
    s3 = s2
    s4 = start_distance + e + t1 + side + t2 + LANE_SECTIONS[4] / 2
    return s1, s2, s3, s4


def pack(m: Manoeuvre, car: dict[str, float]) -> np.ndarray:
    """The driver's array for the compiled loop (see kernel.driver); car: mass (kg), radius (m),
    ratio, wheelbase (m), understeer (rad per m/s^2), mu (peak friction at the static loads)."""
    p = m.params
    v = m.speed
    out = np.zeros(NMAN)
    out[1], out[2] = v, p["start"]
    limit = 0.8 * car["mu"] * 9.81
    name = m.name

    def steady_angle(ay: float) -> float:
        if ay > limit:
            raise ManoeuvreError(
                f"{name}: a lateral acceleration of {ay:g} m/s^2 is beyond the adhesion of the tires "
                f"(0.8 x {car['mu']:.2f} g = {limit:.2f} m/s^2); lower lateral_acceleration")
        return car["ratio"] * (car["wheelbase"] / v**2 + car["understeer"]) * ay

    if name == "sine":  # amplitude from the bicycle model's frequency response at the sine's frequency
        steady_angle(p["lateral_acceleration"])
        gain = car["bicycle"].lateral_gain(v, p["frequency"])
        out[0], out[3], out[4] = M_SINE, car["ratio"] * p["lateral_acceleration"] / gain, p["frequency"]
    elif name == "braking":
        if p["deceleration"] > limit:
            raise ManoeuvreError(
                f"braking: a deceleration of {p['deceleration']:g} m/s^2 is beyond the adhesion of the tires "
                f"({limit:.2f} m/s^2 without ABS); lower deceleration")
        out[0] = M_BRAKE
        out[3] = car["mass"] * p["deceleration"] * car["radius"]
        out[4], out[5], out[6] = p["front_share"], p["ramp"], p["release_speed"] / 3.6
    elif name == "spiral":
        out[0], out[3], out[4] = M_SPIRAL, math.radians(p["rate"]), math.radians(p["max_angle"])
    elif name == "step":
        out[0], out[3], out[4] = M_STEP, steady_angle(p["lateral_acceleration"]), p["rise"]
    elif name == "accel":
        # front-wheel drive: the front axle's static share of the weight at 0.8 of the peak friction
        front = limit * car["front_share"]
        if p["acceleration"] > front:
            raise ManoeuvreError(
                f"accel: an acceleration of {p['acceleration']:g} m/s^2 is beyond the front tires' adhesion "
                f"({front:.2f} m/s^2 with the front axle's share of the weight); lower acceleration")
        out[0], out[3], out[4], out[5] = M_ACCEL, p["acceleration"], p["final_speed"] / 3.6, p["ramp"]
    elif name == "fishhook":
        out[0], out[3], out[4] = M_FISHHOOK, steady_angle(p["lateral_acceleration"]), math.radians(p["rate"])
        out[5], out[6] = p["dwell"], p["hold"]
    elif name == "random":
        steady_angle(p["lateral_acceleration"])
        out[0], out[3] = M_RANDOM, steady_angle(p["lateral_acceleration"])
        out[4], out[5] = p["frequency"], p["components"]
    elif name == "lane":
        s1, s2, s3, s4 = lane_path(p["offset"], v * p["start"])
        peak = 10.0 / math.sqrt(3.0) * p["offset"] * v**2 / min(s2 - s1, s4 - s3) ** 2
        if peak > limit:
            vmax = math.sqrt(limit / (10.0 / math.sqrt(3.0) * p["offset"])) * min(s2 - s1, s4 - s3) * 3.6
            raise ManoeuvreError(
                f"lane: at {p['speed']:g} km/h the lane change needs {peak:.1f} m/s^2 of lateral acceleration, "
                f"beyond the adhesion of the tires ({limit:.2f} m/s^2); use a speed below {vmax:.0f} km/h")
        out[0], out[4], out[5], out[6], out[7], out[8], out[9] = M_LANE, p["offset"], s1, s2, s3, s4, p["preview"]
    elif name == "table":
        out[0], out[3], out[4], out[5] = M_TABLE, p["step"], m.table.shape[1], p["front_share"]
        out = np.concatenate([out, m.table.ravel()])
    else:
        out[0] = M_CONST
    return out
