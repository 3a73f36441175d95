"""Essential parameters: drop the worst-identified parameters while the fit stays as good.

Starting from the base set, the parameter with the largest %σ is removed (its column dropped,
i.e. its value set to zero) as long as the relative residual ``||Y - W X|| / ||Y||`` stays within
``(1 + residual_tol)`` times that of the base set. Every attempt is recorded, the last rejected one
included, so a reviewer can see why the walk stopped.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ._checks import as_label_map, as_value_map
from .errors import IdentificationError
from .quality import POOR_FACTOR
from .result import IdentificationResult
from .streaming import one_block

RESIDUAL_TOL = 0.03
"""Default allowed relative growth of the relative residual over the base set's (3 %)."""


@dataclass(frozen=True)
class EssentialStep:
    """One step of the walk.

    removed : the parameter dropped at this step (None for the base set).
    removed_rel_std_percent : its %σ in the fit it was removed from (None for the base set).
    relative_residual : ``||Y - W X|| / ||Y||`` of the fit without it.
    max_rel_std_percent, worst : the largest %σ among the remaining estimated parameters, and whose.
    accepted : whether the removal was kept (the residual stayed within the tolerance).
    """

    removed: str | None
    removed_rel_std_percent: float | None
    relative_residual: float
    max_rel_std_percent: float
    worst: str
    accepted: bool


@dataclass(frozen=True)
class EssentialResult:
    """names : the essential (estimated) parameters; removed : the dropped ones, in order;
    path : every step; result : the fit on the essential set (known parameters included)."""

    names: tuple[str, ...]
    removed: tuple[str, ...]
    path: tuple[EssentialStep, ...]
    result: IdentificationResult


def _worst(res: IdentificationResult) -> tuple[str, float]:
    rel = {n: float(res.rel_std_percent[res.index(n)]) for n in res.estimated_names}
    name = max(rel, key=lambda n: (np.inf if np.isnan(rel[n]) else rel[n]))
    return name, rel[name]


def essential_parameters(
    W: ArrayLike,
    Y: ArrayLike,
    names: Sequence[str],
    *,
    groups: ArrayLike | None = None,
    group_sigmas: Mapping[str, float] | None = None,
    labels: Mapping[str, str] | None = None,
    a_priori: Mapping[str, float] | None = None,
    truth: Mapping[str, float] | None = None,
    known: Mapping[str, float] | None = None,
    residual_tol: float = RESIDUAL_TOL,
    min_parameters: int = 1,
    rank_tol: float | None = None,
    poor_factor: float = POOR_FACTOR,
) -> EssentialResult:
    """Essential parameters by backward elimination on %σ.

    W : (m, p) observation matrix of a base set (full rank after removing known columns); Y : (m,);
    names : p names. groups : (m,) equation groups; if given, every fit is a WLS with the group
    noise levels of the base set (or ``group_sigmas``) held fixed along the walk, else OLS.
    residual_tol : allowed relative growth of ``||Y - W X|| / ||Y||`` over the base set.
    min_parameters : never go below this many estimated parameters.
    """
    if residual_tol < 0:
        raise IdentificationError(f"residual_tol must be >= 0, got {residual_tol}")
    # every column's factors once; each fit is a column selection of them (`StreamingLS.reparametrised`), not a QR
    # of the rows again
    full = one_block(W, Y, names, groups, rank_tol=rank_tol, poor_factor=poor_factor)
    p = len(full.names)
    lab = as_label_map(labels, full.names)
    prior, true = as_value_map(a_priori, full.names, "a_priori"), as_value_map(truth, full.names, "truth")
    kn = as_value_map(known, full.names, "known")
    sigmas = group_sigmas

    def fit(keep: Sequence[str]) -> IdentificationResult:
        sub = [n for n in full.names if n in keep or n in kn]
        T = np.zeros((p + 1, len(sub) + 1))  # [W_sub | Y] = [W | Y] T
        T[[full.names.index(n) for n in sub], np.arange(len(sub))] = 1.0
        T[p, -1] = 1.0
        ls = full.reparametrised(sub, T, known=kn, labels={n: lab[n] for n in sub},
                                 a_priori={n: v for n, v in prior.items() if n in sub},
                                 truth={n: v for n, v in true.items() if n in sub})
        return ls.solve() if groups is None else ls.solve_weighted(sigmas)

    est_names = [n for n in full.names if n not in kn]
    current = fit(est_names)
    if groups is not None:
        sigmas = current.weights
    limit = current.residual.relative_residual * (1.0 + residual_tol)
    worst, worst_rel = _worst(current)
    path = [EssentialStep(None, None, current.residual.relative_residual, worst_rel, worst, True)]
    removed: list[str] = []
    keep = est_names
    while len(keep) > max(min_parameters, 1):
        candidate = [n for n in keep if n != worst]
        trial = fit(candidate)
        rr = trial.residual.relative_residual
        t_worst, t_rel = _worst(trial)
        ok = rr <= limit
        path.append(EssentialStep(worst, worst_rel, rr, t_rel, t_worst, ok))
        if not ok:
            break
        removed.append(worst)
        keep, current, worst, worst_rel = candidate, trial, t_worst, t_rel
    return EssentialResult(tuple(keep), tuple(removed), tuple(path), current)
