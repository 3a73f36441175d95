"""`dynid identify`: a config in, tables, results.json, figures and an HTML report out.

Data flow (one direction): config -> files -> joint trajectories and forces -> conditioned,
decimated (W, Y) per equation group -> OLS or weighted LS -> direct and cross validation ->
report. Outputs are written atomically to the output folder.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from ..atomic import write_atomic
from ..dynamics import BaseParameters, Model
from ..estimation import IdentificationError, IdentificationResult, nrmse, ols, propagate, relative_errors, wls
from ..estimation.physical import ConsistencyStructure, PhysicalFit, feasible_standard, wls_pc
from ..model import ModelError
from ..report import parameter_table
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
    sections: list[tuple[str, list[str]]] | None = None  # how the parameter tables are grouped
    notes: str = ""  # printed under the tables (e.g. the physical-consistency verdict)
    not_excited: dict[str, list[str]] = field(default_factory=dict)  # kind -> groups whose Y is mostly noise
    systems: dict[str, GroupedSystem] = field(default_factory=dict)  # test name -> its rows (the report's plots)
    config: IdentifyConfig | None = None  # what was run (the report's traceability)
    vehicle: Any = None  # a car's vehicle description (its geometry for the report's engineering figures)
    consistency: dict | None = None  # a robot's physical-consistency verdict (robot_consistency), for results.json

    def summary(self) -> str:
        text = parameter_table(self.result, self.sections)
        return f"{text}\n\n{self.notes}" if self.notes else text

    def reference_table(self) -> str:
        """Our estimate of each published quantity beside the published value (same method), and the gap in σ."""
        r = self.result
        names = list(r.names)
        cov = r.full_covariance
        use_wls = r.method == "WLS"
        lines = [f"{'published':>10} {'ours':>12} {'ours %σ':>8} {'published':>12} {'pub. %σ':>8} {'gap/σ_pub':>9}  as"]
        for m in self.reference:
            pub, pub_rel = (m.row.wls, m.row.wls_rel_std) if use_wls else (m.row.ols, m.row.ols_rel_std)
            ours = m.value(names, r.values)
            ours_rel = 100 * m.std(names, cov) / abs(ours) if ours else float("nan")
            gap = abs(ours - pub) / (abs(pub) * pub_rel / 100) if pub and pub_rel else float("nan")
            how = " + ".join(f"{w:g}*{n}" if w != 1 else n for n, w in m.weights.items())
            lines.append(f"{m.label:>10} {ours:>12.6g} {ours_rel:>8.2f} {pub:>12.6g} {pub_rel:>8.2f} {gap:>9.2f}"
                         f"  {how}")
        return "\n".join(lines)


def load_joint_test(cfg: IdentifyConfig, spec: TestSpec, n: int, progress: Progress | None = None) -> JointTest:
    """Joint positions and forces of one test from its files, on one uniform clock (`timebase`: time columns,
    repeated rows, jitter, gaps, two files' clocks, the start..end window), through the channel map and
    transmission."""
    from ..io import to_si
    from .timebase import on_one_clock

    wanted = {}
    for quantity in ("q", "tau"):
        if quantity not in spec.files:
            raise ConfigError(f"{cfg.path}: test {spec.name!r} needs a file for {quantity!r} in files = {{...}}")
        if quantity not in cfg.channels:
            raise ConfigError(f"{cfg.path}: [channels] has no {quantity!r} = {{ channels = [...], unit = ... }}")
        wanted[quantity] = (spec.files[quantity], list(cfg.channels[quantity].channels))
    fs, channels = on_one_clock(wanted, spec.fs, test=spec.name, config=cfg.path, start=spec.start, end=spec.end,
                                max_gap=spec.max_gap, say=progress or (lambda _m: None))
    arrays = {}
    for quantity, chans in channels.items():
        unit = cfg.channels[quantity].unit
        expect = ("rad", "m") if quantity == "q" else ("N*m", "N")  # a revolute or a prismatic joint's
        arrays[quantity] = np.stack([to_si(c.values, unit or c.unit, channel=c.name, source=str(spec.files[quantity]),
                                           expect=expect)[0] for c in chans], axis=1)
    q, tau = arrays["q"], arrays["tau"]
    shapes = {"q": (n, q.shape[1]), "q_offset": (n,), "tau": (n, tau.shape[1])}
    for key, m in cfg.transmission.items():  # q = Nq q_file + q_offset, tau = Nt tau_file: n joints
        if m.shape != shapes[key]:
            raise ConfigError(f"{cfg.path}: [transmission] {key} is {' x '.join(map(str, m.shape))}; it must be "
                              f"{' x '.join(map(str, shapes[key]))} ({n} joints of the model"
                              + ("" if key == "q_offset" else f", {shapes[key][1]} channels of {key} in [channels]")
                              + ")")
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


def load_car_channels(cfg: IdentifyConfig, spec: TestSpec, progress: Progress | None = None, suite=None
                      ) -> tuple[dict[str, np.ndarray], dict[str, float], float]:
    """The sensor suite's channels of one logger file on one uniform clock, in the file's units (views, no copy
    of a long record, when the file's own clock is uniform), with the factor of each to SI; and the sample rate.

    Real loggers, as for a robot test's files (`timebase`): per time base (a logging rate), rows with one stamp
    are averaged, stamps going back or a hole over the test's `max_gap` sample periods are refused with the file,
    line, sample and time, and jitter or holes are resampled onto a uniform clock, the check reported through
    `progress`. Channels at several rates (an MDF4 file's channel groups, a CSV's sparse columns) are
    interpolated (cubic) onto the clock of the fastest, over the span every channel covers and the test's
    start..end; the rate chosen is reported. suite: the sensors fitted (default: the config's vehicle's)."""
    from ..io import DataError, align, format_of, unit_factor
    from ..io.align import InterpSpec
    from ..vehicle.description import load_vehicle
    from ..vehicle.estimate import required_channels
    from .timebase import RATE_TOLERANCE, read_test_file, stream

    say = progress or (lambda _m: None)
    path = spec.files["channels"]
    suite = load_vehicle(cfg.vehicle or "peugeot406").suite if suite is None else suite  # the sensors fitted
    wanted = required_channels(spin=False, suite=suite)
    renamed = {q: (c.channels[0], c.unit) for q, c in cfg.channels.items()}
    in_file = {q: renamed.get(q, (q, None))[0] for q in wanted}
    names = list(dict.fromkeys(in_file.values()))
    given = None if format_of(path) == "mdf" else spec.fs  # an MDF file's channels always carry their time stamps
    rec, timed = read_test_file(path, given, spec.name, cfg.path, names)
    rec.require(names)
    bases: list[list] = []  # the channels on one time base (one logging rate)
    for name in names:
        ch = rec.channel(name)
        base = next((b for b in bases if b[0].time is ch.time or np.array_equal(b[0].time, ch.time)), None)
        if base is None:
            bases.append([ch])
        else:
            base.append(ch)
    streams = [stream(b, rec.label, timed, spec.max_gap, (spec.start, spec.end)) for b in bases]
    if timed:
        for s in streams:
            listed = ", ".join(list(s.channels)[:3]) + (", ..." if len(s.channels) > 3 else "")
            say(f"{spec.name}: {s.report()}" + (f" ({len(s.channels)} channels: {listed})" if len(streams) > 1
                                                 else ""))
    fastest = min(s.h for s in streams)  # the clock: the fastest channels' (the most of them at one rate)
    ref = max((s for s in streams if s.h <= fastest * (1 + 1e-6)), key=lambda s: len(s.channels))
    h = ref.h
    if timed and spec.fs is not None and abs(1 / h - spec.fs) > RATE_TOLERANCE * spec.fs:
        raise DataError(
            f"{cfg.path}: test {spec.name!r} gives fs = {spec.fs:g} Hz but the time stamps of {rec.label} say "
            f"{1 / h:.6g} Hz (step {h * 1e3:.6g} ms): remove fs from the test (the time stamps are used), or correct "
            "it (a time column in ms needs its unit in the header, e.g. \"time [ms]\")", source=rec.label)
    lo, hi = max(s.t[0] for s in streams), min(s.t[-1] for s in streams)
    if lo > hi:
        spans = "; ".join(f"{', '.join(list(s.channels)[:2])}, ... cover {s.t[0]:.6g}..{s.t[-1]:.6g} s"
                          for s in streams)
        raise DataError(f"{rec.label}: the channels do not overlap in time: {spans}", source=rec.label)
    first, last = max(float(b[0].time[0]) for b in bases), min(float(b[0].time[-1]) for b in bases)
    tol = 1e-9 * max(abs(last), h)
    for key, v in (("start", spec.start), ("end", spec.end)):
        if v is not None and not first - tol <= v <= last + tol:
            raise DataError(f"{cfg.path}: test {spec.name!r}: {key} = {v:g} s is outside the record {rec.label}, "
                            f"which covers {first:.6g}..{last:.6g} s (every channel); give a time inside it",
                            source=rec.label)
    a = lo if spec.start is None else max(lo, spec.start)
    b = hi if spec.end is None else min(hi, spec.end)
    clock = ref.t if ref.uniform else ref.t0 + h * np.arange(np.ceil((ref.t[0] - ref.t0) / h),
                                                             np.floor((ref.t[-1] - ref.t0) / h) + 1)
    clock = clock[(clock >= max(a - tol, lo)) & (clock <= min(b + tol, hi))]
    if clock.size < 2:
        raise DataError(f"{cfg.path}: test {spec.name!r}: no two samples of {rec.label} between start and end "
                        f"({a:.6g}..{b:.6g} s at {1 / h:.6g} Hz): widen the window", source=rec.label)
    if len(streams) > 1:
        rates = ", ".join(f"{1 / s.h:.6g} Hz ({len(s.channels)})" for s in sorted(streams, key=lambda s: s.h))
        say(f"{spec.name}: channels at several rates in {rec.label}: {rates}; every channel interpolated onto the "
            f"{1 / h:.6g} Hz clock of the fastest, {clock.size} samples ({clock[0]:.6g}..{clock[-1]:.6g} s)")
    elif not ref.uniform:
        say(f"{spec.name}: every channel on one uniform {1 / h:.6g} Hz clock, {clock.size} samples "
            f"({clock[0]:.6g}..{clock[-1]:.6g} s)")
    al = align([InterpSpec(n, s.channels[n]) for s in streams for n in s.channels], t=clock, source=rec.label,
               gap_factor=None)
    values, factors = {}, {}
    expected = suite.units  # the sensor's own unit: its dimension is what the channel must have
    for q, name in in_file.items():
        unit = renamed.get(q, (None, None))[1] or rec.channel(name).unit
        expect = (unit_factor(expected[q])[1],) if q in expected else None
        values[q], factors[q] = al[name], unit_factor(unit, channel=name, source=str(path), expect=expect)[0]
    fs = 1.0 / float(np.median(np.diff(al.t)))
    return values, factors, fs


def read_truth(path: Path, tree) -> dict[str, float]:
    """True parameter values from a simulator's JSON sidecar: a {name or label: value} table under
    "true_parameters", "truth" or "parameters" (a list of {"name", "value"} records is accepted too).
    Parameters the model does not have are left out."""
    data = json.loads(Path(path).read_text())
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
            out[tree.parameter_names[tree.column(k)]] = float(v)
        except ModelError:
            continue
    return out


def _identify_car(cfg: IdentifyConfig, say: Progress) -> IdentificationRun:
    """The car: per test, overlapping segments -> joints -> 14 equations -> decimated rows, accumulated
    into an incremental QR per equation group (W is never held whole, whatever the test's length)."""
    from ..estimation import StreamingLS
    from ..signals import border_samples
    from ..symbolic.generated import GeneratedRegressor
    from ..vehicle import EQUATION_ROWS, TIRES, car_base_parameters, car_template
    from ..vehicle.description import load_vehicle
    from ..vehicle.estimate import CarConditioning, estimate_joints
    from ..vehicle.excitation import excitation_hint
    from .car import car_scales, car_sections, car_system, consistency_text, masses_note

    if cfg.model != "peugeot406":
        raise ConfigError(f"{cfg.path}: [model] template = {cfg.model!r}; templates: peugeot406")
    settings = cfg.car
    vehicle = load_vehicle(cfg.vehicle or "peugeot406")
    tree = car_template(vehicle.geometry, vehicle.a_priori.values, name=vehicle.name)
    # the bench values of the vehicle file, then the config's (a config may fix more, or other values)
    known = {**vehicle.known, **{tree.parameter_names[tree.column(k)]: v for k, v in cfg.known.items()}}
    if known:
        tree = tree.with_values(known).with_known(set(known))
    model = Model(tree)
    base = car_base_parameters(tree, settings.base)
    names = list(base.names)
    truth: dict[str, float] = {}
    for spec in cfg.tests:
        if spec.truth is not None:
            truth = read_truth(spec.truth, tree)
            break

    def base_values(values: dict[str, float]) -> dict[str, float]:
        X = np.array([values.get(n, 0.0) for n in tree.parameter_names])
        return dict(zip(names, base.values(X), strict=True))

    kw = dict(labels={n: tree.label(n) for n in names}, a_priori=base_values(vehicle.a_priori.values),
              truth=base_values(truth) if truth else None, poor_factor=cfg.poor_factor)
    streams = {"identify": StreamingLS(names, **kw), "validate": StreamingLS(names, **kw)}
    shown: dict[str, GroupedSystem] = {}
    cond = CarConditioning(settings.cutoff, settings.order, settings.attitude_crossover,
                            compensate_delays=settings.compensate_delays)
    aero = vehicle.aero if settings.aero else None
    fast = GeneratedRegressor(tree)
    suite = vehicle.suite
    # without height lasers the tire deflections come from the loads through the known kt: those rows say nothing
    equations = None if vehicle.lasers else [j for j in EQUATION_ROWS if j not in TIRES]

    def segment_rows(channels, factors, fs, lo, hi, offset: tuple[str, float] | None = None, instruments=None,
                     keep=None):
        si = {k: v[lo:hi] * factors[k] for k, v in channels.items()}  # units converted segment by segment
        if offset is not None:  # one sensor's zero moved by its standard deviation (file unit)
            si[offset[0]] = si[offset[0]] + offset[1] * factors[offset[0]]
        traj = estimate_joints(si, fs, model, vehicle.geometry, vehicle.tables, cond, suite)
        return car_system(model, traj, fs, settings.decimate, base=base, aero=aero, regressor=fast,
                          cutoff=cond.cutoff, min_speed=settings.min_speed, instruments=instruments, keep=keep,
                          equations=equations)[0]

    def segments_of(spec: TestSpec, report: bool = True):
        channels, factors, fs = load_car_channels(cfg, spec, say if report else None, suite)
        N = len(next(iter(channels.values())))
        b = border_samples(fs, cond.cutoff, cond.order)
        step = max(int(settings.segment * fs), 4 * b)
        return channels, factors, fs, [(lo, min(N, lo + step + 2 * b)) for lo in range(0, max(N - 2 * b, 1), step)]

    ident_offsets = streams["identify"].bias_accumulator() if settings.offsets else None

    def picked(n_segments: int) -> dict[int, float]:
        """The segments (index -> weight) on which the declared offsets' effect is evaluated: a few spread
        over the test, each standing for len / picked of them."""
        pick = np.unique(np.linspace(0, n_segments - 1, min(settings.offset_segments, n_segments)).round())
        return {int(i): n_segments / len(pick) for i in pick}

    def offset_jobs(pool, spec: TestSpec, channels, factors, fs, segment, base_job, scale) -> list:
        """Each declared offset applied alone to one segment, paired with that segment's own rows."""
        return [(f"{spec.name}: {q}", scale, base_job, pool.submit(segment_rows, channels, factors, fs, *segment,
                                                                   (q, b)))
                for q, b in settings.offsets.items()]

    def use_offsets(jobs: list) -> None:
        for source, scale, base_job, job in jobs:
            b, p = base_job.result(), job.result()
            ident_offsets.add(source, b.W, b.Y, p.W - b.W, p.Y - b.Y, b.groups, scale)

    from concurrent.futures import ThreadPoolExecutor

    def use(spec: TestSpec, job, k: int, n_seg: int) -> None:
        sys = job.result()
        say(f"{spec.name}: joints and equations, segment {k}/{n_seg}")
        streams[spec.role].add(sys.W, sys.Y, sys.groups)
        shown.setdefault(spec.name, sys)

    def iv_pass(pool, last, final: bool):
        """Instruments from the last estimate on every identification segment (and, on the final pass, on the
        offsets' segments), then the IV estimate on the same rows (their own: min_speed applies to the simulated
        rates)."""
        values = dict(zip(last.names, (float(v) for v in last.values), strict=True))
        ident = StreamingLS(names, **kw)
        sums = ident.instrument_sums()
        acc = ident.bias_accumulator() if settings.offsets and final else None
        for spec in (t for t in cfg.tests if t.role == "identify"):
            channels, factors, fs, segments = segments_of(spec, report=False)  # the file's checks said once
            picks = picked(len(segments)) if acc is not None else {}
            jobs: deque = deque()
            for i, seg in enumerate(segments):
                jobs.append((i, seg, pool.submit(segment_rows, channels, factors, fs, *seg, None, values)))
                while len(jobs) > (0 if i == len(segments) - 1 else 2):
                    j, (lo, hi), job = jobs.popleft()
                    sys = job.result()
                    ident.add(sys.W, sys.Y, sys.groups)
                    sums.add(sys.W, sys.Y, sys.Z, sys.groups)
                    # each offset's rows on the same samples as the segment's (its own simulation, same rows)
                    moved = {q: pool.submit(segment_rows, channels, factors, fs, lo, hi, (q, b), values, sys.kept)
                             for q, b in settings.offsets.items()} if j in picks else {}
                    for q, m in moved.items():
                        p = m.result()
                        acc.add(f"{spec.name}: {q}", sys.W, sys.Y, p.W - sys.W, p.Y - sys.Y, sys.groups, picks[j],
                                Z=sys.Z, dZ=p.Z - sys.Z)
        try:
            # the paper's weights (eq. (8), as WLS): the two estimates then differ by their instruments alone
            result = ident.solve_iv(sums, last.weights or None, iterations=0)
        except IdentificationError as exc:
            raise ConfigError(f"{cfg.path}: method = \"iv\": {exc}") from None
        if acc is not None:
            x = np.array([result.value(n) for n in ident.estimated_names])
            result = result.with_systematic(propagate(sums.normal(result.weights), acc, x, ident.estimated_names,
                                                      result.weights))
        return result, ident

    # segments on both cores: NumPy and SciPy release the GIL in their loops, and threads share the record.
    # BLAS keeps to one thread inside each: its own threads would only compete with the segments' (and spin)
    with ThreadPoolExecutor(max_workers=min(2, os.cpu_count() or 1)) as pool, \
            threadpool_limits(limits=1, user_api="blas"):
        for spec in cfg.tests:
            channels, factors, fs, segments = segments_of(spec)
            say(f"{spec.name}: read {len(next(iter(channels.values())))} samples of {len(channels)} channels at "
                f"{fs:g} Hz")
            with_offsets = picked(len(segments)) if ident_offsets is not None and spec.role == "identify" else {}
            jobs: deque = deque()
            pending: list = []  # the offsets' jobs, used once the test's segments are accumulated
            for i, (lo, hi) in enumerate(segments):  # consecutive segments overlap by the two borders
                jobs.append(pool.submit(segment_rows, channels, factors, fs, lo, hi))
                if i in with_offsets:
                    pending += offset_jobs(pool, spec, channels, factors, fs, (lo, hi), jobs[-1], with_offsets[i])
                if len(jobs) == 3:  # at most three segments in flight; a result is dropped once used
                    use(spec, jobs.popleft(), i - 1, len(segments))
            while jobs:  # segment numbers are 1-based: the job popped is number len(segments) - len(jobs) after it
                use(spec, jobs.popleft(), len(segments) - len(jobs), len(segments))
            if pending:
                say(f"{spec.name}: the effect of {len(settings.offsets)} sensor offsets")
                use_offsets(pending)
        ident = streams["identify"]
        say(f"estimating {len(names)} parameters from {ident.n_rows} rows "
            f"({'WLS' if cfg.method == 'iv' else cfg.method.upper()})")
        try:
            result = ident.solve() if cfg.method == "ols" else ident.solve_weighted()
        except IdentificationError as exc:
            hint = excitation_hint(list(exc.parameters))
            raise ConfigError(f"{cfg.path}: {exc}\n{hint}" if hint else f"{cfg.path}: {exc}") from None
        if ident_offsets is not None:
            result = ident.with_systematic(result, ident_offsets)
        for k in range(settings.iv_passes if cfg.method == "iv" else 0):
            say(f"IDIM-IV pass {k + 1}/{settings.iv_passes}: suspensions simulated with the last estimate")
            result, ident = iv_pass(pool, result, final=k == settings.iv_passes - 1)

    result = dataclasses.replace(result, scales=car_scales(dict(zip(result.names, result.values, strict=True))),
                                 flag_percent=cfg.flag_percent)
    run = IdentificationRun(model, base, result, GroupedSystem.stack(
        [shown[t.name] for t in cfg.tests if t.role == "identify"]), sections=car_sections(names, tree),
        notes=sensors_note(vehicle) + offsets_note(result) + masses_note(result, tree)
        + "Physical consistency of the estimates: "
        + consistency_text(result, base, tree))
    run.validate = {t.name: shown[t.name] for t in cfg.tests if t.role == "validate"}
    run.systems, run.config, run.vehicle = {t.name: shown[t.name] for t in cfg.tests}, cfg, vehicle
    run.errors["direct"] = ident.relative_errors(result)
    if streams["validate"].n_rows:
        run.errors["cross"] = streams["validate"].relative_errors(result)
        # a group the validation test barely moves (braking: the lateral force, yaw and roll moments) has a
        # relative error of noise over noise: marked, not hidden
        noise = ident.group_rms(result)
        moved = streams["validate"].group_rms()
        run.not_excited["cross"] = [g for g, rms in moved.items() if rms < 2 * noise.get(g, 0.0)]
    result.validation.update(run.errors)
    if run.not_excited:
        result.validation["not_excited"] = run.not_excited
    return run


def sensors_note(vehicle) -> str:
    """What the sensors not fitted change (empty for the paper's suite)."""
    from ..vehicle.sensors import gnss_point

    out = ""
    if not vehicle.cameras:
        out += ("No cameras: the damper clearances come from potentiometers, the steering and camber joints from the "
                "kinematic tables at the measured clearance and steering-wheel angle.\n")
    if not vehicle.lasers:
        out += ("No height lasers: the chassis height and the tire deflections come from the wheel loads through the "
                "known tire stiffness (kt15, kt24, kt33, kt42 from the vehicle file's [known]); the tire equations "
                "are then identities and are left out, so the tire stiffness cannot be identified from these tests.\n")
    if not vehicle.correvit:
        out += ("No Correvit: the horizontal velocity over ground comes from the GNSS/INS at its antenna point "
                f"{list(gnss_point(vehicle.geometry))} m in frame 6.\n")
    return out


def offsets_note(result) -> str:
    """What %σ total means, and which declared sensor offsets weigh most (empty without offsets)."""
    sys = result.systematic
    if sys is None:
        return ""
    counts: dict[str, int] = {}
    for n in sys.names:
        channel = sys.main_source(n).split(": ")[-1]
        counts[channel] = counts.get(channel, 0) + 1
    top = ", ".join(f"{c} ({k})" for c, k in sorted(counts.items(), key=lambda kv: -kv[1])[:4])
    return ("%σ is the paper's (least squares, statistical); %σ total adds the sensors' declared zero offsets, "
            f"propagated to first order. The offsets that move most estimates (parameters): {top}.\n")


def _validate(cfg: IdentifyConfig, run: IdentificationRun, systems: dict[str, GroupedSystem]) -> IdentificationRun:
    result = run.result
    ident = run.identify
    run.errors["direct"] = relative_errors(ident.W, ident.Y, result.values, ident.groups)
    cross = [t for t in cfg.tests if t.role == "validate"]
    if cross:
        val = GroupedSystem.stack([systems[t.name] for t in cross])
        run.validate = {t.name: systems[t.name] for t in cross}
        run.errors["cross"] = relative_errors(val.W, val.Y, result.values, val.groups)
    # beside the paper's relative error, the NRMSE robot users compare models by: the static gravity load in
    # ||Y|| makes the relative error look small whatever the dynamics
    run.errors["direct NRMSE"] = nrmse(ident.W, ident.Y, result.values, ident.groups)
    if cross:
        run.errors["cross NRMSE"] = nrmse(val.W, val.Y, result.values, val.groups)
    result.validation.update(run.errors)
    return run


def identify(cfg: IdentifyConfig, progress: Progress | None = None) -> IdentificationRun:
    """Run the identification a config describes (a robot from joint files, or a car from its sensors)."""
    say = progress or (lambda _msg: None)
    if cfg.kind == "car":
        return _identify_car(cfg, say)
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
        systems[spec.name] = joint_system(model, load_joint_test(cfg, spec, model.n, say), base, cfg.conditioning)
    ident = GroupedSystem.stack([systems[t.name] for t in cfg.tests if t.role == "identify"])
    a_priori = dict(zip(names, base.values(model.parameters), strict=True))
    say(f"estimating {len(names)} base parameters from {ident.W.shape[0]} rows ({cfg.method.upper()})")
    kw = dict(a_priori=a_priori, known=cfg.known or None, poor_factor=cfg.poor_factor)
    structure = consistency_structure(model.tree, base)
    fit = None
    try:
        if cfg.method == "wls-pc":
            fit = wls_pc(ident.W, ident.Y, ident.groups, names, structure,
                         standard_prior=dict(zip(model.tree.parameter_names, model.parameters, strict=True)), **kw)
            result = fit.result
        else:
            result = (wls(ident.W, ident.Y, ident.groups, names, **kw) if cfg.method == "wls"
                      else ols(ident.W, ident.Y, names, **kw))
    except IdentificationError as exc:
        raise ConfigError(f"{cfg.path}: {exc}") from None
    result = dataclasses.replace(result, flag_percent=cfg.flag_percent)
    run = _validate(cfg, IdentificationRun(model, base, result, ident, systems=systems, config=cfg), systems)
    run.consistency = robot_consistency(result, structure, model.tree, fit)
    run.notes = (fit.note() if fit is not None else "") + "Physical consistency of the estimates: " \
        + run.consistency["text"]
    if cfg.reference:
        rows = read_reference(cfg.reference["file"])
        run.reference, unmatched = match_reference(rows, base, cfg.reference.get("names", {}),
                                                   cfg.reference.get("combinations", {}))
        if unmatched:
            say(f"{len(unmatched)} published rows match none of our base parameters: "
                + "; ".join(r.expression for r in unmatched[:3]))
    return run


def consistency_structure(tree, base: BaseParameters) -> ConsistencyStructure:
    """What a robot's physical-consistency constraints need: K (base = K @ standard), each moving body's ten
    parameters, the joint terms that must be >= 0. A body none of whose inertial parameters has any effect (all
    eliminated) is left out: nothing the data say can make it inconsistent."""
    from ..model.consistency import NONNEGATIVE_TERMS
    from ..model.tree import FIXED, INERTIAL

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


def robot_consistency(result: IdentificationResult, structure: ConsistencyStructure, tree,
                      fit: PhysicalFit | None = None) -> dict:
    """A robot estimate's physical-consistency verdict, by the car's check (`check_physical`):
    {"realisable": True, False or None (undecided), "checked_on", "violations": [{body, condition, message}],
    "unchecked", "text"} (and "wls_pc": the constrained fit's summary).

    With wls-pc: the standard set it found (its base values are the estimate). Otherwise the base estimate:
    the conditions readable on base parameters that are one standard parameter each, then, with the pc extra
    installed, the standard set of largest pseudo-inertia margin reproducing every base value (a witness when
    realisable); without the extra, the bodies whose parameters regroup are named as not checked."""
    from ..model.consistency import Violation, check_base_singletons, check_joint_terms, check_physical

    couplings = {c.name: c.kind for c in tree.couplings}
    bodies = sorted(structure.bodies)
    unchecked: list[str] = []
    if fit is not None:
        checked_on = "the standard parameters found by wls-pc (their base values are the estimate)"
        violations = check_physical(fit.standard, frames=bodies) + check_joint_terms(fit.standard, couplings)
    else:
        K, std = structure.base_map, structure.standard_names
        single = {n: float(v) for n, v, row in zip(structure.base_names, result.values, K, strict=True)
                  if np.count_nonzero(row) == 1 and n in std and row[std.index(n)] == 1.0}
        violations = check_base_singletons(single, couplings)
        checked_on = "the base parameters that are one standard parameter each"
        try:
            feas = feasible_standard(structure, dict(zip(result.names, (float(v) for v in result.values),
                                                         strict=True)))
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
                "set (pip install 'dynid[pc]' for the check, or method = \"wls-pc\"):\n"
                + "\n".join(f"  {u}" for u in unchecked))
    return {"realisable": realisable, "checked_on": checked_on,
            "violations": [{"body": v.body, "condition": v.condition, "message": v.message} for v in violations],
            "unchecked": unchecked, "text": text, **({"wls_pc": fit.to_dict()} if fit is not None else {})}


def write_outputs(run: IdentificationRun, out: Path, title: str, progress: Progress | None = None) -> list[Path]:
    """results.json, parameters.csv, validation.csv (the measured and predicted signals per test and equation),
    engineering.csv (a car), the figures (PNG) and report.html (self-contained: the figures embedded) in `out`,
    each written atomically; report.html last, so a report on disk always has its data beside it."""
    from ..report.build import build_report

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
        data["reference"] = [{"published": m.row.expression, "label": m.label, "published_value": m.row.wls
                              if r.method == "WLS" else m.row.ols, "ours": m.value(list(r.names), r.values)}
                             for m in run.reference]
    if getattr(run, "consistency", None) is not None:  # a robot's physical-consistency verdict
        data["consistency"] = run.consistency
    data.update(report.data)
    text = json.dumps(_finite(data), indent=2, allow_nan=False, default=_json)
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
