"""The car's identification equations Y = W X (paper §5) and their base parameters.

Joint roles (DESIGN §5): 1-6 free (no actuator: tau = 0), dampers and tires elastic
(tau = 0, their K FV FS OFF and the anti-roll couplings are columns of W), steering,
camber, caster and kingpin are kinematic inputs, half track and half wheelbase constant,
wheel spin without a known torque. Only the equations with a known right-hand side are
kept: x y z yaw pitch roll (rows 1-6), the four dampers (9 18 27 36) and the four tires
(15 24 33 42), plus a wheel's spin row (14 23 32 41) where its torque is given.

Y is the generalized force of the measured wheel wrenches (and of the aerodynamic
wrench), minus the contribution of the parameters taken as known. The wheel wrenches
are given as the dynamometric wheels give them: force and moment about the WHEEL CENTRE
in the non-spinning wheel frame (x forward, y left along the axle, z up: the axes of the
tire frame). They act on the tire-deflection link, whose origin is the contact point,
wheel_radius - q15 below the centre, so the moment is carried there first.

Base parameters. With every joint of the tree free to move (the engine's numeric method
on random states), the paper's 48 parameters form a base set: nothing regroups and
nothing is eliminated, as the paper says (§4.2); `base="generic"` uses it. The car does
not move that way: the half track and half wheelbase are constants, and the tabulated
joints move by a degree or two. With them held still (`base="car"`), the wheel centres
still move along the dampers, so the wheel masses do NOT regroup into M6 (M6 is the
chassis alone; the car's mass is M6 + M14 + M23 + M32 + M41), but the diametral wheel
inertias do: the 4 relations

    XX6 + YY14 + YY23 + YY32 + YY41,   ZZ6 + YY14 + YY23 + YY32 + YY41,   XXw - YYw

leave 44 base parameters (for an axisymmetric wheel XXw - YYw = 0). On track data the
generic set is therefore nearly rank deficient in YY14..YY41 (and XX6, ZZ6 with them):
use base="car", or give the wheel inertias as known.

The wheel link spins whole: ZZ14 multiplies the spin plus the chassis pitch acceleration. A
corner's non-spinning parts (upright, caliper, knuckle) turn about the axle with the pitch
alone, and the template has no body for them (links 7-13 are massless), so their inertia
about the axle regroups with YY6: the estimated YY6 includes it (3.64 kg.m2 on the MuJoCo
test car, 0.2 % of its pitch inertia). Their inertias about the other axes belong in XX14, YY14.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..dynamics import BaseParameters, Model, Wrench
from ..dynamics.base import random_states
from ..kinematics.forward import cross, forward_kinematics, joint_array, to_local
from ..kinematics.per_tree import PerTree
from ..model.tree import CURVE_TERMS, FIXED, PRISMATIC, REVOLUTE, ModelError, Tree
from ..model.workspace import derived
from .template import (
    CHASSIS_GROUPS,
    CONSTANT_JOINTS,
    DAMPERS,
    EQUATION_ROWS,
    FRAMES,
    TIRES,
    WHEELS,
    paper_parameter_names,
    tabulated,
)

Array = np.ndarray


def group_name(row: int) -> str:
    """Equation group of a row: x y z yaw pitch roll, susp9, tire15, spin14, ..."""
    if row <= 6:
        return CHASSIS_GROUPS[row - 1]
    if row in DAMPERS:
        return f"susp{row}"
    if row in TIRES:
        return f"tire{row}"
    if row in WHEELS:
        return f"spin{row}"
    raise ModelError(f"joint {row} has no equation in the car's identification model")


def still_tree(tree: Tree) -> Tree:
    """The tree with the constant and tabulated joints made fixed (the car's motion for base parameters)."""
    still = set(CONSTANT_JOINTS) | {j for k in range(4) for j in tabulated(k)}
    frames = tuple(dataclasses.replace(f, sigma=FIXED) if f.j in still else f for f in tree.frames)
    return dataclasses.replace(tree, frames=frames)


# per tree, what _base and _radius computed from it: kept beside the tree while it lives (PerTree), a few keys each
_DERIVED: PerTree[dict] = PerTree(lambda tree: {})


def _cached(tree: Tree, key: tuple, make):
    """make() once per tree and key (make must not return something that refers to the tree)."""
    derived = _DERIVED(tree)
    if key not in derived:
        derived[key] = make()
    return derived[key]


def identified(tree: Tree) -> list[str]:
    """The paper's parameters not listed as known, in the paper's order (a damper's curve slopes in place of its h,
    `car_template(damper_knees=...)`), then the tires' offsets and progressive stiffnesses where the tree has them
    (`car_template(tire_offsets=True, tire_law="progressive")`) and their lateral-force terms
    (`tire_lateral_force=True`)."""
    paper = [c for n in paper_parameter_names()
             for c in ((n,) if n in tree.index or not n.startswith("FV")
                       else tuple(f"{t}{n[2:]}" for t in CURVE_TERMS if f"{t}{n[2:]}" in tree.index))]
    names = [*paper, *(f"{p}{t}" for p in ("OFF", "KQ", "KFY") for t in TIRES if f"{p}{t}" in tree.index)]
    return [n for n in names if n not in tree.known]


def _load_names(tree: Tree) -> list[str]:
    """The tree's load terms (model.tree: KFY15 ...), whose columns car_identification builds from the wrench."""
    return [f"{p}{j}" for j, terms in tree.load_terms.items() for p in terms]


def _base(tree: Tree, rows: tuple[int, ...], motion: str) -> BaseParameters:
    def make() -> BaseParameters:
        t = still_tree(tree) if motion == "car" else tree
        load = [n for n in identified(tree) if n in _load_names(tree)]
        bp = Model(t).base_parameters(rows=list(rows), cols=[n for n in identified(tree) if n not in load])
        if not load:
            return bp
        # a tire's -Fy² q column is the only one in its row with the lateral force: independent of the others
        # whenever Fy varies (the engines, without the measured wrench, would call it "no effect"), so each is a
        # base parameter of its own, regrouping nothing
        return dataclasses.replace(
            bp, names=(*bp.names, *load), columns=(*bp.columns, *(tree.index[n] for n in load)),
            expressions=(*bp.expressions, *load),
            beta=np.vstack([bp.beta, np.zeros((len(load), bp.beta.shape[1]))]))

    return _cached(tree, ("base", rows, motion), make)


def car_base_parameters(tree: Tree | Model, motion: str = "generic", spin_rows: Sequence[int] = ()) -> BaseParameters:
    """Base parameters of the paper's 48 for the car's equations (see the module doc).

    motion: "generic" (every joint moves) or "car" (constant and tabulated joints still).
    spin_rows: wheel frames whose spin equation is used too.
    """
    tree = tree.tree if isinstance(tree, Model) else tree
    if motion not in ("generic", "car"):
        raise ModelError(f"motion = {motion!r}: use 'generic' or 'car'")
    _check_car(tree)
    return _base(tree, (*EQUATION_ROWS, *sorted(spin_rows)), motion)


def _check_car(tree: Tree) -> None:
    if tree.n != FRAMES or any(f"K{t}" not in tree.index for t in TIRES) or "karf" not in tree.index:
        raise ModelError(f"model {tree.name!r} is not the car template (dynid.vehicle.car_template)")


def _radius(tree: Tree) -> float:
    """Unloaded radius: the wheel centre's distance from the contact point at q = 0 (same for every wheel)."""
    def make() -> float:
        T = Model(tree).transforms(np.zeros(tree.n))
        return float(np.linalg.norm(T[WHEELS[0], :3, 3] - T[TIRES[0], :3, 3]))

    return _cached(tree, ("radius",), make)


@dataclass(frozen=True)
class CarEquations:
    """Y = W X_B stacked group by group: W (m, p), Y (m,), groups (m,) labels, X_B named by `names`
    (W also as per_sample, (N, rows, p), the regressor's own layout).

    Unpacks as `W, Y, groups = car_identification(...)`. base: the regrouping relations
    (X_B = base.values(X) for a full parameter vector X of the tree); labels: the paper's
    labels of the names; rows: the joints used, in the stacking order.
    """

    per_sample: Array  # (N, rows, p): W sample by sample, as the regressor gives it (no copy)
    Y: Array
    groups: Array
    names: tuple[str, ...]
    labels: tuple[str, ...]
    base: BaseParameters
    rows: tuple[int, ...]

    @derived
    def W(self) -> Array:
        """(rows N, p), group by group (made on first use, kept beside the equations: a pipeline that filters
        columns reads per_sample)."""
        return np.ascontiguousarray(self.per_sample.transpose(1, 0, 2)).reshape(-1, self.per_sample.shape[2])

    def __iter__(self):
        return iter((self.W, self.Y, self.groups))

    def residual(self, X: Array) -> Array:
        """Y - W X_B for a full parameter vector X of the tree (the model error)."""
        return self.Y - self.W @ self.base.values(X)


def wheel_wrench_array(wheel_wrenches: Array | Mapping[int, Array], N: int) -> Array:
    """(N, 4, 6) from an (N, 4, 6) array or a mapping wheel frame (14, 23, 32, 41) -> (N, 6)."""
    if isinstance(wheel_wrenches, Mapping):
        bad = set(wheel_wrenches) - set(WHEELS)
        if bad or len(wheel_wrenches) != 4:
            raise ModelError(
                f"wheel_wrenches: need one (N, 6) array per wheel {WHEELS}; got keys {sorted(wheel_wrenches)}"
            )
        ww = np.stack([np.asarray(wheel_wrenches[w], dtype=float) for w in WHEELS], axis=1)
    else:
        ww = np.asarray(wheel_wrenches, dtype=float)
    if ww.shape != (N, 4, 6):
        raise ModelError(
            f"wheel_wrenches must be ({N}, 4, 6): per sample, per wheel (rear left, rear right, front left, "
            f"front right), Fx Fy Fz Mx My Mz at the wheel centre in the wheel frame; got {ww.shape}"
        )
    if not np.isfinite(ww).all():
        i, k, c = np.argwhere(~np.isfinite(ww))[0]
        raise ModelError(f"wheel_wrenches: non-finite value at sample {i}, wheel {WHEELS[k]}, component {c}")
    return ww


def load_rows(model: Model | Tree, q: Array, rows: Sequence[int] = EQUATION_ROWS) -> Array:
    """dY/d(wheel wrench): (N, len(rows), 4, 6), the change of each equation's right-hand side per unit change of
    each measured wheel-wrench component (N, N·m; `car_identification`'s convention: at the wheel centre, in the
    wheel frame; wheels rear left, rear right, front left, front right) at the joints q (N, 42). Y is linear in
    the wrenches (their generalized force J_tᵀ w, the wrench carried to the contact point, the origin of tire
    frame t): exact, whatever the wrenches."""
    model = model if isinstance(model, Model) else Model(model)
    bad = [r for r in rows if not 1 <= r <= model.n]
    if bad:
        raise ModelError(f"load_rows: rows {bad} are not joints of the {model.n}-frame tree (1 to {model.n})")
    q = np.atleast_2d(np.asarray(q, dtype=float))
    rho = _radius(model.tree) - q[:, np.array(TIRES) - 1]  # (N, 4) centre above the contact point, along z
    cols = np.asarray(rows) - 1
    # samples last while it is built (each entry a contiguous row), returned samples first (a view)
    out = np.empty((len(cols), 4, 6, q.shape[0]))
    for k, J in enumerate(_tire_jacobians(model, q, rows)):  # (6, rows, N): linear, then angular
        out[:, k] = J.transpose(1, 0, 2)
        # a force moves the moment about the contact point too: M_contact = M + (-rho Fy, rho Fx, 0)
        out[:, k, 0] += rho[:, k] * J[4]
        out[:, k, 1] -= rho[:, k] * J[3]
    return np.moveaxis(out, -1, 0)


def _tire_jacobians(model: Model, q: Array, rows: Sequence[int]) -> list[Array]:
    """Each tire frame's Jacobian at its origin, expressed in it, of the joints `rows` alone (`Model.jacobian`'s
    columns `rows` - 1), samples last: (6, len(rows), N). One forward pass for the four tires, and only the columns
    asked (each tire's whole (N, 6, 42), then gathered, cost twice as much on a 60 s segment's coarse samples)."""
    tree = model.tree
    if tree.mimic:  # a mimic joint's column goes to its master's (Model.jacobian)
        return [np.moveaxis(model.jacobian(q, t, expressed_in=t)[:, :, np.asarray(rows) - 1], 0, -1) for t in TIRES]
    qs, _ = joint_array(q, tree, "q")
    st = forward_kinematics(tree, qs, frames=TIRES)
    out = []
    for t in TIRES:
        J = np.zeros((6, len(rows), qs.shape[1]))
        R, above = st.Rc[t], set(tree.ancestors[t])
        for i, j in enumerate(rows):
            if j not in above or tree.sigma[j] not in (REVOLUTE, PRISMATIC):
                continue
            z = st.Rc[j][2]
            if tree.sigma[j] == REVOLUTE:
                J[:3, i] = to_local(R, cross(z, st.P[t] - st.P[j]))
                J[3:, i] = to_local(R, z)
            else:
                J[:3, i] = to_local(R, z)
        out.append(J)
    return out


@dataclass(frozen=True)
class _Columns:
    """`car_identification`'s rows and W's columns: the base set's, then the known parameters' (their contribution
    goes to Y); load: the load terms' (built from the measured wrench), engine: the others (the regressor's)."""

    rows: tuple[int, ...]
    base: BaseParameters
    known: list[int]
    cols: list[int]
    load: set[int]
    engine: list[int]


def _equation_columns(tree: Tree, base: str | BaseParameters, spin: Sequence[int]) -> _Columns:
    """The rows and columns of the car's equations with the spin rows `spin` (`car_identification`'s checks)."""
    _check_car(tree)
    rows = (*EQUATION_ROWS, *spin)
    bp = car_base_parameters(tree, base, spin) if isinstance(base, str) else base
    ident = set(identified(tree))
    X = tree.parameters
    known_cols = [i for i, n in enumerate(tree.parameter_names) if n not in ident and X[i] != 0.0]
    used = [tree.parameter_names[c] for c in (*bp.columns, *bp.regrouped_columns)]
    if any(n not in ident for n in used):
        raise ModelError(
            f"the base set uses {[n for n in used if n not in ident]}, known in {tree.name!r}; "
            f"pass base='generic' or 'car' to compute one without them"
        )
    cols = list(bp.columns) + known_cols
    load = {tree.index[n] for n in _load_names(tree)}
    return _Columns(rows, bp, known_cols, cols, load, [c for c in cols if c not in load])


def _contact_wrenches(tree: Tree, q: Array, ww: Array, aero_wrench: Wrench | None
                      ) -> tuple[list[Wrench], Array, Array]:
    """The measured wheel wrenches (N, 4, 6) as Wrenches at the contact points (the tire frames' origins), then the
    aerodynamic one if any; and the measured forces and moments F, M (N, 4, 3) each."""
    # measured moments about the wheel centres, carried to the contact points (origins of the tire frames)
    rho = _radius(tree) - q[:, np.array(TIRES) - 1]  # (N, 4) centre above the contact point, along z
    F, M = ww[:, :, :3], ww[:, :, 3:]
    contact = ww.copy()  # M_contact = M + (-rho Fy, rho Fx, 0), written in place
    contact[:, :, 3] -= rho * F[:, :, 1]
    contact[:, :, 4] += rho * F[:, :, 0]
    wrenches = [Wrench(t, contact[:, k], frame=t) for k, t in enumerate(TIRES)]
    if aero_wrench is not None:
        wrenches.append(aero_wrench)
    return wrenches, F, M


def _load_column(q: Array, F: Array, t: int) -> Array:
    """KFY (model.tree's only load term) of tire t's row: - Fy² q of its wheel's transducer."""
    return -F[:, TIRES.index(t), 1] ** 2 * q[:, t - 1]


def car_identification(
    model: Model | Tree,
    q: Array,
    qd: Array,
    qdd: Array,
    wheel_wrenches: Array | Mapping[int, Array],
    aero_wrench: Wrench | None = None,
    spin_torques: Mapping[int, Array] | None = None,
    base: str | BaseParameters = "generic",
    regressor: Callable[..., tuple[Array, Array]] | None = None,
) -> CarEquations:
    """W, Y and the equation groups of the car's identification model over N samples.

    q, qd, qdd: (N, 42) joint trajectories (constant joints' columns 0, tabulated ones filled,
    e.g. by `KinematicTables.joints`). wheel_wrenches: (N, 4, 6) ground-on-wheel wrenches,
    N and N·m, at the wheel centres in the wheel frames (rear left, rear right, front left,
    front right). aero_wrench: the aerodynamic Wrench on link 6 (`aero.aero_wrench`).
    spin_torques: wheel frame -> (N,) torque on the wheel about its axle (z, pointing left)
    from the driveline and brakes, N·m; adds that wheel's spin equation.
    base: "generic", "car" (see the module doc) or a BaseParameters of the same rows.
    regressor: a callable with `Model.regressor`'s signature (q, qd, qdd, wrenches, rows, cols) -> (W, Q),
    e.g. `dynid.symbolic.generated.GeneratedRegressor(tree)` for generated code; default the engine's.

    Parameters of the tree outside the paper's 48, or listed in tree.known, are known:
    their contribution goes to Y. Rows are stacked group by group (all samples of x, then y...).
    """
    model = model if isinstance(model, Model) else Model(model)
    tree = model.tree
    _check_car(tree)
    q, qd, qdd = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, qd, qdd))
    N = q.shape[0]
    ww = wheel_wrench_array(wheel_wrenches, N)
    spin_torques = dict(spin_torques or {})
    bad = set(spin_torques) - set(WHEELS)
    if bad:
        raise ModelError(f"spin_torques: keys must be wheel frames {WHEELS}; got {sorted(bad)}")
    spin = sorted(spin_torques)
    c = _equation_columns(tree, base, spin)
    rows, bp, known_cols, cols, load, engine = c.rows, c.base, c.known, c.cols, c.load, c.engine
    X = tree.parameters
    wrenches, F, M = _contact_wrenches(tree, q, ww, aero_wrench)
    W, Q = (regressor or model.regressor)(q, qd, qdd, wrenches, rows=list(rows), cols=engine)
    W = np.asarray(W)
    if len(engine) < len(cols):  # the load terms' columns, from the measured wrench (model.tree)
        full = np.zeros((N, len(rows), len(cols)))
        full[:, :, [i for i, c in enumerate(cols) if c not in load]] = W
        for i, c in enumerate(cols):
            if c in load:
                t = int(tree.parameter_names[c].removeprefix("KFY"))
                full[:, rows.index(t), i] = _load_column(q, F, t)
        W = full
    nb = len(bp.columns)
    Y = Q.copy()
    for i, w in enumerate(spin):  # the ground's moment about the axle acts on the wheel itself
        k = WHEELS.index(w)
        Y[:, len(EQUATION_ROWS) + i] += np.asarray(spin_torques[w], dtype=float) + M[:, k, 1]
    if known_cols:
        Y -= W[:, :, nb:] @ X[known_cols]
    Wb = W[:, :, :nb]
    names = tuple(bp.names)
    return CarEquations(
        per_sample=Wb,
        Y=Y.T.reshape(-1),
        groups=np.repeat(np.array([group_name(r) for r in rows]), N),
        names=names,
        labels=tuple(tree.label(n) for n in names),
        base=bp,
        rows=rows,
    )


class CarResidual:
    """Y − W x of `car_identification`'s equations (no spin rows) for one value per column of its W, trajectory
    after trajectory: the columns worked out once, and W x summed from the regressor's W as it comes, over the
    entries that are not structural zeros alone (126 of the paper's 14 x 48), Y and W never formed apart (the known
    parameters' columns enter with their values, as their part of Y does). What the residuals of many moved copies
    of one trajectory need (`pipeline.car`)."""

    def __init__(self, model: Model | Tree, x: Array, base: str | BaseParameters = "generic",
                 regressor: Callable[..., tuple[Array, Array]] | None = None) -> None:
        self.model = model if isinstance(model, Model) else Model(model)
        tree = self.model.tree
        self.columns = c = _equation_columns(tree, base, ())
        x = np.asarray(x, dtype=float)
        if x.shape != (len(c.base.columns),):
            raise ModelError(f"CarResidual: x must hold one value per base parameter ({len(c.base.columns)}); "
                             f"got shape {x.shape}")
        values = np.concatenate([x, tree.parameters[c.known]])  # per column of c.cols
        self.engine_values = np.array([v for v, j in zip(values, c.cols, strict=True) if j not in c.load])
        self.load_values = [(v, int(tree.parameter_names[j].removeprefix("KFY")))
                            for v, j in zip(values, c.cols, strict=True) if j in c.load]
        self.regressor = regressor or self.model.regressor
        self._live: list[tuple[int, Array]] | None = None

    def __call__(self, q: Array, qd: Array, qdd: Array, wheel_wrenches: Array, aero_wrench: Wrench | None = None
                 ) -> Array:
        """(N, rows): Y − W x at these samples (`car_identification`'s arguments, wheel_wrenches (N, 4, 6))."""
        tree, c = self.model.tree, self.columns
        q = np.atleast_2d(np.asarray(q, dtype=float))
        ww = wheel_wrench_array(wheel_wrenches, q.shape[0])
        wrenches, F, _ = _contact_wrenches(tree, q, ww, aero_wrench)
        if self._live is None:
            self._live = self._structure(wrenches)
        W, Q = self.regressor(q, qd, qdd, wrenches, rows=list(c.rows), cols=c.engine)
        # (rows, cols, N): the generated regressor's W has each entry's samples contiguous; the sum is bound by
        # memory, and the live entries are a fifth of W (an einsum over all of it took twice as long)
        Wt = np.moveaxis(np.asarray(W), 0, -1)
        r = np.array(np.asarray(Q).T)
        for i, cols in self._live:
            r[i] -= self.engine_values[cols] @ Wt[i, cols]
        for v, t in self.load_values:
            r[c.rows.index(t)] -= v * _load_column(q, F, t)
        return r.T

    def _structure(self, wrenches: Sequence[Wrench]) -> list[tuple[int, Array]]:
        """Per row, its columns that are not structural zeros and whose value is not 0: W's nonzero entries at
        random states (angles over the full turn, every damper curve's pieces visited: `random_states`), where no
        expression of the model vanishes unless it is identically zero; the wrenches' sites as given (their values
        do not enter W; their sites choose the generated kernel)."""
        c, samples = self.columns, 256
        q, qd, qdd = random_states(self.model.tree, samples, seed=0)
        rng = np.random.default_rng(0)
        anywhere = [dataclasses.replace(w, values=rng.normal(size=(samples, 6))) for w in wrenches]
        W, _ = self.regressor(q, qd, qdd, anywhere, rows=list(c.rows), cols=c.engine)
        live = np.any(np.asarray(W) != 0, axis=0) & (self.engine_values != 0)
        return [(i, np.flatnonzero(live[i])) for i in range(len(c.rows)) if live[i].any()]
