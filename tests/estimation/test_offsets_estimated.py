"""Each test's sensor zero offsets estimated with the parameters (estimation/offsets.py), against the dense least
squares of the whole augmented system (rows [W C | Y] of every test, the prior rows [0 I | 0]) solved at once."""

import numpy as np
import pytest

from dynid.estimation.offsets import OffsetFactors, solve_with_offsets

Q, GROUPS = 4, ("a", "b", "c")
SIGMAS = {"a": 0.5, "b": 2.0, "c": 1.0}


def _tests(rng, x, n_tests=3, m=2, rows=120):
    """Per test: W, groups, the offsets' row changes (ΔW, ΔY) and Y with true offsets u ~ N(0, 1) and noise."""
    out = []
    for t in range(n_tests):
        W = rng.standard_normal((rows, Q))
        g = np.array(GROUPS)[rng.integers(0, len(GROUPS), rows)]
        dW = [0.1 * rng.standard_normal((rows, Q)) for _ in range(m)]
        dY = [rng.standard_normal(rows) for _ in range(m)]
        u = rng.standard_normal(m)
        # rows with the offsets in: Y = W x + Σ u_k (ΔY_k − ΔW_k x0), x0 the linearisation point
        C = np.column_stack([dY[k] - dW[k] @ X0 for k in range(m)])
        e = rng.standard_normal(rows) * np.array([SIGMAS[v] for v in g])
        out.append((f"test {t}", [f"ch{k}" for k in range(m)], W, W @ x + C @ u + e, dW, dY, g, C))
    return out


X0 = np.array([1.0, -2.0, 0.5, 3.0])


def _factors(tests, chunks=1):
    acc = OffsetFactors(np.arange(Q), np.array([], dtype=int), np.array([]), X0)
    for name, sources, W, Y, dW, dY, g, _ in tests:
        for idx in np.array_split(np.arange(len(Y)), chunks):
            part = OffsetFactors(acc.columns, acc.known_columns, acc.known_values, X0)
            part.add(name, sources, W[idx], Y[idx], [d[idx] for d in dW], [d[idx] for d in dY], g[idx])
            acc = acc.merge(part)
    return acc


def _dense(tests):
    """The augmented system solved at once: x, u and their covariance (σ² from its residual, n − q dof)."""
    m = sum(len(t[1]) for t in tests)
    blocks, rhs, col = [], [], Q
    for _, sources, W, Y, _, _, g, C in tests:
        w = 1.0 / np.array([SIGMAS[v] for v in g])
        A = np.zeros((len(Y), Q + m))
        A[:, :Q] = W * w[:, None]
        A[:, col:col + len(sources)] = C * w[:, None]
        col += len(sources)
        blocks.append(A)
        rhs.append(Y * w)
    blocks.append(np.hstack([np.zeros((m, Q)), np.eye(m)]))
    rhs.append(np.zeros(m))
    A, b = np.vstack(blocks), np.concatenate(rhs)
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    n = sum(len(t[3]) for t in tests)
    s2 = float(np.sum((b - A @ sol) ** 2)) / (n - Q)
    return sol, s2 * np.linalg.inv(A.T @ A)


@pytest.mark.parametrize("chunks", [1, 2, 7])
def test_the_estimate_is_the_augmented_least_squares(chunks):
    rng = np.random.default_rng(3)
    x = np.array([2.0, 1.0, -1.0, 0.3])
    tests = _tests(rng, x)
    est = solve_with_offsets(_factors(tests, chunks), [f"x{k}" for k in range(Q)], SIGMAS)
    sol, cov = _dense(tests)
    np.testing.assert_allclose(est.solution.x, sol[:Q], rtol=1e-10, atol=1e-12)
    # the statistical and the offsets' parts add up to the dense covariance of x
    total = est.solution.covariance + est.systematic.covariance
    np.testing.assert_allclose(total, cov[:Q, :Q], rtol=1e-9, atol=1e-14)
    u = np.concatenate([est.u[t[0]] for t in tests])
    np.testing.assert_allclose(u, sol[Q:], rtol=1e-9, atol=1e-12)
    std_u = np.array([est.offsets[f"{t[0]}: {s}"][1] for t in tests for s in t[1]])
    np.testing.assert_allclose(std_u, np.sqrt(np.diag(cov)[Q:]), rtol=1e-9)


@pytest.mark.slow
def test_the_split_of_the_covariance_matches_the_scatter_of_its_causes():
    """Over many draws with the same rows: the estimate's scatter from the noise alone (the offsets fixed at 0) is
    the statistical part, and from the offsets alone (no noise) the systematic part. 2000 draws: each variance to
    about 3 % (√(2/2000)); 12 % allows four of those."""
    rng = np.random.default_rng(11)
    x = np.array([2.0, 1.0, -1.0, 0.3])
    tests = _tests(rng, x)
    ref = solve_with_offsets(_factors(tests), [f"x{k}" for k in range(Q)], SIGMAS, sigma2=1.0)
    draws = {"noise": [], "offsets": []}
    for _ in range(2000):
        for cause in draws:
            moved = []
            for name, sources, W, _, dW, dY, g, C in tests:
                u = rng.standard_normal(len(sources)) if cause == "offsets" else np.zeros(len(sources))
                e = rng.standard_normal(len(g)) * np.array([SIGMAS[v] for v in g]) if cause == "noise" else 0.0
                moved.append((name, sources, W, W @ x + C @ u + e, dW, dY, g, C))
            est = solve_with_offsets(_factors(moved), [f"x{k}" for k in range(Q)], SIGMAS, sigma2=1.0)
            draws[cause].append(est.solution.x - x)
    for cause, cov in (("noise", ref.solution.covariance), ("offsets", ref.systematic.covariance)):
        seen = np.var(np.array(draws[cause]), axis=0)
        np.testing.assert_allclose(seen, np.diag(cov), rtol=0.12, err_msg=cause)


def test_a_test_whose_segments_declare_other_offsets_is_refused():
    acc = OffsetFactors(np.arange(Q), np.array([], dtype=int), np.array([]), X0)
    W, Y, g = np.ones((3, Q)), np.ones(3), np.array(["a"] * 3)
    acc.add("t", ["ch0"], W, Y, [W], [Y], g)
    with pytest.raises(Exception, match="other offsets"):
        acc.add("t", ["ch1"], W, Y, [W], [Y], g)
