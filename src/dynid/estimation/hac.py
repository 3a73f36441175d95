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
"""

from __future__ import annotations

from collections.abc import Mapping

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


class HACSums:
    """Newey–West sums of the scores of rows of one system at one estimate (module doc).

    columns: the estimated columns of the rows' W (in the order of the estimate x); known_columns, known_values:
    the known parameters' columns and values (moved to the right-hand side); x: (q,) the estimate; sigmas:
    {group: σ_g} of a weighted estimate (None: OLS, unit weights); lags: {group: L_g}.
    """

    def __init__(self, columns: ArrayLike, known_columns: ArrayLike, known_values: ArrayLike, x: ArrayLike,
                 sigmas: Mapping[str, float] | None, lags: Mapping[str, int]) -> None:
        self.columns = np.asarray(columns, dtype=int)
        self.known_columns = np.asarray(known_columns, dtype=int)
        self.known_values = np.asarray(known_values, dtype=float)
        self.x = np.asarray(x, dtype=float)
        if self.x.shape != self.columns.shape:
            raise IdentificationError(f"HACSums: the estimate has {self.x.size} values for {self.columns.size} "
                                      "estimated columns")
        self.sigmas = None if sigmas is None else {str(g): float(s) for g, s in sigmas.items()}
        self.lags = {str(g): int(v) for g, v in lags.items()}
        # (stream, group) -> [rows, S (q, q), first min(L, rows) scores, last min(L, rows) scores]
        self._parts: dict[tuple[str, str], list] = {}

    def empty(self) -> HACSums:
        """The same estimate and settings, no rows: a chunk's own."""
        out = object.__new__(HACSums)
        out.__dict__.update(self.__dict__)
        out._parts = {}
        return out

    def scores(self, W: ArrayLike, Y: ArrayLike, groups: ArrayLike) -> np.ndarray:
        """(c, q) the rows' scores w² x e (W: (c, p) every column, Y: (c,), groups: (c,))."""
        W = np.asarray(W, dtype=float)
        y = np.asarray(Y, dtype=float).reshape(-1)
        g = as_groups(groups, W.shape[0])
        A = W[:, self.columns]
        e = y - A @ self.x
        if self.known_columns.size:
            e = e - W[:, self.known_columns] @ self.known_values
        w2 = np.ones(W.shape[0])
        if self.sigmas is not None:
            for name, idx in group_rows(g).items():
                if name not in self.sigmas:
                    raise IdentificationError(f"HACSums: equation group {name!r} has no weight in the estimate")
                w2[idx] = 1.0 / self.sigmas[name] ** 2
        return A * (w2 * e)[:, None]

    def add(self, W: ArrayLike, Y: ArrayLike, groups: ArrayLike, stream: str = "") -> None:
        """Add rows that follow those added before in `stream` (a test): W (c, p) every column, Y (c,), groups (c,),
        each group's rows in time order."""
        W = np.asarray(W, dtype=float)
        if W.shape[0] == 0:
            return
        g = as_groups(groups, W.shape[0])
        s = self.scores(W, Y, g)
        for name, idx in group_rows(g).items():
            L = self._lag(name)
            block = s[idx]
            own = [idx.size, _inner(block, bartlett(L)), block[:L].copy(), block[block.shape[0] - L:].copy()]
            key = (str(stream), name)
            self._parts[key] = own if key not in self._parts else self._joined(self._parts[key], own, L)

    def _lag(self, group: str) -> int:
        if group not in self.lags:
            raise IdentificationError(f"HACSums: equation group {group!r} has no lag (the first pass did not see it)")
        return self.lags[group]

    @staticmethod
    def _joined(a: list, b: list, L: int) -> list:
        """One stream's sums of rows a then rows b."""
        S = a[1] + b[1] + (_cross(a[3], b[2], bartlett(L)) if L else 0.0)
        head = a[2] if a[0] >= L else np.vstack([a[2], b[2]])[:L]
        tail = b[3] if b[0] >= L else np.vstack([a[3], b[3]])[max(0, a[3].shape[0] + b[3].shape[0] - L):]
        return [a[0] + b[0], S, head, tail]

    def merge(self, other: HACSums) -> HACSums:
        """This one's rows then `other`'s (each stream's chunks in order); neither input changes."""
        if not (np.array_equal(self.x, other.x) and self.lags == other.lags and self.sigmas == other.sigmas):
            raise IdentificationError("cannot merge HAC sums of other estimates, weights or lags")
        out = self.empty()
        for key in dict.fromkeys([*self._parts, *other._parts]):
            parts = [s._parts[key] for s in (self, other) if key in s._parts]
            out._parts[key] = parts[0] if len(parts) == 1 else self._joined(*parts, self.lags[key[1]])
        return out

    @property
    def group_rows(self) -> dict[str, int]:
        """{group: rows added} over every stream."""
        out: dict[str, int] = {}
        for (_, g), p in self._parts.items():
            out[g] = out.get(g, 0) + p[0]
        return out

    def meat(self, group: str | None = None) -> np.ndarray:
        """(q, q) S over every stream (of one group)."""
        S = np.zeros((self.x.size, self.x.size))
        for (_, g), p in self._parts.items():
            if group is None or g == group:
                S += p[1]
        return S


__all__ = ["HACSums", "bartlett"]
