"""The paper's car: template, identification equations, statics, base parameters.

Oracles: the engine's inverse dynamics (itself checked against Pinocchio) for the wheel
wrenches that a trajectory needs; rigid-body statics (forces and moments balance, lever
arms); the paper's equation (3) written out by hand for the suspension forces; matrix
rank of W sampled on the car's own motion; the geometry's numbers for the frame poses.
"""

import dataclasses

import numpy as np
import pytest

from dynid import Model, Wrench
from dynid.model import ModelError
from dynid.vehicle import parameters as params
from dynid.vehicle.aero import aero_wrench
from dynid.vehicle.car_model import car_template
from dynid.vehicle.equations import car_base_parameters, car_identification
from dynid.vehicle.geometry import AxleGeometry, GeometryError, demo_geometry
from dynid.vehicle.statics import rest_state
from dynid.vehicle.tables import default_tables
from dynid.vehicle.template import DAMPERS, EQUATION_ROWS, TIRES, WHEELS, paper_parameter_names

ROWS = np.array(EQUATION_ROWS) - 1


@pytest.fixture(scope="module")
def truth_model():
    return Model(car_template(None, params.truth().values))


def sines(rng, t, amp, n=3, f0=0.2, f1=1.5):
    """A smooth random signal and its two derivatives."""
    q, qd, qdd = (np.zeros_like(t) for _ in range(3))
    for _ in range(n):
        a, w, p = amp * rng.normal() / np.sqrt(n), 2 * np.pi * rng.uniform(f0, f1), rng.uniform(0, 2 * np.pi)
        q += a * np.sin(w * t + p)
        qd += a * w * np.cos(w * t + p)
        qdd -= a * w * w * np.sin(w * t + p)
    return q, qd, qdd


def driving(model, rng, N=80, speed=25.0, steer=1.0):
    """Free and elastic joints around the rest state, wheels rolling, tabulated joints from the tables."""
    rest = rest_state(model.tree)
    t = np.linspace(0.0, 2.0, N)
    q, qd, qdd = (np.zeros((N, 42)) for _ in range(3))
    amp = {1: 0.05, 2: 0.05, 3: 0.005, 4: 0.01, 5: 0.01, 6: 0.01}
    amp.update({d: 0.01 for d in DAMPERS})
    amp.update({w: 1.0 for w in WHEELS})
    amp.update({k: 0.002 for k in TIRES})
    for j, a in amp.items():
        s = sines(rng, t, a)
        q[:, j - 1], qd[:, j - 1], qdd[:, j - 1] = s[0] + rest.q[j - 1], s[1], s[2]
    q[:, 1] += speed * t
    qd[:, 1] += speed
    for w in WHEELS:
        q[:, w - 1] += speed / 0.3 * t
        qd[:, w - 1] += speed / 0.3
    return default_tables().joints(q, qd, qdd, sines(rng, t, steer, n=2))


def required_wrenches(model, q, qd, qdd, extra, rng):
    """Ground wrenches at the wheel centres (wheel-frame axes) that make the 14 equations hold, and the q they need.

    Applied to the hub (frame 13 of the corner) at the wheel centre, the wrenches reach every
    chassis and damper equation as on the tire link, but do not depend on the tire deflection.
    The equations are linear in them: one inverse-dynamics call per unit wrench gives the map;
    per sample, plausible tire forces (static load, random longitudinal and lateral forces and
    moments) are corrected by the least-norm change that satisfies the 6 chassis and 4 damper
    equations. The tire equations then set the deflections: q_tire = Fz / kt.
    """
    tree = model.tree
    rows = np.array([1, 2, 3, 4, 5, 6, *DAMPERS]) - 1
    N = q.shape[0]
    T0 = model.transforms(np.zeros(42))
    hubs = [t - 2 for t in TIRES]
    centre = [T0[h][:3, :3].T @ (T0[w][:3, 3] - T0[h][:3, 3]) for h, w in zip(hubs, WHEELS, strict=True)]

    def on_hubs(values):
        return [Wrench(h, values[:, k], point=tuple(centre[k]), frame=t)
                for k, (h, t) in enumerate(zip(hubs, TIRES, strict=True))]

    tau0 = model.inverse_dynamics(q, qd, qdd, wrenches=extra)[:, rows]
    A = np.zeros((N, len(rows), 24))
    for i in range(24):
        e = np.zeros((N, 4, 6))
        e[:, i // 6, i % 6] = 1.0
        A[:, :, i] = model.inverse_dynamics(q, qd, qdd, wrenches=[*extra, *on_hubs(e)])[:, rows] - tau0
    prior = np.zeros((N, 4, 6))
    prior[:, :, 2] = 4300.0
    prior[:, :, [0, 1]] = rng.normal(size=(N, 4, 2)) * 500.0
    prior[:, :, 3:] = rng.normal(size=(N, 4, 3)) * 50.0
    prior = prior.reshape(N, 24)
    gap = -tau0 - np.einsum("nrc,nc->nr", A, prior)
    F = prior + np.stack([np.linalg.lstsq(A[i], gap[i], rcond=None)[0] for i in range(N)])
    F = F.reshape(N, 4, 6)
    q = q.copy()
    for k, t in enumerate(TIRES):
        q[:, t - 1] = F[:, k, 2] / tree.values[f"K{t}"]
    return F, q


def as_measured(model, q, F):
    """Moments about the wheel centres (origin of the wheel frames), from the engine's transforms."""
    T = model.transforms(q)
    out = F.copy()
    for k, (t, w) in enumerate(zip(TIRES, WHEELS, strict=True)):
        r = np.einsum("nji,nj->ni", T[:, t, :3, :3], T[:, w, :3, 3] - T[:, t, :3, 3])
        out[:, k, 3:] = F[:, k, 3:] - np.cross(r, F[:, k, :3])
    return out


def assert_round_off(eq, X, tol=1e-9):
    res = eq.residual(X)
    for g in dict.fromkeys(eq.groups):
        m = eq.groups == g
        scale = np.abs(eq.Y[m]).max() + np.abs(eq.W[m] * eq.base.values(X)).max() + 100.0  # floor: 100 N
        assert np.abs(res[m]).max() <= tol * scale, (g, np.abs(res[m]).max(), scale)


# ----- template ------------------------------------------------------------------------

def test_numbering_roles_and_labels_follow_the_paper():
    tree = car_template()
    assert tree.n == 42
    assert [tree.frames[j - 1].ant for j in TIRES] == [13, 22, 31, 40]
    sigmas = [tree.frames[j - 1].sigma for j in (1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 14, 15)]
    assert sigmas == [1, 1, 1, 0, 0, 0, 1, 1, 1, 0, 0, 1]
    for label, name in (("ks9", "K9"), ("h27", "FV27"), ("fs36", "FS36"), ("off18", "OFF18"), ("kt42", "K42")):
        assert tree.parameter_names[tree.column(label)] == name
    assert len(paper_parameter_names()) == 48 and paper_parameter_names()[-2:] == ("karf", "karr")
    assert {c.name: c.coeffs for c in tree.couplings} == {"karr": {9: 1.0, 18: -1.0}, "karf": {27: 1.0, 36: -1.0}}


def test_design_pose_matches_the_geometry():
    g = demo_geometry()
    T = Model(car_template(g)).transforms(np.zeros(42))
    np.testing.assert_allclose(T[6][:3, :3], [[0, 1, 0], [0, 0, 1], [1, 0, 0]], atol=1e-15)  # x6 up, y6 right, z6 fwd
    # wheel centres in frame 6 coordinates (up, right, forward)
    expect = {14: (0, -0.75, 0.0), 23: (0, 0.75, 0.0), 32: (0, -0.755, 2.70), 41: (0, 0.755, 2.70)}
    for w, p in expect.items():
        np.testing.assert_allclose(T[6][:3, :3].T @ T[w][:3, 3], p, atol=1e-12)
        np.testing.assert_allclose(T[w][:3, 2], [-1, 0, 0], atol=1e-12)  # axle points left (world -x0)
        np.testing.assert_allclose(T[w + 1][:3, 3], T[w][:3, 3] - [0, 0, 0.317], atol=1e-12)  # contact below
    # front-left damper: 11° inboard (towards +x0, the right) and 3° rearward (towards -y0) from the vertical
    z = T[27][:3, 2]
    np.testing.assert_allclose([np.arctan(z[0] / z[2]), np.arctan(-z[1] / z[2])], np.radians([11.0, 3.0]), atol=1e-12)
    # front-left kingpin axis passes 0.06 m inboard of the wheel centre
    k, o = T[31][:3, 2], T[31][:3, 3] - T[32][:3, 3]
    assert abs(np.linalg.norm(np.cross(o, k)) / np.linalg.norm(np.cross([1, 0, 0], k)) - 0.06) < 1e-12


def test_a_priori_centre_of_mass_is_the_papers():
    c = params.a_priori().centre_of_mass(6)
    np.testing.assert_allclose(c, (0.319, 0.003, 1.405), atol=5e-4)


# ----- identification equations ----------------------------------------------------------

def test_equations_vanish_with_the_true_parameters(truth_model):
    rng = np.random.default_rng(0)
    q, qd, qdd = driving(truth_model, rng)
    aw = aero_wrench(truth_model, q, qd)
    F, q = required_wrenches(truth_model, q, qd, qdd, [aw], rng)
    assert np.abs(F[:, :, :2]).max() < 5000 and (F[:, :, 2] > 1000).all()  # plausible tire forces
    eq = car_identification(truth_model, q, qd, qdd, F, aero_wrench=aw)
    assert eq.W.shape == (80 * 14, 48) and set(eq.groups) == {
        "x", "y", "z", "yaw", "pitch", "roll", "susp9", "susp18", "susp27", "susp36",
        "tire15", "tire24", "tire33", "tire42"}
    assert_round_off(eq, truth_model.parameters)
    W, Y, groups = eq
    assert W is eq.W and Y is eq.Y and groups is eq.groups
    # the aerodynamic wrench matters at 25 m/s: leaving it out breaks the x equation by the drag
    eq0 = car_identification(truth_model, q, qd, qdd, F)
    drag = 0.5 * 1.225 * 2.0 * 25.0**2 * 0.31
    gap = np.abs(eq0.residual(truth_model.parameters)[eq0.groups == "y"]).mean()
    assert 0.5 * drag < gap < 1.5 * drag


def test_spin_rows_with_the_drive_torque(truth_model):
    rng = np.random.default_rng(1)
    q, qd, qdd = driving(truth_model, rng, N=40)
    meas, q = required_wrenches(truth_model, q, qd, qdd, [], rng)
    # the wheel's equation by hand: J q'' = drive torque + the ground's moment about the axle; with the
    # engine's hub-to-wheel torque for the motion (no wrench on the wheel itself) the drive torque follows
    tau = truth_model.inverse_dynamics(q, qd, qdd)
    drive = {w: tau[:, w - 1] - meas[:, k, 4] for k, w in enumerate(WHEELS)}
    eq = car_identification(truth_model, q, qd, qdd, meas, spin_torques={14: drive[14], 41: drive[41]})
    assert {"spin14", "spin41"} <= set(eq.groups) and "spin23" not in set(eq.groups)
    assert_round_off(eq, truth_model.parameters)


def test_known_parameters_move_to_the_right_hand_side(truth_model):
    rng = np.random.default_rng(2)
    q, qd, qdd = driving(truth_model, rng, N=30)
    F, q = required_wrenches(truth_model, q, qd, qdd, [], rng)
    known = Model(truth_model.tree.with_known({f"YY{w}" for w in WHEELS} | {"kt15"}))
    eq = car_identification(known, q, qd, qdd, F)
    assert len(eq.names) == 43 and "YY14" not in eq.names and "K15" not in eq.names
    assert_round_off(eq, truth_model.parameters)


def test_car_base_set_is_exact_when_the_tabulated_joints_are_still(truth_model):
    rng = np.random.default_rng(3)
    q, qd, qdd = driving(truth_model, rng, N=30, steer=0.0)
    for a in (qd, qdd):  # tables hold them still: their columns only follow the dampers, zero them
        a[:, [j - 1 for j in range(10, 43) if (j - 7) % 9 in (3, 4, 5, 6)]] = 0.0
    q[:, [j - 1 for j in range(10, 43) if (j - 7) % 9 in (3, 4, 5, 6)]] = 0.0
    F, q = required_wrenches(truth_model, q, qd, qdd, [], rng)
    eq = car_identification(truth_model, q, qd, qdd, F, base="car")
    assert len(eq.names) == 44
    assert_round_off(eq, truth_model.parameters)


# ----- base parameters ---------------------------------------------------------------------

def test_base_parameters_generic_and_car_motion(truth_model):
    gen = car_base_parameters(truth_model, "generic")
    assert gen.rank == 48 and gen.regrouped == () and gen.eliminated == ()
    car = car_base_parameters(truth_model, "car")
    assert car.rank == 44 and set(car.regrouped) == {"YY14", "YY23", "YY32", "YY41"}
    expr = dict(zip(car.names, car.expressions, strict=True))
    assert expr["XX6"] == "XX6 + YY14 + YY23 + YY32 + YY41" == expr["XX6"]
    assert expr["ZZ6"] == "ZZ6 + YY14 + YY23 + YY32 + YY41" and expr["XX32"] == "XX32 - YY32"
    assert expr["M6"] == "M6" and expr["M14"] == "M14"  # wheel masses do not regroup into the chassis


def test_rank_on_the_cars_own_motion_is_44(truth_model):
    """Oracle: numpy's rank of W sampled with constant and tabulated joints still, dampers and tires moving."""
    rng = np.random.default_rng(4)
    N = 60
    q, qd, qdd = (np.zeros((N, 42)) for _ in range(3))
    for j in (1, 2, 3, 4, 5, 6, *DAMPERS, *WHEELS, *TIRES):
        q[:, j - 1], qd[:, j - 1], qdd[:, j - 1] = rng.normal(size=(3, N)) * (0.05 if j > 6 else 1.0)
    W = truth_model.regressor(q, qd, qdd, rows=list(EQUATION_ROWS), cols=list(paper_parameter_names()))
    W = W.reshape(-1, 48)
    W = W / np.linalg.norm(W, axis=0)
    assert np.linalg.matrix_rank(W, tol=1e-8) == 44
    # the regrouping: an isotropic share of the wheel's inertia turns with the chassis
    c = {n: i for i, n in enumerate(paper_parameter_names())}
    raw = truth_model.regressor(q, qd, qdd, rows=list(EQUATION_ROWS), cols=list(paper_parameter_names()))
    raw = raw.reshape(-1, 48)
    np.testing.assert_allclose(raw[:, c["YY23"]], raw[:, c["XX6"]] + raw[:, c["ZZ6"]] - raw[:, c["XX23"]], atol=1e-9)


# ----- statics ---------------------------------------------------------------------------

def test_rest_loads_balance_the_weight_and_split_by_the_lever_arms(truth_model):
    tree = truth_model.tree
    rest = rest_state(tree)
    v = tree.values
    weight = 9.81 * (v["M6"] + sum(v[f"M{w}"] for w in WHEELS))
    assert abs(rest.loads.sum() - weight) < 1e-6 * weight
    T = truth_model.transforms(rest.q)
    contact = np.array([T[t][:3, 3] for t in TIRES])
    com = (v["M6"] * (T[6][:3, :3] @ np.array([v["MX6"], v["MY6"], v["MZ6"]]) / v["M6"] + T[6][:3, 3])
           + sum(v[f"M{w}"] * T[w][:3, 3] for w in WHEELS)) * 9.81 / weight
    # moments about the ground axes balance: sum F_i p_i = W p_G (horizontal components)
    np.testing.assert_allclose(rest.loads @ contact[:, :2], weight * com[:2], rtol=0, atol=1e-6 * weight)
    # closed form with the design lever arms: front axle share = z_G / wheelbase (rear axle at z6 = 0)
    zG = (v["MZ6"] + 2.70 * (v["M32"] + v["M41"])) / (v["M6"] + sum(v[f"M{w}"] for w in WHEELS))
    front = rest.loads[2:].sum() / weight
    assert abs(front - zG / 2.70) < 5e-3
    # the truth's offsets put every damper at its design position at rest
    np.testing.assert_allclose(rest.damper_clearances, 0.0, atol=1e-9)
    assert (rest.tire_deflections > 0).all()


def test_suspension_equations_give_the_static_preloads(truth_model):
    tree = truth_model.tree
    rest = rest_state(tree)
    T = truth_model.transforms(rest.q)
    # the loads as the dynamometric wheels would give them: vertical force, in each wheel frame, about its centre
    ww = np.zeros((1, 4, 6))
    for k, t in enumerate(TIRES):
        ww[0, k, :3] = T[t][:3, :3].T @ [0.0, 0.0, rest.loads[k]]
    ww = as_measured(truth_model, rest.q[None], ww)
    eq = car_identification(truth_model, rest.q, np.zeros(42), np.zeros(42), ww)
    X = eq.base.values(tree.parameters)
    for k, d in enumerate(DAMPERS):
        m = eq.groups == f"susp{d}"
        spring = [i for i, n in enumerate(eq.names) if n in (f"K{d}", f"FV{d}", f"FS{d}", f"OFF{d}", "karr", "karf")]
        body = [i for i in range(len(X)) if i not in spring]
        preload = (eq.Y[m] - eq.W[m][:, body] @ X[body])[0]
        # closed form: the damper carries the load minus the wheel's weight, projected on its axis
        up = T[d][:3, 2] @ [0.0, 0.0, 1.0]
        expected = (rest.loads[k] - 9.81 * tree.values[f"M{WHEELS[k]}"]) * up
        assert abs(preload - expected) < 1e-6 * expected
        assert abs(preload - tree.values[f"OFF{d}"]) < 1e-6 * expected


@pytest.mark.parametrize("mode", ["heave", "roll"])
def test_heave_and_roll_give_the_suspension_and_anti_roll_forces(truth_model, mode):
    """Equation (3) of the paper by hand: F = ks q + h q' + fs sign(q') + off + kar (q - q_opposite)."""
    tree = truth_model.tree
    rest = rest_state(tree)
    N, A, w = 50, 0.02, 2 * np.pi * 1.2
    t = np.linspace(0.05, 1.6, N)
    q = np.tile(rest.q, (N, 1))
    qd, qdd = np.zeros_like(q), np.zeros_like(q)
    sgn = {9: 1, 18: 1, 27: 1, 36: 1} if mode == "heave" else {9: 1, 18: -1, 27: 1, 36: -1}
    for d, s in sgn.items():
        q[:, d - 1] = s * A * np.sin(w * t)
        qd[:, d - 1] = s * A * w * np.cos(w * t)
        qdd[:, d - 1] = -s * A * w * w * np.sin(w * t)
    if mode == "heave":  # the body moves down as the dampers compress
        q[:, 2] -= A * np.sin(w * t)
        qd[:, 2] -= A * w * np.cos(w * t)
        qdd[:, 2] += A * w * w * np.sin(w * t)
    q, qd, qdd = default_tables().joints(q, qd, qdd)
    rng = np.random.default_rng(5)
    F, q = required_wrenches(truth_model, q, qd, qdd, [], rng)
    eq = car_identification(truth_model, q, qd, qdd, F)
    X = eq.base.values(tree.parameters)
    v = tree.values
    opposite = {9: 18, 18: 9, 27: 36, 36: 27}
    for d in DAMPERS:
        m = eq.groups == f"susp{d}"
        spring = [i for i, n in enumerate(eq.names) if n in (f"K{d}", f"FV{d}", f"FS{d}", f"OFF{d}", "karr", "karf")]
        body = [i for i in range(len(X)) if i not in spring]
        force = eq.Y[m] - eq.W[m][:, body] @ X[body]
        x, xd, xo = q[:, d - 1], qd[:, d - 1], q[:, opposite[d] - 1]
        kar = v["karr"] if d in (9, 18) else v["karf"]
        bar = kar * (x - xo)
        np.testing.assert_allclose(bar, 0.0 if mode == "heave" else 2 * kar * x, atol=1e-9)
        expected = v[f"K{d}"] * x + v[f"FV{d}"] * xd + v[f"FS{d}"] * np.sign(xd) + v[f"OFF{d}"] + bar
        np.testing.assert_allclose(force, expected, rtol=1e-9, atol=1e-6)


# ----- bad input ---------------------------------------------------------------------------

def test_geometry_that_makes_wheels_coincide_is_refused():
    with pytest.raises(GeometryError, match=r"half_track = 0\.0 m makes the left and right wheel centres coincide"):
        dataclasses.replace(demo_geometry(), rear=AxleGeometry(half_track=0.0, position=0.0))
    with pytest.raises(GeometryError, match="axles coincide or are swapped"):
        dataclasses.replace(demo_geometry(), front=AxleGeometry(half_track=0.75, position=0.1))


def test_geometry_that_makes_wheels_float_is_refused():
    # front axle 1.0 m ahead of the rear one: the centre of mass (1.4 m) is in front of it. Describing the car
    # solves nothing; its rest state, where it is needed (the simulator, the truth's preloads), refuses it
    g = dataclasses.replace(demo_geometry(), front=AxleGeometry(half_track=0.755, position=1.0))
    tree = car_template(g, params.a_priori().values)
    with pytest.raises(GeometryError, match=r"rear left wheel \(frame 14\) would float.*negative tire deflection q15"):
        rest_state(tree, default_tables(g), fix_dampers=True)


def test_not_a_car_and_bad_wrenches_are_refused(truth_model):
    from dynid import load_model

    with pytest.raises(ModelError, match="not the car template"):
        car_identification(load_model("tx40"), np.zeros(6), np.zeros(6), np.zeros(6), np.zeros((1, 4, 6)))
    with pytest.raises(ModelError, match=r"wheel_wrenches must be \(2, 4, 6\)"):
        car_identification(truth_model, np.zeros((2, 42)), np.zeros((2, 42)), np.zeros((2, 42)), np.zeros((2, 6)))
