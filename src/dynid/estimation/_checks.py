"""Input checks shared by the estimators: shapes, finiteness, names, groups, known parameters.

Bad input raises ``IdentificationError`` saying what is wrong and where (row, parameter,
group); nothing here guesses.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from .errors import IdentificationError


def as_names(names: Sequence[str], p: int | None = None) -> tuple[str, ...]:
    """Parameter names as a tuple of unique non-empty strings, ``p`` of them if given."""
    if isinstance(names, str):
        raise IdentificationError(f"names must be a sequence of parameter names, got the single string {names!r}")
    out = tuple(names)
    bad = [n for n in out if not isinstance(n, str) or not n]
    if bad:
        raise IdentificationError(f"parameter names must be non-empty strings; got {bad[:5]!r}")
    if p is not None and len(out) != p:
        raise IdentificationError(f"W has {p} columns but {len(out)} parameter names were given")
    dup = sorted(n for n, count in Counter(out).items() if count > 1)
    if dup:
        raise IdentificationError(f"duplicate parameter names: {dup}", parameters=dup)
    return out


def as_matrix(W: ArrayLike, names: Sequence[str] | None = None, what: str = "W") -> np.ndarray:
    """``W`` as a finite float64 (m, p) array; the first bad entry is reported by row and parameter."""
    A = np.asarray(W, dtype=float)
    if A.ndim != 2:
        raise IdentificationError(f"{what} must be a 2-D (rows, parameters) array, got shape {A.shape}")
    bad = ~np.isfinite(A)
    if bad.any():
        rows, cols = np.nonzero(bad)
        col = names[cols[0]] if names is not None and cols[0] < len(names) else f"column {cols[0]}"
        raise IdentificationError(
            f"{what} has {bad.sum()} non-finite value(s) (NaN or inf), first at row {rows[0]}, parameter {col!r}; "
            "clean or drop those samples before identification"
        )
    return A


def as_vector(Y: ArrayLike, m: int, what: str = "Y") -> np.ndarray:
    """``Y`` as a finite float64 (m,) array."""
    y = np.asarray(Y, dtype=float)
    if y.ndim == 2 and y.shape[1] == 1:
        y = y[:, 0]
    if y.ndim != 1 or y.shape[0] != m:
        raise IdentificationError(f"{what} must have shape ({m},) to match W's rows, got {y.shape}")
    bad = np.flatnonzero(~np.isfinite(y))
    if bad.size:
        raise IdentificationError(
            f"{what} has {bad.size} non-finite value(s) (NaN or inf), first at row {bad[0]}; "
            "clean or drop those samples before identification"
        )
    return y


def as_groups(groups: ArrayLike, m: int) -> np.ndarray:
    """Equation group of each row as a (m,) array of str."""
    g = np.asarray(groups)
    if g.ndim != 1 or g.shape[0] != m:
        raise IdentificationError(f"groups must be a 1-D array with one label per row of W ({m}), got shape {g.shape}")
    return g.astype(str)


def group_rows(groups: np.ndarray) -> dict[str, np.ndarray]:
    """``{group: row indices}`` in order of first appearance."""
    labels, first, inverse = np.unique(groups, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    return {str(labels[k]): np.flatnonzero(inverse == k) for k in order}


def as_value_map(values: Mapping[str, float] | None, names: Sequence[str], what: str) -> dict[str, float]:
    """A name->float mapping whose keys must all be parameter names (a typo is an error, not ignored)."""
    if values is None:
        return {}
    unknown = [k for k in values if k not in names]
    if unknown:
        raise IdentificationError(f"{what} names parameters that are not in names: {unknown}", parameters=unknown)
    out = {}
    for k, v in values.items():
        x = float(v)
        if not np.isfinite(x):
            raise IdentificationError(f"{what}[{k!r}] is not finite: {v!r}", parameters=[k])
        out[k] = x
    return out


def as_label_map(labels: Mapping[str, str] | None, names: Sequence[str]) -> dict[str, str]:
    """``{name: label}`` for every parameter, the name itself where no label is given."""
    given = dict(labels or {})
    unknown = [k for k in given if k not in names]
    if unknown:
        raise IdentificationError(f"labels names parameters that are not in names: {unknown}", parameters=unknown)
    return {n: str(given.get(n, n)) for n in names}


@dataclass(frozen=True)
class KnownSplit:
    """A problem with the user-fixed parameters moved to the right-hand side.

    W_est : (m, q) columns of the parameters still to estimate, in the order of ``est_names``.
    Y_est : (m,) ``Y - W_known @ x_known``.
    est_names : names of the q estimated parameters (original order).
    known : ``{name: value}`` of the fixed parameters.
    """

    W_est: np.ndarray
    Y_est: np.ndarray
    est_names: tuple[str, ...]
    known: dict[str, float]


def split_known(W: np.ndarray, Y: np.ndarray, names: Sequence[str], known: Mapping[str, float] | None) -> KnownSplit:
    """Move the columns of known parameters to the right-hand side: ``Y <- Y - W_known x_known``."""
    kn = as_value_map(known, names, "known")
    if not kn:
        return KnownSplit(W, Y, tuple(names), {})
    est = [i for i, n in enumerate(names) if n not in kn]
    if not est:
        raise IdentificationError("every parameter is fixed as known: there is nothing left to estimate")
    kidx = [i for i, n in enumerate(names) if n in kn]
    xk = np.array([kn[names[i]] for i in kidx])
    return KnownSplit(W[:, est], Y - W[:, kidx] @ xk, tuple(names[i] for i in est), kn)


@dataclass(frozen=True)
class Problem:
    """A checked identification problem.

    names : the p parameter names. W : (m, p). Y : (m,). labels/a_priori/truth : by name.
    split : the problem with known parameters moved to the right-hand side.
    """

    names: tuple[str, ...]
    W: np.ndarray
    Y: np.ndarray
    labels: dict[str, str]
    a_priori: dict[str, float]
    truth: dict[str, float]
    split: KnownSplit


def prepare(
    W: ArrayLike,
    Y: ArrayLike,
    names: Sequence[str],
    *,
    labels: Mapping[str, str] | None = None,
    a_priori: Mapping[str, float] | None = None,
    truth: Mapping[str, float] | None = None,
    known: Mapping[str, float] | None = None,
) -> Problem:
    """Check every input and move the known parameters to the right-hand side."""
    nm, A, y = checked_rows(W, Y, names)
    return Problem(
        names=nm,
        W=A,
        Y=y,
        labels=as_label_map(labels, nm),
        a_priori=as_value_map(a_priori, nm, "a_priori"),
        truth=as_value_map(truth, nm, "truth"),
        split=split_known(A, y, nm, known),
    )


def checked_rows(W: ArrayLike, Y: ArrayLike, names: Sequence[str]) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """Names, W (m, p) and Y (m,) checked against each other: finite, one name per column, one Y per row."""
    nm = as_names(names)
    A = as_matrix(W, nm)
    as_names(nm, A.shape[1])
    return nm, A, as_vector(Y, A.shape[0])


def norm_ratio(num: float, den: float) -> float:
    """``num / den`` for norms, with 0/0 = 0 and x/0 = inf."""
    if den == 0.0:
        return 0.0 if num == 0.0 else float("inf")
    return float(num / den)
