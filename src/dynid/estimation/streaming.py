"""Least squares on data too big to hold: incremental QR, per equation group.

For each group g, the accumulator keeps the (q+1, q+1) triangular factor R_g of ``[W_g | Y_g]``
(q estimated parameters), updated per chunk by a QR of ``[R_g; W_chunk Y_chunk]``. Since
``[W_g | Y_g] = Q_g R_g`` with Q_g orthonormal, R_g keeps everything least squares needs:
column norms and inner products of W_g, ``W_g^T Y_g``, ``||Y_g||``, and for any X the residual
norm ``||Y_g - W_g X|| = ||R_g [X; -1]||``. So:

- OLS: QR of the stacked R_g gives the factor of the whole ``[W | Y]``; the batch solver runs
  on it with the true row count and gives the same X, sigma and covariance as ``ols``;
- WLS needs no second pass over the data: the per-group fits (eq. (8)) run on each R_g, and the
  weighted system (eq. (10)) is the QR of the stacked ``R_g / sigma_j``.

Memory: (q+1)^2 floats per group, whatever the number of rows.

Accumulators combine exactly: the factor of two row sets stacked is the QR of their two factors
stacked (`merge`), so segments of a long record can be reduced anywhere (threads, a cluster's
workers) and combined by a tree of reductions; the answer is the one-pass answer to round-off.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ._checks import (
    as_groups,
    as_label_map,
    as_matrix,
    as_names,
    as_value_map,
    as_vector,
    checked_rows,
    group_rows,
    norm_ratio,
    split_known,
)
from .errors import IdentificationError
from .hac import SUMMED, HACSums
from .iv import InstrumentSums, iv_covariance
from .lsq import LSQSolution, solve_lsq
from .method import Covariance, Method
from .noise import SIGMA_FLOOR, GroupFit, checked_sigmas, fit_group, warn_floored
from .offsets import OffsetEstimate, OffsetFactors, solve_with_offsets
from .quality import POOR_FACTOR
from .result import IdentificationResult, build_result
from .systematic import BiasAccumulator, propagate

DEFAULT_GROUP = "all"
"""Group label of rows added without ``group_labels``."""


class StreamingLS:
    """Accumulate ``(W, Y)`` chunk by chunk; solve by OLS or by WLS without holding W.

    names : the p parameter names (W's column order), or an int p for names x1..xp.
    labels, a_priori, truth, known, rank_tol, poor_factor : as in ``ols``; the known parameters
    are moved to the right-hand side chunk by chunk.
    """

    def __init__(
        self,
        names: Sequence[str] | int,
        *,
        labels: Mapping[str, str] | None = None,
        a_priori: Mapping[str, float] | None = None,
        truth: Mapping[str, float] | None = None,
        known: Mapping[str, float] | None = None,
        rank_tol: float | None = None,
        poor_factor: float = POOR_FACTOR,
    ) -> None:
        if isinstance(names, int | np.integer):
            names = [f"x{k + 1}" for k in range(int(names))]
        self.names: tuple[str, ...] = as_names(names)
        self.labels = as_label_map(labels, self.names)
        self.a_priori = as_value_map(a_priori, self.names, "a_priori")
        self.truth = as_value_map(truth, self.names, "truth")
        self.known = as_value_map(known, self.names, "known")
        self.estimated_names = tuple(n for n in self.names if n not in self.known)
        if not self.estimated_names:
            raise IdentificationError("every parameter is fixed as known: there is nothing left to estimate")
        self.rank_tol = rank_tol
        self.poor_factor = poor_factor
        self._R: dict[str, np.ndarray] = {}
        self._rows: dict[str, int] = {}
        self._y2: dict[str, float] = {}
        self._sum: dict[str, np.ndarray] = {}  # column sums of the rows [W | Y] (every column): the groups' means

    # ----------------------------------------------------------------- accumulation
    @property
    def n_rows(self) -> int:
        """Rows added so far."""
        return sum(self._rows.values())

    @property
    def group_rows(self) -> dict[str, int]:
        """``{group: rows added}`` in order of first appearance."""
        return dict(self._rows)

    def add(self, W_chunk: ArrayLike, Y_chunk: ArrayLike, group_labels: ArrayLike | None = None) -> None:
        """Add rows: W_chunk (c, p), Y_chunk (c,), group_labels (c,) equation group per row
        (default: all rows in group ``"all"``)."""
        A = as_matrix(W_chunk, self.names, "W chunk")
        if A.shape[1] != len(self.names):
            raise IdentificationError(f"W chunk has {A.shape[1]} columns, expected {len(self.names)} (one per name)")
        self._add_checked(A, as_vector(Y_chunk, A.shape[0], "Y chunk"), group_labels)

    def _add_checked(self, A: np.ndarray, y: np.ndarray, group_labels: ArrayLike | None) -> None:
        """`add` of rows already checked (finite float arrays, one column per name): `one_block` checks a batch
        with the batch messages, and a second pass over W would cost a tenth of an OLS."""
        if A.shape[0] == 0:
            return
        split = split_known(A, y, self.names, self.known)
        # no labels: one group, the whole block (a slice: no copy of the rows by fancy indexing)
        parts: dict[str, slice | np.ndarray] = (
            {DEFAULT_GROUP: slice(None)} if group_labels is None else group_rows(as_groups(group_labels, A.shape[0])))
        q = len(self.estimated_names)
        for name, idx in parts.items():
            block = np.column_stack([split.W_est[idx], split.Y_est[idx]])
            # a group's first block of at least q+1 rows is factored alone (a batch's one QR, as a plain solve's)
            stacked = block if name not in self._R and block.shape[0] > q else np.vstack(
                [self._R.get(name, np.zeros((q + 1, q + 1))), block])
            self._R[name] = np.linalg.qr(stacked, mode="r")
            self._rows[name] = self._rows.get(name, 0) + block.shape[0]
            self._y2[name] = self._y2.get(name, 0.0) + float(y[idx] @ y[idx])
            total = np.append(A[idx].sum(axis=0), y[idx].sum())
            self._sum[name] = total if name not in self._sum else self._sum[name] + total

    def empty(self) -> StreamingLS:
        """An accumulator of the same columns (names, known values, settings) with no rows: a segment's own."""
        out = object.__new__(StreamingLS)
        out.__dict__.update(self.__dict__)
        out._R, out._rows, out._y2, out._sum = {}, {}, {}, {}
        return out

    def merge(self, other: StreamingLS) -> StreamingLS:
        """A new accumulator holding this one's rows and then `other`'s (same columns and known values): per
        group, the QR of the two factors stacked. Neither input changes; the groups keep their first order."""
        if other.names != self.names or other.known != self.known:
            raise IdentificationError("cannot merge accumulators of other parameters or other known values")
        out = self.empty()
        for name in dict.fromkeys([*self._R, *other._R]):  # every factor is square: (q+1, q+1)
            parts = [s._R[name] for s in (self, other) if name in s._R]
            out._R[name] = parts[0] if len(parts) == 1 else np.linalg.qr(np.vstack(parts), mode="r")
            out._rows[name] = self._rows.get(name, 0) + other._rows.get(name, 0)
            out._y2[name] = self._y2.get(name, 0.0) + other._y2.get(name, 0.0)
            out._sum[name] = sum((s._sum[name] for s in (self, other) if name in s._sum), np.zeros(len(self.names) + 1))
        return out

    def reparametrised(self, names: Sequence[str], T: ArrayLike, *, known: Mapping[str, float] | None = None,
                       labels: Mapping[str, str] | None = None, a_priori: Mapping[str, float] | None = None,
                       truth: Mapping[str, float] | None = None) -> StreamingLS:
        """The accumulator of the rows ``[W' | Y'] = [W | Y] T`` (T: (p+1, p'+1), p' = len(names)), with `known`
        of the new parameters moved to the right-hand side: per group the QR of ``R_g T`` (``[W_g | Y_g] = Q_g
        R_g``, so ``[W_g | Y_g] T = Q_g (R_g T)``). This accumulator must hold every column (no known values).

        E.g. T = identity and `known`: the same rows with parameters fixed; or identified drive gains g replaced
        by their values, ``Y' = Y - W_g g``."""
        if self.known:
            raise IdentificationError("reparametrised needs the accumulator of every column (no known values)")
        out = StreamingLS(names, labels=labels, a_priori=a_priori, truth=truth, known=known, rank_tol=self.rank_tol,
                          poor_factor=self.poor_factor)
        T = np.asarray(T, dtype=float)
        if T.shape != (len(self.names) + 1, len(out.names) + 1):
            raise IdentificationError(f"T has shape {T.shape}, expected {(len(self.names) + 1, len(out.names) + 1)}")
        # the new rows' estimated columns, then Y' less the known columns times their values
        est = [out.names.index(n) for n in out.estimated_names]
        kn = [out.names.index(n) for n in out.known]
        rhs = T[:, -1] - T[:, kn] @ np.array(list(out.known.values()), dtype=float)
        Te = np.column_stack([T[:, est], rhs])
        for g, R in self._R.items():
            out._R[g] = np.linalg.qr(R @ Te, mode="r")
            out._rows[g] = self._rows[g]
            out._y2[g] = float(np.sum((R @ T[:, -1]) ** 2))
            out._sum[g] = self._sum[g] @ T
        return out

    # ----------------------------------------------------------------- solving
    def _require_rows(self) -> None:
        if not self._rows:
            raise IdentificationError("StreamingLS has no rows: add() data before solving")

    def _stacked(self, sigmas: Mapping[str, float] | None = None) -> np.ndarray:
        blocks = [R / (1.0 if sigmas is None else sigmas[g]) for g, R in self._R.items()]
        return blocks[0] if len(blocks) == 1 else np.linalg.qr(np.vstack(blocks), mode="r")

    def _solve(self, R: np.ndarray, context: str) -> LSQSolution:
        q = len(self.estimated_names)
        return solve_lsq(R[:, :q], R[:, q], self.estimated_names, n_rows=self.n_rows, rank_tol=self.rank_tol,
                         context=context)

    def group_factor(self, group: str) -> np.ndarray:
        """The (q+1, q+1) triangular factor of the group's [W | Y] (column j is zero where the group's rows do not
        carry estimated parameter j)."""
        return self._R[group]

    def _residual_norm(self, x: np.ndarray, group: str) -> float:
        return float(np.linalg.norm(self._R[group] @ np.append(x, -1.0)))

    def weighted_factor(self, sigmas: Mapping[str, float] | None = None) -> np.ndarray:
        """The (q+1, q+1) triangular factor of the rows weighted by their group's 1/σ_g, [P W | P Y] (the
        estimated columns; no weights: the rows as added)."""
        self._require_rows()
        return self._stacked(None if sigmas is None else checked_sigmas(sigmas, list(self._R)))

    def result_of(self, sol: LSQSolution, method: Method, weights: Mapping[str, float]) -> IdentificationResult:
        """A solution on these rows' estimated parameters as a result (names, known values, relative residual)."""
        return self._result(sol, method, weights)

    def _result(self, sol: LSQSolution, method: Method, weights: Mapping[str, float]) -> IdentificationResult:
        res2 = sum(self._residual_norm(sol.x, g) ** 2 for g in self._R)
        return build_result(
            sol,
            names=self.names,
            estimated_names=self.estimated_names,
            known=self.known,
            labels=self.labels,
            a_priori=self.a_priori,
            truth=self.truth,
            method=method,
            weights=weights,
            relative_residual=norm_ratio(np.sqrt(res2), np.sqrt(sum(self._y2.values()))),
            poor_factor=self.poor_factor,
        )

    def solve(self) -> IdentificationResult:
        """OLS on every row added (same as ``ols`` on the whole stack, to round-off)."""
        self._require_rows()
        return self._result(self._solve(self._stacked(), "W"), Method.OLS, {})

    def group_fits(self, sigma_floor: float = SIGMA_FLOOR) -> dict[str, GroupFit]:
        """Per-group fits (paper eq. (8)) from the accumulators; warns for floored groups."""
        self._require_rows()
        q = len(self.estimated_names)
        n = self.n_rows
        overall = float(np.sqrt(sum(float(R[:, q] @ R[:, q]) for R in self._R.values()) / n))
        fits = {
            g: fit_group(g, R[:, :q], R[:, q], self.estimated_names, n_rows=self._rows[g], rank_tol=self.rank_tol,
                         sigma_floor=sigma_floor, fallback_rms=overall)
            for g, R in self._R.items()
        }
        warn_floored(fits)
        return fits

    def group_sigmas(self, sigma_floor: float = SIGMA_FLOOR) -> dict[str, float]:
        """``{group: sigma_j}`` (paper eq. (8)), units of Y."""
        return {g: f.sigma for g, f in self.group_fits(sigma_floor).items()}

    def solve_weighted(
        self, group_sigmas: Mapping[str, float] | None = None, sigma_floor: float = SIGMA_FLOOR
    ) -> IdentificationResult:
        """WLS (paper eq. (8)-(10)) on every row added, same as ``wls`` on the whole stack.

        group_sigmas : ``{group: sigma_j}`` to use instead of estimating them from the accumulators.
        """
        self._require_rows()
        given = group_sigmas is not None
        sigmas = checked_sigmas(group_sigmas, list(self._R)) if given else self.group_sigmas(sigma_floor)
        return self._result(self._solve(self._stacked(sigmas), "W (weighted)"), Method.WLS, sigmas)

    def instrument_sums(self) -> InstrumentSums:
        """An accumulator of instruments for rows of this system (``solve_iv``)."""
        cols = np.array([self.names.index(n) for n in self.estimated_names], dtype=int)
        known = np.array([self.names.index(n) for n in self.known], dtype=int)
        return InstrumentSums(cols, known, np.array(list(self.known.values()), dtype=float))

    def solve_iv(self, sums: InstrumentSums, group_sigmas: Mapping[str, float] | None = None, iterations: int = 3,
                 sigma_floor: float = SIGMA_FLOOR) -> IdentificationResult:
        """Weighted instrumental variables (IDIM-IV, see `iv`) on the rows added, with `sums` accumulated on the
        same rows. The weights start from `group_sigmas` (default: WLS's) and are re-estimated from the IV
        residuals `iterations` times (p_g: the parameters each group identifies alone, as in WLS; 0: the
        given weights as they are)."""
        self._require_rows()
        if sums.rows != self._rows:
            raise IdentificationError(f"the instruments were accumulated on other rows ({sums.rows}) than the system "
                                      f"({self._rows}): add the same chunks to both")
        fits = self.group_fits(sigma_floor)
        sigmas = dict(group_sigmas) if group_sigmas is not None else {g: f.sigma for g, f in fits.items()}
        sigmas = checked_sigmas(sigmas, list(self._R))
        q, n = len(self.estimated_names), self.n_rows
        for _ in range(iterations):
            x, Ainv, S = sums.solve(sigmas, self.estimated_names)
            res = {g: self._residual_norm(x, g) for g in self._R}
            floor = {g: sigma_floor * np.sqrt(self._y2[g] / self._rows[g]) for g in self._R}
            sigmas = {g: max(res[g] / np.sqrt(max(self._rows[g] - len(fits[g].parameters), 1)), floor[g], 1e-300)
                      for g in self._R}
        x, Ainv, S = sums.solve(sigmas, self.estimated_names)
        rss_w = sum(self._residual_norm(x, g) ** 2 / sigmas[g] ** 2 for g in self._R)
        s2 = rss_w / (n - q)
        cov = iv_covariance(Ainv, S, s2)
        ls = self._solve(self._stacked(sigmas), "W (weighted)")  # the weighted W's condition number
        sol = LSQSolution(x, cov / s2, float(rss_w), n, n - q, float(s2), cov, ls.condition_number)
        return self._result(sol, Method.IV, sigmas)

    def group_rms(self, X: ArrayLike | Mapping[str, float] | IdentificationResult | None = None) -> dict[str, float]:
        """``{group: RMS of Y}`` over the rows added, or of the residual ``Y - W X`` when X is given."""
        self._require_rows()
        if X is None:
            return {g: float(np.sqrt(self._y2[g] / self._rows[g])) for g in self._R}
        x = self._estimated_values(X)
        return {g: self._residual_norm(x, g) / np.sqrt(self._rows[g]) for g in self._R}

    def bias_accumulator(self) -> BiasAccumulator:
        """An accumulator of sensor-offset effects on rows of this system's columns (see `systematic`)."""
        cols = np.array([self.names.index(n) for n in self.estimated_names], dtype=int)
        known = np.array([self.names.index(n) for n in self.known], dtype=int)
        return BiasAccumulator(cols, known, np.array(list(self.known.values()), dtype=float))

    def hac_sums(self, result: IdentificationResult, covariance: Covariance,
                 offsets: OffsetEstimate | None = None) -> HACSums:
        """An empty accumulator of the Newey–West sums at `result`'s estimate and weights (a second pass feeds it
        the same rows, `HACSums.add`), each group's lag from `covariance` and the group's rows here (group-summed:
        the summed series' from the largest group's rows, about the samples). offsets: the estimate of each test's
        sensor offsets `result` comes with (`with_offsets_estimated`): the scores are the profiled problem's, and
        the second pass gives each test's rows their offsets' columns."""
        self._require_rows()
        cols = np.array([self.names.index(n) for n in self.estimated_names], dtype=int)
        known = np.array([self.names.index(n) for n in self.known], dtype=int)
        x = np.array([result.value(n) for n in self.estimated_names])
        # group-summed: one series per test, so one lag (the groups' own would be unused, and results.json says it)
        lags = ({SUMMED: covariance.lags_for(max(self._rows.values()))} if covariance.groupsum
                else {g: covariance.lags_for(n) for g, n in self._rows.items()})
        profile = None if offsets is None else {t: (G, offsets.u[t]) for t, G in offsets.profile.items()}
        # with the offsets, the weights their estimate used (OLS's: the residual's σ, `with_offsets_estimated`)
        sigmas = (result.weights or None) if offsets is None else offsets.weights
        return HACSums(cols, known, np.array(list(self.known.values()), dtype=float), x, sigmas, lags,
                       groupsum=covariance.groupsum, profile=profile,
                       exclude=() if offsets is None else offsets.exclude)

    def with_hac(self, result: IdentificationResult, sums: HACSums, covariance: Covariance,
                 offsets: OffsetEstimate | None = None) -> IdentificationResult:
        """`result` (from `solve` or `solve_weighted` on these rows) with its covariance the sandwich B S B:
        B = (W̃ᵀW̃)⁻¹ of the weighted rows (these factors), S the sums of the second pass over every row. With the
        offsets estimated (`offsets`, as `hac_sums` had), B is the reduced normal matrix's inverse A_r⁻¹ and the
        sandwich the statistical part; `result`'s systematic part (the offsets' remaining effect) stays."""
        if sums.group_rows != self._rows:
            raise IdentificationError(f"the HAC pass saw rows {sums.group_rows}, the estimate {self._rows}: the second "
                                      "pass must go over every row of the first")
        if (offsets is None) != (not sums.profile):
            raise IdentificationError("the HAC sums and the covariance's bread disagree on the offsets: give with_hac "
                                      "the offsets' estimate hac_sums had")
        if offsets is not None:
            B = offsets.inv_gram
        else:
            q = len(self.estimated_names)
            R = self._stacked(result.weights or None)[:q, :q]
            d = np.linalg.norm(R, axis=0)  # unit columns: the units of W's columns differ by orders of magnitude
            Rinv = np.linalg.solve(R / d, np.eye(q))
            B = (Rinv @ Rinv.T) / np.outer(d, d)
        C = B @ sums.meat() @ B
        return result.with_covariance((C + C.T) / 2, covariance.label, sums.lags)

    def with_systematic(self, result: IdentificationResult, accumulator: BiasAccumulator) -> IdentificationResult:
        """`result` (from `solve` or `solve_weighted` on these rows) with the offsets' uncertainty attached."""
        sigmas = result.weights or None
        q = len(self.estimated_names)
        R = self._stacked(sigmas)[:q, :q]
        x = np.array([result.value(n) for n in self.estimated_names])
        return result.with_systematic(propagate(R.T @ R, accumulator, x, self.estimated_names, sigmas))

    def with_offsets_estimated(self, result: IdentificationResult, factors: OffsetFactors,
                               exclude: Sequence[str] = ()) -> tuple[IdentificationResult, OffsetEstimate]:
        """`result`'s estimate again with each test's sensor offsets estimated (`offsets`; the factors hold every
        row added here, with their offsets' columns; `exclude`: groups left out of the offsets' estimate), at
        `result`'s weights, the offsets' remaining effect attached as its systematic part; and the estimate (the
        offsets read, in declared σ)."""
        if factors.group_rows != self._rows:
            raise IdentificationError(f"the offsets' rows ({factors.group_rows}) are not the system's ({self._rows}): "
                                      "estimating the offsets needs every segment's")
        # the paper's weights (eq. (8)) and scale (the weighted system's σ², eq. (10)) of `result` stand: measured on
        # five seeds of the 406, weights re-estimated from the residual with the offsets taken out made σ total too
        # small (RMS z 1.28, 5 of 160 estimates beyond 3 σ, against 0.94 and 0 of 160): what the offsets leave in
        # the rows is not white noise (the sensors' noise through the filters, errors in the variables)
        # (OLS: every row's noise is the residual's σ; the offsets' prior is in units of the rows' noise)
        s = result.residual.sigma
        sigmas, s2 = (result.weights, s ** 2) if result.weights else (dict.fromkeys(self._R, s), 1.0)
        est = solve_with_offsets(factors, self.estimated_names, sigmas, self.rank_tol, sigma2=s2, exclude=exclude)
        out = self._result(est.solution, result.method, result.weights)
        return out.with_systematic(est.systematic), est

    def relative_errors(self, X: ArrayLike | Mapping[str, float] | IdentificationResult,
                        residual: Mapping[str, float] | None = None) -> dict[str, float]:
        """``||Y_g - W_g X|| / ||Y_g||`` per group plus ``"overall"`` on the rows added.

        X : (p,) values in names order, ``{name: value}``, or an ``IdentificationResult``; the values
        of known parameters must equal the known ones (they are already in the accumulators).
        residual : the groups' residual RMS to use instead of the factors' at X (`_residuals`).
        """
        self._require_rows()
        res = self._residuals(self._estimated_values(X), residual)
        out = {g: norm_ratio(res[g], np.sqrt(self._y2[g])) for g in self._R}
        if "overall" in out:
            raise IdentificationError('"overall" is reserved for the whole system; rename that equation group')
        total = np.sqrt(sum(r ** 2 for r in res.values()))
        out["overall"] = norm_ratio(total, np.sqrt(sum(self._y2.values())))
        return out

    def nrmse(self, X: ArrayLike | Mapping[str, float] | IdentificationResult,
              residual: Mapping[str, float] | None = None) -> dict[str, float]:
        """``RMS(Y_g - W_g X) / std(Y_g)`` per group plus ``"overall"`` (the residuals' and the spreads' sums of
        squares pooled), as `quality.nrmse` on the rows added; the spread from the group's sums:
        ``||Y_g - mean||^2 = ||Y_g||^2 - (sum Y_g)^2 / n_g``. residual: as `relative_errors`."""
        self._require_rows()
        res = self._residuals(self._estimated_values(X), residual)
        spread = {g: max(self._y2[g] - self._sum[g][-1] ** 2 / self._rows[g], 0.0) for g in self._R}
        out = {g: norm_ratio(res[g], np.sqrt(spread[g])) for g in self._R}
        if "overall" in out:
            raise IdentificationError('"overall" is reserved for the whole system; rename that equation group')
        out["overall"] = norm_ratio(np.sqrt(sum(r * r for r in res.values())), np.sqrt(sum(spread.values())))
        return out

    def _residuals(self, x: np.ndarray, residual: Mapping[str, float] | None) -> dict[str, float]:
        """Per group ||Y_g - W_g x||, or the norm of the given residual RMS (a residual other than the factors':
        a car's with the sensor offsets the data read taken out, `offsets.OffsetFactors.group_rms`)."""
        if residual is None:
            return {g: self._residual_norm(x, g) for g in self._R}
        return {g: float(residual[g]) * np.sqrt(self._rows[g]) for g in self._R}

    def _estimated_values(self, X: ArrayLike | Mapping[str, float] | IdentificationResult) -> np.ndarray:
        """The estimated parameters' values of X (all p values, by name or in order), known ones checked."""
        if isinstance(X, IdentificationResult):
            X = X.estimates
        if isinstance(X, Mapping):
            missing = [n for n in self.estimated_names if n not in X]
            if missing:
                raise IdentificationError(f"X has no value for parameters {missing}", parameters=missing)
            full = {n: float(X.get(n, self.known.get(n, np.nan))) for n in self.names}
        else:
            arr = np.asarray(X, dtype=float).reshape(-1)
            if arr.size != len(self.names):
                raise IdentificationError(f"X must have {len(self.names)} values (one per name), got {arr.size}")
            full = dict(zip(self.names, arr.tolist(), strict=True))
        wrong = [n for n, v in self.known.items() if full[n] != v]
        if wrong:
            raise IdentificationError(f"X changes known parameters {wrong}; they are fixed in the accumulators",
                                      parameters=wrong)
        return np.array([full[n] for n in self.estimated_names])


def iv(
    W: ArrayLike,
    Y: ArrayLike,
    Z: ArrayLike,
    groups: ArrayLike,
    names: Sequence[str],
    *,
    group_sigmas: Mapping[str, float] | None = None,
    iterations: int = 3,
    **kw,
) -> IdentificationResult:
    """Weighted instrumental variables (IDIM-IV, see `iv`) on a whole system: W (m, p), Y (m,), instruments
    Z (m, p), groups (m,); the other arguments as in ``wls`` and `StreamingLS.solve_iv`."""
    s = one_block(W, Y, names, groups, **kw)
    sums = s.instrument_sums()
    sums.add(W, Y, Z, groups)
    return s.solve_iv(sums, group_sigmas, iterations)


def one_block(W: ArrayLike, Y: ArrayLike, names: Sequence[str], groups: ArrayLike | None = None,
              **kw) -> StreamingLS:
    """The accumulator of a whole system added as one block: the batch entries (`ols`, `wls`, `group_noise`, `iv`,
    the `quality` functions) are this and one of its solves or validations. W (m, p), Y (m,) and names are checked
    first with the batch messages (W's shape, rows, columns); groups (m,) or None (one group); kw: StreamingLS's."""
    nm, A, y = checked_rows(W, Y, names)
    if A.shape[0] == 0:
        raise IdentificationError("W has no rows: there is nothing to estimate or validate; add samples")
    s = StreamingLS(nm, **kw)
    s._add_checked(A, y, groups)
    return s
