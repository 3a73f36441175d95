"""Tire characteristics (vehicle/tire_curves.py). Oracles: a Magic-Formula curve sampled with known noise
(the coefficients, and σ against the spread over seeds); closed-form slips and W-axis forces of a car translating
with its wheels steered or its body rolled; the MuJoCo car's tire law (../shared/data/mujoco-car/tire_truth.csv),
which dynid did not write, through `dynid identify`."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dynid.dynamics import Model
from dynid.pipeline.config import ConfigError, load_config
from dynid.vehicle import car_template
from dynid.vehicle.estimate import CarTrajectory
from dynid.vehicle.tire_curves import (
    TireCurveError,
    TireSamples,
    fit_lateral,
    fit_magic_formula,
    lateral_force,
    magic_formula,
    peak_slip,
    tire_samples,
)

TRUE = {"B": 10.0, "C": 1.4, "D": 4000.0, "E": -0.5}


def _mf_samples(seed: int, n: int = 300, noise: float = 40.0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = rng.uniform(-0.25, 0.25, n)
    return x, magic_formula(x, *TRUE.values()) + noise * rng.standard_normal(n)


def test_magic_formula_recovered_from_a_noisy_curve():
    """The four coefficients of a curve sampled to beyond its peak (|α| up to 14°, peak at 8.6°) with 1 % noise."""
    x, F = _mf_samples(0)
    fit = fit_magic_formula(x, F)
    for name, true in TRUE.items():
        assert fit.value(name) == pytest.approx(true, abs=4 * fit.sigma(name)), name
        assert fit.sigma(name) < 0.1 * max(abs(true), 1.0), name
    assert fit.tau == pytest.approx(1.0, abs=0.3)  # white noise: no correlation to widen σ by


def test_magic_formula_sigma_is_honest():
    """Monte-Carlo over 40 seeds: the RMS of (estimate - truth) / σ is within 0.5..2 for each coefficient."""
    z = {n: [] for n in TRUE}
    for seed in range(40):
        x, F = _mf_samples(100 + seed)
        fit = fit_magic_formula(x, F)
        for n, true in TRUE.items():
            z[n].append((fit.value(n) - true) / fit.sigma(n))
    for n, zs in z.items():
        rms = float(np.sqrt(np.mean(np.square(zs))))
        assert 0.5 <= rms <= 2.0, (n, rms)


def test_correlated_residuals_widen_sigma():
    """Noise low-passed over ~10 samples: σ widened by the residual's autocorrelation stays honest, where the
    white-noise formula would be ~3x too small. A fit that ends on a bound (E = 1: C and E trade when correlated
    noise bends the curve) has no σ and is said so (`at_bound`): at most 1 in 30 here, left out of the RMS."""
    from scipy.signal import butter, filtfilt

    b, a = butter(4, 0.1)
    z, bound = [], 0
    for seed in range(30):
        rng = np.random.default_rng(seed)
        x = np.sort(rng.uniform(-0.25, 0.25, 600))
        e = filtfilt(b, a, rng.standard_normal(600))
        F = magic_formula(x, *TRUE.values()) + 40.0 * e / e.std()
        fit = fit_magic_formula(x, F, runs=np.zeros(600))
        assert fit.tau > 3
        if fit.at_bound:
            bound += 1
            continue
        z += [(fit.value(n) - t) / fit.sigma(n) for n, t in TRUE.items()]
    assert bound <= 1
    assert 0.5 <= float(np.sqrt(np.mean(np.square(z)))) <= 2.0


def test_peak_slip_closed_form():
    """E = 0: the peak is where C atan(B x) = π/2, x = tan(π / 2C) / B."""
    assert peak_slip(10.0, 1.4, 0.0) == pytest.approx(math.tan(math.pi / 2.8) / 10.0, rel=1e-9)
    assert peak_slip(10.0, 1.0, 0.0) == math.inf


def _synthetic_axle(seed: int, alpha_max_deg: float, noise: float = 20.0) -> TireSamples:
    """Two wheels of one axle through a spiral-like sweep, their loads moving apart; the law of the MuJoCo tire."""
    rng = np.random.default_rng(seed)
    n = 400
    alpha = np.radians(np.r_[np.linspace(0, -alpha_max_deg, n), np.linspace(0, -alpha_max_deg, n)])
    ramp = np.r_[np.linspace(0, 1, n), np.linspace(0, 1, n)]
    fz = 3000 + np.r_[np.ones(n), -np.ones(n)] * 1800 * ramp
    p = {"k0": 21.84, "mu0": 1.049, "C": 1.3507, "E": 0.0, "Sh": 0.0, "pK2": 0.0, "pD2": 0.0}
    fy = lateral_force(p, 3000.0, alpha, fz) + noise * rng.standard_normal(2 * n)
    return TireSamples(np.full(2 * n, "spiral", dtype=object), np.r_[np.zeros(n), np.ones(n)],
                       np.r_[np.arange(n), np.arange(n)] * 0.05, alpha, np.zeros(2 * n), np.zeros(2 * n),
                       np.full(2 * n, 20.0), np.zeros(2 * n), fy, fz)


def test_lateral_curve_with_load_dependence():
    """The axle law (Magic Formula with load terms) recovers the cornering coefficient and the curve."""
    curve = fit_lateral(_synthetic_axle(1, 6.0))
    assert curve.magic and not curve.peak_reached
    k, sk = curve.stiffness(3000.0)
    assert k == pytest.approx(21.84 * 3000, rel=0.01) and sk > 0
    a = np.radians(np.linspace(-6, 0, 25))
    for fz in (1500.0, 3000.0, 4500.0):
        true = lateral_force({"k0": 21.84, "mu0": 1.049, "C": 1.3507, "E": 0.0}, 3000.0, a, np.full_like(a, fz))
        assert np.max(np.abs(curve.force(a, np.full_like(a, fz)) - true)) < 0.02 * np.max(np.abs(true))


def test_linear_range_gives_linear_law():
    """Slips within 1°: the data stay linear, no Magic Formula is claimed; the linear law is the curve's secant
    there (load and slip rise together in this sweep, so the load term takes part of the curvature: within 5 %)."""
    curve = fit_lateral(_synthetic_axle(2, 1.0))
    assert not curve.magic
    assert curve.stiffness(3000.0)[0] == pytest.approx(21.84 * 3000, rel=0.05)


def test_bad_input_one_line():
    with pytest.raises(TireCurveError, match="at least") as e:
        fit_magic_formula(np.zeros(5), np.zeros(5))
    assert "\n" not in str(e.value)
    with pytest.raises(TireCurveError, match="one length"):
        fit_magic_formula(np.zeros(30), np.zeros(31))


def test_config_option_checked(tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text('[model]\nvehicle = "peugeot406"\n[[tests]]\nname = "a"\nrole = "identify"\nfile = "a.csv"\n'
                   '[identification]\ntire_curves = "yes"\n')
    (tmp_path / "a.csv").write_text("t\n0\n")
    with pytest.raises(ConfigError, match="tire_curves") as e:
        load_config(cfg)
    assert "\n" not in str(e.value)


# ------------------------------------------------------------------------------------------- slip kinematics
def _translating(steer: float = 0.0, roll: float = 0.0, kappa: float = 0.0, V: float = 20.0, yaw: float = 0.3):
    """A car at yaw `yaw` moving straight ahead at V, front wheels steered `steer` (left > 0), body rolled `roll`
    (right side down), every wheel turning at V (1 - kappa) / R, each tire loaded by 1000 N along its own z and
    500 N along its own y."""
    model = Model(car_template())
    N = 3
    q, qd = np.zeros((N, 42)), np.zeros((N, 42))
    q[:, 3], q[:, 5] = yaw, roll
    qd[:, 0], qd[:, 1] = -V * math.sin(yaw), V * math.cos(yaw)  # forward at yaw 0 is y0
    for b in (25, 34):  # front corners' steering joints (b + 3 = 28, 37)
        q[:, b + 2] = steer
    R = 0.31
    for w in (14, 23, 32, 41):
        qd[:, w - 1] = V * (1 - kappa) / R
    ww = np.zeros((N, 4, 6))
    ww[:, :, 1], ww[:, :, 2] = 500.0, 1000.0
    traj = CarTrajectory(np.arange(N) * 0.01, q, qd, np.zeros_like(q), ww, None, np.zeros(N))
    return tire_samples(model, traj, "t", R)


def test_slip_angle_of_steered_wheels():
    """Front wheels steered δ to the left, the car moving straight: α = -δ on the front, 0 on the rear; forces
    unchanged (the W axes are the wheel's when nothing tilts)."""
    s = _translating(steer=math.radians(3.0))
    front, rear = np.isin(s.corner, (2, 3)), np.isin(s.corner, (0, 1))
    assert np.allclose(s.alpha[front], -math.radians(3.0), atol=1e-9)
    assert np.allclose(s.alpha[rear], 0.0, atol=1e-9)
    assert np.allclose(s.fy, 500.0) and np.allclose(s.fz, 1000.0)


def test_slip_ratio_and_rolled_body():
    """κ = (V - R ω) / V; a body roll φ tilts the wheels: in W axes Fy = 500 cos φ - 1000 sin φ, Fz = 1000 cos φ +
    500 sin φ, and the slip angle stays 0 (the wheel plane's line on the road is still the heading)."""
    phi = math.radians(4.0)
    s = _translating(roll=phi, kappa=0.02)
    assert np.allclose(s.kappa, 0.02, atol=1e-9)
    assert np.allclose(s.alpha, 0.0, atol=1e-9)
    assert np.allclose(np.abs(s.gamma), phi, atol=1e-9)
    assert np.allclose(s.fy, 500 * math.cos(phi) - 1000 * math.sin(phi), atol=1e-6)
    assert np.allclose(s.fz, 1000 * math.cos(phi) + 500 * math.sin(phi), atol=1e-6)
