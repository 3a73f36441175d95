"""`CarResidual`: the car equations' residual Y − W x, summed without forming Y and W apart (what the sensor offsets'
columns need for each moved trajectory, pipeline.car.car_moved_rows with x).

Oracles: the equations built by `car_identification` (W and Y apart, the known parameters' part of Y by its own
product), their Y − W x with x drawn at random; and the physics: with the true parameters and the wheel wrenches that
make the motion (test_vehicle.required_wrenches), the residual vanishes to round-off. On the engine's regressor and
the generated one, with the aerodynamic wrench, known parameters and a tree with load terms (a column of W built from
the measured wrench).

Tolerance: each side rounds a sum of at most 48 + 16 products of |W| |x| and Y at ε each: 1e-13 of
max(|Y| + |W| |x|) (ε times the terms, 64 of them, with room for the pairwise and sequential orders).
"""

import numpy as np
import pytest
from test_tire_lateral_force import _states, _tree
from test_vehicle import driving, required_wrenches

from dynid.dynamics import Model
from dynid.model.tree import ModelError
from dynid.symbolic.generated import GeneratedRegressor
from dynid.vehicle import CarResidual, aero_wrench, car_identification, truth
from dynid.vehicle.car_model import car_template
from dynid.vehicle.template import DAMPERS, WHEELS


def _regressor(tree, engine):
    return GeneratedRegressor(tree) if engine == "generated" else None


def _compare(model, q, qd, qdd, ww, aw, engine, base="generic", seed=0):
    eq = car_identification(model, q, qd, qdd, ww, aw, base=base, regressor=_regressor(model.tree, engine))
    x = np.random.default_rng(seed).normal(size=len(eq.names)) * 10.0
    per_sample = np.asarray(eq.per_sample)
    expected = eq.Y.reshape(len(eq.rows), -1).T - np.einsum("nrp,p->nr", per_sample, x)
    got = CarResidual(model, x, base, _regressor(model.tree, engine))(q, qd, qdd, ww, aw)
    scale = (np.abs(eq.Y).max() + np.einsum("nrp,p->nr", np.abs(per_sample), np.abs(x)).max())
    assert got.shape == expected.shape
    assert np.abs(got - expected).max() <= 1e-13 * scale
    assert np.abs(expected).max() > 1e-3 * scale  # x is not a solution: the residual is far above round-off


@pytest.mark.parametrize("engine", ["numpy", "generated"])
def test_equals_car_identifications_y_minus_w_x(engine):
    model = Model(car_template(None, truth().values).with_known({f"YY{w}" for w in WHEELS} | {"kt15"}))
    rng = np.random.default_rng(4)
    q, qd, qdd = driving(model, rng, N=30)
    ww = rng.normal(size=(30, 4, 6)) * np.array([2e3, 3e3, 4e3, 50.0, 50.0, 50.0])
    aw = aero_wrench(model, q, qd)
    _compare(model, q, qd, qdd, ww, aw, engine)
    _compare(model, q, qd, qdd, ww, None, engine, base="car", seed=1)


@pytest.mark.parametrize("engine", ["numpy", "generated"])
def test_equals_car_identifications_with_load_terms(engine):
    tree = _tree()
    assert tree.load_terms
    q, qd, qdd, ww = _states(tree)
    _compare(Model(tree), q, qd, qdd, ww, None, engine)


@pytest.mark.parametrize("engine", ["numpy", "generated"])
def test_equals_car_identifications_with_damper_curves_on_every_piece(engine):
    """The live entries CarResidual sums over come from random states: a damper curve's slope columns are zero
    wherever the rate is off their piece, so a data set whose rates visit every piece (the knees well inside the
    driving rates) must find them all."""
    rng = np.random.default_rng(5)
    q, qd, qdd = driving(Model(car_template(None, truth().values)), rng, N=60)  # the knees leave the rest state
    # knees at a third of each damper's largest rates: every piece of every curve visited (one without its knee)
    knees = {d: (-np.inf if d == 36 else qd[:, d - 1].min() / 3, qd[:, d - 1].max() / 3) for d in DAMPERS}
    model = Model(car_template(None, truth().values, damper_knees=knees))
    ww = rng.normal(size=(60, 4, 6)) * np.array([2e3, 3e3, 4e3, 50.0, 50.0, 50.0])
    _compare(model, q, qd, qdd, ww, aero_wrench(model, q, qd), engine)


@pytest.mark.parametrize("engine", ["numpy", "generated"])
def test_vanishes_at_the_true_parameters_with_the_wrenches_of_the_motion(engine):
    model = Model(car_template(None, truth().values))
    rng = np.random.default_rng(0)
    q, qd, qdd = driving(model, rng)
    aw = aero_wrench(model, q, qd)
    F, q = required_wrenches(model, q, qd, qdd, [aw], rng)
    eq = car_identification(model, q, qd, qdd, F, aw)
    x = eq.base.values(model.tree.parameters)
    r = CarResidual(model, x, regressor=_regressor(model.tree, engine))(q, qd, qdd, F, aw)
    # the scale of the terms that cancel (the wrenches' generalized forces): test_vehicle.assert_round_off's
    scale = np.abs(eq.Y).max() + 100.0
    assert np.abs(r).max() <= 1e-9 * scale


def test_x_of_another_length_is_refused():
    model = Model(car_template(None, truth().values))
    with pytest.raises(ModelError, match="one value per base parameter"):
        CarResidual(model, np.zeros(3))
