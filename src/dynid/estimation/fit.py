"""Does the model fit an equation group? Its residual against what the sensors' errors explain.

A group whose model is right leaves a residual made of the measurements' errors alone. Those errors are known
from the sensors' error model: white noise of each channel's accuracy and a zero offset of its bias. One draw
of them, e (the offsets with random signs and their full size: the mean square of a sum of offsets of random
signs is the sum of their squares, with no chi-square scatter in their sizes), is added to and subtracted from
the channels of a few segments and carried through the same joint estimation, filters and equations: the rows
[W | Y] become [W | Y](+e) and [W | Y](-e). What the errors add to each group's residual once least squares has
absorbed what it can (a zero offset into an offset parameter, say) is the difference of the group's own fits
(paper eq. (8), each group alone on the parameters it identifies) on the same rows:
noise_rms^2 = (sigma^2(+e) + sigma^2(-e)) / 2 - sigma^2(clean); the pair cancels, to first order, the cross
term between the errors and whatever else is in the residual (a model error). All three are streamed QR
factors (`StreamingLS`): the check costs two more passes over a few segments and combines across segments and
workers like the estimate.

Verdict: the model does not fit group g when the estimate's residual RMS in g exceeds FIT_RATIO times the RMS
its sensors' errors explain. With a fitting model the ratio is about 1; 3 means the unexplained part carries at
least 8/9 of the residual's variance, beyond what one draw of the errors (thousands of rows) or a noise model
off by a factor 2 can make. Such a group's parameters are not results: its equation, not the data, is wrong.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .errors import EstimationWarning
from .streaming import StreamingLS

FIT_RATIO = 3.0


@dataclass(frozen=True)
class ModelFit:
    """One group's verdict: residual RMS, the RMS its sensors' errors explain, their ratio, whether the model
    fits, and the parameters the group's equation carries."""

    group: str
    residual_rms: float
    noise_rms: float
    parameters: tuple[str, ...]

    @property
    def ratio(self) -> float:
        return self.residual_rms / self.noise_rms if self.noise_rms > 0 else float("inf")

    @property
    def fits(self) -> bool:
        return bool(self.ratio <= FIT_RATIO)

    def as_dict(self) -> dict:
        return {"residual_rms": self.residual_rms, "noise_rms": self.noise_rms, "ratio": self.ratio,
                "fits": self.fits, "parameters": list(self.parameters)}


@dataclass(frozen=True)
class ErrorEffect:
    """The rows of some segments as measured (`clean`), with one draw of their sensors' errors added (`plus`) and
    subtracted (`minus`), as streamed factors; merges like them."""

    clean: StreamingLS
    plus: StreamingLS
    minus: StreamingLS

    def merge(self, other: ErrorEffect) -> ErrorEffect:
        return ErrorEffect(self.clean.merge(other.clean), self.plus.merge(other.plus), self.minus.merge(other.minus))

    def explained_rms(self) -> dict[str, float]:
        """{group: the residual RMS the errors add to the group's own least-squares fit}."""
        with warnings.catch_warnings():  # a group without residual (NaN sigma) is the estimate's to warn of
            warnings.simplefilter("ignore", EstimationWarning)
            clean, plus, minus = (s.group_fits(sigma_floor=0.0) for s in (self.clean, self.plus, self.minus))
        return {g: float(np.sqrt(max((plus[g].raw_sigma ** 2 + minus[g].raw_sigma ** 2) / 2 - clean[g].raw_sigma ** 2,
                                     0.0))) for g in clean}


def model_fits(rows: StreamingLS, errors: ErrorEffect, x: Mapping[str, float],
               residual: Mapping[str, float] | None = None) -> dict[str, ModelFit]:
    """Each group's verdict at the estimate x ({name: value}): `rows` holds [W | Y] of the identification rows,
    `errors` the same rows of a few segments without and with the sensors' errors; residual: the groups' RMS
    residual when it is not `rows`' at x (the sensors' zero offsets the data read taken out: estimation.offsets). A
    group none of those segments holds is not judged (left out), rather than called a misfit for want of a noise
    figure."""
    residual = rows.group_rms(x) if residual is None else residual
    explained = errors.explained_rms()
    out = {}
    for g, rms in residual.items():
        if g not in explained:
            continue
        R = rows.group_factor(g)
        carried = tuple(n for j, n in enumerate(rows.estimated_names) if np.any(R[:, j] != 0.0))
        out[g] = ModelFit(g, float(rms), float(explained[g]), carried)
    return out


def misfit_parameters(fits: Mapping[str, ModelFit], rows: StreamingLS,
                      weights: Mapping[str, float] | None = None) -> dict[str, list[str]]:
    """{parameter: the misfit groups it enters}, for the parameters whose estimate rests mostly on groups that do
    not fit: without those groups' rows its variance would more than double (at least half of its information
    comes from them), or it would not be identified at all. A parameter a misfit group shares with groups that
    fit and that determine it (the mass in a lateral-force equation, weighed by the vertical one) keeps its
    estimate; the note still names the group. weights: {group: sigma_j} of the estimate (WLS, IV; None: OLS)."""
    bad = [g for g, f in fits.items() if not f.fits]
    if not bad:
        return {}
    names = list(rows.estimated_names)
    q = len(names)

    def information(groups) -> np.ndarray:
        A = np.zeros((q, q))
        for g in groups:
            R = rows.group_factor(g)[:, :q]
            A += (R.T @ R) / (1.0 if not weights else weights[g]) ** 2
        return A

    def variances(A: np.ndarray) -> np.ndarray:
        out = np.full(q, np.inf)
        seen = np.flatnonzero(np.diag(A) > 0)
        if seen.size:  # scaled to a unit diagonal: the columns' units (kt against an offset) are not conditioning
            d = 1.0 / np.sqrt(np.diag(A)[seen])
            sub = A[np.ix_(seen, seen)] * np.outer(d, d)
            if np.linalg.cond(sub) < 1e12:
                out[seen] = np.diag(np.linalg.inv(sub)) * d ** 2
        return out

    whole = variances(information(fits))
    without = variances(information([g for g in fits if g not in bad]))
    out: dict[str, list[str]] = {}
    for g in bad:
        for n in fits[g].parameters:
            i = names.index(n)
            if not without[i] <= 2.0 * whole[i]:
                out.setdefault(n, []).append(g)
    return out


def fit_note(fits: Mapping[str, ModelFit], label: Mapping[str, str] | None = None,
             misfit: Mapping[str, list[str]] | None = None) -> str:
    """The verdict in words: every group whose model does not fit, with its figures and parameters (those not in
    `misfit`, see `misfit_parameters`, marked kept)."""
    label = label or {}
    bad = [f for f in fits.values() if not f.fits]
    if not bad:
        worst = max(fits.values(), key=lambda f: f.ratio, default=None)
        return ("Model fit: every equation group's residual is within "
                f"{FIT_RATIO:g} x what its sensors' errors explain"
                + (f" (largest: {worst.group}, {worst.ratio:.2g} x)." if worst is not None else ".") + "\n")
    lines = [f"MODEL MISFIT: the residual of {len(bad)} equation group(s) is more than {FIT_RATIO:g} x what the "
             "sensors' errors explain: the model does not fit them. The parameters whose estimate rests mostly on "
             "them are not results (flag misfit); the others are determined by groups that fit:"]
    flagged = set(misfit or ())
    for f in bad:
        names = ", ".join(label.get(n, n) + ("" if n in flagged else " (kept)") for n in f.parameters)
        lines.append(f"  {f.group}: residual {f.residual_rms:.4g} RMS, {f.ratio:.1f} x the {f.noise_rms:.3g} the "
                     f"sensors explain; parameters {names}")
    return "\n".join(lines) + "\n"
