"""End-to-end identification of the car's parameters on trajectories with a known truth.

The wheel wrenches are those that make the paper's 14 equations hold for the truth set
(test_vehicle.required_wrenches: the engine's inverse dynamics, least-norm correction of
plausible tire forces), so on exact joint trajectories Gautier's weighted least squares must
give the truth back to round-off; through the sensor channels and the estimator (filtering,
integration, derivation), close to it.
"""

import warnings

import numpy as np
import pytest
from test_vehicle import driving, required_wrenches

import dynid
from dynid.estimation import EstimationWarning, wls
from dynid.pipeline.car import car_system
from dynid.pipeline.robot import GroupedSystem
from dynid.vehicle import car_identification, car_template
from dynid.vehicle import parameters as params
from dynid.vehicle.estimate import CarTrajectory


@pytest.fixture(scope="module")
def model():
    return dynid.Model(car_template(None, params.truth().values))


def test_noise_free_trajectories_give_the_truth_to_1e6(model):
    rng = np.random.default_rng(3)
    parts, base = [], None
    for _ in range(6):
        q, qd, qdd = driving(model, rng, N=120, steer=2.0)
        F, q = required_wrenches(model, q, qd, qdd, [], rng)
        eq = car_identification(model, q, qd, qdd, F)
        parts.append(GroupedSystem(eq.W, eq.Y, eq.groups, np.zeros(len(eq.Y))))
        base = eq.base
    sys = GroupedSystem.stack(parts)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EstimationWarning)  # noise-free groups: sigma floored, by design
        res = wls(sys.W, sys.Y, sys.groups, list(base.names))
    true = base.values(model.tree.parameters)
    rel = np.abs(res.values - true) / np.maximum(np.abs(true), 1e-3 * np.abs(true).max())
    assert rel.max() < 1e-6, dict(zip(base.names, rel, strict=True))


def test_parallel_decimation_keeps_the_exact_solution(model):
    """car_system filters and decimates W and Y alike: on exact data the solution is unchanged."""
    rng = np.random.default_rng(4)
    q, qd, qdd = driving(model, rng, N=600, steer=2.0)
    F, q = required_wrenches(model, q, qd, qdd, [], rng)
    fs = 600 / 2.0
    traj = CarTrajectory(np.arange(600) / fs, q, qd, qdd, F, None, np.zeros(600))
    sys, base = car_system(model, traj, fs, decimate=(5,))
    full, _ = car_system(model, traj, fs, decimate=())
    assert sys.W.shape[0] == full.W.shape[0] // 5
    true = base.values(model.tree.parameters)
    for s in (sys, full):
        assert np.abs(s.Y - s.W @ true).max() < 1e-8 * np.abs(s.Y).max()


def test_generated_regressor_gives_the_same_rows(model):
    """car_identification with generated code equals it with the engine (W, Y to round-off)."""
    from dynid.symbolic.generated import GeneratedRegressor

    rng = np.random.default_rng(5)
    q, qd, qdd = driving(model, rng, N=50, steer=2.0)
    F, q = required_wrenches(model, q, qd, qdd, [], rng)
    a = car_identification(model, q, qd, qdd, F)
    b = car_identification(model, q, qd, qdd, F, regressor=GeneratedRegressor(model.tree))
    assert np.allclose(a.W, b.W, rtol=1e-10, atol=1e-9) and np.allclose(a.Y, b.Y, rtol=1e-10, atol=1e-8)


@pytest.mark.parametrize("friction", ["sign", "tanh"])
def test_subsampling_before_the_regressor_matches_full_rate_decimation(model, friction):
    """With band-limited inputs, computing W on every 5th sample then decimating by 10 in parallel gives
    the rows that full-rate parallel decimation by (5, 10) gives (to the filters' difference, far below noise).
    The dry-friction columns, not band-limited, are built at the full rate on both paths: by the dampers' own law
    (a vehicle's `damper_friction`; tanh(qd / 5 cm/s) here, wide enough to differ from sign(qd) on most rows),
    as the engine does on the full-rate path."""
    from test_vehicle_estimate import FS, si, smooth_drive

    from dynid.vehicle import DAMPERS
    from dynid.vehicle.estimate import CarConditioning, estimate_joints

    if friction != "sign":
        model = dynid.Model(car_template(None, params.truth().values,
                                         damper_friction={d: (friction, 0.05) for d in DAMPERS}))

    _, _, _, _, _, _, channels = smooth_drive(duration=16.0)
    traj = estimate_joints(si(channels), FS, model, conditioning=CarConditioning(cutoff=4.0, compensate_delays=False))
    fast, _ = car_system(model, traj, FS, (5, 10), cutoff=4.0)
    full, _ = car_system(model, traj, FS, (5, 10))
    for g in set(full.groups):
        a, b = fast.W[fast.groups == g], full.W[full.groups == g]
        assert len(a) == len(b)
        k = len(b) // 10  # the two ends carry the decimation filters' transients, which differ between the paths
        assert np.abs(a[k:-k] - b[k:-k]).max() <= 2e-3 * np.abs(b).max() + 1e-9, g
