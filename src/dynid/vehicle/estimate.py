"""Joint coordinates of the car from its sensors (the paper's §6.2): q, qd, qdd of all 42 frames.

Input: the channels of `sensors.paper_suite` on one clock, converted to SI (rad, rad/s, m,
m/s, m/s², N, N·m). Each joint is taken from its best sensor, filtered by the same
zero-phase Butterworth, and differentiated by central differences (integrated by the
trapezoidal rule where the sensor gives a rate):

  yaw, pitch, roll (q4, q5, q6)   Euler rates from the gyros; angles = integrated rates,
                                  pulled to the absolute inclinometer angles below a
                                  crossover frequency (complementary filter, zero phase)
  x, y (q1, q2)                   velocity of O6 from the Correvit, accelerations from the IMU
  z (q3)                          height of O6 from the four lasers, acceleration from the IMU
  dampers, steering, camber       the camera's channels
  caster, kingpin                 the template's kinematic tables (chain rule)
  wheel spin                      the wheel speeds, integrated
  tire deflection                 geometry: the tire frame's origin lies on the ground
  half track, half wheelbase      constant (0: their value is in the MDH r column)

The wheel wrenches and spin torques pass through the same low-pass, so that both sides
of Y = W X carry the same band.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from ..dynamics import Model
from ..kinematics.forward import forward_kinematics, joint_array, joint_trig, needed_frames
from ..model import ModelError
from ..model.workspace import PerObject
from ..signals import border_samples, derivative, integrate, lowpass, lowpass_columns
from ..signals.filters import undo_lowpass_phase, undo_lowpass_phase_rows
from .dynamics import ChannelDynamics, table1_dynamics
from .geometry import CarGeometry, demo_geometry
from .sensors import (
    CORNER_TAGS,
    ISO_AXES,
    WFT_COMPONENTS,
    SensorSuite,
    correvit_point,
    gnss_point,
    laser_point,
    paper_suite,
)
from .tables import KinematicTables, default_tables
from .template import CONSTANT_JOINTS, DAMPERS, FRAMES, TIRES, WHEELS, tabulated

Array = np.ndarray
# frame 0 coordinates of the ISO earth axes (X forward = y0, Y left = -x0, Z up = z0), as columns
EARTH = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class CarConditioning:
    """cutoff (Hz) and order of the zero-phase Butterworth on every signal; attitude_crossover (Hz):
    below it the inclinometers set roll and pitch, above it the integrated gyros; border (s):
    trimmed at each end (None: the filter's transient); compensate_delays: undo each channel's declared
    dynamics (`estimate_joints`' dynamics, by default the Table-1 sensors'); false: none."""

    cutoff: float = 4.0
    order: int = 4
    attitude_crossover: float = 0.2
    border: float | None = None
    compensate_delays: bool = True


def advance(x: Array, delay: float, fs: float) -> Array:
    """x(t + delay) on the same clock (linear interpolation of a band-limited signal; ends held)."""
    shift = delay * fs
    k = int(np.floor(shift))
    f = shift - k
    n = len(x)
    # y[i] = lo + f (hi - lo), lo = x[clip(i + k)], hi = x[clip(i + k + 1)]: both inside for a <= i < b,
    # and the held end values outside
    a = min(n, max(0, -k))
    b = max(a, min(n, n - 1 - k))
    out = np.empty(n)
    out[:a], out[b:] = x[0], x[-1]
    seg = out[a:b]
    if f:
        np.subtract(x[a + k + 1 : b + k + 1], x[a + k : b + k], out=seg)
        seg *= f
        seg += x[a + k : b + k]
    else:
        seg[:] = x[a + k : b + k]
    return out


def compensate(x: Array, dynamics: ChannelDynamics, fs: float, extra: float = 0.0) -> Array:
    """The channel x as its sensor saw it, as far as a linear filter undoes the declared dynamics: the band
    limit's phase undone exactly (its digital Butterworth run backwards in time, from the last sample's steady
    state: zero phase overall, gain |H|^2, within 0.2 % of 1 below a fifth of the bandwidth), then the hold's
    mean age, the pure delay and `extra` (s) advanced (`advance`). A shift by the band limit's zero-frequency
    group delay alone leaves the phase its group delay gains with frequency: +3.8 % of it at a fifth of the
    bandwidth, 0.9 ms of a 10 Hz inertial unit's 22.5 ms at 2 Hz, which biased the yaw inertia by 0.5 %."""
    shift = dynamics.lag(fs) + extra
    band = dynamics.bandwidth
    if band is not None and band < 0.45 * fs:  # a digital Butterworth of that band exists at this rate
        x = undo_lowpass_phase(x, fs, band, dynamics.order)
        shift -= dynamics.band_delay()
    return advance(x, shift, fs) if shift else np.asarray(x, dtype=float)


@dataclass(frozen=True)
class CarTrajectory:
    """Estimated joint trajectories and measured loads on one clock: t (N,) s, q, qd, qdd (N, 42),
    wheel_wrenches (N, 4, 6) (car_identification's convention), spin_torques (N, 4) N·m or None,
    steering_wheel (N,) rad."""

    t: Array
    q: Array
    qd: Array
    qdd: Array
    wheel_wrenches: Array
    spin_torques: Array | None
    steering_wheel: Array

    def trimmed(self, n: int) -> CarTrajectory:
        sl = slice(n, len(self.t) - n)
        return CarTrajectory(self.t[sl], self.q[sl], self.qd[sl], self.qdd[sl], self.wheel_wrenches[sl],
                             None if self.spin_torques is None else self.spin_torques[sl], self.steering_wheel[sl])


def required_channels(spin: bool = False, suite: SensorSuite | None = None) -> list[str]:
    """The channels the estimator reads: the suite's (default: the paper's), the spin torques only if asked."""
    names = ["imu_roll_rate", "imu_pitch_rate", "imu_yaw_rate", "imu_ax", "imu_ay", "imu_az", "imu_roll",
             "imu_pitch", "correvit_vx", "correvit_vy", "gnss_vx", "gnss_vy", "steering_wheel"]
    for c in CORNER_TAGS:
        names += [f"laser_height_{c}", f"clearance_{c}", f"steer_{c}", f"camber_{c}", f"wheel_speed_{c}"]
        names += [f"wft_{c}_{k}" for k in WFT_COMPONENTS]
    fitted = set((suite or paper_suite()).names)
    return [n for n in names if n in fitted] + ([f"spin_torque_{c}" for c in CORNER_TAGS] if spin else [])


def _zyx(yaw: Array, pitch: Array, roll: Array) -> Array:
    """Rot(z, yaw) Rot(y, pitch) Rot(x, roll), (N, 3, 3), written out (one array, no products of stacks)."""
    cz, sz, cy, sy, cx, sx = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    R = np.empty((len(cz), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 0, 2] = cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx
    R[:, 1, 0], R[:, 1, 1], R[:, 1, 2] = sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx
    R[:, 2, 0], R[:, 2, 1], R[:, 2, 2] = -sy, cy * sx, cy * cx
    return R


def chassis_rotation(yaw: Array, pitch: Array, roll: Array) -> Array:
    """0R6 (N, 3, 3) from ISO yaw, pitch (nose down > 0), roll: the template's q4 = yaw, q5 = -pitch, q6 = roll."""
    yaw, pitch, roll = np.broadcast_arrays(*(np.atleast_1d(np.asarray(a, dtype=float)) for a in (yaw, pitch, roll)))
    # EARTH and ISO_AXES are signed permutations: their product with R is a signed gather of R's entries
    return _zyx(yaw, pitch, roll)[:, _ROWS, _COLS] * _SIGNS


_ROWS = np.abs(EARTH).argmax(axis=1)[:, None]  # EARTH[i] picks row _ROWS[i] of R
_COLS = np.abs(ISO_AXES).argmax(axis=0)[None, :]  # ISO_AXES[:, j] picks column _COLS[j]
_SIGNS = EARTH[np.arange(3)[:, None], _ROWS] * ISO_AXES[_COLS, np.arange(3)[None, :]]


# ISO_AXES (a signed permutation): column j of X @ ISO_AXES is sign X[:, k], (k, sign) = _ISO_GATHER[j]; row i of
# ISO_AXES (the vehicle axis i in frame 6) is sign e_k, (k, sign) = _ISO_ROWS[i], so column i of X @ ISO_AXES.T is
# sign X[:, k]
_ISO_GATHER = tuple((int(np.flatnonzero(ISO_AXES[:, j])[0]), float(ISO_AXES[:, j].sum())) for j in range(3))
_ISO_ROWS = tuple((int(np.flatnonzero(ISO_AXES[i])[0]), float(ISO_AXES[i].sum())) for i in range(3))
_GATHER = (np.array([k for k, _ in _ISO_GATHER]), np.array([s for _, s in _ISO_GATHER]))  # `_velocity_compiled`'s
assert sorted(np.abs(ISO_AXES).sum(axis=0)) == [1.0] * 3 and sorted(np.abs(ISO_AXES).sum(axis=1)) == [1.0] * 3


_CAMERA_TABLES = (("steer", "steering"), ("camber", "camber"))


def _saturated_cameras(ch: Mapping[str, Array], suite: SensorSuite) -> dict[str, Array]:
    """The camera channels that reach a limit of their range somewhere: name -> (N,) mask. The values are
    in SI here and the ranges in the channel's unit; a saturated sample sits exactly on the limit (the logger
    clips after quantising), so the test is made on the limits converted to SI, within a hundredth of the
    channel's resolution."""
    out = {}
    for t in CORNER_TAGS:
        for prefix, _ in _CAMERA_TABLES:
            name = f"{prefix}_{t}"
            c = suite[name] if name in suite.names else None
            if c is None or c.range is None:
                continue
            scale = np.pi / 180.0 if c.unit == "deg" else 1.0
            tol = 0.01 * c.resolution
            x = ch[name]
            if not len(x):
                continue
            # the test's value rises with x (each rounding is monotone): x's least and largest reach a limit if any
            # sample does (a camera saturates on spirals alone: the whole channel's test is then made)
            ends = np.array([x.min(), x.max()])
            if not c.saturated(ends / scale + np.where(ends > 0, tol, -tol)).any():
                continue
            mask = c.saturated(x / scale + np.where(x > 0, tol, -tol))
            if mask.any():
                out[name] = mask
    return out


def _from_tables(ch: dict[str, Array], clipped: Mapping[str, Array], tables: KinematicTables,
                 delays: Mapping[str, float], fs: float) -> None:
    """Saturated camera samples replaced, in place, by the kinematic tables' value at the measured damper
    clearance and steering-wheel angle: a spiral steers the front wheels past the cameras' 5° range, and a
    clipped steering angle biases every front-corner equation. The mask is widened by the channel's delay
    (delays, s: what compensating it moved) so that no sample moved off the limit is kept."""
    for name, mask in clipped.items():
        prefix, tag = name.split("_")
        k = CORNER_TAGS.index(tag)
        if delays.get(name, 0.0):
            reach = int(np.ceil(abs(delays[name]) * fs)) + 1
            mask = np.convolve(mask, np.ones(2 * reach + 1), mode="same") > 0
        table = tables.table(k, dict(_CAMERA_TABLES)[prefix])
        x = ch[name].copy()
        x[mask] = table(ch[f"clearance_{tag}"][mask], ch["steering_wheel"][mask])
        ch[name] = x


def _declared(c: CarConditioning, suite: SensorSuite, dynamics: Mapping[str, ChannelDynamics] | None
              ) -> Mapping[str, ChannelDynamics]:
    """The dynamics to undo: none when the conditioning says so, else the given or the suite's Table-1 ones."""
    if not c.compensate_delays:
        return {}
    return table1_dynamics(suite).channels if dynamics is None else dynamics


def compensated_channels(
    channels: Mapping[str, Array],
    fs: float,
    conditioning: CarConditioning | None = None,
    suite: SensorSuite | None = None,
    dynamics: Mapping[str, ChannelDynamics] | None = None,
    lags: Mapping[str, float] | None = None,
) -> dict[str, Array]:
    """The channels (SI) with their declared dynamics undone (`compensate`) and `lags` advanced, as
    `estimate_joints` takes them first (its arguments' meaning)."""
    dynamics = _declared(conditioning or CarConditioning(), suite or paper_suite(), dynamics)
    lags = lags or {}
    none = ChannelDynamics()
    out = {k: np.asarray(v, dtype=float) for k, v in channels.items()}
    # `compensate` of each channel, the band limits' phase undone for all channels in one pass (each with its own
    # filter; one pass per number of sections)
    banded: dict[tuple, list[str]] = {}
    for k, x in out.items():
        if k not in dynamics and not lags.get(k):
            continue
        d = dynamics.get(k, none)
        if d.bandwidth is not None and d.bandwidth < 0.45 * fs and x.ndim == 1 and len(x):
            banded.setdefault(((d.order + 1) // 2, len(x)), []).append(k)
        else:
            out[k] = compensate(x, d, fs, lags.get(k, 0.0))
    for names in banded.values():
        # stacked as rows (channels first, as the kernel reads them): writing each channel into a column of a C-order
        # (N, C) array touches a cache line per sample per channel
        undone = undo_lowpass_phase_rows(np.stack([out[k] for k in names]), fs,
                                         [(dynamics[k].bandwidth, dynamics[k].order) for k in names])
        for i, k in enumerate(names):
            shift = dynamics[k].lag(fs) + lags.get(k, 0.0)
            shift -= dynamics[k].band_delay()
            out[k] = advance(undone[i], shift, fs) if shift else undone[i]
    return out


def estimate_joints(
    channels: Mapping[str, Array],
    fs: float,
    model: Model,
    geometry: CarGeometry | None = None,
    tables: KinematicTables | None = None,
    conditioning: CarConditioning | None = None,
    suite: SensorSuite | None = None,
    dynamics: Mapping[str, ChannelDynamics] | None = None,
    lags: Mapping[str, float] | None = None,
    compensated: Mapping[str, Array] | None = None,
) -> CarTrajectory:
    """q, qd, qdd of the 42 joints and the filtered loads from the sensor channels (SI), trimmed of the borders.

    suite: the sensors' definitions (default: the paper's suite on this geometry). dynamics: channel -> what the
    logger did to it (`Vehicle.logger.channels`; default: the suite's Table-1 sensors), undone (`compensate`)
    when `conditioning.compensate_delays`. lags: channel -> s, how much later than that the channel is taken
    (advanced by it more, whatever compensate_delays says: the delay estimate's perturbations). compensated:
    the channels already undone (`compensated_channels` of these channels, dynamics and lags), not undone again:
    a sensor offset's pass moves one channel of them (the undoing is affine, of unit gain at 0 Hz)."""
    return joints_pass(channels, fs, model, geometry, tables, conditioning, suite, dynamics, lags, compensated).traj


# the channels a zero offset of which moves the stages after the corners' alone (`JointsPass.moved`), by stage
_ATTITUDE = ("imu_roll_rate", "imu_pitch_rate", "imu_yaw_rate", "imu_roll", "imu_pitch")
_ACCELERATION = ("imu_ax", "imu_ay", "imu_az")
_VELOCITY = ("correvit_vx", "correvit_vy", "gnss_vx", "gnss_vy")
_INCLINOMETERS = ("imu_roll", "imu_pitch")  # the low-passed matrix's last two columns


@dataclass(frozen=True)
class _Context:
    fs: float
    model: Model
    geometry: CarGeometry
    conditioning: CarConditioning
    suite: SensorSuite
    lasers: bool
    border: int


class _Moved:
    """A moved pass's q, qd or qdd: the whole pass's (N, 42) array with the columns the moved stages write kept
    apart. The stages index it as that array (whole columns: `a[:, j]`, `a[:, 3:6]`, `a[:, [..]]`; rows: `a[rows]`),
    so a pass keeps the few columns it changes, not the 42; `whole` and `every` make the arrays the trajectory
    holds, each entry the value the stages wrote or the whole pass's. rows (slice(lo, hi, k)): the columns are kept on
    those rows alone (`every`'s; a stage may write them there, `_derivative_at`), never read back (the accelerations:
    the rows' equations read them on those samples alone). A column is kept as written, a view of the stage's array,
    not copied (the staged passes of a 60 s segment's offsets write 42 MB: 6 ms of copies; the views hold their
    stages' arrays, +4 MB at the peak): the stages write new arrays or views of their own results, which nothing
    writes into afterwards."""

    def __init__(self, base: Array, rows: slice | None = None) -> None:
        self.base = base
        self.shape = base.shape
        self.rows = rows
        self.columns: dict[int, Array] = {}

    def _which(self, key) -> list[int]:
        rows, cols = key
        if rows != slice(None):
            raise TypeError("a moved pass's joints are indexed by whole columns")
        if isinstance(cols, slice):
            return list(range(self.shape[1]))[cols]
        return [int(cols)] if np.ndim(cols) == 0 else [int(j) for j in cols]

    def __setitem__(self, key, value) -> None:
        which = self._which(key)
        value = np.asarray(value, dtype=float)
        if self.rows is not None and len(value) == self.shape[0]:  # a whole column: its rows alone are kept
            value = value[self.rows]
        value = value.reshape(len(value), -1)
        for i, j in enumerate(which):
            self.columns[j] = value[:, i]

    def __getitem__(self, key):
        if self.rows is not None:
            raise TypeError("a moved pass's joints kept on the rows' samples alone are not read back")
        if not isinstance(key, tuple):  # rows, every column
            out = self.base[key]
            if np.may_share_memory(out, self.base):  # a slice's rows are a view: the whole pass's, not written into
                out = out.copy()
            for j, c in self.columns.items():
                out[:, j] = c[key]
            return out
        which = self._which(key)
        cols = [self.columns[j] if j in self.columns else self.base[:, j] for j in which]
        return cols[0] if np.ndim(key[1]) == 0 else np.stack(cols, axis=1)

    def whole(self) -> Array:
        """The (N, 42) array, column-major as the whole pass's."""
        if self.rows is not None:
            raise TypeError("a moved pass's joints kept on the rows' samples alone have no whole array")
        out = self.base.copy(order="F")
        for j, c in self.columns.items():
            out[:, j] = c
        return out

    def every(self, base: Array, lo: int, hi: int, k: int) -> Array:
        """Rows lo, lo + k, ... < hi, C order (`base`: the whole pass's rows there)."""
        if self.rows not in (None, slice(lo, hi, k)):
            raise ValueError(f"a moved pass's joints kept on rows {self.rows}, asked on {slice(lo, hi, k)}")
        out = base.copy()
        for j, c in self.columns.items():
            out[:, j] = c[lo:hi:k] if self.rows is None else c
        return out


def _derivative_at(x: Array, fs: float, rows: slice | None) -> Array:
    """`signals.derivative` of x (N, ...) along axis 0 on `rows` alone (slice(lo, hi, k), `_Moved.rows`: the central
    differences there, the same operations on the same numbers), or on every sample (None)."""
    if rows is None or rows.start < 1 or rows.stop > len(x) - 1:  # the ends' one-sided formulas: the whole derivative
        d = derivative(x, fs, check_finite=False)
        return d if rows is None else d[rows]
    lo, hi, k = rows.start, rows.stop, rows.step
    out = np.subtract(x[lo + 1:hi + 1:k], x[lo - 1:hi - 1:k])
    out /= 2.0 * (1.0 / fs)  # as signals.derivative
    return out


def _rows(a: Array | _Moved) -> slice | None:
    """The rows a moved pass's joints are kept on (`_Moved.rows`; None: every sample)."""
    return a.rows if isinstance(a, _Moved) else None


class _Trimmed:
    """A moved pass's full-rate joint rates, trimmed as its trajectory (`CoarseTrajectory.qd`): whole columns
    (`a[:, j]`, `a[:, [..]]`), made when asked."""

    def __init__(self, moved: _Moved, lo: int, hi: int) -> None:
        self.moved, self.lo, self.hi = moved, lo, hi

    def __getitem__(self, key):
        return self.moved[key][self.lo:self.hi]


@dataclass(frozen=True)
class CoarseTrajectory:
    """A moved pass's trajectory on every k-th sample (`traj`: what the rows' equations are computed on, as
    `pipeline.car`'s coarse samples) with its full-rate joint rates (`qd`: indexed by whole columns; the dry-friction
    columns are built from them at the full rate)."""

    traj: CarTrajectory
    qd: object


@dataclass(frozen=True)
class JointsPass:
    """One pass of `estimate_joints`: its trajectory, and the stages' results that the pass with one channel's
    zero moved by a constant reuses (`moved`): the channels as the joints were taken from them (undone,
    saturated camera samples replaced), the untrimmed joints, the low-passed corner and load columns, the
    chassis rotation and rates, the tire frames' heights and slopes, the lasers' heights of O6."""

    traj: CarTrajectory
    ctx: _Context
    ch: dict[str, Array]
    q: Array
    qd: Array
    qdd: Array
    filtered: Array
    steering: tuple[Array, Array, Array]
    has_spin: bool
    R6: Array
    w6: Array
    pz_zz: Array
    z_laser: Array

    def movable(self, channel: str) -> bool:
        """Whether `moved` takes a zero offset of `channel` (the others: the whole pass)."""
        load = channel.startswith("wft_") and channel.split("_")[-1] in WFT_COMPONENTS and channel in self.ch
        laser = channel.startswith("laser_height_") and channel.removeprefix("laser_height_") in CORNER_TAGS
        return channel in self.ch and (channel in (*_ATTITUDE, *_ACCELERATION, *_VELOCITY) or load or laser)

    def moved(self, channel: str, b: float, every: int = 1) -> CarTrajectory | CoarseTrajectory:
        """The trajectory of these channels with `channel`'s zero moved by b (SI), equal to the whole pass's
        (`estimate_joints` of the channels with b added) to round-off: each stage the channel reaches is run
        again on it, the others' results are reused. Its offset enters the stages as these channels plus b (the
        sensor dynamics' undoing is affine with unit gain at 0 Hz), a low-passed column as that column plus the
        low-passed constant (the filter is linear); an accelerometer's or a height laser's moves the joints
        linearly: b times the pass's response to a unit offset (`_linear`, `_UNIT`: all seven made in two low-pass
        calls, when first asked). every > 1: its samples every `every` (`CoarseTrajectory`, the
        same values), without the whole-rate arrays (the rows' equations read no others)."""
        if not self.movable(channel):
            raise ValueError(f"JointsPass.moved: a zero offset of {channel!r} needs the whole pass (estimate_joints)")
        x = self.ctx
        # the columns the stages write, apart: the rest is the whole pass's; when every > 1, the accelerations on the
        # rows' samples alone (the equations read no others; the rates whole: the dry friction's columns read them)
        rows = slice(None) if every == 1 else slice(x.border, self.q.shape[0] - x.border, every)
        q, qd, qdd = _Moved(self.q), _Moved(self.qd), _Moved(self.qdd, None if every == 1 else rows)
        if self._linear(channel):  # its effect is b times the pass's response to a unit offset (`_UNIT`)
            unit = _UNIT(self)
            if channel in _ACCELERATION:
                qdd[:, :3] = self.qdd[rows, :3] + b * unit.acceleration[_ACCELERATION.index(channel)][rows]
            else:
                i = CORNER_TAGS.index(channel.removeprefix("laser_height_"))
                j = TIRES[i] - 1
                q[:, 2], qd[:, 2] = self.q[:, 2] + b * unit.height[0], self.qd[:, 2] + b * unit.height[1]
                q[:, :2], qd[:, :2] = self.q[:, :2] + b * unit.position, self.qd[:, :2] + b * unit.velocity
                q[:, j], qd[:, j] = (a[:, j] + b * u[i] for a, u in zip((self.q, self.qd), unit.deflection[:2],
                                                                         strict=True))
                qdd[:, j] = self.qdd[rows, j] + b * unit.deflection[2][i][rows]
            return self._trajectory(q, qd, qdd, self.filtered, every)
        ch = {**self.ch, channel: self.ch[channel] + b}
        filtered, R6, w6, pz_zz, z_laser = self.filtered, self.R6, self.w6, self.pz_zz, self.z_laser
        attitude = channel in _ATTITUDE
        heights = attitude or channel.startswith("laser_height_")
        if channel.startswith("wft_"):  # a low-passed load column: the loads, and without lasers the heights
            filtered = filtered.copy()
            i = 17 + 6 * CORNER_TAGS.index(channel.split("_")[1]) + WFT_COMPONENTS.index(channel.split("_")[2])
            filtered[:, i] += _lowpass(np.full(len(filtered), b), x)
            heights = not x.lasers and channel.endswith("_Fz")
        kept = _UNMOVED(self) if attitude else None  # the channels an attitude offset leaves, as the stages read them
        if attitude:  # a gyro's offset leaves the inclinometers and their low-pass as the whole pass's
            gyro = channel not in _INCLINOMETERS
            R6, w6 = _attitude(ch, x, q, qd, qdd, self.filtered[:, -2:] if gyro else None,
                               *((kept.incl, kept.start) if gyro else ()))
            pz_zz = _tire_poses(x, q, kept)
        if heights or attitude or channel in _ACCELERATION:
            z = _heights_acceleration(ch, x, q, qd, qdd, filtered, R6, w6, pz_zz, heights,
                                      attitude or channel in _ACCELERATION, kept)
            z_laser = z if heights else z_laser
        if heights:  # the velocity (it reads the height's rate) and the deflections
            _velocity(ch, x, q, qd, R6, w6, (qdd, pz_zz, z_laser))
        elif channel in _VELOCITY:
            _velocity(ch, x, q, qd, R6, w6)
        return self._trajectory(q, qd, qdd, filtered, every)

    def _linear(self, channel: str) -> bool:
        """Whether a zero offset of `channel` moves the joints linearly, by b times the response to a unit offset
        (`_UNIT`): an accelerometer's (the rotation that carries it is the whole pass's) or a height laser's (its
        heights, the velocity's vertical part and the deflections are linear in them)."""
        return channel in _ACCELERATION or (self.ctx.lasers and channel.startswith("laser_height_"))

    def _trajectory(self, q: _Moved, qd: _Moved, qdd: _Moved, filtered: Array, every: int
                    ) -> CarTrajectory | CoarseTrajectory:
        """`moved`'s trajectory from its joints (the whole pass's with the moved stages' columns) and loads."""
        x = self.ctx
        if every == 1:
            return _trajectory(x, q.whole(), qd.whole(), qdd.whole(), filtered, self.has_spin, self.steering[0])
        N, lo = q.shape[0], x.border
        hi = N - lo
        coarse = _COARSE(self)
        if every not in coarse:
            coarse[every] = tuple(np.ascontiguousarray(a[lo:hi:every]) for a in (self.q, self.qd, self.qdd))
        qc, qdc, qddc = (m.every(c, lo, hi, every) for m, c in zip((q, qd, qdd), coarse[every], strict=True))
        whole = _trajectory_parts(x, filtered, self.has_spin, self.steering[0], N)
        coarse = CarTrajectory(whole[0][lo:hi:every], qc, qdc, qddc, whole[1][lo:hi:every],
                               None if whole[2] is None else whole[2][lo:hi:every], whole[3][lo:hi:every])
        return CoarseTrajectory(coarse, _Trimmed(qd, lo, hi))


@dataclass(frozen=True)
class _UnitResponses:
    """A pass's joints' change per unit zero offset (SI) of the channels that move them linearly
    (`JointsPass._linear`), full rate, untrimmed: acceleration[k] (N, 3): qdd[:, :3] per unit of the k-th
    accelerometer; for a laser: height (q, qd of column 2, (N,) each), position and velocity (q, qd[:, :2]) per unit
    of any laser (each laser's height weighs a quarter), deflection (q, qd, qdd) (4, N) per unit of its own laser
    (its tire's column)."""

    acceleration: Array
    height: tuple[Array, Array]
    position: Array
    velocity: Array
    deflection: tuple[Array, Array, Array]


def _unit_responses(p: JointsPass) -> _UnitResponses:
    """The pass's `_UnitResponses`: the moved stages' formulas differentiated where they are linear in the offset
    (the low-pass, differences and integrals are linear; the rotation and the tire poses are the pass's), all
    columns through two calls of the low-pass."""
    x, R6, pz_zz = p.ctx, p.R6, p.pz_zz
    N = R6.shape[0]
    A = np.asarray(x.geometry.imu_axes, dtype=float)
    # `_unit_acceleration`: f6 = [ax, ay, az] @ A, the acceleration R6 f6 (+ g): a unit of the k-th moves it by R6 A[k]
    cols = [np.einsum("nij,j->ni", R6, A[k]) for k in range(3)]
    if x.lasers:  # `_heights`: each laser's height of O6 moves by R6[:, 2, 0] per unit, their mean by a quarter of it
        cols += [R6[:, 2, 0] / 4.0, -R6[:, 2, 0, None] / pz_zz[:, 4:]]  # and `_deflection`'s own tire
    low = _lowpass_columns(cols, x)
    acceleration = low[:, :9].reshape(N, 3, 3).transpose(1, 0, 2)
    if not x.lasers:
        empty = np.zeros((0, N))
        return _UnitResponses(acceleration, (empty, empty), empty, empty, (empty, empty, empty))
    h = low[:, 9]
    hd = derivative(h, x.fs)
    # `_velocity`: s = (qd[:, 2] - v_known[:, 2]) / (R6 ez6)_z, v0 = v_known + s R6 ez6
    ez = R6 @ ISO_AXES[2]
    v = _lowpass((hd / ez[:, 2])[:, None] * ez[:, :2], x)
    d = np.ascontiguousarray(low[:, 10:14].T)
    dd = derivative(d, x.fs, axis=1)
    return _UnitResponses(acceleration, (h, hd), integrate(v, x.fs), v, (d, dd, derivative(dd, x.fs, axis=1)))


_UNIT: PerObject[JointsPass, _UnitResponses] = PerObject(_unit_responses)

# per pass, k -> its trajectory's q, qd, qdd on every k-th sample (C order): what `moved(..., every=k)` starts from,
# kept beside the frozen pass (model.workspace), not in it
_COARSE: PerObject[JointsPass, dict[int, tuple[Array, Array, Array]]] = PerObject(lambda _pass: {})


def joints_pass(
    channels: Mapping[str, Array],
    fs: float,
    model: Model,
    geometry: CarGeometry | None = None,
    tables: KinematicTables | None = None,
    conditioning: CarConditioning | None = None,
    suite: SensorSuite | None = None,
    dynamics: Mapping[str, ChannelDynamics] | None = None,
    lags: Mapping[str, float] | None = None,
    compensated: Mapping[str, Array] | None = None,
) -> JointsPass:
    """`estimate_joints` (its arguments), with what a pass with one channel moved reuses (`JointsPass`)."""
    g = geometry or demo_geometry()
    tables = tables or default_tables(g)
    c = conditioning or CarConditioning()
    suite = suite or paper_suite(g)
    missing = [n for n in required_channels(suite=suite) if n not in channels]
    if missing:
        raise ModelError(f"the car estimator needs the channels {missing}; got {sorted(channels)}")
    ch = {k: np.asarray(v, dtype=float) for k, v in channels.items()}
    _check_finite(ch, required_channels(suite=suite) + [n for n in ch if n.startswith("spin_torque_")])
    cameras = all(f"steer_{t}" in suite.names and f"camber_{t}" in suite.names for t in CORNER_TAGS)
    lasers = all(f"laser_height_{t}" in suite.names for t in CORNER_TAGS)
    clipped = _saturated_cameras(ch, suite)
    dynamics = _declared(c, suite, dynamics)
    lags = lags or {}
    none = ChannelDynamics()
    delays = {k: dynamics.get(k, none).lag(fs) + lags.get(k, 0.0) for k in ch}
    ch = dict(compensated) if compensated is not None else compensated_channels(ch, fs, c, suite, dynamics, lags)
    _from_tables(ch, clipped, tables, delays, fs)
    N = len(ch["imu_roll"])
    if model.n != FRAMES:
        raise ModelError(f"the car estimator needs the 42-frame car template; got {model.name!r} ({model.n} frames)")
    b = border_samples(fs, c.cutoff, c.order) if c.border is None else round(c.border * fs)
    x = _Context(fs, model, g, c, suite, lasers, b)

    # column-major: every joint is written as a column, and the equations read them as columns. Every column but the
    # constant joints' is written by the stages below: np.zeros would clear the 3 x 12.6 MB first (calloc of reused
    # heap, 0.8 ms each per 60 s segment)
    q, qd, qdd = (np.empty((N, FRAMES), order="F") for _ in range(3))
    for a in (q, qd, qdd):
        a[:, _CONSTANT_COLUMNS] = 0.0

    # --- corners: camera channels, wheel speeds and the steering wheel (17 columns), filtered in one matrix
    # with the loads (24 wheel-wrench components, the 4 spin torques when measured) and the two inclinometers
    # (the attitude's first low-pass, last): one call of the filter
    # without cameras the steering and camber columns are placeholders: the tables fill them below
    names = [f"{n}_{t}" for n in ("clearance", "steer", "camber", "wheel_speed") for t in CORNER_TAGS]
    names += ["steering_wheel"] + [f"wft_{t}_{k}" for t in CORNER_TAGS for k in WFT_COMPONENTS]
    has_spin = all(f"spin_torque_{t}" in ch for t in CORNER_TAGS)
    names += [f"spin_torque_{t}" for t in CORNER_TAGS] if has_spin else []
    names += list(_INCLINOMETERS)
    # stacked as rows, then one transposing copy (the filter's input is (N, C) C order): writing each channel
    # into a column of an (N, C) array touches one cache line per sample per channel (7 ms of a 60 s segment's 8).
    # `signals.lowpass_columns` (the channels written into the filter's work array by blocks) is faster alone
    # (12.4 -> 7.9-10.3 ms) but not in the pass: the stacked array freed here serves the later stages' arrays
    # from the heap (without it 3970 -> 6200-6700 page faults per pass, its median 53.5-55.3 -> 55.5-58.6 ms)
    zero = np.zeros(N)
    filtered = _lowpass(np.stack([ch.get(n, zero) for n in names]).T, x)
    R6, w6 = _attitude(ch, x, q, qd, qdd, filtered[:, -2:])
    h = _corners(filtered, fs, q, qd, qdd)
    q, qd, qdd = tables.joints(q, qd, qdd, steering_wheel=h, measured=("steering", "camber") if cameras else (),
                               copy=False)

    pz_zz = _tire_poses(x, q)
    z_laser = _heights_acceleration(ch, x, q, qd, qdd, filtered, R6, w6, pz_zz)
    _velocity(ch, x, q, qd, R6, w6, (qdd, pz_zz, z_laser))  # and the deflections
    if 2 * b >= N:
        raise ModelError(f"the test is too short for the filter: {N} samples, {2 * b} are spoiled at the borders "
                         f"({c.cutoff} Hz, order {c.order}); record longer or raise the cut-off")
    traj = _trajectory(x, q, qd, qdd, filtered, has_spin, h[0])
    return JointsPass(traj, x, ch, q, qd, qdd, filtered, h, has_spin, R6, w6, pz_zz, z_laser)


def _check_finite(ch: Mapping[str, Array], names: list[str]) -> None:
    """Each named channel finite, or an error naming the channel and its first bad sample. The stages' filters,
    differences and integrals then skip their own scans (they read every sample: ~2 ms of a 60 s segment's pass),
    whose errors could name only a column of a matrix computed from the channels."""
    for n in names:
        x = ch[n]
        with np.errstate(over="ignore", invalid="ignore"):  # inf - inf or an overflow: the scan decides
            if np.isfinite(np.sum(x)):  # a NaN or an infinity makes the sum non-finite
                continue
        bad = np.flatnonzero(~np.isfinite(x))
        if len(bad):
            raise ModelError(f"channel {n!r} has a non-finite value ({x[bad[0]]}) at sample {bad[0]} ({len(bad)} in "
                             "all): the joints' filters would spread it over the segment; fill or cut the gap first")


_CONSTANT_COLUMNS = [j - 1 for j in CONSTANT_JOINTS]  # half tracks and wheelbases: 0 (their value is in r)

# the corners' columns of the low-passed matrix (dampers, steering, camber: frame j in column j - 1), then the
# wheels' (speeds: integrated), then the steering wheel
_CORNER_COLUMNS = np.array([j - 1 for frames in (DAMPERS, [tabulated(k)[0] for k in range(4)],
                                                  [tabulated(k)[1] for k in range(4)], WHEELS) for j in frames])


def _corners(filtered: Array, fs: float, q: Array, qd: Array, qdd: Array) -> tuple[Array, Array, Array]:
    """The corners' joints into q, qd, qdd (column-major, (N, 42)) from the low-passed columns 0:17 of filtered:
    dampers, steering and camber angles and their central differences, the wheels' spin integrated from their
    speeds (trapezoidal), the steering wheel's (h, h', h'') returned. `signals.derivative` and `integrate`, in one
    compiled pass that writes each joint's column once (the NumPy passes' gathers and scatters cost more than
    the differences)."""
    if _corner_kernel is None:  # without numba: the same formulas through NumPy
        xs = filtered[:, :17]
        xd = derivative(xs, fs, check_finite=False)
        xdd = derivative(xd, fs, check_finite=False)
        cols = _CORNER_COLUMNS
        q[:, cols[:12]], qd[:, cols[:12]], qdd[:, cols[:12]] = xs[:, :12], xd[:, :12], xdd[:, :12]
        spin = integrate(xs[:, 12:16], fs, check_finite=False)
        q[:, cols[12:]], qd[:, cols[12:]], qdd[:, cols[12:]] = spin, xs[:, 12:16], xd[:, 12:16]
        return xs[:, 16], xd[:, 16], xdd[:, 16]
    h = np.empty((3, filtered.shape[0]))
    _corner_kernel(np.ascontiguousarray(filtered), float(fs), _CORNER_COLUMNS, q.T, qd.T, qdd.T, h)
    return h[0], h[1], h[2]


def _corners_compiled(x, fs, cols, q, qd, qdd, h):  # pragma: no cover - compiled
    """`_corners`' pass: x (N, C >= 17) C order, q, qd, qdd (42, N) (the column-major arrays' transposes), h (3, N).
    One function of explicit loops (no slice assignment, no second function): its compile is short."""
    n = x.shape[0]
    h2 = 2.0 * (1.0 / fs)  # as signals.derivative
    half = 0.5 / fs  # as signals.integrate
    # the 17 columns gathered row by row (x's rows contiguous): a column read alone touches a cache line per sample
    xs = np.empty((17, n))
    for i in range(n):
        for c in range(17):
            xs[c, i] = x[i, c]
    b = np.empty((3, n))  # a column, its first and second central differences
    for c in range(17):
        for i in range(n):
            b[0, i] = xs[c, i]
        for k in range(2):  # signals.derivative of b[k] into b[k + 1]: its formulas, in their order
            b[k + 1, 0] = (-3.0 * b[k, 0] + 4.0 * b[k, 1] - b[k, 2]) / h2
            for i in range(1, n - 1):
                b[k + 1, i] = (b[k, i + 1] - b[k, i - 1]) / h2
            b[k + 1, n - 1] = (3.0 * b[k, n - 1] - 4.0 * b[k, n - 2] + b[k, n - 3]) / h2
        if c < 12:  # the joint itself, its rate and acceleration
            j = cols[c]
            for i in range(n):
                q[j, i], qd[j, i], qdd[j, i] = b[0, i], b[1, i], b[2, i]
        elif c < 16:  # a wheel's speed: its spin angle integrated (signals.integrate), the speed, its derivative
            j = cols[c]
            acc = 0.0
            q[j, 0], qd[j, 0], qdd[j, 0] = 0.0, b[0, 0], b[1, 0]
            for i in range(1, n):
                acc += (b[0, i] + b[0, i - 1]) * half
                q[j, i], qd[j, i], qdd[j, i] = acc, b[0, i], b[1, i]
        else:
            for i in range(n):
                h[0, i], h[1, i], h[2, i] = b[0, i], b[1, i], b[2, i]


def _lowpass(x: Array, c: _Context) -> Array:
    return lowpass(x, c.fs, c.conditioning.cutoff, order=c.conditioning.order, axis=0, check_finite=False)


def _lowpass_columns(columns: list[Array], c: _Context) -> Array:
    """`_lowpass` of the columns side by side ((N,) or (N, k) each), (N, C'), C order: C' = 8 when they are 3 to 7
    (zero columns after them), else their number. The filter kernel runs its channels in vectors of 8: 6 or 7
    columns go one by one (2.1-2.7 ms per 60 s segment against 1.6 ms for 8); each column's result is its own
    (the same bits), and 1 or 2 columns wait on the recursion's latency either way."""
    n = sum(1 if a.ndim == 1 else a.shape[1] for a in columns)
    return lowpass_columns(columns, c.fs, c.conditioning.cutoff, c.conditioning.order, 8 if 3 <= n < 8 else n,
                           check_finite=False)


def _attitude(ch: Mapping[str, Array], x: _Context, q: Array, qd: Array, qdd: Array, angles: Array | None = None,
              incl: Array | None = None, start: tuple[Array, Array, Array] | None = None) -> tuple[Array, Array]:
    """Yaw, pitch, roll into q, qd, qdd (columns 3:6): Euler rates (ISO ZYX) from the gyros, angles fused with
    the inclinometers; returns 0R6 (N, 3, 3) and the unit's rates in frame 6 (N, 3). angles: the inclinometers
    (roll, pitch) low-passed (N, 2), when known (filtered with other columns: a call on 2 columns waits on the
    filter's latency); incl: the inclinometers stacked (N, 2), start: sin and cos of the angles' roll and tan of their
    pitch, when known (`_Unmoved`: a gyro's offset leaves them)."""
    fs, c = x.fs, x.conditioning
    A = np.asarray(x.geometry.imu_axes, dtype=float)  # rows: the unit's axes in frame 6
    w6 = np.stack([ch["imu_roll_rate"], ch["imu_pitch_rate"], ch["imu_yaw_rate"]], axis=1) @ A  # frame 6
    # about the vehicle x, y, z axes: w6 @ ISO_AXES.T as a signed gather (the product's numbers without its pass)
    p, qb, r = (w6[:, k] if sign > 0 else -w6[:, k] for k, sign in _ISO_ROWS)
    incl = _inclinometers(ch) if incl is None else incl
    phi, theta = (_lowpass(incl, x) if angles is None else angles).T
    for i in range(2):  # the rates depend on the angles: one refinement is plenty at car attitudes
        sp, cp, tt = (np.sin(phi), np.cos(phi), np.tan(theta)) if i or start is None else start
        pitch = theta  # the yaw rate's: the last pass's alone is used
        if _euler_kernel is None:  # without numba: the kernel's formulas through NumPy
            u = qb * sp + r * cp
            dphi = p + u * tt
            dtheta = qb * cp - r * sp
            integ = integrate(np.stack([dphi, dtheta], axis=1), fs, check_finite=False)
            rest = incl - integ
            if i:
                dpsi = u / np.cos(pitch)
                psi = integrate(dpsi, fs, check_finite=False)
        else:  # the rates, their integrals and the inclinometers' part left, in one compiled pass (the yaw's the last)
            n = len(sp) if i else 0
            u, dphi, dtheta, dpsi, psi = (np.empty(len(sp)) for _ in range(5))
            integ, rest = np.empty((len(sp), 2)), np.empty((len(sp), 2))
            _euler_kernel(p, qb, r, sp, cp, tt, incl, float(fs), np.cos(pitch) if i else np.empty(0), u, dphi, dtheta,
                          integ, rest, dpsi[:n], psi[:n])
        phi, theta = (integ + lowpass(rest, fs, c.attitude_crossover, c.order, check_finite=False)).T
    sign = (1.0, -1.0, 1.0)  # yaw, pitch (the template's is nose up), roll
    # the rates (filtered, differentiated) and the angles (filtered) through one low-pass of 6 columns
    low = _lowpass_columns([dpsi, dtheta, dphi, psi, theta, phi], x)
    rdf = _derivative_at(low[:, :3], fs, _rows(qdd))
    # signed, column by column into the column-major joints (a moved pass's too): the (N, 3) products of sign and the
    # columns' strided views, assigned to three columns each, cost 2.6 against 0.9 ms per 60 s segment
    for k in range(3):
        q[:, 3 + k], qd[:, 3 + k], qdd[:, 3 + k] = low[:, 3 + k] * sign[k], low[:, k] * sign[k], rdf[:, k] * sign[k]
    return _rotation(q[:, 3], -q[:, 4], q[:, 5]), w6


def _euler_compiled(p, qb, r, sp, cp, tt, incl, fs, cpitch, u, dphi, dtheta, integ, rest, dpsi, psi
                    ):  # pragma: no cover - compiled
    """`_attitude`'s refinement at each sample, its NumPy lines' operations in their order: the Euler rates (into u,
    dphi, dtheta (N,)) u = qb sp + r cp, dphi = p + u tt, dtheta = qb cp - r sp; dphi's and dtheta's running integrals
    (`signals.integrate`: the trapezoids' sums scaled by 0.5 / fs, summed in turn from 0, plus x0 = 0) into integ
    (N, 2), and incl - integ into rest (N, 2), the crossover low-pass's input. p, qb, r, sp, cp, tt (N,) (strided
    views too), incl (N, 2). cpitch (N,): the cos of the pitch the rates were made with, on the last refinement alone
    (else empty): then the yaw rate u / cpitch and its integral into dpsi, psi (N,) too. One function of explicit
    loops: its compile is short; the NumPy lines made a dozen passes over the samples."""
    n = u.shape[0]
    half = 0.5 / fs  # as signals.integrate
    yaw = cpitch.shape[0] > 0
    prev0 = prev1 = prev2 = acc0 = acc1 = acc2 = 0.0
    for i in range(n):
        ui = qb[i] * sp[i] + r[i] * cp[i]
        d0 = p[i] + ui * tt[i]
        d1 = qb[i] * cp[i] - r[i] * sp[i]
        u[i], dphi[i], dtheta[i] = ui, d0, d1
        if i:
            acc0 = acc0 + (d0 + prev0) * half
            acc1 = acc1 + (d1 + prev1) * half
        prev0, prev1 = d0, d1
        a0, a1 = acc0 + 0.0, acc1 + 0.0  # integrate's x0 added (it turns a -0.0 into 0.0)
        integ[i, 0], integ[i, 1] = a0, a1
        rest[i, 0], rest[i, 1] = incl[i, 0] - a0, incl[i, 1] - a1
        if yaw:
            d2 = ui / cpitch[i]
            if i:
                acc2 = acc2 + (d2 + prev2) * half
            prev2 = d2
            dpsi[i], psi[i] = d2, acc2 + 0.0


def _inclinometers(ch: Mapping[str, Array]) -> Array:
    """The inclinometers' roll and pitch (N, 2)."""
    return np.stack([ch["imu_roll"], ch["imu_pitch"]], axis=1)


def _specific_force(ch: Mapping[str, Array], x: _Context) -> Array:
    """The accelerometers' specific force in frame 6 (N, 3)."""
    return np.stack([ch["imu_ax"], ch["imu_ay"], ch["imu_az"]], axis=1) @ np.asarray(x.geometry.imu_axes, dtype=float)


def _laser_heights(ch: Mapping[str, Array]) -> Array:
    """The four height lasers (N, 4), in CORNER_TAGS' order."""
    return np.stack([ch[f"laser_height_{t}"] for t in CORNER_TAGS], axis=1)


@dataclass(frozen=True)
class _Unmoved:
    """A pass's inputs that an attitude offset (a gyro's or an inclinometer's) leaves as they are, as the stages read
    them, made once per pass when a moved attitude pass first asks: the inclinometers (`_inclinometers`) and the first
    refinement's sin, cos of the low-passed roll and tan of the low-passed pitch (a gyro's offset leaves them:
    `_attitude`'s start, 0.9 ms), the specific force in frame 6, the lasers' heights (None without lasers), the tire
    poses' joints (`_pose_joints`: the attitude's columns are the moved pass's own; 1.3 ms) and the cos and sin of
    their revolute joints but the attitude's (`joint_trig`: the corners'; 20 pairs, 1.2 ms a moved pass)."""

    incl: Array
    start: tuple[Array, Array, Array]
    f6: Array
    lasers: Array | None
    poses: Array
    pose_trig: dict[int, tuple[Array, Array]]


def _unmoved(p: JointsPass) -> _Unmoved:
    phi, theta = p.filtered[:, -2:].T  # as `_attitude` reads its angles
    poses = _pose_joints(p.ctx, p.q)[1]
    tree = p.ctx.model.tree
    corners = [j for j in np.flatnonzero(needed_frames(tree, TIRES)) if j not in _ATTITUDE_FRAMES]
    return _Unmoved(_inclinometers(p.ch), (np.sin(phi), np.cos(phi), np.tan(theta)), _specific_force(p.ch, p.ctx),
                    _laser_heights(p.ch) if p.ctx.lasers else None, poses, joint_trig(tree, poses, corners))


_ATTITUDE_FRAMES = (4, 5, 6)  # yaw, pitch, roll: the joints an attitude offset moves (`_attitude`'s columns 3:6)


_UNMOVED: PerObject[JointsPass, _Unmoved] = PerObject(_unmoved)


def _rotation(yaw: Array, pitch: Array, roll: Array) -> Array:
    """`chassis_rotation` (N, 3, 3) of (N,) angles, each entry written once where the gather would put it (`_zyx`'s
    products in its order, signed): no (N, 3, 3) stack gathered. Entries first in memory, as the gather leaves
    them: its users' einsum and matmul sum in an order that depends on the layout (the rows stay main's to the
    bit)."""
    cz, sz, cy, sy, cx, sx = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    Z = ((lambda: cz * cy, lambda: cz * sy * sx - sz * cx, lambda: cz * sy * cx + sz * sx),
         (lambda: sz * cy, lambda: sz * sy * sx + cz * cx, lambda: sz * sy * cx - cz * sx),
         (lambda: -sy, lambda: cy * sx, lambda: cy * cx))
    R = np.empty((3, 3, len(cz)))
    for a in range(3):
        for b in range(3):
            np.multiply(Z[_ROWS[a, 0]][_COLS[0, b]](), _SIGNS[a, b], out=R[a, b])
    return R.transpose(2, 0, 1)


def _tire_poses(x: _Context, q: Array, start: _Unmoved | None = None) -> Array:
    """Heights and z-axis slopes in frame 0 of the four tire frames (N, 8), from the attitude and the corners'
    joints (q's other columns, written by later stages, are taken as 0).

    The tire frame's origin lies on the ground plane z0 = 0 (prismatic along z_tire). Each corner takes the
    chassis height its own laser implies: attitude errors then act over the 0.35 m between laser and wheel, not
    over the wheelbase. q3 translates the whole car along z0, so one pose at q3 = 0 serves the four corners.
    The pose depends only on joints already low-passed at `cutoff`: it is computed on every k-th sample
    (k keeps the reduced Nyquist frequency above 10 x cutoff) and interpolated back, a fifth of the work.
    start: the pass's `_Unmoved`, when its attitude alone q moves: its other joints (`_pose_joints`) and their cos
    and sin are taken from it."""
    N = q.shape[0]
    trig = None
    if start is None:
        sub, qs = _pose_joints(x, q)
    else:  # the pass's joints on those samples, the attitude's (columns 3:6) q's
        sub, qs, trig = _pose_samples(x, N), start.poses.copy(), start.pose_trig
        for j in _ATTITUDE_FRAMES:
            qs[j - 1] = q[:, j - 1][sub]
    # the heights and the z axes' z components alone: the poses' row 2 (frame 0's z), a third of the work
    st = forward_kinematics(x.model.tree, qs, frames=TIRES, rows=slice(2, 3), trig=trig)
    poses = np.stack([st.P[f][0] for f in TIRES] + [st.Rc[f][2][0] for f in TIRES], axis=1)
    # heights and z-axis slopes of the four tire frames, back on every sample by one spline of 8 columns
    return CubicSpline(sub, poses)(np.arange(N))


def _pose_samples(x: _Context, N: int) -> Array:
    """The samples `_tire_poses` computes the poses on: every k-th and the last."""
    k_sub = max(1, int(x.fs / (20 * x.conditioning.cutoff)))
    sub = np.arange(0, N, k_sub)
    return sub if sub[-1] == N - 1 else np.append(sub, N - 1)


def _pose_joints(x: _Context, q: Array) -> tuple[Array, Array]:
    """`_tire_poses`' samples and its joints there, samples last (42, len(sub)) as `joint_array` gives them: q's, the
    translations' and the tire deflections' 0."""
    sub = _pose_samples(x, q.shape[0])
    q0 = q[sub]  # a copy (fancy index)
    q0[:, [0, 1, 2, *(f - 1 for f in TIRES)]] = 0.0
    return sub, joint_array(q0, x.model.tree, "q")[0]


def _heights_acceleration(ch: Mapping[str, Array], x: _Context, q: Array, qd: Array, qdd: Array, filtered: Array,
                          R6: Array, w6: Array, pz_zz: Array, height: bool = True, acceleration: bool = True,
                          kept: _Unmoved | None = None) -> Array | None:
    """`_heights` (when height; its z_laser returned, else None) and `_acceleration` into qdd (columns 0:3, when
    acceleration), their 1 and 6 columns through one low-pass call (a call on few columns waits on the filter's
    latency); kept: the lasers' heights and the specific force, when an attitude offset leaves them."""
    z_laser = _heights(ch, x, filtered, R6, pz_zz, None if kept is None else kept.lasers) if height else None
    cols = ([z_laser.mean(axis=1)] if height else []) + (
        _unit_acceleration(ch, x, R6, w6, None if kept is None else kept.f6) if acceleration else [])
    low = _lowpass_columns(cols, x)
    if height:  # the height, its rate (`signals.filtered_derivatives`')
        q[:, 2], qd[:, 2] = low[:, 0], derivative(low[:, 0], x.fs, check_finite=False)
    if acceleration:
        qdd[:, :3] = _acceleration(x, R6, low, int(height))
    return z_laser


def _heights(ch: Mapping[str, Array], x: _Context, filtered: Array, R6: Array, pz_zz: Array,
             lasers: Array | None = None) -> Array:
    """Each corner's estimate of the height of O6 (N, 4), before the low-pass.

    From the lasers: h = (z_O6 + (R p)_z) / (R6)_z,x (distance along -x6 to the ground), each laser's own
    estimate, used again for the tire deflections. Without lasers, each corner's contact point on the ground with
    the tire deflected by its load: d = Fz / kt (kt known), z = -(pz + d zz). lasers: `_laser_heights`, when known."""
    g, model = x.geometry, x.model
    if x.lasers:
        z_laser = (_laser_heights(ch) if lasers is None else lasers) * R6[:, 2, 0, None] \
            - R6[:, 2, :] @ np.array([laser_point(g, k) for k in range(4)], dtype=float).T
    else:
        kt = np.array([model.tree.values.get(f"K{f}", 0.0) for f in TIRES])
        if not (kt > 0).all():
            raise ModelError("without height lasers the tire deflections come from the wheel loads: the tires' "
                             "vertical stiffness kt15, kt24, kt33, kt42 must be known (a tire bench), > 0; got "
                             f"{kt.tolist()}")
        load = filtered[:, [17 + 6 * k + WFT_COMPONENTS.index("Fz") for k in range(4)]] / kt
        z_laser = -(pz_zz[:, :4] + load * pz_zz[:, 4:])
    return z_laser


def _unit_acceleration(ch: Mapping[str, Array], x: _Context, R6: Array, w6: Array, f6: Array | None = None
                       ) -> list[Array]:
    """The unit's rates in frame 6 and its acceleration in frame 0, (N, 3) each, before the low-pass
    (`_acceleration`): the low-pass's columns, not concatenated (`signals.lowpass_columns` takes them apart). f6:
    `_specific_force`, when known."""
    f6 = _specific_force(ch, x) if f6 is None else f6
    a0 = np.einsum("nij,nj->ni", R6, f6)
    a0 += np.asarray(x.model.tree.gravity)
    return [w6, a0]


def _acceleration(x: _Context, R6: Array, low: Array, first: int = 0) -> Array:
    """Translational acceleration of O6 in frame 0 (N, 3), from the IMU (specific force at its mounting point);
    low[:, first:first + 6]: `_unit_acceleration` low-passed.

    The unit's own acceleration low-passed once like every signal, then carried to O6 with the low-passed
    rotation rates, the ones the regressor carries O6's back to every point of the chassis with. Carried before
    the low-pass, the angular acceleration's lever arm term is filtered twice, the regressor's once: with the unit
    1.6 m ahead of O6, that difference weighs the pitch acceleration's fast part (a brake release) on the chassis
    equations."""
    r_imu = np.asarray(x.geometry.imu_position, dtype=float)
    if _carry_kernel is not None:  # the NumPy lines below in one compiled pass (a dozen (N, 3) temporaries)
        out = np.empty((low.shape[0], 3))
        _carry_kernel(np.ascontiguousarray(low), first, float(x.fs), np.ascontiguousarray(R6.transpose(1, 2, 0)),
                      r_imu, out)
        return out
    w6f, a_imu0 = low[:, first:first + 3], low[:, first + 3:first + 6]
    dw6 = derivative(w6f, x.fs, check_finite=False)
    return a_imu0 - np.einsum("nij,nj->ni", R6, np.cross(dw6, r_imu) + np.cross(w6f, np.cross(w6f, r_imu)))


def _carry_compiled(low, first, fs, R, r, out):  # pragma: no cover - compiled
    """`_acceleration`'s formulas at each sample in their order (`signals.derivative`'s differences, np.cross's
    products, einsum's sum left to right): w = low[:, first:first + 3], a = low[:, first + 3:first + 6] (C order),
    R (3, 3, N) 0R6's entries first (`_rotation`'s layout), r (3,), out (N, 3). One function of explicit loops: its
    compile is short."""
    n = low.shape[0]
    h2 = 2.0 * (1.0 / fs)  # as signals.derivative
    d = np.empty(3)
    for i in range(n):
        for k in range(3):
            c = first + k
            if i == 0:
                d[k] = (-3.0 * low[0, c] + 4.0 * low[1, c] - low[2, c]) / h2
            elif i == n - 1:
                d[k] = (3.0 * low[n - 1, c] - 4.0 * low[n - 2, c] + low[n - 3, c]) / h2
            else:
                d[k] = (low[i + 1, c] - low[i - 1, c]) / h2
        w0, w1, w2 = low[i, first], low[i, first + 1], low[i, first + 2]
        e0, e1, e2 = w1 * r[2] - w2 * r[1], w2 * r[0] - w0 * r[2], w0 * r[1] - w1 * r[0]  # w x r
        s0 = (d[1] * r[2] - d[2] * r[1]) + (w1 * e2 - w2 * e1)  # dw x r + w x (w x r)
        s1 = (d[2] * r[0] - d[0] * r[2]) + (w2 * e0 - w0 * e2)
        s2 = (d[0] * r[1] - d[1] * r[0]) + (w0 * e1 - w1 * e0)
        for k in range(3):
            out[i, k] = low[i, first + 3 + k] - (R[k, 0, i] * s0 + R[k, 1, i] * s1 + R[k, 2, i] * s2)


def _velocity(ch: Mapping[str, Array], x: _Context, q: Array, qd: Array, R6: Array, w6: Array,
              deflections: tuple[Array, Array, Array] | None = None) -> None:
    """Position and velocity of O6 along x0, y0 into q, qd (columns 0:2): the Correvit (or a GNSS/INS) gives the
    horizontal components (chassis x, y), the height's rate (qd column 2) the vertical. deflections: (qdd, pz_zz,
    z_laser), `_deflections`' arguments: done too, its columns through the same call of the low-pass."""
    g = x.geometry
    N = q.shape[0]
    tag, pc = ("correvit", correvit_point(g)) if "correvit_vx" in x.suite.names else ("gnss", gnss_point(g))
    pc = np.asarray(pc, dtype=float)
    # ISO_AXES is a signed permutation: the sensor's velocity in frame 6 ([vx, vy, 0] @ ISO_AXES, vz unknown) and R6
    # times the vehicle z axis are signed gathers, and w6 x pc is written out in np.cross's operations: the same
    # numbers without their (N, 3) matrix products (0.8 ms each per 60 s segment) and np.cross's copies
    iso = (ch[f"{tag}_vx"], ch[f"{tag}_vy"], None)
    k, sign = _ISO_ROWS[2]  # the vehicle z axis in frame 6: R6 ez6 = sign R6[:, :, k]
    if _velocity_kernel is not None:  # the lines below in one compiled pass, the deflections' too
        qdd, pz_zz, z_laser = deflections if deflections is not None else (None, np.empty((0, 8)), np.empty((0, 4)))
        out = np.empty((N, 2 if deflections is None else 6))
        c = np.ascontiguousarray
        _velocity_kernel(c(w6), pc, c(iso[0]), c(iso[1]), *_GATHER, c(R6.transpose(1, 2, 0)), k, sign, c(qd[:, 2]),
                         c(pz_zz), c(z_laser), out)
        if deflections is None:
            v = _lowpass(out, x)
        else:
            low = _lowpass_columns([out], x)
            v = low[:, :2]
            _deflected(x, q, qd, qdd, low[:, 2:6])
        q[:, :2], qd[:, :2] = integrate(v, x.fs, check_finite=False), v
        return
    rel = np.empty((N, 3))  # v_c - w6 x pc
    for j, (a, b) in enumerate(((1, 2), (2, 0), (0, 1))):
        k_, sign_ = _ISO_GATHER[j]
        wxp = w6[:, a] * pc[b]
        wxp -= w6[:, b] * pc[a]
        if iso[k_] is None:  # 0 - w6 x pc: as the product's +0
            np.subtract(0.0, wxp, out=rel[:, j])
        else:
            np.subtract(iso[k_] if sign_ > 0 else -iso[k_], wxp, out=rel[:, j])
    v_known = np.einsum("nij,nj->ni", R6, rel)
    ez = R6[:, :, k] if sign > 0 else -R6[:, :, k]
    s = (qd[:, 2] - v_known[:, 2]) / ez[:, 2]
    v0 = v_known[:, :2] + s[:, None] * ez[:, :2]
    if deflections is None:
        v = _lowpass(v0, x)
    else:  # the velocity's 2 columns and the 4 deflections through one low-pass
        qdd, pz_zz, z_laser = deflections
        low = _lowpass_columns([v0, _deflection(pz_zz, z_laser)], x)
        v = low[:, :2]
        _deflected(x, q, qd, qdd, low[:, 2:6])
    q[:, :2], qd[:, :2] = integrate(v, x.fs, check_finite=False), v


def _velocity_compiled(w6, pc, vx, vy, gk, gs, R, k, sign, qd2, pz_zz, z_laser, out):  # pragma: no cover - compiled
    """`_velocity`'s NumPy lines at each sample, their operations in their order: rel = v_c - w6 x pc (the sensor's
    velocity [vx, vy, 0] gathered by `_ISO_GATHER`: component j is gs[j] times the gk[j]-th, none when 2; a product
    by 1 or -1 is exact), v_known = R6 rel (einsum's sum left to right), the vertical part from qd2 along sign
    R6[:, :, k], v0 into out[:, :2]; when out has 6 columns, `_deflection`'s -(pz + z_laser) / zz into out[:, 2:6].
    R (3, 3, N): 0R6's entries first (`_rotation`'s layout). One function of explicit loops and few branches: its
    compile is short (0.3 s); the NumPy lines made ~30 passes over the samples."""
    n = out.shape[0]
    deflections = out.shape[1] == 6
    for i in range(n):
        w0, w1, w2 = w6[i, 0], w6[i, 1], w6[i, 2]
        x0 = w1 * pc[2] - w2 * pc[1]  # w6 x pc, np.cross's operations
        x1 = w2 * pc[0] - w0 * pc[2]
        x2 = w0 * pc[1] - w1 * pc[0]
        r0 = 0.0 - x0 if gk[0] == 2 else (vx[i] if gk[0] == 0 else vy[i]) * gs[0] - x0
        r1 = 0.0 - x1 if gk[1] == 2 else (vx[i] if gk[1] == 0 else vy[i]) * gs[1] - x1
        r2 = 0.0 - x2 if gk[2] == 2 else (vx[i] if gk[2] == 0 else vy[i]) * gs[2] - x2
        v0 = R[0, 0, i] * r0 + R[0, 1, i] * r1 + R[0, 2, i] * r2
        v1 = R[1, 0, i] * r0 + R[1, 1, i] * r1 + R[1, 2, i] * r2
        v2 = R[2, 0, i] * r0 + R[2, 1, i] * r1 + R[2, 2, i] * r2
        s = (qd2[i] - v2) / (R[2, k, i] * sign)
        out[i, 0] = v0 + s * (R[0, k, i] * sign)
        out[i, 1] = v1 + s * (R[1, k, i] * sign)
        if deflections:
            for c in range(4):
                out[i, 2 + c] = -(pz_zz[i, c] + z_laser[i, c]) / pz_zz[i, 4 + c]


def _deflection(pz_zz: Array, z_laser: Array) -> Array:
    """The four tires' deflections (N, 4), before the low-pass: -(pz + z_laser) / zz, in one array."""
    d = np.add(pz_zz[:, :4], z_laser)
    np.negative(d, out=d)
    return np.divide(d, pz_zz[:, 4:], out=d)


def _deflected(x: _Context, q: Array, qd: Array, qdd: Array, low: Array) -> None:
    """The low-passed deflections and their central differences (`signals.filtered_derivatives`') into the tire
    columns."""
    cols = [f - 1 for f in TIRES]
    d = derivative(low, x.fs, check_finite=False)
    q[:, cols], qd[:, cols], qdd[:, cols] = low, d, _derivative_at(d, x.fs, _rows(qdd))


def _trajectory(x: _Context, q: Array, qd: Array, qdd: Array, filtered: Array, has_spin: bool,
                steering: Array) -> CarTrajectory:
    """The joints and the low-passed loads, trimmed of the filters' borders."""
    t, ww, spin, steering = _trajectory_parts(x, filtered, has_spin, steering, q.shape[0])
    return CarTrajectory(t, q, qd, qdd, ww, spin, steering).trimmed(x.border)


def _trajectory_parts(x: _Context, filtered: Array, has_spin: bool, steering: Array, N: int
                      ) -> tuple[Array, Array, Array | None, Array]:
    """A trajectory's times, loads, spin torques and steering wheel, untrimmed."""
    ww = filtered[:, 17:41].reshape(N, 4, len(WFT_COMPONENTS))
    return np.arange(N) / x.fs, ww, filtered[:, 41:45] if has_spin else None, steering


# the compiled pass (numba's cache: compiled once per machine, loaded in ms afterwards)
try:
    from numba import njit

    _corner_kernel = njit(cache=True, nogil=True)(_corners_compiled)
    _carry_kernel = njit(cache=True, nogil=True)(_carry_compiled)
    _euler_kernel = njit(cache=True, nogil=True)(_euler_compiled)
    _velocity_kernel = njit(cache=True, nogil=True)(_velocity_compiled)
except ImportError:  # pragma: no cover - exercised only without numba
    _corner_kernel = _carry_kernel = _euler_kernel = _velocity_kernel = None
