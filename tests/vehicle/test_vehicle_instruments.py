"""Instruments for IDIM-IV on the car (`vehicle.instruments`).

Oracles: the simulator's truth (the full 42-frame car integrated with its own tire model: an
independent model of the same physics), and a closed-form check that the clearance channels' noise
does not reach the simulated suspensions.
"""

from __future__ import annotations

import numpy as np
import pytest

from dynid.model import ModelError
from dynid.vehicle.instruments import suspension_loads, suspension_response
from dynid.vehicle.template import DAMPERS

COLS = np.array(DAMPERS) - 1


@pytest.fixture(scope="module")
def sine():
    from dynid.vehicle.sim import CarSimulator

    run = CarSimulator().run("sine", duration=6.0)
    return run, run.identification(spin=False)


def test_simulated_suspensions_give_the_true_clearances_back(sine):
    """Driven by the loads of the true trajectory with the true parameters, the suspensions' equation gives the
    simulator's clearances and rates back. Both integrate the same smooth friction law by RK4 at 1.6 ms, one
    corner by corner, the other the whole car: the gap is the two integrations' truncation error, micrometres at
    most against 24 mm of travel (an error in the load, e.g. the wheel mass's own acceleration left in it,
    moves it by 0.17 mm)."""
    run, eq = sine
    values = dict(run.tree.values)
    load = suspension_loads(run.tree, eq, values, run.qdd)
    q, qd, _ = suspension_response(run.tree, values, run.time, load, run.time, run.q[0, COLS], run.qd[0, COLS])
    np.testing.assert_allclose(q, run.q[:, COLS], atol=1e-6)
    np.testing.assert_allclose(qd, run.qd[:, COLS], atol=1e-4)  # 0.1 mm/s against 80 mm/s
    # from loads known only every tenth sample (the pipeline's coarse rate), through the cubic spline
    q10, _, _ = suspension_response(run.tree, values, run.time[::10], load[::10], run.time, run.q[0, COLS],
                                    run.qd[0, COLS])
    np.testing.assert_allclose(q10, run.q[:, COLS], atol=2e-5)


def test_clearance_noise_does_not_reach_the_instruments(sine):
    """White noise of 1 mm on the clearances (the cameras' accuracy, Table 1), filtered as the pipeline does,
    moves the measured clearances by its full amount; the simulated ones, driven by the loads, by under 2 % of it
    (what remains enters through the wheel wrench's projection, whose geometry follows the clearance)."""
    from dynid.dynamics import Model
    from dynid.signals import filtered_derivatives
    from dynid.vehicle import car_identification

    run, eq = sine
    values = dict(run.tree.values)
    rng = np.random.default_rng(7)
    fs = 1 / (run.time[1] - run.time[0])
    noise = rng.standard_normal((len(run.time), 4)) * 1e-3
    n, nd, ndd = filtered_derivatives(noise, fs, 4.0, order=4, nderiv=2)
    q, qd, qdd = run.q.copy(), run.qd.copy(), run.qdd.copy()
    q[:, COLS] += n
    qd[:, COLS] += nd
    qdd[:, COLS] += ndd
    noisy = car_identification(Model(run.tree), q, qd, qdd, run.wheel_wrenches, run.aero_wrench())
    clean_load = suspension_loads(run.tree, eq, values, run.qdd)
    noisy_load = suspension_loads(run.tree, noisy, values, qdd)
    args = (run.tree, values, run.time)
    clean, _, _ = suspension_response(*args, clean_load, run.time, run.q[0, COLS], run.qd[0, COLS])
    moved, _, _ = suspension_response(*args, noisy_load, run.time, run.q[0, COLS], run.qd[0, COLS])
    rms = np.sqrt(np.mean(n**2, axis=0))
    assert np.all(np.sqrt(np.mean((moved - clean) ** 2, axis=0)) < 0.02 * rms)


def test_bad_estimate_is_refused(sine):
    run, _ = sine
    values = {**run.tree.values, "FV27": -10.0}
    with pytest.raises(ModelError, match="damping > 0"):
        suspension_response(run.tree, values, run.time, np.zeros((len(run.time), 4)), run.time, np.zeros(4),
                            np.zeros(4))
