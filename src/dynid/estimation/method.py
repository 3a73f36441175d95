"""The estimator a run uses, as a value: parsed once from the config's text, then read by the estimator, the
report and results.json (statsmodels' ``fit(method=...)``, typed; never a string compared in several places).

The config's spelling ("ols", "wls", "iv", "wls-pc") and the label tables and results.json print ("OLS", "WLS",
"IV", "WLS-PC") are two views of one member.
"""

from __future__ import annotations

from enum import Enum

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


__all__ = ["Method"]
