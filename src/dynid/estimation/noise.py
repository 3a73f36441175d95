"""Per-group noise levels (paper §5.2, eq. (8)): each equation group solved alone on the parameters it identifies.

The core's pieces (`StreamingLS.group_fits` runs them on each group's factor of [W_j | Y_j]); `wls` and
`group_noise` are the batch entries.
"""

from __future__ import annotations

import os
import sys
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .errors import EstimationWarning, IdentificationError
from .lsq import pivoted_qr

SIGMA_FLOOR = 1e-12
"""Relative floor on a group's noise level: ``sigma_j >= SIGMA_FLOOR * rms(Y_j)``.

Noise-free (simulated) data give ``sigma_j = 0`` or round-off; the weight ``1/sigma_j`` would be
infinite or meaningless, so such a group gets the floor instead, with an ``EstimationWarning``.
``rms(Y_j) = ||Y_j|| / sqrt(n_j)``; if Y_j is all zero the rms of the whole Y is used, and 1 if that
is zero too. Noise-free groups then weigh alike relative to their own scale, and the estimate of
noise-free data is still exact.
"""


@dataclass(frozen=True)
class GroupFit:
    """Result of solving one equation group alone (paper eq. (8)).

    group : its label. n_rows : n_j. parameters : names of the p_j parameters it identifies
    (non-zero columns, independent within the group, chosen by pivoted QR), in the caller's order.
    sigma : the noise level used (units of Y_j). raw_sigma : the value of eq. (8) before the floor.
    floored : True when the floor replaced raw_sigma.
    """

    group: str
    n_rows: int
    parameters: tuple[str, ...]
    sigma: float
    raw_sigma: float
    floored: bool


def fit_group(
    group: str,
    A: np.ndarray,
    b: np.ndarray,
    names: Sequence[str],
    *,
    n_rows: int | None = None,
    rank_tol: float | None = None,
    sigma_floor: float = SIGMA_FLOOR,
    fallback_rms: float = 1.0,
) -> GroupFit:
    """Solve one group alone and return its noise level.

    A : (rows, q) the group's rows of W (or a compressed triangular factor of ``[W_j | Y_j]``, with
    ``n_rows`` the group's true row count); b : (rows,) its Y (or compressed right-hand side);
    names : the q parameter names; fallback_rms : scale for the floor if ``Y_j`` is all zero.
    Raises ``IdentificationError`` naming the group if ``n_j <= p_j``.
    """
    n = A.shape[0] if n_rows is None else int(n_rows)
    nz = np.flatnonzero(np.linalg.norm(A, axis=0) > 0)
    fac = pivoted_qr(A[:, nz], b, n_rows=n, rank_tol=rank_tol)
    r = fac.rank
    chosen = nz[fac.piv[:r]]
    params = tuple(names[i] for i in sorted(chosen))
    if n <= r:
        raise IdentificationError(
            f"equation group {group!r} has {n} rows for the {r} parameters it identifies ({', '.join(params)}): "
            "its noise level sigma_j = ||Y_j - W_j X_j|| / sqrt(n_j - p_j) needs more rows than parameters; "
            "add samples of this group (a longer test, or less decimation: a config's [conditioning] decimate "
            "divides the samples by its factors' product; a lower min_speed), merge it with another group, or pass "
            "group_sigmas",
            parameters=params,
            group=group,
        )
    res = np.asarray(b, dtype=float)
    if r:
        assert fac.qtb is not None
        z = sla.solve_triangular(fac.r[:r, :r], fac.qtb[:r])
        res = res - (A[:, chosen] / fac.norms[fac.piv[:r]]) @ z
    raw = float(np.linalg.norm(res) / np.sqrt(n - r))
    rms = float(np.linalg.norm(b) / np.sqrt(n))
    floor = sigma_floor * (rms if rms > 0 else (fallback_rms if fallback_rms > 0 else 1.0))
    floored = not raw >= floor
    return GroupFit(group, n, params, floor if floored else raw, raw, floored)


def warn_floored(fits: Mapping[str, GroupFit]) -> None:
    """One ``EstimationWarning`` listing the groups whose noise level was floored, shown at the first caller
    outside this package (the user's line, whether it called `wls`, `group_noise` or a `StreamingLS`)."""
    low = [f for f in fits.values() if f.floored]
    if low:
        warnings.warn(
            "equation group(s) with a zero or round-off noise level (noise-free data?): "
            + ", ".join(f"{f.group!r} (sigma_j = {f.raw_sigma:.3g}, floored to {f.sigma:.3g})" for f in low)
            + f"; the floor is {SIGMA_FLOOR:g} x rms(Y_j) by default (sigma_floor)",
            EstimationWarning,
            stacklevel=_outside_stacklevel(),
        )


def _outside_stacklevel() -> int:
    """`warnings.warn`'s stacklevel, called from this module's function, that names the first frame outside
    ``dynid.estimation`` (Python 3.11 has no ``skip_file_prefixes``)."""
    here = os.path.dirname(os.path.abspath(__file__))
    frame, level = sys._getframe(2), 2  # the frame that called warn_floored: stacklevel 2
    while frame.f_back is not None and os.path.dirname(os.path.abspath(frame.f_code.co_filename)) == here:
        frame, level = frame.f_back, level + 1
    return level


def checked_sigmas(group_sigmas: Mapping[str, float], present: Sequence[str]) -> dict[str, float]:
    """User-given ``{group: sigma_j}``: exactly the groups present, each finite and > 0."""
    missing = [g for g in present if g not in group_sigmas]
    extra = [g for g in group_sigmas if g not in present]
    if missing or extra:
        raise IdentificationError(
            f"group_sigmas must give one sigma per equation group present; missing {missing}, unknown {extra}",
            group=(missing or extra)[0],
        )
    out = {}
    for g in present:
        s = float(group_sigmas[g])
        if not (np.isfinite(s) and s > 0):
            raise IdentificationError(f"group_sigmas[{g!r}] must be finite and > 0, got {group_sigmas[g]!r}", group=g)
        out[g] = s
    return out
