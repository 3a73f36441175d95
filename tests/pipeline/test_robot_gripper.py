"""A robot whose URDF has a gripper with mimic fingers, identified from logs that leave the gripper out or log
it (issue 26, item 3).

Oracle: the Panda of example-robot-data's panda.urdf, unedited. The log's torques are the inverse dynamics of the
arm with the gripper held still (the model imported with --joints naming the arm, whose inverse dynamics equal
Pinocchio's reduced model: tests/model/test_urdf.py), plus white noise of known σ. Identified through `dynid
identify` with the model file imported as it is (fingers a mimic pair): the gripper, absent from the log, is held
still by default, and the estimate must agree with the true base parameters within 4.5 σ. A log that gives the
finger too identifies it as a mimic pair.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_urdf import robot_file

from dynid import Model
from dynid.model import save_tree
from dynid.model.urdf import import_urdf
from dynid.pipeline.config import ConfigError, load_config
from dynid.pipeline.run import identify

FS = 500.0
DURATION = 24.0
ARM = [f"panda_joint{i}" for i in range(1, 8)]
SIGMA = 0.05  # N.m (N on the finger)

CONFIG = """
[model]
file = "{model}"
{joints}

[[tests]]
name = "excitation"
role = "identify"
files = {{ q = "{log}", tau = "{log}" }}

[channels]
q = {{ channels = {q} }}
tau = {{ channels = {tau} }}

[conditioning]
cutoff = 10.0
order = 4
decimate = [5]
"""


def trajectory(t: np.ndarray, k: int, seed: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q, qd, qdd (N, k): 5 harmonics at 0.1 Hz, exact derivatives, amplitude about 1 rad."""
    rng = np.random.default_rng(seed)
    w = 2 * np.pi * 0.1 * np.arange(1, 6)
    a, b = rng.normal(0, 0.6, (2, k, 5)) / np.arange(1, 6)
    s, c = np.sin(np.multiply.outer(t, w)), np.cos(np.multiply.outer(t, w))
    return s @ a.T + c @ b.T, (c * w) @ a.T - (s * w) @ b.T, -(s * w**2) @ a.T - (c * w**2) @ b.T


def write_log(path: Path, t: np.ndarray, q: np.ndarray, tau: np.ndarray, names: list[str]) -> None:
    head = ",".join(["time [s]", *(f"q_{n} [rad]" for n in names), *(f"tau_{n} [N.m]" for n in names)])
    np.savetxt(path, np.column_stack([t, q, tau]), delimiter=",", header=head, comments="", fmt="%.15g")


def config(d: Path, name: str, model: Path, log: Path, names: list[str], joints: list[str] | None = None) -> Path:
    path = d / f"{name}.toml"
    path.write_text(CONFIG.format(model=model, log=log, q=[f"q_{n}" for n in names], tau=[f"tau_{n}" for n in names],
                                  joints="" if joints is None else f"joints = {joints}").replace("'", '"'))
    return path


@pytest.fixture(scope="module")
def panda(tmp_path_factory):
    d = tmp_path_factory.mktemp("panda")
    path = robot_file("panda")
    save_tree(import_urdf(path).tree, d / "panda.toml")  # as shipped: the fingers a mimic pair
    t = np.arange(int(DURATION * FS)) / FS
    rng = np.random.default_rng(7)
    arm = import_urdf(path, joints=ARM).tree  # the gripper held still at 0 (= Pinocchio's reduced model)
    q, qd, qdd = trajectory(t, 7)
    tau = Model(arm).inverse_dynamics(q, qd, qdd) + SIGMA * rng.normal(size=q.shape)
    write_log(d / "arm.csv", t, q, tau, ARM)
    return d, arm


def test_gripper_left_out_of_the_log_is_held_still(panda):
    d, _ = panda
    said: list[str] = []
    run = identify(load_config(config(d, "auto", d / "panda.toml", d / "arm.csv", ARM)), progress=said.append)
    assert any("panda_finger_joint1, panda_finger_joint2" in s and "held still" in s for s in said), said
    assert run.model.n == 9 and run.model.tree.equations == tuple(range(1, 8))
    assert {g for g in run.identify.groups} == {f"joint{j}" for j in range(1, 8)}
    # same model, same data: the base estimate equals the one on the model imported with the arm alone
    direct = import_urdf(robot_file("panda"), joints=ARM).tree
    save_tree(direct, d / "arm_model.toml")
    run2 = identify(load_config(config(d, "arm", d / "arm_model.toml", d / "arm.csv", ARM)))
    common = [n for n in run.result.names if n in run2.result.names]
    assert len(common) >= 0.9 * len(run.result.names)
    a = np.array([run.result.value(n) for n in common])
    b = np.array([run2.result.value(n) for n in common])
    assert np.abs(a - b).max() <= 1e-6 * np.abs(b).max()
    # and against the truth the log was simulated from
    truth = np.array([direct.values.get(n, 0.0) for n in direct.parameter_names])
    XB = run2.base.values(truth)
    z = (run2.result.values - XB) / run2.result.std
    assert np.abs(z).max() < 4.5, dict(zip(run2.result.names, np.round(z, 1), strict=True))


def test_model_joints_selection(panda):
    d, _ = panda
    said: list[str] = []
    run = identify(load_config(config(d, "select", d / "panda.toml", d / "arm.csv", ARM, joints=ARM)),
                   progress=said.append)
    assert any("[model] joints" in s for s in said) and run.model.tree.equations == tuple(range(1, 8))
    bad = config(d, "bad", d / "panda.toml", d / "arm.csv", ARM, joints=[*ARM[:6], "panda_finger_joint2"])
    with pytest.raises(ConfigError, match=r"panda_finger_joint2.*mimics.*panda_finger_joint1") as info:
        identify(load_config(bad))
    assert "\n" not in str(info.value)


def test_gripper_in_the_log_is_a_mimic_pair(panda, tmp_path):
    """The finger logged too (8 joints): the fingers move as a mimic pair and the finger's equation is
    tau_1 + tau_2; the estimate agrees with the truth (the tree with the mimic) within 4.5 σ."""
    d, _ = panda
    tree = import_urdf(robot_file("panda")).tree
    t = np.arange(int(DURATION * FS)) / FS
    q7, qd7, qdd7 = trajectory(t, 7)
    qf = 0.02 + 0.015 * np.sin(2 * np.pi * 0.3 * t)
    w = 2 * np.pi * 0.3
    qdf, qddf = 0.015 * w * np.cos(w * t), -0.015 * w**2 * np.sin(w * t)
    finger = tree.frame_of("panda_finger_joint1")
    q, qd, qdd = (np.zeros((t.size, 9)) for _ in range(3))
    q[:, :7], qd[:, :7], qdd[:, :7] = q7, qd7, qdd7
    q[:, finger - 1], qd[:, finger - 1], qdd[:, finger - 1] = qf, qdf, qddf
    tau = Model(tree).inverse_dynamics(q, qd, qdd)
    cols = [*range(7), finger - 1]
    noisy = tau[:, cols] + SIGMA * np.random.default_rng(8).normal(size=(t.size, 8))
    names = [*ARM, "panda_finger_joint1"]
    head = ",".join(["time [s]", *(f"q_{n} [{'m' if 'finger' in n else 'rad'}]" for n in names),
                     *(f"tau_{n} [{'N' if 'finger' in n else 'N.m'}]" for n in names)])
    np.savetxt(tmp_path / "all.csv", np.column_stack([t, q[:, cols], noisy]), delimiter=",", header=head,
               comments="", fmt="%.15g")
    run = identify(load_config(config(tmp_path, "all", d / "panda.toml", tmp_path / "all.csv", names)))
    assert run.model.tree.mimic and run.model.tree.equations == (*range(1, 8), finger)
    XB = run.base.values(tree.parameters)
    z = (run.result.values - XB) / run.result.std
    assert np.abs(z).max() < 4.5, dict(zip(run.result.names, np.round(z, 1), strict=True))
