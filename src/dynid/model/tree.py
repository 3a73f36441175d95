"""A multibody tree in Khalil-Kleinfinger modified Denavit-Hartenberg notation.

Frames are numbered 0..n; frame 0 is the fixed base, frame j is fixed to link j and
a(j) < j is its antecedent. The transform from frame a(j) to frame j is

    Rot(z, gamma) Trans(z, b) Rot(x, alpha) Trans(x, d) Rot(z, theta) Trans(z, r)

and the joint variable q_j is added to theta (sigma = 0, revolute) or to r
(sigma = 1, prismatic); sigma = 2 is a fixed frame. The theta and r columns hold the
constant part (an offset for the variable one).

Parameters, in a stable order that every result carries by name:
  per frame j: XXj XYj XZj YYj YZj ZZj MXj MYj MZj Mj (about O_j, in frame j), then
  the joint terms declared for it among IAj (rotor inertia), FVj (viscous), FSj
  (Coulomb), OFFj (constant offset), Kj (stiffness of an elastic joint), KQj (its
  second-order term), FVPLj FVPHj FVNLj FVNHj (a piecewise-linear viscous curve, below);
  then its load terms (below), then the couplings, each named by the model.

A load term is a term of joint j's equation proportional to a function of the MEASURED external
wrench on its link, not of the joint's motion: KFYj multiplies -q_j Fy_j², Fy_j the measured force
along y_j on link j (a tire whose vertical stiffness falls with its lateral force, Pacejka's qFcy).
The engines hold no measured wrench (theirs is a right-hand side): their column of a load term is 0,
and the application that reads the wrench builds it (vehicle.equations.car_identification).

The generalized force of joint j (what an actuator must supply) is

    tau_j = (rigid-body terms) + IA qdd + FV qd + FS s_j(qd) + OFF + K q
            + sum over couplings c of  c_j * value_c * f_kind(c . q)

            + FVPL clip(qd, 0, v+) + FVPH max(qd - v+, 0) + FVNL clip(qd, v-, 0) + FVNH min(qd - v-, 0)

where s_j is joint j's Coulomb law (`friction_shape`, still linear in FS): sign(qd) by
default, tanh(qd / vs) ("tanh") or 2 / (1 + exp(-qd / vs)) - 1 = tanh(qd / (2 vs))
("sigmoid"), vs > 0 in the joint's velocity unit (rad/s or m/s). Couplings of kind FS
always use sign.

The four curve terms make the viscous force a continuous piecewise-linear function of qd, still
linear in its coefficients, which ARE its slopes: FVPL on 0 < qd < v+, FVPH beyond v+, FVNL on
v- < qd < 0, FVNH below v- (a valved damper: bump and rebound, low and high speed). The knee
velocities (v-, v+), v- < 0 < v+, are joint j's `knees` (default (-inf, inf): a joint with FVPL and
FVNL but no knee has one slope per direction); FVPH needs a finite v+, FVNH a finite v-. With FV
too, FV adds to all four slopes (the constant part of the curve).

where a coupling is a linear combination c . q of joint variables with a kind:
K (spring: c.q), IA (inertia: c.qdd), FV (viscous: c.qd) or FS (Coulomb: sign(c.qd)).
An anti-roll bar is K with c = e_i - e_j; a geared wrist motor is IA/FV/FS with c the
gear ratios of the joints it drives.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from difflib import get_close_matches

import numpy as np

from .workspace import derived

INERTIAL = ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M")
# KQ: a spring's second-order term KQ q^2 (with K and OFF, a quadratic law about any reference: a tire whose load
# rises faster than its deflection)
# FVPL FVPH FVNL FVNH: the slopes of a piecewise-linear viscous curve (positive/negative velocity, low/high
# speed about the joint's knees: see the module doc and Tree.knees)
CURVE_TERMS = ("FVPL", "FVPH", "FVNL", "FVNH")
JOINT_TERMS = ("IA", "FV", "FS", "OFF", "K", "KQ", *CURVE_TERMS)
# terms in the measured wrench on the joint's link (see the module doc); the engines' column of each is 0
LOAD_TERMS = ("KFY",)
NO_KNEES: tuple[float, float] = (-math.inf, math.inf)
FRICTION_SHAPES = ("sign", "tanh", "sigmoid")
SIGN_LAW: tuple[str, float] = ("sign", 0.0)
COUPLING_KINDS = ("K", "IA", "FV", "FS")
REVOLUTE, PRISMATIC, FIXED = 0, 1, 2


class ModelError(ValueError):
    """A model description that cannot be used, with what and where."""


@dataclass(frozen=True)
class Frame:
    """One row of the geometric table (angles in rad, lengths in m)."""

    j: int
    ant: int
    sigma: int
    gamma: float = 0.0
    b: float = 0.0
    alpha: float = 0.0
    d: float = 0.0
    theta: float = 0.0
    r: float = 0.0


@dataclass(frozen=True)
class Coupling:
    """A term acting on the linear combination sum_j coeffs[j] * q_j (see module doc)."""

    name: str
    kind: str
    coeffs: dict[int, float]


@dataclass(frozen=True)
class Mimic:
    """A joint that follows another (a URDF <mimic>): q_slave = ratio * q_master + offset, so qd_slave = ratio *
    qd_master and qdd_slave = ratio * qdd_master. It has no actuator of its own: by virtual work its generalized
    force is carried by the master's, tau_master + ratio * tau_slave, and its own is 0 (as a fixed frame's)."""

    master: int
    ratio: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class Tree:
    """A modified-DH tree with its named parameter vector.

    frames: rows for j = 1..n in order; joint_terms[j]: the joint terms declared for
    frame j (subset of JOINT_TERMS); values: parameter name -> value (missing = 0);
    known: names whose value is taken as known rather than identified;
    labels: name -> the template's own label (e.g. K9 -> ks9) for reports;
    joint_names: frame number -> the name of its joint in another description (a URDF's
    joint names, kept so that data columns and exports can be matched by name);
    friction_shape: frame number -> (shape, vs) of its FS term when not sign, shape
    "tanh" or "sigmoid" (see the module doc); joints not listed use sign;
    knees: frame number -> (v-, v+), v- < 0 < v+ (rad/s or m/s, either may be infinite), the knee
    velocities of its viscous curve terms (CURVE_TERMS); joints not listed have none (NO_KNEES).
    mimic: frame number -> the `Mimic` it follows (a kinematic constraint: its data column is
    ignored, its motion is the master's, its force is added into the master's equation);
    frozen: the moving joints of the description it was imported from (a URDF's) that the import
    held still, name -> value (rad or m), merged into the body they hang from: no frame.
    load_terms[j]: the load terms declared for frame j (subset of LOAD_TERMS; module doc).

    What is derived from the fields (ant, ancestors, index, constant_rotation, parameters, ...) is computed on
    first use and kept beside the tree (model.workspace.derived), never in it: a Tree is not changed by use.
    """

    name: str
    frames: tuple[Frame, ...]
    joint_terms: dict[int, tuple[str, ...]] = field(default_factory=dict)
    couplings: tuple[Coupling, ...] = ()
    values: dict[str, float] = field(default_factory=dict)
    known: frozenset[str] = frozenset()
    labels: dict[str, str] = field(default_factory=dict)
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    joint_names: dict[int, str] = field(default_factory=dict)
    friction_shape: dict[int, tuple[str, float]] = field(default_factory=dict)
    knees: dict[int, tuple[float, float]] = field(default_factory=dict)
    mimic: dict[int, Mimic] = field(default_factory=dict)
    frozen: dict[str, float] = field(default_factory=dict)
    load_terms: dict[int, tuple[str, ...]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        _validate(self)

    # ----- structure -------------------------------------------------------------
    @property
    def n(self) -> int:
        """Number of frames besides the base (= number of joint variables)."""
        return len(self.frames)

    @derived
    def ant(self) -> np.ndarray:
        """a(j) for j = 0..n (a(0) = -1)."""
        return np.array([-1] + [f.ant for f in self.frames])

    @derived
    def sigma(self) -> np.ndarray:
        """sigma_j for j = 0..n (the base counts as fixed)."""
        return np.array([FIXED] + [f.sigma for f in self.frames])

    @derived
    def ancestors(self) -> list[list[int]]:
        """ancestors[k]: the frames j >= 1 on the path from the base to k, k included."""
        out: list[list[int]] = [[]]
        for f in self.frames:
            out.append([*out[f.ant], f.j])
        return out

    @derived
    def children(self) -> list[list[int]]:
        kids: list[list[int]] = [[] for _ in range(self.n + 1)]
        for f in self.frames:
            kids[f.ant].append(f.j)
        return kids

    @derived
    def depth(self) -> np.ndarray:
        return np.array([len(a) for a in self.ancestors])

    @derived
    def equations(self) -> tuple[int, ...]:
        """The frames that have an equation of their own: moving joints that follow no other (mimic)."""
        return tuple(f.j for f in self.frames if f.sigma != FIXED and f.j not in self.mimic)

    @property
    def unconstrained(self) -> Tree:
        """This tree with its mimic joints as independent joints (what the engine recurses over)."""
        return self._without_mimic if self.mimic else self  # never kept beside itself: it would never be collected

    @derived
    def _without_mimic(self) -> Tree:
        return _replace(self, mimic={})

    # ----- constant geometry -----------------------------------------------------
    @derived
    def constant_rotation(self) -> np.ndarray:
        """C_j = Rot(z, gamma) Rot(x, alpha), shape (n+1, 3, 3); index 0 is I."""
        C = np.tile(np.eye(3), (self.n + 1, 1, 1))
        for f in self.frames:
            C[f.j] = _rotz(f.gamma) @ _rotx(f.alpha)
        return C

    @derived
    def constant_offset(self) -> np.ndarray:
        """u_j = Rot(z, gamma) (d, 0, b): origin of frame j in a(j) when r = 0, (n+1, 3)."""
        u = np.zeros((self.n + 1, 3))
        for f in self.frames:
            u[f.j] = _rotz(f.gamma) @ np.array([f.d, 0.0, f.b])
        return u

    @derived
    def theta0(self) -> np.ndarray:
        return np.array([0.0] + [f.theta for f in self.frames])

    @derived
    def r0(self) -> np.ndarray:
        return np.array([0.0] + [f.r for f in self.frames])

    # ----- parameters --------------------------------------------------------------
    @derived
    def parameter_names(self) -> tuple[str, ...]:
        names: list[str] = []
        for f in self.frames:
            names += [f"{p}{f.j}" for p in INERTIAL]
            names += [f"{t}{f.j}" for t in JOINT_TERMS if t in self.joint_terms.get(f.j, ())]
            names += [f"{t}{f.j}" for t in LOAD_TERMS if t in self.load_terms.get(f.j, ())]
        names += [c.name for c in self.couplings]
        return tuple(names)

    @derived
    def index(self) -> dict[str, int]:
        """Parameter name -> column index."""
        return {name: i for i, name in enumerate(self.parameter_names)}

    @property
    def p(self) -> int:
        return len(self.parameter_names)

    @derived
    def parameters(self) -> np.ndarray:
        """The parameter vector X in the order of parameter_names."""
        return np.array([self.values.get(name, 0.0) for name in self.parameter_names])

    @derived
    def known_mask(self) -> np.ndarray:
        return np.array([name in self.known for name in self.parameter_names], dtype=bool)

    def friction_law(self, j: int) -> tuple[str, float]:
        """(shape, vs) of joint j's Coulomb term: ("sign", 0.0) unless `friction_shape` says otherwise."""
        return self.friction_shape.get(j, SIGN_LAW)

    def knee(self, j: int) -> tuple[float, float]:
        """(v-, v+) of joint j's viscous curve: NO_KNEES unless `knees` says otherwise."""
        return self.knees.get(j, NO_KNEES)

    def label(self, name: str) -> str:
        return self.labels.get(name, name)

    def column(self, name_or_label: str) -> int:
        """Column index of a parameter given by name or template label."""
        if name_or_label in self.index:
            return self.index[name_or_label]
        for name, lab in self.labels.items():
            if lab == name_or_label:
                return self.index[name]
        raise ModelError(
            f"model {self.name!r} has no parameter {name_or_label!r}; "
            f"parameters are named like {', '.join(self.parameter_names[:12])}, ..."
        )

    def frame_of(self, joint: str | int) -> int:
        """Frame number of a joint given by its name (the `[joints]` table) or by its number."""
        if isinstance(joint, int) and not isinstance(joint, bool) and 1 <= joint <= self.n:
            return joint
        for j, name in self.joint_names.items():
            if name == joint:
                return j

        close = get_close_matches(str(joint), list(self.joint_names.values()), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        named = ", ".join(list(self.joint_names.values())[:8]) or "none"
        raise ModelError(f"model {self.name!r} has no joint {joint!r}{hint} (named joints: {named})")

    def inertial_block(self, X: np.ndarray | None = None) -> np.ndarray:
        """The 10 inertial parameters of every frame, (n+1, 10); row 0 is the base (zero)."""
        X = self.parameters if X is None else np.asarray(X, dtype=float)
        block = np.zeros((self.n + 1, 10))
        for f in self.frames:
            block[f.j] = X[self.index[f"XX{f.j}"] : self.index[f"XX{f.j}"] + 10]
        return block

    def with_values(self, values: dict[str, float]) -> Tree:
        """A copy with some parameter values replaced (names or labels accepted)."""
        new = dict(self.values)
        for key, v in values.items():
            new[self.parameter_names[self.column(key)]] = float(v)
        return _replace(self, values=new)

    def with_known(self, known: set[str] | frozenset[str]) -> Tree:
        return _replace(self, known=frozenset(self.parameter_names[self.column(k)] for k in known))


def freeze(tree: Tree, frames: dict[int, float]) -> Tree:
    """The tree with the moving joints `frames` (frame -> value, rad or m) held still: fixed frames (sigma = 2)
    whose constant theta (revolute) or r (prismatic) includes the value, their joint terms dropped, their names
    moved from `joint_names` to `frozen`. A joint that mimics a frozen one is frozen with it, at its mimic's value.
    Their bodies stay (their parameters regroup into what the moving joints see). A coupling on a frozen joint is
    refused: it would act on a joint that no longer moves."""
    held = dict(frames)
    for j, m in tree.mimic.items():
        if m.master in held:
            held.setdefault(j, m.ratio * held[m.master] + m.offset)
    for j in held:
        if not 1 <= j <= tree.n or tree.frames[j - 1].sigma == FIXED:
            raise ModelError(f"model {tree.name!r}: frame {j} is not a moving joint; it cannot be frozen")
        if j in tree.mimic and tree.mimic[j].master not in held:
            raise ModelError(f"model {tree.name!r}: frame {j} follows frame {tree.mimic[j].master}, which moves; "
                             "freeze that joint (its mimics follow it)")
    for c in tree.couplings:
        bad = [j for j in c.coeffs if j in held]
        if bad:
            raise ModelError(f"model {tree.name!r}: coupling {c.name!r} acts on joint {bad[0]}, which is frozen")
    new_frames = []
    for f in tree.frames:
        if f.j in held:
            v = held[f.j]
            theta, r = (f.theta + v, f.r) if f.sigma == REVOLUTE else (f.theta, f.r + v)
            f = Frame(f.j, f.ant, FIXED, f.gamma, f.b, f.alpha, f.d, theta, r)
        new_frames.append(f)
    gone = {f"{t}{j}" for j in held for t in (*tree.joint_terms.get(j, ()), *tree.load_terms.get(j, ()))}
    names = {j: n for j, n in tree.joint_names.items() if j not in held}
    frozen = dict(tree.frozen) | {tree.joint_names.get(j, f"frame {j}"): held[j] for j in sorted(held)}
    return _replace(tree, frames=tuple(new_frames),
                    joint_terms={j: t for j, t in tree.joint_terms.items() if j not in held},
                    load_terms={j: t for j, t in tree.load_terms.items() if j not in held},
                    values={k: v for k, v in tree.values.items() if k not in gone},
                    known=frozenset(k for k in tree.known if k not in gone),
                    joint_names=names, mimic={j: m for j, m in tree.mimic.items() if j not in held},
                    friction_shape={j: law for j, law in tree.friction_shape.items() if j not in held},
                    frozen=frozen)


def _replace(tree: Tree, **changes: object) -> Tree:
    return dataclasses.replace(tree, **changes)


def _rotz(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rotx(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _validate(tree: Tree) -> None:
    where = f"model {tree.name!r}"
    for i, f in enumerate(tree.frames, start=1):
        if f.j != i:
            raise ModelError(f"{where}: frame rows must be numbered 1..n in order; row {i} says j={f.j}")
        if not 0 <= f.ant < f.j:
            raise ModelError(
                f"{where}, frame {f.j}: antecedent a({f.j}) = {f.ant} must satisfy 0 <= a(j) < j"
            )
        if f.sigma not in (REVOLUTE, PRISMATIC, FIXED):
            raise ModelError(
                f"{where}, frame {f.j}: sigma = {f.sigma}; use 0 (revolute), 1 (prismatic), 2 (fixed)"
            )
        for col in ("gamma", "b", "alpha", "d", "theta", "r"):
            v = getattr(f, col)
            if not np.isfinite(v):
                raise ModelError(f"{where}, frame {f.j}: {col} = {v} is not a finite number")
    n = len(tree.frames)
    for j, terms in tree.joint_terms.items():
        if not 1 <= j <= n:
            raise ModelError(f"{where}: joint terms given for frame {j}, which does not exist (1..{n})")
        bad = [t for t in terms if t not in JOINT_TERMS]
        if bad:
            raise ModelError(f"{where}, frame {j}: unknown joint term(s) {bad}; known: {JOINT_TERMS}")
        if tree.frames[j - 1].sigma == FIXED and terms:
            raise ModelError(f"{where}, frame {j} is fixed (sigma=2) and cannot have joint terms {terms}")
    for j, terms in tree.load_terms.items():
        if not 1 <= j <= n or tree.frames[j - 1].sigma == FIXED:
            raise ModelError(f"{where}: load terms given for frame {j}, which is not a moving joint (1..{n})")
        bad = [t for t in terms if t not in LOAD_TERMS]
        if bad:
            raise ModelError(f"{where}, frame {j}: unknown load term(s) {bad}; known: {LOAD_TERMS}")
    seen = set()
    for c in tree.couplings:
        if c.kind not in COUPLING_KINDS:
            raise ModelError(f"{where}, coupling {c.name!r}: kind {c.kind!r} not in {COUPLING_KINDS}")
        for j in c.coeffs:
            if not 1 <= j <= n or tree.frames[j - 1].sigma == FIXED:
                raise ModelError(f"{where}, coupling {c.name!r}: joint {j} is not a moving joint")
        if c.name in seen:
            raise ModelError(f"{where}: two couplings are named {c.name!r}")
        seen.add(c.name)
    names = set(tree.parameter_names)
    for c in tree.couplings:
        if sum(1 for nm in tree.parameter_names if nm == c.name) > 1:
            raise ModelError(f"{where}: coupling name {c.name!r} clashes with a standard parameter")
    unknown = [k for k in tree.values if k not in names]
    if unknown:
        raise ModelError(f"{where}: values given for unknown parameter(s) {unknown[:5]}")
    unknown = [k for k in tree.known if k not in names]
    if unknown:
        raise ModelError(f"{where}: 'known' lists unknown parameter(s) {unknown[:5]}")
    for k, v in tree.values.items():
        if not np.isfinite(v):
            raise ModelError(f"{where}: parameter {k} = {v} is not a finite number")
    if len(tree.gravity) != 3:
        raise ModelError(f"{where}: gravity must have 3 components")
    seen_names: dict[str, int] = {}
    for j, name in tree.joint_names.items():
        if not isinstance(j, int) or isinstance(j, bool) or not 1 <= j <= n:
            raise ModelError(f"{where}: joint name {name!r} given for frame {j!r}, which does not exist (1..{n})")
        if not isinstance(name, str) or not name:
            raise ModelError(f"{where}, frame {j}: the joint name must be a non-empty string, got {name!r}")
        if name in seen_names:
            raise ModelError(f"{where}: frames {seen_names[name]} and {j} are both named {name!r}")
        seen_names[name] = j
    for j, m in tree.mimic.items():
        w = f"{where}, frame {j}"
        if not isinstance(m, Mimic):
            raise ModelError(f"{w}: a mimic is Mimic(master, ratio, offset), got {m!r}")
        if not isinstance(j, int) or isinstance(j, bool) or not 1 <= j <= n or tree.frames[j - 1].sigma == FIXED:
            raise ModelError(f"{where}: mimic given for frame {j!r}, which is not a moving joint (1..{n})")
        if not isinstance(m.master, int) or not 1 <= m.master <= n or tree.frames[m.master - 1].sigma == FIXED:
            raise ModelError(f"{w} follows frame {m.master!r}, which is not a moving joint (1..{n})")
        if m.master == j or m.master in tree.mimic:
            raise ModelError(f"{w} follows frame {m.master}, which follows another joint or is itself: name the "
                             "joint that is actuated (a chain q3 = a q2 + b, q2 = c q1 + d is q3 = a c q1 + a d + b)")
        if not (np.isfinite(m.ratio) and np.isfinite(m.offset)) or m.ratio == 0.0:
            raise ModelError(f"{w}: mimic ratio {m.ratio!r} must be finite and non-zero, offset {m.offset!r} finite")
    for jname, v in tree.frozen.items():
        if not isinstance(jname, str) or not jname or isinstance(v, bool) or not isinstance(v, int | float) \
                or not np.isfinite(v):
            raise ModelError(f"{where}: frozen joint {jname!r} = {v!r}: a joint name and a finite value (rad or m)")
        if jname in tree.joint_names.values():
            raise ModelError(f"{where}: joint {jname!r} is both frozen and frame {tree.frame_of(jname)}")
    for j, law in tree.friction_shape.items():
        if not isinstance(j, int) or isinstance(j, bool) or not 1 <= j <= n:
            raise ModelError(f"{where}: friction shape given for frame {j!r}, which does not exist (1..{n})")
        if "FS" not in tree.joint_terms.get(j, ()):
            raise ModelError(f"{where}, frame {j}: a friction shape needs the joint's Coulomb term FS")
        if not isinstance(law, tuple) or len(law) != 2:
            raise ModelError(f"{where}, frame {j}: friction shape must be (shape, vs), got {law!r}")
        shape, vs = law
        if shape not in FRICTION_SHAPES:
            raise ModelError(f"{where}, frame {j}: friction shape {shape!r} not in {FRICTION_SHAPES}")
        if shape == "sign":
            if vs != 0.0:
                raise ModelError(f"{where}, frame {j}: vs = {vs!r} has no meaning for the sign law (0.0 or omit)")
        elif isinstance(vs, bool) or not isinstance(vs, int | float) or not (np.isfinite(vs) and vs > 0.0):
            raise ModelError(f"{where}, frame {j}: {shape} friction needs vs > 0 (m/s or rad/s), got {vs!r}")
    for j, law in tree.knees.items():
        if not isinstance(j, int) or isinstance(j, bool) or not 1 <= j <= n:
            raise ModelError(f"{where}: knees given for frame {j!r}, which does not exist (1..{n})")
        if not isinstance(law, tuple) or len(law) != 2 or any(isinstance(v, bool) or not isinstance(v, int | float)
                                                               for v in law):
            raise ModelError(f"{where}, frame {j}: knees must be (v-, v+), two numbers; got {law!r}")
        lo, hi = law
        if not (lo < 0.0 < hi) or math.isnan(lo) or math.isnan(hi):
            raise ModelError(f"{where}, frame {j}: knees (v-, v+) = {law!r} need v- < 0 < v+ (m/s or rad/s)")
    for j, terms in tree.joint_terms.items():
        lo, hi = tree.knee(j)
        for t, v, side in (("FVPH", hi, "v+"), ("FVNH", lo, "v-")):
            if t in terms and not math.isfinite(v):
                raise ModelError(f"{where}, frame {j}: the high-speed slope {t} needs a finite knee {side} "
                                 "(Tree.knees; a vehicle file's [dampers] knee_bump_m_s / knee_rebound_m_s)")
