"""Parameter tables in the paper's layout: name, a priori, (truth), estimate, %σ, (%σ total), flag, (reference).

%σ is the paper's (least squares, statistical); %σ total adds the declared sensor offsets' effect.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..estimation import EXCITED_FACTOR, IdentificationResult


def _cell(v: float | None, spec: str = ".6g") -> str:
    return "" if v is None or (isinstance(v, float) and not np.isfinite(v)) else format(v, spec)


def parameter_table(
    result: IdentificationResult,
    sections: Sequence[tuple[str, Sequence[str]]] | None = None,
    reference: Mapping[str, tuple[float, float]] | None = None,
    reference_title: str = "published",
) -> str:
    """A text table per section (title, parameter names); all parameters in one section by default.

    reference: name -> (value, %σ) shown beside our estimate (e.g. a publication's).
    """
    sections = sections or [(f"{result.method} estimates", list(result.names))]
    has_truth = bool(result.truth)
    total = result.rel_std_total_percent if result.systematic is not None else None
    head = ["parameter", "a priori"] + (["truth"] if has_truth else []) + ["estimate", "%σ"]
    head += (["%σ total"] if total is not None else []) + ["flag", "paper rule"]
    flags = result.uncertainty_flags
    if reference:
        head += [reference_title, f"{reference_title} %σ"]
    out = []
    for title, names in sections:
        rows = [head]
        for name in names:
            i = result.index(name)
            row = [result.labels.get(name, name), _cell(result.a_priori.get(name))]
            if has_truth:
                row.append(_cell(result.truth.get(name)))
            row += [_cell(float(result.values[i])), _cell(float(result.rel_std_percent[i]), ".2f")]
            row += ([_cell(float(total[i]), ".2f")] if total is not None else []) + [flags[i], result.flags[i]]
            if reference:
                ref = reference.get(name)
                row += [_cell(ref[0]), _cell(ref[1], ".2f")] if ref else ["", ""]
            rows.append(row)
        widths = [max(len(r[c]) for r in rows) for c in range(len(head))]
        lines = [title, "  ".join(h.rjust(w) for h, w in zip(rows[0], widths, strict=True))]
        lines.append("  ".join("-" * w for w in widths))
        lines += ["  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in rows[1:]]
        out.append("\n".join(lines))
    return "\n\n".join(out)


def validation_table(errors: Mapping[str, Mapping[str, float]],
                     not_excited: Mapping[str, Sequence[str]] | None = None) -> str:
    """Relative errors ||Y - W X|| / ||Y|| per group, one column per validation kind (direct, cross);
    not_excited: per kind, the groups whose Y the test barely moves (marked with *)."""
    kinds = [k for k in errors if errors[k]]
    marked = {k: set((not_excited or {}).get(k, ())) for k in kinds}
    groups = list(dict.fromkeys(g for k in kinds for g in errors[k]))
    lines = ["group".rjust(12) + "".join(k.rjust(13) for k in kinds)]
    for g in groups:
        lines.append(g.rjust(12) + "".join(
            ((f"{100 * errors[k][g]:.2f} %" + ("*" if g in marked[k] else " ")) if g in errors[k] else "").rjust(13)
            for k in kinds))
    if any(marked.values()):
        lines.append(f"* the test barely moves this equation (RMS of Y below {EXCITED_FACTOR:g} times the "
                     "identification's residual RMS there): its relative error mostly compares noise with a small "
                     "signal")
    return "\n".join(lines)


def consistency_section(verdict: Mapping[str, Any]) -> str:
    """A robot's physical-consistency verdict for the report (as the car's, under the tables): the verdict,
    then with wls-pc how much the fit worsened against plain WLS and which constraints are active."""
    lines = [f"Physical consistency of the estimates: {verdict['text']}"]
    pc = verdict.get("wls_pc")
    if isinstance(pc, Mapping):
        lines.append(
            f"wls-pc: ||Y - W X||/||Y|| = {100 * pc['relative_residual']:.4g} % against plain WLS's "
            f"{100 * pc['relative_residual_wls']:.4g} % ({pc['fit_worsening_percent']:+.3g} %), chi-square increase "
            f"{pc['chi2_increase']:.4g}; active constraints: {', '.join(pc['active_constraints']) or 'none'}; "
            f"standard deviations: {pc['std']}")
    return "\n".join(lines)
