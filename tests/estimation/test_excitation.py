"""Excitation design (dynid.estimation.excitation, `dynid excite`), each figure against an independent check:
the Fourier series evaluated here term by term, the condition numbers and the Monte-Carlo computed here from
the model's regressor, the derivatives by finite differences, the CSV through dynid.io's reader."""

from __future__ import annotations

import numpy as np
import pytest

import dynid
from dynid.cli.main import main
from dynid.estimation.excitation import (
    ExcitationError,
    FourierTrajectory,
    Limits,
    _Problem,
    design_excitation,
    expected_uncertainty,
)
from dynid.model.files import tree_from_dict

# fast settings: few harmonics, a coarse grid, one refined start (the defaults take ~20 s on the TX40)
FAST = dict(period=6.0, harmonics=5, samples=100, starts=6, optimise=1, maxiter=40, seed=0)
TX40_LIMITS = Limits(q_min=np.array([-2.5, -1.9, -2.2, -2.5, -1.9, -2.5]),
                     q_max=np.array([2.5, 1.9, 2.2, 2.5, 1.9, 2.5]),
                     qd_max=np.array([2.0, 2.0, 2.5, 3.0, 3.0, 4.0]),
                     qdd_max=np.array([6.0, 6.0, 8.0, 10.0, 10.0, 12.0]))
PLANAR_LIMITS = Limits(q_min=np.array([-2.0, -2.5]), q_max=np.array([2.0, 2.5]),
                       qd_max=np.array([2.0, 3.0]), qdd_max=np.array([8.0, 10.0]))


def planar_arm() -> dynid.Model:
    """Two revolute links in a vertical plane (gravity along -y of the base), with joint frictions."""
    data = {
        "name": "planar 2R",
        "gravity": [0.0, -9.81, 0.0],
        "frames": [[1, 0, 0, 0, 0, 0, 0.0, 0, 0], [2, 1, 0, 0, 0, 0, 0.5, 0, 0]],
        "parameters": {
            "1": {"ZZ": 0.4, "MX": 1.2, "M": 5.0, "FV": 2.0, "FS": 1.5},
            "2": {"ZZ": 0.15, "MX": 0.5, "MY": 0.05, "M": 2.0, "FV": 1.0, "FS": 0.8, "IA": 0.05},
        },
    }
    return dynid.Model(tree_from_dict(data))


# ---------------------------------------------------------------- independent evaluation and criterion


def series(C: np.ndarray, period: float, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Fourier series of Swevers et al. written out term by term: C rows [q0, a_1..a_L, b_1..b_L]."""
    L = (C.shape[1] - 1) // 2
    wf = 2 * np.pi / period
    q = np.tile(C[:, 0], (t.size, 1))
    qd, qdd = np.zeros_like(q), np.zeros_like(q)
    for j in range(C.shape[0]):
        for l in range(1, L + 1):
            a, b, w = C[j, l], C[j, L + l], wf * l
            q[:, j] += a / w * np.sin(w * t) - b / w * np.cos(w * t)
            qd[:, j] += a * np.cos(w * t) + b * np.sin(w * t)
            qdd[:, j] += -a * w * np.sin(w * t) + b * w * np.cos(w * t)
    return q, qd, qdd


def base_columns(model: dynid.Model) -> list[int]:
    return list(model.base_parameters().columns)


def criterion(model: dynid.Model, C: np.ndarray, period: float, samples: int, cols: list[int]) -> float:
    """cond of the base regressor stacked over one period, columns scaled to unit norm (exact sign(qd))."""
    t = np.arange(samples) * period / samples
    W = model.regressor(*series(C, period, t), cols=cols).reshape(-1, len(cols))
    s = np.linalg.svd(W / np.linalg.norm(W, axis=0), compute_uv=False)
    return s[0] / s[-1]


def random_within(limits: Limits, harmonics: int, period: float, rng: np.random.Generator) -> np.ndarray:
    """Standard normal coefficients about mid-range, oscillation scaled to touch the limits on a dense grid."""
    m = limits.q_min.size
    C = np.zeros((m, 1 + 2 * harmonics))
    C[:, 0] = (limits.q_min + limits.q_max) / 2
    C[:, 1:] = rng.standard_normal((m, 2 * harmonics))
    osc = C.copy()
    osc[:, 0] = 0
    q, qd, qdd = series(osc, period, np.linspace(0, period, 4000, endpoint=False))
    scale = min(np.min((limits.q_max - C[:, 0]) / np.abs(q).max(axis=0)),
                np.min(limits.qd_max / np.abs(qd).max(axis=0)), np.min(limits.qdd_max / np.abs(qdd).max(axis=0)))
    C[:, 1:] *= scale
    return C


@pytest.fixture(scope="module")
def tx40():
    model = dynid.load_model("tx40")
    return model, design_excitation(model, TX40_LIMITS, **FAST), base_columns(model)


@pytest.fixture(scope="module")
def planar():
    model = planar_arm()
    return model, design_excitation(model, PLANAR_LIMITS, **FAST), base_columns(model)


# ---------------------------------------------------------------- the design


@pytest.mark.parametrize("which, factor", [pytest.param("tx40", 5.0, marks=pytest.mark.slow), ("planar", 1.5)])
def test_optimised_condition_number_beats_random_fourier_trajectories(which, factor, request):
    """Against the median of five random Fourier trajectories scaled to touch the same limits (the strongest
    random baseline). The TX40 (60 base parameters) gains more than 5x. The planar arm's 11 base parameters
    are already well conditioned by any full-amplitude trajectory (cond ~5 with scaled columns, and cond >= 1):
    there the design gains ~1.7x, and 5x is out of reach."""
    model, design, cols = request.getfixturevalue(which)
    limits, T, L, N = design.limits, FAST["period"], FAST["harmonics"], FAST["samples"]
    rng = np.random.default_rng(1234)  # not the design's seed: other random trajectories
    random = [criterion(model, random_within(limits, L, T, rng), T, N, cols) for _ in range(5)]
    optimised = criterion(model, design.trajectory.coefficients(), T, N, cols)
    assert optimised == pytest.approx(design.cond, rel=1e-9)  # the reported figure is the exact one
    assert design.cond <= design.cond_start
    assert np.median(random) >= factor * optimised, (random, optimised)


@pytest.mark.parametrize("which", ["tx40", "planar"])
def test_limits_hold_on_a_grid_ten_times_denser(which, request):
    _, design, _ = request.getfixturevalue(which)
    lim, T = design.limits, FAST["period"]
    t = np.arange(10 * FAST["samples"]) * T / (10 * FAST["samples"])
    q, qd, qdd = series(design.trajectory.coefficients(), T, t)
    tol = 1e-9
    assert np.all(q <= lim.q_max + tol) and np.all(q >= lim.q_min - tol)
    assert np.all(np.abs(qd) <= lim.qd_max + tol) and np.all(np.abs(qdd) <= lim.qdd_max + tol)
    # and the design uses them: some limit is reached within 5 %
    use = max(np.max(np.abs(qd) / lim.qd_max), np.max(np.abs(qdd) / lim.qdd_max),
              np.max((q - lim.q_min) / (lim.q_max - lim.q_min)), np.max((lim.q_max - q) / (lim.q_max - lim.q_min)))
    assert use > 0.95
    # starts at rest (the default)
    assert np.allclose(qd[0], 0, atol=1e-9) and np.allclose(qdd[0], 0, atol=1e-9)


def test_series_matches_the_term_by_term_formula_finite_differences_and_is_periodic():
    rng = np.random.default_rng(3)
    C = rng.standard_normal((3, 9))
    traj = FourierTrajectory.from_coefficients(C, 4.0, joints=(1, 2, 4), n=4)
    t = rng.uniform(0, 4.0, 50)
    q, qd, qdd = traj.evaluate_joints(t)
    for mine, ref in zip((q, qd, qdd), series(C, 4.0, t), strict=True):
        np.testing.assert_allclose(mine, ref, rtol=1e-12, atol=1e-12)
    full = traj.evaluate(t)[0]
    assert np.all(full[:, 2] == 0) and np.array_equal(full[:, [0, 1, 3]], q)
    h = 1e-5  # central differences: error ~ h^2 * (w L)^3 ~ 1e-8
    qp, qdp, _ = traj.evaluate_joints(t + h)
    qm, qdm, _ = traj.evaluate_joints(t - h)
    np.testing.assert_allclose((qp - qm) / (2 * h), qd, atol=1e-7)
    np.testing.assert_allclose((qdp - qdm) / (2 * h), qdd, atol=1e-7)
    ends = [traj.evaluate_joints(np.array([x])) for x in (0.0, 4.0)]
    for a, b in zip(*ends, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-12)
    # the coefficients survive the TOML round trip exactly
    again = FourierTrajectory.from_toml(traj.to_toml({"cond": 1.5}), n=4)
    assert np.array_equal(again.coefficients(), C) and again.joints == (1, 2, 4)


def test_criterion_gradient_matches_finite_differences():
    """The analytic gradient (singular vectors, per-sample differences of W, smooth friction) used by SLSQP."""
    model = planar_arm()
    for scale in ("columns", "none"):
        pb = _Problem(model, PLANAR_LIMITS, 5.0, 3, 60, scale, 0.05, True, 0.0)
        z = pb.variables(pb.random_start(np.random.default_rng(0)))
        _, g = pb.log_cond_grad(z)
        eps = 1e-6
        fd = []
        for i in range(z.size):
            dz = np.zeros_like(z)
            dz[i] = eps
            fd.append((pb.log_cond_grad(z + dz)[0] - pb.log_cond_grad(z - dz)[0]) / (2 * eps))
        np.testing.assert_allclose(g, fd, rtol=1e-4, atol=1e-6 * np.abs(g).max())


def test_design_is_deterministic_for_a_seed(planar):
    model, design, _ = planar
    again = design_excitation(model, PLANAR_LIMITS, **FAST)
    assert np.array_equal(again.trajectory.coefficients(), design.trajectory.coefficients())


# ---------------------------------------------------------------- expected %sigma against a Monte-Carlo


@pytest.mark.slow
def test_expected_sigma_matches_a_monte_carlo_of_weighted_least_squares(tx40):
    """tau = W X_B + noise (sigma per joint) on the designed trajectory sampled at fs for two periods; 200
    weighted least-squares estimates. The relative standard error of a standard deviation estimated from
    200 draws is 1 / sqrt(2 * 199) = 5.0 %: every parameter's empirical std must be within 3 of those
    (15 %) of the closed form, and their mean ratio within 3 standard errors of 1."""
    model, design, cols = tx40
    fs, T = 40.0, FAST["period"]
    sigma = np.array([0.8, 0.8, 0.5, 0.3, 0.3, 0.2])
    u = expected_uncertainty(model, design.trajectory, sigma, fs, duration=2 * T)
    t = np.arange(round(2 * T * fs)) / fs  # both periods stacked explicitly here
    W = model.regressor(*series(design.trajectory.coefficients(), T, t), cols=cols)
    XB = model.base_parameters().values(model.parameters)
    rng = np.random.default_rng(2024)
    draws = 200
    tau = (W @ XB)[:, :, None] + sigma[None, :, None] * rng.standard_normal((t.size, 6, draws))
    A = (W / sigma[None, :, None]).reshape(-1, len(cols))
    Y = (tau / sigma[None, :, None]).reshape(-1, draws)
    est = np.linalg.lstsq(A, Y, rcond=None)[0]
    ratio = est.std(axis=1, ddof=1) / u.sigma
    se = 1 / np.sqrt(2 * (draws - 1))
    assert np.all(np.abs(ratio - 1) < 3 * se), ratio
    assert abs(ratio.mean() - 1) < 3 * se
    np.testing.assert_allclose(est.mean(axis=1), XB, atol=float(4 * u.sigma.max() / np.sqrt(draws)) + 1e-12)
    assert u.names == model.base_parameters().names and u.samples == t.size
    nz = u.values != 0
    np.testing.assert_allclose(u.percent[nz], 100 * u.sigma[nz] / np.abs(u.values[nz]))
    # a duration of no whole number of periods stacks its samples explicitly (no repetition): more samples of the
    # same trajectory never give a larger sigma. Compared with a shorter such duration, whose samples are a prefix of
    # these, to round-off (kappa(W) eps ~ 1e5 x 2.2e-16). Not with the whole periods' shortcut: the design starts
    # at rest, and its rest instant's Coulomb rows are sign(qd) of a +-1e-16 velocity that the CPU's rounding picks,
    # so the second period's first sample need not repeat the first's (it did not on one AMD EPYC: FV6 1.6e-4 up)
    odd = expected_uncertainty(model, design.trajectory, sigma, fs, duration=2 * T + 0.5)
    shorter = expected_uncertainty(model, design.trajectory, sigma, fs, duration=2 * T + 0.25)
    assert odd.samples == t.size + 20 and shorter.samples == t.size + 10
    assert np.all(odd.sigma <= shorter.sigma * (1 + 1e-9)) and np.any(odd.sigma < shorter.sigma * (1 - 1e-3))


# ---------------------------------------------------------------- the command line


def _model_file(tmp_path) -> str:
    path = tmp_path / "planar.toml"
    path.write_text('name = "planar 2R"\ngravity = [0.0, -9.81, 0.0]\n'
                    "frames = [[1, 0, 0, 0, 0, 0, 0.0, 0, 0], [2, 1, 0, 0, 0, 0, 0.5, 0, 0]]\n"
                    "[parameters.1]\nZZ = 0.4\nMX = 1.2\nM = 5.0\nFV = 2.0\nFS = 1.5\n"
                    "[parameters.2]\nZZ = 0.15\nMX = 0.5\nM = 2.0\nFV = 1.0\nFS = 0.8\n")
    return str(path)


CLI_FAST = ["--harmonics", "2", "--period", "4", "--samples", "60", "--starts", "3", "--refine", "1",
            "--maxiter", "20"]


def test_cli_writes_a_csv_dynid_reads_and_the_coefficients_that_reproduce_it(tmp_path, capsys):
    from dynid.io import read_recording

    limits = tmp_path / "limits.toml"
    limits.write_text("q_min = [-2.0, -2.5]\nq_max = [2.0, 2.5]\nqd_max = [2.0, 3.0]\nqdd_max = [8.0, 10.0]\n")
    out = tmp_path / "traj.csv"
    code = main(["excite", _model_file(tmp_path), "--out", str(out), "--limits", str(limits), "--fs", "50",
                 "--duration", "8", "--noise", "0.5,0.2", *CLI_FAST])
    printed = capsys.readouterr().out
    assert code == 0
    assert "optimised" in printed and "random starts" in printed and "%sigma" in printed
    rec = read_recording(out)
    assert sorted(rec.channels) == ["q1", "q2", "qd1", "qd2", "qdd1", "qdd2"]
    assert rec.channels["q1"].unit == "rad" and rec.channels["qdd2"].unit == "rad/s^2"
    t = rec.channels["q1"].time
    assert t.size == 400 and t[1] == pytest.approx(0.02)
    traj = FourierTrajectory.from_toml(out.with_suffix(".toml").read_text(), n=2)
    q, qd, qdd = series(traj.coefficients(), 4.0, t)
    for k, x in (("q", q), ("qd", qd), ("qdd", qdd)):
        for j in (1, 2):
            np.testing.assert_allclose(rec.channels[f"{k}{j}"].values, x[:, j - 1], rtol=1e-12, atol=1e-12)
    lim = Limits.from_toml(limits, 2)
    assert np.all(np.abs(qd) <= lim.qd_max + 1e-9) and np.all(q <= lim.q_max + 1e-9)


@pytest.mark.parametrize("content, message", [
    ("q_min = [-2.0, -2.5]\nq_max = [2.0, 2.5]\nqd_max = [2.0, 3.0]\n", "missing qdd_max"),
    ("q_min = [-2.0]\nq_max = [2.0, 2.5]\nqd_max = [2.0, 3.0]\nqdd_max = [8.0, 10.0]\n", "q_min has 1 values"),
    ("q_min = [-2.0, 3.0]\nq_max = [2.0, 2.5]\nqd_max = [2.0, 3.0]\nqdd_max = [8.0, 10.0]\n",
     "q_max must exceed q_min (joint 2"),
    ("q_min = [-2.0, -2.5]\nq_max = [2.0, 2.5]\nqd_max = [2.0, -3.0]\nqdd_max = [8.0, 10.0]\n",
     "qd_max must be positive"),
    ("q_min = [-2.0, -2.5]\nq_max = [2.0, 2.5]\nqd_max = [2.0, 3.0]\nqdd_mx = [8.0, 10.0]\n",
     "did you mean 'qdd_max'"),
    ("q_min = [-2.0, -2.5]\nq_max = [2.0, \"x\"]\nqd_max = [2.0, 3.0]\nqdd_max = [8.0, 10.0]\n",
     "q_max must be a list of numbers"),
    ("q_min = [-2.0, -2.5\n", "not valid TOML"),
])
def test_cli_bad_limits_file_is_one_line_and_writes_nothing(tmp_path, capsys, content, message):
    limits = tmp_path / "limits.toml"
    limits.write_text(content)
    out = tmp_path / "traj.csv"
    assert main(["excite", _model_file(tmp_path), "--out", str(out), "--limits", str(limits), *CLI_FAST]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("dynid: error: ") and "\n" not in err and message in err, err
    assert not out.exists() and not out.with_suffix(".toml").exists()


@pytest.mark.parametrize("args, message", [
    (["--limits", "missing.toml"], "cannot read the limits file"),
    (["--noise", "0.5,abc"], "--noise"),
    (["--noise", "0.1,0.2,0.3"], "one value or 2"),
    (["--period", "-1"], "--period must be a positive number"),
])
def test_cli_bad_options_are_one_line(tmp_path, capsys, args, message):
    out = tmp_path / "traj.csv"
    assert main(["excite", _model_file(tmp_path), "--out", str(out), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("dynid: error: ") and message in err[-1], err


def test_limits_for_the_wrong_number_of_joints_are_refused():
    with pytest.raises(ExcitationError, match="2 moving joints"):
        Limits.from_dict({"q_min": [-1.0], "q_max": [1.0], "qd_max": [1.0], "qdd_max": [1.0]}, 2)
    with pytest.raises(ExcitationError, match="limits are for 2 joints"):
        design_excitation(dynid.load_model("tx40"), PLANAR_LIMITS, **FAST)
