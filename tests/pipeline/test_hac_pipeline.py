"""cov_type = "hac" through `dynid identify`: the real TX40 files, their chunks mapped twice (the estimate, then the
rows' Newey–West sums at it).

Oracle: statsmodels' WLS(...).fit(cov_type="hac-panel") on the run's own stacked decimated rows (each joint one
panel, weights 1/σ_j², no small-sample correction), which the run keeps whole for its plots (a short test), and
the estimate of the nonrobust run. The chunks are made small (many chunks per test), so the second pass's sums
are folded across chunk borders. Tolerance: the two sides solve the same system (κ of the weighted W ≈ 1e3)
by different factorisations, and the folded sums add the same products in another order: a few κ² ε ≈ 1e-10
relative; 1e-7 holds on any CPU.
"""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from dynid.estimation import Covariance, CovType
from dynid.pipeline import robot as robot_module
from dynid.pipeline.config import ConfigError, load_config
from dynid.pipeline.run import identify

pytestmark = [pytest.mark.slow, pytest.mark.e2e]

CONFIG = Path(__file__).resolve().parents[2] / "examples" / "tx40" / "identify.toml"
sm = pytest.importorskip("statsmodels.api")


@pytest.fixture(scope="module")
def runs(tx40_data):
    cfg = load_config(CONFIG)
    mp = pytest.MonkeyPatch()
    mp.setattr(robot_module, "CHUNK_BYTES", 2**19)  # ~50 chunks of the 5 kHz test instead of a few
    try:
        return identify(cfg), identify(dataclasses.replace(cfg, covariance=Covariance(CovType.HAC, 4)))
    finally:
        mp.undo()


def test_hac_equals_statsmodels_on_the_stacked_rows(runs):
    plain, hac = runs
    r = hac.result
    np.testing.assert_array_equal(r.values, plain.result.values)  # the covariance alone changes
    sys = hac.systems["exciting trajectory"]
    assert sys.W.shape[0] == r.residual.n_rows  # the plots kept every row: the oracle sees them all
    est = [list(r.names).index(n) for n in r.estimated_names]
    w = np.array([1.0 / r.weights[g] ** 2 for g in sys.groups])
    ref = sm.WLS(sys.Y, sys.W[:, est], weights=w).fit(
        cov_type="hac-panel", cov_kwds={"groups": sys.groups, "maxlags": 4, "use_correction": False})
    np.testing.assert_allclose(ref.params, r.values[est], rtol=1e-7, atol=1e-9 * np.abs(ref.params).max())
    scale = np.sqrt(np.outer(np.diag(ref.cov_params()), np.diag(ref.cov_params())))
    assert np.max(np.abs(r.covariance - ref.cov_params()) / scale) < 1e-7
    assert r.hac_lags == dict.fromkeys(r.weights, 4)


def test_the_method_line_and_results_json_say_which(runs):
    plain, hac = runs
    assert plain.result.to_dict()["cov_type"] == "nonrobust" and "hac_lags" not in plain.result.to_dict()
    data = hac.result.to_dict()
    assert data["cov_type"].startswith("HAC (Bartlett kernel, 4 lags") and set(data["hac_lags"]) == set(
        hac.result.weights)
    assert "covariance: HAC" in hac.result.summary()
    # the decimated rows are autocorrelated: HAC σ differs from the white-row σ (larger for most parameters)
    ratio = hac.result.std / plain.result.std
    assert np.nanmedian(ratio) > 1.0


def test_config_keys(tmp_path, tx40_data):  # the config names the TX40 files: loading it checks they exist
    text = CONFIG.read_text().replace("../../../shared", str(CONFIG.parents[3] / "shared"))
    ok = tmp_path / "ok.toml"
    ok.write_text(text.replace('method = "wls"', 'method = "wls"\ncov_type = "hac"\nhac_lags = 3'))
    assert load_config(ok).covariance == Covariance(CovType.HAC, 3)
    auto = tmp_path / "auto.toml"
    auto.write_text(text.replace('method = "wls"', 'method = "ols"\ncov_type = "HAC"'))
    assert load_config(auto).covariance == Covariance(CovType.HAC, None)
    for bad, match in (('cov_type = "robust"', "nonrobust"), ('cov_type = "hac"\nhac_lags = -2', "hac_lags"),
                       ('method = "wls-pc"\ncov_type = "hac"', "ols\" or \"wls")):
        p = tmp_path / "bad.toml"
        p.write_text(text.replace('method = "wls"', bad if bad.startswith("method") else f'method = "wls"\n{bad}'))
        with pytest.raises(ConfigError, match=match):
            load_config(p)


def test_a_car_hac_equals_statsmodels_on_its_stacked_rows(tmp_path):
    """The quick demo's car (noisy sensor files) in one segment per test, so that the run keeps every row of its
    identification tests: cov_type = "hac" against statsmodels' hac-panel on them (each test's group one panel,
    in time order). Tolerance as for the TX40 (κ of the car's weighted W ≈ 1e3)."""
    from dynid.pipeline.demo import simulate_tests, write_demo

    config = write_demo(tmp_path, simulate_tests(quick=True), seed=2, noise=True, fmt="parquet")
    text = config.read_text().replace('method = "wls"', 'method = "wls"\ncov_type = "hac"\nhac_lags = 3')
    text = text.replace("[uncertainty]\n", "[uncertainty]\nestimate = false\n")
    config.write_text(text.replace("[conditioning]\n", "[conditioning]\nsegment = 1000.0\n"))
    run = identify(load_config(config))
    r = run.result
    parts = [run.systems[t.name] for t in run.config.tests if t.role == "identify"]
    W, Y = np.vstack([s.W for s in parts]), np.concatenate([s.Y for s in parts])
    key = np.concatenate([[f"{t.name}/{g}" for g in s.groups] for t, s in zip(
        [t for t in run.config.tests if t.role == "identify"], parts, strict=True)])
    t = np.concatenate([s.t for s in parts])
    assert W.shape[0] == r.residual.n_rows
    order = np.argsort(key, kind="stable")  # panels contiguous; each in the rows' (time) order
    assert all(np.all(np.diff(t[key == k]) > 0) for k in np.unique(key))
    est = [list(r.names).index(n) for n in r.estimated_names]
    w = np.array([1.0 / r.weights[k.rsplit("/", 1)[1]] ** 2 for k in key])
    ref = sm.WLS(Y[order], W[order][:, est], weights=w[order]).fit(
        cov_type="hac-panel", cov_kwds={"groups": key[order], "maxlags": 3, "use_correction": False})
    scale = np.sqrt(np.outer(np.diag(ref.cov_params()), np.diag(ref.cov_params())))
    assert np.max(np.abs(r.covariance - ref.cov_params()) / scale) < 1e-7
    assert r.systematic is not None  # the declared offsets' part is still attached
    # the offsets estimated: the profiled problem's scores (tests/estimation/test_hac_offsets.py), both kinds accepted
    for kind in ("hac", "hac-groupsum"):
        config.write_text(text.replace("[uncertainty]\nestimate = false\n", "[uncertainty]\n").replace(
            'cov_type = "hac"', f'cov_type = "{kind}"'))
        assert load_config(config).covariance.kind.value == kind


@pytest.mark.parametrize("kind", ["hac", "hac-groupsum"])
def test_a_car_hac_with_its_offsets_estimated_equals_statsmodels(tmp_path, monkeypatch, kind):
    """The quick demo's car (noisy sensor files, zero offsets drawn) in one segment per test with each test's offsets
    estimated (identify's default): the σ of cov_type = "hac" and "hac-groupsum" against statsmodels on the run's
    own rows, unprofiled: the estimated columns of W, each test's offsets' columns C (the rows' change per one-σ
    offset, linearised at the a priori values, as the first pass took them: caught on their way into the
    estimate) and the prior's pseudo-rows, weights 1/σ_g; OLS(...).fit()'s bread and residual, the meat over the
    data rows from S_hac_simple per group and test (S_hac_groupsum per test, the sample its time), lags 3; the
    parameters' block of B S B (tests/estimation/test_hac_offsets.py's oracle on the car). Tolerance as the
    estimate=false car's: κ of the car's weighted [W C] ≈ 1e3-1e4, a few κ² ε, 1e-7 on any CPU."""
    from dynid.estimation import offsets as offsets_module
    from dynid.pipeline.demo import simulate_tests, write_demo

    caught = {}
    add = offsets_module.OffsetFactors.add_columns

    def catch(self, test, sources, W, Y, C, groups):
        caught[test] = (np.array(C), self.columns.copy())
        return add(self, test, sources, W, Y, C, groups)

    monkeypatch.setattr(offsets_module.OffsetFactors, "add_columns", catch)
    config = write_demo(tmp_path, simulate_tests(quick=True), seed=2, noise=True, fmt="parquet")
    text = config.read_text().replace('method = "wls"', f'method = "wls"\ncov_type = "{kind}"\nhac_lags = 3')
    config.write_text(text.replace("[conditioning]\n", "[conditioning]\nsegment = 1000.0\n"))
    run = identify(load_config(config))
    r = run.result
    assert ("group-summed" in r.cov_type) == (kind == "hac-groupsum")
    tests = [t.name for t in run.config.tests if t.role == "identify"]
    q, m = len(r.estimated_names), caught[tests[0]][0].shape[1]
    blocks, ys, meta = [], [], []
    for k, name in enumerate(tests):
        s = run.systems[name]
        C, cols = caught[name]
        assert C.shape[0] == len(s.Y)  # one segment: the kept rows are every row of the test
        w = 1.0 / np.array([r.weights[g] for g in s.groups])
        A = np.zeros((len(s.Y), q + m * len(tests)))
        A[:, :q], A[:, q + m * k:q + m * (k + 1)] = s.W[:, cols], C
        blocks.append(A * w[:, None]), ys.append(s.Y * w), meta.append((np.full(len(s.Y), k), s.groups, s.t))
    n = sum(len(y) for y in ys)
    A = np.vstack([*blocks, np.hstack([np.zeros((m * len(tests), q)), np.eye(m * len(tests))])])
    fit = sm.OLS(np.concatenate([*ys, np.zeros(m * len(tests))]), A).fit()
    assert np.allclose(fit.params[:q], [r.value(x) for x in r.estimated_names], rtol=1e-6, atol=0)
    scores = A[:n] * fit.resid[:n, None]
    test_of, group, time = (np.concatenate(a) for a in zip(*meta, strict=True))
    from statsmodels.stats import sandwich_covariance as sw

    S = np.zeros((A.shape[1], A.shape[1]))
    for k in range(len(tests)):
        if kind == "hac-groupsum":
            on = test_of == k
            S += sw.S_hac_groupsum(scores[on], np.unique(time[on], return_inverse=True)[1], nlags=3)
        else:
            for g in np.unique(group[test_of == k]):
                S += sw.S_hac_simple(scores[(test_of == k) & (group == g)], nlags=3)
    B = fit.normalized_cov_params
    ref = (B @ S @ B)[:q, :q]
    scale = np.sqrt(np.outer(np.diag(ref), np.diag(ref)))
    assert np.max(np.abs(r.covariance - ref) / scale) < 1e-7
    assert r.systematic is not None  # what the data leave of the offsets' effect, in σ total
