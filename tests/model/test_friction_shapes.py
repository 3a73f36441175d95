"""Smooth Coulomb friction laws (tanh, sigmoid) declared per joint, and the one-line `friction` table.

Oracles: closed forms of the laws written here with math/numpy (not dynid's code), central finite
differences, a 1-DOF rotor whose torque is known in closed form, the other engine, the shipped TX40 file.
"""

from __future__ import annotations

import ctypes
import dataclasses
import math
import shutil
import subprocess
import tomllib

import numpy as np
import pytest

from dynid import Model
from dynid.dynamics.newton_euler import joint_term_column
from dynid.estimation import ols
from dynid.model import Frame, ModelError, Tree, example_path, load_tree, save_tree, tree_from_dict, tree_to_toml

ENGINES = ("numpy", "numba")
VS = 0.05


def tanh_law(qd: np.ndarray, vs: float) -> np.ndarray:
    return np.array([math.tanh(x / vs) for x in np.ravel(qd)]).reshape(np.shape(qd))


def sigmoid_law(qd: np.ndarray, vs: float) -> np.ndarray:
    """The definition 2 / (1 + exp(-qd / vs)) - 1, evaluated as written (exp's overflow: 2 / inf - 1 = -1)."""

    def one(x: float) -> float:
        try:
            return 2.0 / (1.0 + math.exp(-x / vs)) - 1.0
        except OverflowError:
            return -1.0

    return np.array([one(x) for x in np.ravel(qd)]).reshape(np.shape(qd))


def tx40_dict() -> dict:
    return tomllib.loads(example_path("tx40").read_text())


def tx40_shaped() -> Tree:
    """The TX40 with tanh friction on most joints, sigmoid on joint 2, sign on joint 1."""
    d = tx40_dict()
    d["friction"] = {"shape": "tanh", "vs": VS, "joints": {"2": {"shape": "sigmoid"}, "1": {"shape": "sign"},
                                                            "6": {"vs": 0.02}}}
    return tree_from_dict(d)


def states(n: int, N: int = 300, seed: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random states whose velocities cover 0, |qd| ~ vs and |qd| >> vs."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, (N, n))
    qd = rng.normal(size=(N, n)) * np.logspace(-3, 1, N)[:, None]
    qd[:7] = 0.0
    return q, qd, rng.normal(size=(N, n))


def assert_agree(a: np.ndarray, b: np.ndarray, tol: float = 1e-12) -> None:
    """max |a - b| <= tol in units of the largest |b| (at least 1): the geared wrist's torques reach 1e4 N m,
    whose round-off alone is 2e-12."""
    a, b = np.asarray(a), np.asarray(b)
    assert np.abs(a - b).max() <= tol * max(1.0, np.abs(b).max()), (np.abs(a - b).max(), np.abs(b).max())


# ----- the column itself ------------------------------------------------------------------------------
QD = np.array([0.0, 1e-9, -1e-9, 0.3 * VS, -VS, 2.5 * VS, -4.0 * VS, 50 * VS, -1e3 * VS, 1e6])


@pytest.mark.parametrize("shape, law", [("tanh", tanh_law), ("sigmoid", sigmoid_law)])
def test_fs_column_closed_form(shape, law):
    col = joint_term_column("FS", np.zeros_like(QD), QD, np.zeros_like(QD), (shape, VS))
    np.testing.assert_allclose(col, law(QD, VS), rtol=0, atol=4e-16)
    assert col[0] == 0.0  # no friction at rest, like sign(0)
    far = np.abs(QD) >= 50 * VS  # tends to sign(qd) when |qd| >> vs
    np.testing.assert_allclose(col[far], np.sign(QD[far]), rtol=0, atol=1e-16)


@pytest.mark.parametrize("shape, slope", [("tanh", 1.0 / VS), ("sigmoid", 0.5 / VS)])
def test_fs_column_slope_at_rest(shape, slope):
    """d s / d qd at 0 by central differences: 1 / vs for tanh, 1 / (2 vs) for the sigmoid."""
    h = 1e-6 * VS
    x = np.array([-h, h])
    col = joint_term_column("FS", x, x, x, (shape, VS))
    assert (col[1] - col[0]) / (2 * h) == pytest.approx(slope, rel=1e-9)


def test_sigmoid_is_tanh_of_half():
    x = np.linspace(-3, 3, 61)
    np.testing.assert_allclose(sigmoid_law(x, VS), tanh_law(x, 2 * VS), rtol=0, atol=4e-16)


@pytest.mark.parametrize("backend", ENGINES)
def test_fs_column_is_the_derivative_of_tau(backend):
    """W[:, j, FSj] = d tau_j / d FSj (central differences on the inverse dynamics), and the closed form."""
    tree = tx40_shaped()
    model = Model(tree)
    q, qd, qdd = states(tree.n, 200)
    W = model.regressor(q, qd, qdd, backend=backend)
    X = tree.parameters
    laws = {1: np.sign, 2: lambda v: sigmoid_law(v, VS), 3: lambda v: tanh_law(v, VS),
            4: lambda v: tanh_law(v, VS), 5: lambda v: tanh_law(v, VS), 6: lambda v: tanh_law(v, 0.02)}
    for j, law in laws.items():
        k = tree.index[f"FS{j}"]
        h = 1e-3
        Xp, Xm = X.copy(), X.copy()
        Xp[k] += h
        Xm[k] -= h
        fd = (model.inverse_dynamics(q, qd, qdd, X=Xp, backend=backend)
              - model.inverse_dynamics(q, qd, qdd, X=Xm, backend=backend)) / (2 * h)
        np.testing.assert_allclose(fd[:, j - 1], W[:, j - 1, k], rtol=0, atol=1e-9)
        np.testing.assert_allclose(W[:, j - 1, k], law(qd[:, j - 1]), rtol=0, atol=4e-16)
        others = np.delete(W[:, :, k], j - 1, axis=1)
        assert not others.any()  # a joint's friction acts on its own row only


# ----- a 1-DOF rotor about the vertical: tau = IA qdd + FV qd + FS s(qd) --------------------------------
def rotor(shape: str, vs: float) -> Tree:
    return Tree("rotor", (Frame(1, 0, 0),), joint_terms={1: ("IA", "FV", "FS")},
                friction_shape={} if shape == "sign" else {1: (shape, vs)},
                values={"IA1": 0.37, "FV1": 1.9, "FS1": 2.6})


@pytest.mark.parametrize("backend", ENGINES)
@pytest.mark.parametrize("shape, law", [("tanh", tanh_law), ("sigmoid", sigmoid_law)])
def test_rotor_identified_to_round_off(shape, law, backend):
    vs = 0.02
    tree = rotor(shape, vs)
    model = Model(tree)
    t = np.linspace(0.0, 4.0, 801)
    q = (0.3 * np.sin(2 * np.pi * 0.7 * t) + 0.1 * np.sin(2 * np.pi * 2.3 * t))[:, None]
    qd = (0.3 * 2 * np.pi * 0.7 * np.cos(2 * np.pi * 0.7 * t) + 0.1 * 2 * np.pi * 2.3 * np.cos(2 * np.pi * 2.3 * t))
    qdd = (-0.3 * (2 * np.pi * 0.7) ** 2 * np.sin(2 * np.pi * 0.7 * t)
           - 0.1 * (2 * np.pi * 2.3) ** 2 * np.sin(2 * np.pi * 2.3 * t))
    qd, qdd = qd[:, None], qdd[:, None]
    tau = 0.37 * qdd[:, 0] + 1.9 * qd[:, 0] + 2.6 * law(qd[:, 0], vs)  # the closed form
    np.testing.assert_allclose(model.inverse_dynamics(q, qd, qdd, backend=backend)[:, 0], tau, rtol=0, atol=1e-14)
    names = ["IA1", "FV1", "FS1"]
    W = model.regressor(q, qd, qdd, cols=names, backend=backend)[:, 0, :]
    fit = ols(W, tau, names)
    truth = np.array([0.37, 1.9, 2.6])
    err = np.abs(fit.values - truth) / truth
    assert err.max() < 1e-13, err
    # the sign law would not fit this torque: the shape is what the regressor carries
    W_sign = Model(rotor("sign", vs)).regressor(q, qd, qdd, cols=names, backend=backend)[:, 0, :]
    assert np.abs(ols(W_sign, tau, names).values - truth).max() > 1e-3


# ----- engines, models, symbolic code ------------------------------------------------------------------
def test_engines_agree():
    tree = tx40_shaped()
    model = Model(tree)
    q, qd, qdd = states(tree.n)
    tau = {b: model.inverse_dynamics(q, qd, qdd, backend=b) for b in ENGINES}
    W = {b: model.regressor(q, qd, qdd, backend=b) for b in ENGINES}
    assert_agree(tau["numba"], tau["numpy"])
    assert_agree(W["numba"], W["numpy"])
    cols = ["FS2", "FV3", "FS6", "fsm6", "FS1"]  # a restricted block goes through its own plan
    Wr = {b: model.regressor(q, qd, qdd, rows=[2, 6, 1], cols=cols, backend=b) for b in ENGINES}
    assert_agree(Wr["numba"], Wr["numpy"])
    assert np.array_equal(Wr["numba"], W["numba"][:, [1, 5, 0]][:, :, [tree.index[c] for c in cols]])


@pytest.mark.parametrize("backend", ENGINES)
def test_inverse_dynamics_is_regressor_times_parameters(backend):
    tree = tx40_shaped()
    model = Model(tree)
    q, qd, qdd = states(tree.n)
    tau = model.inverse_dynamics(q, qd, qdd, backend=backend)
    W = model.regressor(q, qd, qdd, backend=backend)
    assert_agree(W @ tree.parameters, tau)


@pytest.mark.parametrize("backend", ENGINES)
def test_sign_law_unchanged(backend):
    """A tree whose laws are all sign gives the same numbers as before: FS sign(qd), bit for bit."""
    tree = load_tree(example_path("tx40"))
    assert tree.friction_shape == {}
    q, qd, qdd = states(tree.n)
    W = Model(tree).regressor(q, qd, qdd, backend=backend)
    for j in range(1, 7):
        assert np.array_equal(W[:, j - 1, tree.index[f"FS{j}"]], np.sign(qd[:, j - 1]))
    assert "[friction" not in tree_to_toml(tree)  # model files (and the generator's cache keys) unchanged


def test_generated_numpy_code_matches_engine():
    from dynid.symbolic import build, numpy_module, to_text

    tree = tx40_shaped()
    model = Model(tree)
    q, qd, qdd = states(tree.n, 100)
    W = numpy_module(tree, "regressor").evaluate(q, qd, qdd)
    assert_agree(W, model.regressor(q, qd, qdd))
    tau = numpy_module(tree, "idm").evaluate(q, qd, qdd, tree.parameters)
    assert_agree(tau, model.inverse_dynamics(q, qd, qdd))
    text = to_text(build(tree, "idm"))
    assert "tanh(" in text and "SGN1 = sign(" in text


def test_generated_numba_code_matches_engine():
    pytest.importorskip("numba")
    from dynid.symbolic import build
    from dynid.symbolic.numba_backend import arguments, numba_model

    tree = tx40_shaped()
    q, qd, qdd = states(tree.n, 50)
    ref = Model(tree).inverse_dynamics(q, qd, qdd)
    fn = numba_model(tree, "idm")
    assert arguments(build(tree, "idm")) == ["q", "qd", "qdd", "X"]
    out = np.zeros(tree.n)
    for s in range(len(q)):
        fn(q[s], qd[s], qdd[s], tree.parameters, out)
        assert_agree(out, ref[s])


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_generated_c_matches_engine(tmp_path):
    from dynid.symbolic import build, to_c

    tree = tx40_shaped()
    header, source = to_c(build(tree, "idm"))
    (tmp_path / "dynid_idm.h").write_text(header)
    (tmp_path / "dynid_idm.c").write_text(source)
    lib = tmp_path / "libidm.so"
    subprocess.run(["cc", "-O1", "-shared", "-fPIC", "-o", str(lib), str(tmp_path / "dynid_idm.c"), "-lm"],
                   check=True, capture_output=True)
    c = ctypes.CDLL(str(lib))
    q, qd, qdd = states(tree.n, 40)
    ref = Model(tree).inverse_dynamics(q, qd, qdd)
    out = np.zeros((len(q), tree.n))
    ptr = ctypes.POINTER(ctypes.c_double)
    arrays = [np.ascontiguousarray(a) for a in (q, qd, qdd, tree.parameters)]
    c.dynid_idm_batch(ctypes.c_long(len(q)), *[a.ctypes.data_as(ptr) for a in arrays], out.ctypes.data_as(ptr))
    assert_agree(out, ref)


# ----- model files ------------------------------------------------------------------------------------
def test_round_trip_keeps_the_laws(tmp_path):
    tree = tx40_shaped()
    save_tree(tree, tmp_path / "m.toml")
    again = load_tree(tmp_path / "m.toml")
    assert again == tree
    assert again.friction_shape == {2: ("sigmoid", VS), 3: ("tanh", VS), 4: ("tanh", VS), 5: ("tanh", VS),
                                    6: ("tanh", 0.02)}
    shared = tree_from_dict({**tx40_dict(), "friction": {"shape": "sigmoid", "vs": 0.003}})
    text = tree_to_toml(shared)
    assert "[friction]\nshape = \"sigmoid\"\nvs = 0.003\n" in text  # one law for all: written once
    assert tree_from_dict(tomllib.loads(text)) == shared


SEPARATE = """
name = "seven"
frames = [[1, 0, 0, 0, 0, 0, 0, 0, 0], [2, 1, 0, 0, 0, "-pi/2", 0, 0, 0], [3, 2, 0, 0, 0, "pi/2", 0, 0, 0.3],
          [4, 3, 0, 0, 0, "-pi/2", 0, 0, 0], [5, 4, 0, 0, 0, "pi/2", 0, 0, 0.3], [6, 5, 2, 0, 0, 0, 0.1, 0, 0],
          [7, 5, 0, 0, 0, "-pi/2", 0, 0, 0], [8, 7, 0, 0, 0, "pi/2", 0, 0, 0]]
"""


def test_one_line_equals_separate_lines():
    """friction.all on a 7-joint arm (a fixed frame among them) = 21 lines of [parameters.j]."""
    moving = [1, 2, 3, 4, 5, 7, 8]
    separate = SEPARATE + "".join(f"[parameters.{j}]\nFV = 0.0\nFS = 0.0\nOFF = 0.0\n" for j in moving)
    one_line = SEPARATE + 'friction = { all = ["FV", "FS", "OFF"] }\n'
    a, b = tree_from_dict(tomllib.loads(separate)), tree_from_dict(tomllib.loads(one_line))
    assert dataclasses.replace(a, values={}) == b  # the same tree; the lines also set the values to 0
    assert a.parameter_names == b.parameter_names and np.array_equal(a.parameters, b.parameters)
    assert 6 not in b.joint_terms  # the fixed frame gets none


def test_one_line_on_the_tx40():
    shipped = load_tree(example_path("tx40"))
    d = tx40_dict()
    for j, table in d["parameters"].items():  # keep the values that are not zero, drop the declarations' lines
        for t in ("FV", "FS", "OFF"):
            table.pop(t)
        d["parameters"][j] = table
    d["friction"] = {"all": ["FV", "FS", "OFF"]}
    terms_only = tree_from_dict(d)
    assert terms_only.joint_terms == shipped.joint_terms
    assert terms_only.parameter_names == shipped.parameter_names
    # with the values given per joint again, the very same tree
    d = tx40_dict()
    d["friction"] = {"all": ["IA", "FV", "FS", "OFF"], "shape": "tanh", "vs": 0.01}
    full = tree_from_dict(d)
    for j in range(1, 6):  # where they coincide; joint 6's rotor is the coupling Iam6, so IA6 is new
        assert full.joint_terms[j] == shipped.joint_terms[j]
    assert full.joint_terms[6] == ("IA",) + shipped.joint_terms[6]
    assert full.friction_shape == {j: ("tanh", 0.01) for j in range(1, 7)}
    assert all(full.values[k] == v for k, v in shipped.values.items())
    d["friction"] = {"all": ["FV", "FS", "OFF"]}
    assert tree_from_dict(d) == shipped


@pytest.mark.parametrize("friction, words", [
    ({"shape": "tahn", "vs": 0.01}, ["shape = 'tahn'", "did you mean 'tanh'"]),
    ({"shape": "tanh"}, ["needs vs"]),
    ({"shape": "sigmoid", "vs": 0.0}, ["vs = 0", "> 0"]),
    ({"shape": "tanh", "vs": -0.1}, ["vs = -0.1", "> 0"]),
    ({"vs": 0.01}, ["vs = 0.01", "sign"]),
    ({"shape": "tanh", "vs": "fast"}, ["friction: vs", "'fast'"]),
    ({"shap": "tanh", "vs": 0.01}, ["unknown key 'shap'", "did you mean 'shape'"]),
    ({"all": ["Fs"]}, ["unknown term 'Fs'", "did you mean 'FS'"]),
    ({"all": ["K"]}, ["unknown term 'K'", "[parameters.j]"]),
    ({"all": "FS"}, ["friction.all", "expected"]),
    ({"shape": "tanh", "vs": 0.01, "joints": {"6": {"shape": "sign", "vs": 0.1}}}, ["joints.6", "sign"]),
    ({"joints": {"9": {"shape": "tanh", "vs": 1.0}}}, ["joints.9", "frame 9 does not exist"]),
    ({"joints": {"wrist": {"vs": 1.0}}}, ["joints.wrist", "frame numbers"]),
    ({"joints": {"6": {"shpe": "tanh"}}}, ["joints.6", "unknown key 'shpe'", "did you mean 'shape'"]),
    ({"joints": {"6": "tanh"}}, ["friction.joints must be a table"]),
    ("tanh", ["friction = 'tanh'", "expected a table"]),
])
def test_bad_friction_tables(friction, words):
    d = tx40_dict()
    d["friction"] = friction
    with pytest.raises(ModelError) as exc:
        tree_from_dict(d, source="arm.toml")
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith("arm.toml: friction")
    for w in words:
        assert w in msg, msg


def test_shape_on_a_joint_without_coulomb_term():
    d = tx40_dict()
    del d["parameters"]["6"]["FS"]
    d["friction"] = {"joints": {"6": {"shape": "tanh", "vs": 0.01}}}
    with pytest.raises(ModelError, match=r"frame 6 has no Coulomb term FS"):
        tree_from_dict(d, source="arm.toml")
    d["friction"] = {"shape": "tanh", "vs": 0.01}  # a shared law applies to the joints that have FS
    assert 6 not in tree_from_dict(d).friction_shape


@pytest.mark.parametrize("laws, words", [
    ({1: ("tanh", 0.0)}, "needs vs > 0"),
    ({1: ("cubic", 0.1)}, "not in"),
    ({1: ("sign", 0.1)}, "no meaning for the sign law"),
    ({2: ("tanh", 0.1)}, "does not exist"),
])
def test_tree_validates_laws(laws, words):
    with pytest.raises(ModelError, match=words):
        Tree("rotor", (Frame(1, 0, 0),), joint_terms={1: ("FS",)}, friction_shape=laws)
