"""The estimator a run uses, as a value: parsed once from the config's text, then read by the estimator, the
report and results.json (statsmodels' ``fit(method=...)``, typed; never a string compared in several places).

The config's spelling ("ols", "wls", "iv", "wls-pc") and the label tables and results.json print ("OLS", "WLS",
"IV", "WLS-PC") are two views of one member.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np

from .errors import IdentificationError


class Method(Enum):
    """An estimator: ordinary LS, Gautier's weighted LS (paper eq. (8)-(10)), weighted instrumental variables
    (IDIM-IV), or WLS under physical-consistency constraints. The value is the config's spelling."""

    OLS = "ols"
    WLS = "wls"
    IV = "iv"
    WLS_PC = "wls-pc"

    @classmethod
    def parse(cls, text: object, where: str = "method") -> Method:
        """The member a config's text (any case) or a result's label names; a one-line error naming the choices."""
        if isinstance(text, Method):
            return text
        if isinstance(text, str):
            for m in cls:
                if text.lower() in (m.value, m.label.lower()):
                    return m
        choices = ", ".join(f'"{m.value}"' for m in cls)
        raise IdentificationError(f"{where} = {text!r}; use one of {choices}")

    @property
    def label(self) -> str:
        """What tables, the report and results.json print: "OLS", "WLS", "IV", "WLS-PC"."""
        return self.value.upper()

    @property
    def weighted(self) -> bool:
        """Whether rows are weighted by their group's 1/σ_j (every estimator but OLS)."""
        return self is not Method.OLS

    @property
    def reference_column(self) -> str:
        """The published column (a [reference] table's "ols" or "wls") an estimate of this method compares with:
        the weighted one for every weighted estimator."""
        return "wls" if self.weighted else "ols"

    def __str__(self) -> str:
        return self.label


class CovType(Enum):
    """How σ is computed (statsmodels' ``cov_type``): "nonrobust", σ² (WᵀW)⁻¹ with white rows (paper eq. (7));
    "hac", Newey–West's sandwich with a Bartlett kernel per equation group (the decimated rows are
    autocorrelated: the filters and the model's errors span many of them); "hac-groupsum", Driscoll–Kraay's: the
    scores of every equation group at one sample summed before the kernel (statsmodels' ``"hac-groupsum"`` with
    the sample as its time), for a sensor whose noise enters several groups' rows at once (a car's inertial unit:
    its accelerations in every chassis equation)."""

    NONROBUST = "nonrobust"
    HAC = "hac"
    HAC_GROUPSUM = "hac-groupsum"


@dataclass(frozen=True)
class Covariance:
    """The covariance option of a run, parsed once: its kind and, for HAC, the lags (None: Newey–West's rule
    floor(4 (n_g / 100)^(2/9)) on each group's row count n_g, statsmodels' default for ``S_hac_simple``)."""

    kind: CovType = CovType.NONROBUST
    lags: int | None = None

    @classmethod
    def parse(cls, cov_type: object = "nonrobust", hac_lags: object = None, where: str = "") -> Covariance:
        """From a config's ``cov_type`` and ``hac_lags`` (an int >= 0, or "auto"/None); one-line errors naming
        `where` and the choices."""
        at = f"{where} " if where else ""
        kinds = {k.value: k for k in CovType}
        if not isinstance(cov_type, str) or cov_type.lower() not in kinds:
            raise IdentificationError(f"{at}cov_type = {cov_type!r}; use one of "
                                      + ", ".join(f'"{k}"' for k in kinds))
        kind = kinds[cov_type.lower()]
        if hac_lags is None or (isinstance(hac_lags, str) and hac_lags.lower() == "auto"):
            lags = None
        elif isinstance(hac_lags, int | np.integer) and not isinstance(hac_lags, bool) and hac_lags >= 0:
            lags = int(hac_lags)
        else:
            raise IdentificationError(f"{at}hac_lags = {hac_lags!r}; give a whole number of rows >= 0, or \"auto\" "
                                      "(Newey–West's rule per group)")
        if kind is CovType.NONROBUST and lags is not None:
            raise IdentificationError(f"{at}hac_lags = {lags} needs cov_type = \"hac\" or \"hac-groupsum\"")
        return cls(kind, lags)

    @property
    def hac(self) -> bool:
        """Whether σ is a sandwich over a second pass (either HAC kind)."""
        return self.kind is not CovType.NONROBUST

    @property
    def groupsum(self) -> bool:
        """Whether the groups' scores at one sample are summed before the kernel (Driscoll–Kraay)."""
        return self.kind is CovType.HAC_GROUPSUM

    def lags_for(self, n_rows: int) -> int:
        """The kernel's last lag (rows) for a group of n_rows rows."""
        if self.lags is not None:
            return self.lags
        return int(np.floor(4.0 * (max(n_rows, 0) / 100.0) ** (2.0 / 9.0)))

    @property
    def label(self) -> str:
        """What the report and results.json print."""
        if not self.hac:
            return "nonrobust"
        if self.groupsum:
            rule = "Newey–West lags" if self.lags is None else f"{self.lags} lags"
            return (f"HAC group-summed (Driscoll–Kraay: every group's scores at a sample summed, Bartlett kernel, "
                    f"{rule})")
        rule = "Newey–West lags per group" if self.lags is None else f"{self.lags} lags"
        return f"HAC (Bartlett kernel, {rule}, per equation group)"


__all__ = ["CovType", "Covariance", "Method"]
