"""The NumPy reference engine (backend="numpy") against Pinocchio (an independent C++ library):
transforms, inverse dynamics, regressor and inertia matrix. The compiled engine, the default
backend, has the same comparisons in test_compiled.py.

Random trees up to 42 frames: branches, revolute, prismatic and fixed frames, non-zero
gamma and b, a virtual floating-base chain, random physical inertias, random gravity; the
shipped robots and the car's 42-frame template without their joint terms and couplings.
"""


import numpy as np
import pytest
from oracles import PinModel, random_inertia, random_states, random_tree, rigid

from dynid import Model, load_model
from dynid.vehicle import car_template

pin = pytest.importorskip("pinocchio")
ENGINE = "numpy"  # the reference engine, never the default (compiled) one

TREES = [
    ("serial6", dict(seed=1, n=6, serial=True, fixed=False)),
    ("branched12", dict(seed=2, n=12)),
    ("floating20", dict(seed=3, n=20, floating=True)),
    ("branched42", dict(seed=4, n=42)),
    ("floating42", dict(seed=5, n=42, floating=True)),
]


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / max(1.0, np.abs(b).max()))


@pytest.fixture(params=TREES, ids=[t[0] for t in TREES])
def tree(request):
    return random_tree(**request.param[1])


def test_transforms_match_pinocchio(tree):
    pm = PinModel(tree)
    q, _, _ = random_states(tree, 5, seed=10)
    T = Model(tree).transforms(q)
    for s in range(q.shape[0]):
        assert rel(T[s], pm.placements(q[s])) < 1e-12


def test_inverse_dynamics_matches_pinocchio(tree):
    q, qd, qdd = random_states(tree, 20, seed=11)
    tau = Model(tree).inverse_dynamics(q, qd, qdd, backend=ENGINE)
    assert rel(tau, PinModel(tree).rnea(q, qd, qdd)) < 1e-9


def test_regressor_matches_pinocchio(tree):
    """Columns of moving frames equal Pinocchio's regressor; fixed frames' columns, which Pinocchio
    folds into their parent joint, are checked through rnea with only that body (10 random inertias
    span its 10 parameters)."""
    pm = PinModel(tree)
    q, qd, qdd = random_states(tree, 6, seed=12)
    W = Model(tree).regressor(q, qd, qdd, backend=ENGINE)
    names = tree.parameter_names
    moving_cols = [names.index(f"XX{j}") + i for j in pm.moving for i in range(10)]
    for s in range(q.shape[0]):
        Wp = pm.regressor(q[s], qd[s], qdd[s])
        assert rel(W[s][np.ix_(pm.cols, moving_cols)], Wp) < 1e-9
    rng = np.random.default_rng(0)
    for f in tree.frames:
        if f.sigma != 2:
            continue
        cols = [names.index(f"XX{f.j}") + i for i in range(10)]
        for _ in range(10):
            x = random_inertia(rng)
            X = np.zeros(tree.p)
            X[cols] = x
            tau_pin = PinModel(tree, X, only_link=f.j).rnea(q, qd, qdd)
            assert rel(W[:, :, cols] @ x, tau_pin) < 1e-9


SHIPPED = {
    "puma560": lambda: rigid(load_model("puma560").tree),
    "tx40": lambda: rigid(load_model("tx40").tree),
    "floating_tree": lambda: rigid(load_model("floating_tree").tree),
    "car": lambda: rigid(car_template()),
}


@pytest.mark.parametrize("name", list(SHIPPED))
def test_shipped_models_match_pinocchio(name):
    """The shipped examples and the car's template, inverse dynamics and regressor times parameters."""
    tree = SHIPPED[name]()
    q, qd, qdd = random_states(tree, 10, seed=3)
    m = Model(tree)
    tau = PinModel(tree).rnea(q, qd, qdd)
    assert rel(m.inverse_dynamics(q, qd, qdd, backend=ENGINE), tau) < 1e-10
    assert rel(m.regressor(q, qd, qdd, backend=ENGINE) @ tree.parameters, tau) < 1e-10


def test_inertia_matrix_matches_pinocchio(tree):
    """Columns of M are Pinocchio's rnea for qd = 0, qdd = e_i, no gravity (its crba assumes joints
    numbered depth-first, which a branched MDH tree need not be)."""
    pm = PinModel(tree)
    pm.model.gravity = pin.Motion.Zero()
    q, _, _ = random_states(tree, 3, seed=13)
    M = Model(tree).inertia_matrix(q, backend=ENGINE)
    c = pm.cols
    eye = np.eye(len(c))
    for s in range(q.shape[0]):
        Mp = np.stack([pin.rnea(pm.model, pm.data, q[s, c], 0 * eye[i], eye[i]) for i in range(len(c))], axis=1)
        assert rel(M[s][np.ix_(c, c)], Mp) < 1e-10


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_far_from_origin_keeps_precision(backend):
    """A floating tree 5 km from the origin gives the same torques and regressor as at the origin (translation
    invariance), in either engine."""
    tree = random_tree(seed=7, n=20, floating=True)
    q, qd, qdd = random_states(tree, 10, seed=1)
    far = q.copy()
    far[:, :3] += 5000.0
    m = Model(tree)
    tau, W = (m.inverse_dynamics, m.regressor)
    assert rel(tau(far, qd, qdd, backend=backend), tau(q, qd, qdd, backend=backend)) < 1e-11
    assert rel(W(far, qd, qdd, backend=backend), W(q, qd, qdd, backend=backend)) < 1e-11
