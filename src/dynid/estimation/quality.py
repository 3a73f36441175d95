"""Quality indicators: relative standard deviations, the 20x rule of thumb, relative errors."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ._checks import as_groups, as_matrix, as_vector, group_rows, norm_ratio
from .errors import IdentificationError

POOR_FACTOR = 20.0
"""Paper §7.2: a parameter whose %σ exceeds 20 times the smallest %σ is poorly identified."""

EXCITED_FACTOR = 2.0
"""A test excites an equation group when the RMS of its Y is at least this many times the identification's
residual RMS in that group (the noise floor): below it, a relative error compares noise with noise."""


def relative_std_percent(values: ArrayLike, std: ArrayLike) -> np.ndarray:
    """``100 * std / |value|`` (%), elementwise; inf for a zero estimate with std > 0, 0 when both are 0."""
    x = np.abs(np.asarray(values, dtype=float))
    s = np.asarray(std, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = 100.0 * s / x
    out[(x == 0) & (s == 0)] = 0.0
    return out


def poorly_identified(rel_std_percent: Mapping[str, float], factor: float = POOR_FACTOR) -> list[str]:
    """Names whose %σ exceeds ``factor`` times the smallest %σ (paper §7.2), in the mapping's order.

    A non-finite %σ (zero estimate) is always poor. With no finite %σ at all, every parameter is poor.
    """
    if factor <= 0:
        raise IdentificationError(f"the poor-identification factor must be positive, got {factor}")
    finite = [v for v in rel_std_percent.values() if np.isfinite(v)]
    if not finite:
        return list(rel_std_percent)
    limit = factor * min(finite)
    return [n for n, v in rel_std_percent.items() if not np.isfinite(v) or v > limit]


def not_excited(signal_rms: Mapping[str, float], noise_rms: Mapping[str, float],
                factor: float = EXCITED_FACTOR) -> list[str]:
    """The groups a test barely moves, in `signal_rms`'s order: RMS of the test's Y (per group) below `factor`
    times the identification's residual RMS there (`noise_rms`; a group without one is never called not
    excited). Their relative error ||Y - W X|| / ||Y|| is noise over noise: say "not excited", not a percentage."""
    return [g for g, rms in signal_rms.items() if rms < factor * noise_rms.get(g, 0.0)]


def relative_errors(
    W: ArrayLike,
    Y: ArrayLike,
    X: ArrayLike | Mapping[str, float],
    groups: ArrayLike,
    names: Sequence[str] | None = None,
) -> dict[str, float]:
    """Relative error ``||Y_g - W_g X|| / ||Y_g||`` per equation group, plus ``"overall"``.

    W : (m, p); Y : (m,); X : (p,) values in W's column order, or ``{name: value}`` with ``names``
    giving W's column order (every name must be present); groups : (m,) group label of each row.
    A group with ``||Y_g|| = 0`` gets 0 if its residual is 0 too, else inf. Direct validation passes
    the identification data, cross validation data from a test not used for estimation (paper §7.2).
    """
    res, y, rows = _residuals(W, Y, X, groups, names)
    out = {name: norm_ratio(np.linalg.norm(res[idx]), np.linalg.norm(y[idx])) for name, idx in rows.items()}
    out["overall"] = norm_ratio(np.linalg.norm(res), np.linalg.norm(y))
    return out


def nrmse(
    W: ArrayLike,
    Y: ArrayLike,
    X: ArrayLike | Mapping[str, float],
    groups: ArrayLike,
    names: Sequence[str] | None = None,
) -> dict[str, float]:
    """Normalised RMS error ``RMS(Y_g - W_g X) / std(Y_g)`` per equation group, plus ``"overall"`` (the
    residuals' and the spreads' sums of squares pooled over groups). Unlike the relative error it does not
    count the part of Y that never changes (a robot's static gravity load): 1 is no better than predicting
    each group's mean. Arguments as for `relative_errors`."""
    res, y, rows = _residuals(W, Y, X, groups, names)
    spread = {name: y[idx] - y[idx].mean() for name, idx in rows.items()}
    out = {name: norm_ratio(np.linalg.norm(res[idx]), np.linalg.norm(spread[name])) for name, idx in rows.items()}
    out["overall"] = norm_ratio(np.linalg.norm(res), np.sqrt(sum(float(s @ s) for s in spread.values())))
    return out


def residual_rms(
    W: ArrayLike,
    Y: ArrayLike,
    X: ArrayLike | Mapping[str, float],
    groups: ArrayLike,
    names: Sequence[str] | None = None,
) -> dict[str, float]:
    """RMS of the residual ``Y_g - W_g X`` per equation group (no "overall"): on the identification rows, the
    noise floor `not_excited` compares a test's signal with. Arguments as for `relative_errors`."""
    res, _, rows = _residuals(W, Y, X, groups, names)
    return {name: float(np.sqrt(np.mean(res[idx] ** 2))) for name, idx in rows.items()}

def _residuals(W, Y, X, groups, names) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """Y - W X, Y and the rows of each group, the arguments checked."""
    A = as_matrix(W, names)
    m, p = A.shape
    y = as_vector(Y, m)
    if isinstance(X, Mapping):
        if names is None:
            raise IdentificationError("X given as {name: value} needs names (the parameter of each column of W)")
        missing = [n for n in names if n not in X]
        if missing:
            raise IdentificationError(f"X has no value for parameters {missing}", parameters=missing)
        x = np.array([float(X[n]) for n in names])
    else:
        x = np.asarray(X, dtype=float).reshape(-1)
    if x.shape != (p,):
        raise IdentificationError(f"X must have {p} values (one per column of W), got {x.shape[0]}")
    g = as_groups(groups, m)
    rows = group_rows(g)
    if "overall" in rows:
        raise IdentificationError('"overall" is reserved for the whole system; rename that equation group')
    return y - A @ x, y, rows
