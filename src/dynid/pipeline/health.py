"""A car test's data health, gathered by the identification's segments: its channels one by one, then the wiring.

The stamps are checked by the plan (`sources.plan_car_test`), before any segment is read. The rest
needs the values, which the identification reads anyway: each segment of its first map
(`reduce.reduce_car_segment`) scans the part of the test it answers for (`segment_health`: the
file's samples of each channel, and sums over the SI channels on the clock), and the parts combine
like the least squares' factors (`CarHealth.merged`, in the map's fold); `car_findings` judges the
whole test before the estimate is solved. Reading the file a second time to scan it cost 45 % of an
identification per hour of data; scanning what a segment holds costs 5 % of its CPU time there, 1.5 % on
the demo (benchmarks/bench_health.py).
`car_health(plan, vehicle)` reads a test's file itself, a window at a time, through the same functions.
What is judged:

- each channel (`io.health.ChannelScan`): values out of the sensor's declared range, runs at that
  range, flat tops at its extremes entered at speed, spikes, a channel that never moves. The
  declared range and resolution come from the vehicle's sensor suite, converted to the file's unit.
  A camera's steering or camber angle at or beyond its range is repaired by the estimator (the
  kinematic tables' value stands in for it: `vehicle.estimate`): a note, not an error. The
  steering-wheel angle may stay still for a whole straight-line test, a rear wheel may never steer,
  a rigid axle's camber never changes (the MuJoCo car's ideal files): a warning, not an error. So is
  a still yaw rate, roll or lateral speed in a test without lateral acceleration, or a still pitch in
  a test without longitudinal acceleration (a noise-free file's straight braking reads no roll).
- the wheel loads against the vehicle's a priori set: each load's mean and its change with the
  longitudinal and lateral accelerations (least squares over the test, on the accelerations that
  the test moves by more than `EXCITED`), against what the corner should give (its share of the weight
  from the centre of mass; the load transfers m h a / 2L and m h a / 4t at the centre of mass's height
  h above the ground). The loads are then assigned to the corners in every order: when another order
  explains them four times better than the file's, and the file's misses by more than 3 tolerances, the
  channels are swapped (an error naming them). The tolerances (10 % of a wheel's static load; half an
  expected transfer) cover an a priori set as far from the car as the demo's (its centre of mass is 8 cm
  off lengthwise and 10 cm in height); a swap of a front and a rear load moves two means by the
  front-rear difference and flips a transfer's sign.
- the total of the loads against the a priori weight (a unit or a calibration factor), and the
  accelerometer's vertical axis against gravity (a sign or a unit).

What needs the whole test combines exactly from its parts: a channel is constant when every part
is, at one value; the wiring's least squares, the mean vertical acceleration and the speeds' ratio
are sums. A channel's scan judges each part alone (its holds, noise level and step sizes: the
robust statistics of `io.health`, not combined across parts, as they were not across the windows
read before): a plateau or a spike straddling two parts is judged in each, and the parts are a
minute long (`[conditioning] segment`), long against a plateau (0.1 s) or a spike.

Findings are `io.health.Finding`s (channel, time span in the file's time base, severity, what to do).
`check_car_tests` runs them over every test: an error stops the identification with one line
(`ConfigError`, exit status 2), before the estimate is solved; warnings and notes are reported through
`progress` and returned.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from ..car_frames import CORNER_TAGS, WHEELS
from ..io import Channel, read_window, unit_factor
from ..io.health import ERROR, NOTE, WARNING, ChannelScan, Finding
from ..signals import border_samples, filtered_derivatives
from .config import ConfigError, IdentifyConfig
from .robot import to_frames
from .sources import (
    CarTestPlan,
    RobotTestPlan,
    SegmentWindow,
    clock_at,
    clock_read,
    driven,
    read_robot_window,
    read_segment,
    segment_window,
)

Progress = Callable[[str], None]
WINDOW_S = 120.0  # s of the file read at a time
EXCITED = 1.0  # m/s^2: an acceleration's standard deviation over the test above which its load transfer is judged
G = 9.80665
# channels that a test without lateral (longitudinal) acceleration may leave still: judged dead only when the
# test moves that acceleration by more than EXCITED
_MOVED_BY = {"imu_yaw_rate": "imu_ay", "imu_roll_rate": "imu_ay", "imu_roll": "imu_ay", "correvit_vy": "imu_ay",
             "gnss_vy": "imu_ay", "imu_pitch_rate": "imu_ax", "imu_pitch": "imu_ax"}
_REPAIRED = ("steer_", "camber_")  # camera channels whose samples at or beyond the range the estimator replaces
# channels that may read one value over a whole test, and what to check then
_STILL = {"steering_wheel": "fine if the driver did not steer in this test; otherwise its encoder is disconnected: "
                            "fix the wiring",
          "steer_": "fine for a wheel that does not steer (a rear axle); otherwise check the camera and its wiring",
          "camber_": "fine for a wheel whose camber does not change (a rigid axle, or an ideal file); otherwise "
                     "check the camera and its wiring"}


@dataclass
class _Loads:
    """Sums for the least squares of the four wheel loads on [1, ax, ay] over a test, and the vertical axis."""

    xtx: NDArray[np.float64] = field(default_factory=lambda: np.zeros((3, 3)))
    xty: NDArray[np.float64] = field(default_factory=lambda: np.zeros((3, 4)))
    n: int = 0
    up_sum: float = 0.0
    up_n: int = 0
    moves: dict = field(default_factory=dict)  # imu_ax, imu_ay -> [n, sum, sum of squares], SI
    speeds: tuple[float, float, int] = (0.0, 0.0, 0)  # sums of v w, w w and the samples, w the wheels' rolling speed

    def move(self, q: str, x: NDArray) -> None:
        m = self.moves.setdefault(q, [0, 0.0, 0.0])
        m[0] += x.size
        m[1] += float(np.sum(x))
        m[2] += float(np.sum(x * x))

    def std(self, q: str) -> float:
        """Standard deviation of an acceleration over the test (0 when not read)."""
        n, s1, s2 = self.moves.get(q, (0, 0.0, 0.0))
        return math.sqrt(max(s2 / n - (s1 / n) ** 2, 0.0)) if n else 0.0

    def add(self, ax: NDArray, ay: NDArray, loads: NDArray) -> None:
        X = np.column_stack([np.ones_like(ax), ax, ay])
        self.xtx += X.T @ X
        self.xty += X.T @ loads
        self.n += ax.size

    def merged(self, other: _Loads) -> _Loads:
        """Both sums (pure)."""
        moves = {q: [a + b for a, b in zip(self.moves.get(q, (0, 0.0, 0.0)), other.moves.get(q, (0, 0.0, 0.0)),
                                           strict=True)] for q in {**self.moves, **other.moves}}
        return _Loads(self.xtx + other.xtx, self.xty + other.xty, self.n + other.n, self.up_sum + other.up_sum,
                      self.up_n + other.up_n, moves,
                      tuple(a + b for a, b in zip(self.speeds, other.speeds, strict=True)))


@dataclass
class CarHealth:
    """What a car test's health is judged from, gathered from parts of the test: each channel's scan (its file
    samples) and the wiring's sums (the loads against the accelerations, the vertical axis, the speeds; on the
    test's clock, SI). Parts of the test that do not overlap combine in any order (`merged`); `car_findings` judges
    the whole. Small (a few numbers per channel and what was found): a segment's map returns one."""

    scans: dict[str, ChannelScan]  # quantity -> its channel's scan
    sums: _Loads

    def merged(self, other: CarHealth) -> CarHealth:
        """Both parts (pure: neither changes)."""
        return CarHealth({q: s.merge(other.scans[q]) for q, s in self.scans.items()}, self.sums.merged(other.sums))


# per process: what the health of a vehicle's windows needs, made once, not for every segment (the vehicle's suite is
# built anew by each `Vehicle.suite`: 3.5 ms of a segment's set-up, a sixth of its scan). (what, id(vehicle), key) ->
# (the vehicle, kept so that its id is not reused while the entry lives; the value)
_MEMO: dict[tuple, tuple[object, object]] = {}
_MEMO_SIZE = 64


def _memo(what: str, vehicle, key: tuple, make: Callable[[], object]):
    """make(), once per process for this vehicle (the same object) and key."""
    k = (what, id(vehicle), key)
    hit = _MEMO.get(k)
    if hit is None or hit[0] is not vehicle:
        if len(_MEMO) >= _MEMO_SIZE:
            _MEMO.clear()
        hit = _MEMO[k] = (vehicle, make())
    return hit[1]


def car_scans(window, vehicle) -> dict[str, ChannelScan]:
    """quantity -> an empty `ChannelScan` of its file channel: the sensor's declared range and resolution (the
    vehicle's suite) in the file's unit, what a still channel means, the shortest plateau (0.1 s). window: a
    `CarTestPlan` or a `SegmentWindow` (their channels, units and factors). The scans' settings are made once per
    process for a vehicle and a file's channels (`_scan_settings`), the scans anew each call."""
    key = (tuple(window.quantity_names.items()), tuple(window.factors.items()), window.index.channels, window.fs)
    settings = _memo("scans", vehicle, key, lambda: _scan_settings(window, vehicle))
    return {q: ChannelScan(*args, **options) for q, args, options in settings}


def _scan_settings(window, vehicle) -> tuple[tuple[str, tuple, dict], ...]:
    """(quantity, ChannelScan's arguments, its keywords) of each of the window's quantities (`car_scans`)."""
    suite = vehicle.suite
    units = window.index.units
    fitted = set(suite.names)
    out = []
    for q, name in window.quantity_names.items():
        c = suite[q] if q in fitted else None
        # the suite's figures are in its unit, the values in the file's: x_file = x_suite * f_suite / f_file
        k = unit_factor(c.unit)[0] / window.factors[q] if c is not None else 1.0
        limits = None if c is None or c.range is None else tuple(sorted((c.range[0] * k, c.range[1] * k)))
        out.append((q, (name, units.get(name, ""), limits, abs(c.resolution * k) if c else 0.0),
                    {"still": next((w for key, w in _STILL.items() if q.startswith(key)), None),
                     "min_run": max(5, round(0.1 * window.fs))}))
    return tuple(out)


def segment_health(w: SegmentWindow, vehicle, own: tuple[float, float, bool], samples: Mapping[str, Channel],
                   channels: Mapping[str, NDArray[np.float64]]) -> CarHealth:
    """The health gathered on one segment, from what its map read anyway: `samples`, the file's samples of each
    channel around the window (file unit, own stamps: `sources.read_segment`'s file_samples), and `channels`, the
    quantities on the window's clock (SI). own: (t_start, t_end, end included) s, the part of the test this segment
    answers for (segments overlap by the filter's borders: each sample is scanned by one segment)."""
    t0, t1, closed = own
    scans = car_scans(w, vehicle)
    for q, name in w.quantity_names.items():
        ch = samples[name]
        a, b = np.searchsorted(ch.time, [t0, t1], side="left")
        if closed:
            b = np.searchsorted(ch.time, t1, side="right")
        scans[q].add(ch.time[a:b], ch.values[a:b])
    a, b = np.searchsorted(w.clock, [t0, t1], side="left")
    if closed:
        b = w.clock.size
    got = {q: x[a:b] for q, x in channels.items()}
    sums = _Loads()
    loads = [f"wft_{c}_Fz" for c in CORNER_TAGS]
    if b - a > 1 and all(q in got for q in (*loads, "imu_ax", "imu_ay")):
        sums.add(got["imu_ax"], got["imu_ay"], np.column_stack([got[q] for q in loads]))
    for q in ("imu_ax", "imu_ay"):
        if q in got:
            sums.move(q, got[q])
    ground = next((q for q in ("correvit_vx", "gnss_vx") if q in got), None)
    wheels = [f"wheel_speed_{c}" for c in CORNER_TAGS if f"wheel_speed_{c}" in got]
    if ground is not None and wheels and b - a > 1:
        w_roll = np.mean([got[q] for q in wheels], axis=0) * vehicle.geometry.wheel_radius
        moving = np.abs(w_roll) > MOVING
        sums.speeds = (float(got[ground][moving] @ w_roll[moving]), float(w_roll[moving] @ w_roll[moving]),
                       int(np.count_nonzero(moving)))
    up = _vertical_axis(vehicle)
    if up is not None and up[0] in got:
        sums.up_sum, sums.up_n = float(np.sum(got[up[0]])), got[up[0]].size
    return CarHealth(scans, sums)


def car_health(plan: CarTestPlan, vehicle) -> list[Finding]:
    """The findings of one planned car test (module doc), errors first, read here a window of `WINDOW_S` at a time
    (the identification gathers the same from its segments instead: `segment_health`). vehicle:
    `vehicle.description.Vehicle`."""
    N = plan.samples
    step = max(2, int(WINDOW_S * plan.fs))
    starts = range(0, N, step)
    edges = clock_at(plan.clock, [*starts, N - 1])  # each window's first stamp and the test's last, in one pass
    whole = None
    for j, lo in enumerate(starts):
        hi = min(N, lo + step)
        w = clock_read(segment_window(plan, lo, min(N, hi + 1)))  # the next window's first stamp closes this one
        samples: dict[str, Channel] = {}
        channels = read_segment(w, file_samples=samples)
        part = segment_health(w, vehicle, (float(edges[j]), float(edges[j + 1]), hi == N), samples, channels)
        whole = part if whole is None else whole.merged(part)
    return car_findings(whole, vehicle, plan)


def car_findings(health: CarHealth, vehicle, plan: CarTestPlan) -> list[Finding]:
    """The findings of a whole car test's gathered health (module doc), errors first."""
    t0, t1 = float(plan.clock[0]), float(plan.clock[-1])
    acc = health.sums
    out = []
    for q, scan in health.scans.items():
        for f in scan.findings():
            if q.startswith(_REPAIRED) and f.kind in ("clipped", "out of range") and "declared range" in f.detail:
                f = replace(f, severity=NOTE, fix="the estimator replaces these samples by the kinematic tables' "
                            "value at the measured clearance and steering-wheel angle")
            if f.kind == "dead" and q in _MOVED_BY and acc.std(_MOVED_BY[q]) <= EXCITED:
                f = replace(f, severity=WARNING, detail=f.detail.replace(" (a dead or disconnected sensor)", ""),
                            fix=f"fine if this test has no such motion ({_MOVED_BY[q]} varies "
                            f"by {acc.std(_MOVED_BY[q]):.2g} m/s^2 RMS); otherwise check the sensor and its wiring")
            out.append(f)
    loads = [f"wft_{c}_Fz" for c in CORNER_TAGS]
    if acc.n > 3:
        out += _wiring(acc, vehicle, [plan.quantity_names[q] for q in loads], t0, t1)
    ground = next((q for q in ("correvit_vx", "gnss_vx") if q in plan.quantity_names), None)
    wheels = [f"wheel_speed_{c}" for c in CORNER_TAGS if f"wheel_speed_{c}" in plan.quantity_names]
    if acc.speeds[2] > 10 and acc.speeds[1] > 0:
        out += _speed(acc.speeds[0] / acc.speeds[1], plan.quantity_names[ground], wheels, t0, t1)
    up = _vertical_axis(vehicle)
    if up is not None and acc.up_n:
        out += _gravity(acc.up_sum / acc.up_n, up, plan.quantity_names.get(up[0], up[0]), t0, t1)
    order = {ERROR: 0, WARNING: 1, NOTE: 2}
    return sorted(out, key=lambda f: order[f.severity])


def expected_loads(vehicle) -> tuple[NDArray[np.float64], float]:
    """Per corner (rl, rr, fl, fr) the a priori [static load N, dFz/dax, dFz/day (N per m/s^2)], (4, 3), and the
    a priori weight, N (module doc; ax forward, ay left, ISO: braking loads the front, a left turn the right)."""
    v = {**vehicle.a_priori.values, **vehicle.known}
    g = vehicle.geometry
    m = v["M6"] + sum(v.get(f"M{j}", 0.0) for j in WHEELS)
    xg, zg = v["MX6"] / v["M6"], v["MZ6"] / v["M6"]
    h = xg - (g.wheel_centre_height - g.wheel_radius)  # the centre of mass above the ground
    L = g.wheelbase
    front = (zg - g.rear.position) / L
    out = np.empty((4, 3))
    for k in range(4):
        ax = g.axle(k)
        right = 1.0 if k % 2 else -1.0
        out[k] = (m * G * (front if k >= 2 else 1.0 - front) / 2.0, (-1.0 if k >= 2 else 1.0) * m * h / (2.0 * L),
                  right * m * h / (4.0 * ax.half_track))
    return out, m * G


def _wiring(acc: _Loads, vehicle, names: Sequence[str], t0: float, t1: float) -> list[Finding]:
    exp, weight = expected_loads(vehicle)
    n = acc.n
    mean = acc.xtx[0] / n
    std = np.sqrt(np.maximum(np.diag(acc.xtx)[1:] / n - mean[1:] ** 2, 0.0))
    used = [0] + [1 + i for i in range(2) if std[i] > EXCITED]  # the accelerations this test moves
    b = np.linalg.solve(acc.xtx[np.ix_(used, used)], acc.xty[used]).T  # (4, len(used)): each load's coefficients
    e = exp[:, used]
    tol = np.concatenate(([0.1 * weight / 4.0], 0.5 * np.abs(exp[0, used[1:]])))
    out = []
    total = float(acc.xty[0].sum() / n)
    if not 0.8 < total / weight < 1.25:
        out.append(Finding(" + ".join(names), "weight", ERROR if not 0.67 < total / weight < 1.5 else WARNING,
                           t0, t1, f"the four wheel loads average {total:.6g} N in all, the a priori weight is "
                           f"{weight:.6g} N ({total / weight:.3g} times)",
                           "check the wheel force channels' unit (N, kN, daN) and calibration, and the vehicle "
                           "file's a priori mass"))

    def cost(order: Sequence[int]) -> float:
        return float(np.sum(((b - e[list(order)]) / tol) ** 2))

    ident = cost(range(4))
    best = min(itertools.permutations(range(4)), key=cost)
    if list(best) != [0, 1, 2, 3] and ident > 9.0 and cost(best) < ident / 4.0:
        moved = [k for k in range(4) if best[k] != k]
        reads = ", ".join(f"{names[k]} reads the {_corner(best[k])} load" for k in moved)
        seen = "; ".join(f"{names[k]}: {_coefficients(b[k], used)}" for k in moved)
        out.append(Finding(" and ".join(names[k] for k in moved), "swapped", ERROR, t0, t1,
                           f"wired to the wrong corners: {reads} (mean load and load transfer with the "
                           f"accelerations; {seen}; the a priori set expects "
                           + "; ".join(f"{_corner(k)}: {_coefficients(exp[k, used], used)}" for k in moved)
                           + f"; {cost(best) / ident:.2g} of the misfit in that order)",
                           "swap the channels' names in the file, or map each corner's quantity to its channel in "
                           "[channels] (e.g. wft_fl_Fz = { channels = [\"<the file's channel>\"] })", 1.0))
    return out


def _corner(k: int) -> str:
    return ("rear left", "rear right", "front left", "front right")[k]


def _coefficients(row: NDArray, used: Sequence[int]) -> str:
    label = ("mean {:.0f} N", "{:+.0f} N per m/s^2 of ax", "{:+.0f} N per m/s^2 of ay")
    return ", ".join(label[u].format(v) for u, v in zip(used, row, strict=True))


def _vertical_axis(vehicle) -> tuple[str, float] | None:
    """The accelerometer channel closest to the chassis' vertical and what it reads at rest, m/s^2 (specific
    force: +g on an axis pointing up), or None without one within 30 degrees of it. Once per process and vehicle."""
    return _memo("up", vehicle, (), lambda: _up_axis(vehicle))


def _up_axis(vehicle) -> tuple[str, float] | None:
    A = np.asarray(vehicle.geometry.imu_axes, dtype=float)  # rows: the unit's x, y, z in frame 6 (x6 up)
    i = int(np.argmax(np.abs(A[:, 0])))
    if abs(A[i, 0]) < math.cos(math.radians(30.0)):
        return None
    name = ("imu_ax", "imu_ay", "imu_az")[i]
    return (name, G * float(A[i, 0])) if name in vehicle.suite.names else None


MOVING = 2.0  # m/s: the wheels' rolling speed above which the speed over ground is compared with it
SPEED_RATIO = (0.7, 1.4)  # speed over ground / the wheels' rolling speed: slip and radius errors stay inside


def _speed(ratio: float, channel: str, wheels: Sequence[str], t0: float, t1: float) -> list[Finding]:
    """The speed over ground against the wheels' rolling speed (spin rate times the radius): a unit slip (km/h
    logged as m/s reads 3.6 times slow) or a wrong scale shows as a ratio far from 1."""
    if SPEED_RATIO[0] <= ratio <= SPEED_RATIO[1]:
        return []
    return [Finding(channel, "speed", ERROR, t0, t1,
                    f"reads {ratio:.3g} times the speed the wheels roll at ({', '.join(wheels)} times the wheel "
                    "radius), where slip and the radius's error keep it within "
                    f"{SPEED_RATIO[0]:g}..{SPEED_RATIO[1]:g}",
                    "a unit slip (km/h and m/s differ by 3.6) or a wrong scale: fix the channel's unit in the file's "
                    "header or in [channels], or the wheel radius in the vehicle file", 1.0)]


def _gravity(mean: float, up: tuple[str, float], channel: str, t0: float, t1: float) -> list[Finding]:
    expect = up[1]
    if abs(mean - expect) <= 0.25 * G:
        return []
    why = ("its sign is inverted (the axis points down)" if abs(mean + expect) <= 0.25 * G
           else "a wrong unit (g or m/s^2?) or a wrong axis")
    return [Finding(channel, "gravity", ERROR, t0, t1,
                    f"averages {mean:.4g} m/s^2 over the test where gravity alone gives {expect:.4g} m/s^2: {why}",
                    "fix the channel's unit or sign in the file or in [channels], or the unit's axes in the vehicle "
                    "file (imu_axes)", 1.0)]


def check_car_tests(cfg: IdentifyConfig, plans: Sequence[CarTestPlan], vehicle, say: Progress,
                    gathered: Mapping[str, CarHealth] | None = None) -> list[dict]:
    """Every planned test's findings: an error stops the run (`ConfigError`: one line naming the test's file,
    the channel, the time span and the fix, and how many more errors there are); the rest is said and returned
    as dicts (the finding's fields, the test and its file), for results.json. gathered: test -> its health as the
    identification's segments gathered it (`segment_health`, combined); None: each test's file read here."""
    return _reported(cfg, [(plan.test, str(plan.index.path), f) for plan in plans
                           for f in (car_health(plan, vehicle) if gathered is None
                                     else car_findings(gathered[plan.test], vehicle, plan))], say)


def robot_health(plan: RobotTestPlan, cfg: IdentifyConfig | None = None, model=None,
                 columns: Sequence[int] | None = None) -> list[Finding]:
    """The findings of one planned robot test, errors first: each joint's position and torque channel
    (`io.health.ChannelScan`: a boolean channel, clipped plateaus, spikes, a channel that never moves), read a window
    at a time; then, with the config, the model (a priori values) and the frame of each data column
    (`robot.data_joints`), the joints against the model (`robot_physics`). No range is declared for a robot's
    channels: clips are seen from the data. A joint that does not move in a test, or whose torque does not change,
    may be the test's design (one joint excited at a time): a warning."""
    t0, t1 = float(plan.clock[0]), float(plan.clock[-1])
    still = "fine if this joint is meant to stay still in this test; otherwise check the sensor and its wiring"
    scans = {(q, n): ChannelScan(n, u, still=still, min_run=max(5, round(0.1 * plan.fs)), continuous=True)
             for q in ("q", plan.effort) for n, u in zip(plan.channels[q], plan.units[q], strict=True)}
    files: dict[int, tuple] = {}  # q and the effort in one file (the same index): read once
    for q in ("q", plan.effort):
        files.setdefault(id(plan.indexes[q]), (plan.indexes[q], []))[1].append(q)
    for index, quantities in files.values():
        names = list(dict.fromkeys(n for q in quantities for n in plan.channels[q]))
        a = t0
        while a <= t1:
            b = min(a + WINDOW_S, t1)
            rec = read_window(index, names, a, b)
            for q in quantities:
                for n in plan.channels[q]:
                    ch = rec.channels[n]
                    keep = slice(None) if b >= t1 else ch.time < b
                    scans[(q, n)].add(ch.time[keep], ch.values[keep])
            if b >= t1:
                break
            a = b
    out = [f for scan in scans.values() for f in scan.findings()]
    if cfg is not None and model is not None and columns is not None:
        broken = {f.channel for f in out if f.severity == ERROR}
        out += robot_physics(plan, cfg, model, columns, broken)
    order = {ERROR: 0, WARNING: 1, NOTE: 2}
    return sorted(out, key=lambda f: order[f.severity])


ANTI = -0.5  # correlation of a joint's torque with the a priori model's at or below which its sign is inverted
TURN = 2.0 * math.pi
# rad: a revolute joint's positions spanning more than two turns over a test are beyond the widest range of common
# arms' joints (a UR's +-360 deg; the TX40's wrist spans 1.1 turns in its measured files)
SPAN = 2.0 * TURN


@dataclass
class RobotHealth:
    """What a robot test's joints are judged from against the model (`robot_physics`), gathered from parts of the
    test that do not overlap (a window, or a chunk of the identification's map: `gather_joints`) and combined in
    any order (`merged`): per data column, the positions' extremes with their times and the way travelled, and
    sums of the measured torque t and the a priori model's a (their correlation). A few numbers per joint."""

    k: int
    torque: bool = True  # the joint torques are known (not with identified drive gains)
    n: NDArray[np.int64] = field(init=False)  # samples in the sums, per column
    sums: NDArray[np.float64] = field(init=False)  # rows: t, a, t t, a a, t a
    low: NDArray[np.float64] = field(init=False)  # rows: value, time
    high: NDArray[np.float64] = field(init=False)
    travel: NDArray[np.float64] = field(init=False)

    def __post_init__(self) -> None:
        self.n = np.zeros(self.k, dtype=np.int64)
        self.sums = np.zeros((5, self.k))
        self.low = np.array([np.full(self.k, np.inf), np.zeros(self.k)])
        self.high = np.array([np.full(self.k, -np.inf), np.zeros(self.k)])
        self.travel = np.zeros(self.k)

    def positions(self, t: NDArray, q: NDArray, step: int) -> None:
        i, j = np.argmin(q, axis=0), np.argmax(q, axis=0)
        cols = np.arange(self.k)
        lo, hi = q[i, cols], q[j, cols]
        less, more = lo < self.low[0], hi > self.high[0]
        self.low[:, less] = np.array([lo, t[i]])[:, less]
        self.high[:, more] = np.array([hi, t[j]])[:, more]
        # on every step-th sample: less of the noise summed (the step between two parts is left out: one in a chunk)
        self.travel += np.abs(np.diff(q[::step], axis=0)).sum(axis=0)

    def torques(self, t: NDArray, a: NDArray) -> None:
        self.n += t.shape[0]
        self.sums += np.array([t.sum(0), a.sum(0), (t * t).sum(0), (a * a).sum(0), (t * a).sum(0)])

    def add_rows(self, system, columns: Sequence[int], a_priori: NDArray[np.float64]) -> None:
        """The torques of an identification chunk's rows (`robot.chunk_rows`: filtered, decimated, the slow rows
        dropped): Y the measured torque, W @ a_priori the model's (a_priori: its base parameters' values, one per
        column of W)."""
        a = system.W @ a_priori
        for i, j in enumerate(columns):
            mask = system.groups == f"joint{j}"
            y, m = system.Y[mask], a[mask]
            self.sums[:, i] += [y.sum(), m.sum(), y @ y, m @ m, y @ m]
            self.n[i] += y.size

    def merged(self, other: RobotHealth) -> RobotHealth:
        """Both parts (pure)."""
        out = RobotHealth(self.k, self.torque and other.torque)
        out.n = self.n + other.n
        out.sums = self.sums + other.sums
        out.travel = self.travel + other.travel
        lo, hi = other.low[0] < self.low[0], other.high[0] > self.high[0]
        out.low = np.where(lo, other.low, self.low)
        out.high = np.where(hi, other.high, self.high)
        return out

    def correlation(self) -> tuple[NDArray, NDArray, NDArray]:
        """(r, the torque's standard deviation, the model's), per column (r = 0 where either is still)."""
        st, sa, stt, saa, sta = self.sums / np.maximum(self.n, 1)
        vt, va = np.maximum(stt - st * st, 0.0), np.maximum(saa - sa * sa, 0.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            r = np.where((vt > 0) & (va > 0), (sta - st * sa) / np.sqrt(vt * va), 0.0)
        return r, np.sqrt(vt), np.sqrt(va)


def _judged(fs: float, cond) -> tuple[int, int]:
    """(border, step): the samples at each end of a test no torque is judged on (the filter's transient), and the
    model's torque on every step-th sample (about 10 per cut-off period)."""
    return border_samples(fs, cond.cutoff, cond.order) + 2, max(1, int(fs / (10.0 * cond.cutoff)))


def gather_joints(cfg: IdentifyConfig, model, columns: Sequence[int], clock: NDArray, fs: float, first: int,
                  own: tuple[int, int], n_samples: int, q: NDArray, tau: NDArray, gains: NDArray | None,
                  torques: bool = True) -> RobotHealth:
    """One part's `RobotHealth`: q, tau the joints' positions and torques (SI, joint side: `sources.driven`, one
    column per data joint) on the clock samples first.. of the test (clock: those samples' times), the part judged
    own = (s, e) of the test's samples (the rest read around it: the filter's transients); gains: the drive gains'
    columns (identified gains: no torque known); torques: False in an identification chunk, whose rows give them
    (`RobotHealth.add_rows`: the filtering and the regressor already done)."""
    cond = cfg.conditioning
    border, step = _judged(fs, cond)
    out = RobotHealth(len(columns), torque=gains is None)
    s, e = own[0] - first, own[1] - first
    if e > s:
        out.positions(clock[s:e], q[s:e], step)
    pick = np.arange(max(own[0], border), min(own[1], n_samples - border), step) - first
    if not (torques and out.torque) or pick.size == 0 or q.shape[0] < 2 * border:
        return out
    qf, qd, qdd = filtered_derivatives(q, fs, cond.cutoff, order=cond.order, nderiv=2)
    n = model.n
    ap = model.inverse_dynamics(to_frames(qf[pick], columns, n), to_frames(qd[pick], columns, n),
                                to_frames(qdd[pick], columns, n))[:, np.asarray(columns) - 1]
    out.torques(tau[pick], ap)
    return out


def robot_physics(plan: RobotTestPlan, cfg: IdentifyConfig, model, columns: Sequence[int],
                  broken: set[str] = frozenset(), gathered: RobotHealth | None = None) -> list[Finding]:
    """A robot test's joints against its model, on the joint side (the channels through [transmission] and the drive
    gains, SI), from `gathered` (the identification's chunks gather it: `gather_joints`) or read here a window of
    `WINDOW_S` at a time:

    - a revolute joint whose positions span more than `SPAN` (two turns; the model files hold no joint limits): in
      degrees under a [rad] header when the span read as degrees is within it and the joint swings (it travels
      more than 1.5 times its span: an error, the joint's kinematics, gravity and every regressor column would be
      wrong), else a joint that turns on and on or a motor-side angle without its gear ratio (a warning);
    - a joint torque against the torque the model's a priori values give on the measured motion (gravity load,
      inertia and friction; in the identification, its rows' Y against W times the a priori base parameters: the
      filtered, decimated rows, those of a joint slower than its min_speed dropped; read here,
      `Model.inverse_dynamics` on the filtered positions and their derivatives, the config's cut-off, on samples
      at about 10 times the cut-off): a correlation at or below `ANTI` over the test
      is a torque whose sign is inverted (an error). A gravity-loaded joint's torque follows its gravity load with
      the a priori model's sign whatever the model's errors; the a priori inertia and friction join it so that a
      fast motion, whose inertial torque may oppose the gravity load's changes, is judged right too.

    Joints whose channels have an error already (`broken`: a spike, a boolean column) are not judged; no torque is
    when a position channel has one, nor the torques with identified drive gains (their scale and sign are
    parameters)."""
    N, fs = plan.samples, plan.fs
    k = len(columns)
    border, _ = _judged(fs, cfg.conditioning)
    if 2 * border + 2 >= N:
        return []  # too short to filter: the identification says so
    sums = gathered
    if sums is None:
        size = max(2 * border + 4, int(WINDOW_S * fs))
        for lo in range(0, N, size):
            hi = min(N, lo + size)
            a, b = max(0, lo - border), min(N, hi + border)  # read past the part judged: the filter's transients
            raw = read_robot_window(plan, a, b)
            part = gather_joints(cfg, model, columns, plan.clock[a:b], fs, a, (lo, hi), N,
                                 *driven(cfg, raw["q"], raw[plan.effort], k))
            sums = part if sums is None else sums.merged(part)
    torque, travel = sums.torque, sums.travel
    t0, t1 = float(plan.clock[0]), float(plan.clock[-1])
    out = []
    q_names = _joint_channels(cfg, plan, "q", k)
    tau_names = _joint_channels(cfg, plan, plan.effort, k)
    sigma = np.asarray(model.tree.sigma)[np.asarray(columns) - 1]
    for j in range(k):
        span = float(sums.high[0, j] - sums.low[0, j])
        if sigma[j] != 0 or not span > SPAN or broken & set(q_names[j]):
            continue
        when = sorted((float(sums.low[1, j]), float(sums.high[1, j])))
        deg = math.radians(span)
        name = " and ".join(q_names[j])
        winds = travel[j] <= 1.5 * span  # a joint turning on travels its span once; one that swings, twice or more
        if deg <= SPAN and not winds:
            out.append(Finding(name, "range", ERROR, when[0], when[1],
                               f"joint {j + 1}'s position spans {span:.4g} rad ({span / TURN:.3g} turns, from "
                               f"{sums.low[0, j]:.4g} to {sums.high[0, j]:.4g} rad), {deg:.3g} rad read as degrees: "
                               "positions in degrees under a [rad] header", "give the channel's unit: "
                               "unit = \"deg\" in [channels] q, or [deg] in the file's header (a joint that does "
                               "turn on and on: data_health = \"warn\" in [identification])", 1.0))
        else:
            out.append(Finding(name, "range", WARNING, when[0], when[1],
                               f"joint {j + 1}'s position spans {span:.4g} rad ({span / TURN:.3g} turns, "
                               f"{travel[j]:.4g} rad travelled)",
                               "fine for a joint that turns on and on; a motor-side angle needs its gear ratio "
                               "([transmission] q)", 1.0))
    # the model's torque from positions that are wrong anywhere is wrong at every joint (the dynamics couple them)
    q_bad = any(f.severity == ERROR for f in out) or bool(broken & set(plan.channels["q"]))
    if torque and not q_bad:
        r, sd_t, sd_a = sums.correlation()
        for j in range(k):
            if r[j] > ANTI or sums.n[j] <= 10 or broken & set(tau_names[j]):
                continue
            name = " and ".join(tau_names[j])
            out.append(Finding(name, "sign", ERROR, t0, t1,
                               f"joint {j + 1}'s torque runs against the one the model file's a priori values give "
                               f"on the measured motion (gravity load, inertia, friction): correlation {r[j]:.2f} "
                               f"over {sums.n[j]} samples while the joints move ({sd_t[j]:.3g} N.m RMS measured, "
                               f"{sd_a[j]:.3g} N.m expected): its sign is inverted",
                               "negate the channel (a -1 in its row of [transmission] tau, or the logger's sign "
                               "convention), or check the model file's a priori masses and first moments", 1.0))
    return out


def _joint_channels(cfg: IdentifyConfig, plan: RobotTestPlan, quantity: str, k: int) -> list[tuple[str, ...]]:
    """Each joint's channels of `quantity` (those its row of [transmission] mixes; the j-th without one)."""
    names = plan.channels[quantity]
    m = cfg.transmission.get("q" if quantity == "q" else "tau")
    if m is None or m.shape != (k, len(names)):
        return [(names[j],) if j < len(names) else () for j in range(k)]
    return [tuple(names[i] for i in np.flatnonzero(m[j])) for j in range(k)]


def check_robot_test(cfg: IdentifyConfig, plan: RobotTestPlan, say: Progress, model=None,
                     columns: Sequence[int] | None = None) -> list[dict]:
    """`robot_health` of one planned test, as `check_car_tests` reports a car's: an error stops the run
    (`ConfigError`, one line), the rest is said and returned as dicts. model, columns: the robot's model (a priori
    values) and the frame of each data column, for the joints' physics (`robot_physics`; without them, each
    channel alone: the identification judges the joints from its chunks, `check_robot_joints`)."""
    return _reported(cfg, _sourced(plan, robot_health(plan, cfg, model, columns)), say)


def check_robot_joints(cfg: IdentifyConfig, plan: RobotTestPlan, say: Progress, model, columns: Sequence[int],
                       broken: set[str], gathered: RobotHealth | None) -> list[dict]:
    """`robot_physics` of one test from what the identification's chunks gathered (`gather_joints`, combined), as
    `check_robot_test` reports: broken, the channels whose own findings were errors (data_health = "warn")."""
    found = robot_physics(plan, cfg, model, columns, broken, gathered)
    order = {ERROR: 0, WARNING: 1, NOTE: 2}
    return _reported(cfg, _sourced(plan, sorted(found, key=lambda f: order[f.severity])), say)


def _sourced(plan: RobotTestPlan, found: Sequence[Finding]) -> list[tuple[str, str, Finding]]:
    """(test, the file of the finding's channel(s), finding)."""
    e = plan.effort
    return [(plan.test, str(plan.indexes[e if set(f.channel.split(" and ")) & set(plan.channels[e]) else "q"].path),
             f) for f in found]


def _reported(cfg: IdentifyConfig, found: Sequence[tuple[str, str, Finding]], say: Progress) -> list[dict]:
    """The findings (test, its file, finding) said and returned as dicts (the finding's fields, the test and its
    file), for results.json; with [identification] data_health = "stop" (the default) an error stops the run
    instead (`ConfigError`: one line naming the test's file, the channel, the span and the fix, and the channels
    of the other errors)."""
    listed, errors = [], []
    for test, source, f in found:
        line = f"test {test!r} ({source}): {f.text()}"
        if f.severity == ERROR and cfg.data_health == "stop":
            errors.append((line, f.channel))
        else:
            say(f"data health, {f.severity}: {line}")
        listed.append({"test": test, "file": source, **f.as_dict()})
    if errors:
        others = list(dict.fromkeys(channel for _, channel in errors[1:]))
        more = (f" ({len(errors) - 1} more error(s), on {', '.join(others[:6])}{', ...' if len(others) > 6 else ''}; "
                "data_health = \"warn\" in [identification] says each and runs on)" if len(errors) > 1 else "")
        raise ConfigError(f"{cfg.path}: data health: {errors[0][0]}{more}")
    return listed


def health_note(listed: Sequence[dict]) -> str:
    """The findings that did not stop the run, a paragraph to append to the notes under the tables (its own
    first line break; '' when none)."""
    if not listed:
        return ""
    lines = [f"  {d['severity']}: {d['test']}: channel {d['channel']!r}: {d['detail']}, "
             f"t = {d['t_start']:.6g}..{d['t_end']:.6g} s: {d['fix']}" for d in listed]
    return "\nData health (checked before the identification):\n" + "\n".join(lines) + "\n"


__all__ = ["RobotHealth", "car_health", "check_car_tests", "check_robot_joints", "check_robot_test", "expected_loads",
           "gather_joints", "health_note", "robot_health", "robot_physics"]
