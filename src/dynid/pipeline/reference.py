"""Published base-parameter tables, matched to ours by parameter combination.

A reference table (CSV, no header) has one base parameter per row:
`expression, OLS value, OLS %σ, WLS value, WLS %σ`, the expression a linear
combination such as `Izz1 + 1.0*Ia1 + 0.07*mz3`. Names are translated to dynid's
(`Izz` -> `ZZ`, ...) by a prefix table; a row matches our base parameter whose
regrouping expression is the same combination (coefficients equal to the table's
rounding). Where a publication parametrizes a term differently, `combinations` gives
the published quantity as a linear combination of our base parameters instead.
"""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..dynamics import BaseParameters
from ..estimation.method import Method
from ..model import ModelError
from ..textfiles import encoding_problem

_TERM = re.compile(r"([+-]?)\s*(?:(\d+(?:\.\d*)?(?:[eE][+-]?\d+)?)\s*\*\s*)?([A-Za-z_][A-Za-z_0-9]*)")


def parse_combination(expr: str, names: Mapping[str, str] | None = None) -> dict[str, float]:
    """'Izz1 + 1.0*Ia1 - 0.05*m3' -> {'ZZ1': 1.0, 'IA1': 1.0, 'M3': -0.05} with names {'Izz': 'ZZ', ...}."""
    out: dict[str, float] = {}
    pos = 0
    text = expr.strip()
    while pos < len(text):
        m = _TERM.match(text, pos)
        if m is None or m.end() == pos:
            raise ModelError(f"cannot read the combination {expr!r} at {text[pos:]!r}")
        sign, coef, name = m.groups()
        prefix, number = re.match(r"(.*?)(\d*)$", name).groups()
        key = (names or {}).get(prefix, prefix) + number if name not in (names or {}) else names[name]
        out[key] = out.get(key, 0.0) + (-1.0 if sign == "-" else 1.0) * float(coef or 1.0)
        pos = m.end()
        while pos < len(text) and text[pos] == " ":
            pos += 1
    return out


@dataclass(frozen=True)
class ReferenceRow:
    expression: str
    ols: float
    ols_rel_std: float
    wls: float
    wls_rel_std: float

    def published(self, method: Method) -> tuple[float, float]:
        """(value, %σ) of the published column to compare an estimate of `method` with (`Method.reference_column`:
        the weighted column for every weighted estimator, the OLS column for OLS)."""
        return (self.ols, self.ols_rel_std) if method.reference_column == "ols" else (self.wls, self.wls_rel_std)


def reference_text(path: str | Path) -> str:
    """The text of a reference table; a file that cannot be read, is binary or is not UTF-8 raises a `ModelError`
    naming it and the fix (a config's loader calls this before any work; its rows are read with the results)."""
    where = f"{path} (the [reference] file)"
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise ModelError(f"{where}: cannot read it ({exc.strerror or exc})") from None
    if b"\x00" in raw[:4096]:
        raise ModelError(f"{where}: binary data, not text (a NUL byte in its first 4 kB); give the published table "
                         "as CSV text: expression, OLS value, OLS %σ, WLS value, WLS %σ") from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise ModelError(f"{where}: {encoding_problem(path)}") from None
    return text


def read_reference(path: str | Path) -> list[ReferenceRow]:
    """The rows of a reference table (module doc). Errors name the file (and the line) and say what to give: a
    file that is not UTF-8 text, a row that is not `expression, 4 numbers`, an expression that is no combination."""
    where = f"{path} (the [reference] file)"
    text = reference_text(path)
    rows = []
    for line, rec in enumerate(csv.reader(io.StringIO(text, newline="")), start=1):
        if not rec or not any(c.strip() for c in rec):
            continue
        try:
            if len(rec) < 5:
                raise ValueError
            row = ReferenceRow(rec[0], *(float(x) for x in rec[1:5]))
            parse_combination(row.expression)
        except (ValueError, TypeError, ModelError):
            shown = repr(rec) if len(repr(rec)) <= 80 else repr(rec)[:60] + "..."
            raise ModelError(
                f"{where}, line {line}: expected 'expression, OLS value, OLS %σ, WLS value, WLS %σ' with the "
                f"expression a combination like Izz1 + 1.0*Ia1; got {shown}"
            ) from None
        rows.append(row)
    if not rows:
        raise ModelError(f"{where}: holds no row; give one line per published base parameter, 'expression, OLS value, "
                         "OLS %σ, WLS value, WLS %σ', or remove [reference] from the config")
    return rows


@dataclass(frozen=True)
class Match:
    """A published row and the same quantity computed from our base parameters (weights over them)."""

    row: ReferenceRow
    label: str
    weights: dict[str, float]

    def value(self, names: list[str], values: np.ndarray) -> float:
        return float(sum(w * values[names.index(n)] for n, w in self.weights.items()))

    def std(self, names: list[str], cov: np.ndarray) -> float:
        idx = [names.index(n) for n in self.weights]
        w = np.array(list(self.weights.values()))
        return float(np.sqrt(w @ cov[np.ix_(idx, idx)] @ w))


def match_reference(
    rows: list[ReferenceRow],
    base: BaseParameters,
    names: Mapping[str, str],
    combinations: Mapping[str, str] | None = None,
    rtol: float = 1e-4,
) -> tuple[list[Match], list[ReferenceRow]]:
    """Match published rows to our base parameters; returns (matches, rows left unmatched)."""
    ours = [parse_combination(e) for e in base.expressions]
    combos = {k: parse_combination(v) for k, v in (combinations or {}).items()}
    matches, unmatched = [], []
    for row in rows:
        pub = parse_combination(row.expression, names)
        label = next(iter(pub))
        if len(pub) == 1 and label in combos:  # a quantity the publication defines differently
            matches.append(Match(row, label, combos[label]))
            continue
        for name, comb in zip(base.names, ours, strict=True):
            if comb.keys() == pub.keys() and all(abs(comb[k] - pub[k]) <= rtol + rtol * abs(pub[k]) for k in pub):
                matches.append(Match(row, name, {name: 1.0}))
                break
        else:
            unmatched.append(row)
    return matches, unmatched
