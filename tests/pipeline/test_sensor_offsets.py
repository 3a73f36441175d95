"""A car config is checked against its own vehicle's sensors, and σ total carries the sensors' zero offsets by
default (issue 24, items 5 and 6).

Data: the demo's quick plan simulated once (the shipped 406's [truth]), its logger files written by the sensor
suite of the vehicle each test names, as a user's logger would write them. Oracles: the simulator's true
parameters (the sidecar the estimator never sees); for the wheel-force shortcut, the full pass through the
estimator it stands for.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dynid.pipeline.config import ConfigError, load_config
from dynid.pipeline.demo import simulate_tests, write_demo
from dynid.pipeline.run import identify, write_outputs
from dynid.vehicle.description import load_vehicle, vehicle_path

GNSS_SENSORS = "[sensors]  # a GNSS/INS instead of the paper's Correvit\ncorrevit = false\n\n[imu]"


@pytest.fixture(scope="module")
def simulated() -> dict:
    return simulate_tests(quick=True)


@pytest.fixture(scope="module")
def noisy(simulated, tmp_path_factory) -> Path:
    """The 406's quick demo files with the suite's noise and zero offsets (seed 1), and its config cut before
    [uncertainty]: a config as the tutorial writes it."""
    folder = tmp_path_factory.mktemp("noisy")
    written = write_demo(folder, simulated, seed=1)
    text = written.read_text()
    (folder / "tutorial.toml").write_text(text[:text.index("[uncertainty]")])
    return folder


def gnss_vehicle(folder: Path) -> Path:
    """The shipped 406 with a GNSS/INS instead of the Correvit (its vehicle file's [sensors])."""
    text = vehicle_path("peugeot406").read_text(encoding="utf-8")
    assert "[sensors]" not in text and text.count("\n[imu]") == 1
    path = folder / "gnss_car.toml"
    path.write_text(text.replace("[imu]", GNSS_SENSORS, 1), encoding="utf-8")
    return path


def renamed_in_kmh(csv: Path, channel: str, name: str) -> None:
    """The logger's own name for `channel` (m/s in the suite) and its values in km/h, as another logger writes."""
    lines = csv.read_text().splitlines()
    i = next(k for k, line in enumerate(lines) if not line.startswith("#"))
    head = lines[i].split(",")
    col = head.index(f"{channel} [m/s]")
    head[col] = f"{name} [km/h]"
    lines[i] = ",".join(head)
    for k in range(i + 1, len(lines)):
        cells = lines[k].split(",")
        cells[col] = repr(3.6 * float(cells[col]))
        lines[k] = ",".join(cells)
    csv.write_text("\n".join(lines) + "\n")


def estimated_errors(result) -> dict[str, float]:
    """name -> (estimate - truth) / scale for every estimated parameter (`car_scales`; else its own value)."""
    from dynid.vehicle.presentation import car_scales

    scales = car_scales(result.truth)
    return {n: (result.values[i] - result.truth[n]) / scales.get(n, abs(result.truth[n]))
            for i, n in enumerate(result.names) if n not in result.known}


@pytest.mark.slow
@pytest.mark.e2e
def test_a_gnss_vehicle_maps_its_velocity_from_a_channel_of_another_name(simulated, tmp_path):
    """A vehicle whose file says [sensors] correvit = false: its logger writes the GNSS/INS forward velocity as
    "GPS_Vel_X" in km/h; the config maps gnss_vx to it and declares its zero offset (0.03 m/s, in the suite's
    unit). The identification runs end to end on the noise-free files (the band limits, sample-and-hold and
    quantisation of the suite): every parameter within 1 % of the simulator's truth (dry friction 5 %), as the
    paper's suite gives; read as m/s, or not read, the velocity would be 3.6 times off. The declared offset alone
    is propagated, and results.json says so."""
    vehicle = gnss_vehicle(tmp_path)
    config = write_demo(tmp_path, simulated, noise=False, vehicle=str(vehicle))
    for csv in (tmp_path / "data").glob("*.csv"):
        renamed_in_kmh(csv, "gnss_vx", "GPS_Vel_X")
    text = config.read_text()
    text = text[:text.index("[uncertainty]")] + (
        '[channels]\ngnss_vx = { channel = "GPS_Vel_X", unit = "km/h" }\n\n'
        "[uncertainty]\noffsets = { gnss_vx = 0.03 }\n")
    config.write_text(text)
    run = identify(load_config(config))
    errors = estimated_errors(run.result)
    assert len(errors) == 32
    bad = {n: f"{100 * e:+.2f} %" for n, e in errors.items() if abs(e) > (0.05 if n.startswith("FS") else 0.01)}
    assert not bad, bad
    assert "GNSS/INS" in run.notes and "gnss_vx" in run.notes
    data = json.loads(write_outputs(run, tmp_path / "out", "GNSS car")[0].read_text())
    assert data["sensor_offsets"]["source"] == "config"
    assert data["sensor_offsets"]["channels"] == [{"channel": "gnss_vx", "value": 0.03, "unit": "m/s"}]
    moved = [p for p in data["parameters"] if p["std_systematic"]]
    assert moved and all(p["main_offset"].endswith(": gnss_vx") for p in moved)


@pytest.mark.parametrize("section, words", [
    ('[channels]\ncorrevit_vx = { channel = "Vx" }', ["[channels]", "'correvit_vx'", "has no such sensor",
                                                       "correvit = false", "map 'gnss_vx' instead"]),
    ("[uncertainty]\noffsets = { correvit_vy = 0.075 }", ["[uncertainty]", "'correvit_vy'", "has no such sensor",
                                                          "map 'gnss_vy' instead"]),
    ('[channels]\ngnss_vz = { channel = "Vz" }', ["[channels]", "unknown channel 'gnss_vz'",
                                                  "did you mean 'gnss_vy'?"]),
])
def test_a_channel_the_vehicle_has_not_is_refused(tmp_path, section, words):
    """[channels] and [uncertainty] name the channels of the vehicle the config names: the paper's Correvit on a
    GNSS/INS car is refused, saying the vehicle has no such sensor and what it has instead; a misspelt channel
    names the nearest of that vehicle's channels."""
    gnss_vehicle(tmp_path)
    (tmp_path / "sine.csv").write_text("time\n0\n")
    cfg = tmp_path / "identify.toml"
    cfg.write_text(f'[model]\nvehicle = "gnss_car.toml"\n\n[[tests]]\nfile = "sine.csv"\n\n{section}\n')
    with pytest.raises(ConfigError) as exc:
        load_config(cfg)
    assert str(exc.value).startswith(f"{cfg}: ")
    for w in words:
        assert w in str(exc.value), (w, str(exc.value))


@pytest.mark.slow
@pytest.mark.e2e
def test_without_uncertainty_the_vehicle_suites_offsets_make_sigma_total(noisy, tmp_path):
    """The tutorial's config (no [uncertainty]) on the simulated 406 with the suite's noise and zero offsets:
    σ total carries the 406's sensor suite's zero offsets (every channel with a `bias`), names them and their
    source, is above σ for every estimated parameter, and covers the simulator's truth within 3 σ total more
    often than σ alone does (seed 1: 32 of 32 against 19 of 32)."""
    run = identify(load_config(noisy / "tutorial.toml"))
    r = run.result
    suite = load_vehicle("peugeot406").suite
    assert run.offsets["source"] == "vehicle"
    assert {c["channel"]: c["value"] for c in run.offsets["channels"]} == {c.name: c.bias for c in suite if c.bias}
    assert "from the vehicle's sensor suite" in run.notes
    est = [i for i, n in enumerate(r.names) if n not in r.known]
    assert np.all(r.std_total[est] > r.std[est])
    err = np.abs(r.values[est] - np.array([r.truth[r.names[i]] for i in est]))
    within_total, within_std = int(np.sum(err <= 3 * r.std_total[est])), int(np.sum(err <= 3 * r.std[est]))
    print(json.dumps({"within_3_sigma_total": within_total, "within_3_sigma": within_std, "of": len(est)}))
    assert within_total > within_std and within_total >= 0.9 * len(est)
    html = (write_outputs(run, tmp_path / "out", "406")[-1]).read_text()
    assert "Sensor zero offsets in σ total" in html and "vehicle&#x27;s sensor suite" in html
    assert "wft_rl_Fz" in html


@pytest.mark.parametrize("uncertainty, source, channels", [
    ("offsets = { imu_az = 0.02, wft_fl_Fz = 10.0 }", "config", {"imu_az", "wft_fl_Fz"}),
    ('offsets = "none"', "none", set()),
    ("offsets = {}", "none", set()),
])
@pytest.mark.slow
@pytest.mark.e2e
def test_explicit_offsets_replace_the_suites_and_none_turns_them_off(noisy, uncertainty, source, channels):
    """[uncertainty] offsets = { ... } replaces the vehicle suite's (only those channels move the estimates);
    offsets = "none", or an empty table, propagates none: σ total is σ."""
    cfg = noisy / f"offsets_{source}.toml"
    cfg.write_text((noisy / "tutorial.toml").read_text() + f"[uncertainty]\n{uncertainty}\n")
    run = identify(load_config(cfg))
    r = run.result
    assert run.offsets["source"] == source
    assert {c["channel"] for c in run.offsets["channels"]} == channels
    if channels:
        mains = {r.systematic.main_source(n).split(": ")[-1] for n in r.systematic.names}
        assert mains <= channels and r.systematic is not None
    else:
        assert r.systematic is None and np.array_equal(r.std_total, r.std)
        assert "No sensor zero offsets propagated" in run.notes


@pytest.mark.slow
@pytest.mark.e2e
def test_a_wheel_force_offset_moves_the_loads_alone(noisy):
    """The wheel-force channels' offsets are propagated without re-estimating the joints (`CarSetup.load_only`),
    the others' without undoing the sensor dynamics again (`CarSetup.compensated`): the rows' change equals the
    full pass through the estimator with the channel moved (to round-off)."""
    from dynid.pipeline.reduce import car_setup, shifted_load
    from dynid.pipeline.sources import plan_car_test, segment_window
    from dynid.signals import border_samples
    from dynid.vehicle.estimate import required_channels

    cfg = load_config(noisy / "tutorial.toml")
    setup = car_setup(cfg)
    suite, cond = setup.vehicle.suite, setup.conditioning
    plan = plan_car_test(cfg, cfg.tests[0], required_channels(suite=suite), suite.units, None,
                         lambda fs: border_samples(fs, cond.cutoff, cond.order))
    w = segment_window(plan, 0, plan.samples)
    channels = w.read()
    traj = setup.trajectory(channels, w.fs)
    sys = setup.rows(traj, w.fs)
    for q, b in (("wft_fl_Fz", 10.0), ("wft_rr_Mx", 2.0), ("wft_rl_Fy", 10.0)):
        assert setup.load_only(q)
        short = setup.rows(shifted_load(traj, q, b), w.fs, keep=sys.kept)
        full = setup.rows(setup.trajectory({**channels, q: channels[q] + b}, w.fs), w.fs, keep=sys.kept)
        dY, dY_full = short.Y - sys.Y, full.Y - sys.Y
        assert np.abs(dY_full).max() > 1e-3 * b  # the offset moves the equations
        assert np.abs(dY - dY_full).max() <= 1e-9 * np.abs(dY_full).max(), q
        assert np.abs(short.W - full.W).max() <= 1e-9 * np.abs(sys.W).max(), q
    assert not any(setup.load_only(q) for q in ("imu_az", "laser_height_rl", "clearance_fl"))
    # the other channels' offsets go through the joints, but not through the sensor dynamics' undoing again:
    # it is affine with unit gain at 0 Hz (the reversed Butterworth from its steady state, a shift), so the
    # moved channel's undone values are the undone channel plus the offset; the same rows as the full pass
    compensated = setup.compensated(channels, w.fs)
    for q, b in (("imu_az", 0.01), ("imu_roll", 0.05 * np.pi / 180), ("laser_height_rl", 5e-4)):
        moved = {**channels, q: channels[q] + b}
        short = setup.rows(setup.trajectory(moved, w.fs, None, {**compensated, q: compensated[q] + b}), w.fs,
                           keep=sys.kept)
        full = setup.rows(setup.trajectory(moved, w.fs), w.fs, keep=sys.kept)
        # round-off of the rows' own scale (1e-12 of it: the filters' sums over thousands of samples), and an
        # offset whose effect stands a thousand times above it (a laser's moves the tire rows' W only)
        roundoff = 1e-12 * max(np.abs(full.Y).max(), np.abs(full.W).max())
        assert max(np.abs(full.Y - sys.Y).max(), np.abs(full.W - sys.W).max()) > 1e3 * roundoff, q
        assert max(np.abs(short.Y - full.Y).max(), np.abs(short.W - full.W).max()) <= roundoff, q


def test_without_height_lasers_a_vertical_wheel_force_moves_the_joints(tmp_path):
    """A car without height lasers takes its heights from the vertical wheel loads: the vertical force's offset
    goes through the full estimator, the other wheel-force components still move the loads alone."""
    from dynid.pipeline.reduce import car_setup

    assert not load_vehicle("compact_suv").lasers
    (tmp_path / "sine.csv").write_text("time\n0\n")
    cfg = tmp_path / "identify.toml"
    cfg.write_text('[model]\nvehicle = "compact_suv"\n\n[[tests]]\nfile = "sine.csv"\n')
    setup = car_setup(load_config(cfg))
    assert not setup.load_only("wft_fl_Fz") and setup.load_only("wft_fl_Fx") and setup.load_only("wft_rr_Mz")
