"""URDF import and export against an independent oracle: Pinocchio reading the SAME URDF text.

Tolerance 1e-10 (relative to max(1, |tau|)), from an error analysis: the import computes each
joint's constant transform with O(10) flops from the file's numbers (a few ulps, ~1e-15),
the two-row split keeps the MDH conversion's magnification <= 10 (urdf._MAX_MAGNIFICATION),
and the Newton-Euler recursion over depth <= 12 adds O(depth) ulps of the largest term; so
~1e-13 is expected (measured max 2e-12 over example-robot-data), and 1e-10 leaves margin
without hiding a wrong frame, axis or inertia (those give errors of order 1).
"""

from __future__ import annotations

import json
import re
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest

from dynid import Model
from dynid.cli.main import main
from dynid.cli.model_io_cmds import standard_from_base
from dynid.model import INERTIAL, Mimic, ModelError, load_tree, save_tree, tree_from_dict, tree_to_toml
from dynid.model.urdf import UrdfError, export_urdf, import_urdf, mdh_rows, row_transform, urdf_with_parameters

pin = pytest.importorskip("pinocchio")

TOL = 1e-10


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / max(1.0, np.abs(b).max()))


def pin_errors(text: str, samples: int = 8, seed: int = 0) -> tuple[float, float]:
    """Max relative errors of dynid's inverse dynamics and of regressor @ X against pinocchio.rnea on the
    same URDF text, joints matched by name (continuous joints are (cos, sin) in Pinocchio's q)."""
    tree = import_urdf(text).tree
    pm = pin.buildModelFromXML(text)
    data = pm.createData()
    frame = {name: j for j, name in tree.joint_names.items()}
    assert sorted(pm.names[1:]) == sorted(frame), "the same moving joints"
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, (samples, tree.n))
    qd, qdd = rng.normal(size=(samples, tree.n)), rng.normal(size=(samples, tree.n))
    model = Model(tree)
    tau = model.inverse_dynamics(q, qd, qdd)
    WX = model.regressor(q, qd, qdd) @ tree.parameters
    cols = [frame[pm.names[i]] - 1 for i in range(1, pm.njoints)]
    e_tau = e_w = 0.0
    for s in range(samples):
        qp = []
        for i, c in zip(range(1, pm.njoints), cols, strict=True):
            qp += [np.cos(q[s, c]), np.sin(q[s, c])] if pm.joints[i].nq == 2 else [q[s, c]]
        ref = pin.rnea(pm, data, np.array(qp), qd[s, cols], qdd[s, cols])
        e_tau, e_w = max(e_tau, rel(tau[s, cols], ref)), max(e_w, rel(WX[s, cols], ref))
    return e_tau, e_w


# ------------------------------------------------------------------------------------------ example-robot-data
def robots_dir() -> Path | None:
    try:
        d = metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data/robots")
    except metadata.PackageNotFoundError:
        return None
    return Path(str(d)) if Path(str(d)).is_dir() else None


ROBOTS = {
    "panda": "panda_description/urdf/panda.urdf",  # 7-axis arm + prismatic fingers (robot_text: mimic removed)
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "xarm7": "xarm_description/urdf/xarm7.urdf",  # 7-axis arm
    "kinova": "kinova_description/robots/kinova.urdf",  # continuous joints
    "tiago": "tiago_description/robots/tiago.urdf",  # mobile base: continuous wheels, prismatic torso, 77 joints
    "talos": "talos_data/robots/talos_full_v2.urdf",  # needs two-row (fixed helper) frames
}


def robot_text(name: str) -> str:
    d = robots_dir()
    if d is None:
        pytest.skip("example-robot-data is not installed (pip install -e '.[test]' in the clone)")
    return re.sub(r"<mimic[^>]*/>", "", (d / ROBOTS[name]).read_text(encoding="utf-8"))


@pytest.mark.parametrize("name", list(ROBOTS))
def test_robot_matches_pinocchio(name):
    e_tau, e_w = pin_errors(robot_text(name))
    assert e_tau <= TOL and e_w <= TOL, (e_tau, e_w)


# ------------------------------------------------------------------------------------------ mimic and frozen joints
def robot_file(name: str) -> Path:
    d = robots_dir()
    if d is None:
        pytest.skip("example-robot-data is not installed (pip install 'dynid[test]')")
    return d / ROBOTS[name]


def states(n: int, samples: int = 8, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.uniform(-2, 2, (samples, n)), rng.normal(size=(samples, n)), rng.normal(size=(samples, n))


def mimic_errors(text: str, tree) -> dict[str, float]:
    """Max relative errors of dynid's inverse dynamics, regressor @ X and inertia matrix on a tree with mimic joints
    against two oracles on the same URDF text: Pinocchio's own mimic joints (buildModelFromXML(mimic=True): rnea,
    crba), and the generalized-force projection tau_master = tau_1 + ratio tau_2 of Pinocchio's rnea on the model
    with every joint independent, at q_follower = ratio q_master + offset (virtual work for a linear constraint)."""
    pm, pfull = pin.buildModelFromXML(text, mimic=True), pin.buildModelFromXML(text)
    data, dfull = pm.createData(), pfull.createData()
    frame = {name: j for j, name in tree.joint_names.items()}
    actuated = [frame[pm.names[i]] - 1 for i in range(1, pm.njoints) if pm.joints[i].nv > 0]
    every = [frame[pfull.names[i]] - 1 for i in range(1, pfull.njoints)]
    assert sorted(actuated) == [j - 1 for j in tree.equations]
    q, qd, qdd = states(tree.n)
    model = Model(tree)
    tau, WX = model.inverse_dynamics(q, qd, qdd), model.regressor(q, qd, qdd) @ tree.parameters
    M = model.inertia_matrix(q)
    err = dict.fromkeys(("pin mimic", "projection", "regressor", "crba", "follower"), 0.0)
    for s in range(q.shape[0]):
        qs, qds, qdds = q[s].copy(), qd[s].copy(), qdd[s].copy()
        ref = pin.rnea(pm, data, qs[actuated], qds[actuated], qdds[actuated])
        err["pin mimic"] = max(err["pin mimic"], rel(tau[s, actuated], ref))
        err["regressor"] = max(err["regressor"], rel(WX[s, actuated], ref))
        Mp = pin.crba(pm, data, qs[actuated])
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        err["crba"] = max(err["crba"], rel(M[s][np.ix_(actuated, actuated)], Mp))
        for j, m in tree.mimic.items():  # the follower's motion is its master's
            qs[j - 1] = m.ratio * qs[m.master - 1] + m.offset
            qds[j - 1], qdds[j - 1] = m.ratio * qds[m.master - 1], m.ratio * qdds[m.master - 1]
        full = np.zeros(tree.n)
        full[every] = pin.rnea(pfull, dfull, qs[every], qds[every], qdds[every])
        for j, m in tree.mimic.items():
            full[m.master - 1] += m.ratio * full[j - 1]
            err["follower"] = max(err["follower"], abs(tau[s, j - 1]))
        err["projection"] = max(err["projection"], rel(tau[s, actuated], full[actuated]))
    return err


def test_panda_imports_unedited_with_its_mimic_finger():
    """example-robot-data's panda.urdf as shipped: panda_finger_joint2 mimics panda_finger_joint1. Inverse dynamics,
    regressor and inertia matrix equal Pinocchio's mimic model and the projection of its independent-joint model."""
    path = robot_file("panda")
    tree = import_urdf(path).tree
    fingers = tree.frame_of("panda_finger_joint1"), tree.frame_of("panda_finger_joint2")
    assert tree.mimic == {fingers[1]: Mimic(fingers[0], 1.0, 0.0)} and len(tree.equations) == 8
    err = mimic_errors(path.read_text(encoding="utf-8"), tree)
    assert max(err.values()) <= TOL, err


def test_mimic_with_ratio_and_offset_matches_pinocchio():
    """A revolute joint following another at ratio -1.7 and offset 0.3 rad, on a branch and behind a fixed joint."""
    text = robot(link("base"), link("a"), link("b", 1.5), link("c", 0.8), link("flange", 0.3), link("d", 0.6),
                 joint("j1", "revolute", "base", "a"), joint("j2", "revolute", "a", "b", axis="1 0 0"),
                 joint("f", "fixed", "b", "flange", axis=None),
                 joint("j3", "revolute", "flange", "c", axis="0 1 0",
                       extra='<mimic joint="j2" multiplier="-1.7" offset="0.3"/>'),
                 joint("j4", "prismatic", "a", "d", axis="0 0.6 0.8", extra='<mimic joint="j1" multiplier="0.05"/>'))
    tree = import_urdf(text).tree
    f = tree.frame_of
    assert tree.mimic == {f("j3"): Mimic(f("j2"), -1.7, 0.3), f("j4"): Mimic(f("j1"), 0.05, 0.0)}
    err = mimic_errors(text, tree)
    assert max(err.values()) <= TOL, err
    base = Model(tree).base_parameters()  # the followers' bodies regroup into what their masters' equations see
    assert base.rank > 0


@pytest.mark.parametrize("how", ["joints", "freeze open", "freeze closed"])
def test_panda_fingers_frozen_match_pinocchio_reduced_model(how, tmp_path):
    """The gripper held still (--joints naming the arm's 7, or --freeze): the arm's inverse dynamics equal
    Pinocchio's model reduced with the fingers locked (buildReducedModel) at the same opening."""
    path = robot_file("panda")
    arm = [f"panda_joint{i}" for i in range(1, 8)]
    opening = {"joints": 0.0, "freeze open": 0.035, "freeze closed": 0.0}[how]
    kw = {"joints": arm} if how == "joints" else {"freeze": {"panda_finger_joint1": opening}}
    tree = import_urdf(path, **kw).tree
    assert tree.n == 7 and not tree.mimic
    assert tree.frozen == {"panda_finger_joint1": opening, "panda_finger_joint2": opening}
    full = pin.buildModelFromXML(path.read_text(encoding="utf-8"))
    locked = [full.getJointId(f"panda_finger_joint{k}") for k in (1, 2)]
    q_ref = pin.neutral(full)
    for jid in locked:
        q_ref[full.idx_qs[jid]] = opening
    pm = pin.buildReducedModel(full, locked, q_ref)
    data = pm.createData()
    cols = [tree.frame_of(pm.names[i]) - 1 for i in range(1, pm.njoints)]
    q, qd, qdd = states(7)
    tau = Model(tree).inverse_dynamics(q, qd, qdd)
    e = max(rel(tau[s, cols], pin.rnea(pm, data, q[s, cols], qd[s, cols], qdd[s, cols])) for s in range(8))
    assert e <= TOL
    # the model file keeps what was frozen, so that an export finds the same frames in the same URDF
    save_tree(tree, tmp_path / "arm.toml")
    back = load_tree(tmp_path / "arm.toml")
    assert back.frozen == tree.frozen
    out, _ = urdf_with_parameters(back, path)
    assert rel(import_urdf(out, freeze=tree.frozen).tree.parameters, tree.parameters) < 1e-12


def test_ur5_imports_unedited():
    path = robot_file("ur5")
    e_tau, e_w = pin_errors(path.read_text(encoding="utf-8"))
    assert e_tau <= TOL and e_w <= TOL
    assert not import_urdf(path).tree.mimic


def test_mimic_model_file_round_trip(tmp_path):
    tree = import_urdf(robot_file("panda")).tree
    save_tree(tree, tmp_path / "panda.toml")
    back = load_tree(tmp_path / "panda.toml")
    assert back.mimic == tree.mimic and back.frames == tree.frames
    assert '[mimic]\n9 = { follows = 8, ratio = 1.0, offset = 0.0 }' in (tmp_path / "panda.toml").read_text()


MIMIC_BAD = {
    "no master": ('<mimic joint="j9"/>', None, None, r'<joint name="j2">: <mimic joint="j9">: no such joint'),
    "fixed master": ('<mimic joint="f"/>', None, None, r'<mimic joint="f">: that joint is fixed'),
    "freeze follower alone": ('<mimic joint="j1"/>', {"j2": 0.1}, None, r"--freeze 'j2': it mimics 'j1', which moves"),
    "freeze unknown": ("", {"j22": 0.0}, None, r"--freeze 'j22': no such joint; did you mean 'j2'"),
    "freeze fixed": ("", {"f": 0.0}, None, r"--freeze 'f': the joint is fixed"),
    "select follower": ('<mimic joint="j1"/>', None, ["j2"], r"--joints 'j2': it mimics 'j1'; select that joint"),
    "select unknown": ("", None, ["j1", "jx"], r"--joints 'jx': no such joint"),
}


@pytest.mark.parametrize("name", list(MIMIC_BAD))
def test_mimic_and_freeze_errors_are_one_line(name):
    extra, freeze, joints, pattern = MIMIC_BAD[name]
    text = robot(link("base"), link("a"), link("b"), link("c"), joint("j1", "revolute", "base", "a"),
                 joint("j2", "revolute", "a", "b", extra=extra), joint("f", "fixed", "a", "c", axis=None))
    with pytest.raises(UrdfError, match=pattern) as info:
        import_urdf(text, freeze=freeze, joints=joints)
    assert "\n" not in str(info.value)


def test_cli_import_freeze_and_joints(tmp_path, capsys):
    path = robot_file("panda")
    out = tmp_path / "arm.toml"
    assert main(["model", "import", str(path), "--out", str(out), "--freeze", "panda_finger_joint1=0.02"]) == 0
    said = capsys.readouterr().out
    assert "7 moving joints" in said and "frozen: panda_finger_joint1 = 0.02, panda_finger_joint2 = 0.02" in said
    bad = ["--freeze", "panda_finger_joint1=x"]
    assert main(["model", "import", str(path), "--out", str(tmp_path / "b.toml"), *bad]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--freeze 'panda_finger_joint1=x'" in err
    assert main(["model", "import", str(path), "--out", str(tmp_path / "c.toml"), "--joints",
                 ",".join(f"panda_joint{i}" for i in range(1, 8))]) == 0
    assert load_tree(tmp_path / "c.toml").n == 7


def test_talos_uses_helper_frames_and_names_moving_ones():
    tree = import_urdf(robot_text("talos")).tree
    assert tree.n > len(tree.joint_names)  # fixed helper frames were needed
    for j in tree.joint_names:
        assert tree.frames[j - 1].sigma != 2
    assert all(tree.frames[j - 1].sigma == 2 for j in range(1, tree.n + 1) if j not in tree.joint_names)


# ------------------------------------------------------------------------------------------ hand-written URDFs
def link(name: str, m: float = 1.0, xyz: str = "0.1 -0.05 0.2", rpy: str = "0.3 -0.2 0.7",
         inertia: str = 'ixx="0.02" ixy="0.001" ixz="-0.002" iyy="0.03" iyz="0.003" izz="0.025"') -> str:
    if m is None:
        return f'<link name="{name}"/>'
    return (f'<link name="{name}"><inertial><origin xyz="{xyz}" rpy="{rpy}"/><mass value="{m}"/>'
            f"<inertia {inertia}/></inertial></link>")


def joint(name: str, kind: str, parent: str, child: str, xyz: str = "0.1 0.2 0.3", rpy: str = "0.1 0.2 0.3",
          axis: str | None = "0 0 1", extra: str = "") -> str:
    ax = f'<axis xyz="{axis}"/>' if axis else ""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}" rpy="{rpy}"/>{ax}<limit effort="1" velocity="1" lower="-1" upper="1"/>'
            f"{extra}</joint>")


def robot(*parts: str) -> str:
    return '<?xml version="1.0"?>\n<robot name="test">' + "".join(parts) + "</robot>"


SMALL = {
    "prismatic": robot(link("base"), link("a"), link("b", 2.0),
                       joint("j1", "revolute", "base", "a"), joint("j2", "prismatic", "a", "b", axis="0 0 1")),
    "arbitrary_axis": robot(link("base"), link("a"), link("b", 0.7), link("c", 1.3),
                            joint("j1", "revolute", "base", "a", axis="0.3 -0.5 0.81"),
                            joint("j2", "prismatic", "a", "b", axis="-1 2 0.5"),
                            joint("j3", "revolute", "b", "c", axis="0 -1 0")),
    "fixed_inertial_child": robot(link("base"), link("a"), link("flange", 0.4, "0.02 0 0.05"), link("tool", 0.9),
                                  link("b", 1.1),
                                  joint("j1", "revolute", "base", "a", axis="1 0 0"),
                                  joint("f1", "fixed", "a", "flange", axis=None),
                                  joint("f2", "fixed", "flange", "tool", xyz="0 0 0.1", rpy="0 1.2 0", axis=None),
                                  joint("j2", "revolute", "tool", "b", axis="0 1 0")),
    "continuous": robot(link("base"), link("wheel", 3.0), link("arm", 0.5),
                        joint("w", "continuous", "base", "wheel", axis="0 1 0"),
                        joint("a", "revolute", "wheel", "arm", axis=None)),  # no <axis>: URDF's default x
    "nearly_parallel_offset": robot(link("base"), link("a"), link("b"),
                                    joint("j1", "revolute", "base", "a"),
                                    joint("j2", "revolute", "a", "b", xyz="0.3 0.4 0.1", rpy="1e-7 0 0.2")),
    "branched": robot(link("base"), link("a"), link("b"), link("c"), link("d", 0.2),
                      joint("j1", "revolute", "base", "a"), joint("j2", "revolute", "a", "b", axis="1 0 0"),
                      joint("j3", "prismatic", "a", "c", axis="0 1 1"), joint("j4", "revolute", "c", "d")),
}


@pytest.mark.parametrize("name", list(SMALL))
def test_small_urdf_matches_pinocchio(name):
    e_tau, e_w = pin_errors(SMALL[name], samples=10)
    assert e_tau <= TOL and e_w <= TOL, (e_tau, e_w)


def test_small_urdf_structure():
    tree = import_urdf(SMALL["fixed_inertial_child"]).tree
    assert tree.n == 2 and tree.joint_names == {1: "j1", 2: "j2"}  # the fixed links are merged into body 1
    assert tree.values["M1"] == pytest.approx(1.0 + 0.4 + 0.9)
    assert tree.frame_of("j2") == 2
    with pytest.raises(ModelError, match="did you mean 'j2'"):
        tree.frame_of("j22")
    assert import_urdf(SMALL["nearly_parallel_offset"]).tree.n == 3  # a fixed frame, then the rotation
    assert [f.sigma for f in import_urdf(SMALL["prismatic"]).tree.frames] == [0, 1]


def test_mdh_rows_reproduce_random_transforms():
    """One KK row (or two) equals any rigid transform, including z parallel or antiparallel."""
    from dynid.model import Frame
    from dynid.model.urdf import _rpy, transform

    rng = np.random.default_rng(1)
    cases = [transform(_rpy(rng.uniform(-3, 3, 3)), rng.normal(size=3)) for _ in range(200)]
    cases += [transform(_rpy([a, 0, rng.uniform(-3, 3)]), rng.normal(size=3)) for a in (0.0, np.pi, 1e-9)]
    for T in cases:
        A = np.eye(4)
        for row in mdh_rows(T):
            A = A @ row_transform(Frame(1, 0, 2, *row))
        assert np.abs(A - T).max() < 1e-13


# ------------------------------------------------------------------------------------------ errors
BAD = {
    "mimic": (robot(link("base"), link("a"), link("b"), joint("j1", "revolute", "base", "a"),
                    joint("j2", "revolute", "a", "b", extra='<mimic joint="j3"/>')),
              r'<joint name="j2">: <mimic joint="j3">: no such joint'),
    "floating": (robot(link("base"), link("a"), joint("free", "floating", "base", "a")),
                 r'<joint name="free">: type="floating"'),
    "planar": (robot(link("base"), link("a"), joint("pl", "planar", "base", "a")), r'<joint name="pl">: type="planar"'),
    "missing_parent": (robot(link("a"), joint("j1", "revolute", "nowhere", "a")),
                       r'<joint name="j1">: <parent link="nowhere">: no such link'),
    "non_numeric_origin": (robot(link("base"), link("a"), joint("j1", "revolute", "base", "a", xyz="0 x 0")),
                           r'<joint name="j1">: <origin xyz="0 x 0">'),
    "negative_mass": (robot(link("base"), link("a", -2.0), joint("j1", "revolute", "base", "a")),
                      r'<link name="a">: <inertial>: <mass value="-2.0">'),
    "closed_loop": (robot(link("base"), link("a"), link("b"), joint("j1", "revolute", "base", "a"),
                          joint("j2", "revolute", "base", "b"), joint("j3", "revolute", "a", "b")),
                    r'<joint name="j3">: link "b" is already the child of joint "j2"'),
    "zero_axis": (robot(link("base"), link("a"), joint("j1", "revolute", "base", "a", axis="0 0 0")),
                  r'<joint name="j1">: <axis xyz="0 0 0"> is zero'),
    "two_roots": (robot(link("base"), link("a"), link("lost")), r"have no parent joint"),
    "not_xml": ("<robot><link", r"not valid XML"),
}


@pytest.mark.parametrize("name", list(BAD))
def test_bad_urdf_one_line_error(name, tmp_path):
    text, pattern = BAD[name]
    with pytest.raises(UrdfError, match=pattern) as info:
        import_urdf(text)
    assert "\n" not in str(info.value)
    path = tmp_path / f"{name}.urdf"
    path.write_text(text)
    with pytest.raises(UrdfError, match=re.escape(str(path))):
        import_urdf(path)


def test_cli_bad_urdf_exits_with_one_line(tmp_path, capsys):
    path = tmp_path / "bad.urdf"
    path.write_text(BAD["negative_mass"][0])
    assert main(["model", "import", str(path), "--out", str(tmp_path / "m.toml")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "bad.urdf" in err and 'link name="a"' in err
    assert not (tmp_path / "m.toml").exists()


# ------------------------------------------------------------------------------------------ [joints] in model files
def test_joints_table_round_trips_and_is_checked():
    tree = import_urdf(SMALL["branched"]).tree
    text = tree_to_toml(tree)
    assert '[joints]\n1 = "j1"' in text
    back = tree_from_dict(__import__("tomllib").loads(text))
    assert back.joint_names == tree.joint_names and back.frames == tree.frames
    data = __import__("tomllib").loads(text)
    data["joints"]["9"] = "j9"
    with pytest.raises(ModelError, match=r"\[joints\] 9: frame 9 does not exist \(the table has frames 1..4\)"):
        tree_from_dict(data, source="m.toml")
    data["joints"] = {"x": "j1"}
    with pytest.raises(ModelError, match=r"\[joints\] x: keys are frame numbers"):
        tree_from_dict(data, source="m.toml")
    data["joints"] = {"1": "j1", "2": "j1"}
    with pytest.raises(ModelError, match="already names frame 1"):
        tree_from_dict(data, source="m.toml")


# ------------------------------------------------------------------------------------------ export
def physical_inertia(rng: np.random.Generator) -> np.ndarray:
    """A realisable body (10 parameters about the frame origin): second moments of mass S > 0 give
    I_G = tr(S) I - S, which satisfies the triangle inequalities (oracles.random_inertia may not)."""
    m = rng.uniform(0.5, 5.0)
    c = rng.normal(scale=0.3, size=3)
    Q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    S = Q @ np.diag(rng.uniform(0.001, 0.05, 3) * m) @ Q.T
    J = np.trace(S) * np.eye(3) - S + m * (c @ c * np.eye(3) - np.outer(c, c))
    return np.array([J[0, 0], J[0, 1], J[0, 2], J[1, 1], J[1, 2], J[2, 2], *(m * c), m])


def random_values(tree, seed: int) -> dict[str, float]:
    rng = np.random.default_rng(seed)
    out = {}
    for j in tree.joint_names:
        out.update({f"{k}{j}": float(v) for k, v in
                    zip(("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M"), physical_inertia(rng),
                        strict=True)})
    return out


@pytest.mark.parametrize("name", ["fixed_inertial_child", "arbitrary_axis", "continuous", "nearly_parallel_offset"])
def test_export_then_import_is_identity(name, tmp_path):
    src = tmp_path / "in.urdf"
    src.write_text(SMALL[name])
    tree = import_urdf(src).tree
    values = random_values(tree, 3)
    export_urdf(tree, src, tmp_path / "out.urdf", values)
    back = import_urdf(tmp_path / "out.urdf").tree
    want = tree.with_values(values)
    assert rel(back.parameters, want.parameters) < 1e-13
    assert back.frames == tree.frames and back.joint_names == tree.joint_names
    # and Pinocchio reads the exported file as the dynamics of the new values
    e_tau, _ = pin_errors((tmp_path / "out.urdf").read_text())
    assert e_tau <= TOL


def test_unchanged_export_rewrites_the_same_inertials(tmp_path):
    text = robot_text("ur5")
    src = tmp_path / "ur5.urdf"
    src.write_text(text)
    tree = import_urdf(src).tree
    out, notes = urdf_with_parameters(tree, src)
    assert not notes

    def nums(t: str) -> np.ndarray:
        attrs = re.findall(r'(?:value|xyz|ixx|ixy|ixz|iyy|iyz|izz)="([^"]+)"', t)
        return np.array([float(v) for a in attrs for v in a.split()])

    assert nums(out).shape == nums(text).shape
    assert np.abs(nums(out) - nums(text)).max() < 1e-12
    assert "<visual>" in out and "mesh filename" in out  # everything else is kept


def test_export_refuses_unphysical_sets(tmp_path):
    src = tmp_path / "in.urdf"
    src.write_text(SMALL["arbitrary_axis"])
    tree = import_urdf(src).tree
    with pytest.raises(UrdfError, match=r"frame 2 \(joint 'j2', link 'b'\) is not physically realisable: .*mass M2"):
        export_urdf(tree, src, tmp_path / "out.urdf", {"M2": -1.0})
    with pytest.raises(UrdfError, match=r"frame 3 \(joint 'j3', link 'c'\).*triangle"):
        export_urdf(tree, src, tmp_path / "out.urdf", {"XX3": 5.0})
    assert not (tmp_path / "out.urdf").exists()


def test_export_refuses_another_urdf(tmp_path):
    a, b = tmp_path / "a.urdf", tmp_path / "b.urdf"
    a.write_text(SMALL["arbitrary_axis"])
    b.write_text(SMALL["branched"])
    with pytest.raises(UrdfError, match="export into the URDF the model was imported from"):
        export_urdf(import_urdf(a).tree, b, tmp_path / "out.urdf")


def test_cli_import_export_with_results_json(tmp_path, capsys):
    """results.json holds base parameters; the exported standard set reproduces them exactly."""
    src = tmp_path / "robot.urdf"
    src.write_text(SMALL["fixed_inertial_child"])
    assert main(["model", "import", str(src), "--out", str(tmp_path / "robot.toml")]) == 0
    tree = load_tree(tmp_path / "robot.toml")
    assert tree.joint_names == {1: "j1", 2: "j2"}
    capsys.readouterr()
    assert main(["model", "show", str(tmp_path / "robot.toml")]) == 0  # each frame's URDF joint, in the table
    rows = [ln.split() for ln in capsys.readouterr().out.splitlines() if ln.split()[:1] in (["1"], ["2"])]
    assert [r[-1] for r in rows[:2]] == ["j1", "j2"]
    true = tree.with_values({k: v * 1.05 for k, v in tree.values.items()})
    base = Model(tree).base_parameters()
    XB = base.values(true.parameters)
    results = {"method": "WLS", "parameters": [{"name": n, "value": float(v)} for n, v in zip(base.names, XB,
                                                                                                strict=True)],
               "base_parameters": dict(zip(base.names, base.expressions, strict=True))}
    (tmp_path / "results.json").write_text(json.dumps(results))
    std = standard_from_base(tree, dict(zip(base.names, XB, strict=True)), "results.json")
    assert rel(base.values(tree.with_values(std).parameters), XB) < 1e-12
    rc = main(["model", "export", str(tmp_path / "robot.toml"), "--params", str(tmp_path / "results.json"),
               "--urdf", str(src), "--out", str(tmp_path / "new.urdf")])
    assert rc == 0, capsys.readouterr().err
    back = import_urdf(tmp_path / "new.urdf").tree
    assert rel(base.values(back.parameters), XB) < 1e-12


def test_cli_export_params_toml_and_errors(tmp_path, capsys):
    src = tmp_path / "robot.urdf"
    src.write_text(SMALL["arbitrary_axis"])
    tree = import_urdf(src).tree
    save_tree(tree, tmp_path / "robot.toml")
    # a body scaled by a factor stays realisable: frame 1 halved as flat names, frame 2 as a [parameters.2] table
    flat = "".join(f"{k}1 = {0.5 * tree.values.get(f'{k}1', 0.0)!r}\n" for k in INERTIAL)
    table = "".join(f"{k} = {0.9 / 0.7 * tree.values.get(f'{k}2', 0.0)!r}\n" for k in INERTIAL)
    (tmp_path / "p.toml").write_text(flat + "[parameters.2]\n" + table)
    args = ["model", "export", str(tmp_path / "robot.toml"), "--urdf", str(src), "--out", str(tmp_path / "new.urdf")]
    assert main([*args, "--params", str(tmp_path / "p.toml")]) == 0
    back = import_urdf(tmp_path / "new.urdf").tree
    assert back.values["M1"] == pytest.approx(0.5) and back.values["M2"] == pytest.approx(0.9)
    (tmp_path / "bad.toml").write_text("[parameters.2]\nM = -0.9\n")
    args.append("--force")  # new.urdf exists now: the errors below are the parameters'
    capsys.readouterr()
    assert main([*args, "--params", str(tmp_path / "bad.toml")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "bad.toml" in err and "frame 2" in err and "not positive" in err
    (tmp_path / "typo.toml").write_text("MM1 = 1.0\n")
    assert main([*args, "--params", str(tmp_path / "typo.toml")]) == 2
    assert "'MM1' is not a parameter" in capsys.readouterr().err


def test_mimic_kinematics_match_pinocchio():
    """The Panda's right finger (a mimic) placed and its Jacobian taken as Pinocchio's mimic model does: the
    finger's column of q is ignored, and its motion is in the first finger's column (J G)."""
    path = robot_file("panda")
    tree = import_urdf(path).tree
    pm = pin.buildModelFromXML(path.read_text(encoding="utf-8"), mimic=True)
    data = pm.createData()
    frame = {name: j for j, name in tree.joint_names.items()}
    actuated = [frame[pm.names[i]] - 1 for i in range(1, pm.njoints) if pm.joints[i].nv > 0]
    right = tree.frame_of("panda_finger_joint2")
    jid = pm.getJointId("panda_finger_joint2")
    q = states(tree.n)[0]
    q[:, right - 1] = 123.0  # ignored
    model = Model(tree)
    T, J = model.transforms(q), model.jacobian(q, right)
    assert np.all(J[:, :, right - 1] == 0.0)
    for s in range(q.shape[0]):
        pin.forwardKinematics(pm, data, q[s, actuated])
        M = data.oMi[jid]
        # dynid's frame has the URDF link frame's origin; its z is the joint axis (0 -1 0 in the link frame)
        assert np.abs(T[s, right][:3, 3] - M.translation).max() < 1e-12
        assert np.abs(T[s, right][:3, 2] - M.rotation @ np.array([0.0, -1.0, 0.0])).max() < 1e-12
        pin.computeJointJacobians(pm, data, q[s, actuated])
        Jp = pin.getJointJacobian(pm, data, jid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        assert np.abs(J[s][:, actuated] - Jp).max() < 1e-12


def test_inertia_shortcut_agrees_with_the_principal_moments():
    """The URDF import's shortcut (`_inside_bounds`: Gershgorin's discs of the second moment tr(I)/2 E - I) passes
    an inertia only where its principal moments (numpy's eigvalsh, the oracle) are >= 0 and meet the triangle
    inequality; over diagonal, near-diagonal, random and boundary inertias (and it is not vacuous: it passes
    more than a quarter of them)."""
    from dynid.model.urdf import _inside_bounds

    rng = np.random.default_rng(11)
    cases = []
    for scale in (1e-8, 1e-3, 1.0, 1e3):
        for _ in range(2000):
            lam = rng.uniform(0.0, 1.0, 3) * scale
            if rng.random() < 0.5:  # on or beyond the triangle's edge, or a negative moment
                lam[2] = lam[0] + lam[1] + rng.choice([-1.0, 0.0, 1.0]) * rng.uniform(0, 0.1) * scale
                lam[0] *= rng.choice([1.0, -1.0])
            Q = np.linalg.qr(rng.normal(size=(3, 3)))[0] if rng.random() < 0.7 else np.eye(3)
            if rng.random() < 0.5:  # near-diagonal: a small rotation
                Q = np.eye(3) + 1e-3 * rng.normal(size=(3, 3))
            cases.append(Q @ np.diag(lam) @ Q.T)
    passed = 0
    for I in cases:
        I = (I + I.T) / 2
        if _inside_bounds(I):
            passed += 1
            lam = np.linalg.eigvalsh(I)
            tol = 1e-12 * np.abs(lam).max()
            assert lam[0] >= -tol and lam[2] <= lam[0] + lam[1] + tol, (I, lam)
    assert passed > len(cases) // 4  # it takes the common case, not none
