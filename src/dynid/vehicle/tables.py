"""Kinematic tables of the suspensions: the tabulated joints versus damper clearance and steering.

Per corner, four tables give the joint variables of frames b+3..b+6 (b = 7, 16, 25, 34)
as functions of the corner's damper clearance u = q(b+2) (m, bump positive) and the
steering-wheel angle h (rad, positive to the left):

  "steering"  q(b+3)  wheel steer about the chassis vertical, > 0 to the left (toe, bump
                      steer, and the steering rack on the front axle)
  "camber"    q(b+4)  camber, > 0 top of the wheel outboard
  "caster"    q(b+5)  side-view rotation of the hub (caster change, wind-up), > 0 top rearward
  "kingpin"   q(b+6)  rotation of the hub about its kingpin axis not already in the steering
                      and camber tables (zero in the defaults: a hook for a maker's table)

Values are interpolated by bicubic splines through the grid points (C2 in each input), so
joint velocities and accelerations follow by the chain rule. A table that does not depend
on the steering is given on one steering value (or in a two-column CSV) and interpolated by
a cubic spline in u. Inputs outside a table's grid raise KinematicTableError naming the
table, the input, the sample and the range: the tables are never extrapolated.

Files. CSV: either two columns (travel, value), or a grid whose first row is a label then
the steering values and whose next rows are a travel value then the table's values at each
steering value. TOML: one table per key "corner.name" (corner among rear_left, rear_right,
front_left, front_right; name among the four above) with arrays `travel`, optional
`steering`, and `values` (a list, or a list of rows, one per travel value); `units =
"deg"` says the angles (values and steering) are in degrees. Lengths are in metres.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline, RectBivariateSpline

from ..model.files import read_toml
from ..model.tree import ModelError
from ..model.workspace import PerObject
from ..textfiles import TextEncodingError, read_csv_rows
from .geometry import CarGeometry, demo_geometry, side
from .table_poly import pack, table_joints
from .template import CORNERS, damper, tabulated

TABLE_NAMES = ("steering", "camber", "caster", "kingpin")
CORNER_KEYS = ("rear_left", "rear_right", "front_left", "front_right")
Array = np.ndarray


class KinematicTableError(ModelError):
    """A kinematic table that cannot be built, read or evaluated where asked."""


@dataclass(frozen=True)
class KinematicTable:
    """One table: value(travel, steering) on a grid (travel m, steering rad, value rad).

    steering: None for a table of travel only (values then 1-D).
    """

    name: str
    corner: str
    travel: Array
    values: Array
    steering: Array | None = None
    _spline: object = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        where = f"kinematic table {self.name!r} of the {self.corner} corner"
        x = np.asarray(self.travel, dtype=float)
        v = np.asarray(self.values, dtype=float)
        y = None if self.steering is None else np.asarray(self.steering, dtype=float)
        if y is not None and y.size == 1:
            y, v = None, v.reshape(-1)
        _check_grid(x, "travel", where)
        if y is None:
            if v.shape != x.shape:
                raise KinematicTableError(f"{where}: {x.size} travel values but values of shape {v.shape}")
            spline = CubicSpline(x, v)
        else:
            _check_grid(y, "steering", where)
            if v.shape != (x.size, y.size):
                raise KinematicTableError(
                    f"{where}: values must be ({x.size} travel, {y.size} steering); got {v.shape}"
                )
            spline = RectBivariateSpline(x, y, v, kx=3, ky=3, s=0)
        if not np.isfinite(v).all():
            raise KinematicTableError(f"{where}: values contain a non-finite number")
        object.__setattr__(self, "travel", x)
        object.__setattr__(self, "steering", y)
        object.__setattr__(self, "values", v)
        object.__setattr__(self, "_spline", spline)

    def _check(self, a: Array, grid: Array, what: str, unit: str) -> None:
        bad = (a < grid[0] - 1e-12) | (a > grid[-1] + 1e-12)
        if bad.any():
            i = int(np.argmax(bad))
            raise KinematicTableError(
                f"kinematic table {self.name!r} of the {self.corner} corner: {what} = {a[i]:.6g} {unit} at "
                f"sample {i} is outside the table's range [{grid[0]:.6g}, {grid[-1]:.6g}] {unit}; "
                f"extend the table or check the {what} signal"
            )

    def derivatives(self, u: Array, h: Array) -> tuple[Array, ...]:
        """(f, f_u, f_h, f_uu, f_uh, f_hh) at the samples (u, h), each (N,)."""
        u, h = np.atleast_1d(np.asarray(u, dtype=float)), np.atleast_1d(np.asarray(h, dtype=float))
        self._check(u, self.travel, "damper clearance", "m")
        if self.steering is None:
            s = self._spline
            z = np.zeros_like(u)
            return s(u), s(u, 1), z, s(u, 2), z, z
        self._check(h, self.steering, "steering-wheel angle", "rad")
        ev = self._spline.ev
        return ev(u, h), ev(u, h, 1, 0), ev(u, h, 0, 1), ev(u, h, 2, 0), ev(u, h, 1, 1), ev(u, h, 0, 2)

    def __call__(self, u: Array, h: Array | float = 0.0) -> Array:
        u = np.atleast_1d(np.asarray(u, dtype=float))
        return self.derivatives(u, np.broadcast_to(np.asarray(h, dtype=float), u.shape))[0]


def _check_grid(a: Array, what: str, where: str) -> None:
    if a.ndim != 1 or a.size < 4:
        raise KinematicTableError(f"{where}: {what} must be a list of at least 4 values (cubic interpolation)")
    if not np.isfinite(a).all() or not (np.diff(a) > 0).all():
        raise KinematicTableError(f"{where}: {what} values must be finite and strictly increasing")


# per KinematicTables, its tables packed for `table_joints` by selection (`KinematicTables._packed`): kept beside
# the frozen tables while they live, a few selections each
_PACKED: PerObject[KinematicTables, dict[tuple, tuple]] = PerObject(lambda tables: {})


@dataclass(frozen=True)
class KinematicTables:
    """The four tables of each corner: tables[corner][name], corner 0 rear left .. 3 front right."""

    tables: tuple[Mapping[str, KinematicTable], ...]

    def __post_init__(self) -> None:
        if len(self.tables) != 4 or any(set(t) != set(TABLE_NAMES) for t in self.tables):
            raise KinematicTableError(f"kinematic tables: need the tables {TABLE_NAMES} for each of the 4 corners")

    def _packed(self, todo: tuple[tuple[int, str], ...]) -> tuple:
        """The tables `todo` (corner, name) packed for `table_joints`, with which tables use the steering and
        their damper and joint columns; built once per set (the tables are immutable) and kept beside them."""
        packed = _PACKED(self)
        hit = packed.get(todo)
        if hit is None:
            tabs = [self.tables[k][n] for k, n in todo]
            steering = np.array([t.steering is not None for t in tabs])
            # the damper's and the tabulated joint's columns (frame j in column j - 1)
            u_cols = np.array([damper(k) - 1 for k, _ in todo], dtype=np.int64)
            out_cols = np.array([tabulated(k)[TABLE_NAMES.index(n)] - 1 for k, n in todo], dtype=np.int64)
            hit = packed.setdefault(todo, (*pack(tabs), steering, u_cols, out_cols))  # two threads: the first kept
        return hit

    def table(self, corner: int, name: str) -> KinematicTable:
        return self.tables[corner][name]

    def replace(self, corner: int, name: str, table: KinematicTable) -> KinematicTables:
        new = [dict(t) for t in self.tables]
        new[corner][name] = table
        return KinematicTables(tuple(new))

    def joints(
        self,
        q: Array,
        qd: Array,
        qdd: Array,
        steering_wheel: tuple[Array, Array, Array] | Array | float = 0.0,
        measured: Sequence[str] = (),
        copy: bool = True,
    ) -> tuple[Array, Array, Array]:
        """Copies of q, qd, qdd (N, 42) with the tabulated joints filled from the damper columns.

        steering_wheel: (h, h', h'') arrays (N,) or one angle (rad, held still). measured:
        table names whose joints are already in q, qd, qdd (e.g. ("steering", "camber") from a
        camera) and are kept. copy=False fills float (N, 42) arrays in place (the returned ones are used).
        """
        # F order always, so that the compiled kernel (given the C-order transposes) sees one layout and compiles
        # once, and reads and writes each joint's samples contiguously; the car estimator builds its joints
        # column-major, so copy=False fills its arrays in place (a C-order caller's arrays are copied even with
        # copy=False: the returned ones are filled)
        q, qd, qdd = (np.array(a, dtype=float, ndmin=2, copy=True if copy else None, order="F") for a in (q, qd, qdd))
        N = q.shape[0]
        if isinstance(steering_wheel, tuple):
            h, hd, hdd = (np.broadcast_to(np.asarray(a, dtype=float), (N,)) for a in steering_wheel)
        else:
            h = np.broadcast_to(np.asarray(steering_wheel, dtype=float), (N,))
            hd = hdd = np.zeros(N)
        unknown = set(measured) - set(TABLE_NAMES)
        if unknown:
            raise KinematicTableError(f"measured = {sorted(unknown)}: not table names {TABLE_NAMES}")
        todo = [(k, name) for k in range(4) for name in TABLE_NAMES if name not in measured]
        if table_joints is not None and todo:
            packed = self._packed(tuple(todo))
            bad = table_joints(*packed, q.T, qd.T, qdd.T, *(np.array(a, dtype=float) for a in (h, hd, hdd)))  # writable
            if bad < 0:
                return q, qd, qdd
        # without numba, or off a table's grid (the scipy path names the table, input and sample)
        for k, name in todo:
            d, j = damper(k) - 1, tabulated(k)[TABLE_NAMES.index(name)] - 1  # columns (frame j in column j - 1)
            u, ud, udd = q[:, d], qd[:, d], qdd[:, d]
            f, fu, fh, fuu, fuh, fhh = self.tables[k][name].derivatives(u, h)
            q[:, j] = f
            qd[:, j] = fu * ud + fh * hd
            qdd[:, j] = fuu * ud**2 + 2 * fuh * ud * hd + fhh * hd**2 + fu * udd + fh * hdd
        return q, qd, qdd


# ----- defaults -------------------------------------------------------------------------

TRAVEL = np.linspace(-0.12, 0.12, 25)  # m, a saloon's damper travel about the design position
STEERING_WHEEL = np.linspace(-3.0 * np.pi, 3.0 * np.pi, 37)  # rad, +-540° (about 3 turns lock to lock)
STEERING_RATIO = 16.0
ACKERMANN = 0.25  # rad^-1: the inner front wheel steers by delta + 0.25 delta^2


@functools.lru_cache(maxsize=8)  # immutable, and every segment of a test asks for them
def default_tables(geometry: CarGeometry | None = None, ratio: float = STEERING_RATIO) -> KinematicTables:
    """Tables of a mid-size saloon (MacPherson front, multi-link rear), smooth in both inputs: a vehicle file that
    gives no tables of its own has these, from its geometry (default: the demo vehicle's).

    Front: steering ratio `ratio` (steering-wheel angle / mean front-wheel steer, 16) with Ackermann,
    0.1° toe-in, bump steer -0.3°/100 mm, camber -0.5°
    and -1.3°/100 mm, plus the camber a steered wheel takes from the kingpin inclination and
    caster of `geometry`; anti-dive caster +1°/100 mm. Rear: 0.15° toe-in, +0.2°/100 mm
    toe-in in bump, camber -1° and -1.6°/100 mm, wind-up -0.5°/100 mm. Kingpin: zero.
    """
    g = demo_geometry() if geometry is None else geometry
    d = math.radians
    U, H = np.meshgrid(TRAVEL, STEERING_WHEEL, indexing="ij")
    per_corner = []
    for k in range(4):
        s, front = side(k), k >= 2
        if front:
            z = H / ratio
            steer = z - s * ACKERMANN * z**2 + s * (d(0.1) - d(3.0) * U)
            sig, tau = g.front.kingpin_inclination, g.front.caster
            camber = d(-0.5) + d(-13.0) * U - 2.0 * U**2 - s * np.sin(tau) * np.sin(steer) \
                + np.sin(sig) * (1.0 - np.cos(steer))
            caster = d(10.0) * U + 0.0 * H
        else:
            steer = s * (d(0.15) + d(2.0) * U) + 0.0 * H
            camber = d(-1.0) + d(-16.0) * U - 2.0 * U**2 + 0.0 * H
            caster = d(-5.0) * U + 0.0 * H
        name = CORNERS[k]
        vals = {"steering": steer, "camber": camber, "caster": caster, "kingpin": 0.0 * U}
        per_corner.append({
            n: KinematicTable(n, name, TRAVEL, v if (front and n in ("steering", "camber")) else v[:, 0],
                              STEERING_WHEEL if (front and n in ("steering", "camber")) else None)
            for n, v in vals.items()
        })
    return KinematicTables(tuple(per_corner))


# ----- files ------------------------------------------------------------------------------

def load_table_csv(path: str | os.PathLike[str], name: str, corner: str, units: str = "rad") -> KinematicTable:
    """One table from a CSV (two columns travel,value, or a grid: see the module doc)."""
    path = Path(path)
    try:
        rows = read_csv_rows(path)
    except OSError as exc:
        raise KinematicTableError(f"{path}: cannot read the table ({exc.strerror})") from None
    except TextEncodingError as exc:
        raise KinematicTableError(f"{path}: {exc}") from None
    if len(rows) < 5:
        raise KinematicTableError(f"{path}: a table needs a header and at least 4 rows")
    body = rows[1:]
    try:
        data = np.array([[float(c) for c in r] for r in body])
    except ValueError:
        line = next(i for i, r in enumerate(body, start=2) if not _numbers(r))
        raise KinematicTableError(f"{path}, line {line}: expected numbers, got {body[line - 2]}") from None
    if data.ndim != 2:
        raise KinematicTableError(f"{path}: rows have different numbers of columns")
    scale = _angle_scale(units, path)
    if data.shape[1] == 2:
        return _named(lambda: KinematicTable(name, corner, data[:, 0], data[:, 1] * scale), path)
    try:
        steer = np.array([float(c) for c in rows[0][1:]]) * scale
    except ValueError:
        raise KinematicTableError(f"{path}, line 1: the steering values after the first cell must be numbers") from None
    return _named(lambda: KinematicTable(name, corner, data[:, 0], data[:, 1:] * scale, steer), path)


def _numbers(row: Sequence[str]) -> bool:
    try:
        [float(c) for c in row]
    except ValueError:
        return False
    return True


def _angle_scale(units: str, where: object) -> float:
    if units not in ("rad", "deg"):
        raise KinematicTableError(f"{where}: units = {units!r}; use 'rad' or 'deg'")
    return math.pi / 180.0 if units == "deg" else 1.0


def _named(build, path: Path) -> KinematicTable:
    try:
        return build()
    except KinematicTableError as exc:
        raise KinematicTableError(f"{path}: {exc}") from None


def load_tables(path: str | os.PathLike[str], defaults: KinematicTables | None = None) -> KinematicTables:
    """Tables from a TOML file; corners/tables it does not give keep the defaults."""
    path = Path(path)
    data = read_toml(path, "tables", KinematicTableError)
    out = default_tables() if defaults is None else defaults
    for ckey, tabs in data.items():
        if ckey not in CORNER_KEYS or not isinstance(tabs, dict):
            raise KinematicTableError(f"{path}: [{ckey}] is not a corner; corners are {', '.join(CORNER_KEYS)}")
        k = CORNER_KEYS.index(ckey)
        for name, spec in tabs.items():
            if name not in TABLE_NAMES or not isinstance(spec, dict):
                raise KinematicTableError(f"{path}: [{ckey}.{name}] is not a table; tables are {TABLE_NAMES}")
            missing = {"travel", "values"} - set(spec)
            if missing:
                raise KinematicTableError(f"{path}: [{ckey}.{name}] lacks {sorted(missing)}")
            scale = _angle_scale(spec.get("units", "rad"), f"{path}: [{ckey}.{name}]")
            steer = spec.get("steering")
            tab = _named(lambda spec=spec, steer=steer, scale=scale, name=name, k=k: KinematicTable(
                name, CORNERS[k], np.asarray(spec["travel"], dtype=float),
                np.asarray(spec["values"], dtype=float) * scale,
                None if steer is None else np.asarray(steer, dtype=float) * scale), path)
            out = out.replace(k, name, tab)
    return out
