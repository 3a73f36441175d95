"""The plan's spread from the noise as it is (`estimation.offsets.NoiseScores`, `plan.predict`, issue 29): one
sensor's noise in several equation groups at equal samples, and correlated between neighbouring rows.

Oracles: statsmodels' Driscoll–Kraay sums (`S_hac_groupsum`, uniform kernel) of the same scores; a Monte-Carlo
spread of the estimator (NumPy's lstsq of [W C; 0 I] [x; u] = [Y; 0], fresh noise and offsets per draw)."""

from __future__ import annotations

import numpy as np
import pytest

from dynid.estimation import StreamingLS
from dynid.estimation.offsets import NoiseScores, OffsetFactors
from dynid.pipeline import plan as planner

THETA = 0.8  # the shared noise's MA(1) coefficient: n_t = (ε_t + θ ε_{t−1}) / sqrt(1 + θ²), lag-1 correlation 0.49


def _shared_noise(rng: np.random.Generator, n: int, draws: int) -> np.ndarray:
    """(n, draws) unit-variance MA(1) noise."""
    eps = rng.standard_normal((n + 1, draws))
    return (eps[1:] + THETA * eps[:-1]) / np.sqrt(1 + THETA**2)


def _noise(rng: np.random.Generator, n: int, draws: int) -> np.ndarray:
    """(2 n, draws) the rows' noise, rows (a_t, b_t) per stamp t: one MA(1) sensor in both groups (b's with the
    opposite sign, as an accelerometer axis in two equations), plus each group's own white noise."""
    shared = _shared_noise(rng, n, draws)
    out = np.empty((2 * n, draws))
    out[0::2] = 0.5 * shared + 0.2 * rng.standard_normal((n, draws))
    out[1::2] = -1.5 * shared + 0.5 * rng.standard_normal((n, draws))
    return out


def _problem(n: int):
    """Rows (a_t, b_t) per stamp t of a slow manoeuvre (the regressors smooth: the noise's neighbours add up), two
    offsets: a constant on a's rows, a gain on b's."""
    t = np.repeat(np.arange(n), 2)
    groups = np.tile(np.array(["a", "b"]), n)
    s = np.linspace(0, 6 * np.pi, n)
    W = np.column_stack([np.ones(2 * n), np.repeat(np.sin(s), 2), np.repeat(np.cos(0.5 * s), 2)])
    W[groups == "b", 2] *= -2.0  # the groups read the third parameter with other gains
    offsets = {"zero": 0.05 * (groups == "a"), "gain": 0.05 * W[:, 1] * (groups == "b")}
    return t, W, groups, offsets


def _piece(rng: np.random.Generator, n: int, x0: np.ndarray, test: str, lag: int | None) -> planner.Piece:
    """A Piece as `reduce_candidates` makes it: noise-free rows, the offsets' columns, a draw of the noise alone
    (`quiet`) and its scores (lag None: none, the white per-group prediction)."""
    t, W, groups, offsets = _problem(n)
    names = [f"x{i}" for i in range(W.shape[1])]
    Y = W @ x0
    ls = StreamingLS(names)
    ls.add(W, Y, groups)
    zeros = OffsetFactors(np.arange(W.shape[1]), np.zeros(0, dtype=int), np.zeros(0), x0)
    zeros.add(test, list(offsets), W, Y, [None] * len(offsets), list(offsets.values()), groups)
    e = _noise(rng, n, 1)[:, 0]
    quiet = StreamingLS(names)
    quiet.add(W, Y + e, groups)
    scores = None
    if lag is not None:
        scores = NoiseScores(lag)
        C = zeros.offset_columns([None] * len(offsets), list(offsets.values()), len(Y))
        half = n  # two segments, as the reduction's jobs give them (merged)
        for rows in (slice(0, half), slice(half, None)):
            part = NoiseScores(lag)
            part.add(test, t[rows], groups[rows], np.column_stack([C, W])[rows], e[rows])
            scores = scores.merge(part)
    return planner.Piece(ls, None, (), zeros, quiet, scores)


def test_noise_scores_are_statsmodels_driscoll_kraay_sums():
    """NoiseScores' S at any weights and profile: statsmodels' S_hac_groupsum (scores summed per time stamp, uniform
    kernel of lag 1) of the rows' profiled, weighted scores. The same sums in another order: rounding only (1e-10)."""
    from statsmodels.stats.sandwich_covariance import S_hac_groupsum, weights_uniform

    rng = np.random.default_rng(7)
    n = 300
    t, W, groups, offsets = _problem(n)
    C = np.column_stack(list(offsets.values()))
    e = _noise(rng, n, 1)[:, 0]
    scores = NoiseScores(1)
    scores.add("t", t, groups, np.column_stack([C, W]), e)
    weights = {"a": 1 / 0.3**2, "b": 1 / 1.7**2}
    profile = np.vstack([rng.standard_normal((2, 3)), np.eye(3)])
    w = np.array([weights[g] for g in groups])
    rows = (np.column_stack([C, W]) @ profile) * (w * e)[:, None]
    want = S_hac_groupsum(rows, t, nlags=1, weights_func=weights_uniform)
    got = scores.covariance("t", weights, profile)
    assert np.allclose(got, want, rtol=1e-10, atol=1e-12 * np.abs(want).max())


@pytest.mark.slow
def test_the_spread_of_noise_shared_across_groups_and_neighbouring_rows():
    """One MA(1) noise (lag-1 correlation 0.49) in both groups' rows of a stamp (correlation −0.9): the predicted σ
    total of two tests from one noise draw each against the spread of 4000 estimates (NumPy's lstsq of [W C; 0 I],
    the prediction's weights, fresh noise and offsets per draw) and against the closed form (the noise's banded
    covariance through that estimator's map). Error analysis: the spread over 4000 draws 1.1 % (against the closed
    form within 5 %: 4.5 of its σ); one draw's S from 2000 stamps per test scatters as sqrt((1 + 2 ρ₁²) / n) of its
    variance, measured 0.97 to 1.02 of the closed form over six pairs of draws (about 2 %); with margin 8 %. The
    white per-group prediction (σ_g per group, rows independent) misses it by 30 % or more here (so the test has
    power), and the lag from the conditioning is what removes the rest (lag 0: more
    than 10 % off)."""
    rng = np.random.default_rng(2029)
    x0 = np.array([1.0, -2.0, 0.5])
    n = 2000
    sigmas = {"a": 0.6, "b": 1.8}  # weights as a seed's eq. (8) gives them (not the noise's own σ)
    weights = (sigmas, 1.0)
    pred = {lag: planner.predict([_piece(np.random.default_rng(s), n, x0, f"t{i}", lag) for i, s in enumerate((5, 6))],
                                 weights=weights) for lag in (None, 0, 1)}
    # the Monte Carlo: two tests, each its own offsets and noise
    _, W, groups, offsets = _problem(n)
    C1 = np.column_stack(list(offsets.values()))
    Z = np.zeros_like(C1)
    Wt = np.vstack([W, W])
    C = np.block([[C1, Z], [Z, C1]])
    w = 1.0 / np.array([sigmas[g] for g in np.concatenate([groups, groups])])
    m = C.shape[1]
    A = np.block([[Wt * w[:, None], C * w[:, None]], [np.zeros((m, 3)), np.eye(m)]])
    pinv = np.linalg.pinv(A)[:3]  # the estimator's linear map (x's rows), lstsq of the stacked system
    est = []
    for _ in range(4):  # 4 x 1000 draws, in chunks
        draws = 1000
        Y = (Wt @ x0)[:, None] + np.vstack([_noise(rng, n, draws), _noise(rng, n, draws)]) \
            + C @ rng.standard_normal((m, draws))
        est.append((pinv @ np.vstack([Y * w[:, None], np.zeros((m, draws))])).T)
    spread = np.std(np.vstack(est), axis=0, ddof=1)
    ratio = pred[1].std_total / spread
    assert np.all(np.abs(ratio - 1) < 0.08), (pred[1].std_total, spread)
    # and the closed form: the noise's covariance (banded: each stamp's 2 x 2, its lag-1 2 x 2) through that map
    rho = THETA / (1 + THETA**2)
    V0 = np.array([[0.25 + 0.04, -0.75], [-0.75, 2.25 + 0.25]])
    V1 = rho * np.array([[0.25, -0.75], [-0.75, 2.25]])
    P = pinv[:, :2 * len(W)] * w
    cov = sum(np.einsum("qtr,rs,pts->qp", blk.reshape(3, n, 2), V0, blk.reshape(3, n, 2))
              + 2 * np.einsum("qtr,rs,pts->qp", blk.reshape(3, n, 2)[:, 1:], V1, blk.reshape(3, n, 2)[:, :-1])
              for blk in (P[:, :len(W)], P[:, len(W):]))
    shifts = P @ C
    exact = np.sqrt(np.diag(cov + shifts @ shifts.T))
    assert np.all(np.abs(spread / exact - 1) < 0.05), (spread, exact)  # the Monte Carlo's own check (1.1 %)
    assert np.all(np.abs(pred[1].std_total / exact - 1) < 0.08), (pred[1].std_total, exact)
    assert np.allclose(pred[1].x, x0, rtol=1e-9)
    assert np.max(np.abs(pred[None].std_total / spread - 1)) > 0.3, (pred[None].std_total, spread)
    assert np.max(np.abs(pred[0].std_total / spread - 1)) > 0.1, (pred[0].std_total, spread)


def test_noise_lag_from_the_conditioning():
    """Rows at 12.5 /s (625 Hz decimated 50 x) of a 4 Hz band oversample it 1.56 x: one neighbour; at the band's
    Nyquist rate (8 rows/s) or below: none; 20 rows/s (2.5 x): two."""
    assert planner.noise_lag(625.0, (5, 10), 4.0) == 1
    assert planner.noise_lag(400.0, (50,), 4.0) == 0
    assert planner.noise_lag(100.0, (50,), 4.0) == 0
    assert planner.noise_lag(1000.0, (50,), 4.0) == 2
