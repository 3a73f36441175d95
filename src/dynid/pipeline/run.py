"""`dynid identify`: a config in, tables, results.json, figures and an HTML report out.

Data flow (one direction): config -> files -> joint trajectories and forces -> conditioned,
decimated (W, Y) per equation group -> OLS or weighted LS -> direct and cross validation ->
report. Outputs are written atomically to the output folder.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from ..atomic import final_text, write_atomic
from ..dynamics import BaseParameters, Model
from ..estimation import (
    IdentificationError,
    IdentificationResult,
    StreamingLS,
    fit_note,
    misfit_parameters,
    model_fits,
    not_excited,
    propagate,
)
from ..estimation.method import Method
from ..estimation.offsets import OffsetEstimate
from ..estimation.physical import (
    PRIOR_SPREAD,
    ConsistencyStructure,
    PhysicalFit,
    feasible_standard,
    plausible_standard,
    wls_pc_streamed,
)
from ..estimation.shifts import estimate_shifts
from ..io.rosbag_format import is_bag
from ..model import ModelError
from ..model.consistency import NONNEGATIVE_TERMS, Violation, check_base_singletons, check_joint_terms, check_physical
from ..model.tree import FIXED, INERTIAL
from ..report import parameter_table
from ..report.build import build_report, car_engineering
from ..report.tables import engineering_block
from ..shipped import CAR_TEMPLATE, DEMO_VEHICLE
from ..signals import border_samples
from .config import ConfigError, IdentifyConfig, TestSpec, load_config
from .health import check_car_tests, check_robot_joints, check_robot_test, health_note
from .heap import trim_heap
from .reduce import (
    CarJob,
    Partial,
    RobotJob,
    car_setup,
    combine,
    reduce_car_segment,
    reduce_robot_chunk,
    robot_setup,
)
from .reference import Match, match_reference, read_reference
from .robot import (
    GroupedSystem,
    JointTest,
    _border,
    chunk_pad,
    in_joint_order,
    link_box,
    link_length,
    robot_chunks,
    robot_scales,
)
from .schedulers import LocalScheduler, Scheduler, scheduler_for, tree_fold
from .sources import (
    clock_window,
    plan_car_test,
    plan_robot_test,
    read_robot_window,
    read_segment,
    segment_edges,
    segment_window,
    transmitted,
)

Progress = Callable[[str], None]
# validation tests whose rows a run keeps for the report's figures and validation.csv (the first, in the config's
# order); the cross-validation errors are over every one, from the streamed factors: memory does not grow with the
# number of validation tests (200 once took 1.2 GB)
SHOWN_VALIDATION = 8


@dataclass
class IdentificationRun:
    """Everything an identification produced: the result, validation errors, reference, and rows to plot: identify
    and validate hold the identification and validation tests' rows kept for the report (a car's first segment of
    each test, a robot's first chunks up to `PLOT_BYTES`); the estimate and the errors come from every segment's
    factors."""

    model: Model
    base: BaseParameters
    result: IdentificationResult
    identify: GroupedSystem
    validate: dict[str, GroupedSystem] = field(default_factory=dict)
    errors: dict[str, dict[str, float]] = field(default_factory=dict)
    reference: list[Match] = field(default_factory=list)
    sections: list[tuple[str, list[str]]] | None = None  # how the parameter tables are grouped
    notes: str = ""  # printed under the tables (e.g. the physical-consistency verdict)
    not_excited: dict[str, list[str]] = field(default_factory=dict)  # kind -> groups whose Y is mostly noise
    # the identification's residual RMS per equation group: the noise floor of `estimation.not_excited`
    residual_rms: dict[str, float] = field(default_factory=dict)
    systems: dict[str, GroupedSystem] = field(default_factory=dict)  # test name -> its rows (the report's plots)
    config: IdentifyConfig | None = None  # what was run (the report's traceability)
    vehicle: Any = None  # a car's vehicle description (its geometry for the report's engineering figures)
    consistency: dict | None = None  # a robot's physical-consistency verdict (robot_consistency), for results.json
    offsets: dict | None = None  # a car's sensor zero offsets (car.SensorOffsets.to_dict), for results.json
    delays: Any = None  # a car's channel delays estimated against the declared ones (pipeline.delays.DelayCheck)
    health: list[dict] | None = None  # a car's data health findings that did not stop the run (pipeline.health)
    tires: Any = None  # a car's tire characteristics (vehicle.tire_curves.TireCurves), when fitted
    # a car's "which test identifies what": {test: {parameter: σ total without that test}} (without_each_test)
    without_test: dict[str, dict[str, float]] = field(default_factory=dict)

    def summary(self) -> str:
        """The parameter tables (a car's: each parameter's corner, quantity and unit), a car's ride-and-handling
        sheet, then the notes."""
        meanings = None
        if self.vehicle is not None:
            # start-up: a car's alone (the vehicle package, scipy.interpolate and optimize: 18 MB)
            from ..vehicle.template import meaning

            found = {n: meaning(n) for n in self.result.names}
            meanings = {n: (m.text(), m.unit) for n, m in found.items() if m is not None}
        text = parameter_table(self.result, self.sections, meanings=meanings)
        if self.vehicle is not None:
            quantities, kind, _, _ = car_engineering(self)
            text += "\n\n" + engineering_block(quantities, kind)
        return f"{text}\n\n{self.notes}" if self.notes else text

    def reference_table(self) -> str:
        """Our estimate of each published quantity beside the published value (same method), and the gap in σ."""
        r = self.result
        names = list(r.names)
        cov = r.full_covariance
        lines = [f"{'published':>10} {'ours':>12} {'ours %σ':>8} {'published':>12} {'pub. %σ':>8} {'gap/σ_pub':>9}  as"]
        for m in self.reference:
            pub, pub_rel = m.row.published(r.method)
            ours = m.value(names, r.values)
            ours_rel = 100 * m.std(names, cov) / abs(ours) if ours else float("nan")
            gap = abs(ours - pub) / (abs(pub) * pub_rel / 100) if pub and pub_rel else float("nan")
            how = " + ".join(f"{w:g}*{n}" if w != 1 else n for n, w in m.weights.items())
            lines.append(f"{m.label:>10} {ours:>12.6g} {ours_rel:>8.2f} {pub:>12.6g} {pub_rel:>8.2f} {gap:>9.2f}"
                         f"  {how}")
        return "\n".join(lines)


def load_joint_test(cfg: IdentifyConfig, spec: TestSpec, n: int, progress: Progress | None = None) -> JointTest:
    """Joint positions and forces of one whole test from its files, on one uniform clock (`sources.plan_robot_test`:
    time columns, repeated rows, jitter, gaps, two files' clocks, the start..end window), through the channel map
    and transmission. The identification reads a chunk at a time instead; this is for looking at a test."""
    plan = plan_robot_test(cfg, _checked_robot_test(cfg, spec), progress)
    arrays = read_robot_window(plan, 0, plan.samples)
    effort = arrays[plan.effort]
    if plan.effort == "current":  # the motor torques by the config's gains (an identified gain's a priori value)
        effort = effort * np.array(cfg.drive.gains)
    q, tau = transmitted(cfg, arrays["q"], effort, n)
    return JointTest(spec.name, float(plan.fs), q, tau)


def _checked_robot_test(cfg: IdentifyConfig, spec: TestSpec) -> TestSpec:
    for quantity in ("q", cfg.effort):
        if quantity not in spec.files:
            raise ConfigError(f"{cfg.path}: test {spec.name!r} needs a file for {quantity!r} in files = {{...}}")
        if quantity not in cfg.channels and not is_bag(spec.files[quantity]):  # a bag's: its joints' names
            raise ConfigError(f"{cfg.path}: [channels] has no {quantity!r} = {{ channels = [...], unit = ... }}")
    return spec


PLOT_BYTES = 8 * 2**20
"""Decimated rows of a robot test kept for the report's plots and validation.csv: the first chunks' up to this
size (about 6 minutes of the Panda arm's 7 joints and 43 base parameters at 1 kHz decimated by 100; the whole
test when shorter). The estimate and the validation errors come from the factors of every chunk. Held twice
while the fold stacks them: 32 MiB was ~90 MB of a 1 h log's peak."""


def chunk_scheduler(scheduler: Scheduler) -> tuple[Scheduler, int]:
    """Where a robot's chunks run, and on how many threads each: this machine's k threads do one chunk at a time,
    its W blocks k at once (one chunk's samples, filtered signals and first-stage output held instead of k: 2 x 43
    MB for the Panda arm's 55,600-sample chunks); a cluster's workers a chunk each, on one thread. More threads
    than the machine has buy nothing here and each holds a W block: the count is capped to the machine's. In order,
    a chunk takes the first decimation stage's outputs the chunk before made on their shared span (`RobotJob.handoff`:
    ~13 % of the W blocks' work saved); a cluster's chunks make their own, so their rows differ from these by the
    decimation filters' tails (1e-9 of the kept rows' weight; both are the whole record's to that)."""
    if isinstance(scheduler, LocalScheduler) and scheduler.workers > 1:
        return LocalScheduler(1), min(scheduler.workers, os.cpu_count() or 1)
    return scheduler, 1


def robot_systems(cfg: IdentifyConfig, model: Model, base: BaseParameters, scheduler: Scheduler, say: Progress,
                  health: list[dict] | None = None, all_rows: bool = False,
                  jobs_out: list[RobotJob] | None = None) -> dict[str, Partial]:
    """The tests of each role ("identify", "validate") reduced to one per-joint factor of [W | Y] (every column):
    each test's files planned from their stamps, their data health checked (an error stops here; the other
    findings appended to `health`), cut into chunks read and reduced on the scheduler's workers
    (`reduce.reduce_robot_chunk`), folded per role as they arrive (`reduce.combine`): no test's factors wait for
    the others', so memory does not grow with the number of tests. The rows of each test's first chunks are kept
    too (Partial.rows, by test), up to `PLOT_BYTES` (the report's plots and validation.csv; every chunk's with
    all_rows), joint by joint. jobs_out: a list the chunks' jobs are appended to (a second pass maps them again)."""
    jobs = [] if jobs_out is None else jobs_out
    plans: dict[str, tuple] = {}  # test -> its plan, the channels with a data health error (data_health = "warn")
    mapper, threads = chunk_scheduler(scheduler)
    in_order = isinstance(mapper, LocalScheduler) and mapper.workers == 1  # its chunks one by one, in their order
    handoff: dict | None = {} if in_order else None  # a chunk's first-stage outputs to the next (`RobotJob.handoff`)
    shown = [t.name for t in cfg.tests if t.role == "validate"][:SHOWN_VALIDATION]
    for spec in cfg.tests:
        say(f"reading and conditioning {spec.name!r}")
        plan = plan_robot_test(cfg, _checked_robot_test(cfg, spec), say)
        # the data's health: each channel, from its file, here (an error stops before any chunk is reduced); the
        # joints against the model, gathered by the chunks (below)
        found = check_robot_test(cfg, plan, say)
        trim_heap()  # the pass over the stamps' and the channels' temporaries (a 1 h log's: ~100 MB kept otherwise)
        if health is not None:
            health += found
        plans[spec.name] = (plan, {d["channel"] for d in found if d["severity"] == "error"})
        transmitted(cfg, np.zeros((1, len(plan.channels["q"]))), np.zeros((1, len(plan.channels[plan.effort]))),
                    len(robot_setup(cfg).joints.columns))
        N, pad = plan.samples, chunk_pad(plan.fs, cfg.conditioning)
        if 2 * _border(plan.fs, cfg.conditioning) >= N:
            raise ConfigError(f"{cfg.path}: test {spec.name!r} has {N} samples, fewer than the filter's two borders "
                              f"({cfg.conditioning.cutoff:g} Hz, order {cfg.conditioning.order}): "
                              + ("widen its window (start, end) or raise the cut-off"
                                 if spec.start is not None or spec.end is not None
                                 else "record longer or raise the cut-off"))
        kept = 0  # bytes of decimated rows kept for the plots so far
        row_bytes = 8 * len(model.tree.equations) * len(robot_setup(cfg).names) / np.prod(cfg.conditioning.decimate)
        for i, (s, e) in enumerate(robot_chunks(N, plan.fs, model, base, cfg.conditioning)):
            lo, hi = max(0, s - pad), min(N, e + pad)
            window = clock_window(plan, lo, hi)
            keep = all_rows or ((spec.role == "identify" or spec.name in shown) and (i == 0 or kept < PLOT_BYTES))
            jobs.append(RobotJob(cfg, window, (s, e), N, keep_rows=keep, health=True, threads=threads,
                                 in_order=in_order, handoff=handoff))
            kept += (e - s) * row_bytes
    parts = mapper.map_reduce(reduce_robot_chunk, jobs, lambda j: j.window.role, combine, say)
    trim_heap()  # the workers' freed chunks (glibc keeps ~25 MB of them otherwise, under the solve and the check)
    setup = robot_setup(cfg)
    for spec in cfg.tests:  # the joints against the model, as the chunks gathered them: an error stops here
        plan, broken = plans[spec.name]
        part = parts.get(spec.role)
        gathered = None if part is None else part.health.pop(spec.name, None)
        found = check_robot_joints(cfg, plan, say, setup.model, setup.joints.columns, broken, gathered)
        if health is not None:
            health += found
    for part in parts.values():
        part.rows = {k: in_joint_order([v]) for k, v in part.rows.items()}
    return parts


def load_car_channels(cfg: IdentifyConfig, spec: TestSpec, progress: Progress | None = None, suite=None
                      ) -> tuple[dict[str, np.ndarray], dict[str, float], float]:
    """The sensor suite's channels of one whole test on its uniform clock, in the file's units, with the factor of
    each to SI, and the sample rate: the plan of `sources.plan_car_test` (time stamps checked, the rates and the
    resampling reported through `progress`) read as one window. The identification reads a segment at a time
    instead; this is for looking at a test. suite: the sensors fitted (default: the config's vehicle's)."""
    # start-up: the car's modules (vehicle, car, delays: scipy.interpolate and optimize, 18 MB) not on a robot's path
    from ..vehicle.description import load_vehicle
    from ..vehicle.estimate import required_channels

    suite = load_vehicle(cfg.vehicle or DEMO_VEHICLE).suite if suite is None else suite
    plan = plan_car_test(cfg, spec, required_channels(spin=False, suite=suite), suite.units, None, lambda fs: 0,
                         progress)
    return read_segment(segment_window(plan, 0, plan.samples), si=False), dict(plan.factors), plan.fs


def true_base_values(truth: dict[str, float], tree, base) -> dict[str, float]:
    """The base parameters' true values from a truth file's standard ones. A standard parameter the file does not
    give is its known value in the tree if it is known (a bench value), else unknown: a base parameter that is
    it or regroups it is left out (the MuJoCo car's truth has no tire offsets: their truth is unknown, not 0)."""
    missing = np.array([n not in truth and n not in tree.known for n in tree.parameter_names])
    X = np.array([truth.get(n, tree.values.get(n, 0.0)) for n in tree.parameter_names])
    XB = base.values(X)
    regrouped = np.asarray(base.regrouped_columns, dtype=int)
    unknown = missing[list(base.columns)]
    if regrouped.size:
        unknown |= (np.abs(base.beta) > 0) @ missing[regrouped] > 0
    return {n: float(v) for n, v, u in zip(base.names, XB, unknown, strict=True) if not u}


def read_truth(path: Path, tree) -> dict[str, float]:
    """True parameter values from a simulator's JSON sidecar: a {name or label: value} table under
    "true_parameters", "truth" or "parameters" (a list of {"name", "value"} records is accepted too).
    Parameters the model does not have are left out."""
    fix = 'give the simulator\'s sidecar (dynid simulate writes <stem>.json), or leave truth out of the test'
    try:
        data = json.loads(Path(path).read_bytes().decode("utf-8-sig"))
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: truth: not UTF-8 text (byte {exc.start}); {fix}") from None
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{path}: truth: not valid JSON ({exc.msg}, line {exc.lineno}, column {exc.colno}); "
                          f"{fix}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: truth: a JSON {type(data).__name__}, not an object with \"true_parameters\": "
                          f"{{name: value}}; {fix}")
    for key in ("true_parameters", "truth", "parameters"):
        table = data.get(key)
        if isinstance(table, dict) and all(isinstance(v, int | float) for v in table.values()):
            break
        if isinstance(table, list):
            table = {r["name"]: r["value"] for r in table if isinstance(r, dict) and "name" in r}
            break
    else:
        raise ConfigError(f"{path}: no true parameter table (\"true_parameters\": {{name: value}})")
    out = {}
    for k, v in table.items():  # terms only the simulator has (its tire damping) are not in this model
        try:
            column = tree.column(k)
        except ModelError:
            continue
        if not isinstance(v, int | float) or isinstance(v, bool) or not np.isfinite(v):
            raise ConfigError(f"{path}: truth: {k} = {v!r} is not a finite number; {fix}")
        out[tree.parameter_names[column]] = float(v)
    return out


def _identify_car(cfg: IdentifyConfig, say: Progress, scheduler: Scheduler | None = None) -> IdentificationRun:
    """The car, as DESIGN.md's data flow: plan each test's file (its clock and overlapping segments), reduce every
    segment to per-group factors (`reduce.reduce_car_segment`: joints, 14 equations, parallel decimation) on the
    scheduler's workers, fold them (`reduce.combine`), solve; IDIM-IV passes map again with the last estimate.
    W is never held whole, whatever the tests' length."""
    # start-up: the car's modules (vehicle, car, delays: scipy.interpolate and optimize, 18 MB) not on a robot's path
    from ..vehicle.estimate import required_channels
    from ..vehicle.excitation import excitation_hint
    from ..vehicle.notes import consistency_text, masses_note, sensors_note
    from ..vehicle.presentation import car_scales, car_sections
    from ..vehicle.tire_curves import sample_steps
    from .car import sensor_offsets
    from .delays import DELAY_SEGMENTS

    if cfg.model != CAR_TEMPLATE:
        raise ConfigError(f"{cfg.path}: [model] template = {cfg.model!r}; templates: {CAR_TEMPLATE}")
    scheduler = scheduler or LocalScheduler()
    settings = cfg.car
    setup = car_setup(cfg)
    vehicle = setup.vehicle

    # 1. plan: each test's file indexed, its clock and segments (a pass over the time stamps only)
    wanted = required_channels(spin=False, suite=vehicle.suite)
    cond = setup.conditioning
    plans = []
    for spec in cfg.tests:
        plan = plan_car_test(cfg, spec, wanted, vehicle.suite.units, settings.segment,
                             lambda fs: border_samples(fs, cond.cutoff, cond.order), say)
        say(f"{spec.name}: read {plan.samples} samples of {len(plan.file_names)} channels at {plan.fs:g} Hz "
            f"({len(plan.segments)} segment(s))")
        plans.append(plan)
        trim_heap()  # the pass over the stamps' temporaries
    knees_note = ""
    if vehicle.knees_from_data:  # the damper curves' knees from the data: a search pass, then the curves' setup
        cfg, knees_note = _knees_from_data(cfg, setup, plans, scheduler, say)
        setup = car_setup(cfg)
        vehicle = setup.vehicle
    tree, names = setup.tree, setup.names
    truth = next((read_truth(t.truth, tree) for t in cfg.tests if t.truth is not None), {})

    def base_values(values: dict[str, float]) -> dict[str, float]:
        X = np.array([values.get(n, 0.0) for n in tree.parameter_names])
        return dict(zip(names, setup.base.values(X), strict=True))

    kw = dict(labels={n: tree.label(n) for n in names}, a_priori=base_values(vehicle.a_priori.values),
              truth=true_base_values(truth, tree, setup.base) if truth else None, poor_factor=cfg.poor_factor)


    # 2. map every segment to its factors (the offsets' effect on a few of each identification test's), fold per
    #    role. The offsets: the config's, or by default the vehicle's sensor suite's
    offsets = sensor_offsets(settings, vehicle)
    moved = tuple(offsets.si().items())
    say((f"sensor zero offsets ({offsets.source}): {len(moved)} channel(s), each test's estimated from its own data"
         if settings.estimate_offsets else f"sensor zero offsets ({offsets.source}): {len(moved)} channel(s), each "
         f"evaluated on up to {settings.offset_segments} segment(s) per identification test") if moved else
        "no sensor zero offsets propagated: σ from the noise alone")

    # the wheel samples' step per test, chosen before the map so that the run gathers at most MAX_SAMPLES of them
    # (the tire fit's memory bounded for any length; under that, the cut-off's step: the same samples as unbounded)
    tire_steps = sample_steps([(p.fs, [hi - lo for lo, hi in p.segments]) for p in plans], cond.cutoff)
    edges = [segment_edges(p) for p in plans]  # the part of its test each segment's health answers for

    def jobs(instruments: dict[str, float] | None = None, with_offsets: bool = True, health: bool = False
             ) -> list[CarJob]:
        """The map's jobs; health: each segment gathers the data health of the part of its test it answers for
        (from its first sample to the next segment's first; the last to the test's end)."""
        out = []
        # the rows kept for the report: each identification test's first segment, and the first validation tests'
        shown = [p.test for p in plans if p.role == "validate"][:SHOWN_VALIDATION]
        for plan, tire_step, edge in zip(plans, tire_steps, edges, strict=True):
            if instruments is not None and plan.role != "identify":
                continue
            estimating = settings.estimate_offsets and instruments is None
            picks = ({} if not (with_offsets and moved and plan.role == "identify") else
                     dict.fromkeys(range(len(plan.segments)), 1.0) if estimating else picked(len(plan.segments)))
            # the sensors' errors' effect on a few segments of each identification test (the model-fit verdict),
            # and the channel delays' on a few
            main = instruments is None and plan.role == "identify"
            errors = picked(len(plan.segments)) if main and with_offsets else {}
            timed = picked(len(plan.segments), DELAY_SEGMENTS) if main else {}
            for i, (lo, hi) in enumerate(plan.segments):
                out.append(CarJob(cfg, segment_window(plan, lo, hi), plan.role, i + 1,
                                  moved if i in picks else (), picks.get(i, 1.0),
                                  instruments, keep_rows=i == 0 and instruments is None
                                  and (plan.role == "identify" or plan.test in shown), errors=i in errors,
                                  delays=i in timed, estimate_offsets=estimating and i in picks,
                                  propagate_offsets=not estimating,
                                  health=edge[i] if health else None, tire_step=tire_step))
        return out

    def picked(n_segments: int, n: int | None = None) -> dict[int, float]:
        """The segments (index -> weight) on which the declared offsets' effect (or the delays) is evaluated: a
        few spread over the test, each standing for len / picked of them."""
        pick = np.unique(np.linspace(0, n_segments - 1, min(n or settings.offset_segments, n_segments)).round())
        return {int(i): n_segments / len(pick) for i in pick}

    say(f"joints and equations on {scheduler}")
    # each identification test folded apart (what the report's "which test identifies what" leaves out), then together
    parts = scheduler.map_reduce(reduce_car_segment, jobs(health=True),
                                 lambda j: (j.role, j.test if j.role == "identify" else ""), combine, say)
    # the data's health, gathered by the segments: an error stops the run here, before the estimate
    health = check_car_tests(cfg, plans, vehicle, say, {t: h for p in parts.values() for t, h in p.health.items()})
    per_test = {t: p for (role, t), p in parts.items() if role == "identify"}
    parts = {role: tree_fold([p for (r, _), p in parts.items() if r == role], combine)
             for role in dict.fromkeys(r for r, _ in parts)}
    # the tests' own wheel samples let go once folded (the tire fit takes the fold's; "without each test" needs
    # none): not held twice, nor merged again for each test left out
    per_test = {t: dataclasses.replace(p, tires=None) for t, p in per_test.items()}
    ident, rows = StreamingLS(names, **kw).merge(parts["identify"].ls), parts["identify"].rows
    errors = parts["identify"].errors
    cross = StreamingLS(names, **kw).merge(parts["validate"].ls) if "validate" in parts else None
    rows.update(parts["validate"].rows if "validate" in parts else {})

    # 3. solve
    # IV starts from WLS's estimate and weights
    say(f"estimating {len(names)} parameters from {ident.n_rows} rows "
        f"({(Method.WLS if cfg.method is Method.IV else cfg.method).label})")
    try:
        result = ident.solve_weighted() if cfg.method.weighted else ident.solve()
    except IdentificationError as exc:
        hint = excitation_hint(list(exc.parameters))
        raise ConfigError(f"{cfg.path}: {exc}\n{hint}" if hint else f"{cfg.path}: {exc}") from None
    offset_estimates, zeros, misfits = None, parts["identify"].zeros, ()
    if zeros is not None:  # each test's offsets estimated with the parameters, from the groups the model fits
        plain = result
        result, offset_estimates = ident.with_offsets_estimated(plain, zeros)
        # the verdict with the offsets read taken out (on the plain rows a realised offset can pass for a misfit:
        # a laser's 1 mm made the 406's own tire24 one on a seed); a group that still misfits cannot say what a
        # sensor's zero is: estimate again without it
        fitted = zeros.group_rms([result.value(n) for n in ident.estimated_names], offset_estimates.u)
        misfits = tuple(g for g, f in model_fits(ident, errors, result.estimates, fitted).items() if not f.fits)
        if misfits:
            result, offset_estimates = ident.with_offsets_estimated(plain, zeros, misfits)
    elif parts["identify"].bias is not None:
        result = ident.with_systematic(result, parts["identify"].bias)
    if cfg.covariance.hac:  # with the offsets estimated, each test's rows with their offsets' columns again
        result = hac_pass(cfg, ident, result, reduce_car_segment,
                          [j for j in jobs(with_offsets=offset_estimates is not None) if j.role == "identify"],
                          lambda j: j.role, scheduler, say, offset_estimates)
    delays = None
    if parts["identify"].shifts is not None:  # the channel groups' delays the residual asks for, against the declared
        delays = _car_delays(cfg, setup, plans, jobs(with_offsets=False), parts["identify"].shifts, result,
                             scheduler, say)
    for k in range(settings.iv_passes if cfg.method is Method.IV else 0):
        # instruments from the last estimate on every identification segment (and, on the final pass, on the
        # offsets' segments), then the IV estimate on the same rows (min_speed applies to the simulated rates)
        say(f"IDIM-IV pass {k + 1}/{settings.iv_passes}: suspensions simulated with the last estimate")
        final = k == settings.iv_passes - 1
        values = dict(zip(result.names, (float(v) for v in result.values), strict=True))
        part = scheduler.map_reduce(reduce_car_segment, jobs(values, with_offsets=final), lambda j: j.role, combine,
                                    say)["identify"]
        ident = StreamingLS(names, **kw).merge(part.ls)
        try:
            # the paper's weights (eq. (8), as WLS): the two estimates then differ by their instruments alone
            result = ident.solve_iv(part.iv, result.weights or None, iterations=0)
        except IdentificationError as exc:
            raise ConfigError(f"{cfg.path}: method = \"iv\": {exc}") from None
        if part.bias is not None:
            x = np.array([result.value(n) for n in ident.estimated_names])
            result = result.with_systematic(propagate(part.iv.normal(result.weights), part.bias, x,
                                                      ident.estimated_names, result.weights))

    # 4. results: does the model fit each group (its residual against what the sensors' errors explain), direct
    #    and cross validation; a delay mismatch's shift of the estimates in their σ total
    # with the offsets estimated, the groups' residuals are the rows' with the offsets the data read taken out (for
    # IV: its estimate with the offsets its WLS start read; the `!= "iv"` this once said compared a Method with a
    # string, always true since the method became typed, and the car-truth tables were measured so)
    fitted = None
    if offset_estimates is not None:
        fitted = zeros.group_rms([result.value(n) for n in ident.estimated_names], offset_estimates.u, misfits)
    fits = model_fits(ident, errors, result.estimates, fitted)
    if delays is not None and delays.mismatched:
        result = result.with_systematic(delays.systematic(result.estimated_names, result.systematic))
    result = dataclasses.replace(result, scales=car_scales(dict(zip(result.names, result.values, strict=True))),
                                 flag_percent=cfg.flag_percent,
                                 misfit=misfit_parameters(fits, ident, result.weights or None))
    run = IdentificationRun(setup.model, setup.base, result, GroupedSystem.stack(
        [rows[t.name] for t in cfg.tests if t.role == "identify"]), sections=car_sections(names),
        notes=sensors_note(vehicle) + knees_note
        + offsets_note(result, offsets, offset_estimates and offset_estimates.offsets)
        + fit_note(fits, result.labels, result.misfit)
        + masses_note(result, tree)
        + "Physical consistency of the estimates: "
        + consistency_text(result, setup.base, tree) + health_note([h for h in health if h["severity"] != "note"]),
        offsets=offsets.to_dict(offset_estimates and offset_estimates.offsets), health=health)
    run.validate = {t.name: rows[t.name] for t in cfg.tests if t.role == "validate" and t.name in rows}
    run.systems, run.config, run.vehicle = {t.name: rows[t.name] for t in cfg.tests if t.name in rows}, cfg, vehicle
    run.notes += shown_note(cfg, list(run.validate))
    run.delays = delays
    run.without_test = without_each_test(names, kw, per_test, misfits)
    # a group the validation test barely moves (braking: the lateral force, yaw and roll moments): marked; the direct
    # figures with the offsets the data read taken out when they were estimated (the model's fit includes them)
    validate(run, ident, cross, residual=fitted)
    if settings.tire_curves:
        run.tires = _tire_curves(parts, vehicle, say)
    result.validation["fit"] = {g: f.as_dict() for g, f in fits.items()}
    return run


def _knees_from_data(cfg: IdentifyConfig, setup, plans, scheduler: Scheduler, say: Progress
                     ) -> tuple[IdentifyConfig, str]:
    """The knees of the dampers the vehicle file gives none (`vehicle.dampers.KneeSearch` on every identification
    segment's rows): the config that carries them, and the results' note saying what was chosen."""
    # start-up: the car's modules (vehicle, car, delays: scipy.interpolate and optimize, 18 MB) not on a robot's path
    from ..vehicle.sensors import CORNER_TAGS
    from ..vehicle.template import DAMPERS

    dampers = setup.vehicle.knees_from_data
    say(f"choosing the knees of {len(dampers)} damper curve(s) from the data's clearance rates")
    jobs = [CarJob(cfg, segment_window(plan, lo, hi), plan.role, i + 1, knees=True)
            for plan in plans if plan.role == "identify" for i, (lo, hi) in enumerate(plan.segments)]
    search = scheduler.map_reduce(reduce_car_segment, jobs, lambda j: j.role, combine, say)["identify"].knees
    knees = search.knees()
    chosen = tuple((d, *knees[d]) for d in dampers)
    words = "; ".join(f"{CORNER_TAGS[DAMPERS.index(d)]} (h{d}) bump {hi:.3g}, rebound {-lo:.3g}"
                      for d, lo, hi in chosen)
    note = (f"Damper knees chosen from the data (m/s; the vehicle file gives none): {words}. Each is where the "
            "damper's slope changes: the least residual of its own equation over candidate knees 4 % apart, both "
            "pieces holding at least 1 % of that side's rows and 10 rows (vehicle.dampers.KneeSearch).\n")
    say(note.rstrip())
    return dataclasses.replace(cfg, car=dataclasses.replace(cfg.car, knees=chosen)), note


def without_each_test(names: list[str], kw: dict, per_test: dict,
                      misfits: tuple[str, ...] = ()) -> dict[str, dict[str, float]]:
    """Which test identifies what: {test: {parameter: σ total (WLS, noise and zero offsets) of the identification
    without that test}} (inf where the others cannot identify it); empty with a single identification test. The
    rows are those already reduced: a WLS solve per test, no pass over the data."""
    if len(per_test) < 2:
        return {}
    out = {}
    for test in per_test:
        rest = tree_fold([p for t, p in per_test.items() if t != test], combine)
        ls = StreamingLS(names, **kw).merge(rest.ls)
        try:
            r = ls.solve_weighted()
            if rest.zeros is not None:  # the offsets estimated, as the identification does (its misfit groups out)
                r, _ = ls.with_offsets_estimated(r, rest.zeros, misfits)
            elif rest.bias is not None:
                r = ls.with_systematic(r, rest.bias)
            out[test] = {n: float(s) for n, s in zip(r.names, r.std_total, strict=True)}
        except IdentificationError:
            out[test] = dict.fromkeys(names, float("inf"))
    return out


def _tire_curves(parts: dict, vehicle, say: Progress):
    """The tire characteristics (vehicle.tire_curves) of every test's wheel samples the map gathered (taken from the
    parts: their `tires` are None after)."""
    # start-up: the car's modules (vehicle, car, delays: scipy.interpolate and optimize, 18 MB) not on a robot's path
    from ..vehicle.tire_curves import TireSamples, fit_tire_curves

    samples = [s for p in parts.values() if p.tires is not None for s in p.tires.parts]
    if not samples:
        return None
    # merged once, in the fit's order, and the parts' own let go: the fit's samples held once, not twice (3 h of
    # data: 871k samples, 70 MB)
    for p in parts.values():
        p.tires = None
    merged = TireSamples.ordered(samples)
    del samples
    curves = fit_tire_curves(merged, vehicle.geometry.wheel_radius)
    say(f"tire curves from {len(merged)} wheel samples in {curves.seconds:.2f} s"
        + (f" ({'; '.join(f'{k}: {v}' for k, v in curves.missing.items())})" if curves.missing else ""))
    return curves


def _car_delays(cfg: IdentifyConfig, setup, plans, jobs: list[CarJob], sums, result, scheduler: Scheduler,
                say: Progress):
    """The channel groups' delays (`pipeline.delays`): Gauss-Newton steps of the joint fit of the estimate and the
    groups' extra delays, the first on the sums the identification's map gathered, the next (while a step moves a
    delay by more than a tenth of a sample, and only when one is more than a sample off) on the same segments
    mapped again about the delays found. The warnings go to `say`."""
    # start-up: the car's modules (vehicle, car, delays: scipy.interpolate and optimize, 18 MB) not on a robot's path
    from .delays import MAX_STEPS, delay_check

    names = result.estimated_names
    x = np.array([result.value(n) for n in names])
    fs = plans[0].fs
    timed = [j for j in jobs if j.delays]
    lags: dict[str, float] = {}
    for k in range(1, MAX_STEPS + 1):
        est = estimate_shifts(sums, x, names, result.weights or None)
        # a group the equations leave uncertain by more than a sample is reported, not stepped on
        moved = {g: float(v) for g, v, e in zip(est.sources, est.values, est.std, strict=True) if e <= 1.0 / fs}
        # every step's sums are taken about the estimate x: its parameter step is the change from x to the joint fit
        shift = est.parameter_step
        big = any(abs(lags.get(g, 0.0) + v) > 1.0 / fs for g, v in moved.items())
        if k == MAX_STEPS or not big or all(abs(v) < 0.1 / fs for v in moved.values()):
            break
        lags = {g: lags.get(g, 0.0) + v for g, v in moved.items()}
        say(f"channel delays: step {k + 1}, about {', '.join(f'{g} {1e3 * v:+.1f} ms' for g, v in lags.items())}")
        again = [dataclasses.replace(j, lags=tuple(lags.items()), keep_rows=False, offsets=()) for j in timed]
        sums = scheduler.map_reduce(reduce_car_segment, again, lambda j: j.role, combine, say)["identify"].shifts
    check = delay_check(est, lags, setup.logger, cfg.car.compensate_delays, fs, len(timed), k, shift)
    for w in check.warnings():
        say(f"WARNING: {w}")
    return check


def offsets_note(result, offsets, estimates: dict[str, tuple[float, float]] | None = None) -> str:
    """Which sensor zero offsets were propagated or estimated (`car.SensorOffsets`; estimates: source -> the offset
    and its σ, in units of its declared σ), where they came from, what %σ total means and which offsets weigh most;
    and whether σ total holds a channel-delay mismatch's shift (`pipeline.delays`)."""
    # start-up: the car's modules (vehicle, car, delays: scipy.interpolate and optimize, 18 MB) not on a robot's path
    from .delays import DELAY_SOURCE

    where = {"vehicle": f"from the vehicle's sensor suite ({offsets.vehicle}: each channel's zero offset; "
                        "[uncertainty] offsets = {...} in the config replaces them, offsets = \"none\" turns them off)",
             "config": "from the config's [uncertainty] offsets (they replace the vehicle's sensor suite's)"}
    sys = result.systematic
    delay = None if sys is None else next((s for s in sys.shifts if s.startswith(DELAY_SOURCE)), None)
    delay_text = ("" if delay is None else
                  f"%σ total also adds the shift of the estimates that the channels' delays as the data say them imply "
                  f"({delay}: see Channel delays), the bias of a logger whose dynamics are not the declared ones.\n")
    if sys is None or not offsets.values:
        why = ("the config's [uncertainty] turns them off" if offsets.source != "vehicle"
               else f"the vehicle's sensor suite ({offsets.vehicle}) declares none")
        return (f"No sensor zero offsets propagated ({why}): %σ is from the noise alone and ignores the sensors' "
                "zero offsets.\n" + delay_text)
    counts: dict[str, int] = {}
    for n in sys.names:
        source = sys.main_source(n)
        if not source.startswith(DELAY_SOURCE):
            channel = source.split(": ")[-1]
            counts[channel] = counts.get(channel, 0) + 1
    top = ", ".join(f"{c} ({k})" for c, k in sorted(counts.items(), key=lambda kv: -kv[1])[:4])
    if estimates:
        return (f"Each identification test's sensor zero offsets ({len(offsets.values)} channel(s) "
                f"{where[offsets.source]}: {offsets.listing()}) are estimated with the parameters from the test's own "
                "data, their declared σ as the prior ([uncertainty] estimate = false propagates them instead); "
                "%σ is the paper's (least squares, statistical), %σ total adds what the data leave of the offsets' "
                "effect. " + (f"The offsets that move most estimates (parameters): {top}. " if top else "")
                + _offsets_read(offsets, estimates) + "\n" + delay_text)
    return ("%σ is the paper's (least squares, statistical); %σ total adds the sensors' zero offsets, propagated to "
            f"first order: {len(offsets.values)} channel(s) {where[offsets.source]}, 1 σ each, "
            f"evaluated on up to {offsets.segments} segment(s) per identification test: {offsets.listing()}. "
            + (f"The offsets that move most estimates (parameters): {top}.\n" if top else "\n") + delay_text)


def _offsets_read(offsets, estimates: dict[str, tuple[float, float]]) -> str:
    """The offsets the data read largest (in their channel's unit and in declared σ), and those beyond 3 σ of the
    declared value: a declared σ too small, or a sensor zeroed badly."""
    def text(source: str) -> str:
        u, s = estimates[source]
        value, unit = offsets.values[source.split(": ")[-1]]
        return f"{source} {u * value:+.3g} {unit} ({u:+.1f} σ ± {s:.1f})"

    ranked = sorted(estimates, key=lambda k: -abs(estimates[k][0]))
    out = "The largest read: " + "; ".join(text(k) for k in ranked[:3]) + "."
    beyond = [k for k in ranked if abs(estimates[k][0]) > 3.0]
    if beyond:
        out += (f" {len(beyond)} read beyond 3 σ of the declared zero offset ({', '.join(beyond[:4])}): check that "
                "sensor's zeroing, or declare its offset larger in the vehicle's [sensors] or [uncertainty] offsets.")
    return out


def hac_pass(cfg: IdentifyConfig, ident: StreamingLS, result: IdentificationResult, fn: Callable, jobs: list,
             key: Callable, scheduler: Scheduler, say: Progress,
             offsets: OffsetEstimate | None = None) -> IdentificationResult:
    """`result` with the config's HAC covariance: the identification's chunks or segments (`jobs`, as the first pass
    mapped them) mapped again through `fn` with the estimate, each reduced to its rows' Newey–West sums alone
    (`estimation.hac`), folded in order, the sandwich from `ident`'s factors; offsets: a car's estimate of each
    test's sensor offsets (the scores then the profiled problem's, the bread its reduced normal matrix's inverse;
    the jobs must evaluate every segment's offsets' columns)."""
    say(f"covariance: {cfg.covariance.label}, a second pass over the {ident.n_rows} rows at the estimate")
    sums = ident.hac_sums(result, cfg.covariance, offsets)
    again = [dataclasses.replace(j, keep_rows=False, health=None if isinstance(j, CarJob) else False, hac=sums)
             for j in jobs]
    part = next(iter(scheduler.map_reduce(fn, again, key, combine, say).values()))
    return ident.with_hac(result, part.hac, cfg.covariance, offsets)


def validate(run: IdentificationRun, ident: StreamingLS, cross: StreamingLS | None,
             values: np.ndarray | None = None, residual: Mapping[str, float] | None = None) -> IdentificationRun:
    """The direct and cross validation of a robot's or a car's estimate, from the factors of every segment of the
    identification and the validation tests (`StreamingLS`, the rows never held): per equation group the paper's
    relative error ||Y - W X|| / ||Y|| and the NRMSE RMS(Y - W X) / std(Y) that robot users compare models by
    (the static gravity load in ||Y|| makes the relative error look small whatever the dynamics); the
    identification's residual RMS per group, and the groups a validation test barely moves (noise over noise:
    marked "not excited", not hidden). Into run.errors, run.residual_rms, run.not_excited and the result's
    validation. values: the values of the accumulators' parameters (default: the result's); residual: the
    identification groups' residual RMS when it is not the factors' at the values (a car's, with the sensor
    offsets the data read taken out: estimation.offsets)."""
    result = run.result
    x = result.values if values is None else values
    run.errors["direct"] = ident.relative_errors(x, residual)
    run.residual_rms = ident.group_rms(x) if residual is None else dict(residual)
    if cross is not None:
        run.errors["cross"] = cross.relative_errors(x)
        run.not_excited["cross"] = not_excited(cross.group_rms(), run.residual_rms)
    run.errors["direct NRMSE"] = ident.nrmse(x, residual)
    if cross is not None:
        run.errors["cross NRMSE"] = cross.nrmse(x)
    result.validation.update(run.errors)
    if run.not_excited:
        result.validation["not_excited"] = run.not_excited
    return run


def shown_note(cfg: IdentifyConfig, shown: Sequence[str]) -> str:
    """Which validation tests the figures and validation.csv show, when not all ('' when all)."""
    n = sum(t.role == "validate" for t in cfg.tests)
    return "" if n <= len(shown) else (f"Cross validation over all {n} validation tests; the figures and "
                                       f"validation.csv show the first {len(shown)} ({', '.join(shown)}).\n")


def identify(cfg: IdentifyConfig | str | os.PathLike[str], progress: Progress | None = None,
             scheduler: Scheduler | None = None) -> IdentificationRun:
    """Run the identification a config describes (a robot from joint files, or a car from its sensors), its
    segments on `scheduler` (default: the config's [compute], else this machine's cores; see `schedulers`).
    cfg: an `IdentifyConfig` (`config.load_config`) or the config file's path."""
    if isinstance(cfg, str | os.PathLike):
        cfg = load_config(cfg)
    elif not isinstance(cfg, IdentifyConfig):
        raise TypeError(f"identify() takes a config file's path or an IdentifyConfig "
                        f"(dynid.pipeline.config.load_config), not {type(cfg).__name__}")
    if scheduler is None:
        with contextlib.closing(scheduler_for(cfg.scheduler, cfg.workers)) as own:
            return identify(cfg, progress, own)
    # BLAS on one thread, as the map's workers already run it: the solves' QRs are small (the offsets' a few
    # hundred rows by ~85 columns), and OpenBLAS's threads on them cost 1.5 ms -> 145 ms of CPU per QR on a loaded
    # 2-core machine (busy-waiting threads competing with the other processes), 8 s of the demo's 18
    with threadpool_limits(limits=1, user_api="blas"):
        return _identify(cfg, progress, scheduler)


def _identify(cfg: IdentifyConfig, progress: Progress | None, scheduler: Scheduler) -> IdentificationRun:
    """`identify` with its scheduler, BLAS limited to one thread."""
    say = progress or (lambda _msg: None)
    if cfg.kind == "car":
        return _identify_car(cfg, say, scheduler)
    setup = robot_setup(cfg)
    model, base = setup.model, setup.base
    if setup.joints.note:
        say(setup.joints.note)
    names = list(setup.names)  # the base parameters, then the drive gains when identified
    gains = names[len(base.names):]
    bad = [k for k in cfg.known if k not in names]
    if bad:
        raise ConfigError(f"{cfg.path}: [identification] known names {bad} are not base parameters of "
                          f"{model.name!r}; base parameters: {', '.join(names)}")
    if gains and cfg.method is Method.WLS_PC:
        raise ConfigError(f"{cfg.path}: [identification] method = \"wls-pc\" does not take identified drive gains "
                          "(its constraints are on the bodies alone): use method = \"wls\", or give the gains as "
                          "known ([drive] identify_gains = false)")
    health: list[dict] = []
    jobs: list[RobotJob] = []
    parts = robot_systems(cfg, model, base, scheduler, say, health, jobs_out=jobs)
    a_priori = dict(zip(base.names, base.values(model.parameters), strict=True))
    known = dict(cfg.known)
    if gains:  # the data sheet's gains are their a priori values; those not identified are known
        a_priori |= dict(zip(gains, cfg.drive.gains, strict=True))
        known |= {g: v for g, v, free in zip(gains, cfg.drive.gains, cfg.drive.identify, strict=True) if not free}
        free = [g for g, f in zip(gains, cfg.drive.identify, strict=True) if f]
        scale = [w for w, has in (("the payload test(s)", any(t.payload for t in cfg.tests if t.role == "identify")),
                                  ("the known gain(s)", len(free) < len(gains))) if has]
        say(f"drive gains identified with the inertial parameters: {', '.join(free)} (the scale from "
            f"{' and '.join(scale)})")
    # the factors of every column, folded per role; the known values moved to the right-hand side on them
    full = {role: parts[role].ls if role in parts else None for role in ("identify", "validate")}
    same = np.eye(len(names) + 1)
    ident = full["identify"].reparametrised(names, same, known=known or None, a_priori=a_priori)
    ident.poor_factor = cfg.poor_factor
    say(f"estimating {len(names)} parameters from {ident.n_rows} rows ({cfg.method.label})")
    structure = consistency_structure(model.tree, base)
    fit = None
    try:
        if cfg.method is Method.WLS_PC:
            fit = wls_pc_streamed(ident, structure,
                                  standard_prior=dict(zip(model.tree.parameter_names, model.parameters, strict=True)))
            result = fit.result
        elif cfg.method is Method.WLS:
            result = _wls_with_gains(full["identify"], ident, names, len(base.names), known) if gains \
                else ident.solve_weighted()
        else:
            result = ident.solve()
    except IdentificationError as exc:
        raise ConfigError(f"{cfg.path}: {exc}{_rank_hints(cfg, ident, health)}") from None
    if cfg.covariance.hac:
        result = hac_pass(cfg, ident, result, reduce_robot_chunk, [j for j in jobs if j.window.role == "identify"],
                          lambda j: j.window.role, chunk_scheduler(scheduler)[0], say)
    # the flag judges each σ against the link's size, not against a value that may be near zero (robot_scales)
    result = dataclasses.replace(result, flag_percent=cfg.flag_percent, scales=robot_scales(
        model.tree, base, dict(zip(result.names, (float(v) for v in result.values), strict=True))))
    # each identification test's first chunks and the first validation tests': the plots (not every validation test's:
    # memory would grow with their number)
    kept = {name: rows for part in parts.values() for name, rows in part.rows.items()}
    systems = {t.name: kept[t.name] for t in cfg.tests if t.name in kept}
    sections = None
    checked = {role: None if ls is None else ls.reparametrised(names, same, known=known or None)
               for role, ls in full.items()}
    if gains:  # the rows in joint torques with the estimated gains, for the validation and its plots
        p, values = len(base.names), result.values[len(base.names):]
        systems = {k: torques_with_gains(s, p, values) for k, s in systems.items()}
        checked = {role: None if ls is None else torque_rows(ls, names, p, values, known)
                   for role, ls in full.items()}
        sections = [(f"{result.method} estimates of the base parameters", list(base.names)),
                    ("drive gains (N·m/A, motor side)", gains)]
    run = IdentificationRun(model, base, result, GroupedSystem.stack(
        [systems[t.name] for t in cfg.tests if t.role == "identify"]), systems=systems, config=cfg, health=health,
        sections=sections)
    run.validate = {t.name: systems[t.name] for t in cfg.tests if t.role == "validate" and t.name in systems}
    validate(run, checked["identify"], checked["validate"], result.values[:len(checked["identify"].names)])
    run.consistency = robot_consistency(result, structure, model.tree, fit)
    run.notes = (fit.note() if fit is not None else "") + "Physical consistency of the estimates: " \
        + run.consistency["text"]
    shown = shown_note(cfg, list(run.validate))
    run.notes += f"\n{shown}" if shown else ""
    if cfg.reference:
        rows = read_reference(cfg.reference["file"])
        run.reference, unmatched = match_reference(rows, base, cfg.reference.get("names", {}),
                                                   cfg.reference.get("combinations", {}))
        if unmatched:
            say(f"{len(unmatched)} published rows match none of our base parameters: "
                + "; ".join(r.expression for r in unmatched[:3]))
    return run


def _wls_with_gains(full: StreamingLS, ident: StreamingLS, names: list[str], p: int, known: dict[str, float]
                    ) -> IdentificationResult:
    """Gautier's WLS with identified drive gains. A joint's equation alone cannot fix its gain's scale (without a
    payload its rows are homogeneous, W_j X - Nt diag(i) g = 0, and solve exactly at X = g = 0), so each joint's
    noise level sigma_j (paper eq. (8)) is taken from its rows in joint torques through given gains: first the
    data sheet's (the a priori values of `ident`), then the estimate's (one pass more: sigma_j is the final
    model's residual per joint). full: the factors of every column; ident: with the known values."""
    gains = np.array([ident.a_priori[n] for n in names[p:]])
    result = None
    for _ in range(2):
        result = ident.solve_weighted(torque_rows(full, names, p, gains, known).group_sigmas())
        gains = result.values[p:]
    return result


def torque_rows(full: StreamingLS, names: list[str], p: int, gains: np.ndarray, known: dict[str, float]
                ) -> StreamingLS:
    """The factors of `torques_with_gains`' rows from those of every column [W | G | Y] (`full`): the base
    parameters' columns W and the measured torque Y - G g (the known base parameters on the right-hand side)."""
    T = np.zeros((len(names) + 1, p + 1))
    T[:p, :p] = np.eye(p)
    T[p:len(names), p] = -np.asarray(gains, dtype=float)
    T[-1, p] = 1.0
    return full.reparametrised(names[:p], T, known={k: v for k, v in known.items() if k in names[:p]} or None)


def torques_with_gains(s: GroupedSystem, p: int, gains: np.ndarray) -> GroupedSystem:
    """Rows [W | G] [X; g] = Y of identified drive gains (G = -Nt diag(i) decimated) as joint-torque rows: the
    measured torque Y - G g (the currents through the estimated gains, the payload's torque off) against W X, the
    gains' columns zeroed (so W @ [X; g] is the prediction)."""
    W = s.W.copy()
    W[:, p:] = 0.0
    return GroupedSystem(W, s.Y - s.W[:, p:] @ gains, s.groups, s.t)


def _rank_hints(cfg: IdentifyConfig, ident: StreamingLS, health: list[dict]) -> str:
    """What in the config or the data may have left parameters unidentifiable: a joint whose rows min_speed left
    out, a channel the health check saw still (said with the error, which names only parameters)."""
    hints = []
    for j, v in sorted(cfg.conditioning.min_speed.items()):
        rows = ident.group_rows.get(f"joint{j}", 0)
        if rows < 10:
            hints.append(f"[conditioning] min_speed = {{ {j} = {v:g} }} leaves {rows} row(s) of joint {j}: lower it "
                         "below the joint's speeds")
    still = sorted({d["channel"] for d in health if d.get("kind") == "dead"})
    if still:
        hints.append(f"channel(s) {', '.join(repr(c) for c in still)} never change in the identification tests: "
                     "a joint that does not move excites none of its parameters (check the sensor, or add a test "
                     "that moves it)")
    return f" ({'; '.join(hints)})" if hints else ""


def consistency_structure(tree, base: BaseParameters) -> ConsistencyStructure:
    """What a robot's physical-consistency constraints need: K (base = K @ standard), each moving body's ten
    parameters, the joint terms that must be >= 0. A body none of whose inertial parameters has any effect (all
    eliminated) is left out: nothing the data say can make it inconsistent."""

    names = tree.parameter_names
    K = np.zeros((base.rank, len(names)))
    K[np.arange(base.rank), list(base.columns)] = 1.0
    if base.regrouped_columns:
        K[:, list(base.regrouped_columns)] += base.beta
    used = np.any(K != 0, axis=0)
    bodies = {}
    for f in tree.frames:
        idx = tuple(tree.index[f"{p}{f.j}"] for p in INERTIAL)
        if f.sigma != FIXED and used[list(idx)].any():
            bodies[f.j] = idx
    kinds = {c.name: c.kind for c in tree.couplings}
    nonneg = tuple(i for i, n in enumerate(names) if kinds.get(n, n.rstrip("0123456789")) in NONNEGATIVE_TERMS)
    return ConsistencyStructure(tuple(names), tuple(base.names), K, bodies, nonneg)


@dataclass(frozen=True)
class PlausibleExport:
    """What `plausible_export` chose: the standard values, the links' moves from the model file (one line each:
    frame, joint, mass, centre of mass and inertia changes) and the lines to warn about (a link moved more than
    its prior spread), and how closely the estimate is reproduced (chi2, worst base parameter in σ)."""

    values: dict[str, float]
    moves: list[str]
    warnings: list[str]
    chi2: float
    worst: tuple[str, float]


def plausible_export(tree, base: BaseParameters, base_values: dict[str, float], base_std: dict[str, float]
                     ) -> PlausibleExport:
    """The standard set a URDF export writes for an identified base estimate (`estimation.physical.
    plausible_standard`): physically plausible (every body's pseudo-inertia positive definite with a margin
    scaled to the link, its centre of mass inside the link's box, `robot.link_box`) and closest to the model
    file in each link's own units, the estimate reproduced within its σ."""

    structure = consistency_structure(tree, base)
    bodies = {}
    for j in structure.bodies:
        m0 = float(tree.values.get(f"M{j}", 0.0))
        lo, hi = link_box(tree, j)
        bodies[j] = (m0, link_length(tree, j), lo, hi)
    prior = dict(zip(tree.parameter_names, tree.parameters, strict=True))
    fit = plausible_standard(structure, base_values, base_std, prior, bodies)
    moves, warn = [], []
    for j in sorted(structure.bodies):
        m0, L, _, _ = bodies[j]
        if m0 <= 0:
            continue
        old = np.array([prior.get(f"{k}{j}", 0.0) for k in ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M")])
        new = np.array([fit.standard[f"{k}{j}"] for k in ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M")])
        dm, shift = new[9] - old[9], float(np.linalg.norm(new[6:9] / new[9] - old[6:9] / old[9]))
        I_old, I_new = _inertia_at_com(old), _inertia_at_com(new)
        dI = float(np.linalg.norm(I_new - I_old) / max(np.linalg.norm(I_old), 1e-300))
        who = f"frame {j} ({tree.joint_names.get(j, 'link')})"
        line = (f"{who}: mass {old[9]:.4g} -> {new[9]:.4g} kg ({100 * dm / old[9]:+.1f} %), centre of mass moved "
                f"{1000 * shift:.1f} mm ({100 * shift / L:.1f} % of the link's {L:.3g} m), inertia at it "
                f"{100 * dI:.1f} %")
        moves.append(line)
        if abs(dm) > PRIOR_SPREAD * old[9] or shift > PRIOR_SPREAD * L:
            warn.append(line)
    return PlausibleExport(fit.standard, moves, warn, fit.chi2, fit.worst)


def _inertia_at_com(p: np.ndarray) -> np.ndarray:
    xx, xy, xz, yy, yz, zz = p[:6]
    c = p[6:9] / p[9]
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]) - p[9] * (c @ c * np.eye(3) - np.outer(c, c))


def robot_consistency(result: IdentificationResult, structure: ConsistencyStructure, tree,
                      fit: PhysicalFit | None = None) -> dict:
    """A robot estimate's physical-consistency verdict, by the car's check (`check_physical`):
    {"realisable": True, False or None (undecided), "checked_on", "violations": [{body, condition, message}],
    "unchecked", "text"} (and "wls_pc": the constrained fit's summary).

    With wls-pc: the standard set it found (its base values are the estimate). Otherwise the base estimate:
    the conditions readable on base parameters that are one standard parameter each, then, with the pc extra
    installed, the standard set of largest pseudo-inertia margin reproducing every base value (a witness when
    realisable); without the extra, the bodies whose parameters regroup are named as not checked."""

    couplings = {c.name: c.kind for c in tree.couplings}
    bodies = sorted(structure.bodies)
    unchecked: list[str] = []
    if fit is not None:
        checked_on = "the standard parameters found by wls-pc (their base values are the estimate)"
        violations = check_physical(fit.standard, frames=bodies) + check_joint_terms(fit.standard, couplings)
    else:
        K, std = structure.base_map, structure.standard_names
        values = dict(zip(result.names, (float(v) for v in result.values), strict=True))  # drive gains aside
        single = {n: values[n] for n, row in zip(structure.base_names, K, strict=True)
                  if np.count_nonzero(row) == 1 and n in std and row[std.index(n)] == 1.0}
        violations = check_base_singletons(single, couplings)
        checked_on = "the base parameters that are one standard parameter each"
        try:
            feas = feasible_standard(structure, values)
        except IdentificationError:  # no pc extra: say what is left unchecked
            unchecked = [f"body {j}: mass, inertia at the centre of mass, triangle inequalities (its parameters "
                         "regroup)" for j in bodies if any(std[i] not in single for i in structure.bodies[j])]
        else:
            checked_on = "a standard set reproducing every base value (largest pseudo-inertia margin) and " \
                + checked_on
            if feas.realisable:
                violations += check_physical(feas.standard, frames=bodies) + check_joint_terms(feas.standard,
                                                                                                couplings)
            elif not violations:
                # what fails in the standard set closest to realisable (the binding bodies' own conditions)
                worst = check_physical(feas.standard, frames=list(feas.tightest)) if feas.standard else []
                violations.append(Violation(
                    feas.tightest[0] if feas.tightest else 0, "pseudo-inertia",
                    "no standard parameter set with these base values is physically realisable (largest "
                    f"pseudo-inertia margin {feas.t:.3g}, bodies {', '.join(map(str, feas.tightest)) or '-'} "
                    "binding): a mass, an inertia at a centre of mass or a triangle inequality fails whatever the "
                    "regrouped parameters are" + (f"; in the set closest to realisable: {worst[0]}" if worst else "")
                    + "; method = \"wls-pc\" gives the closest consistent estimate"))
    realisable = None if unchecked and not violations else not violations
    if violations:
        text = "NOT physically realisable:\n" + "\n".join(f"  {v}" for v in violations)
    elif realisable:
        text = ("physically realisable (every body: mass > 0, inertia at the centre of mass positive definite, "
                f"triangle inequalities hold; IA, FV, FS >= 0), checked on {checked_on}.")
    else:
        text = ("IA, FV, FS >= 0 and the moments readable on the base set hold; not checked on the regrouped "
                "set (pip install cvxpy clarabel, the 'pc' extra, for the check, or method = \"wls-pc\"):\n"
                + "\n".join(f"  {u}" for u in unchecked))
    return {"realisable": realisable, "checked_on": checked_on,
            "violations": [{"body": v.body, "condition": v.condition, "message": v.message} for v in violations],
            "unchecked": unchecked, "text": text, **({"wls_pc": fit.to_dict()} if fit is not None else {})}


def write_outputs(run: IdentificationRun, out: Path, title: str, progress: Progress | None = None) -> list[Path]:
    """results.json, parameters.csv, validation.csv (the measured and predicted signals per test and equation),
    engineering.csv (a car), the figures (PNG) and report.html (self-contained: the figures embedded) in `out`,
    each written atomically; report.html last, so a report on disk always has its data beside it."""

    say = progress or (lambda _msg: None)
    out.mkdir(parents=True, exist_ok=True)
    r = run.result
    say("drawing figures and writing the report")
    report = build_report(run, title)
    data = r.to_dict()
    for p in data["parameters"]:  # the schema kept; each parameter gains its unit and 95 % interval
        p.update(report.per_parameter.get(p["name"], {}))
    data["base_parameters"] = dict(zip(run.base.names, run.base.expressions, strict=True))
    if run.reference:
        data["reference"] = [{"published": m.row.expression, "label": m.label, "published_value":
                              m.row.published(r.method)[0], "ours": m.value(list(r.names), r.values)}
                             for m in run.reference]
    if getattr(run, "consistency", None) is not None:  # a robot's physical-consistency verdict
        data["consistency"] = run.consistency
    if run.offsets is not None:  # a car's sensor zero offsets: which, how large, from where
        data["sensor_offsets"] = run.offsets
    if run.health is not None:  # the data health findings (pipeline.health)
        data["health"] = run.health
    if getattr(run.model.tree, "knees", None) and run.config is not None and hasattr(run.config, "car"):
        # a car's damper curves: the knees (v-, v+) m/s per damper, and which the search chose from the data
        data["damper_knees"] = {str(d): list(k) for d, k in run.model.tree.knees.items()}
        data["damper_knees_from_data"] = [d for d, *_ in run.config.car.knees]
    if run.tires is not None:  # the tire characteristics (vehicle.tire_curves)
        data["tires"] = run.tires.to_dict()
    data.update(report.data)
    # the files a run read in its staging folder (a demo's tests) named where they will be (atomic.final_text)
    text = final_text(json.dumps(_finite(data), indent=2, allow_nan=False, default=_json))
    written = [write_atomic(out / "results.json", text)]
    for name, content in report.files.items():
        written.append(write_atomic(out / name, content))
    written.append(write_atomic(out / "report.html", report.html))
    return written


def _finite(o: object) -> object:
    """NaN and infinities as null (JSON has neither)."""
    if isinstance(o, dict):
        return {k: _finite(v) for k, v in o.items()}
    if isinstance(o, list | tuple):
        return [_finite(v) for v in o]
    if isinstance(o, float | np.floating) and not np.isfinite(o):
        return None
    return o


def _json(o: object) -> object:
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"cannot write {type(o).__name__} to JSON")


__all__ = ["IdentificationRun", "ModelError", "consistency_structure", "identify", "load_joint_test",
           "robot_consistency", "write_outputs"]
