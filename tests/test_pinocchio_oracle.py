"""Transforms, inverse dynamics and regressor against Pinocchio (an independent C++ library).

Random trees up to 42 frames: branches, revolute, prismatic and fixed frames, non-zero
gamma and b, a virtual floating-base chain, random physical inertias, random gravity.
"""

import dataclasses

import numpy as np
import pytest
from oracles import PinModel, random_inertia, random_states, random_tree

from dynid import Model, load_model
from dynid.model import INERTIAL

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
    tau = Model(tree).inverse_dynamics(q, qd, qdd)
    assert rel(tau, PinModel(tree).rnea(q, qd, qdd)) < 1e-9


def test_regressor_matches_pinocchio(tree):
    """Columns of moving frames equal Pinocchio's regressor; fixed frames' columns, which Pinocchio
    folds into their parent joint, are checked through rnea with only that body (10 random inertias
    span its 10 parameters)."""
    pm = PinModel(tree)
    q, qd, qdd = random_states(tree, 6, seed=12)
    W = Model(tree).regressor(q, qd, qdd)
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


@pytest.mark.parametrize("name", ["puma560", "tx40"])
def test_examples_match_pinocchio(name):
    """The shipped examples with their joint terms and couplings removed (Pinocchio has none)."""
    full = load_model(name).tree
    rigid = {k: v for k, v in full.values.items() if k.rstrip("0123456789") in INERTIAL}
    tree = dataclasses.replace(full, couplings=(), joint_terms={}, values=rigid)
    q, qd, qdd = random_states(tree, 10, seed=3)
    assert rel(Model(tree).inverse_dynamics(q, qd, qdd), PinModel(tree).rnea(q, qd, qdd)) < 1e-10


def test_far_from_origin_keeps_precision():
    """A floating tree 5 km from the origin gives the same torques as at the origin (translation invariance)."""
    tree = random_tree(seed=7, n=20, floating=True)
    q, qd, qdd = random_states(tree, 10, seed=1)
    far = q.copy()
    far[:, :3] += 5000.0
    m = Model(tree)
    assert rel(m.inverse_dynamics(far, qd, qdd), m.inverse_dynamics(q, qd, qdd)) < 1e-11
    assert rel(m.regressor(far, qd, qdd), m.regressor(q, qd, qdd)) < 1e-11
