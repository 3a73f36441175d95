"""The compiled (Numba) engine against the NumPy reference engine, for what Pinocchio does not model: joint terms,
couplings, external wrenches, restricted rows and columns. Both engines are compared with Pinocchio, the
independent oracle for the rigid-body models (inverse dynamics, regressor, inertia matrix), on the same trees in
test_pinocchio_oracle.py.
"""

import dataclasses
import math
import warnings

import numpy as np
import pytest
from oracles import random_states

import dynid
from dynid import Model, Wrench, load_model
from dynid.dynamics import newton_euler, resolve_backend
from dynid.model import ModelError
from dynid.vehicle import car_template
from dynid.vehicle.template import EQUATION_ROWS, paper_parameter_names

compiled = pytest.importorskip("dynid.dynamics.compiled")
if not compiled.HAVE_NUMBA:
    pytest.skip("numba is not installed", allow_module_level=True)


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / max(1.0, np.abs(b).max()))


# ----- against the NumPy engine: joint terms, couplings, wrenches, restrictions --------------


def full_model(name: str) -> Model:
    """A model with every joint term and a coupling of each kind, random values."""
    if name == "car":
        return Model(car_template())
    tree = load_model(name).tree
    rng = np.random.default_rng(3)
    moving = [f.j for f in tree.frames if f.sigma != 2]
    terms = {j: ("IA", "FV", "FS", "OFF", "K", "KQ", "FVPL", "FVPH", "FVNL", "FVNH") for j in moving}
    # knees inside the random velocities' range (N(0, 1)), so that every piece of the viscous curve is visited
    knees = {j: (-float(rng.uniform(0.1, 0.8)), float(rng.uniform(0.1, 0.8))) for j in moving}
    a, b = moving[1], moving[-1]
    couplings = tuple(dynid.model.Coupling(f"c{k}", k, {a: 1.5, b: -0.7}) for k in ("K", "IA", "FV", "FS"))
    t = dataclasses.replace(tree, joint_terms=terms, couplings=couplings, values={}, knees=knees)
    return Model(dataclasses.replace(t, values=dict(zip(t.parameter_names, rng.normal(size=t.p), strict=True))))


@pytest.mark.parametrize("name", ["puma560", "tx40", "floating_tree", "car"])
def test_joint_terms_and_couplings_match_numpy_engine(name):
    m = full_model(name)
    q, qd, qdd = random_states(m.tree, 15, seed=5)
    qd[0, :] = 0.0  # sign(0) = 0 for the Coulomb terms
    X = np.random.default_rng(1).normal(size=m.tree.p)
    for x in (None, X):
        assert rel(m.inverse_dynamics(q, qd, qdd, X=x, backend="numba"),
                   m.inverse_dynamics(q, qd, qdd, X=x, backend="numpy")) < 1e-12
    assert rel(m.regressor(q, qd, qdd, backend="numba"), m.regressor(q, qd, qdd, backend="numpy")) < 1e-12
    assert rel(m.inertia_matrix(q, X, backend="numba"), m.inertia_matrix(q, X, backend="numpy")) < 1e-12


def some_wrenches(tree, N: int, rng) -> list[Wrench]:
    """Wrenches on three links, at points, in the link's frame, in frame 0 and in another frame;
    one with constant values."""
    moving = [f.j for f in tree.frames]
    links = rng.choice(moving, size=3, replace=False)
    return [
        Wrench(int(links[0]), rng.normal(size=(N, 6)), rng.normal(size=3)),
        Wrench(int(links[1]), rng.normal(size=(N, 6)), rng.normal(size=3), frame=0),
        Wrench(int(links[2]), rng.normal(size=6), rng.normal(size=3), frame=int(links[0])),
        Wrench(int(links[2]), rng.normal(size=(N, 6)), frame=int(links[1])),
    ]


@pytest.mark.parametrize("name", ["tx40", "floating_tree", "car"])
def test_wrenches_match_numpy_engine(name):
    m = full_model(name)
    rng = np.random.default_rng(7)
    q, qd, qdd = random_states(m.tree, 9, seed=6)
    ws = some_wrenches(m.tree, 9, rng)
    tau = m.inverse_dynamics(q, qd, qdd, ws, backend="numba")
    assert rel(tau, m.inverse_dynamics(q, qd, qdd, ws, backend="numpy")) < 1e-12
    W, Q = m.regressor(q, qd, qdd, ws, backend="numba")
    Wn, Qn = m.regressor(q, qd, qdd, ws, backend="numpy")
    assert rel(W, Wn) < 1e-12 and rel(Q, Qn) < 1e-12
    assert rel(W @ m.parameters - Q, tau) < 1e-11
    rows = [1, 3, m.n]
    Wr, Qr = m.regressor(q, qd, qdd, ws, rows=rows, cols=list(m.parameter_names[:25]), backend="numba")
    assert rel(Qr, Qn[:, np.array(rows) - 1]) < 1e-12
    assert rel(Wr, Wn[:, np.array(rows) - 1, :25]) < 1e-12


@pytest.mark.parametrize("name", ["tx40", "floating_tree"])
def test_forward_dynamics_inverts_inverse_dynamics(name):
    m = load_model(name)
    q, qd, qdd = random_states(m.tree, 6, seed=4)
    ws = some_wrenches(m.tree, 6, np.random.default_rng(2))
    tau = m.inverse_dynamics(q, qd, qdd, ws)
    moving = m.tree.sigma[1:] != 2
    assert rel(m.forward_dynamics(q, qd, tau, ws)[:, moving], qdd[:, moving]) < 1e-9


@pytest.mark.parametrize("seed", range(4))
def test_w_times_random_x_is_the_inverse_dynamics(seed):
    """Linearity in X, with wrenches: W X = tau + Q for any X (joint terms and couplings included)."""
    m = full_model(["puma560", "tx40", "floating_tree", "car"][seed])
    rng = np.random.default_rng(seed)
    q, qd, qdd = random_states(m.tree, 8, seed=seed)
    ws = some_wrenches(m.tree, 8, rng)
    W, Q = m.regressor(q, qd, qdd, ws)
    for _ in range(3):
        X = rng.normal(size=m.tree.p)
        assert rel(W @ X - Q, m.inverse_dynamics(q, qd, qdd, ws, X=X)) < 1e-11


def test_car_equations_block_matches_numpy_engine():
    """The car's 14 equations x 48 paper parameters (labels accepted), and their Q."""
    m = Model(car_template())
    q, qd, qdd = random_states(m.tree, 12, seed=8)
    rows, cols = list(EQUATION_ROWS), paper_parameter_names()
    ws = [Wrench(k, np.random.default_rng(k).normal(size=(12, 6)) * 1e3, frame=0) for k in (15, 24, 33, 42)]
    W, Q = m.regressor(q, qd, qdd, ws, rows=rows, cols=cols)
    Wn, Qn = m.regressor(q, qd, qdd, ws, rows=rows, cols=cols, backend="numpy")
    assert W.shape == (12, 14, 48)
    assert rel(W, Wn) < 1e-12 and rel(Q, Qn) < 1e-12
    full = m.regressor(q, qd, qdd)
    idx = [m.tree.column(c) for c in cols]
    assert rel(W, full[:, np.array(rows) - 1][:, :, idx]) < 1e-12


def test_single_sample_and_repeated_rows_and_columns():
    m = full_model("tx40")
    q, qd, qdd = random_states(m.tree, 3, seed=9)
    rows, cols = [2, 6, 2], ["M3", "ZZ1", "cFV", "M3", "FS6"]
    W = m.regressor(q, qd, qdd, rows=rows, cols=cols)
    Wn = m.regressor(q, qd, qdd, rows=rows, cols=cols, backend="numpy")
    assert W.shape == (3, 3, 5)
    assert rel(W[:, 1:], Wn[:, 1:]) < 1e-12  # (the numpy engine fills only the last of repeated rows)
    assert np.array_equal(W[:, 0], W[:, 2]) and np.array_equal(W[:, :, 0], W[:, :, 3])
    W1 = m.regressor(q[1], qd[1], qdd[1], rows=rows, cols=cols)
    assert W1.shape == (3, 5) and np.allclose(W1, W[1], rtol=0, atol=1e-13)
    tau1 = m.inverse_dynamics(q[1], qd[1], qdd[1])
    assert tau1.shape == (6,) and rel(tau1, m.inverse_dynamics(q, qd, qdd, backend="numpy")[1]) < 1e-12
    ws = [Wrench(4, np.ones(6))]
    W1, Q1 = m.regressor(q[1], qd[1], qdd[1], ws)
    assert W1.shape == (6, m.tree.p) and Q1.shape == (6,)
    _, Qn = m.regressor(q, qd, qdd, ws, backend="numpy")
    assert rel(Q1, Qn[1]) < 1e-12
    assert m.regressor(q, qd, qdd, [])[1].shape == (3, 6)  # an empty wrench list still gives (W, Q)


# ----- the out= buffer -------------------------------------------------------------------------


def test_out_buffer_is_filled_reused_and_leaves_structural_zeros():
    m = Model(car_template())
    q, qd, qdd = random_states(m.tree, 6, seed=10)
    fresh = m.regressor(q, qd, qdd)
    out = np.zeros_like(fresh)
    assert m.regressor(q, qd, qdd, out=out) is out
    assert np.array_equal(out, fresh)
    q2, qd2, qdd2 = random_states(m.tree, 6, seed=11)
    m.regressor(q2, qd2, qdd2, out=out)  # reused without clearing
    assert np.array_equal(out, m.regressor(q2, qd2, qdd2))
    # entries never written are structural zeros of the regressor
    sentinel = np.full_like(fresh, np.nan)
    m.regressor(q, qd, qdd, out=sentinel)
    untouched = np.isnan(sentinel)
    assert untouched.mean() > 0.5 and not fresh[untouched].any()
    assert np.array_equal(sentinel[~untouched], fresh[~untouched])
    # the restricted block, one sample, and the numpy engine take out= too
    rows, cols = list(EQUATION_ROWS), paper_parameter_names()
    part = np.zeros((14, 48))
    assert m.regressor(q[2], qd[2], qdd[2], rows=rows, cols=cols, out=part) is part
    assert np.array_equal(part, m.regressor(q, qd, qdd, rows=rows, cols=cols)[2])
    out_np = np.zeros_like(fresh)
    m.regressor(q, qd, qdd, out=out_np, backend="numpy")
    assert rel(out_np, fresh) < 1e-12


def test_out_buffer_errors():
    m = load_model("puma560")
    q, qd, qdd = random_states(m.tree, 4, seed=1)
    for bad in (np.zeros((4, 6, 5)), np.zeros((4, 6, m.tree.p), dtype=np.float32), np.zeros((4, m.tree.p, 6)).T,
                [[0.0]]):
        for backend in ("numba", "numpy"):
            with pytest.raises(ModelError, match="out must"):
                m.regressor(q, qd, qdd, out=bad, backend=backend)


# ----- inputs, backend selection, sincos ---------------------------------------------------------


def test_bad_inputs_give_the_engines_messages():
    m = load_model("puma560")
    q, qd, qdd = random_states(m.tree, 4, seed=1)
    q[2, 3] = np.nan
    for f in (m.inverse_dynamics, m.regressor):
        with pytest.raises(ModelError, match="sample 2, frame 4"):
            f(q, qd, qdd)
        with pytest.raises(ModelError, match="shape"):
            f(qd[:, :5], qd, qdd)
        with pytest.raises(ModelError, match="same shape"):
            f(qd, qd[:3], qdd)


def test_backend_selection(monkeypatch):
    assert resolve_backend() == "numba" and resolve_backend("numpy") == "numpy"
    with pytest.raises(ModelError, match="backend"):
        resolve_backend("fortran")
    monkeypatch.setenv("DYNID_BACKEND", "numpy")
    assert resolve_backend() == "numpy" and resolve_backend("numba") == "numba"
    monkeypatch.setenv("DYNID_BACKEND", "cuda")
    with pytest.raises(ModelError, match="DYNID_BACKEND"):
        resolve_backend()
    monkeypatch.delenv("DYNID_BACKEND")
    # without numba: the NumPy engine, one warning
    monkeypatch.setattr(newton_euler, "_numba_works", lambda: False)
    monkeypatch.setattr(newton_euler, "_WARNED", [False])
    m = load_model("tx40")
    q, qd, qdd = random_states(m.tree, 3, seed=2)
    with pytest.warns(RuntimeWarning, match="numba is not installed"):
        tau = m.inverse_dynamics(q, qd, qdd)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m.regressor(q, qd, qdd)
    assert rel(tau, m.inverse_dynamics(q, qd, qdd, backend="numpy")) == 0.0


def test_sincos_within_an_ulp_of_libm():
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.uniform(-4, 4, 2000), rng.uniform(-1e5, 1e5, 2000), rng.uniform(-1e9, 1e9, 100),
                        [0.0, -0.0, math.pi / 4, math.pi / 2, math.pi, 1e-300, 99999.99, 100000.0, -2e5]])
    for v in x:
        s, c = compiled._sincos(v)
        assert abs(s - math.sin(v)) <= 2.3e-16 and abs(c - math.cos(v)) <= 2.3e-16, v
