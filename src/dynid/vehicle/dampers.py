"""An identified damper's force-velocity curve with its band, and its slopes in an engineer's terms.

The damper's viscous force is linear in its parameters: h q' (the paper's law) or the curve of four slopes
hbl hbh hrl hrh about the knees (car_model.car_template(damper_knees=...), docs/vehicle.md 'Damper curves'); bump
is q' > 0. So at a velocity v the force is phi(v) . x, phi the engine's own columns (newton_euler.joint_term_column)
and x the estimates, and its variance is phi(v)^T C phi(v), C their covariance: the band is exact to first order
(it is linear), correlations between the slopes included. The dry friction fs sign(q') is left out: a damper
dyno sheet plots the velocity-dependent part, and fs is its own row of the results.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..dynamics.newton_euler import joint_term_column
from ..model.tree import CURVE_TERMS, NO_KNEES
from .template import CURVE_LABELS, CURVE_MEANINGS

Array = np.ndarray


class Estimates(Protocol):
    """What the curve needs of a result (estimation.IdentificationResult has it)."""

    names: tuple[str, ...]
    values: Array

    @property
    def full_covariance(self) -> Array: ...


@dataclass(frozen=True)
class Slope:
    """One slope of a damper: its name (FVPL9), label (hbl9), meaning ("bump, low speed"), value and σ in
    N·s/m, and the velocity range it holds on (m/s; bump positive)."""

    name: str
    label: str
    meaning: str
    value: float
    std: float
    range: tuple[float, float]


def _terms(names: Sequence[str], damper: int) -> list[str]:
    curve = [t for t in CURVE_TERMS if f"{t}{damper}" in names]
    return curve if curve else (["FV"] if f"FV{damper}" in names else [])


def damper_curve(result: Estimates, damper: int, velocities: Array,
                 knees: tuple[float, float] = NO_KNEES) -> tuple[Array, Array]:
    """(force, σ) of damper `damper`'s viscous force at the clearance rates `velocities` (m/s, bump > 0), N, each
    shaped like `velocities`; knees: its (v-, v+) (Tree.knee). A damper the result has no viscous term for is an
    error naming it."""
    names = list(result.names)
    terms = _terms(names, damper)
    if not terms:
        raise KeyError(f"the result has no viscous term of damper {damper} (h{damper} or hbl{damper} ...)")
    v = np.asarray(velocities, dtype=float)
    flat = v.reshape(-1)
    zero = np.zeros_like(flat)
    idx = [names.index(f"{t}{damper}") for t in terms]
    phi = np.stack([joint_term_column(t, zero, flat, zero, knees=knees) for t in terms], axis=1)  # (N, k)
    force = phi @ np.asarray(result.values, dtype=float)[idx]
    C = np.asarray(result.full_covariance)[np.ix_(idx, idx)]
    var = np.einsum("ni,ij,nj->n", phi, C, phi)
    return force.reshape(v.shape), np.sqrt(np.maximum(var, 0.0)).reshape(v.shape)


def damper_slopes(result: Estimates, damper: int, knees: tuple[float, float] = NO_KNEES,
                  labels: Mapping[str, str] | None = None) -> list[Slope]:
    """The slopes of damper `damper` in the results (four with a curve, one, h, with the paper's law), with σ."""
    names = list(result.names)
    C = np.asarray(result.full_covariance)
    lo, hi = knees
    ranges = {"FVPL": (0.0, hi), "FVPH": (hi, np.inf), "FVNL": (lo, 0.0), "FVNH": (-np.inf, lo),
              "FV": (-np.inf, np.inf)}
    out = []
    for t in _terms(names, damper):
        n = f"{t}{damper}"
        i = names.index(n)
        label = (labels or {}).get(n, f"{CURVE_LABELS[t]}{damper}" if t in CURVE_LABELS else f"h{damper}")
        out.append(Slope(n, label, CURVE_MEANINGS.get(t, "both directions"), float(result.values[i]),
                         float(np.sqrt(max(C[i, i], 0.0))), (float(ranges[t][0]), float(ranges[t][1]))))
    return out
