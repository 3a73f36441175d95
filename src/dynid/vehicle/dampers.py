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


# ----- knees from the data ------------------------------------------------------------------------------------------
KNEE_GRID = np.geomspace(0.012, 0.9, 111)
"""m/s: the candidate knees (4 % apart, within the vehicle file's 0.005-2 m/s); the data keep those both of whose
pieces hold rows (KNEE_SHARE, KNEE_ROWS), and the best is refined between its neighbours."""
KNEE_SHARE = 0.01
KNEE_ROWS = 10
"""Each piece of a side (below and past its knee) holds at least KNEE_SHARE of that side's rows and KNEE_ROWS rows:
a slope is estimated from data, not from a handful of peaks (the demo's tests put 1-8 % of a side's rows past
0.1 m/s)."""


class KneeSearch:
    """The knees of damper curves from the data: a breakpoint search on each damper's own equation group.

    Per damper, the group's rows as the linear law writes them (its columns W, h q' among them, and Y) and the
    columns of every candidate curve: max(q', 0) and the hinges max(q' - c, 0), min(q' + c, 0) at each candidate
    knee c (KNEE_GRID), conditioned and decimated as W. With q' these span the curve of knees (-cr, cb) exactly
    (clip(q', 0, cb) = max(q', 0) - max(q' - cb, 0), and likewise in rebound), so the group's least-squares residual
    with the curve of any pair of candidates comes from one triangular factor of [W | hinges | Y] accumulated over
    the rows (`add`, `merge`, as `estimation.StreamingLS`). `knees` takes, per damper, the pair whose residual is
    least among those whose four pieces hold rows (KNEE_SHARE, KNEE_ROWS), refined by a parabola through its
    neighbours in log c: the knee where the slope changes, as a segmented regression finds it. rate: the rows'
    clearance rate, which counts the rows on each piece."""

    def __init__(self, grid: np.ndarray = KNEE_GRID) -> None:
        self.grid = np.asarray(grid, dtype=float)
        self._R: dict[int, np.ndarray] = {}
        self._counts: dict[int, np.ndarray] = {}  # (4, G): rows with q' > 0 below c, past c; q' < 0 below, past

    def hinges(self, rate: Array) -> Array:
        """(N, 1 + 2G) columns max(q', 0), max(q' - c, 0) for each c, min(q' + c, 0) for each c; rate (N,)."""
        r = np.asarray(rate, dtype=float)[:, None]
        return np.concatenate([np.maximum(r, 0.0), np.maximum(r - self.grid, 0.0), np.minimum(r + self.grid, 0.0)],
                              axis=1)

    def add(self, damper: int, W: Array, Y: Array, H: Array, rate: Array) -> None:
        """Rows of one damper's group: W (n, p), Y (n,), H (n, 1 + 2G) its `hinges` conditioned as W, rate (n,)
        the rows' clearance rate (m/s)."""
        block = np.column_stack([W, H, Y])
        R = self._R.get(damper)
        self._R[damper] = np.linalg.qr(block if R is None else np.vstack([R, block]), mode="r")
        r = np.asarray(rate, dtype=float)[:, None]
        c = self.grid
        counts = np.stack([((r > 0) & (r <= c)).sum(0), (r > c).sum(0), ((r < 0) & (r >= -c)).sum(0),
                           (r < -c).sum(0)])
        self._counts[damper] = self._counts.get(damper, 0) + counts

    def merge(self, other: KneeSearch) -> KneeSearch:
        out = KneeSearch(self.grid)
        for d in dict.fromkeys([*self._R, *other._R]):
            parts = [s._R[d] for s in (self, other) if d in s._R]
            out._R[d] = parts[0] if len(parts) == 1 else np.linalg.qr(np.vstack(parts), mode="r")
            out._counts[d] = self._counts.get(d, 0) + other._counts.get(d, 0)
        return out

    def knees(self) -> dict[int, tuple[float, float]]:
        """{damper: (v-, v+)} m/s, the knees where each damper's slopes change (class doc); inf on a side whose
        rates leave no candidate (too few rows past every knee: one slope there). The search: every third
        candidate of both sides, then each side's best given the other's, in turn, until neither moves."""
        out = {}
        for d in self._R:
            rss = self._residuals(d)
            bump, rebound = self._allowed(d)
            i = min(((i, k) for i in bump[::3] for k in rebound[::3]), key=lambda ik: rss(*ik))
            i, k = i
            for _ in range(20):
                i2 = min(bump, key=lambda j: rss(j, k))
                k2 = min(rebound, key=lambda j: rss(i2, j))
                if (i2, k2) == (i, k):
                    break
                i, k = i2, k2
            G = self.grid.size
            out[d] = (-self._refined([rss(i, j) for j in (k - 1, k, k + 1)], k, rebound) if k < G else -np.inf,
                      self._refined([rss(j, k) for j in (i - 1, i, i + 1)], i, bump) if i < G else np.inf)
        return out

    def _allowed(self, damper: int) -> tuple[list[int], list[int]]:
        """The candidates (grid indices) whose two pieces hold rows enough, bump and rebound; [G] (no knee) for a
        side without any."""
        c, G = self._counts[damper], self.grid.size

        def allowed(below: Array, past: Array) -> list[int]:
            least = np.minimum(below, past)
            ok = np.flatnonzero((least >= KNEE_SHARE * (below + past)) & (least >= KNEE_ROWS))
            return [int(i) for i in ok] or [G]

        return allowed(c[0], c[1]), allowed(c[2], c[3])

    def _residuals(self, damper: int):
        """rss(i, k): the group's residual sum of squares with the curve of knees (-grid[k], grid[i]), index G for
        no knee on that side; inf for an index outside the grid or a rank-deficient fit. Cached."""
        R, G = self._R[damper], self.grid.size
        p = R.shape[1] - 2 - 2 * G
        live = [j for j in range(p) if np.any(R[:, j] != 0.0)]
        norms = np.linalg.norm(R, axis=0)
        A = R / np.where(norms > 0, norms, 1.0)  # unit columns: the conditioning is the data's, not the units'
        y = R[:, -1]
        cache: dict[tuple[int, int], float] = {}

        def rss(i: int, k: int) -> float:
            if not (0 <= i <= G and 0 <= k <= G):
                return np.inf
            if (i, k) not in cache:
                cols = [*live, p, *([p + 1 + i] if i < G else []), *([p + 1 + G + k] if k < G else [])]
                x, _res, rank, _sv = np.linalg.lstsq(A[:, cols], y, rcond=None)
                cache[i, k] = float(np.sum((A[:, cols] @ x - y) ** 2)) if rank == len(cols) else np.inf
            return cache[i, k]

        return rss

    def _refined(self, rss: Sequence[float], i: int, allowed: Sequence[int]) -> float:
        """The knee of least residual along one side: the vertex of the parabola in log c through grid point i and
        its two neighbours (rss, in that order), when both are allowed and it is a minimum; else grid point i."""
        x = np.log(self.grid)
        if i - 1 in allowed and i + 1 in allowed and np.isfinite(rss).all():
            a, b, _ = np.polyfit(x[i - 1 : i + 2], rss, 2)
            if a > 0:
                return float(np.exp(np.clip(-b / (2 * a), x[i - 1], x[i + 1])))
        return float(self.grid[i])
