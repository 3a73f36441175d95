"""HAC (Newey–West) covariance per equation group, streamed: estimation/hac.py and StreamingLS.with_hac.

Oracles: statsmodels' OLS(...).fit(cov_type="HAC") on one group's rows and WLS(...).fit(cov_type="hac-panel") on
the stacked weighted system (each group and test one panel); the one-block sums against the same rows fed in
chunks of 1, 2, 50, n, n + 42 (added in turn and merged as a tree); a Monte-Carlo with AR(1) errors, where the
HAC interval covers at its level and the nonrobust one does not.

Tolerances: statsmodels and dynid solve the same well-conditioned systems (κ(W) < 30) by different
factorisations; the covariances differ by a few κ² ε ≈ 1e-13 relative, so 1e-9 holds on any CPU. The chunked
sums add the same products in another order: 1e-10 relative (the brief's figure) is far above the n ε ≈ 1e-13
round-off of a sum of n = 600 products.
"""

from __future__ import annotations

import numpy as np
import pytest

from dynid.estimation import Covariance, CovType, IdentificationError, StreamingLS
from dynid.estimation.hac import HACSums

sm = pytest.importorskip("statsmodels.api")


def _ar1(rng: np.random.Generator, n: int, phi: float, scale: float = 1.0) -> np.ndarray:
    e = np.empty(n)
    e[0] = rng.standard_normal() * scale / np.sqrt(1 - phi ** 2)
    eps = rng.standard_normal(n) * scale
    for t in range(1, n):  # a test fixture's error series, not the product's code
        e[t] = phi * e[t - 1] + eps[t]
    return e


def _system(seed: int = 0, n: int = 300, groups=("joint1", "joint2", "joint3"), tests=("a", "b")):
    """Rows of a few groups and tests, each group's rows in time order within a test: W (m, 4), Y, group, test."""
    rng = np.random.default_rng(seed)
    X = np.array([1.5, -0.7, 2.0, 0.3])
    Ws, Ys, gs, ts = [], [], [], []
    for t in tests:
        for k, g in enumerate(groups):
            tt = np.linspace(0, 10, n)
            W = np.column_stack([np.sin((k + 1) * tt), np.cos(0.7 * tt + k), np.ones(n) * (k % 2), tt / 10])
            W[:, 2] += 0.3 * rng.standard_normal(n)
            Ws.append(W)
            Ys.append(W @ X + _ar1(rng, n, 0.7, 0.1 * (k + 1)))
            gs.append(np.full(n, g))
            ts.append(np.full(n, t))
    return np.vstack(Ws), np.concatenate(Ys), np.concatenate(gs), np.concatenate(ts)


def _hac(ls: StreamingLS, result, cov: Covariance, W, Y, groups, tests, chunk: int | None = None, merge=False):
    """The HAC result from the rows fed in chunks (in time order, each test's rows in turn)."""
    sums = ls.hac_sums(result, cov)
    parts = []
    for t in dict.fromkeys(tests):
        idx = np.flatnonzero(tests == t)
        # time order: the groups' rows interleaved as a chunk of a log holds them
        within = np.concatenate([np.arange((groups[idx] == g).sum()) for g in dict.fromkeys(groups[idx])])
        order = idx[np.argsort(within, kind="stable")]
        step = len(order) if chunk is None else chunk
        for s in range(0, len(order), step):
            rows = order[s:s + step]
            if merge:
                part = sums.empty()
                part.add(W[rows], Y[rows], groups[rows], t)
                parts.append(part)
            else:
                sums.add(W[rows], Y[rows], groups[rows], t)
    if merge:
        while len(parts) > 1:  # a tree of neighbours, as the schedulers fold
            parts = [parts[i].merge(parts[i + 1]) if i + 1 < len(parts) else parts[i] for i in range(0, len(parts), 2)]
        sums = parts[0]
    return ls.with_hac(result, sums, cov)


def test_one_group_ols_equals_statsmodels_hac():
    W, Y, g, t = _system(1, groups=("joint1",), tests=("a",))
    ls = StreamingLS(["a", "b", "c", "d"])
    ls.add(W, Y, g)
    res = ls.solve()
    for L in (0, 1, 7):
        out = _hac(ls, res, Covariance(CovType.HAC, L), W, Y, g, t)
        ref = sm.OLS(Y, W).fit(cov_type="HAC", cov_kwds={"maxlags": L})
        np.testing.assert_allclose(out.covariance, ref.cov_params(), rtol=1e-9, atol=0)
        np.testing.assert_allclose(out.std, ref.bse, rtol=1e-9)
        assert out.hac_lags == {"joint1": L} and out.cov_type.startswith("HAC")


def test_auto_lags_are_newey_west_rule():
    W, Y, g, t = _system(2, n=250, groups=("joint1",), tests=("a",))
    ls = StreamingLS(4)
    ls.add(W, Y, g)
    res = ls.solve()
    out = _hac(ls, res, Covariance(CovType.HAC), W, Y, g, t)
    L = int(np.floor(4 * (250 / 100) ** (2 / 9)))  # statsmodels' S_hac_simple default
    assert out.hac_lags == {"joint1": L}
    ref = sm.OLS(Y, W).fit(cov_type="HAC", cov_kwds={"maxlags": L})
    np.testing.assert_allclose(out.covariance, ref.cov_params(), rtol=1e-9)


@pytest.mark.parametrize("given", [False, True])
def test_wls_equals_statsmodels_hac_panel(given):
    W, Y, g, t = _system(3)
    ls = StreamingLS(["a", "b", "c", "d"])
    ls.add(W, Y, g)
    sig = {"joint1": 0.2, "joint2": 0.25, "joint3": 0.4} if given else None
    res = ls.solve_weighted(sig)
    L = 5
    out = _hac(ls, res, Covariance(CovType.HAC, L), W, Y, g, t)
    # statsmodels: the rows sorted into panels (test, group), each in time order (the fixture's order is)
    key = np.char.add(np.char.add(t.astype(str), "/"), g.astype(str))
    w = np.array([1.0 / res.weights[k] ** 2 for k in g])
    ref = sm.WLS(Y, W, weights=w).fit(cov_type="hac-panel",
                                      cov_kwds={"groups": key, "maxlags": L, "use_correction": False})
    np.testing.assert_allclose(res.values, ref.params, rtol=1e-10)
    np.testing.assert_allclose(out.covariance, ref.cov_params(), rtol=1e-9)
    # the HAC σ of autocorrelated rows is larger than the nonrobust one
    assert np.all(out.std > res.std)


def test_known_parameters_move_to_the_right_hand_side():
    W, Y, g, t = _system(4, groups=("joint1",), tests=("a",))
    ls = StreamingLS(["a", "b", "c", "d"], known={"c": 2.0})
    ls.add(W, Y, g)
    res = ls.solve()
    out = _hac(ls, res, Covariance(CovType.HAC, 3), W, Y, g, t)
    ref = sm.OLS(Y - 2.0 * W[:, 2], W[:, [0, 1, 3]]).fit(cov_type="HAC", cov_kwds={"maxlags": 3})
    np.testing.assert_allclose(out.covariance, ref.cov_params(), rtol=1e-9)
    assert np.isnan(out.std[2])


@pytest.mark.parametrize("merge", [False, True])
def test_batch_equals_streamed_over_chunk_sizes(merge):
    W, Y, g, t = _system(5, n=200)
    ls = StreamingLS(4)
    ls.add(W, Y, g)
    res = ls.solve_weighted()
    cov = Covariance(CovType.HAC, 6)
    batch = _hac(ls, res, cov, W, Y, g, t).covariance
    n = 3 * 200  # rows per test
    for chunk in (1, 2, 50, n, n + 42):
        streamed = _hac(ls, res, cov, W, Y, g, t, chunk, merge).covariance
        np.testing.assert_allclose(streamed, batch, rtol=1e-10, atol=1e-10 * np.abs(batch).max())


def test_second_pass_must_see_every_row():
    W, Y, g, _ = _system(6, groups=("joint1",), tests=("a",))
    ls = StreamingLS(4)
    ls.add(W, Y, g)
    res = ls.solve()
    sums = ls.hac_sums(res, Covariance(CovType.HAC, 2))
    sums.add(W[:-5], Y[:-5], g[:-5], "a")
    with pytest.raises(IdentificationError, match="second pass"):
        ls.with_hac(res, sums, Covariance(CovType.HAC, 2))


def test_merge_refuses_other_estimates():
    a = HACSums([0], [], [], [1.0], None, {"g": 1})
    b = HACSums([0], [], [], [2.0], None, {"g": 1})
    with pytest.raises(IdentificationError, match="other estimates"):
        a.merge(b)


@pytest.mark.parametrize("args, match", [(("robust",), "nonrobust"), (("hac", -1), "hac_lags"),
                                         (("hac", 2.5), "hac_lags"), (("nonrobust", 3), "needs cov_type")])
def test_covariance_parse_errors(args, match):
    with pytest.raises(IdentificationError, match=match):
        Covariance.parse(*args, where="cfg.toml: [identification]")


def test_covariance_parse():
    assert Covariance.parse() == Covariance()
    assert Covariance.parse("HAC", "auto") == Covariance(CovType.HAC, None)
    assert Covariance.parse("hac", 4).lags_for(10 ** 6) == 4


# 400 Monte Carlo draws, 6 s of CPU: slow; the quick run keeps the same HAC code against statsmodels
# (test_one_group_ols_equals_statsmodels_hac, test_wls_equals_statsmodels_hac_panel)
@pytest.mark.slow
def test_monte_carlo_ar1_hac_covers_nonrobust_does_not():
    """AR(1) errors (φ = 0.8) on smooth regressors: the nonrobust 95 % interval covers the truth far less often
    than 95 %; the HAC one (Newey–West lags) near its level. 400 draws: a coverage's binomial σ is ≤ 2.5 %, the
    thresholds are > 4 σ from the expected values (HAC ≈ 0.90, its small-sample bias; nonrobust ≈ 0.6)."""
    rng = np.random.default_rng(20261127)
    n, X = 400, np.array([1.0, 0.5])
    cov = Covariance(CovType.HAC, 12)
    hits_hac = hits_nr = 0
    draws = 400
    for _ in range(draws):
        x1 = _ar1(rng, n, 0.8)
        W = np.column_stack([np.ones(n), x1])
        Y = W @ X + _ar1(rng, n, 0.8)
        g = np.full(n, "g")
        ls = StreamingLS(2)
        ls.add(W, Y, g)
        res = ls.solve()
        out = _hac(ls, res, cov, W, Y, g, np.full(n, "a"), chunk=97)
        hits_nr += abs(res.values[1] - X[1]) <= 1.96 * res.std[1]
        hits_hac += abs(out.values[1] - X[1]) <= 1.96 * out.std[1]
    print(f"coverage HAC {hits_hac / draws:.3f}, nonrobust {hits_nr / draws:.3f}")
    assert hits_hac / draws > 0.84, hits_hac / draws
    assert hits_nr / draws < 0.78, hits_nr / draws
