"""Tests of dynid.estimation against independent oracles.

Oracles: statsmodels OLS/WLS (estimates, standard errors, residual variance), numpy's SVD
(condition number), the chi-square law of a residual variance, and problems constructed so that
the answer is known (dependent columns, noise-free data, a parameter whose true value is 0).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest
import statsmodels.api as sm
from scipy import stats

import dynid.atomic
from dynid.estimation import (
    EstimationWarning,
    IdentificationError,
    Method,
    StreamingLS,
    check_rank,
    essential_parameters,
    group_noise,
    ols,
    poorly_identified,
    relative_errors,
    wls,
)

RTOL = 1e-10


def rel(a, b):
    """Largest relative difference between two arrays (b is the reference)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b) / np.abs(b)))


def well_conditioned(rng, m=240, p=6, noise=0.3):
    W = rng.normal(size=(m, p)) * np.array([1.0, 2.0, 0.5, 3.0, 1.5, 0.8])[:p]
    x = rng.uniform(1.0, 3.0, size=p) * rng.choice([-1.0, 1.0], size=p)
    Y = W @ x + noise * rng.normal(size=m)
    return W, Y, x, [f"P{k}" for k in range(p)]


def two_group_system(rng, n=(300, 300), sigma=(0.1, 10.0), p=3):
    """Rows of group "a" have noise sigma[0], rows of group "b" noise sigma[1]; both excite all columns."""
    x = np.arange(1.0, p + 1)
    W = rng.normal(size=(sum(n), p))
    noise = np.concatenate([sigma[0] * rng.normal(size=n[0]), sigma[1] * rng.normal(size=n[1])])
    groups = np.array(["a"] * n[0] + ["b"] * n[1])
    return W, W @ x + noise, groups, x, [f"P{k}" for k in range(p)]


# --------------------------------------------------------------------------- OLS
def test_ols_matches_statsmodels_estimates_std_and_residual_variance():
    W, Y, _, names = well_conditioned(np.random.default_rng(0))
    res = ols(W, Y, names)
    fit = sm.OLS(Y, W).fit()
    assert res.names == tuple(names) and res.method is Method.OLS
    assert rel(res.values, fit.params) < RTOL
    assert rel(res.std, fit.bse) < RTOL
    assert rel(res.residual.sigma**2, fit.scale) < RTOL
    assert rel(res.covariance, fit.cov_params()) < RTOL
    assert rel(res.rel_std_percent, 100 * fit.bse / np.abs(fit.params)) < RTOL
    assert res.residual.dof == W.shape[0] - W.shape[1]
    # condition number: numpy's SVD of W
    assert rel(res.condition_number, np.linalg.cond(W)) < 1e-8
    # relative residual: statsmodels' residuals
    assert rel(res.residual.relative_residual, np.linalg.norm(fit.resid) / np.linalg.norm(Y)) < RTOL


# --------------------------------------------------------------------------- WLS
def test_wls_with_given_weights_matches_statsmodels_wls():
    rng = np.random.default_rng(1)
    W, Y, _, names = well_conditioned(rng, m=300)
    groups = np.array(["chassis_x", "roll", "susp9"] * 100)
    sigmas = {"chassis_x": 0.1, "roll": 10.0, "susp9": 1.0}
    res = wls(W, Y, groups, names, group_sigmas=sigmas)
    row_sigma = np.array([sigmas[g] for g in groups])
    fit = sm.WLS(Y, W, weights=1.0 / row_sigma**2).fit()
    # statsmodels whitens rows by sqrt(weights) = 1/sigma_j, then its bse is
    # sqrt(scale * diag((W_p^T W_p)^-1)) with scale = ||Y_p - W_p X||^2 / (m - p), the variance of the
    # *weighted* residual. Paper eq. (10) solves the weighted system by LS and takes its standard
    # deviations the same way, so the two agree exactly (no rescaling needed), and the reported
    # residual sigma is sqrt(statsmodels' scale).
    assert rel(res.values, fit.params) < RTOL
    assert rel(res.std, fit.bse) < RTOL
    assert rel(res.residual.sigma**2, fit.scale) < RTOL
    assert res.weights == sigmas and res.method is Method.WLS


def test_group_sigmas_match_statsmodels_per_group_and_wls_follows():
    """sigma_j of eq. (8) = sqrt(scale) of statsmodels OLS on the group's own independent non-zero columns."""
    rng = np.random.default_rng(2)
    m1, m2 = 150, 120
    names = ["M6", "MX6", "ks9", "h9", "kt15"]
    W1 = rng.normal(size=(m1, 5))  # "chassis": excites every parameter
    W2 = np.zeros((m2, 5))  # "susp9": only M6, MX6 and ks9, and ks9's column = M6's + MX6's here
    W2[:, :2] = rng.normal(size=(m2, 2))
    W2[:, 2] = W2[:, 0] + W2[:, 1]
    W = np.vstack([W1, W2])
    x = np.array([2.0, -1.0, 3.0, 0.5, 4.0])
    Y = W @ x + np.concatenate([0.2 * rng.normal(size=m1), 3.0 * rng.normal(size=m2)])
    groups = np.array(["chassis"] * m1 + ["susp9"] * m2)

    fits = group_noise(W, Y, groups, names)
    s_chassis = np.sqrt(sm.OLS(Y[:m1], W1).fit().scale)
    s_susp = np.sqrt(sm.OLS(Y[m1:], W2[:, :2]).fit().scale)  # 2 independent columns span the group's 3
    assert rel(fits["chassis"].sigma, s_chassis) < RTOL
    assert rel(fits["susp9"].sigma, s_susp) < RTOL
    assert len(fits["susp9"].parameters) == 2 and set(fits["susp9"].parameters) <= {"M6", "MX6", "ks9"}
    assert fits["susp9"].n_rows == m2

    res = wls(W, Y, groups, names)
    row_sigma = np.where(groups == "chassis", s_chassis, s_susp)
    fit = sm.WLS(Y, W, weights=1.0 / row_sigma**2).fit()
    assert rel(res.values, fit.params) < RTOL
    assert rel(res.std, fit.bse) < RTOL
    assert rel(list(res.weights.values()), [s_chassis, s_susp]) < RTOL


def test_a_column_of_round_off_is_no_parameter_of_its_group():
    """A regressor term that cancels in exact arithmetic leaves round-off in its column (a TX40's ZZ2 in the
    joint-1 rows: 1e-19 of the largest column). sigma_j is then statsmodels OLS on the other columns, whatever the
    round-off's bits; scaled to unit norm it had passed for a parameter and fitted the noise (sigma_1 moved 0.1 %
    with the last bits of sin/cos)."""
    rng = np.random.default_rng(7)
    m = 200
    names = ["ZZ1", "FV1", "FS1", "ZZ2"]
    W = np.zeros((m, 4))
    W[:, :3] = rng.normal(scale=[500.0, 1.0, 1.0], size=(m, 3))
    Y = W[:, :3] @ [0.5, 2.0, 3.0] + rng.normal(size=m)
    s_ols = np.sqrt(sm.OLS(Y, W[:, :3]).fit().scale)
    for _ in range(3):  # three different round-offs, 1e-16 in absolute terms
        W[:, 3] = 1e-16 * rng.normal(size=m)
        fit = group_noise(W, Y, np.array(["joint1"] * m), names)["joint1"]
        assert rel(fit.sigma, s_ols) < RTOL
        assert fit.parameters == ("ZZ1", "FV1", "FS1")


def test_wls_recovers_group_noise_and_beats_ols():
    n, p, sigma = 300, 3, (0.1, 10.0)
    dof = n - p
    # (n_j - p_j) s_j^2 / sigma_j^2 ~ chi2(n_j - p_j) for Gaussian noise; two-sided bound at 1e-6.
    lo, hi = (np.sqrt(stats.chi2.ppf(q, dof) / dof) for q in (0.5e-6, 1 - 0.5e-6))
    for seed in range(5):
        W, Y, groups, x, names = two_group_system(np.random.default_rng(seed), (n, n), sigma, p)
        res_w = wls(W, Y, groups, names)
        res_o = ols(W, Y, names)
        for g, s in zip("ab", sigma, strict=True):
            assert lo * s <= res_w.weights[g] <= hi * s, (seed, g, res_w.weights[g])
        assert np.linalg.norm(res_w.values - x) < np.linalg.norm(res_o.values - x), seed
        assert abs(res_w.residual.sigma - 1.0) < 0.1  # weighted residual is ~ unit variance


def test_group_with_too_few_rows_is_named():
    rng = np.random.default_rng(3)
    W = rng.normal(size=(50, 3))
    groups = np.array(["chassis_x"] * 47 + ["tire15"] * 3)
    with pytest.raises(IdentificationError, match="tire15") as err:
        wls(W, rng.normal(size=50), groups, ["a", "b", "c"])
    assert err.value.group == "tire15"


def test_noise_free_wls_warns_and_is_exact():
    rng = np.random.default_rng(4)
    W, _, x, names = well_conditioned(rng)
    groups = np.array(["g1", "g2"] * (W.shape[0] // 2))
    with pytest.warns(EstimationWarning, match="noise-free"):
        res = wls(W, W @ x, groups, names)
    assert rel(res.values, x) < RTOL
    assert all(np.isfinite(list(res.weights.values()))) and min(res.weights.values()) > 0


# --------------------------------------------------------------------------- streaming
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_streaming_equals_batch(seed):
    rng = np.random.default_rng(seed)
    W, Y, _, names = well_conditioned(rng, m=400)
    groups = rng.choice(["chassis_z", "roll", "susp18"], size=W.shape[0])
    stream = StreamingLS(names)
    start = 0
    while start < W.shape[0]:
        size = int(rng.integers(0, 40))  # includes empty chunks and chunks shorter than p
        stream.add(W[start:start + size], Y[start:start + size], groups[start:start + size])
        start += size
    assert stream.n_rows == W.shape[0]

    s, b, fit = stream.solve(), ols(W, Y, names), sm.OLS(Y, W).fit()
    for got in (s.values, b.values):
        assert rel(got, fit.params) < RTOL
    assert rel(s.values, b.values) < RTOL
    assert rel(s.std, b.std) < RTOL and rel(s.std, fit.bse) < RTOL
    assert rel(s.covariance, b.covariance) < RTOL
    assert rel(s.residual.sigma, b.residual.sigma) < RTOL
    assert rel(s.residual.relative_residual, b.residual.relative_residual) < RTOL
    assert rel(s.condition_number, np.linalg.cond(W)) < 1e-8

    sw, bw = stream.solve_weighted(), wls(W, Y, groups, names)
    assert rel(sw.values, bw.values) < RTOL
    assert rel(sw.std, bw.std) < RTOL
    assert rel(list(sw.weights.values()), [bw.weights[g] for g in sw.weights]) < RTOL
    assert rel(list(stream.relative_errors(sw).values()),
               [relative_errors(W, Y, sw.values, groups)[g] for g in [*sw.weights, "overall"]]) < RTOL


# --------------------------------------------------------------------------- known parameters
def test_known_parameters_move_to_the_right_hand_side():
    rng = np.random.default_rng(5)
    W, Y, _, names = well_conditioned(rng)
    known = {"P2": 1.5, "P4": -0.7}
    free = [0, 1, 3, 5]
    Y_red = Y - W[:, [2, 4]] @ np.array([1.5, -0.7])
    fit = sm.OLS(Y_red, W[:, free]).fit()
    res = ols(W, Y, names, known=known)
    est = [res.index(names[k]) for k in free]
    assert rel(res.values[est], fit.params) < RTOL
    assert rel(res.std[est], fit.bse) < RTOL
    assert res.estimated_names == ("P0", "P1", "P3", "P5")
    assert res.value("P2") == 1.5 and res.value("P4") == -0.7
    assert res.flags[2] == res.flags[4] == "known" and np.isnan(res.std[2])

    groups = np.array(["a", "b", "c"] * (W.shape[0] // 3))
    sig = {"a": 0.5, "b": 2.0, "c": 1.0}
    row_sigma = np.array([sig[g] for g in groups])
    fit_w = sm.WLS(Y_red, W[:, free], weights=1 / row_sigma**2).fit()
    res_w = wls(W, Y, groups, names, known=known, group_sigmas=sig)
    assert rel(res_w.values[est], fit_w.params) < RTOL
    assert rel(res_w.std[est], fit_w.bse) < RTOL

    stream = StreamingLS(names, known=known)
    stream.add(W[:100], Y[:100])
    stream.add(W[100:], Y[100:])
    assert rel(stream.solve().values[est], fit.params) < RTOL


# --------------------------------------------------------------------------- rank
def test_rank_deficiency_names_exactly_the_dependent_and_zero_columns():
    rng = np.random.default_rng(6)
    W = rng.normal(size=(100, 6))
    W[:, 2] *= 1e-5  # small units, but independent: must not be blamed
    W[:, 3] = 2.0 * W[:, 0] - W[:, 1]
    W[:, 5] = 0.0
    names = ["a", "b", "c", "d", "e", "f"]
    Y = rng.normal(size=100)
    for call in (lambda: ols(W, Y, names), lambda: wls(W, Y, ["g"] * 100, names), lambda: check_rank(W, names)):
        with pytest.raises(IdentificationError) as err:
            call()
        assert err.value.parameters == ("d", "f")
        assert "known" in str(err.value) and "regroup" in str(err.value) and "excite" in str(err.value)
    assert err.value.relations["f"] == {}
    assert err.value.relations["d"] == pytest.approx({"a": 2.0, "b": -1.0}, rel=1e-9)
    stream = StreamingLS(names)
    stream.add(W, Y)
    with pytest.raises(IdentificationError) as err:
        stream.solve()
    assert err.value.parameters == ("d", "f")

    # fixing them as known makes the rest identifiable
    res = ols(W, Y, names, known={"d": 0.0, "f": 0.0})
    assert res.flags[3] == res.flags[5] == "known"

    # a scaled copy: the later parameter is named
    W2 = rng.normal(size=(60, 3))
    W2 = np.column_stack([W2, 1e6 * W2[:, 1]])
    with pytest.raises(IdentificationError) as err:
        ols(W2, rng.normal(size=60), ["w", "x", "y", "z"])
    assert err.value.parameters == ("z",)


# --------------------------------------------------------------------------- noise-free, flags
def test_noise_free_data_recover_x():
    rng = np.random.default_rng(7)
    W, _, x, names = well_conditioned(rng)
    W = W * np.array([1e-2, 1.0, 1e2, 1.0, 10.0, 0.1])  # mixed units
    res = ols(W, W @ x, names)
    assert rel(res.values, x) < RTOL
    stream = StreamingLS(names)
    stream.add(W, W @ x)
    assert rel(stream.solve().values, x) < RTOL


def test_parameter_with_tiny_excitation_is_flagged():
    rng = np.random.default_rng(8)
    m = 400
    W = rng.normal(size=(m, 4))
    W[:, 3] *= 1e-3  # barely excited: std(x3) ~ noise / (1e-3 sqrt(m)), ~1000x the others
    x = np.array([1.0, 2.0, -1.5, 1.0])
    Y = W @ x + 0.05 * rng.normal(size=m)
    res = ols(W, Y, ["a", "b", "c", "d"])
    assert res.flags == ("", "", "", "poor") and res.poor == ["d"]
    assert ols(W, Y, ["a", "b", "c", "d"], poor_factor=1e6).poor == []
    # the rule itself (paper §7.2): strictly more than factor x the smallest
    assert poorly_identified({"a": 0.5, "b": 10.0, "c": 10.5}) == ["c"]
    assert poorly_identified({"a": 0.5, "b": 1.6}, factor=3.0) == ["b"]


# --------------------------------------------------------------------------- essential parameters
def test_essential_path_removes_noise_level_parameter_first():
    rng = np.random.default_rng(9)
    m = 400
    W = rng.normal(size=(m, 5))
    x = np.array([1.0, 2.0, 3.0, 4.0, 0.0])  # "e" does not act: its estimate is noise
    Y = W @ x + 0.1 * rng.normal(size=m)
    ess = essential_parameters(W, Y, ["a", "b", "c", "d", "e"])
    assert ess.path[0].removed is None
    assert ess.path[1].removed == "e" and ess.path[1].accepted
    assert ess.removed == ("e",) and ess.names == ("a", "b", "c", "d")
    assert not ess.path[-1].accepted  # removing a real parameter blows the residual: the walk stops
    assert ess.path[-1].relative_residual > 1.03 * ess.path[0].relative_residual
    assert ess.result.names == ("a", "b", "c", "d")

    groups = np.array(["g1", "g2"] * (m // 2))
    ess_w = essential_parameters(W, Y, ["a", "b", "c", "d", "e"], groups=groups)
    assert ess_w.removed == ("e",) and ess_w.result.method is Method.WLS


# --------------------------------------------------------------------------- validation
def test_relative_errors_per_group():
    rng = np.random.default_rng(10)
    W = rng.normal(size=(30, 2))
    x = np.array([1.0, -2.0])
    Y = W @ x
    Y[20:] *= 2.0  # group "b": Y_b = 2 W_b x, so ||Y_b - W_b x|| / ||Y_b|| = 1/2
    groups = np.array(["a"] * 20 + ["b"] * 10)
    err = relative_errors(W, Y, {"p": 1.0, "q": -2.0}, groups, names=["p", "q"])
    assert err["a"] == pytest.approx(0.0, abs=1e-15)
    assert err["b"] == pytest.approx(0.5, rel=1e-14)
    expected = np.linalg.norm(W[20:] @ x) / np.linalg.norm(Y)
    assert err["overall"] == pytest.approx(expected, rel=1e-14)


# --------------------------------------------------------------------------- results object
def make_result():
    W, Y, _, names = well_conditioned(np.random.default_rng(11))
    groups = np.array(["chassis", "susp9"] * (W.shape[0] // 2))
    return wls(W, Y, groups, names, labels={"P0": "ks9"}, a_priori={"P0": 2.0}, truth={"P1": 1.0},
               known={"P5": 0.3})


def test_to_dict_schema_and_summary():
    res = make_result()
    d = res.to_dict()
    assert set(d) >= {"parameters", "validation", "condition_number", "weights"}
    assert d["validation"] == {"direct": {}, "cross": {}}
    assert set(d["weights"]) == {"chassis", "susp9"}
    p0, p5 = d["parameters"][0], d["parameters"][5]
    assert set(p0) == {"name", "label", "value", "std", "rel_std_percent", "a_priori", "truth", "flag", "paper_rule",
                       "scale"}
    assert p0["label"] == "ks9" and p0["a_priori"] == 2.0 and d["parameters"][1]["truth"] == 1.0
    assert p5 == {"name": "P5", "label": "P5", "value": 0.3, "std": None, "rel_std_percent": None,
                  "a_priori": None, "truth": None, "flag": "known", "paper_rule": "known", "scale": 0.3}
    text = res.summary()
    for word in ("WLS", "ks9", "a priori", "truth", "%std", "known", "chassis", "susp9"):
        assert word in text


def test_save_json_round_trip_and_atomic(tmp_path, monkeypatch):
    res = make_result()
    res.validation["direct"] = {"chassis": 0.01, "overall": float("nan")}
    target = tmp_path / "result.json"
    res.save_json(target)
    assert json.loads(target.read_text()) == res.to_dict()
    assert json.loads(target.read_text())["validation"]["direct"]["overall"] is None
    good = target.read_text()

    real_write_text = Path.write_text

    def broken_write(self, text, *args, **kw):
        real_write_text(self, text[: len(text) // 2], *args, **kw)  # half a file, then the disk "fails"
        raise OSError("disk full")

    monkeypatch.setattr(Path, "write_text", broken_write)
    with pytest.raises(OSError, match="disk full"):
        res.save_json(target)
    monkeypatch.undo()
    assert target.read_text() == good and os.listdir(tmp_path) == ["result.json"]

    def broken_replace(src, dst):
        raise OSError("rename failed")

    monkeypatch.setattr(dynid.atomic.os, "replace", broken_replace)
    with pytest.raises(OSError, match="rename failed"):
        res.save_json(tmp_path / "new.json")
    assert os.listdir(tmp_path) == ["result.json"]


def test_to_dataframe_and_missing_pandas(monkeypatch):
    res = make_result()
    df = res.to_dataframe()
    assert list(df.index) == list(res.names) and df.loc["P0", "label"] == "ks9"
    assert df.loc["P5", "flag"] == "known"
    monkeypatch.setitem(sys.modules, "pandas", None)  # makes `import pandas` raise ImportError
    with pytest.raises(ImportError, match="pandas"):
        res.to_dataframe()


def test_bad_input_is_reported():
    W = np.ones((10, 2))
    W[4, 1] = np.nan
    with pytest.raises(IdentificationError, match=r"row 4.*'b'"):
        ols(W, np.zeros(10), ["a", "b"])
    with pytest.raises(IdentificationError, match="not in names"):
        ols(np.eye(3), np.ones(3), ["a", "b", "c"], known={"z": 1.0})
    with pytest.raises(IdentificationError, match="more rows than parameters"):
        ols(np.eye(3), np.ones(3), ["a", "b", "c"])


# ---------------------------------------------------------------- sensor offsets (systematic uncertainty)


def _biased_system(b: np.ndarray, rng_seed: int = 5):
    """A two-group system built from two 'measured' signals u1, u2 whose zero offsets are b:
    W and Y depend on them nonlinearly, as the car's equations depend on their channels."""
    rng = np.random.default_rng(rng_seed)
    t = np.linspace(0.0, 10.0, 400)
    u1 = np.sin(1.3 * t) + b[0]
    u2 = np.cos(0.7 * t) + 0.3 * t / 10 + b[1]
    X = np.array([2.0, -1.0, 0.5, 3.0])
    Wa = np.column_stack([u1, u1 * u2, np.ones_like(t), np.zeros_like(t)])
    Wb = np.column_stack([np.zeros_like(t), u2 ** 2, np.sin(u1), u2])
    truth_a = np.column_stack([np.sin(1.3 * t), np.sin(1.3 * t) * np.cos(0.7 * t), np.ones_like(t), 0 * t]) @ X
    truth_b = np.column_stack([0 * t, (np.cos(0.7 * t) + 0.03 * t) ** 2, np.sin(np.sin(1.3 * t)),
                               np.cos(0.7 * t) + 0.03 * t]) @ X
    W = np.vstack([Wa, Wb])
    Y = np.concatenate([truth_a + 0.05 * rng.standard_normal(t.size) + 4.0 * b[0],
                        truth_b + 0.2 * rng.standard_normal(t.size)])
    groups = np.repeat(["a", "b"], t.size)
    return W, Y, groups


@pytest.mark.parametrize("weighted", [False, True])
def test_sensor_offsets_propagate_as_a_finite_difference_of_the_estimate(weighted):
    """ΔX for a one-σ offset equals the change of the least-squares estimate when the data are rebuilt
    with that offset (re-solved by numpy, same weights), to first order; the covariance is their sum."""
    names = ["a", "b", "c", "d"]
    sigma_b = np.array([0.02, 0.05])
    W0, Y0, g = _biased_system(np.zeros(2))
    s = StreamingLS(names, known={"c": 0.5})
    s.add(W0, Y0, g)
    res = s.solve_weighted() if weighted else s.solve()
    acc = s.bias_accumulator()
    eps = 1e-4  # the derivative by a small offset, scaled to one sigma
    for k in range(2):
        b = np.zeros(2)
        b[k] = eps * sigma_b[k]
        W1, Y1, _ = _biased_system(b)
        acc.add(f"u{k + 1}", W0, Y0, (W1 - W0) / eps, (Y1 - Y0) / eps, g)
    full = s.with_systematic(res, acc)
    w = np.array([1.0 / res.weights[x] if weighted else 1.0 for x in g])
    est = [0, 1, 3]

    def solve(W, Y):
        Ye = Y - W[:, 2] * 0.5
        return np.linalg.lstsq(W[:, est] * w[:, None], Ye * w, rcond=None)[0]

    x0 = solve(W0, Y0)
    np.testing.assert_allclose(x0, [res.value(n) for n in ("a", "b", "d")], rtol=1e-10)
    shifts = []
    for k in range(2):
        b = np.zeros(2)
        b[k] = sigma_b[k]
        W1, Y1, _ = _biased_system(b * 1e-3)
        shifts.append((solve(W1, Y1) - x0) / 1e-3)  # one-σ shift by finite difference
        np.testing.assert_allclose(full.systematic.shifts[f"u{k + 1}"], shifts[-1], rtol=1e-3, atol=1e-9)
    cov = sum(np.outer(d, d) for d in shifts)
    np.testing.assert_allclose(full.systematic.covariance, cov, rtol=2e-3, atol=1e-12)
    np.testing.assert_allclose(full.std_total[[0, 1, 3]], np.hypot(res.std[[0, 1, 3]], np.sqrt(np.diag(cov))),
                               rtol=2e-3)
    main = f"u{1 + int(abs(shifts[1][0]) > abs(shifts[0][0]))}"
    assert np.isnan(full.std_total[2]) and full.systematic.main_source("a") == main
    d = full.to_dict()["parameters"][0]
    assert d["std_total"] > d["std"] and d["main_offset"] == main
    assert "%std total" in full.summary()


def test_streaming_group_rms_of_y_and_of_the_residual():
    W, Y, g = _biased_system(np.zeros(2))
    s = StreamingLS(["a", "b", "c", "d"])
    for chunk in np.array_split(np.arange(len(Y)), 3):
        s.add(W[chunk], Y[chunk], g[chunk])
    res = s.solve()
    r = Y - W @ res.values
    for grp in ("a", "b"):
        rows = g == grp
        assert s.group_rms()[grp] == pytest.approx(np.sqrt(np.mean(Y[rows] ** 2)), rel=1e-12)
        assert s.group_rms(res)[grp] == pytest.approx(np.sqrt(np.mean(r[rows] ** 2)), rel=1e-9)
