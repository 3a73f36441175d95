"""Inverse dynamics properties against independent oracles: linearity in X, energy, closed forms."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from oracles import random_states, random_tree

from dynid import Model, Wrench, load_model
from dynid.kinematics.forward import cross, dot, forward_kinematics, joint_array, to_world
from dynid.kinematics.motion import dense, local_motion
from dynid.model import Coupling, Frame, Tree


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), model=st.sampled_from(["puma560", "tx40", "floating_tree"]))
def test_regressor_times_any_X_is_the_inverse_dynamics(seed, model):
    """W X = tau for random parameter vectors X (including joint terms and couplings)."""
    m = load_model(model)
    rng = np.random.default_rng(seed)
    X = rng.normal(size=m.tree.p)
    q, qd, qdd = random_states(m.tree, 7, seed)
    W = m.regressor(q, qd, qdd)
    tau = m.inverse_dynamics(q, qd, qdd, X=X)
    assert np.allclose(W @ X, tau, rtol=1e-10, atol=1e-10 * np.abs(tau).max())


def test_restricted_regressor_is_the_block_of_the_full_one():
    m = load_model("floating_tree")
    q, qd, qdd = random_states(m.tree, 9, 4)
    rows, cols = [1, 3, 6, 8], ["M6", "XX6", "K8", "FV7", "MZ10", "IA9"]
    full = m.regressor(q, qd, qdd)
    part = m.regressor(q, qd, qdd, rows=rows, cols=cols)
    idx = [m.tree.column(c) for c in cols]
    # equal up to round-off: the moments are taken about a reference point that depends on the links used
    assert np.allclose(part, full[:, np.array(rows) - 1][:, :, idx], rtol=1e-12, atol=1e-12)


def test_wrenches_enter_as_minus_J_transpose_F():
    """An external wrench changes tau by -J^T F, with J the Jacobian of the application point."""
    m = load_model("floating_tree")
    q, qd, qdd = random_states(m.tree, 5, 6)
    rng = np.random.default_rng(1)
    F = rng.normal(size=(5, 6))
    point = np.array([0.1, 0.2, -0.05])
    for frame in (None, 0, 6):
        w = Wrench(link=8, values=F, point=point, frame=frame)
        e = 8 if frame is None else frame
        T = m.transforms(q)
        Re = T[:, e, :3, :3]
        f0 = np.einsum("nij,nj->ni", Re, F[:, :3])
        m_point = np.einsum("nij,nj->ni", Re, F[:, 3:])  # moment about the point, frame-0 axes
        J = m.jacobian(q, 8, point)
        expected = -(np.einsum("nji,nj->ni", J[:, :3], f0) + np.einsum("nji,nj->ni", J[:, 3:], m_point))
        diff = m.inverse_dynamics(q, qd, qdd, [w]) - m.inverse_dynamics(q, qd, qdd)
        assert np.allclose(diff, expected, atol=1e-10)
        W, Q = m.regressor(q, qd, qdd, [w])
        assert np.allclose(W @ m.parameters - Q, m.inverse_dynamics(q, qd, qdd, [w]), atol=1e-10)


def energy(m: Model, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """Kinetic + gravity + spring energy from link velocities (not from the dynamics), (N,).

    Per link, in its own frame: T = m v.v / 2 + v.(w x MS) + w.J w / 2 (about O_k);
    potential -g.(m P_k + R_k MS) with positions from the geometric model.
    """
    tree = m.tree
    qs, _ = joint_array(q, tree, "q")
    qds, _ = joint_array(qd, tree, "qd")
    N = qs.shape[1]
    mo = local_motion(tree, qs, qds, np.zeros_like(qs), velocities=True)
    st = forward_kinematics(tree, qs)
    g = np.array(tree.gravity)
    E = np.zeros(N)
    for j, p in enumerate(tree.inertial_block()):
        if j == 0 or not p.any():
            continue
        J = np.array([[p[0], p[1], p[2]], [p[1], p[3], p[4]], [p[2], p[4], p[5]]])
        w, v = dense(mo.w[j], N), dense(mo.v[j], N)
        E += 0.5 * p[9] * dot(v, v) + dot(v, cross(w, p[6:9, None])) + 0.5 * dot(w, J @ w)
        E -= dot(g[:, None], p[9] * st.P[j] + to_world(st.Rc[j], p[6:9]))
    X = tree.parameters
    for j, terms in tree.joint_terms.items():
        if "K" in terms:
            E += 0.5 * X[tree.index[f"K{j}"]] * qs[j - 1] ** 2
        if "IA" in terms:
            E += 0.5 * X[tree.index[f"IA{j}"]] * qds[j - 1] ** 2
    for c in tree.couplings:
        v = sum(k * qs[j - 1] for j, k in c.coeffs.items())
        E += 0.5 * X[tree.index[c.name]] * v**2
    return E


def test_energy_balance_along_a_trajectory():
    """With no friction, qd^T tau = d(kinetic + potential)/dt (springs and an anti-roll coupling included)."""
    base = load_model("floating_tree").tree
    values = {k: v for k, v in base.values.items() if not k.startswith(("FV", "FS"))}
    values["karb"] = 40.0
    tree = Tree(base.name, base.frames, {8: ("K",), 9: ("IA",)}, (Coupling("karb", "K", {7: 1.0, 9: -1.0}),),
                {k: v for k, v in values.items() if not k.startswith(("FV", "FS"))}, gravity=base.gravity)
    m = Model(tree)
    t = np.linspace(0, 2, 2001)
    rng = np.random.default_rng(5)
    a, w, ph = rng.uniform(0.2, 1, tree.n), rng.uniform(1, 4, tree.n), rng.uniform(0, 6, tree.n)
    q = a * np.sin(np.outer(t, w) + ph)
    qd = a * w * np.cos(np.outer(t, w) + ph)
    qdd = -a * w**2 * np.sin(np.outer(t, w) + ph)
    power = np.einsum("nj,nj->n", qd, m.inverse_dynamics(q, qd, qdd))
    E = energy(m, q, qd)
    dEdt = np.gradient(E, t, edge_order=2)
    inner = slice(5, -5)
    assert np.abs(power[inner] - dEdt[inner]).max() < 1e-4 * np.abs(power).max()


def test_closed_form_pendulum_on_a_cart():
    """Cart (mass mc) sliding along x0 with a pendulum (point mass mp, length l) swinging in the x0-z0 plane.

    Frame 1: gamma = alpha = pi/2 gives z1 = x0, x1 = y0, y1 = z0. Frame 2: the same pair gives
    z2 = x1 = y0, x2 = y1 = z0; with theta = pi + q2 the mass at l*x2 sits at (x - l sin q2, 0, -l cos q2):
    the textbook pendulum with phi = -q2, whose Lagrange equations are the oracle.
    """
    mc, mp, l, g = 2.0, 0.5, 0.7, 9.81
    frames = (Frame(1, 0, 1, gamma=np.pi / 2, alpha=np.pi / 2),
              Frame(2, 1, 0, gamma=np.pi / 2, alpha=np.pi / 2, theta=np.pi))
    values = {"M1": mc, "M2": mp, "MX2": mp * l, "YY2": mp * l**2, "ZZ2": mp * l**2}
    m = Model(Tree("cart-pendulum", frames, values=values, gravity=(0.0, 0.0, -g)))
    rng = np.random.default_rng(0)
    q, qd, qdd = rng.normal(size=(3, 10, 2))
    tau = m.inverse_dynamics(q, qd, qdd)
    phi, dphi, ddphi = -q[:, 1], -qd[:, 1], -qdd[:, 1]
    Fx = (mc + mp) * qdd[:, 0] + mp * l * (ddphi * np.cos(phi) - dphi**2 * np.sin(phi))
    Tphi = mp * l**2 * ddphi + mp * l * qdd[:, 0] * np.cos(phi) + mp * g * l * np.sin(phi)
    assert np.allclose(tau[:, 0], Fx, atol=1e-12)
    assert np.allclose(tau[:, 1], -Tphi, atol=1e-12)  # tau_q2 = tau_phi * dphi/dq2


def test_inertia_matrix_and_forward_dynamics():
    """M is symmetric positive definite, M qdd + h = tau, and forward dynamics inverts the IDM."""
    m = load_model("tx40")
    q, qd, qdd = random_states(m.tree, 8, 9)
    M = m.inertia_matrix(q)
    assert np.allclose(M, M.transpose(0, 2, 1), atol=1e-14)
    assert (np.linalg.eigvalsh(M) > 0).all()
    h = m.inverse_dynamics(q, qd, np.zeros_like(qdd))
    assert np.allclose(np.einsum("nij,nj->ni", M, qdd) + h, m.inverse_dynamics(q, qd, qdd), atol=1e-10)
    tau = m.inverse_dynamics(q, qd, qdd)
    assert np.allclose(m.forward_dynamics(q, qd, tau), qdd, atol=1e-9)


def test_single_sample_shapes():
    m = load_model("puma560")
    q, qd, qdd = random_states(m.tree, 1, 1)
    assert m.inverse_dynamics(q[0], qd[0], qdd[0]).shape == (6,)
    assert m.regressor(q[0], qd[0], qdd[0]).shape == (6, m.tree.p)
    assert m.inertia_matrix(q[0]).shape == (6, 6)
    assert m.transforms(q[0]).shape == (7, 4, 4)
    assert np.allclose(m.inverse_dynamics(q[0], qd[0], qdd[0]), m.inverse_dynamics(q, qd, qdd)[0])


def test_fixed_frames_carry_no_torque():
    tree = random_tree(seed=31, n=15)
    q, qd, qdd = random_states(tree, 4, 2)
    tau = Model(tree).inverse_dynamics(q, qd, qdd)
    assert (tau[:, tree.sigma[1:] == 2] == 0).all()
