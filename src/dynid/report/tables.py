"""Parameter tables in the paper's layout: name, a priori, (truth), estimate, %σ, (%σ total), flag, (reference).

%σ is the paper's (least squares, statistical); %σ total adds the declared sensor offsets' effect.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..estimation import EXCITED_FACTOR, IdentificationResult
from .format import round_to_uncertainty


def _cell(v: float | None, spec: str = ".6g") -> str:
    return "" if v is None or (isinstance(v, float) and not np.isfinite(v)) else format(v, spec)


def _line(cells: Sequence[str], widths: Sequence[int], left: set[int]) -> str:
    return "  ".join(c.ljust(w) if i in left else c.rjust(w)
                     for i, (c, w) in enumerate(zip(cells, widths, strict=True))).rstrip()


def parameter_table(
    result: IdentificationResult,
    sections: Sequence[tuple[str, Sequence[str]]] | None = None,
    reference: Mapping[str, tuple[float, float]] | None = None,
    reference_title: str = "published",
    meanings: Mapping[str, tuple[str, str]] | None = None,
) -> str:
    """A text table per section (title, parameter names); all parameters in one section by default.

    reference: name -> (value, %σ) shown beside our estimate (e.g. a publication's).
    meanings: name -> (what it is, unit), e.g. ("spring, rear left", "N/m") for the car's ks9: two columns after
    the parameter's label.
    """
    sections = sections or [(f"{result.method} estimates", list(result.names))]
    has_truth = bool(result.truth)
    total = result.rel_std_total_percent if result.systematic is not None else None
    head = ["parameter"] + (["corner, quantity", "unit"] if meanings else []) + ["a priori"]
    head += (["truth"] if has_truth else []) + ["estimate", "%σ"]
    head += (["%σ total"] if total is not None else []) + ["flag", "paper rule"]
    flags = result.uncertainty_flags
    if reference:
        head += [reference_title, f"{reference_title} %σ"]
    out = []
    for title, names in sections:
        rows = [head]
        for name in names:
            i = result.index(name)
            row = [result.labels.get(name, name)]
            if meanings:
                row += list(meanings.get(name, ("", "")))
            row.append(_cell(result.a_priori.get(name)))
            if has_truth:
                row.append(_cell(result.truth.get(name)))
            row += [_cell(float(result.values[i])), _cell(float(result.rel_std_percent[i]), ".2f")]
            row += ([_cell(float(total[i]), ".2f")] if total is not None else []) + [flags[i], result.flags[i]]
            if reference:
                ref = reference.get(name)
                row += [_cell(ref[0]), _cell(ref[1], ".2f")] if ref else ["", ""]
            rows.append(row)
        widths = [max(len(r[c]) for r in rows) for c in range(len(head))]
        words = {1, 2} if meanings else set()  # the words left-aligned, the numbers right-aligned
        lines = [title, _line(rows[0], widths, words), "  ".join("-" * w for w in widths)]
        lines += [_line(r, widths, words) for r in rows[1:]]
        out.append("\n".join(lines))
    return "\n\n".join(out)


def equation_axes(kind: str | None) -> tuple[Mapping[str, Any], str]:
    """How a run's equation groups are shown, by the run's kind (its config's `kind`): a car's chassis equations
    in ISO 8855 terms (`vehicle.axes`: group -> label, sign, the paper's name) and the note that maps them to the
    paper's names; ({}, "") for anything else, whose groups are shown as they are named."""
    if kind != "car":
        return {}, ""
    # start-up: a car's alone (the vehicle package is not on a robot's path)
    from ..vehicle.axes import CHASSIS_AXES, TABLE_NOTE

    return CHASSIS_AXES, TABLE_NOTE


def axis_label(group: str, axes: Mapping[str, Any]) -> str:
    """The name the report gives an equation group: its label in `axes` (equation_axes), else the group's."""
    axis = axes.get(group)
    return axis.label if axis else group


def to_iso(group: str, axes: Mapping[str, Any], *signals: np.ndarray) -> tuple[np.ndarray, ...]:
    """The signals of an equation group in the report's sign (`axes`' sign for the group, else as they are)."""
    axis = axes.get(group)
    s = axis.sign if axis else 1.0
    return tuple(np.asarray(x) if s == 1.0 else s * np.asarray(x) for x in signals)


def validation_table(errors: Mapping[str, Mapping[str, float]],
                     not_excited: Mapping[str, Sequence[str]] | None = None, kind: str | None = None) -> str:
    """Relative errors ||Y - W X|| / ||Y|| per group, one column per validation kind (direct, cross);
    not_excited: per kind, the groups whose Y the test barely moves (marked with *); kind: the run's (its
    config's), which says how its groups are named (`equation_axes`)."""
    axes, note = equation_axes(kind)
    kinds = [k for k in errors if errors[k]]
    marked = {k: set((not_excited or {}).get(k, ())) for k in kinds}
    groups = list(dict.fromkeys(g for k in kinds for g in errors[k]))
    width = max([12, *(len(axis_label(g, axes)) + 1 for g in groups)])
    lines = ["group".rjust(width) + "".join(k.rjust(13) for k in kinds)]
    for g in groups:  # a car's chassis equation by its ISO 8855 name, as in the report (vehicle.axes)
        lines.append(axis_label(g, axes).rjust(width) + "".join(
            ((f"{100 * errors[k][g]:.2f} %" + ("*" if g in marked[k] else " ")) if g in errors[k] else "").rjust(13)
            for k in kinds))
    if any(g in axes for g in groups):
        lines.append(note)
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


def _plus_minus(value: float, std: float) -> str:
    """value ± σ rounded to σ's two digits; the value alone (4 significant digits) when σ is 0 or not known."""

    if np.isfinite(std) and std > 0:
        v, s = round_to_uncertainty(value, std)
        return f"{v} ± {s}"
    return f"{value:.4g}"


# the terminal's ride-and-handling block: (row title, unit, [(item label, key)]); a row's unit is its items'
_BLOCK = (
    ("mass", "kg", [("total", "mass_total"), ("sprung (M6)", "mass_sprung"), ("unsprung", "mass_unsprung")]),
    ("CoG, whole car", "m", [("ahead of rear axle", "cg_ahead_rear"), ("above ground", "cg_height"),
                             ("left", "cg_lateral")]),
    ("inertia at sprung CoG", "kg·m²", [("roll Ixx", "Ixx"), ("pitch Iyy", "Iyy"), ("yaw Izz", "Izz")]),
    ("corner weights", "kg", [("FL", "corner_front_left"), ("FR", "corner_front_right"), ("RL", "corner_rear_left"),
                              ("RR", "corner_rear_right")]),
    ("axle loads", "N", [("front", "front_load"), ("rear", "rear_load")]),
    ("front axle share", "%", [("whole car", "front_share")]),
    ("spring wheel rates", "N/m", [("FL", "wheel_rate_front_left"), ("FR", "wheel_rate_front_right"),
                                   ("RL", "wheel_rate_rear_left"), ("RR", "wheel_rate_rear_right")]),
    ("bar wheel rates, in roll", "N/m", [("front", "wheel_rate_bar_front"), ("rear", "wheel_rate_bar_rear")]),
    ("ride frequency", "Hz", [("front", "ride_frequency_front"), ("rear", "ride_frequency_rear")]),
    ("damping ratio", "", [("front", "damping_ratio_front"), ("rear", "damping_ratio_rear")]),
    ("roll stiffness", "N·m/deg", [("front", "roll_front"), ("rear", "roll_rear")]),
    ("roll stiffness share", "%", [("front", "roll_front_share")]),
    ("roll gradient", "deg/g", [("", "roll_gradient")]),
    ("pitch gradient", "deg/g", [("braking", "pitch_gradient")]),
)


def engineering_block(quantities: Sequence[Any], uncertainty: str = "total") -> str:
    """The car's figures in a chassis engineer's units, one row per quantity with its unit, σ propagated (the
    `vehicle.engineering.Quantity` list of an identification); report.html and engineering.csv have them all."""
    by = {q.key: q for q in quantities}
    rows = []
    for title, unit, items in _BLOCK:
        cells = [f"{label + ' ' if label else ''}{_plus_minus(by[k].value, by[k].std)}" for label, k in items
                 if k in by]
        if cells:
            rows.append((title, unit, "   ".join(cells)))
    width = max(len(t) for t, _, _ in rows)
    uw = max(len(u) for _, u, _ in rows)
    sigma = "σ total" if uncertainty == "total" else "σ statistical"
    lines = [f"The car in engineering terms (value ± {sigma}, first order; ISO 8855; report.html and "
             "engineering.csv have every figure, docs/engineering.md the formulas):"]
    lines += [f"  {t.ljust(width)}  {u.ljust(uw)}  {c}" for t, u, c in rows]
    return "\n".join(lines)
