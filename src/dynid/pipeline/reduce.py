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

A robot's chunk (`reduce_robot_chunk`) reduces to the same `Partial`: its rows' per-group factors of [W | Y]
(every column: the known values and the drive gains are applied to the factors when solving), and for each
test's first chunks the rows themselves (the report's plots, up to `run.PLOT_BYTES`). A chunk's full-rate W is
never whole either (`robot.chunk_rows`: a block at a time through the first decimation stage). So a robot's
memory is bounded by its factors, a few decimated chunks and one block per worker, whatever the length of its
logs.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import math
import os
import pickle
import threading
import zlib
from collections import OrderedDict
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..dynamics import BaseParameters, Model, load_model
from ..estimation import StreamingLS
from ..estimation.fit import ErrorEffect
from ..estimation.hac import HACSums
from ..estimation.iv import InstrumentSums
from ..estimation.offsets import NoiseScores, OffsetFactors
from ..estimation.shifts import ShiftSums
from ..estimation.systematic import BiasAccumulator
from ..io import Channel
from ..io.units import unit_factor
from ..io.windows import forget_blocks_before
from ..shipped import DEMO_VEHICLE
from ..signals.decimation import FirstStage
from ..symbolic.generated import GeneratedRegressor
from .config import ConfigError, IdentifyConfig
from .health import CarHealth, RobotHealth, gather_joints, segment_health
from .robot import GroupedSystem, chunk_buffers, chunk_filtered, chunk_pad, chunk_rows, to_frames
from .schedulers import Staged
from .sources import (
    RobotTestPlan,
    SegmentWindow,
    clock_read,
    config_joints,
    driven,
    gain_names,
    read_robot_window,
    read_segment,
)

if TYPE_CHECKING:
    from ..vehicle.dampers import KneeSearch
    from ..vehicle.estimate import CarTrajectory, CoarseTrajectory, JointsPass
    from ..vehicle.tire_curves import SampleParts


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
    estimate_offsets: bool = False  # the offsets' rows kept for their estimate (estimation.offsets), weight 1
    # the offsets' propagation's sums (Partial.bias) too; identify's estimate needs only the offsets' columns
    propagate_offsets: bool = True
    knees: bool = False  # the knees' search alone (vehicle.dampers.KneeSearch): the dampers' rows and candidates
    # the part of the test whose data health this segment gathers: (t_start, t_end, end included), s (the first map's
    # segments each answer for theirs: segments overlap by the filter's borders); None: not gathered here
    health: tuple[float, float, bool] | None = None
    hac: HACSums | None = None  # the second pass of a HAC covariance: the rows' scores at this estimate, alone
    # the plan's: this window of files with draws of the noise alone (with estimate_offsets): the rows' noise as it
    # is, scored by the noise-free rows (estimation.offsets.NoiseScores, lag `noise_lag` rows)
    noise: tuple[SegmentWindow, ...] = ()
    noise_lag: int = 0
    # the step between the wheel samples gathered for the tire curves (vehicle.tire_curves.sample_steps: the run's
    # budget, chosen from the plan); None: the cut-off's (a job alone)
    tire_step: int | None = None

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
    tires: SampleParts | None = None  # the wheels' slips and forces (vehicle.tire_curves), a few per second
    zeros: OffsetFactors | None = None  # each test's rows with its offsets' columns (estimation.offsets)
    knees: KneeSearch | None = None  # the damper curves' knees from the data (vehicle.dampers)
    # test -> its data health so far (pipeline.health; a robot's: its joints against the model)
    health: dict[str, CarHealth | RobotHealth] = field(default_factory=dict)
    hac: HACSums | None = None  # the Newey–West sums of a HAC covariance's second pass (estimation.hac)
    noise: NoiseScores | None = None  # the plan's: one draw of the rows' noise, scored (CarJob.noise)


def combine(a: Partial, b: Partial) -> Partial:
    """a's rows then b's (pure: neither changes)."""
    def both(x, y):
        return y if x is None else x if y is None else x.merge(y)

    rows = {**b.rows, **a.rows}  # a test's rows kept on both sides (a robot's, all kept): a's then b's
    rows.update({k: GroupedSystem.stack([a.rows[k], b.rows[k]]) for k in a.rows.keys() & b.rows.keys()})
    health = {t: a.health[t].merged(b.health[t]) if t in b.health else a.health[t] for t in a.health}
    return Partial(a.ls.merge(b.ls), both(a.bias, b.bias), both(a.iv, b.iv), rows,
                   a.segments + b.segments, both(a.errors, b.errors), both(a.shifts, b.shifts),
                   both(a.tires, b.tires), both(a.zeros, b.zeros), both(a.knees, b.knees), {**b.health, **health},
                   both(a.hac, b.hac), both(a.noise, b.noise))


class CarSetup:
    """What every segment of one config needs, built once per process: the vehicle, its tree with the known values,
    the base parameters, the conditioning, the generated identification model."""

    def __init__(self, cfg: IdentifyConfig) -> None:
        # start-up: a car's alone (the vehicle package, scipy.interpolate and optimize: 18 MB not on a robot's path)
        from ..vehicle import DAMPERS, EQUATION_ROWS, TIRES, car_base_parameters
        from ..vehicle.description import load_vehicle
        from ..vehicle.dynamics import group_channels
        from ..vehicle.equations import group_name
        from ..vehicle.estimate import CarConditioning

        settings = self.settings = cfg.car
        vehicle = load_vehicle(cfg.vehicle or DEMO_VEHICLE)
        if settings.knees:  # the knees the search chose from the data (pipeline.run)
            vehicle = vehicle.with_knees({d: (lo, hi) for d, lo, hi in settings.knees})
        self.vehicle = vehicle
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
    def a_priori(self) -> np.ndarray:
        """The base parameters' a priori values (the vehicle's), in `names` order: where the offsets' rows are
        linearised (estimation.offsets)."""
        tree = self.tree
        X = np.array([self.vehicle.a_priori.values.get(n, 0.0) for n in tree.parameter_names])
        return np.asarray(self.base.values(X), dtype=float)

    @cached_property
    def regressor(self):
        return GeneratedRegressor(self.tree)

    def trajectory(self, channels: dict[str, np.ndarray], fs: float, lags: Mapping[str, float] | None = None,
                   compensated: Mapping[str, np.ndarray] | None = None) -> CarTrajectory:
        """The joints and filtered loads of one segment's channels (SI), the declared dynamics undone (none when
        the config turns the compensation off); lags: channel group -> s, its channels taken as that much later
        than declared (advanced by it more: the delay estimate's perturbations); compensated: `compensated` of
        these channels and lags, when known (not undone again)."""
        return self.joints(channels, fs, lags, compensated).traj

    def joints(self, channels: dict[str, np.ndarray], fs: float, lags: Mapping[str, float] | None = None,
               compensated: Mapping[str, np.ndarray] | None = None) -> JointsPass:
        """`trajectory` with what a pass with one channel's zero moved reuses (`vehicle.estimate.JointsPass`)."""
        from ..vehicle.estimate import joints_pass  # start-up: a car's alone (CarSetup.__init__)

        return joints_pass(channels, fs, self.model, self.vehicle.geometry, self.vehicle.tables, self.conditioning,
                           self.vehicle.suite, self.logger.channels, self._lags(channels, lags), compensated)

    def compensated(self, channels: dict[str, np.ndarray], fs: float,
                    lags: Mapping[str, float] | None = None) -> dict[str, np.ndarray]:
        """The channels with the declared dynamics undone and the groups' lags advanced (`trajectory`'s first
        step), to be reused by passes that move one channel by a constant."""
        from ..vehicle.estimate import compensated_channels  # start-up: a car's alone (CarSetup.__init__)

        return compensated_channels(channels, fs, self.conditioning, self.vehicle.suite, self.logger.channels,
                                    self._lags(channels, lags))

    @staticmethod
    def _lags(channels, lags: Mapping[str, float] | None) -> dict[str, float]:
        """channel -> s of the groups' lags."""
        from ..vehicle.dynamics import group_channels  # start-up: a car's alone (CarSetup.__init__)

        return {n: d for g, d in (lags or {}).items() for n in group_channels(g, channels)}

    def rows(self, traj: CarTrajectory, fs: float, instruments: dict[str, float] | None = None,
             keep: np.ndarray | None = None) -> GroupedSystem:
        """The decimated rows of one segment's trajectory."""
        from .car import car_system  # start-up: a car's alone (CarSetup.__init__)

        s = self.settings
        return car_system(self.model, traj, fs, s.decimate, base=self.base, aero=self.aero, regressor=self.regressor,
                          cutoff=self.conditioning.cutoff, min_speed=s.min_speed, instruments=instruments, keep=keep,
                          equations=self.equations, friction_lowpass=s.order if s.friction_lowpass else None)[0]

    def moved_rows(self, traj: CarTrajectory, moved: Iterable[CarTrajectory | CoarseTrajectory], fs: float,
                   keep: np.ndarray, x: np.ndarray | None = None
                   ) -> list[tuple[np.ndarray, np.ndarray]] | list[np.ndarray]:
        """(W, Y) of the kept rows of each moved trajectory (traj's with an input changed), in one pass; with x
        (a value per column of W) the change of their residual Y − W x from traj's alone (`car_moved_rows`)."""
        from .car import car_moved_rows  # start-up: a car's alone (CarSetup.__init__)

        s = self.settings
        return car_moved_rows(self.model, traj, moved, fs, keep, s.decimate, base=self.base, aero=self.aero,
                              regressor=self.regressor, cutoff=self.conditioning.cutoff,
                              friction_lowpass=s.order if s.friction_lowpass else None, x=x)

    def load_changes(self, traj: CarTrajectory, moved: Sequence[tuple[str, float]], fs: float, keep: np.ndarray
                     ) -> list[np.ndarray]:
        """ΔY of the kept rows for each (wheel-load channel, offset SI) (`load_only` channels: W unchanged)."""
        from ..vehicle.sensors import CORNER_TAGS, WFT_COMPONENTS  # start-up: a car's alone (CarSetup.__init__)
        from .car import car_load_changes

        which = [(CORNER_TAGS.index(q.split("_")[1]), WFT_COMPONENTS.index(q.split("_")[2]), b) for q, b in moved]
        return car_load_changes(self.model, traj, which, fs, keep, self.settings.decimate,
                                cutoff=self.conditioning.cutoff)

    def load_only(self, channel: str) -> bool:
        """Whether a zero offset of `channel` moves the filtered wheel loads alone: a wheel force or moment, except
        the vertical force of a car without height lasers (its heights come from that load). The estimator takes
        such a channel through a delay and a low-pass, both of unit gain at 0 Hz, into the loads: its offset moves
        them by itself, the joints not at all (tests/pipeline/test_sensor_offsets.py checks it against the full
        pass)."""
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
    from ..vehicle.dampers import KneeSearch  # start-up: a car's alone (CarSetup.__init__)
    from ..vehicle.tire_curves import SampleParts, sample_steps, tire_samples
    from .car import knee_rows

    setup = car_setup(job.cfg)
    samples: dict[str, Channel] | None = None if job.health is None else {}
    channels = read_segment(job.window, file_samples=samples)
    # its stamps in memory (the health's): a file's clock's from the blocks the read just decoded
    w = clock_read(job.window)
    health = None
    if samples is not None and job.hac is None and not job.knees:  # the segment's data health, its samples then let go
        health = {w.test: segment_health(w, setup.vehicle, job.health, samples, channels)}
    samples = None  # the file's samples (the health scan's alone) not held through the segment's work
    lags = dict(job.lags)
    compensated = setup.compensated(channels, w.fs, lags)
    joints = setup.joints(channels, w.fs, lags, compensated)
    traj = joints.traj
    sys = setup.rows(traj, w.fs, job.instruments)
    if job.hac is not None:  # a HAC covariance's second pass: the rows' scores at the estimate, nothing else
        C = None
        if w.test in job.hac.profile:  # the test's offsets estimated: the scores of the profiled rows need C
            h = job.hac
            zeros = OffsetFactors(h.columns, h.known_columns, h.known_values, setup.a_priori[h.columns])
            C = offset_residuals(setup, channels, w.fs, lags, compensated, joints, sys, job.offsets,
                                 zeros.point(sys.W.shape[1]))
        return Partial(StreamingLS(setup.names), hac=_scores(job.hac, sys, w.test, C))
    if job.knees:
        search = KneeSearch()
        knee_rows(sys, traj, w.fs, setup.settings.decimate, setup.conditioning.cutoff, search,
                  setup.vehicle.knees_from_data)
        return Partial(StreamingLS(setup.names), knees=search)
    ls = StreamingLS(setup.names)
    ls.add(sys.W, sys.Y, sys.groups)
    part = Partial(ls, rows={w.test: sys} if job.keep_rows else {})
    if health is not None:  # the data health of the part of the test this segment answers for
        part.health = health
    if setup.settings.tire_curves and job.instruments is None and not job.lags:
        step = job.tire_step or sample_steps([(w.fs, [len(w.clock)])], setup.conditioning.cutoff)[0]
        part.tires = SampleParts((tire_samples(setup.model, traj, w.test, setup.vehicle.geometry.wheel_radius,
                                               w.first / w.fs, step),))
    if not job.offsets:  # the main pass is the offsets' alone from here: not held beside the passes below
        joints = compensated = traj = None
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
        moved = None
        if job.propagate_offsets or not job.estimate_offsets:
            part.bias = ls.bias_accumulator()
            moved = offset_changes(setup, channels, w.fs, lags, compensated, joints, sys, job.offsets,
                                   job.instruments)
            part.bias.add_many([f"{w.test}: {q}" for q, _ in job.offsets], sys.W, sys.Y, [m[0] for m in moved],
                               [m[1] for m in moved], sys.groups, job.weight,
                               *(() if job.instruments is None else (sys.Z, [m[2] for m in moved])))
        if job.estimate_offsets:
            columns, known, values = _columns(ls)
            part.zeros = OffsetFactors(columns, known, values, setup.a_priori[columns])
            # the offsets' columns from the changes when the propagation made them, else from the moved residuals
            C = (part.zeros.offset_columns([m[0] for m in moved], [m[1] for m in moved], len(sys.Y))
                 if moved is not None else offset_residuals(setup, channels, w.fs, lags, compensated, joints, sys,
                                                            job.offsets, part.zeros.point(sys.W.shape[1])))
            part.zeros.add_columns(w.test, [q for q, _ in job.offsets], sys.W, sys.Y, C, sys.groups)
            if job.noise:
                part.noise = _noise_scores(setup, job, sys, part.zeros, C, lags)
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


def _noise_scores(setup: CarSetup, job: CarJob, sys: GroupedSystem, zeros: OffsetFactors, C: np.ndarray,
                  lags: Mapping[str, float]) -> NoiseScores:
    """Each noise draw's rows (job.noise: the same window of its file) on the noise-free rows' kept rows: their
    residual at x0 less the noise-free one, row by row, scored by the noise-free [C | W] (`NoiseScores`; C: the
    offsets' columns of sys)."""
    fs = job.window.fs

    def residual(s: GroupedSystem) -> np.ndarray:
        return s.Y - s.W[:, zeros.known_columns] @ zeros.known_values - s.W[:, zeros.columns] @ zeros.x0

    rate = fs / math.prod(setup.settings.decimate)  # the rows' rate: stamps in rows
    out = NoiseScores(job.noise_lag)
    CW, stamps, clean = np.column_stack([C, sys.W[:, zeros.columns]]), np.rint(np.asarray(sys.t) * rate), residual(sys)
    for d, window in enumerate(job.noise):
        noisy = setup.rows(setup.trajectory(read_segment(window), fs, lags), fs, job.instruments, keep=sys.kept)
        out.add(job.window.test, stamps, sys.groups, CW, residual(noisy) - clean, d)
    return out


def offset_changes(setup: CarSetup, channels: dict[str, np.ndarray], fs: float, lags: Mapping[str, float],
                   compensated: dict[str, np.ndarray], joints: JointsPass, sys: GroupedSystem,
                   offsets: Sequence[tuple[str, float]], instruments: dict[str, float] | None = None,
                   one_pass: bool = True) -> list[tuple[np.ndarray, np.ndarray, np.ndarray | None]]:
    """(ΔW, ΔY, ΔZ) of the kept rows `sys` (of joints.traj, of these channels) for each (channel, one-σ zero
    offset SI): the rows of the trajectory with that channel's zero moved, less sys's (ΔW None where W does not
    move, ΔZ None without instruments); the offset's exact effect, not a linearisation (the attitude's rows are
    curved enough for a one-σ gyro or inclinometer offset to move them 0.02 to 0.3 % off their tangent).

    A wheel-load channel's offset moves the filtered loads alone (`CarSetup.load_only`): ΔY is the rows' change
    per unit load times it, for all of them in one decimation (`CarSetup.load_changes`), unless the tree has load
    terms (a column of W built from the loads: then as the others). The others' moved
    trajectories: a camera's moves what its range clips (the whole pass); the inertial unit's, the lasers' and the
    velocity sensor's run again only the estimator's stages they reach (`JointsPass.moved`; an accelerometer's and a
    laser's move the joints linearly: b times the pass's response to a unit offset, made once); any other's goes
    through the whole estimator but not through the sensor dynamics' undoing again (affine with unit gain at 0 Hz:
    the offset passes through it as is). Their rows come from one evaluation of the equations and one decimation
    for all of them (`CarSetup.moved_rows`). With instruments (the loads move the simulated suspensions too), or
    one_pass=False, each moved trajectory's rows through `CarSetup.rows` in turn; one_pass=False, the trajectories
    too through the whole estimator (`CarSetup.trajectory`): the old way, the oracle the tests compare with."""
    traj = joints.traj
    if not one_pass or instruments is not None:  # the loads move the instruments' simulated suspensions: rows
        out = []
        for t in _moved_trajectories(setup, channels, fs, lags, compensated, joints, offsets, one_pass):
            p = setup.rows(t, fs, instruments, keep=sys.kept)
            out.append((p.W - sys.W, p.Y - sys.Y, None if instruments is None else p.Z - sys.Z))
        return out
    # the loads' rows by their change per unit load where W does not depend on them: a tree with load terms (a
    # tire's -ktfy Fy² q) has a column built from them
    linear = not setup.tree.load_terms
    loads = [(q, b) for q, b in offsets if linear and setup.load_only(q)]
    others = [(q, b) for q, b in offsets if not (linear and setup.load_only(q))]
    changes = {}
    for (q, _), dY in zip(loads, setup.load_changes(traj, loads, fs, sys.kept), strict=True):
        changes[q] = (None, dY, None)  # W does not depend on the loads
    trajs = _moved_trajectories(setup, channels, fs, lags, compensated, joints, others, one_pass)
    for (q, _), (W, Y) in zip(others, setup.moved_rows(traj, trajs, fs, sys.kept), strict=True):
        changes[q] = (W - sys.W, Y - sys.Y, None)
    return [changes[q] for q, _ in offsets]


def offset_residuals(setup: CarSetup, channels: dict[str, np.ndarray], fs: float, lags: Mapping[str, float],
                     compensated: dict[str, np.ndarray], joints: JointsPass, sys: GroupedSystem,
                     offsets: Sequence[tuple[str, float]], x: np.ndarray) -> np.ndarray:
    """C (rows, m): the change of the kept rows' residual Y − W x (x: a value per column of W,
    `OffsetFactors.point`) for each (channel, one-σ zero offset SI): the offsets' columns of their estimate
    (C_k = ΔY_k − ΔW_k x0, `estimation.offsets`) from `offset_changes`' moved trajectories without ΔW: a wheel load's
    ΔY by its change per unit load; the others' from their residuals' changes, W x formed before the decimation
    (`car_moved_rows` with x: one column per equation decimated, not W's, for all of them in one call). Equal to
    `offset_columns` of `offset_changes` to round-off."""
    from .car import coarse_step  # start-up: a car's alone (CarSetup.__init__)

    linear = not setup.tree.load_terms
    loads = [(q, b) for q, b in offsets if linear and setup.load_only(q)]
    others = [(q, b) for q, b in offsets if not (linear and setup.load_only(q))]
    index = {q: k for k, (q, _) in enumerate(offsets)}
    C = np.empty((len(sys.Y), len(offsets)))
    for (q, _), dY in zip(loads, setup.load_changes(joints.traj, loads, fs, sys.kept), strict=True):
        C[:, index[q]] = dY  # W does not depend on the loads
    if others:
        # the staged passes' trajectories on the equations' samples alone (their whole-rate arrays never made)
        every = coarse_step(joints.traj, fs, setup.settings.decimate, setup.conditioning.cutoff)[0]
        trajs = _moved_trajectories(setup, channels, fs, lags, compensated, joints, others, True, every)
        for (q, _), r in zip(others, setup.moved_rows(joints.traj, trajs, fs, sys.kept, x), strict=True):
            C[:, index[q]] = r
    return C


def _moved_trajectories(setup: CarSetup, channels: dict[str, np.ndarray], fs: float, lags: Mapping[str, float],
                        compensated: dict[str, np.ndarray], joints: JointsPass, offsets: Sequence[tuple[str, float]],
                        staged: bool, every: int = 1) -> Iterator[CarTrajectory | CoarseTrajectory]:
    """The trajectory with each offset's channel moved (`offset_changes`), one at a time (each is the size of the
    segment's); staged: through the stages it reaches only, where it can (`JointsPass.moved`, on every `every`-th
    sample)."""
    for q, b in offsets:  # each sensor's zero moved by its standard deviation (SI), rows unchanged
        if setup.load_only(q):  # the joints unchanged: a tenth of the work (CarSetup.load_only)
            yield shifted_load(joints.traj, q, b)
        elif q.startswith(CAMERAS):  # a camera's offset moves what its range clips: the whole pass
            yield setup.trajectory({**channels, q: channels[q] + b}, fs, lags)
        elif staged and joints.movable(q):
            yield joints.moved(q, b, every)
        else:  # undoing the dynamics is affine with unit gain at 0 Hz: the offset passes through it as is
            yield setup.trajectory({**channels, q: channels[q] + b}, fs, lags, {**compensated, q: compensated[q] + b})


def sensor_errors(channels: dict[str, np.ndarray], suite, seed: int, fs: float) -> tuple[dict[str, np.ndarray], ...]:
    """One draw of the sensors' errors on the channels present (SI, logger at fs Hz), and its opposite: white
    noise of each channel's accuracy held at the sensor's own rate, as the suite's chain holds it
    (`vehicle.sensors.corrupt`: a 125 Hz unit's noise is 5 samples long, so more of it passes the low-pass), and
    its zero offset (bias) with a random sign (channel units; estimation/fit.py says why)."""
    from ..vehicle.sensors import sample_and_hold  # start-up: a car's alone (CarSetup.__init__)

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
    from ..vehicle.sensors import CORNER_TAGS, WFT_COMPONENTS  # start-up: a car's alone (CarSetup.__init__)

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
    keep_rows: bool = False  # return the rows themselves (each test's first chunk: the report's plots)
    health: bool = False  # gather the joints' data health of the chunk's own samples (pipeline.health.gather_joints)
    hac: HACSums | None = None  # the second pass of a HAC covariance: the rows' scores at this estimate, alone
    threads: int = 1  # the chunk's W blocks done on this many threads at once (`robot.chunk_rows`)
    in_order: bool = False  # its test's chunks read one after another, by one reader (the block cache keeps less)
    # in_order's chunks done one after another by this process: (test, a chunk's start) -> the first decimation
    # stage's outputs the chunk before made on its span (`robot.chunk_rows`' before and after), one at a time
    handoff: dict[tuple[str, int], FirstStage] | None = field(default=None, compare=False, repr=False)

    @property
    def test(self) -> str:
        return self.window.test


class RobotSetup:
    """A robot config's model and base parameters, built once per process."""

    def __init__(self, cfg: IdentifyConfig) -> None:
        self.joints = config_joints(cfg, load_model(cfg.model).tree)
        self.model = Model(self.joints.tree)
        self.base: BaseParameters = self.model.base_parameters()
        self.a_priori = self.base.values(self.model.parameters)  # the model file's values of the base parameters
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


@dataclass
class RobotChunkRead:
    """A chunk's samples read and filtered (`read_robot_chunk`), what its rows need before the model's W."""

    window: RobotTestPlan  # the job's, its clock read
    tau: np.ndarray  # (samples, frames): its torques
    gains: np.ndarray | None  # (samples, frames, k): the drive gains' columns when identified
    health: dict  # test -> the joints' data health of the positions (pipeline.health.gather_joints)
    filtered: tuple[np.ndarray, np.ndarray]  # `robot.chunk_filtered`'s (qf, speed)
    buffers: list[np.ndarray]  # `robot.chunk_buffers`: the chunk's W block buffers, made by the thread that read it


def read_robot_chunk(job: RobotJob) -> RobotChunkRead:
    """The chunk's samples read, through the channel map, drive gains and transmission, their positions' data health
    gathered, filtered (`robot.chunk_filtered`): the first stage of `reduce_robot_chunk`, no model's W (the next
    chunk's, run on a second thread while this one's W blocks run: `schedulers.Staged`)."""
    setup = robot_setup(job.cfg)
    w = clock_read(job.window)  # its stamps read once (a file's clock is not held by the plan)
    arrays = read_robot_window(w, 0, w.samples)
    if job.in_order:  # the next chunk's window begins chunk_pad before this chunk's end: the blocks before it go
        k = min(max(0, job.chunk[1] - chunk_pad(w.fs, job.cfg.conditioning) - w.first), w.samples - 1)
        for index in {id(x): x for x in w.indexes.values()}.values():
            forget_blocks_before(index, float(w.clock[k]) - w.margin)
    columns, n = setup.joints.columns, setup.model.n
    q, tau, gains = driven(job.cfg, arrays["q"], arrays[w.effort], len(columns))
    del arrays
    # the joints' data health: the positions here, the torques from the rows (pipeline.health)
    health = {w.test: gather_joints(job.cfg, setup.model, columns, w.clock, w.fs, w.first, job.chunk, job.n_samples,
                                    q, tau, gains, torques=False)} if job.health else {}
    q, tau = to_frames(q, columns, n), to_frames(tau, columns, n)
    if gains is not None and len(columns) != n:  # the joints without data: no rows, zero columns
        full = np.zeros((gains.shape[0], n, gains.shape[2]))
        full[:, np.asarray(columns) - 1, :] = gains
        gains = full
    filtered = chunk_filtered(job.cfg.conditioning, q, w.fs, w.first, job.chunk, job.n_samples)
    del q  # the raw positions not held once filtered (3.7 MB of the Panda's 55,600-sample chunks)
    # the W block buffers made last, here: in the heap this read's transients left free (this thread's glibc arena),
    # not beside them in the calling thread's (~24 MB of the Panda's, two threads)
    buffers = chunk_buffers(setup.base, job.cfg.conditioning, w.fs, job.chunk, job.n_samples,
                            setup.model.tree.equations, 0 if gains is None else gains.shape[2], job.threads)
    return RobotChunkRead(w, tau, gains, health, filtered, buffers)


def robot_chunk_partial(job: RobotJob, read: RobotChunkRead, ready: Callable[[], None] | None = None) -> Partial:
    """The chunk's read samples (`read_robot_chunk`) to its decimated rows (with the drive gains' columns when they
    are identified, and the test's payload torque taken off), reduced to their per-joint factors (every column:
    `StreamingLS.reparametrised` applies the known values when solving): the second stage of `reduce_robot_chunk`.
    ready: called once the chunk's W blocks are done and freed (`schedulers.Staged`: the next chunk read then)."""
    setup = robot_setup(job.cfg)
    w, health, gains = read.window, read.health, read.gains
    box, after = job.handoff, None
    before = None if box is None else box.pop((w.test, job.chunk[0]), None)
    if box is not None:
        box.clear()  # nothing stale held (a test's first chunk: the map's chunks are in order)

        def after(stage: FirstStage, key: tuple[str, int] = (w.test, job.chunk[1])) -> None:
            box[key] = stage

    sys = chunk_rows(setup.model, setup.base, job.cfg.conditioning, None, read.tau, w.fs, w.first, job.chunk,
                     job.n_samples, gains=gains, payload=setup.payloads.get(w.test), threads=job.threads,
                     filtered=read.filtered, blocks_done=ready, buffers=read.buffers, before=before, after=after)
    if job.hac is not None:
        return Partial(StreamingLS(setup.names), hac=_scores(job.hac, sys, w.test))
    if health and gains is None:
        health[w.test].add_rows(sys, setup.joints.columns, setup.a_priori)
    ls = StreamingLS(setup.names)
    ls.add(sys.W, sys.Y, sys.groups)
    return Partial(ls, rows={w.test: sys} if job.keep_rows else {}, health=health)


# The chunk's samples read, through the channel map, drive gains and transmission, to its decimated rows (with the
# drive gains' columns when they are identified, and the test's payload torque taken off), reduced to their
# per-joint factors: a function of a job, whose two stages this machine's scheduler overlaps across chunks.
reduce_robot_chunk: Staged[RobotJob, RobotChunkRead, Partial] = Staged(read_robot_chunk, robot_chunk_partial)


def _scores(empty: HACSums, sys: GroupedSystem, test: str, C: np.ndarray | None = None) -> HACSums:
    """A chunk's or segment's rows added to a HAC pass's sums: each group's rows are in time order, the test is the
    stream (lags never cross tests); C: the rows' offsets' columns where the test's offsets were estimated."""
    sums = empty.empty()
    sums.add(sys.W, sys.Y, sys.groups, test, C, sys.t)
    return sums
