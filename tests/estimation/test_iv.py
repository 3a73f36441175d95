"""Instrumental variables (IDIM-IV): estimator, covariance, weights and the offsets' propagation.

Oracles: statsmodels' IV2SLS (estimate, standard errors; exactly identified, so 2SLS is IV), the
closed-form errors-in-variables bias of least squares (attenuation by var(x) / (var(x) + var(noise))),
and finite differences of the estimate for the offsets' first-order effect.
"""

from __future__ import annotations

import numpy as np
import pytest
from statsmodels.sandbox.regression.gmm import IV2SLS

from dynid.estimation import IdentificationError, Method, StreamingLS, iv, propagate, wls


def _eiv_system(rng, n=4000, noise=0.5, sigma_y=(0.1, 0.4)):
    """Two groups sharing parameter b: y_a = a*x1 + b*x2, y_b = b*x2 + c; W holds x1 measured with noise,
    Z a second, independent measurement of the same x1 (its noise uncorrelated with W's)."""
    t = np.linspace(0, 40, n)
    x1, x2 = np.sin(t) + 0.3 * np.sin(3.1 * t), np.cos(0.7 * t)
    a, b, c = 2.0, -1.0, 0.5
    W = np.zeros((2 * n, 3))
    Z = np.zeros((2 * n, 3))
    W[:n, 0] = x1 + noise * rng.standard_normal(n)
    Z[:n, 0] = x1 + noise * rng.standard_normal(n)
    W[:n, 1] = Z[:n, 1] = x2
    W[n:, 1] = Z[n:, 1] = x2
    W[n:, 2] = Z[n:, 2] = 1.0
    Y = np.concatenate([a * x1 + b * x2 + sigma_y[0] * rng.standard_normal(n),
                        b * x2 + c + sigma_y[1] * rng.standard_normal(n)])
    groups = np.repeat(["a", "b"], n)
    return W, Y, Z, groups, np.array([a, b, c])


def test_iv_matches_statsmodels_iv2sls_with_given_weights():
    """With the weights fixed, weighted IV is IV on rows scaled by 1/sigma_g: statsmodels' IV2SLS gives the
    same estimate and standard errors."""
    rng = np.random.default_rng(1)
    W, Y, Z, g, _ = _eiv_system(rng)
    sig = {"a": 0.3, "b": 0.6}
    res = iv(W, Y, Z, g, ["a", "b", "c"], group_sigmas=sig, iterations=0)
    w = np.array([1 / sig[k] for k in g])
    ref = IV2SLS(Y * w, W * w[:, None], Z * w[:, None]).fit()
    np.testing.assert_allclose(res.values, ref.params, rtol=1e-10)
    np.testing.assert_allclose(res.std, ref.bse, rtol=1e-9)
    assert res.method is Method.IV and res.weights == sig


def test_iv_removes_the_errors_in_variables_bias_that_least_squares_has():
    """Least squares shrinks a by var(x1) / (var(x1) + var(noise)) (the attenuation of a noisy regressor);
    IV recovers a within 4 of its own standard deviations, and its sigma matches the spread over seeds."""
    ests, stds, ls = [], [], []
    for seed in range(20):
        rng = np.random.default_rng(100 + seed)
        W, Y, Z, g, truth = _eiv_system(rng)
        r = iv(W, Y, Z, g, ["a", "b", "c"])
        ests.append(r.values)
        stds.append(r.std)
        ls.append(wls(W, Y, g, ["a", "b", "c"]).values)
    ests, stds, ls = np.array(ests), np.array(stds), np.array(ls)
    t = np.linspace(0, 40, len(Y) // 2)
    v = np.var(np.sin(t) + 0.3 * np.sin(3.1 * t))
    attenuated = truth[0] * v / (v + 0.5**2)
    assert np.mean(ls[:, 0]) == pytest.approx(attenuated, rel=0.03)  # the closed form: LS is biased
    z = (ests - truth) / stds
    assert np.all(np.abs(z) < 4)
    assert 0.6 < np.sqrt(np.mean(z[:, 0] ** 2)) < 1.5  # sigma honest: RMS of the standardized error near 1


def test_iv_with_the_regressor_as_instrument_is_wls():
    """Z = W: the IV normal equations are the least-squares ones, weights and standard deviations included."""
    rng = np.random.default_rng(2)
    W, Y, _, g, _ = _eiv_system(rng)
    ref = wls(W, Y, g, ["a", "b", "c"], known={"c": 0.5})
    res = iv(W, Y, W, g, ["a", "b", "c"], known={"c": 0.5}, group_sigmas=ref.weights, iterations=0)
    np.testing.assert_allclose(res.values, ref.values, rtol=1e-10)
    np.testing.assert_allclose(res.std[:2], ref.std[:2], rtol=1e-8)


def test_iv_weights_are_the_iv_residuals_own():
    """After the iterations, each sigma_g is ||Y_g - W_g X_iv|| / sqrt(n_g - p_g) at the estimate (fixed point to
    the solver's precision)."""
    rng = np.random.default_rng(3)
    W, Y, Z, g, _ = _eiv_system(rng)
    res = iv(W, Y, Z, g, ["a", "b", "c"], iterations=6)
    r = Y - W @ res.values
    for grp, p in (("a", 2), ("b", 2)):
        rows = g == grp
        assert res.weights[grp] == pytest.approx(np.linalg.norm(r[rows]) / np.sqrt(rows.sum() - p), rel=1e-6)


def test_iv_offsets_propagate_as_a_finite_difference():
    """The first-order effect of an offset on the IV estimate (with Z and W both moved) equals re-solving."""
    rng = np.random.default_rng(4)
    W0, Y0, Z0, g, _ = _eiv_system(rng)
    names = ["a", "b", "c"]

    def shifted(u):  # an offset u on the measured x1, seen by W and Z alike, and a bias u on group b's y
        W, Y, Z = W0.copy(), Y0.copy(), Z0.copy()
        n = len(Y) // 2
        W[:n, 0] += u
        Z[:n, 0] += u
        Y[n:] += 0.5 * u
        return W, Y, Z

    s = StreamingLS(names)
    s.add(W0, Y0, g)
    sums = s.instrument_sums()
    sums.add(W0, Y0, Z0, g)
    res = s.solve_iv(sums, iterations=2)
    acc = s.bias_accumulator()
    eps, sigma_u = 1e-6, 0.05
    W1, Y1, Z1 = shifted(eps)
    acc.add("u", W0, Y0, (W1 - W0) / eps * sigma_u, (Y1 - Y0) / eps * sigma_u, g, Z=Z0, dZ=(Z1 - Z0) / eps * sigma_u)
    full = res.with_systematic(propagate(sums.normal(res.weights), acc, res.values, res.estimated_names, res.weights))
    W1, Y1, Z1 = shifted(1e-3 * sigma_u)
    moved = iv(W1, Y1, Z1, g, names, group_sigmas=res.weights, iterations=0).values
    np.testing.assert_allclose(full.systematic.shifts["u"], (moved - res.values) / 1e-3, rtol=1e-3, atol=1e-12)


def test_iv_refuses_instruments_on_other_rows_and_useless_instruments():
    rng = np.random.default_rng(5)
    W, Y, Z, g, _ = _eiv_system(rng)
    s = StreamingLS(["a", "b", "c"])
    s.add(W, Y, g)
    sums = s.instrument_sums()
    sums.add(W[:100], Y[:100], Z[:100], g[:100])
    with pytest.raises(IdentificationError, match="other rows"):
        s.solve_iv(sums)
    Z = Z.copy()
    Z[:, 0] = 0.0
    with pytest.raises(IdentificationError, match="instruments do not identify"):
        iv(W, Y, Z, g, ["a", "b", "c"])
