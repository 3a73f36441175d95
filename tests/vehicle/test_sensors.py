"""The sensor suite (dynid.vehicle.sensors): contract, error model, ideal channels.
Oracles: the paper's Table 1 numbers, sample statistics, the engine's Jacobian at a point."""

from __future__ import annotations

import numpy as np
import pytest

from dynid import Model
from dynid.vehicle import car_template, rest_state, truth
from dynid.vehicle.geometry import demo_geometry
from dynid.vehicle.sensors import (
    CORNER_TAGS,
    SensorChannel,
    SensorSuite,
    channel_names,
    correvit_point,
    ideal_channels,
    paper_suite,
)


def test_contract_names_units_and_table1():
    s = paper_suite()
    names = s.names
    for n in ("imu_yaw_rate", "imu_pitch_rate", "imu_roll_rate", "imu_ax", "imu_ay", "imu_az", "imu_roll",
              "imu_pitch", "correvit_vx", "correvit_vy", "steering_wheel"):
        assert n in names
    for c in CORNER_TAGS:
        for pre in ("laser_height", "clearance", "steer", "camber", "wheel_speed", "spin_torque"):
            assert f"{pre}_{c}" in names
        for a in ("Fx", "Fy", "Fz", "Mx", "My", "Mz"):
            assert f"wft_{c}_{a}" in names
    u = s.units
    assert (u["imu_yaw_rate"], u["imu_ay"], u["imu_roll"], u["correvit_vx"], u["correvit_vy"]) == \
        ("deg/s", "m/s^2", "deg", "km/h", "m/s")
    assert (u["laser_height_rl"], u["clearance_fr"], u["steer_fl"], u["wheel_speed_rr"], u["wft_rl_Mz"]) == \
        ("mm", "mm", "deg", "rev/s", "N.m")
    # Table 1
    assert (s["imu_ay"].accuracy, s["imu_ax"].accuracy, s["imu_az"].accuracy) == (0.1, 0.02, 0.02)
    assert (s["imu_yaw_rate"].bandwidth, s["imu_roll"].bandwidth, s["steer_fl"].bandwidth) == (10.0, 5.0, 30.0)
    assert s["clearance_rl"].resolution == 0.062 and s["camber_fr"].accuracy == 0.042
    assert s["wft_fr_Fz"].range == (-20000.0, 20000.0) and s["wft_fr_Fz"].accuracy == 25.0
    assert s["correvit_vy"].accuracy == 0.075 and s["correvit_vx"].accuracy == 1.0
    assert len(channel_names(truth=True)) == len(names) + 3 * 42 + 24


def test_error_model_statistics():
    c = SensorChannel("x", "m/s^2", "test", "test", "x", accuracy=0.1, bandwidth=None, resolution=0.0,
                      range=None, rate=625.0, bias=0.0)
    s = SensorSuite((c,))
    y = s.measure({"x": np.zeros(200_000)}, 1)["x"]
    assert np.std(y) == pytest.approx(0.1, rel=0.01)  # accuracy taken as 1 sigma
    assert np.array_equal(y, s.measure({"x": np.zeros(200_000)}, 1)["x"])  # seeded
    q = SensorSuite((SensorChannel("x", "-", "t", "t", "x", 0.0, None, 0.5, (-1.0, 1.0), 125.0),))
    ramp = np.linspace(-3, 3, 625)
    out = q.measure({"x": ramp}, 0)["x"]
    assert set(np.unique(out)) <= {-1.0, -0.5, 0.0, 0.5, 1.0}  # quantised, saturated
    assert all(len(set(out[i:i + 5])) == 1 for i in range(0, 620, 5))  # held for 5 acquisition samples


def test_lowpass_has_the_stated_bandwidth():
    s = paper_suite()
    c = s["imu_ay"].__class__("x", "-", "t", "t", "x", 0.0, 10.0, 0.0, None, 625.0)
    t = np.arange(20000) / 625.0
    y = SensorSuite((c,)).measure({"x": np.sin(2 * np.pi * 10.0 * t)}, 0, noise=False)["x"]
    assert np.max(np.abs(y[5000:])) == pytest.approx(1 / np.sqrt(2), rel=0.02)  # -3 dB at the bandwidth


def test_ideal_channels_at_rest_and_moving():
    tree = car_template(values=truth().values)
    rest = rest_state(tree)
    m = Model(tree)
    rng = np.random.default_rng(2)
    N = 4
    q = np.tile(rest.q, (N, 1))
    qd = rng.normal(size=(N, 42)) * 0.2
    qdd = rng.normal(size=(N, 42)) * 0.2
    ww = np.zeros((N, 4, 6))
    ch = ideal_channels(m, q, np.zeros_like(q), np.zeros_like(q), ww, np.zeros(N), np.zeros((N, 4)))
    assert ch["imu_az"] == pytest.approx(9.81, abs=1e-3)
    assert np.degrees(-rest.q[4]) == pytest.approx(ch["imu_pitch"][0], abs=1e-9)  # ISO pitch: nose down > 0
    assert ch["laser_height_fl"][0] == pytest.approx(1e3 * (rest.q[2] - 0.0), abs=5.0)
    ch = ideal_channels(m, q, qd, qdd, ww, np.zeros(N), np.zeros((N, 4)))
    J = m.jacobian(q, 6, point=correvit_point(demo_geometry()), expressed_in=6)
    v = np.einsum("nij,nj->ni", J[:, :3], qd)  # frame 6: up, right, forward
    assert np.allclose(ch["correvit_vx"], 3.6 * v[:, 2]) and np.allclose(ch["correvit_vy"], -v[:, 1])


@pytest.mark.parametrize("bandwidth", [5.0, 10.0, 30.0, 150.0, 200.0])
def test_lowpass_is_scipys_butterworth_started_in_steady_state(bandwidth):
    """The band limit (closed-form design, FFT convolution) is scipy's butter(2) + lfilter from the
    steady state at x[0], to round-off, on a signal that starts far from zero."""
    from scipy.signal import butter, lfilter, lfilter_zi

    from dynid.vehicle.sensors import lowpass

    x = 50.0 + np.cumsum(np.random.default_rng(4).normal(size=7001))
    b, a = butter(2, bandwidth / 312.5)
    ref, _ = lfilter(b, a, x, zi=lfilter_zi(b, a) * x[0])
    assert np.abs(lowpass(x, bandwidth, 625.0) - ref).max() < 1e-11 * np.abs(x).max()


def test_fast_fft_length_is_the_next_5_smooth_number():
    from dynid.vehicle.sensors import _fast_length

    def smooth(m: int) -> bool:
        for p in (2, 3, 5):
            while m % p == 0:
                m //= p
        return m == 1

    for n in [*range(1, 400), 12501 + 1100, 2_250_001]:
        m = n
        while not smooth(m):
            m += 1
        assert _fast_length(n) == m, n
