"""URDF in and out: a robot description (ROS URDF) as a modified-DH tree, and identified inertias back.

Import (`import_urdf`, `read_urdf`). A URDF link frame is the frame of the joint it hangs
from: child = parent * Origin(xyz, rpy) * Motion(axis, q). dynid's frame j of a moving
joint has the same origin as the URDF link frame, rotated by the smallest rotation R_a
that brings z onto the joint axis (R_a = I when the axis is z, as in most files), so that

    a(j)T_j(q) = [T_{a(j), parent link}] * Origin * R_a * Rot(z, q)     (or Trans(z, q))

One Khalil-Kleinfinger row (gamma b alpha d theta r) is a complete parametrization of a
rigid transform: gamma, alpha, theta are z-x-z Euler angles and (d, b, r) place the origin
(see `mdh_rows`). So every URDF joint becomes one row, except when the new z is nearly
parallel to the previous z but displaced sideways: the common normal is then far away
(r ~ offset / sin(alpha)); that case gets a fixed frame (sigma=2) for the translation
followed by a rotation-only moving row, so the numbers stay well conditioned.

Fixed joints are merged: their child links' inertias are added into the body they are
fixed to (as Pinocchio does). The tree then has one frame per moving joint, and a
joint data file has exactly one column per actuated joint, which a dead column per
fixed URDF joint (flanges, tool frames, sensors: 29 of Tiago's 77 joints) would not.

Inertias: the URDF gives per link the mass m, the CoM c and the inertia I_G at the CoM in
the inertial frame (origin xyz, rpy); dynid wants, per frame, J_O = R I_G R^T +
m (|c|^2 I - c c^T) about the frame origin and the first moments m c, in the frame's axes.

Export (`export_urdf`): the reverse, written into a copy of the URDF, changing only the
<inertial> elements. A body that merged fixed links keeps the URDF's values of those links
and puts the rest on the link of its moving joint; `inertials_of` reads what import reads,
so export followed by import is the identity.

Parsing uses the standard library's xml.etree: the dynamics need only <link>/<inertial>
and <joint> (type, parent, child, origin, axis, mimic), export must rewrite the file
keeping every other element (meshes, transmissions, gazebo tags) untouched, and the PyPI
URDF parsers either pull mesh libraries (yourdfpy, urchin: trimesh) or rebuild the XML
from their own object model, dropping what they do not know. expat (>= 2.4.1, checked
below) caps entity expansion and ElementTree never fetches external entities; a file
that declares entities is refused anyway (a URDF has no use for them).
"""

from __future__ import annotations

import io
import math
import os
import pyexpat
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from difflib import get_close_matches
from pathlib import Path

import numpy as np

from ..atomic import write_atomic
from ..textfiles import TextEncodingError, read_utf8
from .consistency import check_body
from .files import MAX_LENGTH_M, MAX_PARAMETER
from .tree import FIXED, INERTIAL, PRISMATIC, REVOLUTE, Frame, Mimic, ModelError, Tree, _rotx, _rotz

_MOVING = {"revolute": REVOLUTE, "continuous": REVOLUTE, "prismatic": PRISMATIC}
# a length or angle below this is round-off of the transform algebra (a few ulps of 1 m or 1 rad)
_SNAP = 1e-13
# one row while r = offset / sin(alpha) stays within this factor of the offset (the round-off of b = z - r cos(alpha)
# grows as |r| eps); beyond it, two rows (see module doc)
_MAX_MAGNIFICATION = 10.0


class UrdfError(ModelError):
    """A URDF that cannot be read or used, with the file and the element."""


@dataclass(frozen=True)
class Placement:
    """Where a URDF link is in the tree: the dynid frame that carries it and the link frame in that frame (4x4)."""

    frame: int
    T: np.ndarray


@dataclass(frozen=True)
class UrdfImport:
    """A URDF read as a tree: the tree, where each link went, and which link each moving frame moves."""

    tree: Tree
    links: dict[str, Placement]
    frame_link: dict[int, str]  # moving frame -> the child link of its joint
    merged: dict[int, list[str]] = field(default_factory=dict)  # frame -> links merged in by fixed joints
    source: str = "<urdf>"
    notes: tuple[str, ...] = ()  # links whose inertia no real body has (imported as given: said, not refused)


# ---------------------------------------------------------------------------------------------- reading XML
def _parse(path_or_text: str | os.PathLike[str], source: str | None = None) -> tuple[ET.ElementTree, str]:
    """The parsed file (comments kept, for export) and the name used in messages."""
    if isinstance(path_or_text, str) and path_or_text.lstrip().startswith("<"):
        text, src = path_or_text, source or "<urdf>"
    else:
        src = source or str(path_or_text)
        try:
            text = read_utf8(path_or_text)
        except OSError as exc:
            raise UrdfError(f"{src}: cannot read the URDF ({exc.strerror})") from None
        except TextEncodingError as exc:
            raise UrdfError(f"{src}: the URDF is {exc}") from None
    if "<!ENTITY" in text:
        raise UrdfError(f"{src}: declares XML entities (<!ENTITY>); a URDF needs none, expand them first")
    if tuple(int(x) for x in pyexpat.version_info) < (2, 4, 1):  # pragma: no cover - old expat only
        raise UrdfError(f"{src}: this Python's expat {pyexpat.EXPAT_VERSION} predates entity-expansion limits")
    parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True, insert_pis=True))
    try:
        doc = ET.ElementTree(ET.fromstring(text, parser=parser))
    except ET.ParseError as exc:
        raise UrdfError(f"{src}: not valid XML: {exc}") from None
    root = doc.getroot()
    if root.tag != "robot":
        raise UrdfError(f"{src}: the root element is <{root.tag}>, a URDF's is <robot>")
    if any(isinstance(e.tag, str) and e.tag.startswith("{") and "xacro" in e.tag for e in root.iter()):
        raise UrdfError(f"{src}: has namespaced (xacro) elements; expand it first: xacro robot.urdf.xacro > robot.urdf")
    return doc, src


def _values(el: ET.Element | None, attr: str, n: int, default: tuple[float, ...], where: str) -> list[float]:
    """The attribute's n finite numbers (default where the element or the attribute is absent), as floats."""
    text = None if el is None else el.get(attr)
    if text is None:
        return [float(x) for x in default]
    try:
        vals = [float(x) for x in text.split()]
    except ValueError:
        raise UrdfError(f'{where}: <{el.tag} {attr}="{text}">: expected {n} numbers') from None
    if len(vals) != n or not all(map(math.isfinite, vals)):
        raise UrdfError(f'{where}: <{el.tag} {attr}="{text}">: expected {n} finite numbers')
    return vals


def _origin(el: ET.Element, where: str) -> np.ndarray:
    o = el.find("origin")
    xyz = _values(o, "xyz", 3, (0, 0, 0), where)
    if max(map(abs, xyz)) > MAX_LENGTH_M:  # a unit slip (mm for m) or a placeholder: no link is that long
        raise UrdfError(f'{where}: <origin xyz="{o.get("xyz")}">: beyond {MAX_LENGTH_M:g} m; URDF lengths are in '
                        "metres (a unit slip? mm written for m)")
    return transform(_rpy(_values(o, "rpy", 3, (0, 0, 0), where)), xyz)


def _rpy(rpy: Sequence[float]) -> np.ndarray:
    """URDF's fixed-axis roll, pitch, yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    (cr, sr), (cp, sp), (cy, sy) = ((math.cos(a), math.sin(a)) for a in rpy)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def transform(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


@dataclass(frozen=True)
class _Inertial:
    m: float
    T: np.ndarray  # inertial frame in the link frame
    I: np.ndarray  # inertia at the CoM, inertial frame axes
    problem: str = ""  # why no real body has this inertia (`_inertia_problem`), '' if one may


def _inertial(link: ET.Element, where: str) -> _Inertial | None:
    el = link.find("inertial")
    if el is None:
        return None
    where = f"{where}: <inertial>"
    mass = el.find("mass")
    if mass is None:
        raise UrdfError(f"{where}: no <mass value=...>")
    m = _values(mass, "value", 1, (math.nan,), where)[0]
    if math.isnan(m):
        raise UrdfError(f"{where}: <mass> has no value")
    if m < 0.0:
        raise UrdfError(f'{where}: <mass value="{mass.get("value")}">: a mass cannot be negative')
    if m > MAX_PARAMETER:
        raise UrdfError(f'{where}: <mass value="{mass.get("value")}">: beyond {MAX_PARAMETER:g} kg; URDF masses are '
                        "in kg (a unit or exponent slip?)")
    inertia = el.find("inertia")
    terms = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    if inertia is None:
        raise UrdfError(f"{where}: no <inertia ixx=... ixy=... ixz=... iyy=... iyz=... izz=...>")
    missing = [k for k in terms if inertia.get(k) is None]
    if missing:
        raise UrdfError(f"{where}: <inertia> has no {', '.join(missing)}; give all six terms (0 where zero)")
    v = {k: _values(inertia, k, 1, (0.0,), where)[0] for k in terms}
    I = np.array([[v["ixx"], v["ixy"], v["ixz"]], [v["ixy"], v["iyy"], v["iyz"]], [v["ixz"], v["iyz"], v["izz"]]])
    return _Inertial(m, _origin(el, where), I, _inertia_problem(I, inertia, where))


def _inside_bounds(I: np.ndarray) -> bool:
    """Whether I's principal moments are >= 0 and meet the triangle inequality by Gershgorin's discs alone (a few
    float operations: most links' inertias, near-diagonal): the triangle inequality is the second moment
    S = tr(I)/2 E - I positive semidefinite (S's eigenvalues are (l1 + l2 - l3)/2 and their kin), which also makes
    I's semidefinite (I = tr(S) E - S); each disc of S on the right of 0 proves it."""
    (a, d, e), (_, b, f), (_, _, c) = I.tolist()
    return (b + c - a >= 2.0 * (abs(d) + abs(e)) and a + c - b >= 2.0 * (abs(d) + abs(f))
            and a + b - c >= 2.0 * (abs(e) + abs(f)))


def _inertia_problem(I: np.ndarray, el: ET.Element, where: str) -> str:
    """The inertia at the centre of mass of a real body has moments ixx, iyy, izz >= 0 (else refused: the model
    file written would be refused by the next command) and principal moments >= 0, each at most the sum of the
    other two (the triangle inequality), within round-off of the largest: a breach of these is returned as a
    note, not refused, for published URDFs have them on small links (Tiago's antennas: a negative principal
    moment of 4e-8 kg·m²), and an identification starts from these values only as a priori ones."""
    if np.abs(I).max() > MAX_PARAMETER or np.diag(I).min() < 0.0:
        given = " ".join(f'{k}="{el.get(k)}"' for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"))
        if np.abs(I).max() > MAX_PARAMETER:
            raise UrdfError(f"{where}: <inertia {given}>: beyond {MAX_PARAMETER:g} kg·m²; URDF inertias are in "
                            "kg·m²")
        raise UrdfError(f"{where}: <inertia {given}>: a negative moment of inertia; ixx, iyy, izz are >= 0 (a sign "
                        "slip?)")
    if _inside_bounds(I):  # the eigenvalues below only where the discs cannot tell (a few links in a robot)
        return ""
    lam = np.linalg.eigvalsh(I)
    tol = 1e-9 * max(float(np.abs(lam).max()), np.finfo(float).tiny)
    given = " ".join(f'{k}="{el.get(k)}"' for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"))
    moments = ", ".join(f"{x:.6g}" for x in lam)
    if lam[0] < -tol:
        return (f"{where}: <inertia {given}>: principal moments ({moments}) kg·m², one negative: no body has that "
                "(check the products of inertia)")
    if lam[2] > lam[0] + lam[1] + tol:
        return (f"{where}: <inertia {given}>: principal moments ({moments}) kg·m² break the triangle inequality (the "
                "largest exceeds the sum of the other two): no body has that (a moment in the wrong unit or about "
                "another point?)")
    return ""


def spatial(inertial: _Inertial, T: np.ndarray) -> np.ndarray:
    """dynid's 10 parameters (about the origin of a frame F, in F) of an inertial whose link frame is T in F."""
    A = T @ inertial.T
    R, c = A[:3, :3], A[:3, 3]
    m = inertial.m
    J = R @ inertial.I @ R.T + m * (c @ c * np.eye(3) - np.outer(c, c))
    return np.array([J[0, 0], J[0, 1], J[0, 2], J[1, 1], J[1, 2], J[2, 2], *(m * c), m])


# ---------------------------------------------------------------------------------------------- geometry
def _axis_rotation(a: np.ndarray) -> np.ndarray:
    """The smallest rotation taking z onto the unit vector a (Rodrigues about z x a); exact for the axes."""
    s = math.hypot(a[0], a[1])
    if s == 0.0:
        return np.eye(3) if a[2] > 0 else np.diag([1.0, -1.0, -1.0])
    k = np.array([-a[1], a[0], 0.0]) / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * K + (1.0 - a[2]) * (K @ K)


def _snap(x: float, angle: bool) -> float:
    if angle:
        k = round(x / (math.pi / 2))
        return k * math.pi / 2 if abs(x - k * math.pi / 2) < _SNAP else x
    return 0.0 if abs(x) < _SNAP else x


def mdh_rows(T: np.ndarray) -> list[tuple[float, float, float, float, float, float]]:
    """(gamma, b, alpha, d, theta, r) rows whose product is the rigid transform T (4x4); one row, or
    a translation row then a rotation-only row when one row would be ill-conditioned (module doc).

    One row: R = Rz(gamma) Rx(alpha) Rz(theta) (z-x-z Euler angles) and the origin
    p = Rz(gamma) (d, -r sin(alpha), b + r cos(alpha)). When z stays parallel (sin(alpha) = 0),
    gamma is free and is chosen to point x at the new origin (d = |p_xy|, r = 0)."""
    R, p = T[:3, :3], T[:3, 3]
    z = R[:, 2]
    s = math.hypot(z[0], z[1])
    if s < _SNAP:
        alpha = 0.0 if z[2] > 0 else math.pi
        rho = math.hypot(p[0], p[1])
        gamma = math.atan2(p[1], p[0]) if rho >= _SNAP else 0.0
        return [_row(R, gamma, p[2], alpha, rho, 0.0)]
    gamma, alpha = math.atan2(z[0], -z[1]), math.atan2(s, z[2])
    pp = _rotz(-gamma) @ p
    r = -pp[1] / math.sin(alpha)
    if abs(r) <= _MAX_MAGNIFICATION * float(np.linalg.norm(p)):
        return [_row(R, gamma, pp[2] - r * math.cos(alpha), alpha, pp[0], r)]
    rho = math.hypot(p[0], p[1])
    g1 = math.atan2(p[1], p[0]) if rho >= _SNAP else 0.0
    return [_row(np.eye(3), g1, p[2], 0.0, rho, 0.0), _row(R, gamma, 0.0, alpha, 0.0, 0.0)]


def _row(R: np.ndarray, gamma: float, b: float, alpha: float, d: float, r: float) -> tuple[float, ...]:
    M = _rotx(-alpha) @ _rotz(-gamma) @ R  # = Rz(theta)
    theta = math.atan2(M[1, 0], M[0, 0])
    return (_snap(gamma, True), _snap(b, False), _snap(alpha, True), _snap(d, False), _snap(theta, True),
            _snap(r, False))


def row_transform(f: Frame) -> np.ndarray:
    """The transform of one row at q = 0 (used by the tests and by export's sanity check)."""
    def tr(v: tuple[float, float, float]) -> np.ndarray:
        return transform(np.eye(3), np.array(v))

    def rot(R: np.ndarray) -> np.ndarray:
        return transform(R, np.zeros(3))

    return (rot(_rotz(f.gamma)) @ tr((0, 0, f.b)) @ rot(_rotx(f.alpha)) @ tr((f.d, 0, 0)) @ rot(_rotz(f.theta))
            @ tr((0, 0, f.r)))


# ---------------------------------------------------------------------------------------------- import
def import_urdf(path_or_text: str | os.PathLike[str], name: str | None = None,
                source: str | None = None, freeze: Mapping[str, float] | Sequence[str] | None = None,
                joints: Sequence[str] | None = None) -> UrdfImport:
    """Read a URDF (a path, or the XML text) into a tree with one frame per moving joint (module doc).

    Mimic joints (<mimic joint= multiplier= offset=>) become `Tree.mimic` entries: q = multiplier q_master +
    offset, no data column or equation of their own, their force carried by the master's.
    freeze: moving joints to hold still, by name, at a value (rad or m; a sequence of names: at 0), merged into
    the body they hang from as a fixed joint is; a joint that mimics a frozen one is frozen with it, at its
    mimic's value. joints: the identified chain: every moving joint not named (nor mimicking a named one) is
    frozen (at its `freeze` value, else 0). The tree records what was frozen (`Tree.frozen`), so that an export
    into the same URDF finds the same frames.

    Refused with a one-line UrdfError naming the element: floating and planar joints, closed loops, missing
    links, non-numeric or non-finite numbers, negative masses, a mimic of a joint that is not a moving one, a
    frozen or selected joint the file does not have, a mimic frozen without its master or selected without it."""
    doc, src = _parse(path_or_text, source)
    return _import(doc, src, name, _as_values(freeze), None if joints is None else tuple(joints))


def _as_values(freeze: Mapping[str, float] | Sequence[str] | None) -> dict[str, float]:
    if freeze is None:
        return {}
    if isinstance(freeze, Mapping):
        return {str(k): float(v) for k, v in freeze.items()}
    if isinstance(freeze, str):
        raise TypeError("freeze takes joint names as a list or {name: value}, not one string")
    return dict.fromkeys(freeze, 0.0)


def read_urdf(path_or_text: str | os.PathLike[str], name: str | None = None) -> Tree:
    """The tree of a URDF (see import_urdf)."""
    return import_urdf(path_or_text, name).tree


def _import(doc: ET.ElementTree, src: str, name: str | None, freeze: Mapping[str, float] | None = None,
            select: tuple[str, ...] | None = None) -> UrdfImport:
    robot = doc.getroot()
    links: dict[str, ET.Element] = {}
    for el in robot.findall("link"):
        lname = el.get("name")
        if not lname:
            raise UrdfError(f"{src}: a <link> has no name")
        if lname in links:
            raise UrdfError(f'{src}: two <link name="{lname}">')
        links[lname] = el
    children: dict[str, list[ET.Element]] = {k: [] for k in links}
    parent_joint: dict[str, ET.Element] = {}
    joint_names: set[str] = set()
    for el in robot.findall("joint"):
        jname = el.get("name")
        if not jname:
            raise UrdfError(f"{src}: a <joint> has no name")
        where = f'{src}: <joint name="{jname}">'
        if jname in joint_names:
            raise UrdfError(f'{src}: two <joint name="{jname}">')
        joint_names.add(jname)
        kind = el.get("type")
        if kind in ("floating", "planar"):
            raise UrdfError(f'{where}: type="{kind}" is not supported; model a free base as 3 prismatic + 3 revolute '
                            f"joints (see the floating_tree example) or make it fixed")
        if kind not in (*_MOVING, "fixed"):
            raise UrdfError(f'{where}: unknown type="{kind}"; URDF types: revolute, continuous, prismatic, fixed')
        ends = {}
        for end in ("parent", "child"):
            e = el.find(end)
            lk = None if e is None else e.get("link")
            if lk is None:
                raise UrdfError(f'{where}: no <{end} link="...">')
            if lk not in links:
                raise UrdfError(f'{where}: <{end} link="{lk}">: no such link')
            ends[end] = lk
        if ends["child"] in parent_joint:
            raise UrdfError(f'{where}: link "{ends["child"]}" is already the child of joint '
                            f'"{parent_joint[ends["child"]].get("name")}": closed loops are not supported; '
                            f"cut the loop (keep one joint) and model the constraint otherwise")
        parent_joint[ends["child"]] = el
        children[ends["parent"]].append(el)
    roots = [k for k in links if k not in parent_joint]
    if not links:
        raise UrdfError(f"{src}: no <link>")
    if len(roots) != 1:
        if not roots:
            raise UrdfError(f"{src}: every link is the child of a joint: the joints form a closed loop")
        raise UrdfError(f"{src}: links {', '.join(repr(r) for r in roots[:4])} have no parent joint; a URDF tree has "
                        f"one root: connect them with joints")

    kinds = {el.get("name"): el.get("type") for el in robot.findall("joint")}
    mimics = _mimics(robot, kinds, src)
    frozen = _frozen(kinds, mimics, dict(freeze or {}), select, src)
    frames: list[Frame] = []
    values: dict[str, float] = {}
    names: dict[int, str] = {}
    placements: dict[str, Placement] = {}
    frame_link: dict[int, str] = {}
    merged: dict[int, list[str]] = {}
    notes: list[str] = []
    root = roots[0]
    stack = [(root, Placement(0, np.eye(4)))]
    while stack:  # depth first, children in file order, so that a(j) < j
        lname, place = stack.pop()
        placements[lname] = place
        where = f'{src}: <link name="{lname}">'
        inertial = _inertial(links[lname], where)
        if inertial is not None and inertial.problem:
            notes.append(inertial.problem)
        if inertial is not None and place.frame > 0:
            p = spatial(inertial, place.T)
            for k, v in zip(INERTIAL, p, strict=True):
                key = f"{k}{place.frame}"
                values[key] = values.get(key, 0.0) + float(v)
        todo = []
        for el in children[lname]:
            jname, kind = el.get("name", ""), el.get("type", "")
            jwhere = f'{src}: <joint name="{jname}">'
            origin = place.T @ _origin(el, jwhere)
            child = el.find("child").get("link")  # checked above
            if kind == "fixed":
                merged.setdefault(place.frame, []).append(child)
                todo.append((child, Placement(place.frame, origin)))
                continue
            axis = np.array(_values(el.find("axis"), "xyz", 3, (1.0, 0.0, 0.0), jwhere))
            norm = float(np.linalg.norm(axis))
            if norm < 1e-12:
                raise UrdfError(f'{jwhere}: <axis xyz="{el.find("axis").get("xyz")}"> is zero')
            if jname in frozen:  # held at its value: a fixed joint whose origin includes the motion
                merged.setdefault(place.frame, []).append(child)
                todo.append((child, Placement(place.frame, origin @ _motion(kind, axis / norm, frozen[jname]))))
                continue
            Ra = transform(_axis_rotation(axis / norm), np.zeros(3))
            rows = mdh_rows(origin @ Ra)
            ant = place.frame
            for i, row in enumerate(rows):
                j = len(frames) + 1
                moving = i == len(rows) - 1
                frames.append(Frame(j, ant, _MOVING[kind] if moving else FIXED, *row))
                ant = j
            names[ant], frame_link[ant] = jname, child
            todo.append((child, Placement(ant, np.linalg.inv(Ra))))
        stack += reversed(todo)
    lost = [k for k in links if k not in placements]
    if lost:
        raise UrdfError(f"{src}: links {', '.join(repr(k) for k in lost[:4])} are not connected to the root link "
                        f"{root!r}: their joints form a closed loop; cut it")
    frame_of = {v: k for k, v in names.items()}
    mimic = {frame_of[s]: Mimic(frame_of[m], r, o) for s, (m, r, o) in mimics.items() if s not in frozen}
    try:
        tree = Tree(name=name or robot.get("name") or Path(src).stem, frames=tuple(frames), values=values,
                    joint_names=names, mimic=mimic, frozen=frozen)
    except ModelError as exc:
        raise UrdfError(f"{src}: {exc}") from None
    if not frames:
        raise UrdfError(f"{src}: no moving joint (revolute, continuous or prismatic): nothing to identify")
    return UrdfImport(tree, placements, frame_link, {k: v for k, v in merged.items() if k > 0}, src, tuple(notes))


def _mimics(robot: ET.Element, kinds: dict[str, str | None], src: str) -> dict[str, tuple[str, float, float]]:
    """joint -> (the moving joint it follows in the end, multiplier, offset), chains of mimics composed."""
    direct: dict[str, tuple[str, float, float]] = {}
    for el in robot.findall("joint"):
        mim = el.find("mimic")
        if mim is None:
            continue
        jname = el.get("name")
        where = f'{src}: <joint name="{jname}">: <mimic joint="{mim.get("joint")}">'
        master = mim.get("joint")
        if kinds.get(jname) == "fixed":
            continue  # a fixed joint has no motion to mimic with
        if master not in kinds:
            raise UrdfError(f"{where}: no such joint; name the joint it follows")
        if kinds[master] not in _MOVING:
            raise UrdfError(f'{where}: that joint is {kinds[master]}; a mimic must follow a moving joint (remove '
                            "the <mimic> or make this joint fixed)")
        ratio = _values(mim, "multiplier", 1, (1.0,), where)[0]
        offset = _values(mim, "offset", 1, (0.0,), where)[0]
        if ratio == 0.0:
            raise UrdfError(f'{where}: multiplier="0" holds it still: make the joint fixed instead')
        direct[jname] = (master, ratio, offset)
    out = {}
    for jname in direct:
        master, ratio, offset, seen = *direct[jname], [jname]
        while master in direct:  # q = r (r2 q2' + o2) + o
            if master in seen:
                raise UrdfError(f'{src}: <joint name="{jname}">: its <mimic> chain {" -> ".join(seen)} -> {master} is '
                                "a loop; one of them must be actuated")
            seen.append(master)
            m2, r2, o2 = direct[master]
            master, ratio, offset = m2, ratio * r2, ratio * o2 + offset
        out[jname] = (master, ratio, offset)
    return out


def _frozen(kinds: dict[str, str | None], mimics: dict[str, tuple[str, float, float]], freeze: dict[str, float],
            select: tuple[str, ...] | None, src: str) -> dict[str, float]:
    """The moving joints held still -> their value: those named, those not selected, and the mimics of frozen ones."""

    moving = [k for k, t in kinds.items() if t in _MOVING]
    for what, named in (("--freeze", list(freeze)), ("--joints", list(select or ()))):
        for jname in named:
            if jname not in kinds:
                close = get_close_matches(jname, moving, n=1)
                hint = f"; did you mean {close[0]!r}?" if close else f" (moving joints: {', '.join(moving[:8])})"
                raise UrdfError(f"{src}: {what} {jname!r}: no such joint{hint}")
            if kinds[jname] not in _MOVING:
                raise UrdfError(f"{src}: {what} {jname!r}: the joint is {kinds[jname]}, not a moving one")
            if not math.isfinite(freeze.get(jname, 0.0)):
                raise UrdfError(f"{src}: --freeze {jname}={freeze[jname]}: not a finite number")
    if select is not None:
        for jname in select:
            if jname in mimics:
                raise UrdfError(f"{src}: --joints {jname!r}: it mimics {mimics[jname][0]!r}; select that joint "
                                "(its mimics follow it)")
            if jname in freeze:
                raise UrdfError(f"{src}: {jname!r} is both selected (--joints) and frozen (--freeze)")
        keep = set(select)
        for jname in moving:
            followed = mimics[jname][0] if jname in mimics else jname
            if followed not in keep:
                freeze.setdefault(jname, 0.0)
    out = {}
    for jname in moving:
        if jname in mimics:
            master, ratio, offset = mimics[jname]
            if master in freeze:
                value = ratio * freeze[master] + offset
                if jname in freeze and select is None and not math.isclose(freeze[jname], value, abs_tol=1e-12):
                    raise UrdfError(f"{src}: --freeze {jname}={freeze[jname]:g}: it mimics {master!r}, frozen at "
                                    f"{freeze[master]:g}, so it is at {value:g}; give only {master!r}")
                out[jname] = value
            elif jname in freeze:
                raise UrdfError(f"{src}: --freeze {jname!r}: it mimics {master!r}, which moves; freeze {master!r} "
                                "too (its mimics follow it)")
        elif jname in freeze:
            out[jname] = freeze[jname]
    return out


def _motion(kind: str | None, axis: np.ndarray, value: float) -> np.ndarray:
    """The joint's motion Motion(axis, value) as a 4x4 transform: a rotation about the unit axis, or a translation
    along it."""
    if kind == "prismatic":
        return transform(np.eye(3), value * axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return transform(np.eye(3) + math.sin(value) * K + (1.0 - math.cos(value)) * (K @ K), np.zeros(3))


# ---------------------------------------------------------------------------------------------- export
def export_urdf(tree: Tree, urdf: str | os.PathLike[str], out: str | os.PathLike[str],
                values: Mapping[str, float] | None = None, what: str = "parameters") -> list[str]:
    """Write `urdf` with the inertials of `tree` (or `values`, standard names XXj..Mj) to `out`, atomically.

    The URDF must be the one the tree was imported from (its geometry is checked). Refuses a
    parameter set that no real body has (mass <= 0, inertia at the CoM not positive definite,
    triangle inequality broken), naming the frame, its joint and link. `what` names the
    parameter source in messages. Returns notes (links whose merged children took their share)."""
    text, notes = urdf_with_parameters(tree, urdf, values, what)
    write_atomic(out, text)
    return notes


def urdf_with_parameters(tree: Tree, urdf: str | os.PathLike[str], values: Mapping[str, float] | None = None,
                         what: str = "parameters") -> tuple[str, list[str]]:
    """The text of `urdf` with new inertials (see export_urdf) and the notes."""
    doc, src = _parse(urdf)
    imp = _import(doc, src, tree.name, tree.frozen)
    _check_same(tree, imp.tree, src)
    X = tree.parameters if values is None else tree.with_values(dict(values)).parameters
    block = tree.inertial_block(X)
    links = {el.get("name"): el for el in doc.getroot().findall("link")}
    notes: list[str] = []
    for f in tree.frames:
        p = block[f.j]
        if f.j not in imp.frame_link:  # a fixed frame inserted for the geometry carries no link
            if np.any(p != 0.0):
                raise UrdfError(f"{what}: frame {f.j} is a geometric helper frame with no URDF link; its inertial "
                                f"parameters must be zero (put them on frame {f.ant})")
            continue
        lname = imp.frame_link[f.j]
        who = f"frame {f.j} (joint {tree.joint_names.get(f.j, '?')!r}, link {lname!r})"
        if not np.any(p != 0.0):  # a massless body: no <inertial> at all
            gone = [k for k in [lname, *imp.merged.get(f.j, [])] if links[k].find("inertial") is not None]
            for k in gone:
                links[k].remove(links[k].find("inertial"))
            if gone:
                notes.append(f"{who}: all inertial parameters are zero; <inertial> removed from {', '.join(gone)}")
            continue
        bad = check_body(p, f.j)
        if bad:
            raise UrdfError(f"{what}: {who} is not physically realisable: {bad[0].message}")
        rest = p.copy()
        kept = []
        for k in imp.merged.get(f.j, []):
            inert = _inertial(links[k], src)
            if inert is not None:
                rest -= spatial(inert, imp.links[k].T)
                kept.append(k)
        if kept and check_body(rest, f.j):  # the merged links' URDF values leave no real body: lump all on one
            rest = p
            for k in kept:
                el = links[k].find("inertial")
                links[k].remove(el)
            notes.append(f"{who}: the identified body is lighter than the URDF's {', '.join(kept)}; the whole "
                         f"body is written on {lname!r} and their <inertial> removed")
        if np.abs(rest).max() <= 1e-12 * np.abs(p).max():  # all on the merged links, as the URDF had it
            if links[lname].find("inertial") is not None:
                links[lname].remove(links[lname].find("inertial"))
            continue
        _write_inertial(links[lname], rest, imp.links[lname].T, src)
    buf = io.BytesIO()
    doc.write(buf, encoding="utf-8", xml_declaration=True)
    return buf.getvalue().decode("utf-8") + "\n", notes


def _check_same(model: Tree, urdf: Tree, src: str) -> None:
    """The model must be the URDF's (same frames, same joint names) for the inertials to land on the right links."""
    hint = "export into the URDF the model was imported from (dynid model import)"
    if model.n != urdf.n:
        raise UrdfError(f"{src}: gives {urdf.n} frames, the model {model.n}; {hint}")
    for a, b in zip(model.frames, urdf.frames, strict=True):
        same = (a.ant, a.sigma) == (b.ant, b.sigma) and np.allclose(
            row_transform(a), row_transform(b), rtol=0.0, atol=1e-9)
        if not same or model.joint_names.get(a.j) != urdf.joint_names.get(b.j):
            raise UrdfError(f"{src}: frame {a.j} ({urdf.joint_names.get(b.j, 'fixed')}) differs from the model's "
                            f"({model.joint_names.get(a.j, 'fixed')}); {hint}")


def _write_inertial(link: ET.Element, p: np.ndarray, T_frame_link: np.ndarray, src: str) -> None:
    """Write 10 parameters (about the dynid frame origin, in its axes) as the link's <inertial>, keeping the
    inertial frame's rpy when the file has one (so that an unchanged set rewrites the same numbers)."""
    m = float(p[9])
    J = np.array([[p[0], p[1], p[2]], [p[1], p[3], p[4]], [p[2], p[4], p[5]]])
    c = p[6:9] / m
    JG = J - m * (c @ c * np.eye(3) - np.outer(c, c))
    A = np.linalg.inv(T_frame_link)  # dynid frame in the link frame
    c_link = A[:3, :3] @ c + A[:3, 3]
    el = link.find("inertial")
    if el is None:
        el = ET.SubElement(link, "inertial")
    old = el.find("origin")
    rpy = _values(old, "rpy", 3, (0, 0, 0), src)
    R = A[:3, :3].T @ _rpy(rpy)  # inertial axes in the dynid frame
    I = R.T @ JG @ R
    origin = old if old is not None else ET.SubElement(el, "origin")
    origin.set("xyz", " ".join(_num(x) for x in c_link))
    origin.set("rpy", " ".join(_num(x) for x in rpy))
    mass = el.find("mass") if el.find("mass") is not None else ET.SubElement(el, "mass")
    mass.set("value", _num(m))
    inertia = el.find("inertia") if el.find("inertia") is not None else ET.SubElement(el, "inertia")
    for k, (a, b) in {"ixx": (0, 0), "ixy": (0, 1), "ixz": (0, 2), "iyy": (1, 1), "iyz": (1, 2),
                      "izz": (2, 2)}.items():
        inertia.set(k, _num(0.5 * (I[a, b] + I[b, a])))


def _num(x: float) -> str:
    """Shortest text that reads back to the same float (so export then import is exact)."""
    x = float(x)
    return "0" if x == 0.0 else repr(x)


__all__ = ["Placement", "UrdfError", "UrdfImport", "export_urdf", "import_urdf", "mdh_rows", "read_urdf",
           "row_transform", "urdf_with_parameters"]
