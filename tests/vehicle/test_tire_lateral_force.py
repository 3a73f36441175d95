"""The progressive tire law's lateral-force term ([wheels] tire_lateral_force: kt q + ktq q² + off - ktfy Fy² q = Fz,
the Magic Formula's vertical stiffness falling with the lateral force, qFcy): a load term of the tree (model.tree),
whose column car_identification builds from the measured wrench in every engine the car rows use.

Oracles: the column built by hand from the trajectory and the wrenches (-Fy² q of the tire's own wheel, in its own
row only), and a least-squares fit of the tire rows of synthetic data whose vertical loads follow the law with known
coefficients (recovered to round-off: the rows are exact)."""

import numpy as np
import pytest

from dynid.dynamics import Model
from dynid.dynamics.base import random_states
from dynid.symbolic.generated import GeneratedRegressor
from dynid.vehicle.car_model import car_template
from dynid.vehicle.equations import car_identification
from dynid.vehicle.template import EQUATION_ROWS, TIRES

N = 40


def _tree(fy: bool = True):
    return car_template(tire_offsets=True, tire_law="progressive", tire_lateral_force=fy)


def _states(tree, seed: int = 3):
    q, qd, qdd = random_states(tree, N, seed=seed)
    rng = np.random.default_rng(seed)
    ww = rng.normal(size=(N, 4, 6)) * np.array([2e3, 3e3, 4e3, 50.0, 50.0, 50.0])
    return q, qd, qdd, ww


@pytest.mark.parametrize("engine", ["numpy", "generated"])
def test_the_column_is_minus_fy_squared_times_the_deflection_in_its_tire_row_only(engine):
    tree = _tree()
    q, qd, qdd, ww = _states(tree)
    eq = car_identification(Model(tree), q, qd, qdd, ww,
                            regressor=GeneratedRegressor(tree) if engine == "generated" else None)
    W = eq.per_sample  # (N, rows, p)
    for k, t in enumerate(TIRES):
        c = eq.names.index(f"KFY{t}")
        by_hand = np.zeros((N, len(eq.rows)))
        by_hand[:, eq.rows.index(t)] = -ww[:, k, 1] ** 2 * q[:, t - 1]
        np.testing.assert_array_equal(W[:, :, c], by_hand)
        assert eq.labels[c] == f"ktfy{t}"
    # the term adds columns and changes nothing else: every other column and Y are the progressive law's
    other = _tree(fy=False)
    plain = car_identification(Model(other), q, qd, qdd, ww,
                               regressor=GeneratedRegressor(other) if engine == "generated" else None)
    keep = [eq.names.index(n) for n in plain.names]
    np.testing.assert_array_equal(W[:, :, keep], plain.per_sample)
    np.testing.assert_array_equal(eq.Y, plain.Y)


def test_least_squares_recovers_the_coefficients_of_loads_made_with_the_law():
    tree = _tree()
    q, qd, qdd, ww = _states(tree, seed=5)
    rng = np.random.default_rng(7)
    law = {t: (rng.uniform(1.5e5, 2.5e5), rng.uniform(1e6, 5e6), rng.uniform(2e3, 4e3), rng.uniform(1e-3, 5e-3))
           for t in TIRES}  # kt, ktq, off, ktfy
    for k, t in enumerate(TIRES):
        kt, ktq, off, ktfy = law[t]
        x, fy = q[:, t - 1], ww[:, k, 1]
        ww[:, k, 2] = kt * x + ktq * x**2 + off - ktfy * fy**2 * x
    eq = car_identification(Model(tree), q, qd, qdd, ww)
    rows = len(EQUATION_ROWS)
    Y = eq.Y.reshape(rows, N)
    for t in TIRES:
        r = eq.rows.index(t)
        cols = [eq.names.index(f"{p}{t}") for p in ("K", "KQ", "OFF", "KFY")]
        other = np.delete(np.arange(len(eq.names)), cols)
        assert not eq.per_sample[:, r, other].any()  # the tire row has only its tire's parameters
        A = eq.per_sample[:, r, cols]
        norms = np.linalg.norm(A, axis=0)  # columns of unit norm: the fit's error is then cond(A / norms) x eps
        x = np.linalg.lstsq(A / norms, Y[r], rcond=None)[0] / norms
        cond = np.linalg.cond(A / norms)
        assert cond < 100  # random deflections and forces: the four columns are far from dependent
        # exact rows (Y is the load to round-off): each coefficient to cond x a few hundred eps of the loads' size
        err = np.abs(x - law[t]) * norms / np.linalg.norm(Y[r])
        assert err.max() < cond * 1e-13, (t, err, cond)


def test_without_the_progressive_law_the_option_is_refused():
    with pytest.raises(ValueError, match="progressive"):
        car_template(tire_offsets=True, tire_law="paper", tire_lateral_force=True)


def test_engines_give_a_load_term_no_column_of_their_own():
    """The engines hold no measured wrench: their column of a load term is 0 (model.tree), whichever engine."""
    tree = _tree()
    q, qd, qdd = random_states(tree, 5, seed=1)
    m = Model(tree)
    for backend in ("numpy", "numba"):
        W = m.regressor(q, qd, qdd, rows=list(TIRES), cols=[f"KFY{t}" for t in TIRES], backend=backend)
        assert not np.asarray(W).any()


def test_a_model_file_refuses_a_tree_with_load_terms():
    """A model file cannot say which measured wrench a load term reads: saving one is refused, not silently dropped."""
    from dynid.model.files import tree_to_toml
    from dynid.model.tree import ModelError

    with pytest.raises(ModelError, match="load terms on frames \\[15, 24, 33, 42\\]"):
        tree_to_toml(_tree())
    assert "KQ = " in tree_to_toml(_tree(fy=False))
