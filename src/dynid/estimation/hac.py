"""Newey–West (HAC) covariance per equation group, streamed: the second pass over the rows.

The decimated rows of one equation group are a time series whose residual is autocorrelated (the zero-phase
filters and the decimation spread one disturbance over several rows; a model error is slow), so σ² (WᵀW)⁻¹
(white rows, paper eq. (7)) is too small. The sandwich ``C = B S B`` with ``B = (W̃ᵀW̃)⁻¹`` (W̃ the rows weighted
by their group's 1/σ_g: the estimator's own system) and the kernel-weighted sum of the scores'
autocovariances

    S = Σ_streams Σ_l k(l) Σ_t (s_t s_{t-l}ᵀ + s_{t-l} s_tᵀ)   (the l = 0 term once),

``s_t = w_t² x_t e_t`` (the weighted row times the weighted residual, w_t = 1/σ_g, e_t = y_t − x_t X̂), a Bartlett
kernel ``k(l) = 1 − l / (L_g + 1)``, is statsmodels' ``cov_type="HAC"`` on one series and ``"hac-panel"`` on
several (no small-sample correction). A stream is one equation group of one test: lags never cross groups or
tests (the rows of different tests are not neighbours in time).

The residuals need the estimate, which the factors of the first pass give but cannot replay: `HACSums` is fed
the same chunks (rows in time order within each group) and keeps, per stream, S, the row count and the first
and last L_g scores, so that two sums of consecutive chunks combine exactly (`merge` adds the products across
the border), in any tree of reductions that keeps the chunks' order. Memory: (q² + 2 L_g q) floats per stream.

Group-summed (Driscoll–Kraay, statsmodels' ``"hac-groupsum"`` with the sample as its time): one sensor's noise enters
several groups' rows at the same sample (a car's inertial unit: its accelerations in every chassis equation), so
the groups' scores are not independent; they are summed per sample (the rows' time stamps, `add`'s t) into one
series per test, and the kernel runs over that series (its lag L: `SUMMED`'s).

With each test's sensor offsets estimated (`offsets`: columns C of the rows, a prior on u), the scores are those of
the profiled problem: the row less its offsets' part, x_t − Γ_kᵀ c_t (Γ_k = (C̃ᵀC̃ + I)⁻¹ C̃ᵀ W̃ of test k, weighted),
times the residual with the offsets the test's data read taken out, e_t − c_t û_k; the bread is then the reduced
normal matrix's inverse A_r⁻¹ (`offsets.OffsetEstimate.inv_gram`). The sandwich over the data rows is the
statistical part alone: with white rows of the weights' σ it is σ² A_r⁻¹ less the offsets' part, as
`solve_with_offsets` splits it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ._checks import as_groups, group_rows
from .errors import IdentificationError


def bartlett(lags: int) -> np.ndarray:
    """(lags + 1,) Bartlett kernel weights 1 − l / (lags + 1), l = 0..lags (statsmodels' ``weights_bartlett``)."""
    return 1.0 - np.arange(lags + 1) / (lags + 1.0)


def _inner(s: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Σ_l k(l) Σ_t (s_t s_{t-l}ᵀ + transpose) of one block of scores s (n, q), lags 0..len(k) - 1."""
    S = k[0] * (s.T @ s)
    for lag in range(1, min(len(k), s.shape[0])):
        G = s[lag:].T @ s[:-lag]
        S += k[lag] * (G + G.T)
    return S


def _cross(tail: np.ndarray, head: np.ndarray, k: np.ndarray) -> np.ndarray:
    """The products across a border: `tail` (the last rows before it), `head` (the first after), lags up to
    len(k) - 1 counted from the last row of `tail`."""
    m, h = tail.shape[0], head.shape[0]
    S = np.zeros((tail.shape[1], tail.shape[1]))
    for lag in range(1, len(k)):
        j0, j1 = max(0, lag - m), min(lag, h)  # head rows j with tail row m - lag + j
        if j1 <= j0:
            continue
        G = head[j0:j1].T @ tail[m - lag + j0:m - lag + j1]
        S += k[lag] * (G + G.T)
    return S


SUMMED = "Σ groups"
"""The key of the group-summed series (`HACSums`' lags and streams)."""


class HACSums:
    """Newey–West sums of the scores of rows of one system at one estimate (module doc).

    columns: the estimated columns of the rows' W (in the order of the estimate x); known_columns, known_values:
    the known parameters' columns and values (moved to the right-hand side); x: (q,) the estimate; sigmas:
    {group: σ_g} of a weighted estimate (None: OLS, unit weights); lags: {group: L_g} ({SUMMED: L} when
    groupsum). groupsum: sum the groups' scores per sample before the kernel (module doc). profile: {stream (a
    test): (Γ (m, q), û (m,))} of a test whose offsets were estimated (its rows' offsets' columns C then go to
    `add`); exclude: groups whose rows the offsets neither inform nor correct (`offsets.solve_with_offsets`).
    """

    def __init__(self, columns: ArrayLike, known_columns: ArrayLike, known_values: ArrayLike, x: ArrayLike,
                 sigmas: Mapping[str, float] | None, lags: Mapping[str, int], *, groupsum: bool = False,
                 profile: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None,
                 exclude: Sequence[str] = ()) -> None:
        self.columns = np.asarray(columns, dtype=int)
        self.known_columns = np.asarray(known_columns, dtype=int)
        self.known_values = np.asarray(known_values, dtype=float)
        self.x = np.asarray(x, dtype=float)
        if self.x.shape != self.columns.shape:
            raise IdentificationError(f"HACSums: the estimate has {self.x.size} values for {self.columns.size} "
                                      "estimated columns")
        self.sigmas = None if sigmas is None else {str(g): float(s) for g, s in sigmas.items()}
        self.lags = {str(g): int(v) for g, v in lags.items()}
        self.groupsum = bool(groupsum)
        if self.groupsum and SUMMED not in self.lags:
            raise IdentificationError(f"HACSums: group-summed scores need the lag of their series (lags[{SUMMED!r}])")
        self.profile = {str(k): (np.asarray(G, dtype=float), np.asarray(u, dtype=float))
                        for k, (G, u) in (profile or {}).items()}
        for k, (G, u) in self.profile.items():
            if G.shape != (u.size, self.x.size):
                raise IdentificationError(f"HACSums: test {k!r}: Γ has shape {G.shape}, expected "
                                          f"{(u.size, self.x.size)}")
        self.exclude = tuple(str(g) for g in exclude)
        # (stream, series) -> [rows, S (q, q), first min(L, rows) scores, last min(L, rows) scores, (first, last)
        # sample time of a group-summed series, else None]; a series is a group, or SUMMED
        self._parts: dict[tuple[str, str], list] = {}
        self._rows: dict[str, int] = {}  # rows added per group

    def empty(self) -> HACSums:
        """The same estimate and settings, no rows: a chunk's own."""
        out = object.__new__(HACSums)
        out.__dict__.update(self.__dict__)
        out._parts, out._rows = {}, {}
        return out

    def scores(self, W: ArrayLike, Y: ArrayLike, groups: ArrayLike, stream: str = "",
               C: ArrayLike | None = None) -> np.ndarray:
        """(c, q) the rows' scores w² x e (W: (c, p) every column, Y: (c,), groups: (c,)); of the profiled problem
        when `stream` has its offsets estimated (C: (c, m) the rows' offsets' columns, `offsets.offset_columns`)."""
        W = np.asarray(W, dtype=float)
        y = np.asarray(Y, dtype=float).reshape(-1)
        g = as_groups(groups, W.shape[0])
        A = W[:, self.columns]
        e = y - A @ self.x
        if self.known_columns.size:
            e = e - W[:, self.known_columns] @ self.known_values
        if str(stream) in self.profile:
            G, u = self.profile[str(stream)]
            if C is None:
                raise IdentificationError(f"HACSums: test {stream!r} has its offsets estimated: give its rows' "
                                          "offsets' columns C")
            C = np.asarray(C, dtype=float)
            if C.shape != (W.shape[0], u.size):
                raise IdentificationError(f"HACSums: test {stream!r}: C has shape {C.shape}, expected "
                                          f"{(W.shape[0], u.size)}")
            on = ~np.isin(g, self.exclude)  # an excluded group's rows: neither informing nor corrected
            e = e - np.where(on, C @ u, 0.0)
            A = A - np.where(on[:, None], C @ G, 0.0)
        w2 = np.ones(W.shape[0])
        if self.sigmas is not None:
            for name, idx in group_rows(g).items():
                if name not in self.sigmas:
                    raise IdentificationError(f"HACSums: equation group {name!r} has no weight in the estimate")
                w2[idx] = 1.0 / self.sigmas[name] ** 2
        return A * (w2 * e)[:, None]

    def add(self, W: ArrayLike, Y: ArrayLike, groups: ArrayLike, stream: str = "", C: ArrayLike | None = None,
            t: ArrayLike | None = None) -> None:
        """Add rows that follow those added before in `stream` (a test): W (c, p) every column, Y (c,), groups (c,),
        each group's rows in time order; C (c, m): the rows' offsets' columns where the test's offsets were
        estimated; t (c,): the rows' sample times (group-summed scores: the rows of one sample share it)."""
        W = np.asarray(W, dtype=float)
        if W.shape[0] == 0:
            return
        g = as_groups(groups, W.shape[0])
        s = self.scores(W, Y, g, stream, C)
        for name, idx in group_rows(g).items():
            self._lag(name)
            self._rows[name] = self._rows.get(name, 0) + idx.size
        if self.groupsum:
            if t is None:
                raise IdentificationError("HACSums: group-summed scores need the rows' sample times t")
            t = np.asarray(t).reshape(-1)
            if t.shape != (W.shape[0],):
                raise IdentificationError(f"HACSums: t has {t.size} times for {W.shape[0]} rows")
            stamps, at = np.unique(t, return_inverse=True)  # in time order
            summed = np.zeros((stamps.size, s.shape[1]))
            np.add.at(summed, at, s)
            series = {SUMMED: (summed, (stamps[0], stamps[-1]))}
        else:
            series = {name: (s[idx], None) for name, idx in group_rows(g).items()}
        for name, (block, ends) in series.items():
            L = self._lag(name)
            own = [block.shape[0], _inner(block, bartlett(L)), block[:L].copy(), block[block.shape[0] - L:].copy(),
                   ends]
            key = (str(stream), name)
            self._parts[key] = own if key not in self._parts else self._joined(self._parts[key], own, L)

    def _lag(self, group: str) -> int:
        """The series' last lag; a group's own needs none when the groups are summed."""
        if group not in self.lags and not (self.groupsum and group != SUMMED):
            raise IdentificationError(f"HACSums: equation group {group!r} has no lag (the first pass did not see it)")
        return self.lags.get(group, 0)

    @staticmethod
    def _joined(a: list, b: list, L: int) -> list:
        """One stream's sums of rows a then rows b (group-summed: b's samples after a's, none split between them)."""
        if a[4] is not None and not b[4][0] > a[4][1]:
            raise IdentificationError(f"HACSums: group-summed scores of the sample at {b[4][0]} in two chunks (or "
                                      "chunks out of order): give each chunk whole samples, in time order")
        S = a[1] + b[1] + (_cross(a[3], b[2], bartlett(L)) if L else 0.0)
        head = a[2] if a[0] >= L else np.vstack([a[2], b[2]])[:L]
        tail = b[3] if b[0] >= L else np.vstack([a[3], b[3]])[max(0, a[3].shape[0] + b[3].shape[0] - L):]
        return [a[0] + b[0], S, head, tail, None if a[4] is None else (a[4][0], b[4][1])]

    def merge(self, other: HACSums) -> HACSums:
        """This one's rows then `other`'s (each stream's chunks in order); neither input changes."""
        if not (np.array_equal(self.x, other.x) and self.lags == other.lags and self.sigmas == other.sigmas
                and self.groupsum == other.groupsum and self.exclude == other.exclude
                and self.profile.keys() == other.profile.keys()):
            raise IdentificationError("cannot merge HAC sums of other estimates, weights, lags or offsets")
        out = self.empty()
        out._rows = {g: self._rows.get(g, 0) + other._rows.get(g, 0)
                     for g in dict.fromkeys([*self._rows, *other._rows])}
        for key in dict.fromkeys([*self._parts, *other._parts]):
            parts = [s._parts[key] for s in (self, other) if key in s._parts]
            out._parts[key] = parts[0] if len(parts) == 1 else self._joined(*parts, self.lags[key[1]])
        return out

    @property
    def group_rows(self) -> dict[str, int]:
        """{group: rows added} over every stream."""
        return dict(self._rows)

    def meat(self, group: str | None = None) -> np.ndarray:
        """(q, q) S over every stream (of one group; group-summed: of SUMMED)."""
        S = np.zeros((self.x.size, self.x.size))
        for (_, g), p in self._parts.items():
            if group is None or g == group:
                S += p[1]
        return S


__all__ = ["SUMMED", "HACSums", "bartlett"]
