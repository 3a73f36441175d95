"""`dynid identify` on bad configs: one clear line naming the file and key, and nothing half-written."""

from pathlib import Path

import numpy as np
import pytest

from dynid.cli.main import main

GOOD = """
[model]
example = "puma560"

[[tests]]
name = "t"
fs = 200.0
files = {{ q = "{q}", tau = "{tau}" }}

[channels]
q = {{ channels = ["j1", "j2", "j3", "j4", "j5", "j6"], unit = "rad" }}
tau = {{ channels = ["j1", "j2", "j3", "j4", "j5", "j6"], unit = "N.m" }}

[conditioning]
cutoff = 10.0
decimate = [2]
"""


@pytest.fixture
def files(tmp_path: Path):
    """Joint positions and the torques the engine computes for them: a consistent robot test."""
    import dynid

    m = dynid.load_model("puma560")
    t = np.arange(0, 6, 1 / 200.0)
    rng = np.random.default_rng(0)
    a, w, p = rng.uniform(0.3, 1, 6), rng.uniform(0.5, 2, 6), rng.uniform(0, 6, 6)
    q = a * np.sin(np.outer(t, w) + p)
    qd = a * w * np.cos(np.outer(t, w) + p)
    qdd = -a * w**2 * np.sin(np.outer(t, w) + p)
    tau = m.inverse_dynamics(q, qd, qdd)
    head = ",".join(f"j{i}" for i in range(1, 7))
    np.savetxt(tmp_path / "q.csv", q, delimiter=",", header=head, comments="")
    np.savetxt(tmp_path / "tau.csv", tau, delimiter=",", header=head, comments="")
    return tmp_path


def run(tmp_path: Path, text: str, capsys, out: str = "out", q: str = "q.csv") -> tuple[int, str, str]:
    cfg = tmp_path / "identify.toml"
    cfg.write_text(text.format(q=tmp_path / q, tau=tmp_path / "tau.csv"))
    rc = main(["identify", str(cfg), "--out", str(tmp_path / out)])
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def test_a_consistent_robot_test_is_identified(files, capsys):
    rc, out, err = run(files, GOOD, capsys)
    assert rc == 0, err
    assert (files / "out" / "report.html").exists() and (files / "out" / "results.json").exists()
    assert "joint1" in out


def test_missing_file_is_named(files, capsys):
    rc, _, err = run(files, GOOD, capsys, q="nope.csv")
    assert rc == 2 and "identify.toml" in err and "not found" in err and "nope.csv" in err
    assert not (files / "out").exists()


@pytest.mark.parametrize("change, words", [
    (('"j6"], unit = "rad"', '"j7"], unit = "rad"'), ["q.csv", "j7", "j1, j2, j3, j4, j5, j6"]),
    (("[conditioning]", "[identification]\nmethod = \"lasso\"\n[conditioning]"), ["method", "lasso"]),
    (("[conditioning]", "[identification]\nmethod = \"iv\"\n[conditioning]"), ["method", "iv", "robot", "wls"]),
    (("[conditioning]", "[identification]\nknown = {{ ZZ9 = 1.0 }}\n[conditioning]"), ["ZZ9", "base parameters"]),
    (("cutoff = 10.0", "cutoff = 150.0"), ["Nyquist", "100 Hz"]),
])
def test_bad_configs_fail_with_one_clear_line(files, capsys, change, words):
    rc, _, err = run(files, GOOD.replace(*change), capsys)
    last = err.strip().splitlines()[-1]  # progress lines come first
    assert rc == 2 and last.startswith("dynid: error:") and "Traceback" not in err
    for w in words:
        assert w in err, (w, err)
    assert not (files / "out" / "results.json").exists()  # nothing half-written


CAR = """
[model]
template = "peugeot406"

[[tests]]
file = "sine.csv"

[uncertainty]
{uncertainty}
"""


@pytest.mark.parametrize("uncertainty, words", [
    ('offsets = { imu_azz = 0.01 }', ["[uncertainty]", "'imu_azz'", "imu_az"]),
    ('offsets = { imu_az = -0.01 }', ["[uncertainty]", "imu_az", ">= 0"]),
    ('offsets = { imu_az = "a lot" }', ["[uncertainty]", "imu_az"]),
    ('offsets = { imu_az = 0.01 }\nsegments = 0', ["[uncertainty]", "segments", ">= 1"]),
    ('offset = { imu_az = 0.01 }', ["[uncertainty]", "unknown key", "offset"]),
])
def test_sensor_offset_declarations_are_checked(tmp_path, uncertainty, words):
    from dynid.pipeline.config import ConfigError, load_config

    (tmp_path / "sine.csv").write_text("time\n0\n")
    cfg = tmp_path / "identify.toml"
    cfg.write_text(CAR.format(uncertainty=uncertainty))
    with pytest.raises(ConfigError) as exc:
        load_config(cfg)
    for w in words:
        assert w in str(exc.value), (w, str(exc.value))
    cfg.write_text(CAR.format(uncertainty='offsets = { imu_az = 0.01, laser_height_rl = 0.5 }\nsegments = 3'))
    settings = load_config(cfg).car
    assert settings.offsets == {"imu_az": 0.01, "laser_height_rl": 0.5} and settings.offset_segments == 3


def test_sensor_offsets_are_for_the_car_only(files, capsys):
    rc, _, err = run(files, GOOD + "\n[uncertainty]\noffsets = {{ j1 = 0.01 }}\n", capsys)
    assert rc == 2 and "[uncertainty]" in err and "car template only" in err


CAR_OPTIONS = """
[model]
template = "peugeot406"

[[tests]]
file = "sine.csv"

[conditioning]
{conditioning}

[identification]
{identification}
"""


@pytest.mark.parametrize("conditioning, identification, words", [
    ('min_speed = "fast"', "", ["[conditioning]", "min_speed", "m/s"]),
    ("min_speed = { 10 = 0.01 }", "", ["[conditioning]", "min_speed", "10", "9, 18, 27, 36"]),
    ("min_speed = { 9 = -0.01 }", "", ["[conditioning]", "min_speed", ">= 0"]),
    ("compensate_delays = 1", "", ["[conditioning]", "compensate_delays", "true or false"]),
    ("", "flag_percent = 0", ["[identification]", "flag_percent", "positive"]),
    ("", 'flag_percent = "5 %"', ["[identification]", "flag_percent", "positive"]),
    ("", 'method = "iv"\niv_passes = 0', ["[identification]", "iv_passes", "1 to 10"]),
    ("", 'method = "iv"\niv_passes = 1.5', ["[identification]", "iv_passes", "whole number"]),
])
def test_car_conditioning_options_are_checked(tmp_path, conditioning, identification, words):
    from dynid.pipeline.config import ConfigError, load_config

    (tmp_path / "sine.csv").write_text("time\n0\n")
    cfg = tmp_path / "identify.toml"
    cfg.write_text(CAR_OPTIONS.format(conditioning=conditioning, identification=identification))
    with pytest.raises(ConfigError) as exc:
        load_config(cfg)
    for w in words:
        assert w in str(exc.value), (w, str(exc.value))
    cfg.write_text(CAR_OPTIONS.format(conditioning="min_speed = { 9 = 0.02, 27 = 0 }\ncompensate_delays = false",
                                      identification='flag_percent = 4\nmethod = "iv"\niv_passes = 3'))
    c = load_config(cfg)
    assert c.car.min_speed == {9: 0.02, 27: 0.0} and not c.car.compensate_delays and c.flag_percent == 4.0
    assert c.method == "iv" and c.car.iv_passes == 3
    cfg.write_text(CAR_OPTIONS.format(conditioning="", identification=""))
    c = load_config(cfg)
    assert c.car.min_speed == {9: 0.01, 18: 0.01, 27: 0.01, 36: 0.01} and c.car.compensate_delays
