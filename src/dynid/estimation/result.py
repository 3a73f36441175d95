"""The result of an identification: named values, standard deviations, flags; table, dict, JSON."""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import atomic_path
from .lsq import LSQSolution
from .method import Method
from .quality import POOR_FACTOR, poorly_identified, relative_std_percent
from .systematic import SystematicUncertainty

FLAG_POOR = "poor"
FLAG_KNOWN = "known"
FLAG_UNCERTAIN = "uncertain"
FLAG_MISFIT = "misfit"  # the parameter's equation group does not fit the data (estimation/fit.py): not a result
FLAG_PERCENT = 2.5
"""The flag a user acts on: a parameter whose total standard uncertainty exceeds 2.5 % of its engineering scale
(so that its 95 % interval is wider than +-5 %) is "uncertain". Chosen on ten seeds of the demo (see the
demo's note): it caught the estimates more than 5 % off and left most of those within 5 % unflagged, where
the paper's 20x rule flags nearly everything once %σ is small for a few parameters."""


@dataclass(frozen=True)
class ResidualStats:
    """Residual statistics of an identification.

    n_rows : rows of W (m). n_estimated : estimated parameters (q). dof : m - q.
    sigma : standard deviation of the residual of the system actually solved (for WLS the
    weighted one, dimensionless and ≈ 1 when the group noise levels are right).
    rss : its squared norm. relative_residual : ``||Y - W X|| / ||Y||`` on the unweighted data,
    with the known parameters included (units cancel).
    """

    n_rows: int
    n_estimated: int
    dof: int
    sigma: float
    rss: float
    relative_residual: float

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON dict of the fields."""
        return _jsonable(self.__dict__)


def _default_validation() -> dict[str, dict[str, Any]]:
    return {"direct": {}, "cross": {}}


@dataclass(eq=False)
class IdentificationResult:
    """Identified parameters with their names (one entry per parameter, estimated or known).

    names : all p parameter names, in the caller's order.
    values : (p,) estimates (the fixed value for a known parameter), SI units of each parameter.
    std : (p,) standard deviations (NaN for known parameters).
    rel_std_percent : (p,) ``100 * std / |value|`` (NaN for known parameters).
    flags : the paper's rule (§7.2), per parameter "" (fine), "poor" (%σ > poor_factor x smallest %σ) or "known".
    scales : ``{name: engineering scale}`` (same unit as the parameter; default |value|): the size against
    which an error matters (a product of inertia against a principal moment, a first moment against a
    centimetre of centre-of-mass shift times the mass). flag_percent : `uncertainty_flags` threshold.
    labels, a_priori, truth, known : ``{name: ...}`` (labels default to the names).
    method : the estimator (`Method`; its label, "OLS", "WLS", "IV" or "WLS-PC", is what tables and JSON print).
    weights : ``{group: sigma_j}`` (every weighted method; {} for OLS).
    condition_number : condition number of the matrix solved (W for OLS, the weighted W for WLS).
    residual : ``ResidualStats``.
    covariance : (q, q) covariance of the estimated parameters, order ``estimated_names``.
    validation : ``{"direct": {...}, "cross": {...}}``, filled by the caller (e.g. relative errors).
    systematic : the declared sensor offsets' effect (`with_systematic`), or None; `std` stays the
    statistical (paper) one, `std_total` combines both.
    """

    names: tuple[str, ...]
    values: np.ndarray
    std: np.ndarray
    rel_std_percent: np.ndarray
    flags: tuple[str, ...]
    labels: dict[str, str]
    a_priori: dict[str, float]
    truth: dict[str, float]
    known: dict[str, float]
    method: Method
    weights: dict[str, float]
    condition_number: float
    residual: ResidualStats
    covariance: np.ndarray
    estimated_names: tuple[str, ...]
    poor_factor: float = POOR_FACTOR
    validation: dict[str, dict[str, Any]] = field(default_factory=_default_validation)
    systematic: SystematicUncertainty | None = None
    scales: dict[str, float] = field(default_factory=dict)
    flag_percent: float = FLAG_PERCENT
    misfit: dict[str, list[str]] = field(default_factory=dict)
    cov_type: str = "nonrobust"  # which covariance `covariance` and σ are (`method.Covariance.label`)
    hac_lags: dict[str, int] = field(default_factory=dict)  # {group: the kernel's last lag} of a HAC covariance

    # ----------------------------------------------------------------- access by name
    def index(self, name: str) -> int:
        """Position of parameter ``name`` in ``names`` (KeyError naming it if absent)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no parameter {name!r} in this result") from None

    def value(self, name: str) -> float:
        """Estimate (or known value) of parameter ``name``."""
        return float(self.values[self.index(name)])

    @property
    def full_covariance(self) -> np.ndarray:
        """(p, p) covariance over every parameter in ``names`` order (zero rows and columns for known ones)."""
        names = list(self.names)
        cov = np.zeros((len(names), len(names)))
        idx = [names.index(n) for n in self.estimated_names]
        cov[np.ix_(idx, idx)] = self.covariance
        return cov

    @property
    def estimates(self) -> dict[str, float]:
        """``{name: value}`` of every parameter."""
        return {n: float(v) for n, v in zip(self.names, self.values, strict=True)}

    @property
    def std_systematic(self) -> np.ndarray:
        """(p,) standard deviations caused by the declared sensor offsets (0 without any; NaN if known)."""
        out = np.where(np.isnan(self.std), np.nan, 0.0)
        if self.systematic is not None:
            for k, n in enumerate(self.systematic.names):
                out[self.index(n)] = self.systematic.std[k]
        return out

    @property
    def std_total(self) -> np.ndarray:
        """(p,) combined standard uncertainty: statistical and systematic in quadrature."""
        return np.hypot(self.std, self.std_systematic)

    @property
    def rel_std_total_percent(self) -> np.ndarray:
        return relative_std_percent(self.values, self.std_total)

    def with_systematic(self, systematic: SystematicUncertainty) -> IdentificationResult:
        """This result with the sensor offsets' uncertainty attached (flags unchanged: paper's rule)."""

        return dataclasses.replace(self, systematic=systematic)

    def with_covariance(self, covariance: np.ndarray, cov_type: str,
                        hac_lags: Mapping[str, int] | None = None) -> IdentificationResult:
        """This estimate with another covariance of its estimated parameters (q, q, `estimated_names` order):
        σ, %σ and the paper's flags from it; cov_type says which (the report and results.json print it)."""
        C = np.asarray(covariance, dtype=float)
        q = len(self.estimated_names)
        if C.shape != (q, q):
            raise ValueError(f"with_covariance: covariance has shape {C.shape}, expected {(q, q)}")
        pos = [self.index(n) for n in self.estimated_names]
        std, rel = self.std.copy(), self.rel_std_percent.copy()
        std[pos] = np.sqrt(np.diag(C))
        rel[pos] = relative_std_percent(self.values[pos], std[pos])
        poor = set(poorly_identified(dict(zip(self.estimated_names, rel[pos], strict=True)), self.poor_factor))
        flags = tuple(f if f == FLAG_KNOWN else FLAG_POOR if n in poor else "" for n, f in zip(self.names, self.flags,
                                                                                                 strict=True))
        return dataclasses.replace(self, covariance=C, std=std, rel_std_percent=rel, flags=flags, cov_type=cov_type,
                                   hac_lags=dict(hac_lags or {}))

    @property
    def scale(self) -> np.ndarray:
        """(p,) the engineering scale of each parameter: `scales`, else |value|."""
        return np.array([self.scales.get(n, abs(float(v))) for n, v in zip(self.names, self.values, strict=True)])

    @property
    def rel_std_scale_percent(self) -> np.ndarray:
        """(p,) 100 std_total / scale: the total uncertainty against the parameter's engineering scale."""
        return relative_std_percent(self.scale, self.std_total)

    @property
    def uncertainty_flags(self) -> tuple[str, ...]:
        """Per parameter "misfit" (an equation group it enters does not fit the data: `misfit`), "uncertain"
        (std_total above flag_percent of its scale), "known" or "": the flag to act on. Unlike the paper's rule it
        does not depend on the best-identified parameter, and it counts the sensors' declared offsets."""
        rel = self.rel_std_scale_percent
        return tuple(FLAG_KNOWN if f == FLAG_KNOWN else FLAG_MISFIT if self.names[i] in self.misfit
                     else FLAG_UNCERTAIN if not rel[i] <= self.flag_percent else ""
                     for i, f in enumerate(self.flags))

    @property
    def uncertain(self) -> list[str]:
        """Names flagged "uncertain"."""
        return [n for n, f in zip(self.names, self.uncertainty_flags, strict=True) if f == FLAG_UNCERTAIN]

    @property
    def poor(self) -> list[str]:
        """Names flagged as poorly identified."""
        return [n for n, f in zip(self.names, self.flags, strict=True) if f == FLAG_POOR]

    # ----------------------------------------------------------------- exports
    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON dict (non-finite numbers become null).

        Schema: ``{"method", "cov_type", ("hac_lags": {group: L},) "parameters": [{"name", "label", "value", "std",
        "rel_std_percent", "a_priori", "truth", "flag", "paper_rule", "scale"}],
        "validation": {"direct": {...}, "cross": {...}}, "condition_number", "weights": {group: sigma},
        "residual": {...}, "poor_factor", "flag_percent"}``;
        "flag" is `uncertainty_flags`, "paper_rule" the paper's 20x rule (`flags`); with sensor
        offsets declared, each parameter also has "std_systematic", "std_total", "rel_std_total_percent"
        and "main_offset" (the offset that moves it most).
        """
        sys_std, total, rel_total = self.std_systematic, self.std_total, self.rel_std_total_percent
        uflags, scale = self.uncertainty_flags, self.scale
        params = [
            {
                "name": n,
                "label": self.labels.get(n, n),
                "value": float(self.values[i]),
                "std": float(self.std[i]),
                "rel_std_percent": float(self.rel_std_percent[i]),
                "a_priori": self.a_priori.get(n),
                "truth": self.truth.get(n),
                "flag": uflags[i],
                "paper_rule": self.flags[i],
                "scale": float(scale[i]),
                **({"std_systematic": float(sys_std[i]), "std_total": float(total[i]),
                    "rel_std_total_percent": float(rel_total[i]),
                    "main_offset": self.systematic.main_source(n) if n in self.systematic.names else None}
                   if self.systematic is not None else {}),
            }
            for i, n in enumerate(self.names)
        ]
        return _jsonable(
            {
                "method": self.method.label,
                "cov_type": self.cov_type,
                **({"hac_lags": self.hac_lags} if self.hac_lags else {}),
                "parameters": params,
                "validation": self.validation,
                "condition_number": self.condition_number,
                "weights": self.weights,
                "residual": self.residual.to_dict(),
                "poor_factor": self.poor_factor,
                "flag_percent": self.flag_percent,
            }
        )

    def to_dataframe(self) -> Any:
        """One row per parameter (index: name) with label, a_priori, truth, value, std, rel_std_percent, flag.

        Imports pandas only here; raises ImportError saying so if it is not installed.
        """
        try:
            import pandas as pd  # optional: pandas
        except ImportError as exc:
            raise ImportError(
                "IdentificationResult.to_dataframe() needs pandas, which is not installed; "
                "install pandas or use to_dict() / summary()"
            ) from exc
        rows = {
            "label": [self.labels.get(n, n) for n in self.names],
            "a_priori": [self.a_priori.get(n, np.nan) for n in self.names],
            "truth": [self.truth.get(n, np.nan) for n in self.names],
            "value": self.values.astype(float),
            "std": self.std.astype(float),
            "rel_std_percent": self.rel_std_percent.astype(float),
            "flag": list(self.flags),
        }
        return pd.DataFrame(rows, index=pd.Index(self.names, name="name"))

    def save_json(self, path: str | os.PathLike[str]) -> Path:
        """Write ``to_dict()`` as JSON atomically: a temp file in the same directory, fsync, os.replace.

        A failure at any point leaves the previous file (if any) untouched and no temp file behind.
        The new file keeps the mode of the file it replaces, else 0o644. Returns the path written.
        """
        target = Path(path)
        with atomic_path(target) as tmp:
            tmp.write_text(json.dumps(self.to_dict(), indent=2, allow_nan=False) + "\n", encoding="utf-8")
        return target

    def summary(self) -> str:
        """A paper-style text table: parameter (label), a priori, truth, estimate, std, %σ, flag."""
        p, q = len(self.names), len(self.estimated_names)
        r = self.residual
        head = [
            f"Identification by {self.method}: {r.n_rows} rows, {p} parameters "
            f"({q} estimated, {p - q} known), {r.dof} degrees of freedom",
            f"  condition number {_num(self.condition_number, '.4g')}"
            f"{' (weighted W)' if self.weights else ''}, "
            f"residual std {_num(r.sigma, '.4g')}{' (weighted, ~1 expected)' if self.weights else ''}, "
            f"||Y - W X||/||Y|| = {_num(100 * r.relative_residual, '.3g')} %",
            *([f"  covariance: {self.cov_type}"] if self.cov_type != "nonrobust" else []),
        ]
        show_label = any(self.labels.get(n, n) != n for n in self.names)
        columns = ["parameter"] + (["label"] if show_label else [])
        columns += (["a priori"] if self.a_priori else []) + (["truth"] if self.truth else [])
        columns += ["estimated", "std", "%std"] + (["%std total"] if self.systematic is not None else [])
        columns += ["flag", "paper rule"]
        rel_total, uflags = self.rel_std_total_percent, self.uncertainty_flags
        body = []
        for i, n in enumerate(self.names):
            row = [n] + ([self.labels.get(n, n)] if show_label else [])
            if self.a_priori:
                row.append(_num(self.a_priori.get(n), ".6g"))
            if self.truth:
                row.append(_num(self.truth.get(n), ".6g"))
            row += [
                _num(self.values[i], ".6g"),
                _num(self.std[i], ".3g"),
                _num(self.rel_std_percent[i], ".2f"),
                *([_num(rel_total[i], ".2f")] if self.systematic is not None else []),
                uflags[i],
                self.flags[i],
            ]
            body.append(row)
        widths = [max(len(c), *(len(b[k]) for b in body)) for k, c in enumerate(columns)]
        text_cols = 2 if show_label else 1

        def line(cells: Sequence[str]) -> str:
            out = [c.ljust(w) if k < text_cols or k == len(cells) - 1 else c.rjust(w)
                   for k, (c, w) in enumerate(zip(cells, widths, strict=True))]
            return "  ".join(out).rstrip()

        table = [line(columns), line(["-" * w for w in widths]), *(line(b) for b in body)]
        est = {n: float(self.rel_std_percent[self.index(n)]) for n in self.estimated_names}
        finite = {n: v for n, v in est.items() if np.isfinite(v)}
        foot = []
        if finite:
            best = min(finite, key=finite.__getitem__)
            foot.append(
                f"flag uncertain: the total standard uncertainty exceeds {self.flag_percent:g} % of the parameter's "
                f"scale (its 95 % interval is wider than +-{2 * self.flag_percent:g} %); {len(self.uncertain)} flagged"
            )
            foot.append(
                f"paper rule poor: %std > {self.poor_factor:g} x the smallest %std ({finite[best]:.3g} % for {best}), "
                f"paper §7.2; {len(self.poor)} flagged"
            )
        if self.systematic is not None:
            foot.append("%std total: with the declared sensor offsets propagated (%std is the paper's, statistical)")
        if self.weights:
            foot.append("equation groups: residual std sigma_j (rows weighted by 1/sigma_j)")
            gw = max(len(g) for g in self.weights)
            foot += [f"  {g.ljust(gw)}  {s:.4g}" for g, s in self.weights.items()]
        return "\n".join([*head, "", *table, "", *foot]).rstrip() + "\n"


def _num(v: float | None, spec: str) -> str:
    if v is None or (isinstance(v, float | np.floating) and np.isnan(v)):
        return "-"
    return format(float(v), spec)


def _jsonable(obj: Any) -> Any:
    """Plain JSON types: dict keys to str, arrays/tuples to lists, numpy scalars to Python, non-finite to None."""
    if isinstance(obj, Mapping):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, np.ndarray):
        return [_jsonable(v) for v in obj.tolist()]
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, bool | np.bool_):
        return bool(obj)
    if isinstance(obj, int | np.integer):
        return int(obj)
    if isinstance(obj, float | np.floating):
        x = float(obj)
        return x if np.isfinite(x) else None
    return obj


def build_result(
    solution: LSQSolution,
    *,
    names: Sequence[str],
    estimated_names: Sequence[str],
    known: Mapping[str, float],
    labels: Mapping[str, str],
    a_priori: Mapping[str, float],
    truth: Mapping[str, float],
    method: Method,
    weights: Mapping[str, float],
    relative_residual: float,
    poor_factor: float = POOR_FACTOR,
) -> IdentificationResult:
    """Assemble an ``IdentificationResult`` from a solution on the estimated parameters, by name."""
    est_pos = {n: k for k, n in enumerate(estimated_names)}
    p = len(names)
    values = np.empty(p)
    std = np.full(p, np.nan)
    rel = np.full(p, np.nan)
    sol_std = solution.std
    sol_rel = relative_std_percent(solution.x, sol_std)
    poor = set(poorly_identified(dict(zip(estimated_names, sol_rel, strict=True)), poor_factor))
    flags = []
    for i, n in enumerate(names):
        if n in est_pos:
            k = est_pos[n]
            values[i], std[i], rel[i] = solution.x[k], sol_std[k], sol_rel[k]
            flags.append(FLAG_POOR if n in poor else "")
        else:
            values[i] = known[n]
            flags.append(FLAG_KNOWN)
    return IdentificationResult(
        names=tuple(names),
        values=values,
        std=std,
        rel_std_percent=rel,
        flags=tuple(flags),
        labels={n: labels.get(n, n) for n in names},
        a_priori=dict(a_priori),
        truth=dict(truth),
        known=dict(known),
        method=method,
        weights=dict(weights),
        condition_number=solution.condition_number,
        residual=ResidualStats(
            n_rows=solution.n_rows,
            n_estimated=len(estimated_names),
            dof=solution.dof,
            sigma=float(np.sqrt(solution.sigma2)),
            rss=solution.rss,
            relative_residual=float(relative_residual),
        ),
        covariance=solution.covariance,
        estimated_names=tuple(estimated_names),
        poor_factor=float(poor_factor),
    )
