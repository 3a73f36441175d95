"""Both engines against Pinocchio (an independent C++ library): transforms, inverse dynamics, regressor and inertia
matrix, for the compiled engine (backend="numba", the default) and the NumPy reference engine (backend="numpy"),
on the same trees. What Pinocchio does not model (joint terms, couplings, external wrenches, restricted rows and
columns) is compared between the two engines in test_compiled.py.

Random trees up to 42 frames: branches, revolute, prismatic and fixed frames, non-zero gamma and b, a virtual
floating-base chain, random physical inertias, random gravity; the shipped robots and the car's 42-frame template
without their joint terms and couplings.
"""


import numpy as np
import pytest
from oracles import PinModel, random_inertia, random_states, random_tree, rigid

from dynid import Model, load_model
from dynid.dynamics import compiled
from dynid.vehicle import car_template

pin = pytest.importorskip("pinocchio")

TREES = {
    "puma560": lambda: rigid(load_model("puma560").tree),
    "tx40": lambda: rigid(load_model("tx40").tree),
    "floating_tree": lambda: rigid(load_model("floating_tree").tree),
    "car": lambda: rigid(car_template()),
    "serial6": lambda: random_tree(seed=1, n=6, serial=True, fixed=False),
    "branched12": lambda: random_tree(seed=2, n=12),
    "floating20": lambda: random_tree(seed=3, n=20, floating=True),
    "branched42": lambda: random_tree(seed=4, n=42),
    "floating42": lambda: random_tree(seed=5, n=42, floating=True),
}
# the engines' own agreement with Pinocchio, relative to max(1, |tau|): the compiled engine's sums in the order of
# Pinocchio's recursion, the NumPy engine's batched einsum products in another (measured ~1e-13 both)
TOLERANCE = {"numba": 1e-10, "numpy": 1e-9}


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / max(1.0, np.abs(b).max()))


@pytest.fixture(params=list(TREES), scope="module")
def tree(request):
    return TREES[request.param]()


@pytest.fixture(params=list(TOLERANCE))
def engine(request) -> str:
    if request.param == "numba" and not compiled.HAVE_NUMBA:
        pytest.skip("numba is not installed")
    return request.param


def test_transforms_match_pinocchio(tree):
    pm = PinModel(tree)
    q, _, _ = random_states(tree, 5, seed=10)
    T = Model(tree).transforms(q)
    for s in range(q.shape[0]):
        assert rel(T[s], pm.placements(q[s])) < 1e-12


def test_inverse_dynamics_matches_pinocchio(tree, engine):
    q, qd, qdd = random_states(tree, 20, seed=11)
    tau = Model(tree).inverse_dynamics(q, qd, qdd, backend=engine)
    assert rel(tau, PinModel(tree).rnea(q, qd, qdd)) < TOLERANCE[engine]


def test_regressor_matches_pinocchio(tree, engine):
    """Columns of moving frames equal Pinocchio's regressor; fixed frames' columns, which Pinocchio folds into their
    parent joint, are checked through rnea with only that body (10 random inertias span its 10 parameters); and all
    columns at once through W X = rnea for random inertias X."""
    pm = PinModel(tree)
    q, qd, qdd = random_states(tree, 6, seed=12)
    W = Model(tree).regressor(q, qd, qdd, backend=engine)
    tol = TOLERANCE[engine]
    names = tree.parameter_names
    moving_cols = [names.index(f"XX{j}") + i for j in pm.moving for i in range(10)]
    for s in range(q.shape[0]):
        assert rel(W[s][np.ix_(pm.cols, moving_cols)], pm.regressor(q[s], qd[s], qdd[s])) < tol
    rng = np.random.default_rng(0)
    for f in tree.frames:
        if f.sigma != 2:
            continue
        cols = [names.index(f"XX{f.j}") + i for i in range(10)]
        for _ in range(10):
            x = random_inertia(rng)
            X = np.zeros(tree.p)
            X[cols] = x
            assert rel(W[:, :, cols] @ x, PinModel(tree, X, only_link=f.j).rnea(q, qd, qdd)) < tol
    X = np.zeros(tree.p)
    for f in tree.frames:
        X[names.index(f"XX{f.j}") : names.index(f"XX{f.j}") + 10] = random_inertia(rng)
    assert rel(W @ X, PinModel(tree, X).rnea(q, qd, qdd)) < tol


def test_inertia_matrix_matches_pinocchio(tree, engine):
    """Columns of M are Pinocchio's rnea for qd = 0, qdd = e_i, no gravity (its crba assumes joints
    numbered depth-first, which a branched MDH tree need not be)."""
    pm = PinModel(tree)
    pm.model.gravity = pin.Motion.Zero()
    q, _, _ = random_states(tree, 3, seed=13)
    M = Model(tree).inertia_matrix(q, backend=engine)
    c = pm.cols
    eye = np.eye(len(c))
    for s in range(q.shape[0]):
        Mp = np.stack([pin.rnea(pm.model, pm.data, q[s, c], 0 * eye[i], eye[i]) for i in range(len(c))], axis=1)
        assert rel(M[s][np.ix_(c, c)], Mp) < TOLERANCE[engine]


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
