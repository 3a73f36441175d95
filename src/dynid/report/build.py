"""The report of an identification run: what an engineer shares.

`build_report(run, title)` turns an `IdentificationRun` into the HTML page (tables with units, values rounded
to their uncertainty, flags with a legend, the car's engineering figures, the figures, the regrouping, the
physical-consistency verdict, traceability), the CSV files (parameters, validation signals, engineering
figures) and the additions to results.json. Writing is the caller's (`pipeline.run.write_outputs`).
"""

from __future__ import annotations

import csv
import io
import platform
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from .._version import __version__
from ..atomic import file_sha256, final_path
from ..estimation import EXCITED_FACTOR, not_excited
from ..estimation.fit import FIT_RATIO
from ..estimation.result import FLAG_KNOWN, FLAG_MISFIT, FLAG_UNCERTAIN
from ..shipped import DEMO_VEHICLE
from .apart import Apart
from .figures import (
    NOT_EXCITED,
    CogPoint,
    DamperCurve,
    ParameterRow,
    centre_of_gravity_figure,
    damper_curve_figure,
    parameter_figure,
    preload,
    validation_grid,
)
from .format import decimals, fixed, force_unit, parameter_unit, round_to_uncertainty
from .html import Cell, Section, Table, esc, render_html, table_html
from .tables import axis_label, equation_axes, to_iso
from .tables import consistency_section as robot_verdict

Z95 = 1.959964  # two-sided 95 % of a normal distribution
# a car's split of its equation groups into the validation figures: groups -> [(section, its groups, the paper's
# figures of it or "")]
Split = Callable[[list[str]], list[tuple[str, list[str], str]]]


@dataclass
class Report:
    """The page, the extra files (name -> text or bytes) and what results.json gains."""

    html: str
    files: dict[str, str | bytes] = field(default_factory=dict)
    data: dict[str, Any] = field(default_factory=dict)
    per_parameter: dict[str, dict[str, Any]] = field(default_factory=dict)


# ------------------------------------------------------------------ parameters


def _sections(run) -> list[tuple[str, list[str]]]:
    r = run.result
    return run.sections or [(f"{r.method} estimates of the base parameters", list(r.names))]


def interval95(value: float, std_total: float) -> tuple[float, float]:
    """The 95 % interval value ± 1.96 σ (normal, first order); NaNs for a known parameter."""
    if not np.isfinite(std_total):
        return float("nan"), float("nan")
    return value - Z95 * std_total, value + Z95 * std_total


def _num(x: float | None, d: int | None) -> Cell:
    ok = x is not None and np.isfinite(x)
    return Cell(fixed(float(x), d) if ok else "", float(x) if ok else None)


def meanings(run) -> dict[str, tuple[str, str]]:
    """A car's parameters' (corner, quantity) by name (`vehicle.template.meaning`); {} for a robot."""
    if not _is_car(run):
        return {}
    # start-up: a car's alone (the vehicle package, scipy.interpolate and optimize: 18 MB not on a robot's path)
    from ..vehicle.template import meaning

    found = {n: meaning(n) for n in run.result.names}
    return {n: (m.corner, m.quantity) for n, m in found.items() if m is not None}


def _is_car(run) -> bool:
    """Whether the run identified a car: what its config says it is."""
    return getattr(run.config, "kind", None) == "car"


def _car_equations(run) -> tuple[tuple[str, ...], Split | None]:
    """A car's chassis equation groups (joints 1..6, whose names carry no joint number) and its split of the
    equation groups into figures (`vehicle.presentation.equation_sections`); ((), None) for a robot."""
    if not _is_car(run):
        return (), None
    # start-up: a car's alone (the vehicle package, scipy.interpolate and optimize: 18 MB not on a robot's path)
    from ..vehicle.presentation import equation_sections
    from ..vehicle.template import CHASSIS_GROUPS

    return CHASSIS_GROUPS, equation_sections


def _equation_axes(run) -> Mapping[str, Any]:
    """How the run's equation groups are named and signed in the report, by its kind (`tables.equation_axes`: a
    car's chassis equations in ISO 8855, from the vehicle package; none for a robot)."""
    return equation_axes(getattr(run.config, "kind", None))[0]


def _frame_text(run) -> str:
    """The words over the parameter tables: a car's chassis frame (`vehicle.notes.FRAME6_TEXT`); none for a robot."""
    if not _is_car(run):
        return ""
    # start-up: a car's alone (the vehicle package, scipy.interpolate and optimize: 18 MB not on a robot's path)
    from ..vehicle.notes import FRAME6_TEXT

    return FRAME6_TEXT


def parameter_tables(run) -> list[Table]:
    """One table per section of the run (the paper's tables): unit, a priori, truth, estimate and σ total
    rounded to σ total, σ, %σ, %σ total, 95 % interval and the flag (the paper's rule: `paper_rule_details`)."""
    r, tree = run.result, run.model.tree
    has_truth, has_sys = bool(r.truth), r.systematic is not None
    total, flags, rel_total = r.std_total, r.uncertainty_flags, r.rel_std_total_percent
    what = meanings(run)
    head = ["parameter"] + (["corner, quantity"] if what else []) + ["unit", "a priori"]
    head += (["truth"] if has_truth else []) + ["estimate", "σ total", "σ"]
    head += ["%σ"] + (["%σ total"] if has_sys else []) + ["95 % interval", "flag"]
    tips = ["the parameter (paper's label)"] + (["which corner of the car, and what the parameter is"] if what
                                                 else []) + ["SI unit", "the a priori value (vehicle file or model)"]
    tips += ["the simulator's value"] if has_truth else []
    tips += ["estimate, rounded to two significant digits of σ total",
             "total standard uncertainty: statistical and the declared sensor offsets" if has_sys
             else "standard uncertainty (statistical)", "the paper's statistical standard deviation (eq. 9)",
             "100 σ / |estimate| (the paper's)"]
    tips += ["100 σ total / |estimate|"] if has_sys else []
    tips += ["estimate ± 1.96 σ total", "uncertain: act on it (see the legend)"]
    tables = []
    for title, names in _sections(run):
        rows = []
        for n in names:
            i = r.index(n)
            v, s, st = float(r.values[i]), float(r.std[i]), float(total[i])
            d = decimals(st)
            lo, hi = interval95(v, st)
            label = r.labels.get(n, n)
            row = [Cell(label, title=n if label != n else "", cls="t")]
            if what:
                row.append(Cell(", ".join(reversed(what[n])) if n in what else "", cls="t"))
            row += [Cell(parameter_unit(n, tree), cls="t nowrap"), _num(r.a_priori.get(n), d)]
            if has_truth:
                row.append(_num(r.truth.get(n), d))
            vs, ss = round_to_uncertainty(v, st)
            row += [Cell(vs, v), Cell(ss, st if np.isfinite(st) else None),
                    Cell(round_to_uncertainty(0.0, s)[1] if np.isfinite(s) else "", s if np.isfinite(s) else None),
                    _num(float(r.rel_std_percent[i]), 2)]
            if has_sys:
                row.append(_num(float(rel_total[i]), 2))
            row.append(Cell(f"[{fixed(lo, d)}, {fixed(hi, d)}]" if np.isfinite(lo) else "", lo if np.isfinite(lo)
                            else None, cls="nowrap"))
            f = flags[i]
            rank = {FLAG_MISFIT: 3, FLAG_UNCERTAIN: 2, FLAG_KNOWN: 0}.get(f, 1)
            rows.append([*row, Cell(f, rank, cls=f"t flag-{f}" if f else "t")])
        tables.append(Table(head, rows, caption=title, tips=tips, cls="params", pin=("corner, quantity", "estimate")))
    return tables


def _scale_rule(run) -> str:
    """How the flag's scales were chosen, for the legend: the car's chassis rule or the robot's per-link rule."""
    if _is_car(run):
        # start-up: a car's alone (the vehicle package, scipy.interpolate and optimize: 18 MB not on a robot's path)
        from ..vehicle.presentation import SCALE_RULE

        return SCALE_RULE
    return ("; for a product of inertia XY_j the largest a real body with the link's a priori moments can have, "
            "sqrt(XX_j YY_j); for a first moment the link's mass × its size (centre-of-mass distance, joint-to-joint "
            "length or radius of gyration, the largest); a base parameter that regroups several sums their scales, "
            "and none is judged against less than its own value")


def flag_legend(run) -> str:
    """What each flag means and what to do about it; for the car, which test would excite the flagged ones."""
    r = run.result
    uncertain = r.uncertain
    labels = ", ".join(r.labels.get(n, n) for n in uncertain)
    items = [
        (FLAG_UNCERTAIN, f"the total standard uncertainty exceeds {r.flag_percent:g} % of the parameter's "
         "engineering scale (its value" + (_scale_rule(run) if r.scales else "")
         + f"): its 95 % interval is wider than ±{2 * r.flag_percent:g} %. "
         "What to do: do not use the value as is; add a test that excites it, fix it from a bench measurement "
         "(declare it known), or carry its interval into what you use it for."
         + (f" Flagged here: {labels}." if uncertain else " None flagged here.")),
        (FLAG_MISFIT, "the residual of an equation group the parameter enters is more than "
         f"{FIT_RATIO:g} × what its sensors' errors explain (noise and zero offsets, drawn from the sensor suite and "
         "carried through the same joints and equations): the model does not fit that group, so the value is not a "
         "result, however small its σ. What to do: read the Notes (which group, by how much); a different equation "
         "(e.g. a tire that is not a straight line over the tests' load range), sensor dynamics that the vehicle "
         "file does not declare, or a test outside the model's range."
         + (f" Flagged here: {', '.join(r.labels.get(n, n) for n in r.misfit)}." if r.misfit
            else " None flagged here.")),
        (FLAG_KNOWN, "fixed from a bench or the config, not identified (no σ)."),
        ("paper rule: poor", f"the paper's rule (§7.2): %σ above {r.poor_factor:g} × the smallest %σ. Listed under "
         "the legend (folded) and in parameters.csv (paper_rule) for comparison; it depends on the "
         "best-identified parameter and ignores the sensors' offsets, so act on the flag instead."),
        ("rounding", "estimates, intervals, a priori and truth are rounded to two significant digits of σ total; "
         "the unrounded numbers are in results.json and parameters.csv."),
    ]
    out = '<dl class="legend">' + "".join(f"<dt>{esc(k)}</dt><dd>{esc(v)}</dd>" for k, v in items) + "</dl>"
    if uncertain and getattr(run.config, "kind", None) == "car":
        # start-up: a car's alone (the vehicle package, scipy.interpolate and optimize: 18 MB not on a robot's path)
        from ..vehicle.excitation import excitation_hint

        hint = excitation_hint(list(uncertain))
        if hint:
            out += "<p>" + "<br>".join(esc(line.strip()) for line in hint.split("\n")) + "</p>"
    return out


def paper_rule_details(run) -> str:
    """The paper's rule (§7.2: %σ above poor_factor × the smallest %σ) folded away under the legend: which
    parameters it calls poor beside our flag, for comparison with the paper; parameters.csv has it per row."""
    r = run.result
    rel = np.asarray(r.rel_std_percent, dtype=float)
    est = [i for i, f in enumerate(r.flags) if f != FLAG_KNOWN]
    finite = [i for i in est if np.isfinite(rel[i])]
    poor = [i for i in est if r.flags[i]]
    if not finite:
        return ""
    best = min(finite, key=lambda i: rel[i])
    flags = r.uncertainty_flags
    rows = [[Cell(r.labels.get(r.names[i], r.names[i]), cls="t"), _num(float(rel[i]), 2),
             Cell(flags[i], cls=f"t flag-{flags[i]}" if flags[i] else "t")] for i in poor]
    table = Table(["parameter", "%σ", "flag"], rows, cls="rule")
    best_label = r.labels.get(r.names[best], r.names[best])
    summary = (f"The paper's rule (§7.2): {len(poor)} of {len(est)} estimated parameters \"poor\" (%σ above "
               f"{r.poor_factor:g} × {rel[best]:.3g} %, that of {best_label})")
    why = ("For comparison with the paper only: the rule depends on the best-identified parameter and ignores the "
           "sensors' offsets; the flag column is the one to act on.")
    return (f'<details class="rule"><summary>{esc(summary)}</summary><p>{esc(why)}</p>'
            + (table_html(table) if rows else "") + "</details>")


def _parameter_rows(run) -> list[tuple[str, list[ParameterRow]]]:
    r = run.result
    total, scale = r.std_total, r.scale
    groups = []
    for title, names in _sections(run):
        rows = []
        for n in names:
            i = r.index(n)
            if not np.isfinite(total[i]):
                continue  # known: nothing estimated
            rows.append(ParameterRow(r.labels.get(n, n), float(r.values[i]), Z95 * float(total[i]),
                                     r.a_priori.get(n), r.truth.get(n) if r.truth else None,
                                     float(scale[i]) or 1.0))
        groups.append((title, rows))
    return groups


# ------------------------------------------------------------------ the car in engineering terms


def _covariance(r) -> tuple[np.ndarray, str]:
    """The estimate's covariance over estimated_names: statistical + sensor offsets when declared."""
    C = np.array(r.covariance, dtype=float)
    if r.systematic is not None:
        order = [r.systematic.names.index(n) for n in r.estimated_names]
        return C + np.asarray(r.systematic.covariance)[np.ix_(order, order)], "total"
    return C, "statistical"


def _vehicle(run):
    if getattr(run, "vehicle", None) is not None:
        return run.vehicle
    # start-up: a car's alone (the vehicle package, scipy.interpolate and optimize: 18 MB not on a robot's path)
    from ..vehicle.description import load_vehicle

    cfg = run.config
    return load_vehicle((getattr(cfg, "vehicle", None) or DEMO_VEHICLE) if cfg is not None else DEMO_VEHICLE)


def car_engineering(run) -> tuple[list, str, Any, dict[str, float]]:
    """The engineering figures of the estimate (with σ), which covariance they used, the vehicle, and all the
    parameter values (estimates and the tree's known ones)."""
    # start-up: a car's alone (the vehicle package, scipy.interpolate and optimize: 18 MB not on a robot's path)
    from ..vehicle.engineering import engineering_figures

    r, tree = run.result, run.model.tree
    vehicle = _vehicle(run)
    values = {**tree.values, **r.estimates}
    C, kind = _covariance(r)
    quantities = engineering_figures(values, vehicle.geometry, list(r.estimated_names), C)
    if getattr(run, "tires", None) is not None:  # the tire characteristics (vehicle.tire_curves), σ of their fit
        quantities += run.tires.quantities()
    return quantities, kind, vehicle, values


@dataclass(frozen=True)
class _Estimates:
    """names, values and a covariance over them (vehicle.dampers reads these)."""

    names: tuple[str, ...]
    values: np.ndarray
    full_covariance: np.ndarray


def damper_section(run) -> tuple[Section, bytes] | None:
    """The dampers' curves (car_model.car_template(damper_knees=...)): each corner's slopes with σ and 95 %
    interval in N·s/m, and the force-velocity figure with its 95 % band; None when no damper has a curve."""
    # start-up: a car's alone (the vehicle package, scipy.interpolate and optimize: 18 MB not on a robot's path)
    from ..vehicle.dampers import damper_curve, damper_slopes
    from ..vehicle.notes import DAMPER_CURVES_TEXT
    from ..vehicle.template import CORNERS, DAMPERS

    r, tree = run.result, run.model.tree
    curved = [d for d in DAMPERS if f"FVPL{d}" in r.names]
    if not curved:
        return None
    names = tuple(r.names)
    C = np.zeros((len(names), len(names)))
    idx = [names.index(n) for n in r.estimated_names]
    C[np.ix_(idx, idx)] = _covariance(r)[0]
    est = _Estimates(names, np.asarray(r.values, dtype=float), C)
    truth = (_Estimates(names, np.array([r.truth.get(n, np.nan) for n in names]), np.zeros_like(C))
             if r.truth and all(f"FVPL{d}" in r.truth for d in curved) else None)
    head = ["slope", "range (m/s)", "unit", "estimate", "σ", "95 % interval"] + (["truth"] if truth else [])
    tables, curves = [], []
    for d in curved:
        knees = tree.knee(d)
        rows = []
        for sl in damper_slopes(est, d, knees, tree.labels):
            dd = decimals(sl.std)
            vs, ss = round_to_uncertainty(sl.value, sl.std)
            lo, hi = interval95(sl.value, sl.std)
            span = " to ".join(f"{x:+g}" if np.isfinite(x) else ("+∞" if x > 0 else "−∞") for x in sl.range)
            row = [Cell(f"{sl.label} ({sl.meaning})", cls="t"), Cell(span, cls="t nowrap"), Cell("N·s/m", cls="t"),
                   Cell(vs, sl.value), Cell(ss, sl.std), Cell(f"[{fixed(lo, dd)}, {fixed(hi, dd)}]", cls="nowrap")]
            rows.append(row + ([_num(truth.values[names.index(sl.name)], dd)] if truth else []))
        corner = CORNERS[DAMPERS.index(d)]
        tables.append(Table(head, rows, caption=f"damper {d}, {corner}", sortable=False, cls="eng"))
        finite = [abs(k) for k in knees if np.isfinite(k)]
        top = max(0.3, 3.0 * max(finite, default=0.1))
        v = np.linspace(-top, top, 241)
        force, std = damper_curve(est, d, v, knees)
        curves.append(DamperCurve(f"damper {d} ({corner})", v, force, std,
                                  None if truth is None else damper_curve(truth, d, v, knees)[0], knees))
    return Section("Damper curves", DAMPER_CURVES_TEXT, tables=tables, anchor="dampers"), damper_curve_figure(curves)


def engineering_section(run, quantities, kind: str, vehicle, values) -> Section:
    # start-up: a car's alone (the vehicle package, scipy.interpolate and optimize: 18 MB not on a robot's path)
    from ..vehicle.engineering import car_quantities
    from ..vehicle.notes import engineering_text

    r = run.result
    truth = car_quantities({**values, **r.truth}, vehicle.geometry) if r.truth else None
    prior = car_quantities({**values, **r.a_priori}, vehicle.geometry) if r.a_priori else None
    head = ["quantity", "unit", "estimate", "σ", "95 % interval"] + (["a priori"] if prior else [])
    head += (["truth"] if truth else []) + ["note"]
    tables, rows, group = [], [], None
    for q in quantities:
        if q.group != group and rows:
            tables.append(Table(head, rows, caption=group, sortable=False, cls="eng"))
            rows = []
        group = q.group
        d = decimals(q.std)
        vs, ss = round_to_uncertainty(q.value, q.std)
        lo, hi = interval95(q.value, q.std)
        row = [Cell(q.label, cls="t"), Cell(q.unit, cls="t nowrap"), Cell(vs, q.value), Cell(ss, q.std),
               Cell(f"[{fixed(lo, d)}, {fixed(hi, d)}]" if np.isfinite(lo) else "", cls="nowrap")]
        row += [_num(prior.get(q.key), d)] if prior else []
        row += [_num(truth.get(q.key), d)] if truth else []
        rows.append([*row, Cell(q.note, cls="t")])
    if rows:
        tables.append(Table(head, rows, caption=group, sortable=False, cls="eng"))
    by = {q.key: q for q in quantities}
    m6, mu, mt = by["mass_sprung"], by["mass_unsprung"], by["mass_total"]
    text = engineering_text(fixed(m6.value, decimals(m6.std)), fixed(mu.value, 1), fixed(mt.value, decimals(mt.std)),
                            r.estimated_names, kind, vehicle.geometry)
    return Section("The car in engineering terms", text, tables=tables, anchor="engineering")


def cog_figure(run, quantities, vehicle, values) -> bytes:
    # start-up: a car's alone (the vehicle package, scipy.interpolate and optimize: 18 MB not on a robot's path)
    from ..vehicle.engineering import car_quantities, jacobian

    r, g = run.result, vehicle.geometry
    by = {q.key: q for q in quantities}
    C, _ = _covariance(r)
    names = list(r.estimated_names)

    def f(x):
        return car_quantities(x, g)

    covs = {}
    for prefix in ("cgs", "cg"):
        keys = [f"{prefix}_ahead_rear", f"{prefix}_height", f"{prefix}_lateral"]
        J = jacobian(f, values, names, keys, np.sqrt(np.clip(np.diag(C), 0, None)))
        S = J @ C @ J.T
        covs[prefix] = (S[np.ix_([0, 1], [0, 1])], S[np.ix_([0, 2], [0, 2])])
    points = [CogPoint("sprung mass (estimate)", by["cgs_ahead_rear"].value, by["cgs_height"].value,
                       by["cgs_lateral"].value, *covs["cgs"]),
              CogPoint("whole car (estimate)", by["cg_ahead_rear"].value, by["cg_height"].value,
                       by["cg_lateral"].value, *covs["cg"], color="#2ca02c", marker="s")]
    for label, src, color, marker in (("sprung, a priori", r.a_priori, "#888888", "^"),
                                      ("sprung, truth", r.truth, "#d62728", "D")):
        if src:
            q = car_quantities({**values, **src}, g)
            points.append(CogPoint(label, q["cgs_ahead_rear"], q["cgs_height"], q["cgs_lateral"], color=color,
                                   marker=marker))
    return centre_of_gravity_figure(g.front.position, g.rear.position, g.front.half_track, g.rear.half_track,
                                    g.wheel_radius, points)


# ------------------------------------------------------------------ validation


def group_unit(group: str, tree, chassis: Sequence[str] = ()) -> str:
    """The unit of an equation group's force: N for a prismatic joint's, N·m for a revolute one's. chassis: a car's
    groups of joints 1, 2, ... (`_car_equations`), whose names carry no joint number."""
    if group in chassis:
        j = chassis.index(group) + 1
    else:
        digits = group[len(group.rstrip("0123456789")):]
        if not digits:
            return ""
        j = int(digits)
    frame = next((f for f in tree.frames if f.j == j), None)
    return force_unit(frame is not None and frame.sigma == 1)


def validation_signals(run) -> dict[str, dict[str, dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]]]:
    """kind ("direct", "cross") -> test -> group -> (t, measured Y, predicted W X)."""
    x = run.result.values
    cfg = run.config
    if run.systems and cfg is not None:
        kinds = {"direct": [t.name for t in cfg.tests if t.role == "identify"],
                 "cross": [t.name for t in cfg.tests if t.role == "validate"]}
        systems = run.systems
    else:
        kinds = {"direct": ["identification tests"], "cross": list(run.validate)}
        systems = {"identification tests": run.identify, **run.validate}
    out: dict = {}
    for kind, tests in kinds.items():
        for name in tests:
            s = systems.get(name)
            if s is None or not len(s.Y):
                continue
            WX = s.W @ x
            per = {}
            for g in dict.fromkeys(s.groups.tolist()):
                m = s.groups == g
                per[g] = (s.t[m], s.Y[m], WX[m])
            out.setdefault(kind, {})[name] = per
    return out


def validation_csv(signals, tree, chassis: Sequence[str] = (), axes: Mapping[str, Any] | None = None) -> str:
    """validation.csv: per sample the measured and predicted side of each equation, in the report's names and
    signs (axes: a car's chassis equations in ISO 8855, `tables.equation_axes`)."""
    axes = axes or {}
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["validation", "test", "equation", "quantity", "unit", "t_s", "measured", "predicted"])
    for kind, tests in signals.items():
        for test, groups in tests.items():
            for g, (t, Y, WX) in groups.items():
                unit, label = group_unit(g, tree, chassis), axis_label(g, axes)
                for row in zip(t, *to_iso(g, axes, Y, WX), strict=True):  # the report's signs: ISO 8855, a chassis
                    w.writerow([kind, test, g, label, unit, *(f"{v:.9g}" for v in row)])
    return buf.getvalue()


def panel_corners(signals, noise: dict[str, float], axes: Mapping[str, Any] | None = None,
                  ) -> dict[tuple[str, str], str]:
    """What each validation panel (equation's label, test) says in its corner: the relative error ||Y - W X||/||Y||,
    or "not excited" where the test barely moves that equation by the rule that marks the cross-validation table
    (`estimation.not_excited`: RMS of the test's Y against the identification's residual RMS, `noise`); axes: how
    the equations are named (`tables.equation_axes`)."""
    axes = axes or {}
    out = {}
    for tests in signals.values():
        for test, per in tests.items():
            quiet = set(not_excited({g: float(np.sqrt(np.mean(np.square(Y)))) if len(Y) else 0.0
                                     for g, (_, Y, _) in per.items()}, noise))
            for g, (_, Y, WX) in per.items():
                err = np.linalg.norm(Y - WX) / max(float(np.linalg.norm(Y)), 1e-300)
                out[(axis_label(g, axes), test)] = NOT_EXCITED if g in quiet else f"{100 * err:.1f} %"
    return out


def validation_figures(signals, tree, noise: dict[str, float] | None = None, chassis: Sequence[str] = (),
                       split: Split | None = None, axes: Mapping[str, Any] | None = None) -> list[tuple[str, bytes]]:
    """One figure per equation section (the car: chassis, suspensions, tires; a robot: its joints), the direct
    and the cross validation side by side: the paper's Figures 4 and 7, 5 and 8, 6 in one each. A car's chassis
    equations in ISO 8855 axes (axes: `tables.equation_axes`); noise: the identification's residual RMS per group
    (the run's `residual_rms`), under which a panel says "not excited" instead of a relative error of noise over noise.
    chassis, split: a car's chassis groups and its split of the groups into figures (`_car_equations`); without a
    split, one figure of every joint."""
    axes = axes or {}
    corners = panel_corners(signals, noise or {}, axes)
    tests = [(kind, test, per) for kind, by_test in signals.items() for test, per in by_test.items()]
    groups = list(dict.fromkeys(g for _, _, per in tests for g in per))
    # each test's time axis from all its equations, the same in every figure
    spans = {test: (min(float(v[0][0]) for v in per.values() if len(v[0])),
                    max(float(v[0][-1]) for v in per.values() if len(v[0])))
             for _, test, per in tests if any(len(v[0]) for v in per.values())}
    figs = []
    data = {(axis_label(g, axes), test): (per[g][0], *to_iso(g, axes, *per[g][1:])) for _, test, per in tests
            for g in per}
    for section, gs, paper in (split(groups) if split is not None else [("joints", groups, "")]):
        caption = (f"Validation, {section}: measured Y and model W X per equation and test, direct (identification "
                   "tests) then cross (tests not used for the estimate)"
                   + (f"; the paper's Figures {paper}" if paper else ""))
        figs.append((caption, validation_grid(f"{section}: measured and predicted forces",
                                              [(axis_label(g, axes), group_unit(g, tree, chassis)) for g in gs],
                                              [t for _, t, _ in tests], data, kinds=[k for k, _, _ in tests],
                                              spans=spans, corners=corners)))
    return figs


def validation_table(run) -> Table | None:
    errors = {k: v for k, v in run.errors.items() if v}
    if not errors:
        return None
    kinds = list(errors)
    marked = {k: set(run.not_excited.get(k, ())) for k in kinds}
    groups = list(dict.fromkeys(g for k in kinds for g in errors[k]))
    chassis = _car_equations(run)[0]
    axes = _equation_axes(run)
    rows = []
    for g in groups:
        axis = axes.get(g)
        row = [Cell(axis_label(g, axes), title=f"the paper's {axis.paper}" if axis else "", cls="t"),
               Cell(group_unit(g, run.model.tree, chassis), cls="t")]
        for k in kinds:
            e = errors[k].get(g)
            text = "" if e is None else f"{100 * e:.2f} %" + (" *" if g in marked[k] else "")
            row.append(Cell(text, None if e is None else 100 * e))
        rows.append(row)
    heads = [k.replace("NRMSE", "RMS(Y − W X)/std(Y)") if k.endswith("NRMSE") else f"{k} ‖Y − W X‖/‖Y‖"
             for k in kinds]
    return Table(["equation", "force unit", *heads], rows,
                 caption="Relative error per equation group" + (" and NRMSE (1: no better than the mean)"
                                                                if any(k.endswith("NRMSE") for k in kinds) else ""),
                 cls="valid")


# ------------------------------------------------------------------ reference, regrouping, consistency, provenance


def reference_table(run) -> Table:
    r = run.result
    names = list(r.names)
    cov = r.full_covariance
    rows = []
    for m in run.reference:
        pub, pub_rel = m.row.published(r.method)
        ours = m.value(names, r.values)
        sd = m.std(names, cov)
        gap = abs(ours - pub) / (abs(pub) * pub_rel / 100) if pub and pub_rel else float("nan")
        how = " + ".join(f"{w:g}·{n}" if w != 1 else n for n, w in m.weights.items())
        vs, ss = round_to_uncertainty(ours, sd)
        rows.append([Cell(m.label, cls="t"), Cell(vs, ours), Cell(ss, sd),
                     _num(100 * sd / abs(ours) if ours else float("nan"), 2), Cell(f"{pub:.6g}", pub),
                     _num(pub_rel, 2), _num(gap, 2), Cell(how, cls="t")])
    return Table(["published", "ours", "σ", "ours %σ", "published value", "published %σ", "gap / σ published",
                  "as"], rows, caption="Our estimate of each published quantity", cls="ref", pin=("ours",))


def offsets_section(offsets: dict) -> Section:
    """The sensor zero offsets a car's σ total carries (`pipeline.car.SensorOffsets.to_dict`): which channels, how
    large, and whether the vehicle's sensor suite or the config gave them."""
    source = offsets["source"]
    rows = [[Cell(c["channel"], cls="t"), Cell(f"{c['value']:g}", c["value"]), Cell(c["unit"], cls="t nowrap")]
            for c in offsets["channels"]]
    if source == "vehicle":
        text = (f"σ total carries the zero offsets of the vehicle's sensor suite ({offsets['vehicle']}): each "
                "channel's constant zero error, 1 σ, taken independent between tests (each test zeroed anew) and "
                f"propagated to first order on up to {offsets['segments']} segment(s) per identification test. The "
                "config's [uncertainty] offsets = { channel = value } replaces them; offsets = \"none\" turns them "
                "off.")
    elif source == "config":
        text = ("σ total carries the zero offsets the config declares ([uncertainty] offsets; they replace the "
                "vehicle's sensor suite's), 1 σ each, taken independent between tests and propagated to first "
                f"order on up to {offsets['segments']} segment(s) per identification test.")
    else:
        text = ("None: the config's [uncertainty] turns the sensors' zero offsets off, so σ total is the "
                "statistical σ alone (from the noise) and ignores them.")
    if source == "vehicle" and not rows:
        text = (f"None: the vehicle's sensor suite ({offsets['vehicle']}) declares no zero offsets, so σ total is "
                "the statistical σ alone.")
    tables = [Table(["channel", "1 σ", "unit"], rows, caption="Zero offsets declared (the suite's unit of each "
                    "channel)", cls="offsets")] if rows else []
    if offsets.get("estimated"):
        text = text.replace("propagated to first order on up to", "estimated with the parameters from each test's "
                            "own data (their declared σ as the prior; [uncertainty] estimate = false propagates "
                            "them instead), evaluated on every segment, not on up to").replace(
                            "propagated to first order on", "estimated from the data on")
        text += (" σ total adds what the data leave of each offset's effect. The table below gives the offsets "
                 "read largest against their declared σ; results.json's sensor_offsets.estimates has all of them.")
        read = sorted(offsets["estimates"], key=lambda e: -abs(e["value"] / max(_declared(offsets, e), 1e-300)))
        tables.append(Table(["test", "channel", "read", "σ", "unit", "declared σ"], [
            [Cell(e["test"], cls="t"), Cell(e["channel"], cls="t"), Cell(f"{e['value']:+.3g}", e["value"]),
             Cell(f"{e['std']:.2g}", e["std"]), Cell(e["unit"], cls="t nowrap"),
             Cell(f"{_declared(offsets, e):g}", _declared(offsets, e))] for e in read[:12]],
            caption="Zero offsets the data read (largest against the declared σ)", cls="offsets"))
    return Section("Sensor zero offsets in σ total", text, tables=tables, anchor="offsets")


def _declared(offsets: dict, estimate: dict) -> float:
    """The declared 1 σ of an estimated offset's channel."""
    return next(c["value"] for c in offsets["channels"] if c["channel"] == estimate["channel"])


def which_test_rows(run) -> tuple[list[str], list[tuple[str, float, list[float]]]]:
    """The identification tests and, per parameter, (label, σ total %, [σ total % without each test]), in % of the
    parameter's engineering scale (the flag's: `IdentificationResult.scale`); inf where the others cannot tell."""
    r = run.result
    tests = list(run.without_test)
    std, scale = dict(zip(r.names, r.std_total, strict=True)), dict(zip(r.names, r.scale, strict=True))
    def pct(s: float, n: str) -> float:
        return 100 * s / abs(scale[n]) if scale[n] else float("nan")

    rows = [(r.labels.get(n, n), pct(std[n], n), [pct(run.without_test[t][n], n) for t in tests])
            for n in r.estimated_names]
    return tests, rows


def which_test_section(run) -> Section | None:
    """Which test identifies what (issue 29): each parameter's σ total with all the identification tests and
    without each one, from the partial sums the identification already reduced (no new pass over the data)."""
    if not getattr(run, "without_test", None):
        return None
    tests, rows = which_test_rows(run)

    def cell(v: float) -> Cell:
        return Cell("—" if not np.isfinite(v) else f"{v:.2f}", v if np.isfinite(v) else 1e300)

    table = Table(["parameter", "all tests", *[f"without {t}" for t in tests]],
                  [[Cell(label, cls="t"), cell(a), *map(cell, w)] for label, a, w in rows],
                  caption="σ total (noise and zero offsets, WLS) in % of each parameter's scale; — : the other tests "
                          "cannot identify every parameter", pin=("parameter",))
    text = ("What each identification test buys: every parameter's σ total with all of them, and without each one "
            "(its rows and its zeroing's offsets left out, the weights re-estimated). A column far above \"all "
            "tests\" marks what that test identifies; one below it, a test whose zeroing costs more than its rows "
            "bring. `dynid plan` predicts the same table before the car goes to the track.")
    return Section("Which test identifies what", text, tables=[table], anchor="which-test")


def regrouping_text(run) -> str:
    base = run.base
    regrouped = [(n, e) for n, e in zip(base.names, base.expressions, strict=True) if e.replace(" ", "") != n]
    known = sorted(run.model.tree.known)
    tail = (f" Fixed as known (moved to the right-hand side, not identified): {', '.join(known)}."
            if known else "")
    if not regrouped:
        return (f"The {len(base.names)} identified parameters form a base set as they stand: none is regrouped, "
                "each base parameter is the standard parameter of its name." + tail)
    return (f"{len(regrouped)} of the {len(base.names)} base parameters regroup standard ones (the standard "
            f"parameters {', '.join(base.regrouped)} are not identifiable alone and appear only inside these "
            "sums); the others are the standard parameters of their names." + tail)


def regrouping_table(run) -> Table | None:
    base = run.base
    rows = [[Cell(n, cls="t"), Cell(e, cls="t")] for n, e in zip(base.names, base.expressions, strict=True)
            if e.replace(" ", "") != n]
    return Table(["base parameter", "= standard parameters"], rows, cls="regroup") if rows else None


_CONSISTENCY = "Physical consistency"


def split_notes(notes: str) -> tuple[list[str], list[str]]:
    """The run's notes as (physical-consistency lines, the other paragraphs): the verdict gets its own section.
    A verdict is a line starting "Physical consistency" and the indented lines after it (its violations)."""
    verdict, other = [], []
    inside = False
    for line in notes.split("\n"):
        if not line.strip():
            inside = False
            continue
        if line.startswith(_CONSISTENCY):
            inside = True
        elif not line.startswith(" "):
            inside = False
        (verdict if inside else other).append(line.strip())
    return verdict, other


def consistency_section(run) -> Section:
    verdict, _ = split_notes(run.notes)
    text = "\n".join(verdict)
    if getattr(run, "consistency", None):  # a robot's verdict (and its wls-pc fit), as the terminal prints it
        text = robot_verdict(run.consistency)
    if not text:
        text = ("Not checked for this model: its base parameters regroup inertial parameters, so no rigid body "
                "can be rebuilt from them alone.")
    bad = "NOT physically realisable" in text
    good = "physically realisable" in text and not bad
    word = ("Realisable: rigid bodies with these masses and inertias exist (positive mass, inertia about the "
            "centre of mass positive definite, triangle inequalities): the estimate can drive a simulator."
            if good else
            "NOT realisable: no rigid body has these values; do not put them in a simulator as they are: look at "
            "the flagged parameters and the excitation, or identify with a physically-constrained method."
            if bad else "")
    cls = "verdict-ok" if good else "verdict-bad" if bad else ""
    html = f'<p class="{cls}">{esc(word)}</p>' if word else ""
    return Section("Physical consistency", text, html=html, anchor="consistency")


def delays_section(run) -> Section | None:
    """A car's channel delays relative to the wheel force transducers, declared against estimated
    (`pipeline.delays`), and the mismatch warnings."""
    check = run.delays
    if check is None:
        return None
    rows = []
    for g in check.groups:
        verdict = ("MISMATCH" if g.mismatch(check.sample) else "ok") if g.determined else "not determined"
        est = [Cell(f"{1e3 * g.estimated:+.2f}", 1e3 * g.estimated), Cell(f"{1e3 * g.std:.2f}", 1e3 * g.std),
               Cell(f"{1e3 * g.residual:+.2f}", 1e3 * g.residual)] if g.determined else ["", "", ""]
        rows.append([Cell(g.group, cls="t"), Cell(g.label, cls="t"),
                     Cell(f"{1e3 * g.declared:+.2f}", 1e3 * g.declared), *est,
                     Cell(verdict, cls="t flag-uncertain" if verdict == "MISMATCH" else "t")])
    table = Table(["group", "channels", "declared, ms", "estimated, ms", "σ, ms", "difference, ms", "verdict"], rows,
                  caption="Delay relative to the wheel force transducers", sortable=False)
    off = "" if check.compensated else "; here compensate_delays = false: none"
    text = (f"How late each channel group is against the wheel force transducers: as declared (the vehicle file's "
            f"[sensors.dynamics], compensated before the equations{off}), and as the chassis and suspension "
            f"equations' residual says (the delay that minimises it jointly with the parameters, σ from its curvature; "
            f"{check.segments} segment(s), {check.steps} step(s)). One "
            f"sample is {1e3 * check.sample:.2f} ms; a difference above a sample and 3 σ is a mismatch: the estimates "
            "the misalignment moves carry that shift in their σ total (source \"delay mismatch\").")
    warnings = check.warnings()
    if warnings:
        text += "\n\n" + "\n\n".join(f"WARNING: {w}" for w in warnings)
    return Section("Channel delays", text, tables=[table], anchor="delays")


def input_files(cfg) -> list[tuple[str, Path]]:
    """(role, path) of every file the run read: the config, the model or vehicle file, the tests' files and
    truth sidecars, the reference."""
    if cfg is None:
        return []
    out = [("config", Path(cfg.path))]
    for what in ("model", "vehicle"):
        p = getattr(cfg, what, None)
        if isinstance(p, Path) or (isinstance(p, str) and p.endswith(".toml")):
            out.append((what, Path(p)))
    if cfg.kind == "car" and not isinstance(cfg.vehicle, Path):  # a shipped vehicle: its file, as installed
        # start-up: a car's alone (the vehicle package, scipy.interpolate and optimize: 18 MB not on a robot's path)
        from ..vehicle.description import vehicle_path

        out.append(("vehicle (shipped)", vehicle_path(cfg.vehicle or DEMO_VEHICLE)))
    for t in cfg.tests:
        for q, p in t.files.items():
            out.append((f"{t.name}: {q}", Path(p)))
        if t.truth is not None:
            out.append((f"{t.name}: truth", Path(t.truth)))
    if cfg.reference and cfg.reference.get("file"):
        out.append(("reference", Path(cfg.reference["file"])))
    return out


def provenance(run) -> dict[str, Any]:
    files = []
    # hashed where read, named where they will be: a demo reads its files from a staging folder renamed at the end
    for role, p in input_files(run.config):
        files.append({"role": role, "path": str(final_path(p)), "sha256": file_sha256(p) if p.is_file() else None})
    return {"dynid": __version__, "python": platform.python_version(), "numpy": np.__version__,
            "written_utc": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"), "files": files}


def provenance_section(run, prov: dict[str, Any]) -> Section:
    rows = [[Cell(f["role"], cls="t"), Cell(f["path"], cls="t"), Cell(f["sha256"] or "(missing)", cls="t")]
            for f in prov["files"]]
    html = ""
    cfg = run.config
    if cfg is not None and Path(cfg.path).is_file():
        html = (f"<details><summary>the config, {esc(Path(cfg.path).name)}</summary>"
                f'<pre class="config">{esc(Path(cfg.path).read_text(errors="replace"))}</pre></details>')
    text = (f"dynid {prov['dynid']}, Python {prov['python']}, NumPy {prov['numpy']}; written "
            f"{prov['written_utc']}.")
    tables = [Table(["input", "path", "SHA-256"], rows, sortable=False, cls="files")] if rows else []
    return Section("Traceability", text, html=html, tables=tables, anchor="trace")


# ------------------------------------------------------------------ the whole


def parameters_csv(run, sections) -> str:
    r = run.result
    tree = run.model.tree
    where = {n: t for t, names in sections for n in names}
    total, rel_total, uflags = r.std_total, r.rel_std_total_percent, r.uncertainty_flags
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    what = meanings(run)
    w.writerow(["name", "label", "corner", "quantity", "table", "unit", "a_priori", "truth", "value", "std",
                "std_total", "rel_std_percent", "rel_std_total_percent", "ci95_low", "ci95_high", "flag",
                "paper_rule"])

    def g(x):
        return "" if x is None or not np.isfinite(x) else f"{float(x):.10g}"

    for i, n in enumerate(r.names):
        lo, hi = interval95(float(r.values[i]), float(total[i]))
        corner, quantity = what.get(n, ("", ""))
        w.writerow([n, r.labels.get(n, n), corner, quantity, where.get(n, ""), parameter_unit(n, tree),
                    g(r.a_priori.get(n)),
                    g(r.truth.get(n)) if r.truth else "", g(r.values[i]), g(r.std[i]), g(total[i]),
                    g(r.rel_std_percent[i]), g(rel_total[i]), g(lo), g(hi), uflags[i], r.flags[i]])
    return buf.getvalue()


def build_report(run, title: str) -> Report:
    """Everything but the writing: the page, the CSV files and figures (file name -> content), the additions
    to results.json."""
    r, tree = run.result, run.model.tree
    is_car = _is_car(run)
    sections_list = _sections(run)
    files: dict[str, str | bytes] = {}
    data: dict[str, Any] = {}
    per: dict[str, dict[str, Any]] = {}
    total = r.std_total
    what = meanings(run)
    for i, n in enumerate(r.names):
        lo, hi = interval95(float(r.values[i]), float(total[i]))
        per[n] = {"unit": parameter_unit(n, tree), "interval_95": [lo, hi]}
        if n in what:
            per[n].update(zip(("corner", "quantity"), what[n], strict=True))
    res = r.residual
    n_known = len(r.names) - len(r.estimated_names)
    summary = (f"{r.method}: {len(r.estimated_names)} parameters estimated from {res.n_rows} rows"
               f"{f', {n_known} known' if n_known else ''}; "
               f"condition number {r.condition_number:.3g}; ‖Y − W X‖/‖Y‖ = {100 * res.relative_residual:.3g} %; "
               f"{len(r.uncertain)} flagged uncertain; σ from the {r.cov_type} covariance.")
    out_sections: list[Section] = []
    figs_written: list[tuple[str, str, bytes]] = []  # (file, caption, png)
    signals = validation_signals(run)
    chassis, split = _car_equations(run)
    axes = _equation_axes(run)
    # the validation figures (about half the report's drawing) in a forked process while this one draws the others
    # and builds the tables; pyplot imported first, so that the child has it
    preload()
    vfigs_apart = Apart(lambda: validation_figures(signals, tree, run.residual_rms, chassis, split, axes))
    if is_car:
        quantities, kind, vehicle, values = car_engineering(run)
        out_sections.append(engineering_section(run, quantities, kind, vehicle, values))
        cog = cog_figure(run, quantities, vehicle, values)
        figs_written.append(("figure_centre_of_gravity.png", "The centres of gravity on the car (side and top "
                             "views from the vehicle geometry) and their 95 % uncertainty ellipses", cog))
        out_sections[-1] = Section(out_sections[-1].heading, out_sections[-1].text,
                                   figures=[figs_written[-1][1:]], tables=out_sections[-1].tables,
                                   anchor="engineering")
        data["engineering"] = {"uncertainty": kind, "quantities": [
            {"key": q.key, "group": q.group, "label": q.label, "unit": q.unit, "value": q.value, "std": q.std}
            for q in quantities]}
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["key", "group", "quantity", "unit", "value", "std", "ci95_low", "ci95_high", "note"])
        for q in quantities:
            lo, hi = interval95(q.value, q.std)
            w.writerow([q.key, q.group, q.label, q.unit, f"{q.value:.10g}", f"{q.std:.6g}", f"{lo:.10g}",
                        f"{hi:.10g}", q.note])
        files["engineering.csv"] = buf.getvalue()
        dampers = damper_section(run)
        if dampers is not None:
            figs_written.append(("figure_dampers.png", "The dampers' force against their clearance rate: the "
                                 "estimate, its 95 % band, the truth where known, the knees", dampers[1]))
            out_sections.append(Section(dampers[0].heading, dampers[0].text, figures=[figs_written[-1][1:]],
                                        tables=dampers[0].tables, anchor=dampers[0].anchor))
    if getattr(run, "tires", None) is not None:  # the tire characteristics (vehicle.tire_curves)
        # start-up: a car's alone (the vehicle package, scipy.interpolate and optimize: 18 MB not on a robot's path)
        from .tires import tire_section

        section, tire_files = tire_section(run.tires)
        out_sections.append(section)
        files.update(tire_files)
    pfig = parameter_figure([(t, rows) for t, rows in _parameter_rows(run)])
    figs_written.append(("figure_parameters.png", "Each estimate's 95 % interval with the a priori and the "
                         "truth, as a difference from the estimate in % of the parameter's scale", pfig))
    out_sections.append(Section("Estimated parameters", _frame_text(run), tables=parameter_tables(run),
                                html=flag_legend(run) + paper_rule_details(run), figures=[figs_written[-1][1:]],
                                anchor="parameters"))
    if run.offsets is not None:
        out_sections.append(offsets_section(run.offsets))
    which = which_test_section(run)
    if which is not None:
        out_sections.append(which)
    if run.reference:
        out_sections.append(Section("Comparison with the published identification", tables=[reference_table(run)],
                                    anchor="reference"))
    out_sections.append(consistency_section(run))
    vt = validation_table(run)
    vfigs = vfigs_apart.result()
    for k, (caption, png) in enumerate(vfigs, start=1):
        figs_written.append((f"figure_validation{k}.png", caption, png))
    vtext = ("Y is the measured side of each equation (forces from the sensors), W X the model's prediction with "
             "the estimate. Direct: the identification tests; cross: tests the estimate never saw.")
    rule = (f"RMS of its Y below {EXCITED_FACTOR:g} × the identification's residual RMS in that equation: its "
            "relative error would compare noise with noise")
    if any(run.not_excited.values()):
        vtext += f"\n* the cross-validation tests barely move this equation ({rule})."
    vtext += f"\nA plot's panel says \"{NOT_EXCITED}\" instead of its relative error where its test barely moves its "
    vtext += f"equation ({rule})."
    if is_car:
        from ..vehicle.axes import ISO_TEXT  # start-up: a car's alone (the vehicle package)

        vtext += ("\nThe plots show the first segment of each test (validation.csv has the same rows, in the same "
                  "signs, with the paper's equation name beside the ISO one).\n\n" + ISO_TEXT)
    out_sections.append(Section("Validation", vtext, tables=[vt] if vt else [], figures=vfigs, anchor="validation"))
    ds = delays_section(run)
    if ds is not None:
        out_sections.append(ds)
        data["delays"] = run.delays.to_dict()
    if getattr(run, "without_test", None):  # σ total without each identification test (which_test_section)
        data["without_test"] = run.without_test
    _, other = split_notes(run.notes)
    if other:
        out_sections.append(Section("Notes", "\n\n".join(other), anchor="notes"))
    rt = regrouping_table(run)
    out_sections.append(Section("Regrouping relations", regrouping_text(run), tables=[rt] if rt else [],
                                anchor="regrouping"))
    prov = provenance(run)
    out_sections.append(provenance_section(run, prov))
    data["provenance"] = prov
    files["parameters.csv"] = parameters_csv(run, sections_list)
    files["validation.csv"] = validation_csv(signals, tree, chassis, _equation_axes(run))
    for name, _, png in figs_written:
        files[name] = png
    page = render_html(title, out_sections, subtitle=summary)
    return Report(page, files, data, per)


__all__ = ["Report", "build_report", "group_unit", "interval95", "parameter_tables", "split_notes",
           "validation_signals"]
