"""The paper's sensor suite (Table 1): what each logged channel means and how it errs.

Every channel is logged on one acquisition clock of 625 Hz (sample time 1.6 ms, the
paper's) with a `time` column in s. Names and units are those a logger writes; the
meaning of each channel is fixed here and nowhere else, so that the simulator that
writes the channels and the estimator that reads them agree.

Frames (see template.py): ground x0 right, y0 forward, z0 up; chassis frame 6 x6 up,
y6 right, z6 forward, origin O6 mid rear axle at wheel-centre height. "Vehicle axes"
below are ISO 8855 axes fixed in the chassis: x forward (= z6), y left (= -y6), z up
(= x6). Angles about them follow the right-hand rule: roll > 0 lowers the right side,
pitch > 0 is NOSE DOWN (the template's q5 > 0 is nose up), yaw rate > 0 turns left.

  channel                        unit    meaning
  imu_yaw_rate, _pitch_rate,     deg/s   angular velocity of the chassis, components about
    _roll_rate                           the vehicle z, y, x axes (ISO)
  imu_ax, imu_ay, imu_az         m/s^2   specific force at the unit (O6): acceleration of the
                                         point minus gravity, vehicle axes (az = +9.81 at rest)
  imu_roll, imu_pitch            deg     attitude of the vehicle axes w.r.t. the horizontal:
                                         R0_vehicle = Rz(yaw) Ry(pitch) Rx(roll), ISO signs
  correvit_vx                    km/h    velocity over ground of the Correvit point, along x
  correvit_vy                    m/s     ... and along y (vehicle axes, chassis-fixed)
  laser_height_{c}               mm      distance from the sensor to the ground plane along
                                         the chassis' downward vertical axis -x6
  clearance_{c}                  mm      damper clearance q9, q18, q27, q36 (bump > 0)
  steer_{c}                      deg     steering joint q10, q19, q28, q37 (> 0 to the left)
  camber_{c}                     deg     camber joint q11, q20, q29, q38 (> 0 top outboard)
  wheel_speed_{c}                rev/s   wheel spin rate qd14, qd23, qd32, qd41 (> 0 forward)
  wft_{c}_Fx, _Fy, _Fz           N       wrench of the ground on the wheel, at the WHEEL CENTRE,
  wft_{c}_Mx, _My, _Mz           N.m     in the non-spinning wheel frame = the axes of the tire
                                         frame 15+9k: x forward in the wheel plane, y left along
                                         the axle, z up in the wheel plane (car_identification's
                                         `wheel_wrenches`, corner order rl rr fl fr)
  steering_wheel                 deg     steering-wheel angle (> 0 to the left)
  spin_torque_{c}                N.m     drive + brake torque on the wheel joint about its axle
                                         (z14 points left: > 0 drives forward); a command,
                                         logged exactly (the spin equations take it as known)

with {c} in rl, rr, fl, fr = the corners of wheels 14, 23, 32, 41. With the truth switch
the logger also writes `true_q{j}`, `true_qd{j}`, `true_qdd{j}` (j = 1..42, SI: m, rad)
and `true_wft_{c}_{Fx..Mz}` (the noise-free wrenches, N and N.m).

Error model of a channel (`SensorChannel`), applied in this order by `measure`:
1. band limit: a causal 2nd-order Butterworth low-pass at `bandwidth` (the -3 dB
   frequency), run on the 625 Hz truth from its steady state (no start transient);
2. sampling at the sensor's own `rate`, then sample-and-hold onto the 625 Hz clock (a
   value is held until the sensor's next sample, as a logger does);
3. noise: white Gaussian of standard deviation `accuracy` -- the table's "accuracy" is
   TAKEN AS 1 sigma (conservative: a datasheet figure is often 2 sigma) -- plus a constant
   `bias` drawn once per run, N(0, bias^2), where a real sensor drifts (gyros,
   accelerometers, inclinometers, the Correvit's scale-free offset, wheel-force zeros);
4. quantisation to `resolution` (round to the nearest step), then saturation to `range`.
The random numbers come from a numpy Generator (seeded by the caller); `noise=False`
gives the band-limited, sampled, quantised, saturated channel without noise or bias,
and `ideal=True` in `SensorSuite.measure` skips every step (the truth in the channel's unit).

Values not in the paper's Table 1 are chosen and marked `source="chosen"`.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ..car_frames import CORNER_TAGS as CORNER_TAGS  # wheels 14, 23, 32, 41; the car's modules name it from here
from ..kinematics.forward import forward_kinematics, joint_array
from .geometry import CarGeometry, demo_geometry, side
from .template import damper, tabulated, tire, wheel

ACQUISITION_RATE = 625.0  # Hz (the paper's sample time 1.6 ms)
SAMPLE_TIME = 1.0 / ACQUISITION_RATE
WFT_COMPONENTS = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
PAPER = "paper, Table 1"
CHOSEN = "chosen (not in the paper)"
# vehicle (ISO 8855) axes in frame 6: rows = x forward, y left, z up
ISO_AXES = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])


class SensorError(ValueError):
    """A sensor definition or a measurement request that cannot be used."""


@dataclass(frozen=True)
class SensorChannel:
    """One logged channel: meaning, mounting and error model (all in the channel's unit).

    name, unit: as the logger writes them. quantity: what is measured (words and, where it
    is a joint, the joint: "q9"). sensor: the device. mounting: the point in frame 6 (m),
    or None when the channel is not tied to a chassis point (a joint, a wheel).
    axes: words naming the axis of the component. accuracy: 1-sigma white noise; bias:
    1-sigma of a constant offset drawn per run; bandwidth: -3 dB frequency, Hz (None:
    no band limit); resolution: quantisation step (0: none); range: (low, high) saturation
    (None: none); rate: the sensor's own sample rate, Hz. source: where the numbers come from.
    """

    name: str
    unit: str
    quantity: str
    sensor: str
    axes: str
    accuracy: float
    bandwidth: float | None
    resolution: float
    range: tuple[float, float] | None
    rate: float
    bias: float = 0.0
    mounting: tuple[float, float, float] | None = None
    joint: int | None = None
    source: str = PAPER

    def saturated(self, x: np.ndarray) -> np.ndarray:
        """Where the logged values x (channel unit) sit at a limit of `range`: (N,) bool."""
        if self.range is None:
            return np.zeros(np.shape(x), dtype=bool)
        return (x <= self.range[0]) | (x >= self.range[1])

    def as_dict(self) -> dict:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}


def _imu(g: CarGeometry) -> list[SensorChannel]:
    p = tuple(float(x) for x in g.imu_position)
    sag = "inertial unit (Sagem)"
    out = []
    for name, axis, joint in (("yaw_rate", "vehicle z (up)", 4), ("pitch_rate", "vehicle y (left)", 5),
                              ("roll_rate", "vehicle x (forward)", 6)):
        out.append(SensorChannel(f"imu_{name}", "deg/s", f"chassis angular velocity about the {axis}", sag, axis,
                                 accuracy=0.01, bandwidth=10.0, resolution=0.005, range=(-50.0, 50.0), rate=125.0,
                                 bias=0.01, mounting=p, joint=joint,
                                 source=PAPER + "; rate and bias (gyro drift, 1 sigma) chosen"))
    for name, axis, acc in (("ax", "vehicle x (forward)", 0.02), ("ay", "vehicle y (left)", 0.1),
                            ("az", "vehicle z (up)", 0.02)):
        out.append(SensorChannel(f"imu_{name}", "m/s^2", f"specific force (acceleration minus gravity) along the "
                                 f"{axis} at the rear axle", sag, axis, accuracy=acc, bandwidth=10.0, resolution=0.01,
                                 range=(-15.0, 15.0) if name != "az" else (-5.0, 25.0), rate=125.0, bias=0.01,
                                 mounting=p,
                                 source=PAPER + "; rate, bias (1 sigma) and the vertical range around +1 g chosen"))
    for name, axis, joint in (("roll", "about vehicle x", 6), ("pitch", "about vehicle y, nose down > 0", 5)):
        out.append(SensorChannel(f"imu_{name}", "deg", f"absolute {name} angle w.r.t. gravity (ISO 8855)", sag, axis,
                                 accuracy=0.1, bandwidth=5.0, resolution=0.05, range=(-50.0, 50.0), rate=125.0,
                                 bias=0.05, mounting=p, joint=joint, source=PAPER + "; rate and bias chosen"))
    return out


def correvit_point(g: CarGeometry) -> tuple[float, float, float]:
    """The Correvit's mounting point in frame 6: `geometry.correvit_position`, or by default right flank,
    mid-wheelbase, 0.1 m above the wheel centres (chosen: an optical speed sensor on a bracket over the right
    doors)."""
    if g.correvit_position is not None:
        return tuple(float(x) for x in g.correvit_position)
    return (g.wheel_centre_height + 0.1, g.rear.half_track + 0.25, 0.5 * (g.front.position + g.rear.position))


def gnss_point(g: CarGeometry) -> tuple[float, float, float]:
    """The GNSS/INS velocity's point in frame 6: `geometry.gnss_position`, or by default the roof antenna on the
    centreline at mid-wheelbase, 1.1 m above the wheel centres (chosen)."""
    if g.gnss_position is not None:
        return tuple(float(x) for x in g.gnss_position)
    return (g.wheel_centre_height + 1.1, 0.0, 0.5 * (g.front.position + g.rear.position))


def _gnss(g: CarGeometry) -> list[SensorChannel]:
    p = gnss_point(g)
    dev = "GNSS/INS (dual-antenna receiver with an inertial unit)"
    return [SensorChannel(f"gnss_v{a}", "m/s", f"velocity over ground of the antenna point along vehicle {a}", dev,
                          f"vehicle {a} ({'forward' if a == 'x' else 'left'})", accuracy=0.03, bandwidth=10.0,
                          resolution=0.001, range=(-70.0, 70.0), rate=100.0, mounting=p,
                          source=CHOSEN + ": a survey-grade GNSS/INS velocity (0.03 m/s, 100 Hz)") for a in "xy"]


def laser_point(g: CarGeometry, corner: int) -> tuple[float, float, float]:
    """A laser height sensor's point in frame 6: `geometry.laser_positions[corner]`, or by default 0.35 m
    inboard of the wheel centre, on the axle line, at wheel-centre height (chosen: on the body beside the
    damper, seeing flat ground inside the wheel track)."""
    if g.laser_positions is not None:
        return tuple(float(x) for x in g.laser_positions[corner])
    ax = g.axle(corner)
    return (g.wheel_centre_height, side(corner) * (ax.half_track - 0.35), ax.position)


def _correvit(g: CarGeometry) -> list[SensorChannel]:
    p = correvit_point(g)
    dev = "optical speed sensor (Correvit)"
    return [
        SensorChannel("correvit_vx", "km/h", "velocity over ground of the sensor point along vehicle x", dev,
                      "vehicle x (forward)", accuracy=1.0, bandwidth=5.0, resolution=0.01, range=(-150.0, 150.0),
                      rate=125.0, mounting=p, source=PAPER + "; resolution and rate chosen"),
        SensorChannel("correvit_vy", "m/s", "velocity over ground of the sensor point along vehicle y", dev,
                      "vehicle y (left)", accuracy=0.075, bandwidth=5.0, resolution=0.001, range=(-15.0, 15.0),
                      rate=125.0, mounting=p, source=PAPER + "; resolution and rate chosen"),
    ]


def _corners(g: CarGeometry) -> list[SensorChannel]:
    out = []
    for k, c in enumerate(CORNER_TAGS):
        out.append(SensorChannel(f"laser_height_{c}", "mm", "distance from the sensor to the ground along -x6",
                                 "laser height sensor", "chassis down (-x6)", accuracy=1.0, bandwidth=200.0,
                                 resolution=0.062, range=(50.0, 600.0), rate=625.0, bias=0.5,
                                 mounting=laser_point(g, k),
                                 source=PAPER + " (ground clearances: 1 mm, 200 Hz, 0.062 mm); mounting, range and "
                                 "bias chosen"))
    for k, c in enumerate(CORNER_TAGS):
        out.append(SensorChannel(f"clearance_{c}", "mm", f"damper clearance q{damper(k)} (bump > 0)",
                                 "video camera (Zimmer)",
                                 "damper axis", accuracy=1.0, bandwidth=200.0, resolution=0.062, range=(-125.0, 125.0),
                                 rate=625.0, joint=damper(k), source=PAPER + "; rate chosen"))
    for k, c in enumerate(CORNER_TAGS):
        steer = tabulated(k)[0]
        out.append(SensorChannel(f"steer_{c}", "deg", f"steering joint q{steer} (> 0 to the left)",
                                 "video camera (Zimmer)", "chassis vertical x6", accuracy=0.033, bandwidth=30.0,
                                 resolution=0.011, range=(-5.0, 5.0), rate=125.0, joint=steer,
                                 source=PAPER + "; rate chosen"))
    for k, c in enumerate(CORNER_TAGS):
        camber = tabulated(k)[1]
        out.append(SensorChannel(f"camber_{c}", "deg", f"camber joint q{camber} (> 0 top outboard)",
                                 "video camera (Zimmer)", "wheel heading", accuracy=0.042, bandwidth=30.0,
                                 resolution=0.014, range=(-2.5, 2.5), rate=125.0, joint=camber,
                                 source=PAPER + "; rate chosen"))
    for k, c in enumerate(CORNER_TAGS):
        out.append(SensorChannel(f"wheel_speed_{c}", "rev/s", f"wheel spin rate qd{wheel(k)} (> 0 rolling forward)",
                                 "dynamometric wheel (IGEL)", "wheel axle (left)", accuracy=0.005, bandwidth=150.0,
                                 resolution=0.001, range=(-30.0, 30.0), rate=625.0, joint=wheel(k),
                                 source=PAPER + " (30 rev/s, 150 Hz); accuracy, resolution and rate chosen"))
    axes = {"Fx": "wheel x (forward, wheel plane)", "Fy": "wheel y (left, axle)", "Fz": "wheel z (up, wheel plane)"}
    axes.update({"M" + a[1]: v for a, v in axes.items()})
    for k, c in enumerate(CORNER_TAGS):
        for comp in WFT_COMPONENTS:
            force = comp[0] == "F"
            out.append(SensorChannel(
                f"wft_{c}_{comp}", "N" if force else "N.m",
                f"{'force' if force else 'moment about the wheel centre'} of the ground on wheel {wheel(k)}, "
                f"non-spinning wheel frame (axes of frame {tire(k)})",
                "dynamometric wheel (IGEL)", axes[comp], accuracy=25.0 if force else 5.0, bandwidth=150.0,
                resolution=1.0 if force else 0.1, range=(-20000.0, 20000.0) if force else (-5000.0, 5000.0),
                rate=625.0, bias=10.0 if force else 2.0, joint=wheel(k),
                source=PAPER + " (forces 25 N, 20 kN, 150 Hz); moments, resolution, bias and rate chosen"))
    return out


def _driver() -> list[SensorChannel]:
    out = [SensorChannel("steering_wheel", "deg", "steering-wheel angle (> 0 to the left)", "steering-wheel encoder",
                         "steering column", accuracy=0.1, bandwidth=100.0, resolution=0.1, range=(-720.0, 720.0),
                         rate=625.0, source=CHOSEN)]
    for k, c in enumerate(CORNER_TAGS):
        out.append(SensorChannel(f"spin_torque_{c}", "N.m", f"drive + brake torque on wheel joint {wheel(k)} "
                                 "about its axle (> 0 forward)", "driveline and brake command", "wheel axle (left)",
                                 accuracy=0.0, bandwidth=None, resolution=0.0, range=None, rate=625.0,
                                 joint=wheel(k), source=CHOSEN + ": a known command, logged exactly"))
    return out


@dataclass(frozen=True)
class SensorSuite:
    """The channels of the paper's instrumented car, in logging order (see the module doc)."""

    channels: tuple[SensorChannel, ...]
    rate: float = ACQUISITION_RATE
    _by_name: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        names = [c.name for c in self.channels]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise SensorError(f"sensor suite: channel names must be unique; repeated: {sorted(dup)}")
        object.__setattr__(self, "_by_name", {c.name: c for c in self.channels})

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.channels)

    @property
    def units(self) -> dict[str, str]:
        return {c.name: c.unit for c in self.channels}

    def __getitem__(self, name: str) -> SensorChannel:
        try:
            return self._by_name[name]
        except KeyError:
            raise SensorError(f"no channel {name!r} in the sensor suite; channels: {', '.join(self.names)}") from None

    def __iter__(self):
        return iter(self.channels)

    def __len__(self) -> int:
        return len(self.channels)

    def replace(self, name: str, **changes) -> SensorSuite:
        """A suite with one channel's fields changed (e.g. accuracy=0.0)."""
        self[name]
        return SensorSuite(tuple(replace(c, **changes) if c.name == name else c for c in self.channels), self.rate)

    def table(self) -> list[dict]:
        """One dict per channel (JSON-ready): name, unit, quantity, mounting, axes, accuracy, ..."""
        return [c.as_dict() for c in self.channels]

    def measure(
        self,
        truth: Mapping[str, np.ndarray],
        rng: np.random.Generator | int | None = None,
        noise: bool = True,
        ideal: bool = False,
    ) -> dict[str, np.ndarray]:
        """Logged channels from the true values on the 625 Hz clock, (N,) each, in channel units.

        truth: channel name -> true value (N,) in the channel's unit at t = k / rate
        (`ideal_channels` computes them); every channel of the suite must be given.
        rng: numpy Generator or seed. noise: add noise and bias; ideal: return the truth.
        """
        missing = [c.name for c in self.channels if c.name not in truth]
        if missing:
            raise SensorError(f"measure: no true values for {', '.join(missing)}")
        rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        out = {}
        for c in self.channels:  # the random draws always happen, so a channel's noise does not depend on the switches
            x = np.asarray(truth[c.name], dtype=float)
            e = rng.standard_normal(x.shape) * c.accuracy + rng.standard_normal() * c.bias
            out[c.name] = x.copy() if ideal else corrupt(x, c, self.rate, e if noise else None)
        return out


@functools.lru_cache(maxsize=64)
def _butter2(bandwidth: float, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of scipy.signal.butter(2, bandwidth / (rate / 2)) in closed form: the analogue 2nd-order
    Butterworth through the bilinear transform, pre-warped at the bandwidth (no scipy.signal import:
    it costs up to a second per process)."""
    k = math.tan(math.pi * bandwidth / rate)
    n = 1.0 / (1.0 + math.sqrt(2.0) * k + k * k)
    b0 = k * k * n
    a = [1.0, 2.0 * (k * k - 1.0) * n, (1.0 - math.sqrt(2.0) * k + k * k) * n]
    return np.array([b0, 2.0 * b0, b0]), np.array(a)


@functools.lru_cache(maxsize=64)
def _impulse_response(bandwidth: float, rate: float) -> np.ndarray:
    """The filter's impulse response, closed form from its complex pole pair p, conj(p), cut where it has
    decayed below 1e-17 (so convolving with it is the recursion to round-off)."""
    b, a = _butter2(bandwidth, rate)
    p = complex(np.roots(a)[0])
    n = np.arange(math.ceil(math.log(1e-17) / math.log(abs(p))) + 3)
    g = (p ** (n + 1)).imag / p.imag  # impulse response of 1 / a(z)
    h = b[0] * g
    h[1:] += b[1] * g[:-1]
    h[2:] += b[2] * g[:-2]
    h.setflags(write=False)
    return h


def _fast_length(n: int) -> int:
    """The smallest 2^i 3^j 5^k >= n (an FFT size numpy transforms fast)."""
    best = 1 << max(n - 1, 0).bit_length()
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            m = p35
            while m < n:
                m *= 2
            best = min(best, m)
            p35 *= 3
        p5 *= 5
    return best


@functools.lru_cache(maxsize=64)
def _spectrum(bandwidth: float, rate: float, nfft: int) -> np.ndarray:
    return np.fft.rfft(_impulse_response(bandwidth, rate), nfft)


def lowpass(x: np.ndarray, bandwidth: float | None, rate: float) -> np.ndarray:
    """Causal 2nd-order Butterworth low-pass at `bandwidth` Hz, started in steady state at x[0].

    The convolution with the impulse response by FFT, the input extended before its start by x[0]:
    scipy's lfilter(b, a, x, zi=lfilter_zi(b, a) * x[0]) to round-off, without per-sample recursion."""
    if bandwidth is None or bandwidth >= 0.45 * rate or x.size < 2:
        return x
    h = _impulse_response(float(bandwidth), float(rate))
    m = h.size
    nfft = _fast_length(x.size + m)  # circular wrap-around only reaches the m - 1 leading samples dropped
    xp = np.concatenate([np.full(m, x[0]), x])
    y = np.fft.irfft(np.fft.rfft(xp, nfft) * _spectrum(float(bandwidth), float(rate), nfft), nfft)
    return y[m:m + x.size]


@functools.lru_cache(maxsize=64)
def _hold_index(n: int, sensor_rate: float, rate: float) -> np.ndarray:
    t = np.arange(n) / rate
    k = np.floor(t * sensor_rate + 1e-9)  # the sensor sample last taken at or before t
    idx = np.minimum(np.ceil(k / sensor_rate * rate - 1e-9).astype(int), n - 1)
    idx.setflags(write=False)
    return idx


def sample_and_hold(x: np.ndarray, sensor_rate: float, rate: float) -> np.ndarray:
    """Sample x (on the clock `rate`) at the sensor's own rate and hold each value until the next."""
    if sensor_rate >= rate:
        return x
    return x[_hold_index(x.size, float(sensor_rate), float(rate))]


def corrupt(x: np.ndarray, c: SensorChannel, rate: float, error: np.ndarray | None) -> np.ndarray:
    """One channel through the error chain of the module doc; error: noise + bias per sample, or None."""
    y = sample_and_hold(lowpass(x, c.bandwidth, rate), c.rate, rate)
    if error is not None:
        y = y + sample_and_hold(error, c.rate, rate)
    if c.resolution > 0:
        y = np.round(y / c.resolution) * c.resolution
    if c.range is not None:
        y = np.clip(y, *c.range)
    return y


def paper_suite(geometry: CarGeometry | None = None) -> SensorSuite:
    """The paper's instrumented car (Table 1; mounting points from `geometry`, default the demo vehicle's)."""
    g = demo_geometry() if geometry is None else geometry
    return SensorSuite(tuple(_imu(g) + _correvit(g) + _corners(g) + _driver()))


def fitted_suite(geometry: CarGeometry | None = None, cameras: bool = True, lasers: bool = True,
                 correvit: bool = True) -> SensorSuite:
    """The paper's suite with fewer sensors, as many test cars are equipped.

    cameras=False: no video cameras at the corners; the damper clearances come from linear potentiometers on
    the dampers (`clearance_*`: 0.2 mm, 100 Hz, a 0.2 mm zero offset) and the steering and camber joints from
    the kinematic tables at the measured clearance and steering-wheel angle. lasers=False: no height lasers;
    the chassis height and the tire deflections then come from the wheel loads through the tires' stiffness,
    which has to be known (a tire bench) and cannot be identified. correvit=False: no Correvit; the horizontal
    velocity over ground comes from a GNSS/INS (`gnss_vx`, `gnss_vy` at `gnss_point`)."""
    g = demo_geometry() if geometry is None else geometry
    out = [] if correvit else _gnss(g)
    for c in paper_suite(g):
        if not correvit and c.name.startswith("correvit_"):
            continue
        prefix = c.name.split("_")[0]
        if not cameras and prefix in ("steer", "camber"):
            continue
        if not lasers and c.name.startswith("laser_height_"):
            continue
        if not cameras and prefix == "clearance":
            c = replace(c, sensor="damper potentiometer", accuracy=0.2, bandwidth=100.0, resolution=0.01, bias=0.2,
                        source=CHOSEN + ": a linear potentiometer on the damper")
        out.append(c)
    return SensorSuite(tuple(out))


def mounted(geometry: CarGeometry, suite: SensorSuite) -> CarGeometry:
    """The geometry with the suite's own mounting points for the Correvit, the GNSS/INS and the height lasers
    (a suite built for another geometry, or with points of its own, is measured where it is)."""
    points: dict = {}
    if "correvit_vx" in suite.names:
        points["correvit_position"] = suite["correvit_vx"].mounting
    if "gnss_vx" in suite.names:
        points["gnss_position"] = suite["gnss_vx"].mounting
    if all(f"laser_height_{t}" in suite.names for t in CORNER_TAGS):
        points["laser_positions"] = tuple(suite[f"laser_height_{t}"].mounting for t in CORNER_TAGS)
    return replace(geometry, **points)


def channel_names(truth: bool = False) -> tuple[str, ...]:
    """All logged channel names (without `time`), with the truth channels when asked."""
    names = paper_suite().names
    return names + truth_channel_names() if truth else names


def truth_channel_names(n: int = 42) -> tuple[str, ...]:
    names = [f"true_{v}{j}" for v in ("q", "qd", "qdd") for j in range(1, n + 1)]
    names += [f"true_wft_{c}_{comp}" for c in CORNER_TAGS for comp in WFT_COMPONENTS]
    return tuple(names)


def truth_channel_units(n: int = 42, prismatic: Sequence[int] = ()) -> dict[str, str]:
    """Units of the truth channels: m, m/s, m/s^2 for prismatic joints, rad... otherwise; N, N.m."""
    pris = set(prismatic)
    out = {}
    for v, suffix in (("q", ""), ("qd", "/s"), ("qdd", "/s^2")):
        for j in range(1, n + 1):
            out[f"true_{v}{j}"] = ("m" if j in pris else "rad") + suffix
    for c in CORNER_TAGS:
        for comp in WFT_COMPONENTS:
            out[f"true_wft_{c}_{comp}"] = "N" if comp[0] == "F" else "N.m"
    return out


# ----- the true value of every channel from the car's motion -------------------------------------

def ideal_channels(
    model,
    q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    wheel_wrenches: np.ndarray,
    steering_wheel: np.ndarray,
    spin_torques: np.ndarray,
    geometry: CarGeometry | None = None,
) -> dict[str, np.ndarray]:
    """The noise-free value of every channel of `paper_suite(geometry)`, (N,) each, channel units.

    model: dynid Model of the car template; q, qd, qdd (N, 42); wheel_wrenches (N, 4, 6) as in
    car_identification (wheel centre, non-spinning wheel frame, N and N.m); steering_wheel (N,)
    rad; spin_torques (N, 4) N.m. This is the definition the estimator inverts.
    """
    g = demo_geometry() if geometry is None else geometry
    q, qd, qdd = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, qd, qdd))
    N = q.shape[0]
    deg = np.degrees
    out: dict[str, np.ndarray] = {}

    st = forward_kinematics(model.tree, joint_array(q, model.tree, "q")[0], frames=[6])  # frame 6 only
    R6 = np.stack([np.asarray(c).T for c in st.Rc[6]], axis=2)  # (N, 3, 3), columns = axes of frame 6
    O6 = np.asarray(st.P[6]).T  # (N, 3)
    A = np.asarray(g.imu_axes, dtype=float)  # rows: the unit's axes in frame 6
    imu = np.asarray(g.imu_position, dtype=float)
    J = model.jacobian(q, 6, point=imu)  # ground axes, rotated to frame 6 below (6 x N, not 6 x 42 x N)
    tw0 = np.concatenate([np.einsum("nij,nj->ni", J, qd), np.einsum("nij,nj->ni", J[:, :3], qdd)], axis=1)
    tw6 = np.einsum("nji,nkj->nki", R6, tw0.reshape(N, 3, 3))  # each 3-vector into frame 6
    tw = tw6[:, :2].reshape(N, 6)
    acc = tw6[:, 2] + model.jdot_qdot(q, qd, 6, point=imu, expressed_in=6)[:, :3]
    w_iso = tw[:, 3:] @ A.T
    out["imu_roll_rate"], out["imu_pitch_rate"], out["imu_yaw_rate"] = (deg(w_iso[:, i]) for i in range(3))
    grav = np.asarray(model.tree.gravity, dtype=float)
    g6 = np.einsum("nji,j->ni", R6, grav)  # gravity in frame 6
    f_iso = (acc - g6) @ A.T
    out["imu_ax"], out["imu_ay"], out["imu_az"] = f_iso[:, 0], f_iso[:, 1], f_iso[:, 2]
    Rv = R6 @ A.T  # columns: the unit's axes in the ground frame
    out["imu_pitch"] = deg(-np.arcsin(np.clip(Rv[:, 2, 0], -1.0, 1.0)))
    out["imu_roll"] = deg(np.arctan2(Rv[:, 2, 1], Rv[:, 2, 2]))
    p = np.asarray(correvit_point(g))
    v_iso = (tw[:, :3] + np.cross(tw[:, 3:], p - imu)) @ ISO_AXES.T  # the chassis' twist moved to the point
    out["correvit_vx"], out["correvit_vy"] = v_iso[:, 0] * 3.6, v_iso[:, 1]
    v_iso = (tw[:, :3] + np.cross(tw[:, 3:], np.asarray(gnss_point(g)) - imu)) @ ISO_AXES.T
    out["gnss_vx"], out["gnss_vy"] = v_iso[:, 0], v_iso[:, 1]
    for k, c in enumerate(CORNER_TAGS):
        steer, camber = tabulated(k)[:2]  # frame j in column j - 1
        P0 = np.einsum("nij,j->ni", R6, np.asarray(laser_point(g, k))) + O6
        out[f"laser_height_{c}"] = 1e3 * P0[:, 2] / R6[:, 2, 0]
        out[f"clearance_{c}"] = 1e3 * q[:, damper(k) - 1]
        out[f"steer_{c}"] = deg(q[:, steer - 1])
        out[f"camber_{c}"] = deg(q[:, camber - 1])
        out[f"wheel_speed_{c}"] = qd[:, wheel(k) - 1] / (2 * np.pi)
        for i, comp in enumerate(WFT_COMPONENTS):
            out[f"wft_{c}_{comp}"] = np.array(wheel_wrenches[:, k, i], dtype=float)
        out[f"spin_torque_{c}"] = np.array(spin_torques[:, k], dtype=float)
    out["steering_wheel"] = deg(np.broadcast_to(np.asarray(steering_wheel, dtype=float), (N,))).copy()
    return out


__all__ = ["ACQUISITION_RATE", "CORNER_TAGS", "ISO_AXES", "SAMPLE_TIME", "WFT_COMPONENTS", "SensorChannel",
           "SensorError", "SensorSuite", "channel_names", "correvit_point", "corrupt", "fitted_suite", "gnss_point",
           "ideal_channels", "laser_point", "lowpass", "mounted", "paper_suite", "sample_and_hold",
           "truth_channel_names", "truth_channel_units"]
