"""`dynid identify`: a config in, tables, results.json, figures and an HTML report out.

Data flow (one direction): config -> files -> joint trajectories and forces -> conditioned,
decimated (W, Y) per equation group -> OLS or weighted LS -> direct and cross validation ->
report. Outputs are written atomically to the output folder.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..atomic import write_atomic
from ..dynamics import BaseParameters, Model
from ..estimation import IdentificationResult, ols, relative_errors, wls
from ..model import ModelError
from ..report import Section, parameter_table, render_html, residual_histograms, validation_figure, validation_table
from .config import ConfigError, IdentifyConfig, TestSpec
from .reference import Match, match_reference, read_reference
from .robot import GroupedSystem, JointTest, joint_system

Progress = Callable[[str], None]


@dataclass
class IdentificationRun:
    """Everything an identification produced: the result, the systems used, validation errors, reference."""

    model: Model
    base: BaseParameters
    result: IdentificationResult
    identify: GroupedSystem
    validate: dict[str, GroupedSystem] = field(default_factory=dict)
    errors: dict[str, dict[str, float]] = field(default_factory=dict)
    reference: list[Match] = field(default_factory=list)

    def reference_values(self) -> dict[str, tuple[float, float]]:
        """Published values (value, %σ) keyed by our base-parameter name, same method as ours."""
        use_wls = self.result.method == "WLS"
        out = {}
        for m in self.reference:
            if len(m.weights) == 1 and next(iter(m.weights)) == m.label and m.weights[m.label] == 1.0:
                row = m.row
                out[m.label] = (row.wls, row.wls_rel_std) if use_wls else (row.ols, row.ols_rel_std)
        return out


def load_joint_test(cfg: IdentifyConfig, spec: TestSpec, n: int) -> JointTest:
    """Joint positions and forces of one test from its files, through the channel map and transmission."""
    from ..io import read_recording, to_si

    arrays = {}
    fs = spec.fs
    for quantity in ("q", "tau"):
        if quantity not in spec.files:
            raise ConfigError(f"{cfg.path}: test {spec.name!r} needs a file for {quantity!r} in files = {{...}}")
        if quantity not in cfg.channels:
            raise ConfigError(f"{cfg.path}: [channels] has no {quantity!r} = {{ channels = [...], unit = ... }}")
        ch = cfg.channels[quantity]
        rec = read_recording(spec.files[quantity], fs=fs)
        cols = []
        for name in ch.channels:
            c = rec.channel(name)
            values, _ = to_si(c.values, ch.unit or c.unit, channel=name)
            cols.append(values)
        arrays[quantity] = np.stack(cols, axis=1)
        if fs is None:
            t = rec.channel(ch.channels[0]).time
            fs = 1.0 / float(np.median(np.diff(t)))
    q, tau = arrays["q"], arrays["tau"]
    if "q" in cfg.transmission:
        q = q @ cfg.transmission["q"].T
    if "q_offset" in cfg.transmission:
        q = q + cfg.transmission["q_offset"]
    if "tau" in cfg.transmission:
        tau = tau @ cfg.transmission["tau"].T
    for name, a in (("q", q), ("tau", tau)):
        if a.shape[1] != n:
            raise ConfigError(f"{cfg.path}: {name} has {a.shape[1]} columns after the transmission; the model has {n}")
    return JointTest(spec.name, float(fs), q, tau)


def identify(cfg: IdentifyConfig, progress: Progress | None = None) -> IdentificationRun:
    say = progress or (lambda _msg: None)
    from .. import load_model

    model = load_model(cfg.model)
    base = model.base_parameters()
    names = list(base.names)
    bad = [k for k in cfg.known if k not in names]
    if bad:
        raise ConfigError(f"{cfg.path}: [identification] known names {bad} are not base parameters of "
                          f"{model.name!r}; base parameters: {', '.join(names)}")
    systems: dict[str, GroupedSystem] = {}
    for spec in cfg.tests:
        say(f"reading and conditioning {spec.name!r}")
        systems[spec.name] = joint_system(model, load_joint_test(cfg, spec, model.n), base, cfg.conditioning)
    ident = GroupedSystem.stack([systems[t.name] for t in cfg.tests if t.role == "identify"])
    a_priori = dict(zip(names, base.values(model.parameters), strict=True))
    say(f"estimating {len(names)} base parameters from {ident.W.shape[0]} rows ({cfg.method.upper()})")
    kw = dict(a_priori=a_priori, known=cfg.known or None, poor_factor=cfg.poor_factor)
    result = (wls(ident.W, ident.Y, ident.groups, names, **kw) if cfg.method == "wls"
              else ols(ident.W, ident.Y, names, **kw))
    run = IdentificationRun(model, base, result, ident)
    run.errors["direct"] = relative_errors(ident.W, ident.Y, result.values, ident.groups)
    cross = [t for t in cfg.tests if t.role == "validate"]
    if cross:
        val = GroupedSystem.stack([systems[t.name] for t in cross])
        run.validate = {t.name: systems[t.name] for t in cross}
        run.errors["cross"] = relative_errors(val.W, val.Y, result.values, val.groups)
    result.validation.update(run.errors)
    if cfg.reference:
        rows = read_reference(cfg.reference["file"])
        run.reference, unmatched = match_reference(rows, base, cfg.reference.get("names", {}),
                                                   cfg.reference.get("combinations", {}))
        if unmatched:
            say(f"{len(unmatched)} published rows match none of our base parameters: "
                + "; ".join(r.expression for r in unmatched[:3]))
    return run


def write_outputs(run: IdentificationRun, out: Path, title: str, progress: Progress | None = None) -> list[Path]:
    """results.json, the figures and report.html in `out`, each written atomically."""
    say = progress or (lambda _msg: None)
    out.mkdir(parents=True, exist_ok=True)
    r = run.result
    tables = parameter_table(r, reference=run.reference_values() or None)
    say("drawing figures")
    figs = []
    for kind, sys in [("direct", run.identify)] + [("cross", s) for s in run.validate.values()]:
        WX = sys.W @ r.values
        figs.append((f"{kind} validation: Y and W X per equation", validation_figure(sys.Y, WX, sys.groups, kind)))
    figs.append(("residuals of the identification tests",
                 residual_histograms(run.identify.Y, run.identify.W @ r.values, run.identify.groups, "residuals")))
    data = r.to_dict()
    data["base_parameters"] = dict(zip(run.base.names, run.base.expressions, strict=True))
    if run.reference:
        data["reference"] = [{"published": m.row.expression, "label": m.label, "published_value": m.row.wls
                              if r.method == "WLS" else m.row.ols, "ours": m.value(list(r.names), r.values)}
                             for m in run.reference]
    written = [write_atomic(out / "results.json", json.dumps(data, indent=2, allow_nan=False, default=_json))]
    for i, (_, png) in enumerate(figs, start=1):
        written.append(write_atomic(out / f"figure{i}.png", png))
    sections = [Section("Estimated base parameters", tables),
                Section("Regrouping relations", str(run.base)),
                Section("Validation: relative error ||Y - W X|| / ||Y||", validation_table(run.errors), figs)]
    written.append(write_atomic(out / "report.html", render_html(title, sections)))
    return written


def _json(o: object) -> object:
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"cannot write {type(o).__name__} to JSON")


__all__ = ["IdentificationRun", "ModelError", "identify", "load_joint_test", "write_outputs"]
