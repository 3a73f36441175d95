"""The measurement pipeline on the simulator's files (issue 6's oracles).

A sine-steer test is simulated once with the sensor suite (noise, biases, band limits) and the
noise-free truth channels; the file goes through the readers, the unit conversion and the
estimator, and the joint trajectories are compared with the truth channels. Bounds per
quantity follow from the sensors' accuracies (Table 1) and the 4 Hz filter: attitude within a
few tenths of a degree, clearances within a millimetre, their rates and accelerations within
the band-limited noise.
"""

import numpy as np
import pytest

import dynid
from dynid.io import read_recording, to_si, write_recording
from dynid.vehicle import car_template
from dynid.vehicle.estimate import CarConditioning, estimate_joints, required_channels

SECONDS = 10.0


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    from dynid.vehicle.sim import CarSimulator
    from dynid.vehicle.sim.recording import write_test

    folder = tmp_path_factory.mktemp("sim")
    result = CarSimulator().run("sine", duration=SECONDS)
    path, _ = write_test(result, folder / "sine.csv", seed=7, truth=True)
    return folder, path


def estimate_from(path):
    rec = read_recording(path)
    al = rec.aligned(required_channels())
    ch = {n: to_si(al[n], rec.channel(n).unit)[0] for n in required_channels()}
    fs = 1.0 / float(np.median(np.diff(al.t)))
    model = dynid.Model(car_template())
    return rec, estimate_joints(ch, fs, model, conditioning=CarConditioning(cutoff=4.0)), fs


def truth_on(rec, est, fs, kind, j):
    t = rec.channel(f"true_{kind}{j}")
    return np.interp(est.t, t.time - t.time[0], t.values)


@pytest.mark.parametrize("kind, joints, bound", [
    ("q", (5, 6), np.radians(0.3)),           # pitch, roll: inclinometers 0.1 deg, bias 0.05 deg
    ("qd", (4, 5, 6), np.radians(0.2)),       # body rates: gyros 0.01 deg/s, 10 Hz band, compensated
    ("q", (9, 18, 27, 36), 1.5e-3),           # damper clearances: camera 1 mm
    ("qd", (9, 18, 27, 36), 0.02),            # their rates after the 4 Hz filter, m/s
    ("q", (10, 28), np.radians(0.1)),         # steering: camera 0.033 deg
    ("qdd", (3,), 0.5),                       # vertical acceleration: inertial unit 0.02 m/s^2 + attitude
    ("qd", (14, 23, 32, 41), 0.1),            # wheel spin rates, rad/s
])
def test_estimated_joints_match_the_truth_channels(simulated, kind, joints, bound):
    _, path = simulated
    rec, est, fs = estimate_from(path)
    inner = slice(len(est.t) // 10, -len(est.t) // 10)  # away from the ends of the record
    for j in joints:
        got = getattr(est, kind)[inner, j - 1]
        true = truth_on(rec, est, fs, kind, j)[inner]
        assert np.abs(got - true).max() < bound, (kind, j, np.abs(got - true).max())


def test_ground_speed_and_horizontal_acceleration(simulated):
    """In the ground plane the estimate's axes start at the test's own heading: compare magnitudes."""
    _, path = simulated
    rec, est, fs = estimate_from(path)
    inner = slice(len(est.t) // 10, -len(est.t) // 10)
    for kind, bound in (("qd", 0.6), ("qdd", 0.5)):  # Correvit 1 km/h; inertial unit 0.1 m/s^2 + attitude
        got = np.hypot(getattr(est, kind)[inner, 0], getattr(est, kind)[inner, 1])
        true = np.hypot(truth_on(rec, est, fs, kind, 1)[inner], truth_on(rec, est, fs, kind, 2)[inner])
        assert np.abs(got - true).max() < bound, (kind, np.abs(got - true).max())


def test_the_same_test_in_three_formats_gives_the_same_trajectories(simulated):
    folder, path = simulated
    rec = read_recording(path)
    keep = [rec.channel(n) for n in required_channels()]
    outs = []
    for fmt in ("csv", "parquet", "mf4"):
        target = folder / f"copy.{fmt}"
        write_recording(type(rec).from_channels(keep), target)
        outs.append(estimate_from(target)[1])
    for other in outs[1:]:
        assert np.allclose(other.q, outs[0].q, atol=1e-12) and np.allclose(other.qdd, outs[0].qdd, atol=1e-9)
