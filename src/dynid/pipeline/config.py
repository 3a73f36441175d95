"""The identification config (TOML): model, tests and their roles, channels, conditioning, method.

    [model]                          # one of:
    example = "tx40"                 # a shipped robot model,
                                     # or file = "robot.toml" (a robot model file, relative to this config),
                                     # or template = "peugeot406" (a car: see below),
                                     # or vehicle = "peugeot406" (a car described by a vehicle file: a shipped
                                     # vehicle's name, or a path ending in .toml relative to this config)
    joints = ["joint1", "joint2"]    # optional, a robot: the identified joints (the model file's [joints] names;
                                     # the others are held still at 0). Without it, data that lack the joints
                                     # others mimic (a gripper) hold those still, and say so

    [[tests]]
    name = "exciting trajectory"
    role = "identify"                # or "validate" (cross-validation only)
    fs = 5000.0                      # sample rate when the files have no time column (with one: optional,
                                     # checked against it)
    start = 2.0                      # optional: s, the part of the test used (the files' time base)
    end = 58.0
    max_gap = 10                     # optional: longest hole in the time stamps, sample periods (default 10)
    files = { q = "pos.csv", tau = "torques.csv" }   # or current = "currents.csv" (with [channels] current)
                                     # or file = "run.mcap": one file holding q and tau. A ROS 2 bag (a folder
                                     # with metadata.yaml, or its .db3/.mcap) reads sensor_msgs/JointState and
                                     # takes topic = "/joint_states" (default: the bag's only JointState topic)
                                     # and ignore_joints = ["gripper"] (joints the model does not have); its q
                                     # and tau are each model joint's position and effort, matched by the names
                                     # of the model's [joints] table: [channels] is not needed for it
    payload = { mass_kg = 2.0, com_m = [0, 0, 0.05], inertia_kg_m2 = [0.004, 0.004, 0.002, 0, 0, 0] }
                                     # optional: a known payload fixed to the last link during this test (its
                                     # centre of mass in that link's frame; its inertia about the centre of mass,
                                     # [xx, yy, zz, xy, xz, yz]; frame = 6 names another link): its torque is known

    [channels]                       # quantity (q, tau or current) -> channels, one per joint, with the file's unit
    q = { channels = ["Joint_1", "Joint_2"], unit = "rad" }
    tau = { channels = ["Joint_1", "Joint_2"], unit = "N.m" }
                                     # or current = { channels = ["I_1", "I_2"], unit = "A" }: motor currents

    # [drive]                        # with current channels: the motor torque is gain x current (tau_m = g i,
    # gains = [0.35, 0.35]           # N.m/A motor side, one per current channel; [transmission] tau maps it)
    # identify_gains = true          # optional: the gains are parameters (the values above their a priori); or
                                     # the channels whose gain is identified, identify_gains = ["I_1"]. Every gain
                                     # identified needs a test with a known payload (the scale is free otherwise)

    [transmission]                   # optional: joint = matrix @ channels (+ offset)
    q = [["1/32", 0], [0, "1/32"]]
    q_offset = [0, "-pi/2"]
    tau = [[32, 0], [0, 32]]

    [conditioning]
    cutoff = 25.0                    # Hz (0.01 to below fs/2), zero-phase Butterworth on positions
    order = 4                        # a whole number from 1 to 20
    border = 0.1                     # s trimmed at each end (default: the filter transient)
    decimate = [10, 10]              # whole factors >= 2, applied in turn (or one: decimate = 10)
    min_speed = { 1 = 0.05 }         # rows of joint 1 dropped where |qd1| < 0.05

    [identification]
    method = "wls"                   # or "ols", or "wls-pc": WLS with every body physically consistent
                                     # (needs pip install cvxpy clarabel; docs/robot.md)
    known = { IA1 = 0.36 }           # fixed parameters (SI, within ±1e9): their contribution moves to Y
    poor_factor = 20.0               # the paper's rule: %σ > 20 x the smallest %σ ("paper rule" column)
    flag_percent = 2.5               # "uncertain": total σ above 2.5 % of the parameter's scale (the flag to act on)
    cov_type = "nonrobust"           # σ² (WᵀW)⁻¹ (paper eq. (7)); "hac": Newey–West per equation group (the
    hac_lags = "auto"                # decimated rows are autocorrelated; ols or wls), lags floor(4 (n_g/100)^(2/9))
                                     # or a whole number of rows: one more pass over the data; "hac-groupsum":
                                     # the groups' scores at a sample summed first (Driscoll–Kraay: one sensor's
                                     # noise in several groups' rows); a car's estimated offsets profiled out
    data_health = "stop"             # a data health error (a clipped, dead or swapped channel) stops the run;
                                     # "warn": said, kept in results.json, the run goes on (docs/tutorial.md)

    [reference]                      # optional: a published base-parameter table to compare with
    file = "published.csv"
    names = { Izz = "ZZ" }
    combinations = { fvm6 = "1024*fvm6" }

A car ([model] template = "peugeot406", or vehicle = "name" or "my_car.toml": the template with that
vehicle file's geometry, tables and values) reads one logger file per test with the channels of
`dynid.vehicle.sensors`, estimates the 42 joints from them and assembles the paper's 14 equations.
Its [[tests]] take name, role, fs (optional, as above), `file = "sine.csv"` (CSV, Parquet, MATLAB or
MDF4; channels at several rates are interpolated onto the fastest one's clock), optionally start, end
and max_gap (as a robot's: the part of the test used, s in the file's time base; the longest hole in its
time stamps, sample periods) and `truth = "sine.json"` (the simulator's sidecar with the true
parameters); [transmission] and [reference] are the robot's only, [uncertainty] the car's only:

    [channels]                       # only where the file's names differ from the suite's: the channels of
    imu_yaw_rate = { channel = "GyroZ", unit = "deg/s" }   # the vehicle's own suite ([model] vehicle's
                                     # [sensors]: a car with a GNSS/INS maps gnss_vx, gnss_vy, not correvit_*)

    [conditioning]
    cutoff = 4.0                     # Hz, on every signal (the paper: ~3 Hz, order 5-8)
    order = 4
    decimate = [5, 10]
    attitude_crossover = 0.2         # Hz: inclinometers below, integrated gyros above
    segment = 60.0                   # s: long tests are processed in overlapping segments (bounded memory)
    compensate_delays = true         # undo each channel's declared dynamics (the vehicle file's
                                     # [sensors.dynamics], default Table 1); false: none, whatever is declared
    min_speed = 0.01                 # m/s: damper rows left out where |clearance rate| is below (dry
                                     # friction is undefined at reversal); or { 9 = 0.01, 27 = 0.02 }; 0: none;
                                     # more where the friction builds up over a wider range of rates
    friction_lowpass = true          # the dampers' dry-friction columns s(rate) through the same low-pass
                                     # (cutoff, order) as the loads, before the parallel decimation; false: not

    [identification]                 # known, poor_factor and flag_percent as for a robot, and:
    method = "wls"                   # or "iv": IDIM-IV, instruments from the suspensions simulated with the
    iv_passes = 2                    # last estimate, driven by the measured loads (vehicle.instruments)
    base = "generic"                 # "generic" (the paper's 48) or "car" (44, see vehicle.equations)
    aero = true                      # the aerodynamic wrench of the template's tables in Y
    tire_curves = true               # the tires' cornering and slip stiffness and lateral Magic Formula from
                                     # the wheel wrenches and slips (vehicle.tire_curves); false: not fitted

    [uncertainty]                    # optional: the sensors' zero offsets propagated to the estimates (%σ
                                     # total). Default: the vehicle's sensor suite's (each channel's `bias`);
    offsets = { imu_az = 0.01, laser_height_rl = 0.5 }   # a table replaces them (1 sigma, in the suite's unit
                                     # of each channel: docs/vehicle.md); offsets = "none" (or {}) turns them off
    segments = 2                     # segments per test on which their effect is evaluated
    estimate = true                  # each test's offsets estimated with the parameters, their σ as the prior
                                     # (estimation/offsets.py; every segment evaluated); false: propagated only

Either kind may say where its work runs (the command line's --scheduler and --workers override it):

    [compute]
    scheduler = "local"              # a Dask LocalCluster on this machine, or a Dask scheduler's address
                                     # ("tcp://10.0.0.5:8786"; needs pip install distributed); default: this
                                     # machine's threads. The workers read the files themselves: give paths
                                     # every worker reaches (a shared file system)
    workers = 2                      # threads, or a LocalCluster's single-threaded worker processes

Every section is strict: an unknown section or key (in every [[tests]] entry too) is an error naming
the file, the section, the key and the nearest valid key; so is a value of the wrong type. Every
error names the config file and the key, and says what is expected.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..car_frames import DAMPERS
from ..estimation.errors import IdentificationError
from ..estimation.method import Covariance, Method
from ..io.rosbag_format import is_bag, is_bag_folder
from ..model import ModelError
from ..model.files import did_you_mean, parse_number, read_toml, unknown_keys
from ..shipped import CAR_TEMPLATE, DEMO_VEHICLE
from .reference import parse_combination, reference_text
from .robot import Conditioning
from .schedulers import address_problem


class ConfigError(ModelError):
    """A config that cannot be used, naming the file and key."""


@dataclass(frozen=True)
class TestSpec:
    name: str
    role: str
    files: dict[str, Path]
    fs: float | None
    truth: Path | None = None
    start: float | None = None  # s, in the files' time base: the part of the test used
    end: float | None = None
    max_gap: float = 10.0  # sample periods: a longer hole in the time stamps is refused
    payload: Payload | None = None  # a robot test's known payload on its last link
    topic: str | None = None  # a ROS 2 bag's JointState topic (None: the bag's only one)
    ignore_joints: tuple[str, ...] = ()  # a bag's joints the model does not have, left out


@dataclass(frozen=True)
class Payload:
    """A known rigid payload fixed to a link during a test (Gautier's method for drive gains): its mass (kg), its
    centre of mass (m, in the link's frame) and its inertia about the centre of mass (kg.m2, in the link's axes,
    [xx, yy, zz, xy, xz, yz]); frame: the link's frame (None: the last joint's link)."""

    mass: float
    com: tuple[float, float, float]
    inertia: tuple[float, float, float, float, float, float]
    frame: int | None = None

    def standard(self) -> np.ndarray:
        """(10,) its standard parameters about the link frame's origin, in Khalil's order XX XY XZ YY YZ ZZ MX MY MZ M
        (the parallel-axis theorem: I_O = I_G + m (|c|^2 1 - c c^T))."""
        xx, yy, zz, xy, xz, yz = self.inertia
        c = np.array(self.com)
        I_o = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]) + self.mass * (c @ c * np.eye(3) - np.outer(c, c))
        return np.array([I_o[0, 0], I_o[0, 1], I_o[0, 2], I_o[1, 1], I_o[1, 2], I_o[2, 2], *(self.mass * c),
                         self.mass])


@dataclass(frozen=True)
class DriveSpec:
    """[drive]: the current channels' gains (N.m/A, motor side, one per channel in [channels] current's order) and
    which are identified (their gains the a priori values)."""

    gains: tuple[float, ...]
    identify: tuple[bool, ...]

    @property
    def identified(self) -> bool:
        return any(self.identify)


@dataclass(frozen=True)
class ChannelSpec:
    channels: tuple[str, ...]
    unit: str | None
    unit_over_file: bool = False  # the config's unit wins over a file that says another (its header is wrong)


@dataclass(frozen=True)
class CarSettings:
    """The car's conditioning and options (see the module doc)."""

    cutoff: float = 4.0
    order: int = 4
    decimate: tuple[int, ...] = (5, 10)
    attitude_crossover: float = 0.2
    segment: float = 60.0
    compensate_delays: bool = True
    min_speed: dict[int, float] = field(default_factory=lambda: dict.fromkeys(DAMPERS, 0.01))
    friction_lowpass: bool = True  # the dry-friction columns through the loads' low-pass (pipeline.car.car_system)
    base: str = "generic"
    aero: bool = True
    # channel -> 1-sigma zero offset in the suite's unit of the channel (the config's [uncertainty] offsets);
    # None: the vehicle's sensor suite's (each channel's bias), {}: none
    offsets: dict[str, float] | None = None
    offset_segments: int = 2
    estimate_offsets: bool = True  # each test's offsets estimated with the parameters (estimation.offsets)
    iv_passes: int = 2  # method = "iv": simulate with the last estimate and re-estimate, this many times
    tire_curves: bool = True  # fit the tire characteristics after the identification (vehicle.tire_curves)
    # the damper curves' knees chosen from the data ((damper, v-, v+) m/s, pipeline.run): the vehicle file's
    # dampers without knees (Vehicle.knees_from_data) take these; () until the search ran
    knees: tuple[tuple[int, float, float], ...] = ()


@dataclass(frozen=True)
class IdentifyConfig:
    path: Path
    model: str | Path
    tests: tuple[TestSpec, ...]
    channels: dict[str, ChannelSpec]
    transmission: dict[str, np.ndarray] = field(default_factory=dict)
    conditioning: Conditioning = field(default_factory=Conditioning)
    method: Method = Method.WLS  # a config's text ("wls", ...) is resolved here, once (`estimation.method`)
    covariance: Covariance = field(default_factory=Covariance)  # cov_type and hac_lags, parsed once
    known: dict[str, float] = field(default_factory=dict)
    poor_factor: float = 20.0
    flag_percent: float = 2.5
    data_health: str = "stop"
    reference: dict[str, Any] | None = None
    car: CarSettings | None = None
    # [model] vehicle: a vehicle file (resolved Path: the value ended in .toml) or a shipped vehicle's name
    vehicle: str | Path | None = None
    joints: tuple[str, ...] | None = None  # [model] joints: a robot's identified joints, by name
    scheduler: str | None = None  # [compute]: None (this machine's threads), "local" or a Dask scheduler's address
    workers: int | None = None
    drive: DriveSpec | None = None  # a robot logging motor currents: [drive] gains (identified or known)

    def __post_init__(self) -> None:
        # the one place a method's text becomes a `Method` (dataclasses.replace(cfg, method="ols") included)
        try:
            object.__setattr__(self, "method", Method.parse(self.method, f"{self.path}: [identification] method"))
        except IdentificationError as exc:
            raise ConfigError(str(exc)) from None

    @property
    def kind(self) -> str:
        return "car" if self.car is not None else "robot"

    @property
    def effort(self) -> str:
        """The robot's effort quantity: "current" (motor currents, with [drive] gains) or "tau" (joint torques)."""
        return "current" if "current" in self.channels else "tau"


Err = Callable[[str, str], ConfigError]  # (where, e.g. "[model]", message) -> the error naming the file

# the keys each section reads; a car and a robot read different ones (see the module doc)
_TOP = ("model", "tests", "channels", "transmission", "conditioning", "identification", "reference", "uncertainty",
        "compute", "drive")
_COMPUTE_KEYS = ("scheduler", "workers")
_MODEL_KEYS = ("example", "file", "template", "vehicle")
_MODEL_OPTIONS = ("joints",)  # a robot's: the identified joints, by name (the others are held still)
_ROBOT_TEST_KEYS = ("name", "role", "fs", "files", "file", "topic", "ignore_joints", "start", "end", "max_gap",
                    "payload")
_CAR_TEST_KEYS = ("name", "role", "fs", "file", "truth", "start", "end", "max_gap")
_ROBOT_QUANTITIES = ("q", "tau", "current")
_EFFORTS = ("tau", "current")  # a robot test's effort channels: joint torques, or motor currents with [drive] gains
_DRIVE_KEYS = ("gains", "identify_gains")
_PAYLOAD_KEYS = ("mass_kg", "com_m", "inertia_kg_m2", "frame")
_TRANSMISSION_KEYS = ("q", "q_offset", "tau")
_ROBOT_CONDITIONING = ("cutoff", "order", "border", "decimate", "min_speed")
_CAR_CONDITIONING = ("cutoff", "order", "decimate", "attitude_crossover", "segment", "compensate_delays", "min_speed",
                     "friction_lowpass")
_ROBOT_IDENTIFICATION = ("method", "known", "poor_factor", "flag_percent", "data_health", "cov_type", "hac_lags")
_CAR_IDENTIFICATION = ("method", "cov_type", "hac_lags", "base", "aero", "known", "poor_factor", "flag_percent",
                       "iv_passes", "data_health",
                       "tire_curves")
DATA_HEALTH = ("stop", "warn")  # what a data health error does: stop the run (default), or be said and kept
_REFERENCE_KEYS = ("file", "names", "combinations")
_UNCERTAINTY_KEYS = ("offsets", "segments", "estimate")
_FOR_A_CAR = "a car's key: [model] template or vehicle"


def _keys(table: dict, valid: Sequence[str], where: str, err: Err, notes: dict[str, str] | None = None) -> None:
    unknown = [k for k in table if k not in valid]
    if unknown:
        raise err(where, unknown_keys(unknown, valid, notes=notes))


def _test_label(i: int, t: object) -> str:
    name = t.get("name") if isinstance(t, dict) else None
    return f'[[tests]] #{i} ("{name}")' if isinstance(name, str) else f"[[tests]] #{i}"


def load_config(path: str | Path) -> IdentifyConfig:
    path = Path(path)
    data = read_toml(path, "config", ConfigError)
    here = path.resolve().parent

    def err(where: str, msg: str) -> ConfigError:
        return ConfigError(f"{path}: {where} {msg}")

    _sections(data, path)
    model, vehicle = _model(data.get("model", {}), here, err)
    is_car = vehicle is not None or "template" in data.get("model", {})
    if "uncertainty" in data and not is_car:
        raise err("[uncertainty]", "sensor offsets are propagated for the car template only ([model] template or "
                                   "vehicle); remove the section")
    for name in ("transmission", "reference", "drive"):
        if name in data and is_car:
            raise err(f"[{name}]", "is for a robot's joint files; a car reads its sensor suite's channels: remove "
                                   "the section")
    _keys(data.get("conditioning", {}), _CAR_CONDITIONING if is_car else _ROBOT_CONDITIONING, "[conditioning]",
          err, {"border": "a robot's key: a car's borders are its filters' transients"} if is_car
          else dict.fromkeys(set(_CAR_CONDITIONING) - set(_ROBOT_CONDITIONING), _FOR_A_CAR))
    ident = data.get("identification", {})
    _keys(ident, _CAR_IDENTIFICATION if is_car else _ROBOT_IDENTIFICATION, "[identification]", err,
          None if is_car else dict.fromkeys(set(_CAR_IDENTIFICATION) - set(_ROBOT_IDENTIFICATION), _FOR_A_CAR))
    # a car's [channels] and [uncertainty] name channels of the suite its vehicle has (read only when named)
    suite = _VehicleChannels(vehicle or DEMO_VEHICLE, err) if is_car else None
    car = _car_settings(data, err, suite) if is_car else None
    channels_raw = data.get("channels", {})
    effort = "current" if isinstance(channels_raw, dict) and "current" in channels_raw else "tau"
    tests = _tests(data.get("tests", []), here, is_car, err, effort)
    channels = _channels(data.get("channels", {}), err, suite)
    transmission = _transmission(data.get("transmission", {}), err)
    drive = None if is_car else _drive(data, channels, tests, err)
    cond = Conditioning() if is_car else _robot_conditioning(data.get("conditioning", {}), err)

    text = ident.get("method", "wls")
    if not isinstance(text, str) or text.lower() not in [m.value for m in Method]:
        raise err("[identification]", f"method = {text!r}; use \"ols\", \"wls\", \"iv\" (a car) or \"wls-pc\" "
                  "(a robot)")
    method = Method(text.lower())
    if method is Method.WLS_PC and car is not None:
        raise err("[identification]", "method = \"wls-pc\" (physically consistent WLS) is for a robot; a car's "
                  "identification runs \"wls\", \"ols\" or \"iv\"")
    if method is Method.IV and car is None:
        raise err("[identification]", "method = \"iv\" takes its instruments from a simulation of the car's "
                  "suspensions driven by the measured loads; a robot has none here: use \"wls\"")
    try:
        covariance = Covariance.parse(ident.get("cov_type", "nonrobust"), ident.get("hac_lags"), "")
    except IdentificationError as exc:
        raise err("[identification]", str(exc)) from None
    if covariance.hac and method not in (Method.OLS, Method.WLS):
        raise err("[identification]", f"cov_type = \"{covariance.kind.value}\" is for method = \"ols\" or \"wls\" "
                  f"(its sandwich is least squares'), not {method.value!r}: use cov_type = \"nonrobust\" with it")
    return IdentifyConfig(
        path=path, model=model, tests=tests, channels=channels, transmission=transmission,
        conditioning=cond, method=method, covariance=covariance, known=_known(ident, err),
        poor_factor=_positive(ident, "poor_factor", 20.0, err), flag_percent=_positive(ident, "flag_percent", 2.5, err),
        data_health=_data_health(ident, err), reference=_reference(data.get("reference"), here, err), car=car,
        vehicle=vehicle, joints=_model_joints(data.get("model", {}), is_car, err),
        **_compute(data.get("compute", {}), err), drive=drive,
    )


def _drive(data: dict, channels: dict[str, ChannelSpec], tests: Sequence[TestSpec], err: Err) -> DriveSpec | None:
    """A robot's effort channels and [drive]: torques or currents (not both); current channels need a gain each
    (known, or identified with a payload test or a known gain to fix the scale); every test reads the effort."""
    raw = data.get("drive")
    if "tau" in channels and "current" in channels:
        raise err("[channels]", "gives both tau and current: give one effort per joint, tau (joint torques) or "
                                "current (motor currents, with [drive] gains)")
    effort = "current" if "current" in channels else "tau"
    for i, t in enumerate(tests, start=1):
        other = next((q for q in _EFFORTS if q != effort and q in t.files), None)
        if other is not None or effort not in t.files:
            what = f"files has {other!r}, but [channels] reads {effort}" if other else \
                f"files has no {effort!r}, which [channels] reads"
            raise err(f'[[tests]] #{i} ("{t.name}")', f"{what}: give files = {{ q = \"...\", {effort} = \"...\" }}")
    if effort == "tau":
        if raw is not None:
            raise err("[drive]", "gives the gains of motor current channels; [channels] has tau (joint torques): "
                                 "remove [drive], or read currents with [channels] current = { channels = [...], "
                                 "unit = \"A\" }")
        return None
    names = channels["current"].channels
    if raw is None or "gains" not in raw:
        raise err("[channels.current]", f"channel {names[0]!r} has no drive gain: give [drive] gains = [...] (N.m/A, "
                                        f"motor side, one per current channel: {len(names)})")
    _keys(raw, _DRIVE_KEYS, "[drive]", err)
    gains = raw["gains"]
    if not isinstance(gains, list):
        raise err("[drive]", f"gains = {gains!r}; give a list of gains, one per current channel (N.m/A, motor side)")
    if len(gains) < len(names):
        raise err("[drive]", f"gains has {len(gains)} values for {len(names)} current channels: channel "
                             f"{names[len(gains)]!r} has no gain; give one per channel of [channels] current")
    if len(gains) > len(names):
        raise err("[drive]", f"gains has {len(gains)} values for {len(names)} current channels; give one per channel "
                             "of [channels] current")
    values = []
    for name, g in zip(names, gains, strict=True):
        try:
            v = parse_number(g, f"gains ({name})")
        except ModelError as exc:
            raise err("[drive]", f"{exc} (N.m/A, motor side)") from None
        if not np.isfinite(v) or v == 0 or abs(v) > MAX_KNOWN:
            raise err("[drive]", f"gains: {name} = {g!r}; give the motor's torque constant in N.m/A (finite, not 0)")
        values.append(v)
    which = raw.get("identify_gains", False)
    if isinstance(which, bool):
        identify = (which,) * len(names)
    elif isinstance(which, list) and which and all(isinstance(n, str) for n in which):
        unknown = [n for n in which if n not in names]
        if unknown:
            raise err("[drive]", f"identify_gains: {unknown[0]!r} is not a current channel;"
                                 f"{did_you_mean(unknown[0], list(names))} channels: {', '.join(names)}")
        identify = tuple(n in which for n in names)
    else:
        raise err("[drive]", f"identify_gains = {which!r}; give true (every gain identified), false (the gains "
                             "known) or the channels whose gain is identified: [\"I_1\", ...]")
    if all(identify) and not any(t.payload is not None for t in tests if t.role == "identify"):
        raise err("[drive]", "identify_gains: every gain identified and no identification test carries a known "
                             "payload, so the gains and the inertial parameters are free to a common scale: add a "
                             "[[tests]] entry with the robot carrying payload = { mass_kg = ..., com_m = [...], "
                             "inertia_kg_m2 = [...] } (Gautier's method), or give one gain as known (identify_gains "
                             "= [the other channels])")
    return DriveSpec(tuple(values), identify)


def _payload(raw: object, where: str, err: Err) -> Payload:
    """[[tests]] payload = { mass_kg, com_m = [x, y, z], inertia_kg_m2 = [xx, yy, zz, xy, xz, yz], frame }: a real
    body (mass > 0, inertia about its centre of mass positive definite, triangle inequalities)."""
    where = f"{where} payload:"
    expected = ("payload = { mass_kg = 2.0, com_m = [0, 0, 0.05], inertia_kg_m2 = [xx, yy, zz, xy, xz, yz] } (its "
                "centre of mass in the link's frame, its inertia about it)")
    if not isinstance(raw, dict):
        raise err(where, f"= {raw!r}; give {expected}")
    _keys(raw, _PAYLOAD_KEYS, where, err)
    missing = [k for k in _PAYLOAD_KEYS[:3] if k not in raw]
    if missing:
        raise err(where, f"has no {missing[0]}; give {expected}")
    mass = raw["mass_kg"]
    if not _number(mass, lambda v: v > 0):
        raise err(where, f"mass_kg = {mass!r}; give the payload's mass in kg (> 0)")

    def numbers(key: str, n: int) -> tuple[float, ...]:
        v = raw[key]
        if not isinstance(v, list) or len(v) != n or not all(_number(x) for x in v):
            raise err(where, f"{key} = {v!r}; give {n} numbers" + (" (m, in the link's frame)" if n == 3 else
                             " (kg.m2 about the centre of mass: xx, yy, zz, xy, xz, yz)"))
        return tuple(float(x) for x in v)

    com, inertia = numbers("com_m", 3), numbers("inertia_kg_m2", 6)
    xx, yy, zz, xy, xz, yz = inertia
    moments = np.linalg.eigvalsh(np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]))
    if moments[0] <= 0:
        raise err(where, f"inertia_kg_m2 = {list(inertia)} is not positive definite (principal moments "
                         f"{', '.join(f'{m:.4g}' for m in moments)} kg.m2): no body has it; give the inertia about the "
                         "payload's centre of mass, [xx, yy, zz, xy, xz, yz] (products with their sign: -sum m x y)")
    if moments[0] + moments[1] < moments[2] * (1 - 1e-9):
        raise err(where, f"inertia_kg_m2 = {list(inertia)}: principal moments {', '.join(f'{m:.4g}' for m in moments)}"
                         " kg.m2 break the triangle inequality (the two smaller must sum to at least the largest): no "
                         "body has it; check the values")
    frame = raw.get("frame")
    if frame is not None and (isinstance(frame, bool) or not isinstance(frame, int) or frame < 1):
        raise err(where, f"frame = {frame!r}; give the link's frame number (from 1), or leave it out (the last link)")
    return Payload(float(mass), com, inertia, frame)


def _data_health(ident: dict, err: Err) -> str:
    value = ident.get("data_health", "stop")
    if value not in DATA_HEALTH:
        raise err("[identification]", f"data_health = {value!r}; give \"stop\" (a data health error stops the run, "
                                      "the default) or \"warn\" (it is said and kept in results.json, the run goes on)")
    return value


def _compute(c: dict, err: Err) -> dict[str, Any]:
    """[compute]: where the segments run."""
    _keys(c, _COMPUTE_KEYS, "[compute]", err)
    scheduler = c.get("scheduler")
    if scheduler is not None and (not isinstance(scheduler, str) or not scheduler.strip()):
        raise err("[compute]", f"scheduler = {scheduler!r}; give \"local\" (a Dask cluster on this machine) or a "
                               "Dask scheduler's address such as \"tcp://10.0.0.5:8786\"")
    if scheduler is not None:
        problem = address_problem(scheduler)
        if problem is not None:
            raise err("[compute]", f"scheduler = {problem}")
    workers = c.get("workers")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise err("[compute]", f"workers = {workers!r}; give a whole number >= 1 (threads, or worker processes)")
    return {"scheduler": scheduler.strip() if scheduler else None, "workers": workers}


def _sections(data: dict, path: Path) -> None:
    """Only the known sections, each a table ([[tests]]: an array of tables)."""
    for name, value in data.items():
        if name in _TOP:
            continue
        if isinstance(value, dict):
            close = difflib.get_close_matches(name, _TOP, n=1)
            hint = f"; did you mean [{close[0]}]?" if close else ";"
            raise ConfigError(f"{path}: unknown section [{name}]{hint} sections: {', '.join(_TOP)}")
        homes = [f"[{s}]" for s, keys in (("model", _MODEL_KEYS), ("conditioning", (*_CAR_CONDITIONING, "border")),
                                          ("identification", _CAR_IDENTIFICATION)) if name in keys]
        hint = f" (a key of {' or '.join(homes)}: write it under that section's header)" if homes else ""
        raise ConfigError(f"{path}: unknown top-level key {name!r}{hint}; the config's keys belong in its sections: "
                          f"{', '.join(_TOP)}")
    for name in _TOP:
        value = data.get(name)
        if name == "tests":
            if value is not None and not isinstance(value, list):
                raise ConfigError(f"{path}: [[tests]] must be an array of tables: write each test under its own "
                                  "[[tests]] header (two brackets), not [tests]" if isinstance(value, dict) else
                                  f"{path}: tests = {value!r}; write each test under its own [[tests]] header")
        elif value is not None and not isinstance(value, dict):
            raise ConfigError(f"{path}: {name} = {value!r}; [{name}] is a section: write [{name}] on its own line "
                              "and its keys below")


def _model_joints(m: dict, is_car: bool, err: Err) -> tuple[str, ...] | None:
    """[model] joints = ["joint1", ...]: a robot's identified joints (the model file's [joints] names)."""
    if "joints" not in m:
        return None
    joints = m["joints"]
    if is_car:
        raise err("[model]", "joints = [...] chooses a robot's identified joints; a car's equations are its template's")
    if not isinstance(joints, list) or not joints or not all(isinstance(j, str) and j for j in joints):
        raise err("[model]", f"joints = {joints!r}; give the identified joints' names, like joints = [\"joint1\", "
                  "\"joint2\"] (the model file's [joints] table)")
    return tuple(joints)


def _model(m: dict, here: Path, err: Err) -> tuple[str | Path, str | Path | None]:
    """[model]: the model (a shipped name or a robot file's path) and the vehicle (a car's vehicle file: a
    resolved Path, or a shipped vehicle's name; None for a robot or the template alone)."""
    where = "[model]"
    unknown = [k for k in m if k not in (*_MODEL_KEYS, *_MODEL_OPTIONS)]
    if unknown:  # e.g. wheelbase: a car's dimensions are its vehicle file's
        raise err(where, unknown_keys(unknown, (*_MODEL_KEYS, *_MODEL_OPTIONS)) + " (a car's geometry, tables and "
                         "known values are its vehicle file's: vehicle = \"my_car.toml\")")
    given = [k for k in _MODEL_KEYS if k in m]
    if not given:
        raise err(where, "give example = \"tx40\" (a shipped model), file = \"model.toml\", "
                         f"template = \"{CAR_TEMPLATE}\" or vehicle = \"{DEMO_VEHICLE}\" (a car: a shipped vehicle "
                         "or a vehicle file)")
    if {"template", "vehicle"} <= set(given):
        raise err(where, f"template = {m['template']!r} and vehicle = {m['vehicle']!r} together: give one (vehicle "
                         f"describes the car on the {CAR_TEMPLATE} template; template alone is the shipped vehicle "
                         f"{DEMO_VEHICLE})")
    if len(given) > 1:
        raise err(where, f"{' and '.join(given)} together: give one of {', '.join(_MODEL_KEYS)}")
    key = given[0]
    value = m[key]
    if not isinstance(value, str) or not value.strip():
        raise err(where, f"{key} = {value!r}; give a name or a file name (a string)")
    if key == "vehicle":
        if not value.lower().endswith(".toml"):
            return CAR_TEMPLATE, value  # a shipped vehicle's name (resolved with the vehicle files)
        file = (here / value).resolve()
        if not file.is_file():
            raise err(where, f"vehicle file not found: {file}")
        return CAR_TEMPLATE, file
    return (here / value if key == "file" else value), None


def _tests(raw: object, here: Path, is_car: bool, err: Err, effort: str = "tau") -> tuple[TestSpec, ...]:
    tests: list[TestSpec] = []
    seen: dict[str, int] = {}
    valid = _CAR_TEST_KEYS if is_car else _ROBOT_TEST_KEYS
    notes = ({"files": "a robot test's key; a car test reads one logger file: file = \"test.csv\""} if is_car else
             {"truth": "a car test's key: the simulator's sidecar"})
    for i, t in enumerate(raw, start=1):  # a list: checked in _sections
        where = _test_label(i, t)
        if not isinstance(t, dict):
            raise err(where, f"= {t!r}; each test is a table of keys under its own [[tests]] header")
        _keys(t, valid, where, err, notes)
        name = t.get("name", f"test {i}")
        if not isinstance(name, str) or not name.strip():
            raise err(where, f"name = {name!r}; give the test's name (a string)")
        if name in seen:
            raise err(where, f"name = {name!r} is test #{seen[name]}'s too; give each test its own name")
        seen[name] = i
        role = t.get("role", "identify")
        if role not in ("identify", "validate"):
            raise err(where, f"role = {role!r}; use \"identify\" or \"validate\"")
        if is_car:
            if not isinstance(t.get("file"), str):
                raise err(where, "needs file = \"test.csv\" (one logger file with the sensor suite's channels)")
            files = {"channels": here / t["file"]}
        elif "file" in t:
            if "files" in t:
                raise err(where, "has file and files: give file = \"run.mcap\" (one file holding q and tau) or "
                                 "files = { q = \"...\", tau = \"...\" }, not both")
            if not isinstance(t["file"], str):
                raise err(where, f"file = {t['file']!r}; give a file name (a string, relative to this config)")
            files = {"q": here / t["file"], effort: here / t["file"]}  # effort: tau, or current with [drive]
        else:
            files = _test_files(t.get("files"), here, where, err)
        bag = _bag_options(t, files, where, err) if not is_car else (None, ())
        for q, f in files.items():
            if f.is_symlink() and not f.exists():
                raise err(where, f"the file for {q!r}, {f}, is a symbolic link that leads nowhere (its target is "
                                 "missing, or the link leads back to itself); link it to the data file")
            if not f.exists():
                raise err(where, f"file for {q!r} not found: {f}")
            if f.is_dir() and not _bag_folder(f):  # a ROS 2 bag is a folder; any other is a slip
                raise err(where, f"the file for {q!r}, {f}, is a folder; give a data file in it (or a ROS 2 bag's "
                                 "folder, with its metadata.yaml)")
        fs = t.get("fs")
        if fs is not None and not _number(fs, lambda v: v > 0):
            raise err(where, f"fs = {fs!r}; give the sample rate in Hz (a positive number)")
        window = {k: t.get(k) for k in ("start", "end")}
        for k, v in window.items():
            if v is not None and not _number(v):
                raise err(where, f"{k} = {v!r}; give a time in s (a number, in the files' time base)")
        if None not in window.values() and not window["start"] < window["end"]:
            raise err(where, f"start = {window['start']!r} s is not before end = {window['end']!r} s")
        max_gap = t.get("max_gap", 10.0)
        if not _number(max_gap, lambda v: v >= 1):
            raise err(where, f"max_gap = {max_gap!r}; give the longest hole allowed in the time stamps, in sample "
                             "periods (a number >= 1)")
        payload = None if is_car or "payload" not in t else _payload(t["payload"], where, err)
        truth = t.get("truth")
        if truth is not None:
            if not isinstance(truth, str):
                raise err(where, f"truth = {truth!r}; give the simulator's sidecar file (a string)")
            truth = here / truth
            if not truth.exists():
                raise err(where, f"truth file not found: {truth}")
        tests.append(TestSpec(name, role, files, None if fs is None else float(fs), truth,
                              *(None if v is None else float(v) for v in window.values()), float(max_gap), payload,
                              *bag))
    if not any(t.role == "identify" for t in tests):
        raise err("[[tests]]", "at least one test must have role = \"identify\"")
    return tuple(tests)


def _bag_options(t: dict, files: dict[str, Path], where: str, err: Err) -> tuple[str | None, tuple[str, ...]]:
    """A robot test's topic and ignore_joints, which only a ROS 2 bag takes."""

    topic, ignore = t.get("topic"), t.get("ignore_joints", [])
    if ("topic" in t or "ignore_joints" in t) and not all(is_bag(f) for f in files.values()):
        key = "topic" if "topic" in t else "ignore_joints"
        raise err(where, f"{key} is for a ROS 2 bag (a .db3 or .mcap file, or a bag folder); this test reads "
                         f"{', '.join(sorted({f.name for f in files.values()}))}: remove it")
    if topic is not None and (not isinstance(topic, str) or not topic.strip()):
        raise err(where, f"topic = {topic!r}; give the JointState topic's name, e.g. \"/joint_states\"")
    if not isinstance(ignore, list) or not all(isinstance(j, str) for j in ignore):
        raise err(where, f"ignore_joints = {ignore!r}; give a list of joint names, e.g. [\"panda_finger_joint1\"]")
    return topic, tuple(ignore)


def _bag_folder(path: Path) -> bool:
    return is_bag_folder(path)


def _test_files(files: object, here: Path, where: str, err: Err) -> dict[str, Path]:
    """A robot test's files = { q = "positions.csv", tau = "torques.csv" } (one file may hold both; current in place
    of tau: motor currents)."""
    if not isinstance(files, dict) or not files:
        raise err(where, "needs files = { q = \"positions.csv\", tau = \"torques.csv\" } (a table of quantity = "
                         "file; one file may hold both)")
    unknown = [q for q in files if q not in _ROBOT_QUANTITIES]
    if unknown:
        raise err(where, "files: " + unknown_keys(unknown, _ROBOT_QUANTITIES, what="quantity"))
    if "tau" in files and "current" in files:
        raise err(where, "files has both tau and current: give the one [channels] reads")
    for q in files:
        if not isinstance(files[q], str):
            raise err(where, f"files: {q} = {files[q]!r}; give a file name (a string, relative to this config)")
        if not files[q].strip():
            raise err(where, f"the file for {q!r} is an empty name; give the file's name, relative to this config")
    for q in ("q", "tau"):
        if q not in files and (q == "q" or "current" not in files):
            raise err(where, f"files has no {q!r}: give files = {{ q = \"...\", tau = \"...\" }}")
    return {q: here / f for q, f in files.items()}


def _channels(raw: dict, err: Err, suite: _VehicleChannels | None) -> dict[str, ChannelSpec]:
    """[channels]: a robot's quantity -> { channels = [...], unit }; a car's renamed sensor channels (suite: the
    car's vehicle's sensors, None for a robot)."""
    is_car = suite is not None
    if is_car:
        for q in raw:
            suite.check(q, "[channels]")
        inner = ("channel", "unit", "unit_over_file")
        expected = "{ channel = \"name in the file\", unit = \"...\" }"
    else:
        inner = ("channels", "unit", "unit_over_file")
        expected = "{ channels = [\"name in the file\", ...], unit = \"...\" } (one channel per joint)"
        unknown = [q for q in raw if q not in _ROBOT_QUANTITIES]
        if unknown:
            raise err("[channels]", unknown_keys(unknown, _ROBOT_QUANTITIES, what="quantity"))
    channels = {}
    for q, spec in raw.items():
        where = f"[channels.{q}]"
        if not isinstance(spec, dict) or inner[0] not in spec:
            raise err(where, f"= {spec!r}; expected {expected}")
        _keys(spec, inner, where, err)
        names = spec[inner[0]]
        if is_car:
            names = [names] if isinstance(names, str) else None
        if not isinstance(names, list) or not names or not all(isinstance(c, str) for c in names):
            raise err(where, f"{inner[0]} = {spec[inner[0]]!r}; expected {expected}")
        twice = sorted({c for c in names if names.count(c) > 1})
        if twice:
            raise err(where, f"channel {twice[0]!r} is listed twice; each joint reads its own channel")
        unit = spec.get("unit")
        if unit is not None and not isinstance(unit, str):
            raise err(where, f"unit = {unit!r}; give the file's unit as a string (\"rad\", \"deg/s\")")
        if unit is not None and not unit.strip():
            raise err(where, "unit = \"\"; give the channels' unit (\"rad\", \"deg/s\"), or leave unit out to read "
                             "the file's")
        over = spec.get("unit_over_file", False)
        if not isinstance(over, bool) or (over and unit is None):
            raise err(where, f"unit_over_file = {over!r}; true (with a unit) when the file's own unit is wrong and "
                             "the config's is right, else leave it out")
        channels[q] = ChannelSpec(tuple(names), unit, over)
    if is_car:  # two sensors read from one logger channel: a copy-paste slip, never a car's wiring
        seen: dict[str, str] = {}
        for q, c in channels.items():
            if c.channels[0] in seen:
                raise err(f"[channels.{q}]", f"channel = {c.channels[0]!r} is also [channels.{seen[c.channels[0]]}]'s;"
                          " each sensor has its own channel")
            seen[c.channels[0]] = q
    return channels


def _transmission(raw: dict, err: Err) -> dict[str, np.ndarray]:
    """[transmission] q, tau: matrices (rows of equal length); q_offset: one number per joint."""
    where = "[transmission]"
    _keys(raw, _TRANSMISSION_KEYS, where, err)
    out = {}
    for k, v in raw.items():
        if k == "q_offset":
            ok = isinstance(v, list) and v and not any(isinstance(x, list | dict) for x in v)
            expected = "a list of numbers, one per joint: q_offset = [0, \"-pi/2\"]"
        else:
            ok = (isinstance(v, list) and v and all(isinstance(r, list) and r for r in v)
                  and len({len(r) for r in v}) == 1)
            expected = f"a matrix, a list of rows of equal length: {k} = [[\"1/32\", 0], [0, \"1/32\"]]"
        if not ok:
            raise err(where, f"{k} = {v!r}; give {expected}")
        try:
            out[k] = np.array([[parse_number(x, k) for x in row] if isinstance(row, list) else parse_number(row, k)
                               for row in v])
        except ModelError as exc:
            raise err(where, str(exc)) from None
        big = np.flatnonzero(~np.isfinite(out[k].ravel()) | (np.abs(out[k].ravel()) > MAX_KNOWN))
        if big.size:
            raise err(where, f"{k}: {out[k].ravel()[big[0]]:g} is not a finite number within ±{MAX_KNOWN:g}; a "
                             "transmission is a gear ratio or a scale (1/32, 0.0174533), a unit or exponent slip?")
        if k != "q_offset":
            rank = np.linalg.matrix_rank(out[k])
            if rank < out[k].shape[0]:
                zero = np.flatnonzero(~out[k].any(axis=1))
                which = f"row {zero[0] + 1} is all zeros" if zero.size else "rows depend on each other"
                raise err(where, f"{k} is singular ({which}; rank {rank} for {out[k].shape[0]} joints): each "
                                 "joint must read its own combination of the channels (a gear ratio on the "
                                 "diagonal, like [[32, 0], [0, 32]])")
    return out


def _robot_conditioning(c: dict, err: Err) -> Conditioning:
    where = "[conditioning]"
    border = c.get("border")
    if border is not None and not _number(border, lambda v: v >= 0):
        raise err(where, f"border = {border!r}; give the time trimmed at each end in s (a number >= 0)")
    return Conditioning(
        cutoff=_cutoff(c, 25.0, where, err),
        order=_whole(c, "order", 4, where, err),
        border=None if border is None else float(border),
        decimate=_decimate(c, (10, 10), where, err),
        min_speed=_robot_min_speed(c.get("min_speed", {}), where, err),
    )


def _robot_min_speed(raw: object, where: str, err: Err) -> dict[int, float]:
    """[conditioning] min_speed for a robot: { joint (1-based) = speed >= 0 }."""
    if not isinstance(raw, dict):
        raise err(where, f"min_speed = {raw!r}; give {{ joint = speed, ... }}, e.g. {{ 1 = 0.05 }} (joints from 1)")
    out = {}
    for k, v in raw.items():
        if not k.isdigit() or int(k) < 1 or not _number(v, lambda x: x >= 0):
            raise err(where, f"min_speed: {k} = {v!r}; keys are joint numbers (from 1), values speeds >= 0 "
                             "(rad/s or m/s)")
        out[int(k)] = float(v)
    return out


def _known(ident: dict, err: Err) -> dict[str, float]:
    """[identification] known = { parameter = value }: numbers (or arithmetic on numbers and pi)."""
    raw = ident.get("known", {})
    if not isinstance(raw, dict):
        raise err("[identification]", f"known = {raw!r}; give a table of fixed parameters and their values: "
                                      "known = { IA1 = 0.36 }")
    out = {}
    for name, v in raw.items():
        try:
            value = parse_number(v, f"known: {name}")
        except ModelError as exc:
            raise err("[identification]", f"{exc} (the parameter's fixed value, SI)") from None
        if not np.isfinite(value):
            raise err("[identification]", f"known: {name} = {v!r}; give a finite number (its fixed value, SI)")
        if abs(value) > MAX_KNOWN:
            raise err("[identification]", f"known: {name} = {v!r} is beyond ±{MAX_KNOWN:g}: give its fixed value in SI "
                                          "units (kg, m, kg·m², N/m, N·s/m, N; is the unit right?)")
        out[name] = value
    return out


def _reference(ref: dict | None, here: Path, err: Err) -> dict[str, Any] | None:
    """[reference] file (required), names and combinations: tables of strings."""
    if ref is None:
        return None
    where = "[reference]"
    _keys(ref, _REFERENCE_KEYS, where, err)
    if not isinstance(ref.get("file"), str):
        raise err(where, "needs file = \"published.csv\"")
    for k in ("names", "combinations"):
        table = ref.get(k, {})
        if not isinstance(table, dict) or not all(isinstance(v, str) for v in table.values()):
            raise err(where, f"{k} = {table!r}; give a table of strings: " +
                      ("names = { Izz = \"ZZ\" }" if k == "names" else "combinations = { fvm6 = \"1024*fvm6\" }"))
    ref = {**ref, "file": here / ref["file"]}
    if not ref["file"].exists():
        raise err(where, f"file not found: {ref['file']}")
    if ref["file"].is_dir():
        raise err(where, f"file = {str(ref['file'])!r} is a folder; give the published table's CSV file")

    try:  # a binary or non-UTF-8 file is refused now, before the identification (its rows are read with the results)
        reference_text(ref["file"])
        for k, v in ref.get("combinations", {}).items():
            try:
                parse_combination(v)
            except ModelError as exc:
                raise ModelError(f"combinations: {k} = {v!r}: {exc}; give a linear combination of base "
                                 "parameters: fvm6 = \"1024*fvm6\"") from None
    except ModelError as exc:
        raise err(where, str(exc)) from None
    return ref


def _car_settings(data: dict, err: Err, suite: _VehicleChannels) -> CarSettings:
    """The car's [conditioning], [identification] options and [uncertainty] (keys checked by the caller)."""
    c = data.get("conditioning", {})
    ident = data.get("identification", {})
    where = "[conditioning]"
    base = ident.get("base", "generic")
    if base not in ("generic", "car"):
        raise err("[identification]", f"base = {base!r}; use \"generic\" (the paper's 48) or \"car\"")
    offsets, segments = _offsets(data.get("uncertainty", {}), err, suite)
    return CarSettings(
        cutoff=_cutoff(c, 4.0, where, err),
        order=_whole(c, "order", 4, where, err), decimate=_decimate(c, (5, 10), where, err, empty=True),
        attitude_crossover=_crossover(c, where, err),
        segment=_float(c, "segment", 60.0, where, err, "a segment length in s (a positive number)"),
        compensate_delays=_flag(c, "compensate_delays", True, where, err), min_speed=_car_min_speed(c, err),
        friction_lowpass=_flag(c, "friction_lowpass", True, where, err),
        base=base, aero=_flag(ident, "aero", True, "[identification]", err), offsets=offsets,
        offset_segments=segments, iv_passes=_iv_passes(ident, err),
        estimate_offsets=_flag(data.get("uncertainty", {}), "estimate", True, "[uncertainty]", err),
        tire_curves=_flag(ident, "tire_curves", True, "[identification]", err),
    )


MAX_CROSSOVER = 10.0  # Hz: inclinometers are trusted below a few tenths of Hz; above this the gyros are not used


def _crossover(c: dict, where: str, err: Err) -> float:
    value = _float(c, "attitude_crossover", 0.2, where, err, "a crossover in Hz (a positive number)")
    if value > MAX_CROSSOVER:
        raise err(where, f"attitude_crossover = {value:g} Hz; give the frequency below which the inclinometers are "
                         f"trusted and above which the integrated gyros are, at most {MAX_CROSSOVER:g} Hz (the paper: "
                         "0.2 Hz)")
    return value


def _iv_passes(ident: dict, err: Err) -> int:
    n = ident.get("iv_passes", 2)
    if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= 10:
        raise err("[identification]", f"iv_passes = {n!r}: give a whole number from 1 to 10 (IDIM-IV passes: "
                  "simulate the suspensions with the last estimate, re-estimate)")
    return n



def _car_min_speed(c: dict, err: Err) -> dict[int, float]:
    """[conditioning] min_speed for a car: one speed (m/s) for the four dampers, or { 9 = 0.01, ... }."""
    raw = c.get("min_speed", 0.01)
    table = dict.fromkeys(DAMPERS, raw) if isinstance(raw, int | float) and not isinstance(raw, bool) else raw
    if not isinstance(table, dict):
        raise err("[conditioning]", f"min_speed = {raw!r}; use a speed in m/s (0.01) or {{ 9 = 0.01, 27 = 0.02 }}")
    out = {}
    for k, v in table.items():
        if str(k) not in {str(d) for d in DAMPERS} or not _number(v, lambda x: x >= 0):
            raise err("[conditioning]", f"min_speed: {k} = {v!r}; keys are the damper frames "
                      f"{', '.join(map(str, DAMPERS))}, values speeds >= 0 in m/s")
        out[int(k)] = float(v)
    return out


def _number(value, ok=lambda v: True) -> bool:
    """A finite int or float (not a bool) for which `ok` holds."""
    return (not isinstance(value, bool) and isinstance(value, int | float) and bool(np.isfinite(value))
            and bool(ok(value)))


def _float(table: dict, key: str, default: float, where: str, err: Err, expected: str) -> float:
    """A positive number."""
    value = table.get(key, default)
    if not _number(value, lambda v: v > 0):
        raise err(where, f"{key} = {value!r}; give {expected}")
    return float(value)


# the Butterworth's order: the paper uses 5 to 8; beyond 20 the sections' poles crowd the unit circle and the
# borders outgrow any test (order 5000 designed for minutes, 2**62 asked for an array larger than memory)
MAX_ORDER = 20
# Hz: below it the zero-phase filter's borders (about 3 / cutoff s at each end) outlast any test, and its impulse
# response is longer than memory holds (1e-9 Hz once asked for 52 TiB)
MIN_CUTOFF_HZ = 0.01
# [identification] known: a fixed value larger than this in SI units is a unit slip (no robot or car parameter
# comes near: a car's body is 1e3 kg, 1e4 kg.m^2, a tire 1e6 N/m), and 1e308 overflowed the least squares
MAX_KNOWN = 1e9


def _cutoff(table: dict, default: float, where: str, err: Err) -> float:
    """The positions' (a car's: every signal's) low-pass cut-off, Hz: MIN_CUTOFF_HZ or above (the sample rate's
    Nyquist limit is checked against each test's files)."""
    value = _float(table, "cutoff", default, where, err, "a cut-off in Hz (a positive number)")
    if value < MIN_CUTOFF_HZ:
        raise err(where, f"cutoff = {table.get('cutoff')!r} Hz is below {MIN_CUTOFF_HZ:g} Hz: the filter's borders "
                         f"(about {3 / value:.3g} s at each end) would outlast any test; give the cut-off in Hz, 2 to "
                         "5 times the highest frequency of the motion (a robot: 10-30 Hz, a car: 3-5 Hz)")
    return value


def _whole(table: dict, key: str, default: int, where: str, err: Err) -> int:
    """The filter order: a whole number from 1 to MAX_ORDER (4.7 is refused, not truncated)."""
    value = table.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_ORDER:
        raise err(where, f"{key} = {value!r}; give the Butterworth order, a whole number >= 1 and at most "
                         f"{MAX_ORDER} (the paper uses 5 to 8)")
    return value


def _decimate(table: dict, default: tuple[int, ...], where: str, err: Err, empty: bool = False) -> tuple[int, ...]:
    """decimate = 10 or [10, 10]: whole factors >= 2 applied in turn (2.5 is refused, not truncated); `empty`: []
    (no decimation) is accepted."""
    raw = table.get("decimate", list(default))
    factors = raw if isinstance(raw, list) else [raw]
    if (not factors and not empty) or any(isinstance(f, bool) or not isinstance(f, int) or f < 2 for f in factors):
        raise err(where, f"decimate = {raw!r}; give whole decimation factors >= 2, applied in turn: [10, 10] "
                         "(or one: 10)")
    return tuple(factors)


def _positive(table: dict, key: str, default: float, err: Err, where: str = "[identification]") -> float:
    value = table.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
        raise err(where, f"{key} = {value!r}; use a positive number")
    return float(value)


def _flag(table: dict, key: str, default: bool, where: str, err: Err) -> bool:
    value = table.get(key, default)
    if not isinstance(value, bool):
        raise err(where, f"{key} = {value!r}; use true or false")
    return value


OFFSETS_OFF = "none"  # [uncertainty] offsets = "none": no offsets propagated (so does an empty table)
OFFSETS_VEHICLE = "vehicle"  # the default, written out: the vehicle's sensor suite's


def _offsets(u: dict, err: Err, suite: _VehicleChannels) -> tuple[dict[str, float] | None, int]:
    """[uncertainty] offsets: absent or "vehicle" (None: the vehicle's suite's), "none" or {} (none), or a table
    { channel = 1-sigma zero offset in the suite's unit of the channel }; segments = n."""
    where = "[uncertainty]"
    _keys(u, _UNCERTAINTY_KEYS, where, err)
    raw = u.get("offsets", OFFSETS_VEHICLE)
    if isinstance(raw, str) and raw.strip().lower() in (OFFSETS_VEHICLE, OFFSETS_OFF):
        offsets = None if raw.strip().lower() == OFFSETS_VEHICLE else {}
    elif not isinstance(raw, dict):
        raise err(where, f"offsets = {raw!r}: give a table {{ channel = 1-sigma zero offset in its unit, ... }} "
                         f"(it replaces the vehicle's sensor suite's), \"{OFFSETS_OFF}\" (no offsets: σ from the noise "
                         f"alone) or \"{OFFSETS_VEHICLE}\" (the suite's, the default)")
    else:
        offsets = {}
        for name, v in raw.items():
            suite.check(name, where, "offsets: ")
            try:
                value = parse_number(v, f"offsets.{name}")
            except ModelError as exc:
                raise err(where, str(exc)) from None
            if not np.isfinite(value) or value < 0:
                raise err(where, f"offsets.{name} = {v!r}: give a standard deviation >= 0 in the channel's unit")
            if value > 0:
                offsets[name] = value
    segments = u.get("segments", 2)
    if isinstance(segments, bool) or not isinstance(segments, int) or segments < 1:
        raise err(where, f"segments = {segments!r}: give a whole number >= 1 (segments per test on which "
                         "the offsets' effect is evaluated)")
    return offsets, segments


# why a channel of the paper's suite (or a GNSS/INS) is not on a vehicle, and the prefix of what it has instead
_NOT_FITTED = (
    ("correvit_", "its file says [sensors] correvit = false: no Correvit; the horizontal velocity over ground comes "
                  "from its GNSS/INS (gnss_vx, gnss_vy)", "gnss_"),
    ("gnss_", "it has the paper's Correvit instead, correvit_vx and correvit_vy; a GNSS/INS is fitted by "
              "[sensors] correvit = false in the vehicle file", "correvit_"),
    ("laser_height_", "its file says [sensors] lasers = false: no height lasers; the heights come from the wheel "
                      "loads through the known tire stiffness", None),
    ("steer_", "its file says [sensors] cameras = false: no corner cameras; the steering joints come from the "
               "kinematic tables", None),
    ("camber_", "its file says [sensors] cameras = false: no corner cameras; the camber joints come from the "
                "kinematic tables", None),
)


class _VehicleChannels:
    """The channels the estimator reads on the config's vehicle (its sensor suite), for checking the config's
    channel names; the vehicle file is read at the first name checked (a config naming none does not read it)."""

    def __init__(self, vehicle: str | Path, err: Err) -> None:
        self.ref, self.err = vehicle, err
        self._valid: list[str] | None = None
        self._vehicle = None

    @property
    def valid(self) -> list[str]:
        if self._valid is None:
            # start-up: the vehicle's modules (scipy.interpolate and optimize, 18 MB) are not needed to read a robot's
            from ..vehicle.description import load_vehicle
            from ..vehicle.estimate import required_channels

            self._vehicle = load_vehicle(self.ref)
            self._valid = required_channels(spin=False, suite=self._vehicle.suite)
        return self._valid

    def check(self, name: str, where: str, what: str = "") -> None:
        """name must be a channel of the vehicle's suite: an error naming it and the nearest valid channel, or
        saying the vehicle has no such sensor (a channel of another suite)."""
        valid = self.valid
        if name in valid:
            return
        v = self._vehicle
        label = f"vehicle {v.name!r} ({Path(v.source).name if v.source else self.ref})"
        listing = f"{label}'s channels: {', '.join(valid)}"
        if name in _every_channel():
            why, instead = next((w, i) for p, w, i in _NOT_FITTED if name.startswith(p))
            hint = ""
            if instead is not None:
                alike = instead + name.split("_", 1)[1]
                hint = f"; map {alike!r} instead" if alike in valid else ""
            raise self.err(where, f"{what}{name!r}: {label} has no such sensor ({why}){hint}")
        raise self.err(where, f"{what}unknown channel {name!r}, not in the sensor suite of {label};"
                              f"{did_you_mean(name, valid)} {listing}")


def _every_channel() -> set[str]:
    """Every channel the estimator knows, whatever the suite: the paper's and a GNSS/INS car's."""
    # start-up: the vehicle's modules (scipy.interpolate and optimize, 18 MB) are not needed to read a robot's config
    from ..vehicle.estimate import required_channels
    from ..vehicle.sensors import fitted_suite

    return {*required_channels(spin=False), *required_channels(spin=False, suite=fitted_suite(correvit=False))}
