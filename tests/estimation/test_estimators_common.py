"""Every estimator on the same fixtures (issue 25 item 1), as scikit-learn's common tests hold `fit` to `partial_fit`.

Oracles: statsmodels' OLS for the shared answer (estimates, standard errors); then identities that hold in exact
arithmetic between different code paths: OLS = WLS with unit weights = IV with Z = W (A = ZᵀW = WᵀW and
S = ZᵀZ = WᵀW, so s² A⁻¹ S A⁻ᵀ = s² (WᵀW)⁻¹) = wls-pc when no constraint binds; and batch = streamed: the rows
added in chunks of 1, 2, 50, n and n + 42 rows give the factors of the same [W | Y] (per group R_g with
[W_g | Y_g] = Q_g R_g, unique up to the signs of its rows), hence the same answer.

Tolerances. The least-squares paths are backward stable QR factorisations (Householder, chunk by chunk or at once):
their estimates differ by about cond(W) ε relative, 1e-14 here (cond ≈ 10); 1e-10 is the issue's figure, with
four orders of margin for any CPU (FMA or not). wls-pc comes from an interior-point solve: its distance from the
WLS optimum is bounded in the WLS's own metric (tests/estimation/test_wls_pc.py's module doc): Clarabel's relative
gap 1e-8 on ||P r||² ≈ n = 400 gives sqrt(4e-6) = 2e-3 σ per solve; 1e-2 σ allows two solves.
"""

from __future__ import annotations

import numpy as np
import pytest
import statsmodels.api as sm

from dynid.estimation import Method, StreamingLS, iv, nrmse, ols, relative_errors, residual_rms, wls

RTOL = 1e-10
AGREE_SIGMA = 1e-2  # wls-pc against a least-squares answer, in σ (module doc)
CHUNKS = (1, 2, 50, "n", "n + 42")
NAMES = ["XX1", "XY1", "XZ1", "YY1", "YZ1", "ZZ1", "MX1", "MY1", "MZ1", "M1"]


def rel(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b) / np.abs(b)))


def _body() -> np.ndarray:
    """A realisable body (2 kg, centre of mass 0.1 m off O, inertia well inside the triangle inequalities), its
    ten parameters about O in Khalil's order."""
    m, c = 2.0, np.array([0.1, -0.05, 0.08])
    I_g = np.diag([0.05, 0.04, 0.03])
    I_o = I_g + m * (c @ c * np.eye(3) - np.outer(c, c))
    return np.array([I_o[0, 0], I_o[0, 1], I_o[0, 2], I_o[1, 1], I_o[1, 2], I_o[2, 2], *(m * c), m])


@pytest.fixture(scope="module")
def system():
    """Two equation groups of 200 rows (noise levels 1e-3 and 3e-3 of Y's size), the rows interleaved so that a
    chunk holds both groups; the truth is a body far from the consistency bounds."""
    rng = np.random.default_rng(25)
    n = 400
    W = rng.normal(size=(n, 10)) * np.array([3.0, 1.0, 1.0, 2.0, 1.0, 4.0, 0.5, 0.7, 0.6, 0.3])
    x = _body()
    groups = np.where(np.arange(n) % 3 == 0, "a", "b")
    scale = np.where(groups == "a", 1e-3, 3e-3) * np.std(W @ x)
    Y = W @ x + scale * rng.normal(size=n)
    return W, Y, groups, x


def _chunks(n: int, size) -> list[slice]:
    size = {"n": n, "n + 42": n + 42}.get(size, size)
    return [slice(s, min(n, s + size)) for s in range(0, n, size)]


def _streamed(W, Y, groups, size, **kw) -> StreamingLS:
    ls = StreamingLS(NAMES, **kw)
    for c in _chunks(W.shape[0], size):
        ls.add(W[c], Y[c], groups[c])
    return ls


def test_the_shared_answer_is_statsmodels_ols(system):
    W, Y, _, _ = system
    fit = sm.OLS(Y, W).fit()
    res = ols(W, Y, NAMES)
    assert res.method is Method.OLS
    assert rel(res.values, fit.params) < RTOL and rel(res.std, fit.bse) < RTOL


def test_ols_wls_with_unit_weights_and_iv_with_z_w_are_one_estimate(system):
    W, Y, groups, _ = system
    unit = {"a": 1.0, "b": 1.0}
    o = ols(W, Y, NAMES)
    w = wls(W, Y, groups, NAMES, group_sigmas=unit)
    v = iv(W, Y, W, groups, NAMES, group_sigmas=unit, iterations=0)
    for r, m in ((w, Method.WLS), (v, Method.IV)):
        assert r.method is m
        assert rel(r.values, o.values) < RTOL
        assert rel(r.std, o.std) < RTOL
        assert rel(r.covariance, o.covariance) < RTOL
        assert r.residual.dof == o.residual.dof


def test_wls_pc_with_slack_constraints_is_wls(system):
    pytest.importorskip("cvxpy", reason="the pc extra (pip install cvxpy clarabel) is not installed")
    from dynid.estimation.physical import ConsistencyStructure, wls_pc

    W, Y, groups, _ = system
    structure = ConsistencyStructure(tuple(NAMES), tuple(NAMES), np.eye(10), {1: tuple(range(10))})
    for sigmas in ({"a": 1.0, "b": 1.0}, None):  # unit weights (= OLS), then Gautier's
        w = wls(W, Y, groups, NAMES, group_sigmas=sigmas)
        pc = wls_pc(W, Y, groups, NAMES, structure, group_sigmas=sigmas)
        assert pc.active == () and pc.result.method is Method.WLS_PC
        assert np.max(np.abs(pc.result.values - w.values) / w.std) < AGREE_SIGMA
        assert rel(pc.result.std, w.std) < 1e-6  # the covariance at the constrained solution: its rss moved by δ


@pytest.mark.parametrize("size", CHUNKS)
def test_batch_equals_streamed_for_every_method(system, size):
    W, Y, groups, _ = system
    ls = _streamed(W, Y, groups, size)
    assert ls.n_rows == W.shape[0] and ls.group_rows == {"a": 134, "b": 266}
    o, s = ols(W, Y, NAMES), ls.solve()
    assert rel(s.values, o.values) < RTOL and rel(s.std, o.std) < RTOL
    w, s = wls(W, Y, groups, NAMES), ls.solve_weighted()
    assert rel(s.values, w.values) < RTOL and rel(s.std, w.std) < RTOL
    assert rel(list(s.weights.values()), list(w.weights.values())) < RTOL
    # IV with its instruments' sums streamed in the same chunks
    Z = W + 0.1 * np.random.default_rng(1).normal(size=W.shape)
    sums = ls.instrument_sums()
    for c in _chunks(W.shape[0], size):
        sums.add(W[c], Y[c], Z[c], groups[c])
    v, s = iv(W, Y, Z, groups, NAMES), ls.solve_iv(sums)
    assert rel(s.values, v.values) < RTOL and rel(s.std, v.std) < RTOL
    # the validation from the factors: relative error, NRMSE and residual RMS per group, as numpy on the rows; the
    # batch functions (one block) the same
    rows = _row_validation(W, Y, w.values, groups)
    for what, streamed, batch in (("relative", ls.relative_errors(w.values), relative_errors(W, Y, w.values, groups)),
                                  ("nrmse", ls.nrmse(w.values), nrmse(W, Y, w.values, groups)),
                                  ("rms", ls.group_rms(w.values), residual_rms(W, Y, w.values, groups))):
        assert streamed.keys() == batch.keys() == rows[what].keys()
        assert rel(list(streamed.values()), list(rows[what].values())) < RTOL
        assert rel(list(batch.values()), list(rows[what].values())) < RTOL


def _row_validation(W, Y, x, groups) -> dict[str, dict[str, float]]:
    """The validation errors computed on the rows by numpy (the oracle of the factors' validation)."""
    r = Y - W @ x
    out: dict[str, dict[str, float]] = {"relative": {}, "nrmse": {}, "rms": {}}
    for g in dict.fromkeys(groups):
        k = groups == g
        out["relative"][g] = np.linalg.norm(r[k]) / np.linalg.norm(Y[k])
        out["nrmse"][g] = np.linalg.norm(r[k]) / np.linalg.norm(Y[k] - Y[k].mean())
        out["rms"][g] = np.sqrt(np.mean(r[k] ** 2))
    out["relative"]["overall"] = np.linalg.norm(r) / np.linalg.norm(Y)
    spread = sum(np.sum((Y[groups == g] - Y[groups == g].mean()) ** 2) for g in dict.fromkeys(groups))
    out["nrmse"]["overall"] = np.linalg.norm(r) / np.sqrt(spread)
    return out


@pytest.mark.parametrize("size", CHUNKS)
def test_wls_pc_batch_equals_streamed(system, size):
    pytest.importorskip("cvxpy", reason="the pc extra (pip install cvxpy clarabel) is not installed")
    from dynid.estimation.physical import ConsistencyStructure, wls_pc, wls_pc_streamed

    W, Y, groups, _ = system
    # the data now say M1 = -0.05 kg: the body breaks its bounds, the constraint binds (not a slack case)
    structure = ConsistencyStructure(tuple(NAMES), tuple(NAMES), np.eye(10), {1: tuple(range(10))})
    Yb = Y - W[:, 9] * 2.05
    batch = wls_pc(W, Yb, groups, NAMES, structure)
    streamed = wls_pc_streamed(_streamed(W, Yb, groups, size), structure)
    assert batch.active and streamed.active == batch.active
    sd = batch.wls.std
    assert np.max(np.abs(streamed.result.values - batch.result.values) / sd) < AGREE_SIGMA
    assert rel(streamed.wls.values, batch.wls.values) < RTOL


def test_known_values_and_gains_applied_to_the_factors(system):
    """`StreamingLS.reparametrised` on the factors of every column equals the rows rewritten: known parameters moved
    to the right-hand side (`ols(known=...)`), and a column's parameter replaced by a value (Y' = Y - W_k g, the
    joint-torque rows of identified drive gains) before the per-group noise levels (`group_noise` on the rows)."""
    from dynid.estimation import group_noise

    W, Y, groups, _ = system
    full = _streamed(W, Y, groups, 50)
    known = {"XY1": 0.01, "M1": 2.0}
    same = full.reparametrised(NAMES, np.eye(11), known=known)
    o = ols(W, Y, NAMES, known=known)
    s = same.solve()
    assert rel(s.values, o.values) < RTOL and rel(s.std[np.isfinite(s.std)], o.std[np.isfinite(o.std)]) < RTOL
    g = 1.7  # the last column's parameter given: rows [W[:, :9] | Y - 1.7 W[:, 9]]
    T = np.zeros((11, 10))
    T[:9, :9] = np.eye(9)
    T[9, 9], T[10, 9] = -g, 1.0
    view = full.reparametrised(NAMES[:9], T)
    rows = group_noise(W[:, :9], Y - g * W[:, 9], groups, NAMES[:9])
    assert rel([f.sigma for f in view.group_fits().values()], [f.sigma for f in rows.values()]) < RTOL
    x9 = o.values[:9]
    rows9 = _row_validation(W[:, :9], Y - g * W[:, 9], x9, groups)["nrmse"]
    assert rel(list(view.nrmse(x9).values()), list(rows9.values())) < RTOL
