"""Jacobians and J-dot qd against finite differences of the geometric model."""

import numpy as np
import pytest
from oracles import random_states, random_tree

from dynid import Model, load_model


def skew_to_vec(S: np.ndarray) -> np.ndarray:
    return np.array([S[2, 1] - S[1, 2], S[0, 2] - S[2, 0], S[1, 0] - S[0, 1]]) / 2


def fd_jacobian(m: Model, q: np.ndarray, frame: int, point: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """6 x n Jacobian by central differences of the point position and of the frame rotation."""
    J = np.zeros((6, m.n))
    for j in range(m.n):
        dq = np.zeros(m.n)
        dq[j] = h
        Tp, Tm = m.transforms(q + dq)[frame], m.transforms(q - dq)[frame]
        J[:3, j] = ((Tp[:3, :3] @ point + Tp[:3, 3]) - (Tm[:3, :3] @ point + Tm[:3, 3])) / (2 * h)
        R = m.transforms(q)[frame][:3, :3]
        J[3:, j] = skew_to_vec((Tp[:3, :3] - Tm[:3, :3]) / (2 * h) @ R.T)
    return J


@pytest.mark.parametrize("tree_kw", [dict(seed=21, n=12), dict(seed=22, n=16, floating=True)])
def test_jacobian_finite_differences(tree_kw):
    tree = random_tree(**tree_kw)
    m = Model(tree)
    q, _, _ = random_states(tree, 3, seed=1)
    point = np.array([0.1, -0.2, 0.3])
    for frame in (tree.n, tree.n // 2):
        J = m.jacobian(q, frame, point)
        for s in range(3):
            assert np.allclose(J[s], fd_jacobian(m, q[s], frame, point), atol=1e-7)
        # expressed in another frame: rotate by that frame's orientation
        Je = m.jacobian(q, frame, point, expressed_in=3)
        R3 = m.transforms(q)[:, 3, :3, :3]
        assert np.allclose(Je[:, :3], np.einsum("nji,njk->nik", R3, J[:, :3]), atol=1e-12)


def test_jdot_qdot_finite_differences():
    tree = random_tree(seed=23, n=14, floating=True)
    m = Model(tree)
    q, qd, _ = random_states(tree, 4, seed=2)
    point = [0.2, 0.1, -0.1]
    h = 1e-5
    for frame in (tree.n, 8):
        a = m.jdot_qdot(q, qd, frame, point)
        for s in range(4):
            Jp = m.jacobian(q[s] + h * qd[s], frame, point)
            Jm = m.jacobian(q[s] - h * qd[s], frame, point)
            assert np.allclose(a[s], (Jp - Jm) @ qd[s] / (2 * h), atol=1e-6 * max(1, np.abs(a[s]).max()))


def test_jacobian_times_qd_is_the_velocity():
    """J qd equals the velocity obtained by differentiating the position along a path."""
    m = load_model("floating_tree")
    rng = np.random.default_rng(3)
    q, qd = rng.normal(size=m.n), rng.normal(size=m.n)
    h = 1e-6
    p = [0.05, 0.0, 0.02]
    T = m.transforms(np.stack([q + h * qd, q - h * qd]))[:, 10]
    v = ((T[0, :3, :3] @ p + T[0, :3, 3]) - (T[1, :3, :3] @ p + T[1, :3, 3])) / (2 * h)
    assert np.allclose(m.jacobian(q, 10, p)[:3] @ qd, v, atol=1e-7)


@pytest.mark.parametrize("expressed_in", [0, 5])
def test_point_velocity_is_the_derivative_of_the_position(expressed_in):
    """point_velocity (J qd without J) against central differences of the point's position along a path,
    on a floating random tree, batched, and one sample alone."""
    from dynid.kinematics.forward import point_velocity

    tree = random_tree(seed=24, n=14, floating=True)
    m = Model(tree)
    q, qd, _ = random_states(tree, 5, seed=4)
    p, frame, h = np.array([0.2, -0.1, 0.3]), tree.n, 1e-6
    Tp, Tm = m.transforms(q + h * qd), m.transforms(q - h * qd)
    v0 = ((Tp[:, frame, :3, :3] @ p + Tp[:, frame, :3, 3]) - (Tm[:, frame, :3, :3] @ p + Tm[:, frame, :3, 3])) / (2 * h)
    Rdot = (Tp[:, frame, :3, :3] - Tm[:, frame, :3, :3]) / (2 * h)
    W = Rdot @ m.transforms(q)[:, frame, :3, :3].transpose(0, 2, 1)  # skew(omega)
    w0 = np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], axis=1)
    Re = m.transforms(q)[:, expressed_in, :3, :3]
    v, w = point_velocity(tree, q, qd, frame, p, expressed_in)
    assert np.allclose(v, np.einsum("nji,nj->ni", Re, v0), atol=1e-7)
    assert np.allclose(w, np.einsum("nji,nj->ni", Re, w0), atol=1e-7)
    v1, w1 = point_velocity(tree, q[2], qd[2], frame, p, expressed_in)
    assert v1.shape == (3,) and np.allclose(v1, v[2], atol=1e-14) and np.allclose(w1, w[2], atol=1e-14)


@pytest.mark.parametrize("rows", [slice(2, 3), slice(0, 1), slice(1, 3)])
def test_forward_kinematics_rows_are_the_whole_poses_rows(rows):
    """Oracle: the whole forward kinematics. The rows of frame 0 kept alone (a tire's height and z axis) are the
    same numbers, bit for bit: each row of a rotation propagates apart down the chain."""
    from dynid.kinematics.forward import forward_kinematics, joint_array

    tree = random_tree(seed=24, n=14, floating=True)
    q, _, _ = random_states(tree, 50, seed=3)
    qs = joint_array(q, tree, "q")[0]
    frames = [tree.n, 9]
    whole = forward_kinematics(tree, qs, frames=frames)
    part = forward_kinematics(tree, qs, frames=frames, rows=rows)
    for j in range(tree.n + 1):
        if whole.P[j] is None:
            assert part.P[j] is None
            continue
        assert np.array_equal(part.P[j], whole.P[j][rows])
        for c in range(3):
            assert np.array_equal(np.broadcast_to(part.Rc[j][c], part.P[j].shape), whole.Rc[j][c][rows])


def test_forward_kinematics_with_some_joints_cos_and_sin_given_is_the_whole_pass():
    """Oracle: the forward kinematics of the moved joints computed whole. A pass with a few joints moved and the
    others' cos and sin kept from a first pass (`joint_trig`, what a moved attitude pass of the car reuses) gives the
    same numbers, bit for bit; the kept pairs are used, not computed again (a pair made up shows in the poses)."""
    from dynid.kinematics.forward import forward_kinematics, joint_array, joint_trig

    tree = random_tree(seed=25, n=14, floating=True)
    q, _, _ = random_states(tree, 50, seed=4)
    qs = joint_array(q, tree, "q")[0]
    moved = [4, 5, 6]
    kept = [j for j in range(1, tree.n + 1) if j not in moved]
    trig = joint_trig(tree, qs, kept)
    assert trig and all(tree.sigma[j] == 0 for j in trig)
    qm = qs.copy()
    qm[[j - 1 for j in moved]] += 0.01
    whole = forward_kinematics(tree, qm, rows=slice(2, 3))
    part = forward_kinematics(tree, qm, rows=slice(2, 3), trig=trig)
    for j in range(1, tree.n + 1):
        assert np.array_equal(part.P[j], whole.P[j])
        assert all(np.array_equal(part.Rc[j][c], whole.Rc[j][c]) for c in range(3))
    j = max(trig)  # the last revolute frame kept: its pair taken as given
    c, s = trig[j]
    other = forward_kinematics(tree, qm, rows=slice(2, 3), trig={**trig, j: (s, -c)})
    assert not np.array_equal(other.Rc[j][0], whole.Rc[j][0])
