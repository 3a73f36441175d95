"""The identification's unit of work: one segment of one test to its reduced form, and their combination.

`reduce_car_segment(job)` is a pure function of a small picklable job (the config, the segment's
time window of its file, and what to evaluate on it): it reads the window, estimates the joints,
builds the 14 equations' decimated rows and reduces them to a `Partial` (per equation group the
triangular factor of [W | Y]; for a few segments of each identification test the sensor offsets'
sensitivities, the rows with one draw of the sensors' errors added and subtracted (the model-fit verdict,
estimation/fit.py) and the channel groups' delay sensitivities (estimation/shifts.py); or an IDIM-IV pass's
instrument sums). `combine` is pure and associative to round-off: Partials of any split of
the data combine into the whole data's. A scheduler (`schedulers`) maps the first over every
segment, on this machine's cores or a cluster's workers, and folds with the second.

A robot's chunk (`reduce_robot_chunk`) reduces to its decimated rows (a robot's estimators, wls-pc
among them, and its validation files read rows), which `stack_rows` folds.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import os
import pickle
import threading
import zlib
from collections import OrderedDict
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..dynamics import BaseParameters, Model
from ..estimation import StreamingLS
from ..estimation.fit import ErrorEffect
from ..estimation.iv import InstrumentSums
from ..estimation.shifts import ShiftSums
from ..estimation.systematic import BiasAccumulator
from ..io import Channel
from ..io.units import unit_factor
from .config import IdentifyConfig
from .health import CarHealth, segment_health
from .robot import GroupedSystem, chunk_rows, to_frames
from .sources import RobotTestPlan, SegmentWindow, config_joints, driven, gain_names, read_robot_window, read_segment

if TYPE_CHECKING:
    from ..vehicle.estimate import CarTrajectory
    from ..vehicle.tire_curves import TireSamples


@dataclass(frozen=True)
class CarJob:
    """One segment and what to evaluate on it.

    offsets: (quantity, one-σ zero offset, SI) whose effect is evaluated on this segment,
    standing for `weight` segments of the test; instruments: the last estimate, for an IDIM-IV pass;
    keep_rows: return the rows themselves (each test's first segment: the report's plots)."""

    cfg: IdentifyConfig
    window: SegmentWindow
    role: str
    number: int  # 1-based, within its test
    offsets: tuple[tuple[str, float], ...] = ()
    weight: float = 1.0
    instruments: dict[str, float] | None = None
    keep_rows: bool = False
    errors: bool = False  # evaluate the sensors' errors' effect on the rows (the model-fit verdict)
    delays: bool = False
    lags: tuple[tuple[str, float], ...] = ()  # channel group -> s later than declared (the delays' refinement)
    # the part of the test whose data health this segment gathers: (t_start, t_end, end included), s (the first map's
    # segments each answer for theirs: segments overlap by the filter's borders); None: not gathered here
    health: tuple[float, float, bool] | None = None

    @property
    def test(self) -> str:
        return self.window.test


@dataclass
class Partial:
    """Reduced rows of some segments: least squares' factors, and where evaluated the offsets' sums and the
    instruments' sums, the channel groups' delay sensitivities; rows: {test: its first segment's rows}; segments:
    how many segments went in."""

    ls: StreamingLS
    bias: BiasAccumulator | None = None
    iv: InstrumentSums | None = None
    rows: dict[str, GroupedSystem] = field(default_factory=dict)
    segments: int = 1
    errors: ErrorEffect | None = None  # rows without and with one draw of the sensors' errors (estimation/fit.py)
    shifts: ShiftSums | None = None
    tires: TireSamples | None = None  # the wheels' slips and forces (vehicle.tire_curves), a few per second
    health: dict[str, CarHealth] = field(default_factory=dict)  # test -> its data health so far (pipeline.health)


def combine(a: Partial, b: Partial) -> Partial:
    """a's rows then b's (pure: neither changes)."""
    def both(x, y):
        return y if x is None else x if y is None else x.merge(y)

    health = {t: a.health[t].merged(b.health[t]) if t in b.health else a.health[t] for t in a.health}
    return Partial(a.ls.merge(b.ls), both(a.bias, b.bias), both(a.iv, b.iv), {**b.rows, **a.rows},
                   a.segments + b.segments, both(a.errors, b.errors), both(a.shifts, b.shifts),
                   both(a.tires, b.tires), {**b.health, **health})


class CarSetup:
    """What every segment of one config needs, built once per process: the vehicle, its tree with the known values,
    the base parameters, the conditioning, the generated identification model."""

    def __init__(self, cfg: IdentifyConfig) -> None:
        from ..vehicle import DAMPERS, EQUATION_ROWS, TIRES, car_base_parameters
        from ..vehicle.description import load_vehicle
        from ..vehicle.dynamics import group_channels
        from ..vehicle.equations import group_name
        from ..vehicle.estimate import CarConditioning

        settings = self.settings = cfg.car
        vehicle = self.vehicle = load_vehicle(cfg.vehicle or "peugeot406")
        tree = vehicle.template()
        # the bench values of the vehicle file, then the config's (a config may fix more, or other values)
        known = {**vehicle.known, **{tree.parameter_names[tree.column(k)]: v for k, v in cfg.known.items()}}
        if known:
            tree = tree.with_values(known).with_known(set(known))
        self.tree, self.model = tree, Model(tree)
        self.base: BaseParameters = car_base_parameters(tree, settings.base)
        self.names = list(self.base.names)
        self.conditioning = CarConditioning(settings.cutoff, settings.order, settings.attitude_crossover,
                                            compensate_delays=settings.compensate_delays)
        self.logger = vehicle.logger
        self.aero = vehicle.aero if settings.aero else None
        # the channel groups whose delay the identification estimates (pipeline.delays): the inertial unit (the
        # chassis motion) and the clearances (the suspensions), from the chassis and suspension equations. Not the
        # tire equations: their model (a linear spring through the geometric radius) misfits a real tire, and a
        # misfit's residual reads as a delay; so not the lasers either, which only they see. Nor the steering and
        # camber cameras (their angles turn the wheel forces by a few degrees: the MuJoCo car's tests left their
        # delay at +-20 ms) or the Correvit and GNSS/INS (the horizontal velocity enters only the aerodynamic
        # wrench: the demo's σ was above a sample): not worth a pass each
        self.delay_equations = frozenset(group_name(j) for j in (*range(1, 7), *DAMPERS))
        self.delay_groups = tuple(g for g in ("imu", "clearances") if group_channels(g, vehicle.suite.names))
        # without height lasers the tire deflections come from the loads through the known kt: those rows say nothing
        self.equations = None if vehicle.lasers else [j for j in EQUATION_ROWS if j not in TIRES]

    @cached_property
    def regressor(self):
        from ..symbolic.generated import GeneratedRegressor

        return GeneratedRegressor(self.tree)

    def trajectory(self, channels: dict[str, np.ndarray], fs: float, lags: Mapping[str, float] | None = None,
                   compensated: Mapping[str, np.ndarray] | None = None) -> CarTrajectory:
        """The joints and filtered loads of one segment's channels (SI), the declared dynamics undone (none when
        the config turns the compensation off); lags: channel group -> s, its channels taken as that much later
        than declared (advanced by it more: the delay estimate's perturbations); compensated: `compensated` of
        these channels and lags, when known (not undone again)."""
        from ..vehicle.estimate import estimate_joints  # the car's modules, as in __init__: a robot needs none

        return estimate_joints(channels, fs, self.model, self.vehicle.geometry, self.vehicle.tables,
                               self.conditioning, self.vehicle.suite, self.logger.channels,
                               self._lags(channels, lags), compensated)

    def compensated(self, channels: dict[str, np.ndarray], fs: float,
                    lags: Mapping[str, float] | None = None) -> dict[str, np.ndarray]:
        """The channels with the declared dynamics undone and the groups' lags advanced (`trajectory`'s first
        step), to be reused by passes that move one channel by a constant."""
        from ..vehicle.estimate import compensated_channels

        return compensated_channels(channels, fs, self.conditioning, self.vehicle.suite, self.logger.channels,
                                    self._lags(channels, lags))

    @staticmethod
    def _lags(channels, lags: Mapping[str, float] | None) -> dict[str, float]:
        """channel -> s of the groups' lags."""
        from ..vehicle.dynamics import group_channels

        return {n: d for g, d in (lags or {}).items() for n in group_channels(g, channels)}

    def rows(self, traj: CarTrajectory, fs: float, instruments: dict[str, float] | None = None,
             keep: np.ndarray | None = None) -> GroupedSystem:
        """The decimated rows of one segment's trajectory."""
        from .car import car_system

        s = self.settings
        return car_system(self.model, traj, fs, s.decimate, base=self.base, aero=self.aero, regressor=self.regressor,
                          cutoff=self.conditioning.cutoff, min_speed=s.min_speed, instruments=instruments, keep=keep,
                          equations=self.equations)[0]

    def load_only(self, channel: str) -> bool:
        """Whether a zero offset of `channel` moves the filtered wheel loads alone: a wheel force or moment, except
        the vertical force of a car without height lasers (its heights come from that load). The estimator takes
        such a channel through a delay and a low-pass, both of unit gain at 0 Hz, into the loads: its offset moves
        them by itself, the joints not at all (tests/test_sensor_offsets.py checks it against the full pass)."""
        return channel.startswith("wft_") and (self.vehicle.lasers or not channel.endswith("_Fz"))


CAMERAS = ("steer_", "camber_")  # the channels whose saturation the estimator replaces by the kinematic tables

_SETUPS: OrderedDict[str, Any] = OrderedDict()
_SETUPS_KEPT = 64  # a campaign's configs take turns on every worker: keep them all (a setup is a few MB)
_SETUPS_LOCK = threading.Lock()


def _setup(key: tuple, make: Callable[[], Any]) -> Any:
    """One setup per config and process (a worker receives the config with every job), the last few kept."""
    h = hashlib.sha256(pickle.dumps(key)).hexdigest()
    with _SETUPS_LOCK:
        if h in _SETUPS:
            _SETUPS.move_to_end(h)
            return _SETUPS[h]
    made = make()  # outside the lock: a slow build does not hold the other threads' segments
    with _SETUPS_LOCK:
        made = _SETUPS.setdefault(h, made)
        while len(_SETUPS) > _SETUPS_KEPT:
            _SETUPS.popitem(last=False)
    return made


def _stamp(source: object) -> object:
    """A setup's source in its key: a file by its absolute path and its version (size, time of change), so that a
    config or model file edited, or another one of the same relative name (a Python session that changes folder),
    never gets a setup built from the other; a shipped name as it is."""
    if isinstance(source, str | os.PathLike):
        path = Path(source)
        with contextlib.suppress(OSError):
            st = path.stat()
            return (str(path.resolve()), st.st_size, st.st_mtime_ns)
    return source


def car_setup(cfg: IdentifyConfig) -> CarSetup:
    """The config's car setup (see `_setup`)."""
    return _setup(("car", _stamp(cfg.path), _stamp(cfg.model), _stamp(cfg.vehicle), cfg.known, cfg.car),
                  lambda: CarSetup(cfg))


def reduce_car_segment(job: CarJob) -> Partial:
    """The job's segment read, turned into rows and reduced (module doc)."""
    setup = car_setup(job.cfg)
    w = job.window
    samples: dict[str, Channel] | None = None if job.health is None else {}
    channels = read_segment(w, file_samples=samples)
    lags = dict(job.lags)
    compensated = setup.compensated(channels, w.fs, lags)
    traj = setup.trajectory(channels, w.fs, lags, compensated)
    sys = setup.rows(traj, w.fs, job.instruments)
    ls = StreamingLS(setup.names)
    ls.add(sys.W, sys.Y, sys.groups)
    part = Partial(ls, rows={w.test: sys} if job.keep_rows else {})
    if job.health is not None:  # the data health of the part of the test this segment answers for
        part.health = {w.test: segment_health(w, setup.vehicle, job.health, samples, channels)}
    if setup.settings.tire_curves and job.instruments is None and not job.lags:
        from ..vehicle.tire_curves import tire_samples

        # the loads and joints are low-passed at the cut-off: five samples per period of it are plenty
        step = max(1, round(w.fs / (5 * setup.conditioning.cutoff)))
        part.tires = tire_samples(setup.model, traj, w.test, setup.vehicle.geometry.wheel_radius, w.first / w.fs,
                                  step)
    if job.instruments is not None:
        part.iv = ls.instrument_sums()
        part.iv.add(sys.W, sys.Y, sys.Z, sys.groups)
    if job.delays and setup.delay_groups:
        # each group a sample later than declared: the rows' change per second of delay (`estimation.shifts`),
        # on the equations the delays are read from
        h = 1.0 / w.fs
        part.shifts = ShiftSums(setup.delay_groups, *_columns(ls))
        moved = [setup.rows(setup.trajectory(channels, w.fs, {**lags, g: lags.get(g, 0.0) + h}), w.fs,
                            job.instruments, keep=sys.kept) for g in setup.delay_groups]
        used = np.isin(sys.groups, list(setup.delay_equations))
        part.shifts.add(sys.W[used], sys.Y[used], [(p.W - sys.W)[used] / h for p in moved],
                        [(p.Y - sys.Y)[used] / h for p in moved], sys.groups[used])
    if job.offsets:
        part.bias = ls.bias_accumulator()
        for q, b in job.offsets:  # each sensor's zero moved by its standard deviation (SI), rows unchanged
            if setup.load_only(q):  # the joints unchanged: a tenth of the work (CarSetup.load_only)
                moved_traj = shifted_load(traj, q, b)
            elif q.startswith(CAMERAS):  # a camera's offset moves what its range clips: the whole pass
                moved_traj = setup.trajectory({**channels, q: channels[q] + b}, w.fs, lags)
            else:  # undoing the dynamics is affine with unit gain at 0 Hz: the offset passes through it as is
                moved_traj = setup.trajectory({**channels, q: channels[q] + b}, w.fs, lags,
                                              {**compensated, q: compensated[q] + b})
            p = setup.rows(moved_traj, w.fs, job.instruments, keep=sys.kept)
            iv = {} if job.instruments is None else {"Z": sys.Z, "dZ": p.Z - sys.Z}
            part.bias.add(f"{w.test}: {q}", sys.W, sys.Y, p.W - sys.W, p.Y - sys.Y, sys.groups, job.weight, **iv)
    if job.errors:
        seed = zlib.crc32(f"{w.test}/{job.number}".encode())  # the same draw on threads and on a cluster
        noisy = []
        for e in sensor_errors(channels, setup.vehicle.suite, seed, w.fs):
            noisy_traj = setup.trajectory({k: v + e[k] if k in e else v for k, v in channels.items()}, w.fs, lags)
            p = setup.rows(noisy_traj, w.fs, job.instruments, keep=sys.kept)
            noisy.append(StreamingLS(setup.names))
            noisy[-1].add(p.W, p.Y, sys.groups)
        part.errors = ErrorEffect(ls, *noisy)
    return part


def sensor_errors(channels: dict[str, np.ndarray], suite, seed: int, fs: float) -> tuple[dict[str, np.ndarray], ...]:
    """One draw of the sensors' errors on the channels present (SI, logger at fs Hz), and its opposite: white
    noise of each channel's accuracy held at the sensor's own rate, as the suite's chain holds it
    (`vehicle.sensors.corrupt`: a 125 Hz unit's noise is 5 samples long, so more of it passes the low-pass), and
    its zero offset (bias) with a random sign (channel units; estimation/fit.py says why)."""
    from ..vehicle.sensors import sample_and_hold

    rng = np.random.default_rng(seed)
    e = {}
    for c in suite:
        if c.name in channels:
            n = np.size(channels[c.name])
            factor = unit_factor(c.unit, channel=c.name)[0]
            noise = sample_and_hold(c.accuracy * rng.standard_normal(n), c.rate, fs)
            e[c.name] = factor * (noise + c.bias * rng.choice((-1.0, 1.0)))
    return e, {k: -v for k, v in e.items()}


def shifted_load(traj: CarTrajectory, channel: str, b: float) -> CarTrajectory:
    """traj with the wheel-wrench component of the channel wft_{corner}_{component} moved by b (SI)."""
    from ..vehicle.sensors import CORNER_TAGS, WFT_COMPONENTS

    _, corner, comp = channel.split("_")
    ww = traj.wheel_wrenches.copy()
    ww[:, CORNER_TAGS.index(corner), WFT_COMPONENTS.index(comp)] += b
    return dataclasses.replace(traj, wheel_wrenches=ww)


def _columns(ls: StreamingLS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The estimated columns, the known ones and their values (`StreamingLS.bias_accumulator`'s)."""
    acc = ls.bias_accumulator()
    return acc.columns, acc.known_columns, acc.known_values


# ------------------------------------------------------------------------------------------------------- a robot
@dataclass(frozen=True)
class RobotJob:
    """One chunk (kept samples s..e) of a robot test: the test's plan cut to the samples read around it."""

    cfg: IdentifyConfig
    window: RobotTestPlan  # the plan, its clock cut to the samples read: window.first onwards
    chunk: tuple[int, int]
    n_samples: int

    @property
    def test(self) -> str:
        return self.window.test


class RobotSetup:
    """A robot config's model and base parameters, built once per process."""

    def __init__(self, cfg: IdentifyConfig) -> None:
        from ..dynamics import load_model
        from .config import ConfigError

        self.joints = config_joints(cfg, load_model(cfg.model).tree)
        self.model = Model(self.joints.tree)
        self.base: BaseParameters = self.model.base_parameters()
        # the estimated parameters: the base parameters, then the drive gains when identified
        self.names = [*self.base.names, *gain_names(cfg)]
        clash = sorted(set(self.base.names) & set(gain_names(cfg)))
        if clash:
            raise ConfigError(f"{cfg.path}: [drive] the gain {clash[0]!r} has the name of a parameter of the model; "
                              "rename that parameter (a coupling) in the model file")
        self.payloads: dict[str, tuple[int, np.ndarray]] = {}  # test -> (frame, its standard parameters)
        for t in cfg.tests:
            if t.payload is not None:
                j = max(self.joints.columns) if t.payload.frame is None else t.payload.frame
                if not 1 <= j <= self.model.n:
                    raise ConfigError(f"{cfg.path}: test {t.name!r}: payload frame = {j}; model {self.model.name!r} "
                                      f"has frames 1 to {self.model.n}: name the link that carries it")
                self.payloads[t.name] = (j, t.payload.standard())


def robot_setup(cfg: IdentifyConfig) -> RobotSetup:
    """The config's robot setup (see `_setup`)."""
    return _setup(("robot", _stamp(cfg.path), _stamp(cfg.model), cfg.tests, cfg.drive, cfg.joints,
                   {k: v.tolist() for k, v in cfg.transmission.items()},
                   {k: c.channels for k, c in cfg.channels.items()}), lambda: RobotSetup(cfg))


def reduce_robot_chunk(job: RobotJob) -> GroupedSystem:
    """The chunk's samples read, through the channel map, drive gains and transmission, to its decimated rows (with
    the drive gains' columns when they are identified, and the test's payload torque taken off)."""
    setup = robot_setup(job.cfg)
    w = job.window
    arrays = read_robot_window(w, 0, w.samples)
    columns, n = setup.joints.columns, setup.model.n
    q, tau, gains = driven(job.cfg, arrays["q"], arrays[w.effort], len(columns))
    q, tau = to_frames(q, columns, n), to_frames(tau, columns, n)
    if gains is not None and len(columns) != n:  # the joints without data: no rows, zero columns
        full = np.zeros((gains.shape[0], n, gains.shape[2]))
        full[:, np.asarray(columns) - 1, :] = gains
        gains = full
    return chunk_rows(setup.model, setup.base, job.cfg.conditioning, q, tau, w.fs, w.first, job.chunk,
                      job.n_samples, gains=gains, payload=setup.payloads.get(w.test))


def stack_rows(a: GroupedSystem, b: GroupedSystem) -> GroupedSystem:
    """a's rows then b's."""
    return GroupedSystem.stack([a, b])
