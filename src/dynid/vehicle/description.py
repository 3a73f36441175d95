"""A car described by a vehicle file (TOML): what a vehicle engineer writes from the data sheets and the
bench files they have. The paper's 42-frame template takes its geometry, kinematic and aerodynamic
tables, sensor positions, a priori and known values from it; the Peugeot 406 is one shipped file.

Frame 6 (the chassis): x6 UP, y6 to the RIGHT, z6 FORWARD, origin O6 on the rear axle, midway between
the rear wheel centres, at their height in the design position (docs/vehicle.md draws it). Every key
that has a unit carries it in its name (`_m`, `_deg`, `_kg_m3`, `_m2`); parameters are SI.

    name = "Peugeot 406 saloon"
    [axles]
    wheelbase_m = 2.70                      # front axle ahead of the rear one (O6)
    [axles.front]                           # the steered axle (the template's front corners steer)
    half_track_m = 0.755
    damper_lateral_tilt_deg = 11.0          # front view, top inboard positive
    damper_longitudinal_tilt_deg = 3.0      # side view, top rearward positive
    kingpin_inclination_deg = 12.0          # front view, top inboard positive
    caster_deg = 3.5                        # side view, top rearward positive
    kingpin_offset_m = 0.06                 # wheel centre to kingpin axis, inboard
    anti_roll_bar = true                    # false: karf is known to be 0
    [axles.rear]
    ...
    [wheels]
    radius_m = 0.317                        # unloaded
    centre_height_m = 0.0                   # x6 of the wheel centres at design (0: O6 at their height)
    [steering]                              # optional
    ratio = 16.0                            # steering-wheel angle / front-wheel steer (the default tables')
    [sensors]                               # optional: what is not fitted (default: the paper's suite)
    cameras = false                         # clearances from damper potentiometers, steer and camber from tables
    lasers = false                          # heights from the loads: kt must be [known]
    correvit = false                        # horizontal velocity from a GNSS/INS instead (gnss_vx, gnss_vy)
    gnss_position_m = [1.1, 0.0, 1.35]      # its point in frame 6 (default: roof, centreline, mid-wheelbase)
    correvit_position_m = [0.1, 1.0, 1.35]  # the Correvit's point (default: right flank, mid-wheelbase)
    laser_positions_m = [[0, -0.4, 0], [0, 0.4, 0], [0, -0.4, 2.7], [0, 0.4, 2.7]]  # rl rr fl fr
    [sensors.dynamics]                      # optional: the logger's delays (vehicle.dynamics; default Table 1)
    default = "table1"                      # or "none": every channel already aligned by the logger
    "wft_*" = "none"                        # a pattern, a group (imu, cameras, ...) or a channel
    imu = { bandwidth_hz = 10, rate_hz = 125, delay_ms = 2 }
    [imu]                                   # optional: where the inertial unit is
    position_m = [0.0, 0.0, 0.0]            # in frame 6
    axes = [[0, 0, 1], [0, -1, 0], [1, 0, 0]]   # rows: the unit's x, y, z in frame 6 (ISO 8855)
    [tables]                                # optional: the maker's kinematic tables (default: from the geometry)
    file = "kc.toml"                        # vehicle.tables' TOML format, and/or one CSV per table:
    front_left.camber = { csv = "fl_camber.csv", units = "deg" }
    [aero]                                  # optional
    file = "aero.csv"                       # beta_deg, cx, cy, cz, cl, cm, cn (default: a saloon's)
    rho_kg_m3 = 1.225
    area_m2 = 2.0
    length_m = 2.70
    [dampers]                               # optional: the dampers' law (docs/vehicle.md, "Damper curves")
    law = "curve"                           # "linear" (default: the paper's h q') or "curve": per damper
    knee_bump_m_s = 0.1                     # four slopes hbl hbh (bump) hrl hrh (rebound) about these knees
    knee_rebound_m_s = 0.1                  # (clearance rates, > 0; "inf": no knee on that side; an axle
                                            # given neither: the identification chooses them from the data)
    [dampers.front]                         # optional: an axle's own knees
    knee_bump_m_s = 0.15
    [a_priori]                              # the parameters' a priori values (names or the paper's labels)
    XX6 = 6810.44
    [truth]                                 # optional: the set a simulation drives with; a damper offset left
    ...                                     # out is the static preload that holds it at its design position
    [known]                                 # optional: values measured on a bench, not identified
    M14 = 35.0

Errors name the file, the section and the key, and say the fix; an unknown key names the nearest
valid one.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

import numpy as np

from ..model.consistency import check_physical
from ..model.files import did_you_mean, read_toml, unknown_keys
from ..model.tree import FRICTION_SHAPES, ModelError, Tree
from ..model.workspace import derived
from ..shipped import DEMO_VEHICLE
from ..textfiles import TextEncodingError, read_csv_rows
from .aero import COEFFICIENTS, Aerodynamics, AeroError, reference_point
from .dynamics import DynamicsError, LoggerDynamics, parse_dynamics, table1_dynamics
from .engineering import chassis_data_sheet, chassis_from_data_sheet
from .geometry import CarGeometry, GeometryError, file_geometry
from .parameter_set import ParameterSet
from .sensors import SensorSuite, correvit_point, fitted_suite, gnss_point, laser_point
from .statics import design_preloads
from .tables import (
    CORNER_KEYS,
    STEERING_RATIO,
    TABLE_NAMES,
    KinematicTableError,
    KinematicTables,
    default_tables,
    load_table_csv,
)
from .tables import load_tables as load_table_file
from .template import (
    CHASSIS,
    CORNERS,
    CURVE_LABELS,
    DAMPERS,
    TIRE_LAWS,
    TIRES,
    WHEELS,
    car_tree,
    labels,
    paper_parameter_names,
)

AXLE_KEYS = {"half_track_m", "damper_lateral_tilt_deg", "damper_longitudinal_tilt_deg", "kingpin_inclination_deg",
             "caster_deg", "kingpin_offset_m", "anti_roll_bar", "damper_friction"}
SECTIONS = {"name": str, "description": str, "axles": dict, "wheels": dict, "steering": dict, "imu": dict,
            "sensors": dict, "dampers": dict, "tables": dict, "aero": dict, "a_priori": dict, "truth": dict,
            "known": dict}
REQUIRED = ("name", "axles", "wheels", "a_priori")
# plausible passenger-car ranges: outside them the number is a unit slip or a typo, not a car
RANGES = {"wheelbase_m": (1.5, 4.5), "ratio": (8.0, 30.0), "half_track_m": (0.4, 1.1), "radius_m": (0.2, 0.6),
          "centre_height_m": (-0.3, 0.3), "kingpin_offset_m": (0.0, 0.2), "rho_kg_m3": (0.5, 1.5),
          "area_m2": (0.5, 10.0), "length_m": (1.0, 6.0)}
ANGLE_LIMIT_DEG = 45.0  # a damper or kingpin axis tilted further is no longer a suspension axis


class VehicleError(ModelError):
    """A vehicle file that cannot describe a car: the message names the file, the key and the fix."""


@dataclass(frozen=True)
class Vehicle:
    """A car for the template: name, geometry, kinematic tables, aerodynamics, sensor suite, a priori values,
    the simulation's truth (None when the file gives none) and the parameters known from a bench.

    A description only: reading it solves nothing. The truth's damper offsets that the file leaves out are the
    static preloads, solved at the first use of `truth` (the simulator's) and kept beside the vehicle
    (model.workspace.derived), never in it."""

    name: str
    geometry: CarGeometry
    tables: KinematicTables
    aero: Aerodynamics
    a_priori: ParameterSet
    # the file's [truth] with [known] and [a_priori] for the rest, less the damper offsets it leaves out (`truth`
    # adds them); None when the file gives no [truth]
    truth_given: ParameterSet | None
    known: dict[str, float] = field(default_factory=dict)
    source: str = ""
    steering_ratio: float = STEERING_RATIO
    cameras: bool = True
    lasers: bool = True
    correvit: bool = True
    tire_offsets: bool = True
    tire_law: str = "paper"  # [wheels] tire_law: template.TIRE_LAWS
    tire_lateral_force: bool = False  # [wheels] tire_lateral_force: the progressive law's lateral-force term
    damper_law: str = "linear"  # [dampers] law: DAMPER_LAWS
    # [dampers] knees per damper frame, (v-, v+) m/s (bump is q' > 0): the identification's curves ("curve") and
    # the truth's (a [truth] curve slope); {} when the file gives none
    damper_knees: dict[int, tuple[float, float]] = field(default_factory=dict)
    # [axles.*] damper_friction: damper frame -> (shape, vs) of its dry friction's law; absent: sign(qd)
    damper_friction: dict[int, tuple[str, float]] = field(default_factory=dict)
    # the kinematic tables the file did not give ("front_left.caster", ...): dynid's defaults stand in for them
    defaulted_tables: tuple[str, ...] = ()
    dynamics: LoggerDynamics | None = None  # [sensors.dynamics]; None: the suite's Table-1 sensors

    @property
    def knees_from_data(self) -> tuple[int, ...]:
        """The dampers whose curve's knees the identification chooses from the data (law "curve", no knees in
        the file): until then they have h (`with_knees`)."""
        return tuple(d for d in DAMPERS if self.damper_law == "curve" and d not in self.damper_knees)

    def with_knees(self, knees: Mapping[int, tuple[float, float]]) -> Vehicle:
        """This vehicle with the knees of dampers in `knees_from_data` ((v-, v+) m/s each), their a priori
        curves starting from h (each slope = h)."""
        values = dict(self.a_priori.values)
        for d, (lo, hi) in knees.items():
            if d not in self.knees_from_data:
                raise VehicleError(f"{self.source or self.name}: damper {d}'s knees are the file's, not the data's")
            h = values.pop(f"FV{d}")
            values.update({f"{t}{d}": h for t, finite in (("FVPL", True), ("FVPH", math.isfinite(hi)),
                                                         ("FVNL", True), ("FVNH", math.isfinite(lo))) if finite})
        return replace(self, damper_knees={**self.damper_knees, **knees},
                       a_priori=replace(self.a_priori, values=values))

    def template(self, values: dict[str, float] | None = None) -> Tree:
        """The car's 42-frame tree with `values` (default: the a priori set)."""
        return car_tree(self.geometry, self.a_priori.values if values is None else values, name=self.name,
                        tire_offsets=self.tire_offsets, tire_law=self.tire_law,
                        tire_lateral_force=self.tire_lateral_force,
                        damper_knees=self.damper_knees if self.damper_law == "curve" else None,
                        damper_friction=self.damper_friction)

    @derived
    def truth(self) -> ParameterSet | None:
        """The simulation's set: `truth_given` with each damper offset it lacks the static preload that holds the
        damper at its design position on flat ground (`statics.design_preloads`); None when the file gives none."""
        given = self.truth_given
        if given is None or all(f"OFF{d}" in given.values for d in DAMPERS):
            return given
        curved = {d: self.damper_knees[d] for d in DAMPERS if f"FVPL{d}" in given.values}
        try:
            tree = car_tree(self.geometry, {**given.values, **{f"OFF{d}": 0.0 for d in DAMPERS}},
                            damper_knees=curved)
            preloads = design_preloads(tree, self.tables)
        except GeometryError as exc:
            raise VehicleError(f"{self.source or self.name}: [truth]: {exc}") from None
        values, sources = dict(given.values), dict(given.sources)
        for d, f in zip(DAMPERS, preloads, strict=True):
            if f"OFF{d}" not in values:
                values[f"OFF{d}"] = float(f)
                sources[f"OFF{d}"] = "static preload: damper at its design position (q = 0) at rest on flat ground"
        return ParameterSet(given.name, values, sources)

    @property
    def suite(self) -> SensorSuite:
        """The sensors fitted: the paper's suite (Table 1) at this car's positions, less what the file says is
        not fitted (`sensors.fitted_suite`)."""
        return fitted_suite(self.geometry, cameras=self.cameras, lasers=self.lasers, correvit=self.correvit)

    @property
    def logger(self) -> LoggerDynamics:
        """Each channel's declared dynamics (`vehicle.dynamics`): the file's [sensors.dynamics], by default the
        paper's Table-1 sensors."""
        return self.dynamics if self.dynamics is not None else table1_dynamics(self.suite)


def shipped_vehicles() -> list[str]:
    """Names of the vehicle files shipped with dynid."""
    folder = resources.files("dynid.vehicle") / "vehicles"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def vehicle_path(name_or_path: str | os.PathLike[str]) -> Path:
    """The file of a shipped vehicle name, or the path given (a name not shipped and not a file is an error)."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.is_file():
        if not p.is_file():
            what = "a folder, not a vehicle file" if p.is_dir() else "no such vehicle file"
            raise VehicleError(f"{p}: {what}; `dynid vehicle new NAME --out {p}` writes a starting one")
        return p
    if str(name_or_path) in shipped_vehicles():  # a folder of the same name (a run's output) does not hide it
        return Path(str(resources.files("dynid.vehicle") / "vehicles" / f"{name_or_path}.toml"))
    if p.is_dir():
        raise VehicleError(f"{p}: a folder, not a vehicle file; give the .toml file (shipped vehicles: "
                           f"{', '.join(shipped_vehicles())})")
    raise VehicleError(f"no shipped vehicle {str(name_or_path)!r} and no such file; shipped: "
                       f"{', '.join(shipped_vehicles())} (or give a path to a .toml vehicle file)")


def load_vehicle(name_or_path: str | os.PathLike[str] = DEMO_VEHICLE) -> Vehicle:
    """Read and check a vehicle file (a path, or a shipped vehicle's name)."""
    path = vehicle_path(name_or_path)
    data = read_toml(path, "vehicle file", VehicleError)
    return vehicle_from_dict(data, path)


@functools.cache
def demo_vehicle() -> Vehicle:
    """The demo vehicle, `load_vehicle(DEMO_VEHICLE)` read once per process: what a function given no vehicle,
    geometry or parameter set uses. Shared: read it, do not change its dicts."""
    return load_vehicle(DEMO_VEHICLE)


def vehicle_from_dict(data: dict, path: Path) -> Vehicle:
    where = str(path)
    _keys(data, set(SECTIONS), where, "the top level")
    missing = [k for k in REQUIRED if k not in data]
    if missing:
        raise VehicleError(f"{where}: missing {', '.join(repr(k) for k in missing)} (see `dynid vehicle new`)")
    for k, kind in SECTIONS.items():
        if k in data and not isinstance(data[k], kind):
            what = "a table [" + k + "]" if kind is dict else "a string"
            raise VehicleError(f"{where}: {k!r} must be {what}; got {data[k]!r}")
    geometry = _geometry(data, where)
    steering = data.get("steering", {})
    _keys(steering, {"ratio"}, where, "[steering]")
    ratio = _number(steering, "ratio", where, "[steering]", STEERING_RATIO)
    tables, defaulted = _tables(data.get("tables", {}), geometry, ratio, path)
    aero = _aero(data.get("aero", {}), geometry, path)
    names = _parameter_names()
    damper_law, knees = _dampers(data.get("dampers", {}), where)
    a_priori = _curves(_parameters(data["a_priori"], names, where, "a_priori", complete=True, geometry=geometry),
                       damper_law, knees, where, "a_priori")
    known = _parameters(data.get("known", {}), names, where, "known", complete=False, geometry=geometry)
    _check_known_dampers(known, damper_law, where)
    for axle, bar in (("front", "karf"), ("rear", "karr")):
        if not data["axles"][axle].get("anti_roll_bar", True):
            if known.get(bar, 0.0) != 0.0:
                raise VehicleError(f"{where}: [axles.{axle}] anti_roll_bar = false but [known] {bar} = {known[bar]}")
            known[bar] = 0.0
            a_priori[bar] = 0.0
    fitted = _sensors(data.get("sensors", {}), where)
    points = {k: fitted.pop(k) for k in ("gnss_position", "correvit_position", "laser_positions")}
    geometry = dataclasses.replace(geometry, **{k: v for k, v in points.items() if v is not None})
    _check_points(geometry, where)
    declared = fitted.pop("dynamics")
    try:
        dynamics = None if declared is None else parse_dynamics(declared, fitted_suite(geometry, **fitted), where)
    except DynamicsError as exc:
        raise VehicleError(str(exc)) from None
    if not fitted["lasers"]:
        missing = [n for n in ("K15", "K24", "K33", "K42") if n not in known]
        if missing:
            raise VehicleError(f"{where}: [sensors] lasers = false: the tire deflections then come from the wheel "
                               f"loads through the tires' stiffness, so the tire equations identify nothing: give "
                               f"{', '.join(missing)} (kt15 ...) in [known] (a tire bench)")
    known_radius = data["wheels"].get("unloaded_radius_known", False)
    if not isinstance(known_radius, bool):
        raise VehicleError(f"{where}: [wheels] unloaded_radius_known must be true or false; got {known_radius!r}")
    # without lasers the deflections come from the loads through the bench's kt: there is no offset to identify
    tire_offsets = fitted["lasers"] and not known_radius
    damper_friction = {d: law for axle, pair in (("rear", DAMPERS[:2]), ("front", DAMPERS[2:]))
                       if (law := _damper_friction(data["axles"][axle], where, f"[axles.{axle}]")) for d in pair}
    tire_law = data["wheels"].get("tire_law", "paper")
    if tire_law not in TIRE_LAWS:
        raise VehicleError(f"{where}: [wheels] tire_law = {tire_law!r}; give one of {', '.join(TIRE_LAWS)} "
                           "(docs/vehicle.md, 'The tire equation')")
    fy_term = data["wheels"].get("tire_lateral_force", False)
    if not isinstance(fy_term, bool):
        raise VehicleError(f"{where}: [wheels] tire_lateral_force must be true or false; got {fy_term!r}")
    if fy_term and tire_law != "progressive":
        raise VehicleError(f"{where}: [wheels] tire_lateral_force = true is an option of the progressive tire law; "
                           "add tire_law = \"progressive\" (docs/vehicle.md, 'The tire equation')")
    truth = None
    if "truth" in data:
        given = _parameters(data["truth"], names, where, "truth", complete=False, geometry=geometry)
        truth = _truth(given, a_priori, known, geometry, tables, where, knees)
    name = data["name"].strip()
    if not name:
        raise VehicleError(f"{where}: name is empty; give the car's name")
    return Vehicle(name, geometry, tables, aero, ParameterSet("a priori", a_priori, dict.fromkeys(a_priori, where)),
                   truth, known, where, ratio, tire_offsets=tire_offsets, tire_law=tire_law,
                   tire_lateral_force=fy_term,
                   damper_friction=damper_friction, **fitted, defaulted_tables=defaulted, dynamics=dynamics,
                   damper_law=damper_law, damper_knees=knees)


DAMPER_LAWS = ("linear", "curve")
_KNEE_KEYS = ("knee_bump_m_s", "knee_rebound_m_s")


def _dampers(t: dict, where: str) -> tuple[str, dict[int, tuple[float, float]]]:
    """[dampers]: the law and the knees per damper frame ((v-, v+), m/s; {} when none are given)."""
    _keys(t, {"law", *_KNEE_KEYS, "front", "rear"}, where, "[dampers]")
    law = t.get("law", "linear")
    if law not in DAMPER_LAWS:
        raise VehicleError(f"{where}: [dampers] law = {law!r}; give one of {', '.join(DAMPER_LAWS)} "
                           "(docs/vehicle.md, 'Damper curves')")
    knees: dict[int, tuple[float, float]] = {}
    for axle, corners in (("rear", (0, 1)), ("front", (2, 3))):
        sub = t.get(axle, {})
        if not isinstance(sub, dict):
            raise VehicleError(f"{where}: [dampers] {axle} must be a table [dampers.{axle}] of {', '.join(_KNEE_KEYS)}")
        _keys(sub, set(_KNEE_KEYS), where, f"[dampers.{axle}]")
        pair = []
        for key in _KNEE_KEYS:
            v, sec = (sub[key], f"[dampers.{axle}]") if key in sub else (t.get(key), "[dampers]")
            if v is None:
                break
            if isinstance(v, str) and v.strip().lower() == "inf":
                v = math.inf
            if isinstance(v, bool) or not isinstance(v, int | float) or not v > 0.0:
                raise VehicleError(f"{where}: {sec} {key} = {v!r}: give the knee's speed in m/s, a number > 0 "
                                   "(\"inf\": no knee on that side), like 0.1")
            if math.isfinite(v) and not 0.005 <= v <= 2.0:
                raise VehicleError(f"{where}: {sec} {key} = {v:g} m/s is outside 0.005..2 m/s for a damper's knee; "
                                   "is the unit right? (m/s of the clearance)")
            pair.append(float(v))
        if len(pair) == 2:
            for k in corners:
                knees[DAMPERS[k]] = (-pair[1], pair[0])
        elif pair:
            raise VehicleError(f"{where}: [dampers] the {axle} dampers have {_KNEE_KEYS[0]} but no {_KNEE_KEYS[1]}: "
                               "give both knees, or neither (law = \"curve\" then chooses them from the data, "
                               "docs/vehicle.md 'Damper curves')")
    return law, knees


def _curve_names(d: int) -> list[str]:
    return [f"{t}{d}" for t in CURVE_LABELS]


def _curves(values: dict[str, float], law: str, knees: dict[int, tuple[float, float]], where: str,
            section: str) -> dict[str, float]:
    """A parameter set with each curved damper's four slopes in place of its h (a slope not given is h), where the
    law (a priori) or the set itself (truth: a slope given) says the damper has a curve."""
    out = dict(values)
    for d in DAMPERS:
        given = [n for n in _curve_names(d) if n in values]
        if law != "curve" and section == "a_priori":
            if given:
                lab = labels()
                raise VehicleError(f"{where}: [{section}] {lab[given[0]]} is a damper curve's slope, but [dampers] law "
                                   "is \"linear\": set law = \"curve\" (with its knees), or give h only")
            continue
        if section == "truth" and not given:
            continue
        if d not in knees and section == "a_priori" and not given:
            continue  # its knees come from the data (Vehicle.with_knees): h until then
        if d not in knees:
            lab = labels()
            raise VehicleError(f"{where}: [{section}] {lab[given[0]]} is a damper curve's slope: give its knees, "
                               "knee_bump_m_s and knee_rebound_m_s in [dampers]")
        lo, hi = knees[d]
        h = out.pop(f"FV{d}", 0.0)
        for n in _curve_names(d):
            high = (n.startswith("FVPH") and math.isfinite(hi)) or (n.startswith("FVNH") and math.isfinite(lo))
            if n.startswith(("FVPL", "FVNL")) or high:
                out[n] = values.get(n, h)
            elif n in values:
                raise VehicleError(f"{where}: [{section}] {labels()[n]} is a high-speed slope, but that side's knee is "
                                   "\"inf\" (no knee): remove it, or give the knee")
    return out


def _check_known_dampers(known: dict[str, float], law: str, where: str) -> None:
    """[known] of a damper's viscous term: h with the linear law, the slopes with the curve."""
    lab = labels()
    for d in DAMPERS:
        if law == "curve" and f"FV{d}" in known:
            raise VehicleError(f"{where}: [known] h{d}: with [dampers] law = \"curve\" the damper has four slopes, not "
                               f"h: give {', '.join(lab[n] for n in _curve_names(d))}")
        if law != "curve" and any(n in known for n in _curve_names(d)):
            raise VehicleError(f"{where}: [known] gives a curve slope of damper {d} but [dampers] law is \"linear\"")


def _damper_friction(t: dict, where: str, sec: str) -> tuple[str, float] | None:
    """damper_friction = "sign" (the default: fs sign(qd)) or { shape = "tanh" | "sigmoid", vs_m_s = ... }: the dry
    friction of the axle's dampers as a smooth law of the clearance rate (`model.tree.FRICTION_SHAPES`)."""
    raw = t.get("damper_friction", "sign")
    if raw == "sign":
        return None
    smooth = [s for s in FRICTION_SHAPES if s != "sign"]
    if not isinstance(raw, dict) or set(raw) != {"shape", "vs_m_s"} or raw["shape"] not in smooth:
        raise VehicleError(f"{where}: {sec} damper_friction = {raw!r}; give \"sign\" or {{ shape = \"tanh\" or "
                           f"\"sigmoid\", vs_m_s = the rate (m/s) below which the friction is not developed }}")
    vs = raw["vs_m_s"]
    if isinstance(vs, bool) or not isinstance(vs, int | float) or not 0.0 < vs <= 0.5:
        raise VehicleError(f"{where}: {sec} damper_friction vs_m_s = {vs!r}; give a rate in m/s in (0, 0.5], e.g. "
                           "0.002")
    return raw["shape"], float(vs)


def _sensors(t: dict, where: str) -> dict:
    """[sensors]: cameras, lasers, correvit (true: fitted, the default) and gnss_position_m (where the GNSS/INS
    velocity is measured when there is no Correvit), the sensors' points, and `dynamics` (checked by
    `dynamics.parse_dynamics` once the suite is known). The inertial unit, the dynamometric wheels and the
    steering-wheel encoder are always fitted."""
    _keys(t, {"cameras", "lasers", "correvit", "gnss_position_m", "correvit_position_m", "laser_positions_m",
              "dynamics"}, where, "[sensors]")
    out: dict = {"dynamics": t.get("dynamics")}
    for k in ("cameras", "lasers", "correvit"):
        v = t.get(k, True)
        if not isinstance(v, bool):
            raise VehicleError(f"{where}: [sensors] {k} = {v!r} must be true or false")
        out[k] = v
    gnss = t.get("gnss_position_m")
    if gnss is not None and out["correvit"]:
        raise VehicleError(f"{where}: [sensors] gnss_position_m is for a car without a Correvit: add correvit = false "
                           "(the horizontal velocity then comes from the GNSS/INS), or remove it")
    out["gnss_position"] = None if gnss is None else tuple(float(x) for x in _vector(gnss, (3,), where,
                                                                                     "[sensors] gnss_position_m"))
    c = t.get("correvit_position_m")
    out["correvit_position"] = None if c is None else tuple(
        float(x) for x in _vector(c, (3,), where, "[sensors] correvit_position_m"))
    lasers = t.get("laser_positions_m")
    out["laser_positions"] = None if lasers is None else tuple(
        tuple(float(x) for x in row) for row in _vector(lasers, (4, 3), where,
                                                        "[sensors] laser_positions_m (rear left, rear right, front "
                                                        "left, front right)"))
    return out


def _check_points(g: CarGeometry, where: str) -> None:
    """Sensor points a car can carry: above the ground (x6 above the wheel centres' height minus the radius) and
    within 3 m of O6."""

    ground = g.wheel_centre_height - g.wheel_radius
    named = [("[sensors] correvit_position_m", correvit_point(g)), ("[sensors] gnss_position_m", gnss_point(g))]
    named += [(f"[sensors] laser_positions_m[{k}]", laser_point(g, k)) for k in range(4)]
    named.append(("[imu] position_m", np.asarray(g.imu_position, dtype=float)))
    for key, p in named:
        if p[0] <= ground + 0.05 or float(np.linalg.norm(p)) > 3.0 + g.wheelbase:
            raise VehicleError(f"{where}: {key} = {[float(x) for x in p]} m is not on the car (x6 must be above the "
                               f"ground, {ground + 0.05:.3g} m, and the point within {3.0 + g.wheelbase:.3g} m of "
                               "O6); frame 6: x6 up, y6 right, z6 forward, origin on the rear axle; lengths in m")


def _keys(table: dict, valid: set[str], where: str, section: str) -> None:
    unknown = [k for k in table if k not in valid]
    if unknown:
        raise VehicleError(f"{where}: {section}: {unknown_keys(unknown, sorted(valid))}")


def _number(table: dict, key: str, where: str, section: str, default: float | None = None) -> float:
    if key not in table:
        if default is None:
            raise VehicleError(f"{where}: {section}: missing {key}")
        return default
    v = table[key]
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise VehicleError(f"{where}: {section}: {key} = {v!r} must be a finite number")
    lo_hi = RANGES.get(key)
    if lo_hi is not None and not lo_hi[0] <= v <= lo_hi[1]:
        raise VehicleError(f"{where}: {section}: {key} = {v} is outside {lo_hi[0]}..{lo_hi[1]} for a passenger car "
                           f"(is the unit right? the key says it: {key.rsplit('_', 1)[-1]})")
    if key.endswith("_deg") and abs(v) > ANGLE_LIMIT_DEG:
        raise VehicleError(f"{where}: {section}: {key} = {v}° tilts the axis more than {ANGLE_LIMIT_DEG:g}° from the "
                           "vertical (an axis nearly parallel to the ground guides no suspension); angles are in "
                           "degrees")
    return float(v)


def _geometry(data: dict, where: str) -> CarGeometry:
    """[axles], [wheels], [imu] checked (keys, numbers, ranges: the message names the key), then the geometry they
    give (`geometry.file_geometry`, without the sensors' points: [sensors] is checked after)."""
    axles = data["axles"]
    _keys(axles, {"wheelbase_m", "front", "rear"}, where, "[axles]")
    for a in ("front", "rear"):
        if not isinstance(axles.get(a), dict):
            raise VehicleError(f"{where}: missing the table [axles.{a}] (half_track_m, damper tilts, kingpin, ...)")
    _number(axles, "wheelbase_m", where, "[axles]")
    wheels = data["wheels"]
    _keys(wheels, {"radius_m", "centre_height_m", "unloaded_radius_known", "tire_law",
                    "tire_lateral_force"}, where, "[wheels]")
    imu = data.get("imu", {})
    _keys(imu, {"position_m", "axes"}, where, "[imu]")
    _vector(imu.get("position_m", [0.0, 0.0, 0.0]), (3,), where, "[imu] position_m")
    _vector(imu.get("axes", [[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]]), (3, 3), where, "[imu] axes")
    for a in ("front", "rear"):
        t = axles[a]
        sec = f"[axles.{a}]"
        _keys(t, AXLE_KEYS, where, sec)
        if not isinstance(t.get("anti_roll_bar", True), bool):
            raise VehicleError(f"{where}: {sec}: anti_roll_bar = {t['anti_roll_bar']!r} must be true or false")
        for k in ("damper_lateral_tilt", "damper_longitudinal_tilt", "kingpin_inclination", "caster"):
            _number(t, f"{k}_deg", where, sec, 0.0)
        _number(t, "half_track_m", where, sec)
        _number(t, "kingpin_offset_m", where, sec, 0.0)
    _number(wheels, "radius_m", where, "[wheels]")
    _number(wheels, "centre_height_m", where, "[wheels]", 0.0)
    try:
        return file_geometry({k: data[k] for k in ("axles", "wheels", "imu") if k in data})
    except GeometryError as exc:
        raise VehicleError(f"{where}: {exc}") from None


def _vector(v, shape: tuple[int, ...], where: str, what: str) -> np.ndarray:
    try:
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        a = None
    if a is None or a.shape != shape or not np.isfinite(a).all():
        raise VehicleError(f"{where}: {what} must be {'x'.join(map(str, shape))} finite numbers; got {v!r}")
    return a


def _tables(t: dict, g: CarGeometry, ratio: float, path: Path) -> tuple[KinematicTables, tuple[str, ...]]:
    """The file's kinematic tables over dynid's defaults, and which ones ("front_left.caster", ...) are defaults."""
    where = str(path)
    _keys(t, {"file", *CORNER_KEYS}, where, "[tables]")
    defaults = tables = default_tables(g, ratio)
    try:
        if "file" in t:
            tables = load_table_file(path.parent / str(t["file"]), defaults=tables)
        for ckey in CORNER_KEYS:
            corner = t.get(ckey, {})
            if not isinstance(corner, dict):
                raise VehicleError(f"{where}: [tables.{ckey}] must be a table of {', '.join(TABLE_NAMES)}")
            _keys(corner, set(TABLE_NAMES), where, f"[tables.{ckey}]")
            for name, spec in corner.items():
                if not isinstance(spec, dict) or "csv" not in spec:
                    raise VehicleError(f"{where}: [tables.{ckey}] {name} = {{ csv = \"file.csv\", units = \"deg\" }}")
                _keys(spec, {"csv", "units"}, where, f"[tables.{ckey}] {name}")
                k = CORNER_KEYS.index(ckey)
                tab = load_table_csv(path.parent / str(spec["csv"]), name, CORNERS[k],
                                     spec.get("units", "rad"))
                tables = tables.replace(k, name, tab)
    except KinematicTableError as exc:
        raise VehicleError(f"{where}: [tables]: {exc}") from None
    defaulted = tuple(f"{CORNER_KEYS[k]}.{n}" for k in range(4) for n in TABLE_NAMES
                      if tables.table(k, n) is defaults.table(k, n))
    return tables, defaulted


def _aero(t: dict, g: CarGeometry, path: Path) -> Aerodynamics:
    """The file's density, area, length and coefficient tables (`file`: a CSV with columns beta_deg, cx, cy, cz,
    cl, cm, cn; default: a saloon's), applied at this car's reference point (mid-wheelbase, centreline, ground)."""
    where = str(path)
    _keys(t, {"rho_kg_m3", "area_m2", "length_m", "file"}, where, "[aero]")
    d = Aerodynamics()
    tables = _aero_tables(path.parent / str(t["file"]), where) if "file" in t else {}
    try:
        return Aerodynamics(rho=_number(t, "rho_kg_m3", where, "[aero]", d.rho),
                            area=_number(t, "area_m2", where, "[aero]", d.area),
                            length=_number(t, "length_m", where, "[aero]", d.length),
                            point=tuple(float(x) for x in reference_point(g)), **tables)
    except AeroError as exc:
        raise VehicleError(f"{where}: [aero]: {exc}") from None


def _aero_tables(csv_path: Path, where: str) -> dict[str, np.ndarray]:
    """beta (rad) and the six coefficients from a CSV: a header naming beta_deg, cx, cy, cz, cl, cm, cn (any order),
    then one row per sideslip angle."""
    names = ("beta_deg", *COEFFICIENTS)
    try:
        rows = read_csv_rows(csv_path)
    except OSError as exc:
        raise VehicleError(f"{where}: [aero] file {csv_path}: cannot read it ({exc.strerror})") from None
    except TextEncodingError as exc:
        raise VehicleError(f"{where}: [aero] file {csv_path}: {exc}") from None
    head = [c.strip() for c in rows[0]] if rows else []
    missing = [n for n in names if n not in head]
    if missing:
        raise VehicleError(f"{where}: [aero] file {csv_path}, line 1: the header lacks {', '.join(missing)} (columns: "
                           f"{', '.join(names)})")
    cols = [head.index(n) for n in names]
    data = []
    for line, r in enumerate(rows[1:], start=2):
        try:
            data.append([float(r[i]) for i in cols])
        except (ValueError, IndexError):
            raise VehicleError(f"{where}: [aero] file {csv_path}, line {line}: expected numbers in every column, got "
                               f"{r}") from None
    a = np.asarray(data, dtype=float).reshape(-1, len(names))
    return {"beta": np.radians(a[:, 0]), **{n: a[:, i + 1] for i, n in enumerate(COEFFICIENTS)}}


def _parameter_names() -> dict[str, str]:
    """Accepted name or label -> dynid name, for the paper's 48 parameters."""
    lab = labels()
    out = {n: n for n in paper_parameter_names()}
    out.update({lab[n]: n for n in paper_parameter_names() if n in lab})
    for d in DAMPERS:  # the dampers' curve slopes ([dampers] law = "curve", or a curve in [truth])
        out.update({n: n for n in _curve_names(d)})
        out.update({lab[n]: n for n in _curve_names(d)})
    return out


# plausible passenger-car ranges of the paper's 48 parameters (SI): outside them the value is a unit slip (g for kg,
# N/mm for N/m) or a typo; wide enough for a small city car to a large van. docs/vehicle.md lists them


def parameter_range(name: str) -> tuple[float, float, str, str]:
    """(low, high, unit, what) of a template parameter's plausible value for a passenger car."""
    kind, frame = name.rstrip("0123456789"), name[len(name.rstrip("0123456789")):]
    j = int(frame) if frame else 0
    if j == CHASSIS:
        return {"M": (300.0, 4000.0, "kg", "the body's mass, wheels apart"),
                "XX": (0.0, 2e5, "kg·m²", "a moment of inertia of the body about O6"),
                "YY": (0.0, 2e5, "kg·m²", "a moment of inertia of the body about O6"),
                "ZZ": (0.0, 2e5, "kg·m²", "a moment of inertia of the body about O6"),
                }.get(kind, (-2e5, 2e5, "kg·m² or kg·m", "a product of inertia or first moment of the body"))
    if j in WHEELS:
        return {"M": (1.0, 200.0, "kg", "a wheel's mass")}.get(kind, (0.0, 50.0, "kg·m²", "a wheel's inertia"))
    if j in TIRES:
        return (1e4, 5e6, "N/m", "a tire's vertical stiffness kt")
    if kind in CURVE_LABELS:
        return 0.0, 1e5, "N·s/m", "a damper curve's slope"
    return {"K": (1e3, 1e6, "N/m", "a suspension spring's stiffness ks"),
            "FV": (0.0, 1e5, "N·s/m", "a damper's viscous coefficient h"),
            "FS": (0.0, 1e4, "N", "a damper's dry friction fs"),
            "OFF": (-1e5, 1e5, "N", "a damper's offset (preload) off"),
            "karf": (0.0, 1e6, "N/m", "an anti-roll bar's stiffness"),
            "karr": (0.0, 1e6, "N/m", "an anti-roll bar's stiffness")}.get(kind, (-math.inf, math.inf, "", ""))


# [a_priori.chassis], [truth.chassis], [known.chassis]: the chassis as a data sheet gives it, in place of XX6..M6.
# key -> (low, high, unit, what); the CoG's position ahead of the rear axle is checked against the wheelbase
CHASSIS_SHEET = {
    "mass_kg": (300.0, 4000.0, "kg", "the chassis's (sprung) mass, wheels apart"),
    "cog_ahead_of_rear_axle_m": (0.0, math.inf, "m", "the chassis's CoG ahead of the rear axle, between the axles"),
    "cog_above_ground_m": (0.15, 1.5, "m", "the chassis's CoG above the ground at design ride height"),
    "cog_above_wheel_centres_m": (-0.3, 1.2, "m", "the chassis's CoG above the wheel centres at design"),
    "cog_left_m": (-0.3, 0.3, "m", "the chassis's CoG left of the centreline (ISO y)"),
    "Ixx_kg_m2": (50.0, 2e4, "kg·m²", "roll inertia at the CoG (ISO x forward)"),
    "Iyy_kg_m2": (200.0, 5e4, "kg·m²", "pitch inertia at the CoG (ISO y left)"),
    "Izz_kg_m2": (200.0, 5e4, "kg·m²", "yaw inertia at the CoG (ISO z up)"),
    "Ixy_kg_m2": (-1e4, 1e4, "kg·m²", "inertia matrix entry xy at the CoG, -∫xy dm"),
    "Ixz_kg_m2": (-1e4, 1e4, "kg·m²", "inertia matrix entry xz at the CoG, -∫xz dm"),
    "Iyz_kg_m2": (-1e4, 1e4, "kg·m²", "inertia matrix entry yz at the CoG, -∫yz dm"),
}
CHASSIS_PARAMETERS = ("XX6", "XY6", "XZ6", "YY6", "YZ6", "ZZ6", "MX6", "MY6", "MZ6", "M6")


def _chassis_sheet(t: object, g: CarGeometry, where: str, section: str) -> dict[str, float]:
    """XX6..M6 from a [section.chassis] data sheet (`engineering.chassis_from_data_sheet`), every key checked."""

    sec = f"[{section}.chassis]"
    if not isinstance(t, dict):
        raise VehicleError(f"{where}: {sec} must be a table (mass_kg, cog_ahead_of_rear_axle_m, cog_above_ground_m, "
                           f"Ixx_kg_m2, ...); got {t!r}")
    _keys(t, set(CHASSIS_SHEET), where, sec)
    heights = [k for k in ("cog_above_ground_m", "cog_above_wheel_centres_m") if k in t]
    missing = [k for k in ("mass_kg", "cog_ahead_of_rear_axle_m", "Ixx_kg_m2", "Iyy_kg_m2", "Izz_kg_m2") if k not in t]
    if len(heights) != 1:
        missing.append("cog_above_ground_m (or cog_above_wheel_centres_m)" if not heights else
                       "not both: cog_above_ground_m and cog_above_wheel_centres_m, only one")
    if missing:
        raise VehicleError(f"{where}: {sec}: missing {', '.join(missing)}")
    x: dict[str, float] = {}
    for k, v in t.items():
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise VehicleError(f"{where}: {sec} {k} = {v!r} must be a finite number (the unit is in the key)")
        lo, hi, unit, what = CHASSIS_SHEET[k]
        hi = g.wheelbase if k == "cog_ahead_of_rear_axle_m" else hi
        if not lo <= v <= hi:
            raise VehicleError(f"{where}: {sec} {k} = {v:g} is outside {lo:g}..{hi:g} {unit} for a passenger car "
                               f"({what}); is the unit right?")
        x[k] = float(v)
    above = (x["cog_above_ground_m"] if heights[0] == "cog_above_ground_m"
             else x["cog_above_wheel_centres_m"] + g.wheel_radius)
    J = np.array([[x["Ixx_kg_m2"], x.get("Ixy_kg_m2", 0.0), x.get("Ixz_kg_m2", 0.0)],
                  [x.get("Ixy_kg_m2", 0.0), x["Iyy_kg_m2"], x.get("Iyz_kg_m2", 0.0)],
                  [x.get("Ixz_kg_m2", 0.0), x.get("Iyz_kg_m2", 0.0), x["Izz_kg_m2"]]])
    return chassis_from_data_sheet(x["mass_kg"], x["cog_ahead_of_rear_axle_m"], above, x.get("cog_left_m", 0.0), J, g)


def chassis_sheet_keys(values: dict[str, float], g: CarGeometry) -> dict[str, float]:
    """The [*.chassis] keys of a parameter set's XX6..M6 (`engineering.chassis_data_sheet`): what `dynid vehicle
    show` prints, and what reads back to the same XX6..M6."""

    d = chassis_data_sheet(values, g)
    tiny = 1e-13 * max(abs(d["Ixx"]), abs(d["Iyy"]), abs(d["Izz"]))  # a product that is round-off of 0 reads 0
    d = {k: 0.0 if k.startswith("I") and abs(x) < tiny else x for k, x in d.items()}
    return {"mass_kg": d["mass_sprung"], "cog_ahead_of_rear_axle_m": d["cgs_ahead_rear"],
            "cog_above_ground_m": d["cgs_height"], "cog_above_wheel_centres_m": d["cgs_height"] - g.wheel_radius,
            "cog_left_m": d["cgs_lateral"], "Ixx_kg_m2": d["Ixx"], "Iyy_kg_m2": d["Iyy"], "Izz_kg_m2": d["Izz"],
            "Ixy_kg_m2": d["Ixy"], "Ixz_kg_m2": d["Ixz"], "Iyz_kg_m2": d["Iyz"]}


def _parameters(t: dict, names: dict[str, str], where: str, section: str, complete: bool,
                geometry: CarGeometry | None = None) -> dict[str, float]:
    t = dict(t)
    sheet: dict[str, float] = {}
    if "chassis" in t and geometry is not None:
        given = [k for k in t if names.get(k) in CHASSIS_PARAMETERS]
        if given:
            raise VehicleError(f"{where}: [{section}] gives {', '.join(given)} and [{section}.chassis]: give the "
                               "chassis one way, its data sheet or the frame-6 parameters XX6..M6")
        sheet = _chassis_sheet(t.pop("chassis"), geometry, where, section)
    out: dict[str, float] = {}
    for k, v in t.items():
        if k not in names:
            hint = did_you_mean(k, sorted(names))
            raise VehicleError(f"{where}: [{section}] unknown parameter {k!r}{';' + hint if hint else ''} (the paper's "
                               "48: XX6..M6, ks9 h9 "
                               "fs9 off9 (K9 FV9 FS9 OFF9), XX14 YY14 ZZ14 M14, kt15 (K15), ..., karf, karr)")
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise VehicleError(f"{where}: [{section}] {k} = {v!r} must be a finite number (SI units)")
        n = names[k]
        if n in out:
            raise VehicleError(f"{where}: [{section}] {n} is given twice (as a name and as a label)")
        out[n] = float(v)
    out.update(sheet)
    for n, v in out.items():
        kind = n.rstrip("0123456789")
        if (kind == "M" or kind in ("K", "FV", "FS", "karf", "karr", *CURVE_LABELS)) and v < 0:
            raise VehicleError(f"{where}: [{section}] {n} = {v}: a mass, stiffness, damping or friction is >= 0")
    given = {names[k]: k for k in t}
    for n, v in out.items():
        lo, hi, unit, what = parameter_range(n)
        if not lo <= v <= hi:
            key = given.get(n, n)
            raise VehicleError(f"{where}: [{section}] {key} = {v:g} is outside {lo:g}..{hi:g} {unit} for a passenger "
                               f"car ({what}); is the unit right? parameters are SI")
    if complete:
        absent = [n for n in paper_parameter_names() if n not in out
                  and not n.startswith(("FS", "OFF"))]  # the paper gives no a priori fs and off: 0
        if absent:
            raise VehicleError(f"{where}: [{section}] lacks {', '.join(absent[:8])}{' ...' if len(absent) > 8 else ''}"
                               " (every parameter needs an a priori value; fs and off may be left out: 0)")
        out = {**{n: out.get(n, 0.0) for n in paper_parameter_names()}, **out}
    return out


def _truth(given: dict[str, float], a_priori: dict[str, float], known: dict[str, float], g: CarGeometry,
           tables: KinematicTables, where: str, knees: dict[int, tuple[float, float]]) -> ParameterSet:
    """The simulation's set: the file's [truth], the known values and the a priori values for the rest; a damper
    offset not given is left out: `Vehicle.truth` solves it, the static preload that holds the damper at its design
    position. A damper whose curve slopes [truth] gives drives with that curve (a slope not given: the truth's h);
    the others with h (the a priori's when the a priori set has a curve)."""
    curved = {d for d in DAMPERS if any(n in given for n in _curve_names(d))}
    values = {**a_priori, **known, **given}
    for d in DAMPERS:
        slopes = [n for n in _curve_names(d) if n in values]
        if f"FV{d}" not in values and slopes:  # an a priori curve: its low-speed slopes' mean stands for h
            values[f"FV{d}"] = 0.5 * (values[f"FVPL{d}"] + values[f"FVNL{d}"])
        for n in slopes if d not in curved else [n for n in slopes if n not in given]:
            del values[n]  # the truth's curve is its own, a slope it leaves out is its h (_curves)
    values = _curves(values, "linear", knees, where, "truth")
    sources = {n: f"{where} [truth]" if n in given else f"{where} [known]" if n in known else f"{where} [a_priori]"
               for n in values}
    problems = check_physical(values, frames=[6, *WHEELS])
    if problems:
        raise VehicleError(f"{where}: [truth] is not a physically realisable car: {problems[0]} (a simulation needs "
                           "one: mass > 0, inertia at the centre of mass positive definite, triangle inequalities)")
    for d in DAMPERS:  # an offset the file leaves out is the static preload, solved at first use (Vehicle.truth)
        if f"OFF{d}" not in given:
            del values[f"OFF{d}"], sources[f"OFF{d}"]
    return ParameterSet("truth", values, sources)
