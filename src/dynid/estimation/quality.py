"""Quality indicators: relative standard deviations, the 20x rule of thumb, which groups a test excites.

The validation errors on rows (relative error, NRMSE, residual RMS) are in `validation`: the factors' (`StreamingLS`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike

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
