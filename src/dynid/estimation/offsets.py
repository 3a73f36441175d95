"""The sensors' zero offsets estimated with the parameters: each test's own, their declared σ as the prior.

A zero offset is constant over a test (the sensors are zeroed before each one): an offset of u_k standard
deviations moves the test's rows by u_k (ΔW_k, ΔY_k) (`systematic`, which propagates that pattern to the estimates'
uncertainty). But the data say much of u: a test's straight, level lead-in and the other equations pin a load
cell's or a laser's zero, and what they pin no longer needs to be carried as uncertainty, nor left in the estimate.
So estimate them. With the rows linearised at x0 (the a priori values: the neglected term is u ΔW (x − x0), second
order), a test's rows read

    Y = W x + C u + e,   C_k = ΔY_k − ΔW_k x0,   u ~ N(0, I),

and least squares on [W C | Y] with the prior as m pseudo-rows [0 I | 0] is the estimate with the prior
information (Gauss–Markov with stochastic restrictions, Theil and Goldberger 1961). Each test's offsets touch only its
own rows, so they are eliminated test by test: the QR of the test's weighted [C W | Y] with the prior rows stacked
below leaves, under its first m rows, the test's factor of [W | Y] with its offsets profiled out; the estimate is the
least squares of those reduced factors stacked.

Covariance, with A_r the reduced normal matrix and, per test, R_uu R_ux the first m rows of its triangle: the estimate
moves by ΔX_k = A_r⁻¹ R_uxᵀ R_uu⁻ᵀ e_k per unit of the true u_k, and by A_r⁻¹ (…) e for the noise; the two parts
add up to A_r⁻¹ exactly. So the statistical part (the paper's σ, with the offsets estimated) is
A_r⁻¹ − Σ ΔX_k ΔX_kᵀ, and the offsets' part is Σ ΔX_k ΔX_kᵀ: what the data leave of each offset's effect
(`SystematicUncertainty`, so σ total reads as before; it is ≤ the propagated one).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
from numpy.typing import ArrayLike

from .errors import IdentificationError
from .lsq import LSQSolution, solve_lsq
from .systematic import SystematicUncertainty


@dataclass
class OffsetFactors:
    """Per test and equation group, the triangular factor of the rows [C | W | Y] (C: one column per declared offset
    of the test, its rows' change per one σ, linearised at `x0`).

    columns, known_columns, known_values : as `BiasAccumulator` (the estimated columns of W; the known ones go to
    the right-hand side); x0 : the estimated parameters' linearisation point (their a priori values).
    """

    columns: np.ndarray
    known_columns: np.ndarray
    known_values: np.ndarray
    x0: np.ndarray
    sources: dict[str, tuple[str, ...]] = field(default_factory=dict)
    factors: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    rows: dict[str, dict[str, int]] = field(default_factory=dict)

    def add(self, test: str, sources: Sequence[str], W: ArrayLike, Y: ArrayLike, dW: Sequence[ArrayLike | None],
            dY: Sequence[ArrayLike], groups: ArrayLike) -> None:
        """A segment's rows of `test` and, per source (its declared offsets, the same for every segment of the
        test), the rows' change for a one-σ offset (a dW of None: W unchanged)."""
        self.add_columns(test, sources, W, Y, self.offset_columns(dW, dY, np.shape(Y)[0]), groups)

    def add_columns(self, test: str, sources: Sequence[str], W: ArrayLike, Y: ArrayLike, C: ArrayLike,
                    groups: ArrayLike) -> None:
        """`add` with the offsets' columns C (rows, m) given (`offset_columns`, or the rows' residual at `point`
        moved by each offset)."""
        sources = tuple(sources)
        if self.sources.setdefault(test, sources) != sources:
            raise IdentificationError(f"test {test!r}: its segments declare other offsets ({sources} against "
                                      f"{self.sources[test]}); a test's offsets are the same on every segment")
        W, Y, C = np.asarray(W, dtype=float), np.asarray(Y, dtype=float), np.asarray(C, dtype=float)
        if C.shape != (len(Y), len(sources)):
            raise IdentificationError(f"test {test!r}: offsets' columns of shape {C.shape} for {len(Y)} rows and "
                                      f"{len(sources)} offsets")
        groups = np.asarray(groups)
        Y = Y - W[:, self.known_columns] @ self.known_values
        block = np.column_stack([C, W[:, self.columns], Y])
        per, counts = self.factors.setdefault(test, {}), self.rows.setdefault(test, {})
        for g in dict.fromkeys(groups.tolist()):
            rows = groups == g
            stacked = block[rows] if g not in per else np.vstack([per[g], block[rows]])
            per[g] = np.linalg.qr(stacked, mode="r")
            counts[g] = counts.get(g, 0) + int(rows.sum())

    def point(self, width: int) -> np.ndarray:
        """The linearisation point as one value per column of W (`width` columns): x0 in the estimated ones, the
        known values in the known ones, 0 elsewhere; C_k = Δ(Y − W point) for offset k (`offset_columns`)."""
        x = np.zeros(width)
        x[self.known_columns] = self.known_values
        x[self.columns] = self.x0
        return x

    def offset_columns(self, dW: Sequence[ArrayLike | None], dY: Sequence[ArrayLike], rows: int) -> np.ndarray:
        """(rows, m) the offsets' columns C_k = ΔY_k − ΔW_k x0 (the known parameters' columns at their values) of
        rows whose change per one-σ offset is (dW, dY) (a dW of None: W unchanged)."""
        kv = self.known_values
        C = np.empty((rows, len(dY)))
        for k, (w, y) in enumerate(zip(dW, dY, strict=True)):
            C[:, k] = y
            if w is not None:
                w = np.asarray(w, dtype=float)
                C[:, k] -= w[:, self.known_columns] @ kv + w[:, self.columns] @ self.x0
        return C

    def merge(self, other: OffsetFactors) -> OffsetFactors:
        """A new accumulator with both one's rows (segments reduced apart, combined)."""
        out = OffsetFactors(self.columns, self.known_columns, self.known_values, self.x0, dict(self.sources),
                            {t: dict(p) for t, p in self.factors.items()}, {t: dict(c) for t, c in self.rows.items()})
        for test, per in other.factors.items():
            if out.sources.setdefault(test, other.sources[test]) != other.sources[test]:
                raise IdentificationError(f"test {test!r}: its segments declare other offsets")
            mine, counts = out.factors.setdefault(test, {}), out.rows.setdefault(test, {})
            for g, R in per.items():
                mine[g] = R if g not in mine else np.linalg.qr(np.vstack([mine[g], R]), mode="r")
                counts[g] = counts.get(g, 0) + other.rows[test][g]
        return out

    def group_rms(self, x: ArrayLike, u: Mapping[str, np.ndarray], exclude: Sequence[str] = ()) -> dict[str, float]:
        """Per group the RMS of Y − W x − C u over every test: the residual with the offsets the data read (u: test
        -> its offsets in declared σ, `OffsetEstimate.u`) taken out; of Y − W x in the `exclude` groups."""
        x = np.asarray(x, dtype=float)
        ss: dict[str, float] = {}
        for test, per in self.factors.items():
            u_t = np.asarray(u[test], dtype=float)
            for g, R in per.items():
                v = np.concatenate([np.zeros(len(u_t)) if g in exclude else -u_t, -x, [1.0]])
                ss[g] = ss.get(g, 0.0) + float(np.sum((R @ v) ** 2))
        rows = self.group_rows
        return {g: float(np.sqrt(ss[g] / rows[g])) for g in ss}

    @property
    def group_rows(self) -> dict[str, int]:
        """Rows per equation group over every test."""
        out: dict[str, int] = {}
        for counts in self.rows.values():
            for g, n in counts.items():
                out[g] = out.get(g, 0) + n
        return out


@dataclass(frozen=True)
class OffsetEstimate:
    """The estimate with the offsets estimated: `solution` (its covariance the statistical part), `systematic`
    (what the data leave of the offsets' effect), and per source ("test: channel") the offset in units of its σ
    with its standard deviation."""

    solution: LSQSolution
    systematic: SystematicUncertainty
    offsets: dict[str, tuple[float, float]]
    u: dict[str, np.ndarray]  # test -> its offsets' estimate, in declared σ, order `OffsetFactors.sources`
    # the reduced normal matrix's inverse A_r⁻¹ (weighted rows, the prior in; a HAC covariance's bread), and per test
    # Γ = R_uu⁻¹ R_ux (m, q): its offsets' regression on the weighted W (the profiled rows are W̃ − C̃ Γ)
    inv_gram: np.ndarray | None = None
    profile: dict[str, np.ndarray] = field(default_factory=dict)
    exclude: tuple[str, ...] = ()  # the groups left out of the offsets' estimate
    weights: dict[str, float] = field(default_factory=dict)  # {group: σ_g} the rows were weighted by


def _without_offsets(R: np.ndarray, m: int) -> np.ndarray:
    """The factor of [C | W | Y] with its offsets' columns C zeroed: the QR of its last columns has the same inner
    products as [W | Y] (Qᵀ Q = I)."""
    Rw = np.linalg.qr(R[:, m:], mode="r")
    return np.hstack([np.zeros((Rw.shape[0], m)), Rw])


def solve_with_offsets(acc: OffsetFactors, names: Sequence[str], sigmas: Mapping[str, float] | None = None,
                       rank_tol: float | None = None, sigma2: float | None = None,
                       exclude: Sequence[str] = ()) -> OffsetEstimate:
    """Weighted least squares (σ_g per group; None: all 1) with each test's offsets estimated (module doc).
    sigma2: the scale of the rows' covariance (the weighted system's σ² without the offsets, `solve_weighted`'s;
    1 when the weights are the noise's standard deviations); None: from this system's residual. exclude: groups
    whose rows neither inform the offsets nor are corrected by them (a group the model does not fit: its residual
    is the model's error, not a zero offset; measured on the MuJoCo car, its tires' line read into the lasers'
    offsets and moved their kt by 5 %)."""
    names = tuple(names)
    q = len(names)
    reduced, heads, rows = [], {}, 0
    for test, per in acc.factors.items():
        m = len(acc.sources[test])
        # an excluded group's factor of [W | Y] alone: the QR of its factor's last columns (same inner products)
        blocks = [(R if g not in exclude else _without_offsets(R, m)) / (1.0 if sigmas is None else sigmas[g])
                  for g, R in per.items()]
        rows += sum(acc.rows[test].values())
        prior = np.hstack([np.eye(m), np.zeros((m, q + 1))])
        R = np.linalg.qr(np.vstack([*blocks, prior]), mode="r")
        heads[test] = (R[:m, :m], R[:m, m:m + q], R[:m, m + q])
        reduced.append(R[m:, m:])
    R_red = reduced[0] if len(reduced) == 1 else np.linalg.qr(np.vstack(reduced), mode="r")
    total = solve_lsq(R_red[:, :q], R_red[:, q], names, n_rows=rows, rank_tol=rank_tol,
                      context="W with the sensor offsets estimated")
    if sigma2 is not None:
        total = dataclasses.replace(total, sigma2=float(sigma2), covariance=float(sigma2) * total.inv_gram)
    shifts, offsets, us, profile = {}, {}, {}, {}
    s = np.sqrt(total.sigma2)
    for test, (Ruu, Rux, ruy) in heads.items():
        # per unit of the true u: ΔX = A_r⁻¹ R_uxᵀ R_uu⁻ᵀ (module doc), in the weighted rows' scale s
        Ruu_inv = sla.solve_triangular(Ruu, np.eye(len(Ruu)))
        dX = s * total.inv_gram @ Rux.T @ Ruu_inv.T
        u = us[test] = Ruu_inv @ (ruy - Rux @ total.x)  # the offsets' estimate given x
        # u's covariance: (R_uuᵀR_uu)⁻¹ given x, plus x's own through R_uu⁻¹ R_ux
        H = profile[test] = Ruu_inv @ Rux
        cov_u = total.sigma2 * (Ruu_inv @ Ruu_inv.T) + H @ total.covariance @ H.T
        for k, source in enumerate(acc.sources[test]):
            key = f"{test}: {source}"
            shifts[key] = dX[:, k]
            offsets[key] = (float(u[k]), float(np.sqrt(max(cov_u[k, k], 0.0))))
    systematic = SystematicUncertainty(names, sum((np.outer(d, d) for d in shifts.values()), np.zeros((q, q))), shifts)
    statistical = total.covariance - systematic.covariance
    solution = LSQSolution(total.x, statistical / total.sigma2, total.rss, total.n_rows, total.dof, total.sigma2,
                           statistical, total.condition_number)
    weights = {g: 1.0 if sigmas is None else float(sigmas[g]) for per in acc.factors.values() for g in per}
    return OffsetEstimate(solution, systematic, offsets, us, total.inv_gram, profile, tuple(exclude), weights)


@dataclass
class NoiseScores:
    """One draw of the rows' noise as it is, for the estimator's spread (a sandwich that keeps the noise's
    correlation across equation groups and between neighbouring rows).

    Per test, e (the noisy rows' residual at x0 less the noise-free rows', row by row: the noise the rows carry)
    times the noise-free rows' [C | W] (`OffsetFactors`' columns), summed per equation group and row time stamp
    (integer, in rows): a_{g,t} (m + q). At weights w_g = 1 / σ_g² and a test's profile P = [−R_uu⁻¹ R_ux; I]
    ((m + q, q): its offsets read taken out) the scores are s_t = Pᵀ Σ_g w_g a_{g,t} summed over the groups of
    one stamp (one sensor's noise sits in several groups' rows at once), and their covariance is
    S = Σ_{|l| ≤ lag} Σ_t s_t s_{t−l}ᵀ (uniform kernel: rows closer than the conditioning's correlation time);
    the estimate's noise covariance is A_r⁻¹ (Σ_tests S) A_r⁻¹. The sums are kept per group, so any draw of the
    weights reweights them without the rows."""

    lag: int
    # test -> draw of the noise -> its segments' (stamps, groups, [C | W] e)
    chunks: dict[str, dict[int, list[tuple[np.ndarray, np.ndarray, np.ndarray]]]] = field(default_factory=dict)
    _dense: dict[tuple[str, int], tuple[tuple[str, ...], np.ndarray]] = field(default_factory=dict, repr=False,
                                                                             compare=False)

    def add(self, test: str, stamps: ArrayLike, groups: ArrayLike, CW: ArrayLike, e: ArrayLike, draw: int = 0
            ) -> None:
        """A segment's rows of `test`: their time stamps (integer, in rows), groups, noise-free [C | W] and noise e
        of one draw of the noise (several draws: S their mean)."""
        CW, e = np.asarray(CW, dtype=float), np.asarray(e, dtype=float)
        if CW.shape[0] != len(e):
            raise IdentificationError(f"NoiseScores.add, test {test!r}: {CW.shape[0]} rows of [C | W] for {len(e)} "
                                      "of noise; give both of the same (kept) rows")
        self.chunks.setdefault(test, {}).setdefault(draw, []).append(
            (np.asarray(stamps, dtype=np.int64), np.asarray(groups), CW * e[:, None]))

    def merge(self, other: NoiseScores) -> NoiseScores:
        """A new accumulator with both one's rows (segments reduced apart, combined)."""
        if other.lag != self.lag:
            raise IdentificationError(f"NoiseScores.merge: lags {self.lag} and {other.lag}; reduce every segment "
                                      "with one conditioning")
        out = NoiseScores(self.lag, {t: {d: list(c) for d, c in per.items()} for t, per in self.chunks.items()})
        for t, per in other.chunks.items():
            for d, c in per.items():
                out.chunks.setdefault(t, {}).setdefault(d, []).extend(c)
        return out

    def dense(self, test: str, draw: int = 0) -> tuple[tuple[str, ...], np.ndarray]:
        """The test's groups and a draw's sums a (stamps, groups, m + q), every stamp from the first to the last
        (zero where no row falls: a gap is no neighbour)."""
        key = (test, draw)
        if key not in self._dense:
            chunks = self.chunks[test][draw]
            stamps = np.concatenate([c[0] for c in chunks])
            groups = np.concatenate([c[1] for c in chunks])
            rows = np.vstack([c[2] for c in chunks])
            names, gi = np.unique(groups, return_inverse=True)
            a = np.zeros((int(stamps.max() - stamps.min()) + 1, len(names), rows.shape[1]))
            np.add.at(a, (stamps - stamps.min(), gi), rows)
            self._dense[key] = (tuple(names.tolist()), a)
        return self._dense[key]

    def covariance(self, test: str, weights: Mapping[str, float], profile: np.ndarray) -> np.ndarray:
        """S (q, q) of the test's scores at weights {group: w_g} (1 / σ_g²) and profile P (m + q, q) (class doc),
        the mean over the draws of the noise."""
        q = profile.shape[1]
        S = np.zeros((q, q))
        draws = self.chunks[test]
        for d in draws:
            groups, a = self.dense(test, d)
            w = np.array([weights[g] for g in groups])
            s = np.einsum("tgk,g->tk", a, w) @ profile  # (stamps, q): the scores summed over a stamp's groups
            S += s.T @ s
            for lag in range(1, min(self.lag, len(s) - 1) + 1):
                G = s[lag:].T @ s[:-lag]
                S += G + G.T
        return S / len(draws)
