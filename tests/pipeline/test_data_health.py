"""The data health check before a car's identification (issue 30, item 2): defects injected into the demo's files.

Oracle: the defect we inject ourselves into the simulated car's logger files (the demo's quick tests,
two noise seeds): a channel clipped at a percentile of its own values, one spike, a channel frozen at
its first value, two wheel loads swapped, the accelerometer's vertical axis inverted. Each must be
found, on the channel we touched, with a time span that covers every sample we changed; the files as
written give no finding but the notes on the lane change's steering cameras, which saturate at their
declared +-5 deg and which the estimator replaces by the kinematic tables (a true finding, kept as a
note). Through `dynid identify` an error stops the run, exit status 2, one line naming the file, the
channel, the span and the fix, before any segment is reduced; on clean files the check changes no
number of the answer (the same run with the check switched off gives the same estimates, bit for bit).
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from dynid.cli.main import main
from dynid.io import Channel, Recording, read_recording, write_recording
from dynid.io.health import ERROR, NOTE, WARNING, ChannelScan
from dynid.pipeline.config import ConfigError, load_config
from dynid.pipeline.demo import simulate_tests, write_demo
from dynid.pipeline.health import car_health
from dynid.pipeline.sources import plan_car_test
from dynid.vehicle.description import load_vehicle
from dynid.vehicle.estimate import required_channels

SEEDS = (406, 7)
VEHICLE = load_vehicle("peugeot406")


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """The demo's quick tests written with the sensor suite at two seeds: seed -> the folder."""
    results = simulate_tests(quick=True)
    folders = {}
    for seed in SEEDS:
        folders[seed] = tmp_path_factory.mktemp(f"seed{seed}")
        write_demo(folders[seed], results, seed=seed)
    return folders


def findings(config, test_file: str | None = None) -> dict[str, list]:
    """file name -> the findings of each test of a config (or of the one test reading test_file)."""
    cfg = load_config(config)
    wanted = required_channels(spin=False, suite=VEHICLE.suite)
    out = {}
    for spec in cfg.tests:
        name = spec.files["channels"].name
        if test_file is None or name == test_file:
            plan = plan_car_test(cfg, spec, wanted, VEHICLE.suite.units, None, lambda fs: 0)
            out[name] = car_health(plan, VEHICLE)
    return out


def injected(folder, tmp_path, file: str, edit) -> tuple:
    """A copy of the demo folder whose `file` has had `edit(channels)` applied; (its config, the channels before,
    after)."""
    work = tmp_path / "work"
    shutil.copytree(folder, work)
    path = work / "data" / file
    rec = read_recording(path)
    before = {n: rec.channel(n) for n in rec.names}
    after = dict(before)
    edit(after)
    write_recording(Recording.from_channels(list(after.values())), path)
    return work / "identify.toml", before, after


def replaced(channels: dict, name: str, values: np.ndarray) -> None:
    c = channels[name]
    channels[name] = Channel(name, c.unit, values, c.time)


def changed_span(before: Channel, after: Channel) -> tuple[float, float]:
    """First and last time at which the injected channel differs from the file's."""
    k = np.flatnonzero(before.values != after.values)
    return float(before.time[k[0]]), float(before.time[k[-1]])


def the_one(found: list, kind: str, channel: str):
    hits = [f for f in found if f.kind == kind and channel in f.channel.split(" and ")]
    assert len(hits) == 1, [f.text() for f in found]
    return hits[0]


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.slow
@pytest.mark.e2e
def test_the_demo_files_give_no_finding(demo, seed):
    """Zero false positives on the six tests of two seeds; the lane change's camera notes are the only output."""
    every = findings(demo[seed] / "identify.toml")
    assert len(every) == 6
    loud = [f.text() for fs in every.values() for f in fs if f.severity != NOTE]
    assert not loud, loud
    notes = {(name, f.channel) for name, fs in every.items() for f in fs}
    assert notes == {("lane.csv", "steer_fl"), ("lane.csv", "steer_fr")}, notes


@pytest.mark.parametrize("file, channel, percentile", [
    ("sine.csv", "imu_yaw_rate", 70),    # the tester's: ZZ6 +12 % and "realisable"
    ("spiral.csv", "imu_yaw_rate", 70),  # a slow ramp clipped: a flat end beside noise
    ("sine.csv", "wft_fl_Fz", 60),       # the tester's: ZZ6 = -110; the flat tops broken by the noise
    ("braking.csv", "wft_fl_Fz", 60),
])
@pytest.mark.slow
@pytest.mark.e2e
def test_a_channel_clipped_at_a_percentile_stops_the_run(demo, tmp_path, file, channel, percentile):
    def clip(ch):
        x = ch[channel].values
        replaced(ch, channel, np.minimum(x, np.percentile(x, percentile)))

    config, before, after = injected(demo[SEEDS[0]], tmp_path, file, clip)
    f = the_one(findings(config, file)[file], "clipped", channel)
    first, last = changed_span(before[channel], after[channel])
    assert f.severity == ERROR and f.t_start <= first and f.t_end >= last, f.text()
    assert f.share == pytest.approx(1 - percentile / 100, abs=0.02)


@pytest.mark.slow
@pytest.mark.e2e
def test_a_spike_is_found_where_it_is(demo, tmp_path):
    """One sample of a wheel load 3 kN off (120 times the transducer's noise, within its range): a warning at
    its time; the tester's 1e6 N: beyond the transducer's 20 kN range, an error."""
    file, channel, k = "sine.csv", "wft_rr_Fz", 3000
    for size, kind, severity in ((3000.0, "spike", WARNING), (1e6, "out of range", ERROR)):
        def spike(ch, size=size):
            x = ch[channel].values.copy()
            x[k] += size
            replaced(ch, channel, x)

        config, before, _ = injected(demo[SEEDS[1]], tmp_path / kind.replace(" ", "_"), file, spike)
        found = findings(config, file)[file]
        f = the_one(found, kind, channel)
        t = float(before[channel].time[k])
        assert f.severity == severity and f.t_start <= t <= f.t_end and f.t_end - f.t_start < 0.01, f.text()
        others = [g.text() for g in found if g.channel != channel and g.severity != NOTE]
        assert not others, others


@pytest.mark.slow
@pytest.mark.e2e
def test_a_dead_channel_stops_the_run(demo, tmp_path):
    file, channel = "sine.csv", "imu_yaw_rate"

    def freeze(ch):
        replaced(ch, channel, np.full(len(ch[channel]), ch[channel].values[0]))

    config, before, after = injected(demo[SEEDS[0]], tmp_path, file, freeze)
    f = the_one(findings(config, file)[file], "dead", channel)
    first, last = changed_span(before[channel], after[channel])
    assert f.severity == ERROR and f.t_start <= first and f.t_end >= last, f.text()


@pytest.mark.parametrize("file, pair", [
    ("sine.csv", ("wft_fl_Fz", "wft_rr_Fz")),     # the tester's: ZZ6 = -6649
    ("braking.csv", ("wft_fl_Fz", "wft_rr_Fz")),  # no lateral acceleration: the mean loads and the pitch transfer
    ("spiral.csv", ("wft_rl_Fz", "wft_rr_Fz")),   # left and right: the lateral transfer alone
])
@pytest.mark.slow
@pytest.mark.e2e
def test_two_wheel_loads_swapped_are_named(demo, tmp_path, file, pair):
    a, b = pair

    def swap(ch):
        xa, xb = ch[a].values, ch[b].values
        replaced(ch, a, xb)
        replaced(ch, b, xa)

    config, before, _ = injected(demo[SEEDS[1]], tmp_path, file, swap)
    f = the_one(findings(config, file)[file], "swapped", a)
    assert set(f.channel.split(" and ")) == {a, b} and f.severity == ERROR, f.text()
    assert f.t_start <= before[a].time[0] and f.t_end >= before[a].time[-1]


@pytest.mark.slow
@pytest.mark.e2e
def test_the_vertical_accelerometer_upside_down(demo, tmp_path):
    file = "braking.csv"
    config, *_ = injected(demo[SEEDS[0]], tmp_path, file, lambda ch: replaced(ch, "imu_az", -ch["imu_az"].values))
    f = the_one(findings(config, file)[file], "gravity", "imu_az")
    assert f.severity == ERROR and "inverted" in f.detail


def test_channel_scan_judges_each_block_alone():
    """A block at a time: a plateau and a spike in the second of two blocks are found at their times; a sensor
    held at 125 Hz on a 625 Hz clock with noise gives nothing (closed form: white noise, fixed seed)."""
    rng = np.random.default_rng(3)
    t = np.arange(12500) / 625.0
    x = 10 * np.sin(2 * np.pi * 0.5 * t) + 0.05 * rng.standard_normal(t.size)
    x = np.round(x[(np.arange(t.size) // 5) * 5] / 0.005) * 0.005  # held 5 samples, quantised
    clean = ChannelScan("x", "deg/s", resolution=0.005)
    for half in (slice(0, 6250), slice(6250, None)):
        clean.add(t[half], x[half])
    assert clean.findings() == []
    bad = x.copy()
    bad[6250:] = np.minimum(bad[6250:], 8.0)  # the second block clipped at 8
    bad[3000] += 5.0
    scan = ChannelScan("x", "deg/s", resolution=0.005)
    for half in (slice(0, 6250), slice(6250, None)):
        scan.add(t[half], bad[half])
    kinds = {f.kind: f for f in scan.findings()}
    assert set(kinds) == {"clipped", "spike"}
    clipped = np.flatnonzero(bad != x)
    clipped = clipped[clipped >= 6250]
    assert kinds["clipped"].t_start <= t[clipped[0]] and kinds["clipped"].t_end >= t[clipped[-1]]
    assert kinds["spike"].t_start == t[3000]


@pytest.mark.slow
@pytest.mark.e2e
def test_identify_stops_with_one_line_and_status_2(demo, tmp_path, capsys):
    file, channel = "lane.csv", "imu_yaw_rate"

    def freeze(ch):
        replaced(ch, channel, np.full(len(ch[channel]), 0.25))

    config, *_ = injected(demo[SEEDS[1]], tmp_path, file, freeze)
    code = main(["identify", str(config), "--out", str(tmp_path / "out")])
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("dynid: error")]
    assert code == 2 and len(errors) == 1, errors
    err = errors[0]
    assert f"data{'/'}{file}" in err.replace("\\", "/") and repr(channel) in err and "t = 0..8 s" in err, err
    assert "wiring" in err  # the fix
    assert not (tmp_path / "out" / "results.json").exists()
    with pytest.raises(ConfigError, match="data health"):
        from dynid.pipeline.run import identify

        identify(load_config(config))


@pytest.mark.slow
@pytest.mark.e2e
def test_data_health_warn_says_the_errors_and_runs_on(demo, tmp_path, capsys):
    """[identification] data_health = "warn": the same dead channel is said (and kept in results.json as an
    error), the run goes on; the stop's one line names the other errors' channels and this setting."""
    file = "lane.csv"

    def freeze(ch):
        for name in ("imu_yaw_rate", "imu_roll_rate"):
            replaced(ch, name, np.full(len(ch[name]), 0.25))

    config, *_ = injected(demo[SEEDS[1]], tmp_path, file, freeze)
    assert main(["identify", str(config), "--out", str(tmp_path / "stop")]) == 2
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("dynid: error")]
    assert len(errors) == 1, errors
    err = errors[0]
    assert "1 more error(s), on imu_" in err and 'data_health = "warn"' in err, err
    assert "imu_roll_rate" in err and "imu_yaw_rate" in err, err
    text = config.read_text()
    assert "[identification]" in text
    config.write_text(text.replace("[identification]", '[identification]\ndata_health = "warn"'))
    assert main(["identify", str(config), "--out", str(tmp_path / "warn")]) == 0
    health = json.loads((tmp_path / "warn" / "results.json").read_text())["health"]
    dead = {h["channel"] for h in health if h["kind"] == "dead" and h["severity"] == ERROR}
    assert {"imu_yaw_rate", "imu_roll_rate"} <= dead, health
    config.write_text(text.replace("[identification]", '[identification]\ndata_health = "ignore"'))
    assert main(["identify", str(config), "--out", str(tmp_path / "bad")]) == 2
    assert 'data_health = \'ignore\'; give "stop"' in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.e2e
def test_clean_files_keep_their_answer_and_list_the_notes(demo, tmp_path, monkeypatch):
    """The check reads the files beside the identification and changes nothing: the estimates with and without it
    are the same numbers; results.json carries the findings (here the lane change's camera notes)."""
    import dynid.pipeline.run as run_module

    cfg = load_config(demo[SEEDS[0]] / "identify.toml")
    checked = run_module.identify(cfg)
    monkeypatch.setattr(run_module, "check_car_tests", lambda *a: [])
    unchecked = run_module.identify(cfg)
    assert np.array_equal(checked.result.values, unchecked.result.values)
    assert np.array_equal(checked.result.std, unchecked.result.std)
    assert {(h["test"], h["channel"], h["severity"]) for h in checked.health} == {
        ("double lane change 50 km/h", "steer_fl", NOTE), ("double lane change 50 km/h", "steer_fr", NOTE)}
    run_module.write_outputs(checked, tmp_path / "out", "health")
    data = json.loads((tmp_path / "out" / "results.json").read_text())
    assert [h["channel"] for h in data["health"]] == ["steer_fl", "steer_fr"]


# ------------------------------------------------------------------------------------------------------- a robot
ROBOT_CONFIG = """[model]
example = "tx40"

[[tests]]
name = "sines"
role = "identify"
files = { q = "log.csv", tau = "log.csv" }

[channels]
q = { channels = ["q1", "q2", "q3", "q4", "q5", "q6"] }
tau = { channels = ["tau1", "tau2", "tau3", "tau4", "tau5", "tau6"] }

[conditioning]
cutoff = 20.0
order = 4
decimate = [5]

[identification]
method = "wls"
"""


def robot_log(folder, clip: float | None = None, noise: float = 0.0) -> None:
    """A TX40 on six sines for 6 s at 500 Hz, torques from its own inverse dynamics (plus white noise of `noise`
    N.m, seeded); clip: tau2 clipped at that percentile of its own values."""
    from dynid import load_model

    model = load_model("tx40")
    t = np.arange(3000) / 500.0
    q = np.stack([0.5 * np.sin(2 * np.pi * (0.3 + 0.1 * j) * t + j) for j in range(6)], axis=1)
    qd = np.gradient(q, t, axis=0)
    tau = model.inverse_dynamics(q, qd, np.gradient(qd, t, axis=0))
    tau = tau + noise * np.random.default_rng(5).standard_normal(tau.shape)
    if clip is not None:
        tau[:, 1] = np.minimum(tau[:, 1], np.percentile(tau[:, 1], clip))
    head = ",".join(["time [s]"] + [f"q{j + 1} [rad]" for j in range(6)] + [f"tau{j + 1} [N.m]" for j in range(6)])
    np.savetxt(folder / "log.csv", np.column_stack([t, q, tau]), delimiter=",", header=head, comments="",
               fmt="%.10g")
    (folder / "robot.toml").write_text(ROBOT_CONFIG)


@pytest.mark.parametrize("noise", [0.0, 0.5])
@pytest.mark.slow
@pytest.mark.e2e
def test_a_robot_torque_clipped_on_40_percent_stops_the_run(tmp_path, capsys, noise):
    """The tester's: tau2 clipped on 40 % of its samples identified with a 0.23 % residual. Now exit status 2, one
    line naming the file, tau2 and a span covering every clipped sample; the same log unclipped identifies with
    no finding (noise-free, and with 0.5 N.m of noise)."""
    clean, clipped = tmp_path / "clean", tmp_path / "clipped"
    for folder, clip in ((clean, None), (clipped, 60)):
        folder.mkdir()
        robot_log(folder, clip, noise)
    assert main(["identify", str(clean / "robot.toml"), "--out", str(clean / "out")]) == 0
    assert json.loads((clean / "out" / "results.json").read_text())["health"] == []
    capsys.readouterr()
    assert main(["identify", str(clipped / "robot.toml"), "--out", str(clipped / "out")]) == 2
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("dynid: error")]
    assert len(errors) == 1 and "log.csv" in errors[0] and "'tau2'" in errors[0], errors
    rec = read_recording(clipped / "log.csv")
    tau2 = rec.channel("tau2")
    at = tau2.time[tau2.values == tau2.values.max()]
    span = errors[0].split("), t = ")[-1].split(" s:")[0]
    t0, t1 = (float(v) for v in span.split(".."))
    assert t0 <= at[0] and t1 >= at[-1], (span, at[0], at[-1])
    assert "40" in errors[0]  # the share, in %


@pytest.mark.parametrize("fmt", ["csv", "parquet", "mat", "mf4"])
def test_stamps_going_back_stop_the_plan_in_every_format(tmp_path, fmt):
    """A logger file whose stamps go back at one sample (the tester's MDF4 was resampled at 1250 Hz instead of
    625 Hz): refused by the plan, before any segment is read, naming the file, the sample and the fix, in each
    format the car reads."""
    from dynid.io import DataError

    t = np.arange(1250) / 625.0
    t[700] = t[698]  # back by two periods
    units = VEHICLE.suite.units
    wanted = required_channels(spin=False, suite=VEHICLE.suite)
    rec = Recording.from_channels([Channel(q, units[q], np.sin(t + k), t) for k, q in enumerate(wanted)])
    path = write_recording(rec, tmp_path / f"log.{fmt}")
    config = tmp_path / "identify.toml"
    config.write_text(f'[model]\nvehicle = "peugeot406"\n\n[[tests]]\nname = "t"\nfile = "{path.name}"\n')
    cfg = load_config(config)
    with pytest.raises(DataError) as exc:
        plan_car_test(cfg, cfg.tests[0], wanted, units, None, lambda fs: 0)
    text = str(exc.value)
    assert path.name in text and "time goes back" in text and "sample 700" in text, text
    assert "Sort the rows by time" in text, text


# ------------------------------------------------------------------------------ a robot's joints against its model
def _robot_findings(folder, edit=None):
    """The robot health findings of `robot_log`'s TX40 sines with `edit(t, q, tau)` applied to the arrays first."""
    from dynid import load_model
    from dynid.pipeline.health import robot_health
    from dynid.pipeline.reduce import robot_setup
    from dynid.pipeline.sources import plan_robot_test

    folder.mkdir()
    robot_log(folder)
    if edit is not None:
        rec = read_recording(folder / "log.csv")
        t = rec.channel("q1").time
        q = np.stack([rec.channel(f"q{j}").values for j in range(1, 7)], axis=1)
        tau = np.stack([rec.channel(f"tau{j}").values for j in range(1, 7)], axis=1)
        edit(t, q, tau, load_model("tx40"))
        head = ",".join(["time [s]"] + [f"q{j} [rad]" for j in range(1, 7)] + [f"tau{j} [N.m]" for j in range(1, 7)])
        np.savetxt(folder / "log.csv", np.column_stack([t, q, tau]), delimiter=",", header=head, comments="",
                   fmt="%.10g")
    cfg = load_config(folder / "robot.toml")
    setup = robot_setup(cfg)
    return robot_health(plan_robot_test(cfg, cfg.tests[0]), cfg, setup.model, setup.joints.columns)


def _winds(t, q, tau, model) -> None:
    """Joint 6 turns on for 2.2 turns over the test, its sine on top: its speed (2.3 rad/s on average, the sine's
    2.5 rad/s) still changes sign, so its Coulomb friction is told from its offset; the torques recomputed from the
    model (the file is consistent)."""
    q[:, 5] += 2.2 * 2 * np.pi * t / t[-1]
    qd = np.gradient(q, t, axis=0)
    tau[:] = model.inverse_dynamics(q, qd, np.gradient(qd, t, axis=0))


@pytest.mark.parametrize("joint", [1, 2, 3])
def test_a_robot_torque_with_its_sign_inverted_is_named(tmp_path, joint):
    """Oracle: the log's torques are the TX40 model's own inverse dynamics on the sines; one joint's negated by hand
    (joint 1 turns about the vertical: no gravity load, only inertia and friction; 2 and 3 carry the arm's weight).
    The clean log gives no finding; the negated one an error on that channel alone, over the whole test."""
    assert _robot_findings(tmp_path / "clean") == []

    def flip(_t, _q, tau, _m):
        tau[:, joint - 1] *= -1.0

    found = _robot_findings(tmp_path / "flipped", flip)
    assert [(f.channel, f.kind, f.severity) for f in found] == [(f"tau{joint}", "sign", ERROR)], found
    assert "inverted" in found[0].detail and "negate the channel" in found[0].fix
    assert found[0].t_start == 0.0 and found[0].t_end == pytest.approx(5.998)


def test_positions_in_degrees_and_a_joint_that_turns_on(tmp_path):
    """q2 logged in degrees under [rad] (0.5 rad sines: 57 "rad" peak to peak, 9 turns) is an error naming q2 and the
    unit's fix; joint 6 turning on for 2.2 turns (its torque recomputed from the model: the file is consistent) is a
    warning only (a continuous joint), as is nothing else."""
    def degrees(_t, q, _tau, _m):
        q[:, 1] = np.degrees(q[:, 1])

    found = _robot_findings(tmp_path / "deg", degrees)
    assert [(f.channel, f.kind, f.severity) for f in found] == [("q2", "range", ERROR)], found
    assert "degrees" in found[0].detail and 'unit = "deg"' in found[0].fix

    found = _robot_findings(tmp_path / "winds", _winds)
    assert [(f.channel, f.kind, f.severity) for f in found] == [("q6", "range", WARNING)], found


@pytest.mark.slow
@pytest.mark.e2e
@pytest.mark.parametrize("case", ["winds", "flipped"])
def test_the_identification_judges_the_joints_from_its_chunks_as_a_read_of_the_file(tmp_path, capsys, case):
    """Oracle: the same judgement read from the file here (`robot_health` with the model: its own filtering and
    inverse dynamics). `dynid identify` gathers it from its chunks' rows instead: the same findings (a winding
    joint 6 listed in results.json; tau2 negated stops the run, exit 2, one line naming it)."""
    def edit(t, q, tau, model):
        if case == "flipped":
            tau[:, 1] *= -1.0
            return
        _winds(t, q, tau, model)

    folder = tmp_path / case
    read_here = [(f.channel, f.kind, f.severity) for f in _robot_findings(folder, edit)]
    code = main(["identify", str(folder / "robot.toml"), "--out", str(folder / "out")])
    err = capsys.readouterr().err
    if case == "winds":
        assert code == 0 and read_here == [("q6", "range", WARNING)], (read_here, err[-800:])
        listed = json.loads((folder / "out" / "results.json").read_text())["health"]
        assert [(d["channel"], d["kind"], d["severity"]) for d in listed] == read_here
    else:
        assert read_here == [("tau2", "sign", ERROR)]
        errors = [ln for ln in err.splitlines() if ln.startswith("dynid: error")]
        assert code == 2 and len(errors) == 1 and "'tau2'" in errors[0] and "sign is inverted" in errors[0], err


def test_a_boolean_column_for_a_continuous_quantity():
    """0s and 1s alone, in blocks merged in either order: an error for a continuous quantity (a joint's position),
    nothing for a channel not declared continuous, and nothing once one other value is seen."""
    t = np.arange(400) / 100.0
    x = (np.sin(t) > 0).astype(float)
    for continuous, tail, expect in ((True, x[200:], ["boolean"]), (False, x[200:], []),
                                     (True, np.where(x[200:] > 0, 0.5, 0.0), [])):
        a, b = ChannelScan("q3", "rad", continuous=continuous), ChannelScan("q3", "rad", continuous=continuous)
        a.add(t[:200], x[:200])
        b.add(t[200:], tail)
        for whole in (a.merge(b), b.merge(a)):
            kinds = [f.kind for f in whole.findings() if f.kind == "boolean"]
            assert kinds == expect
            if expect:
                assert whole.findings()[0].severity == ERROR and "[channels]" in whole.findings()[0].fix


def test_the_tx40_measured_files_give_no_robot_finding(tx40_data):
    """The TX40's real files (5 kHz, motor side, coupled wrist) through the example config: no finding (their
    torques follow the a priori model's with correlations of 0.83 to 0.98; the wrist spans 1.1 turns)."""
    from pathlib import Path

    from dynid.pipeline.health import robot_health
    from dynid.pipeline.reduce import robot_setup
    from dynid.pipeline.sources import plan_robot_test

    cfg = load_config(Path(__file__).resolve().parents[2] / "examples" / "tx40" / "identify.toml")
    setup = robot_setup(cfg)
    assert robot_health(plan_robot_test(cfg, cfg.tests[0]), cfg, setup.model, setup.joints.columns) == []
