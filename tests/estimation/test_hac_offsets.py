"""HAC covariance with each test's sensor offsets estimated, per group and group-summed (estimation/hac.py with
estimation/offsets.py): the scores of the profiled problem, the bread the reduced normal matrix's inverse.

Oracles: statsmodels on the whole stacked system, the offsets' columns as regressors (one block per test) and their
prior as pseudo-rows, unprofiled: OLS(...).fit() gives the bread (normalized_cov_params) and the residual; the meat
over the data rows from statsmodels' kernels (S_hac_simple per group and test, S_hac_groupsum per test with the
sample as its time); the parameters' block of B S B. The pseudo-rows' scores are the offsets' own part (the
systematic part, kept apart as `solve_with_offsets` does), so they are left out of the meat. Then the streamed sums
against the one-block ones over chunks of 1, 2, 50, n, n + 42 samples, merged as a tree; and a Monte-Carlo whose
noise is one series shared by every group at the same samples, where the group-summed σ covers and the per-group
one does not.

Tolerances: the two sides solve the same system (κ of the weighted [W C] < 1e2) by different factorisations (QR of
per-test factors with the offsets eliminated, against statsmodels' pinv): a few κ² ε ≈ 1e-12 relative, so 1e-9
holds on any CPU, with or without FMA. The chunked sums add the same products in another order: 1e-10 relative.
"""

from __future__ import annotations

import numpy as np
import pytest

from dynid.estimation import Covariance, CovType, IdentificationError, StreamingLS
from dynid.estimation.offsets import OffsetFactors

sm = pytest.importorskip("statsmodels.api")
sw = pytest.importorskip("statsmodels.stats.sandwich_covariance")

GROUPS = ("x", "z", "susp9")
NAMES = ["m", "a", "b", "c"]
SOURCES = ("imu_az", "wft_Fz")
X = np.array([2.0, -0.7, 1.3, 0.4])


def _test_rows(rng: np.random.Generator, n: int, u: np.ndarray, shared: float = 0.3, own: float = 0.1):
    """One test's rows: n samples, a row per group at each (rows of one sample together, in time order); column
    m in every group (a mass in every chassis equation); one noise series shared by every group at a sample plus
    each group's own; the offsets' columns C (imu_az: every group, wft_Fz: the suspension's), offsets u."""
    tt = np.arange(n) * 0.08
    common = shared * rng.standard_normal(n)
    W, Y, g, t, C = [], [], [], [], []
    for k, name in enumerate(GROUPS):
        w = np.column_stack([1.0 + 0.5 * np.sin(0.9 * tt), np.sin((k + 1) * 0.7 * tt), np.cos(0.5 * tt + k),
                             (tt / tt[-1]) * (k == 2) + 0.3 * rng.standard_normal(n)])
        c = np.column_stack([np.ones(n), np.full(n, float(k == 2))])
        W.append(w), C.append(c), g.append(np.full(n, name)), t.append(tt)
        Y.append(w @ X + c @ u + common + own * rng.standard_normal(n))
    order = np.argsort(np.concatenate(t), kind="stable")  # rows of a sample together
    return tuple(np.concatenate(a)[order] for a in (W, Y, g, t, C))


def _campaign(seed: int, n: int = 120, tests=("sine", "braking"), u_scale: float = 1.0, **kw):
    rng = np.random.default_rng(seed)
    return {name: _test_rows(rng, n, u_scale * rng.standard_normal(len(SOURCES)), **kw) for name in tests}


def _identified(data):
    """WLS with each test's offsets estimated, as a car's run: (ls, result, the offsets' estimate)."""
    ls = StreamingLS(NAMES)
    factors = OffsetFactors(np.arange(len(NAMES)), np.array([], dtype=int), np.array([]), np.zeros(len(NAMES)))
    for test, (W, Y, g, _, C) in data.items():
        ls.add(W, Y, g)
        factors.add(test, SOURCES, W, Y, [None, None], [C[:, 0], C[:, 1]], g)
    result, est = ls.with_offsets_estimated(ls.solve_weighted(), factors)
    return ls, result, est


def _streamed(ls, result, est, data, cov: Covariance, chunk: int | None = None, merge: bool = False):
    """The HAC result from each test's rows fed in chunks of `chunk` samples (whole samples, time order)."""
    sums = ls.hac_sums(result, cov, est)
    parts = []
    for test, (W, Y, g, t, C) in data.items():
        stamps = np.unique(t)
        step = len(stamps) if chunk is None else chunk
        for s in range(0, len(stamps), step):
            rows = np.isin(t, stamps[s:s + step])
            part = sums.empty() if merge else sums
            part.add(W[rows], Y[rows], g[rows], test, C[rows], t[rows])
            parts.append(part)
    if merge:
        while len(parts) > 1:  # a tree of neighbours, as the schedulers fold
            parts = [parts[i].merge(parts[i + 1]) if i + 1 < len(parts) else parts[i] for i in range(0, len(parts), 2)]
        sums = parts[0]
    return ls.with_hac(result, sums, cov, est)


def _statsmodels(data, weights, lags: int, groupsum: bool) -> np.ndarray:
    """The parameters' block of B S B on the unprofiled stacked system (module doc)."""
    q, m = len(NAMES), len(SOURCES)
    tests = list(data)
    blocks, ys, keys = [], [], []
    for k, test in enumerate(tests):
        W, Y, g, t, C = data[test]
        w = 1.0 / np.array([weights[x] for x in g])
        A = np.zeros((len(Y), q + m * len(tests)))
        A[:, :q], A[:, q + m * k:q + m * (k + 1)] = W, C
        blocks.append(A * w[:, None]), ys.append(Y * w), keys.append((k, g, t))
    n = sum(len(y) for y in ys)
    A = np.vstack([*blocks, np.hstack([np.zeros((m * len(tests), q)), np.eye(m * len(tests))])])
    fit = sm.OLS(np.concatenate([*ys, np.zeros(m * len(tests))]), A).fit()
    scores = A[:n] * fit.resid[:n, None]
    test_of = np.concatenate([np.full(len(g), k) for k, g, _ in keys])
    group = np.concatenate([g for _, g, _ in keys])
    time = np.concatenate([t for _, _, t in keys])
    S = np.zeros((A.shape[1], A.shape[1]))
    for k in range(len(tests)):
        if groupsum:
            on = test_of == k
            S += sw.S_hac_groupsum(scores[on], np.round(time[on] / 0.08).astype(int), nlags=lags)
        else:
            for gname in GROUPS:
                on = (test_of == k) & (group == gname)
                S += sw.S_hac_simple(scores[on], nlags=lags)
    B = fit.normalized_cov_params
    return (B @ S @ B)[:q, :q]


@pytest.mark.parametrize("kind", [CovType.HAC, CovType.HAC_GROUPSUM])
def test_hac_with_offsets_estimated_equals_statsmodels_on_the_stacked_system(kind):
    data = _campaign(3)
    ls, result, est = _identified(data)
    cov = Covariance(kind, 3)
    out = _streamed(ls, result, est, data, cov)
    ref = _statsmodels(data, est.weights, 3, kind is CovType.HAC_GROUPSUM)
    scale = np.sqrt(np.outer(np.diag(ref), np.diag(ref)))
    assert np.max(np.abs(out.covariance - ref) / scale) < 1e-9
    assert out.systematic is result.systematic  # the offsets' part stays as the estimate gave it
    assert out.cov_type == cov.label and ("group-summed" in out.cov_type) == (kind is CovType.HAC_GROUPSUM)


@pytest.mark.parametrize("kind", [CovType.HAC, CovType.HAC_GROUPSUM])
def test_streamed_equals_one_block_over_chunk_sizes(kind):
    data = _campaign(5, n=100)
    ls, result, est = _identified(data)
    cov = Covariance(kind, 4)
    one = _streamed(ls, result, est, data, cov).covariance
    scale = np.sqrt(np.outer(np.diag(one), np.diag(one)))
    for chunk in (1, 2, 50, 100, 142):
        for merge in (False, True):
            got = _streamed(ls, result, est, data, cov, chunk, merge).covariance
            assert np.max(np.abs(got - one) / scale) < 1e-10, (chunk, merge)


def test_a_sample_split_between_chunks_is_refused():
    data = _campaign(1, n=20, tests=("sine",))
    ls, result, est = _identified(data)
    sums = ls.hac_sums(result, Covariance(CovType.HAC_GROUPSUM, 2), est)
    W, Y, g, t, C = data["sine"]
    sums.add(W[:4], Y[:4], g[:4], "sine", C[:4], t[:4])  # the second sample's first row only
    with pytest.raises(IdentificationError, match="whole samples"):
        sums.add(W[4:], Y[4:], g[4:], "sine", C[4:], t[4:])
    with pytest.raises(IdentificationError, match="offsets' columns C"):
        ls.hac_sums(result, Covariance(CovType.HAC, 2), est).add(W, Y, g, "sine")
    with pytest.raises(IdentificationError, match="sample times"):
        ls.hac_sums(result, Covariance(CovType.HAC_GROUPSUM, 2), est).add(W, Y, g, "sine", C)


@pytest.mark.slow
def test_one_noise_shared_by_the_groups_is_covered_by_the_group_summed_sigma_only():
    """The offsets all 0 but estimated (the sensors' noise alone, as the SUV's experiment): the noise shared by
    every group at a sample moves m (in every group's rows) by the sum of the groups' scores, which the per-group σ
    takes as independent. Over 300 campaigns the RMS of (m̂ - m) / σ: the group-summed one's within 0.85 to 1.15
    (the RMS of 300 standard normals is within 1 ± 0.07 at 3 σ; the HAC's small-sample bias, lags 3 of 240
    samples, a few %), the per-group one's above 1.3 (three groups of one shared noise: √3 in exact terms, less
    the groups' own noise and weights)."""
    z = {CovType.HAC: [], CovType.HAC_GROUPSUM: []}
    for seed in range(300):
        data = _campaign(100 + seed, n=120, u_scale=0.0, shared=0.3, own=0.05)
        ls, result, est = _identified(data)
        for kind in z:
            out = _streamed(ls, result, est, data, Covariance(kind, 3))
            z[kind].append((out.value("m") - X[0]) / out.std[0])
    rms = {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in z.items()}
    assert 0.85 < rms[CovType.HAC_GROUPSUM] < 1.15, rms
    assert rms[CovType.HAC] > 1.3, rms
