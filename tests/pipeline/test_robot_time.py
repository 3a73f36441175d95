"""Robot tests from logger files with time stamps (issue 14, item 1).

Oracle: q is a smooth Fourier trajectory, tau the model's own inverse dynamics at the instants the
samples were taken (true parameters: the shipped puma560's) plus white noise of known sigma. A log
whose stamps have jitter, holes and repeated rows samples the same motion at other instants: its
estimates must equal those of the clean uniform log within the noise (3 sigma of the estimate).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import dynid
from dynid.cli.main import main
from dynid.pipeline.config import ConfigError, load_config
from dynid.pipeline.run import identify

FS = 1000.0
DURATION = 24.0
SIGMA_TAU = 0.05  # N.m, the noise added to the torques
JOINTS = [f"j{i}" for i in range(1, 7)]

CONFIG = """
[model]
example = "puma560"

[[tests]]
name = "t"
{extra}
files = {{ q = "{q}", tau = "{tau}" }}

[channels]
q = {{ channels = ["j1", "j2", "j3", "j4", "j5", "j6"], unit = "rad" }}
tau = {{ channels = {tau_channels}, unit = "N.m" }}

[conditioning]
cutoff = 20.0
decimate = [10, 5]
"""
TAU_IN_ONE = '["tau1", "tau2", "tau3", "tau4", "tau5", "tau6"]'


def fourier(t: np.ndarray, seed: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q, qd, qdd (N, 6) of a 5-harmonic finite Fourier series at a 0.1 Hz base frequency."""
    rng = np.random.default_rng(seed)
    w = 2 * np.pi * 0.1 * np.arange(1, 6)
    a, b = rng.normal(0, 0.25, (2, 6, 5)) / np.arange(1, 6)
    q0 = rng.uniform(-0.5, 0.5, 6)
    s, c = np.sin(np.multiply.outer(t, w)), np.cos(np.multiply.outer(t, w))  # (N, 5)
    q = q0 + s @ a.T + c @ b.T
    qd = (c * w) @ a.T - (s * w) @ b.T
    qdd = -(s * w**2) @ a.T - (c * w**2) @ b.T
    return q, qd, qdd


def torques(model, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    q, qd, qdd = fourier(t)
    return q, model.inverse_dynamics(q, qd, qdd)


def write(path: Path, t: np.ndarray | None, columns: dict[str, np.ndarray]) -> Path:
    names = ([] if t is None else ["time"]) + list(columns)
    data = np.column_stack(([] if t is None else [t]) + list(columns.values()))
    np.savetxt(path, data, delimiter=",", header=",".join(names), comments="", fmt="%.12g")
    return path


def qtau(q: np.ndarray, tau: np.ndarray) -> dict[str, np.ndarray]:
    return {**{f"j{i + 1}": q[:, i] for i in range(6)}, **{f"tau{i + 1}": tau[:, i] for i in range(6)}}


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """The clean 1 kHz log in several layouts, and an irregular log of the same motion and noise."""
    d = tmp_path_factory.mktemp("logs")
    model = dynid.load_model("puma560")
    n = int(DURATION * FS)
    k = np.arange(n)
    t = k / FS
    noise = np.random.default_rng(7).normal(0, SIGMA_TAU, (n, 6))
    q, tau = torques(model, t)
    tau = tau + noise
    write(d / "clean.csv", t, qtau(q, tau))
    write(d / "q.csv", t, dict(zip(JOINTS, q.T, strict=True)))
    write(d / "tau.csv", t, {f"tau{i + 1}": tau[:, i] for i in range(6)})
    write(d / "no_time.csv", None, qtau(q, tau))
    cut = (t >= 3.0) & (t <= 20.0)
    write(d / "cut.csv", t[cut], qtau(q[cut], tau[cut]))

    # the same samples as a real logger writes them: stamps jittered by up to 0.1 ms, holes of up to 8
    # missing samples (9 ms between stamps), some rows written twice
    rng = np.random.default_rng(11)
    keep = np.ones(n, bool)
    holes = rng.choice(np.arange(100, n - 100), 40, replace=False)
    for i, h in enumerate(holes):
        keep[h:h + (8 if i % 4 == 0 else rng.integers(1, 5))] = False
    stamp = t + rng.uniform(-1e-4, 1e-4, n)
    qj, tauj = torques(model, stamp)  # the motion at the instants the samples were taken
    tauj = tauj + noise
    idx = np.flatnonzero(keep)
    twice = np.sort(rng.choice(idx[10:-10], 30, replace=False))
    rows = np.sort(np.concatenate([idx, twice]))
    write(d / "jitter.csv", stamp[rows], qtau(qj[rows], tauj[rows]))
    gaps = np.diff(stamp[idx])
    return d, {"repeated": twice.size, "largest_gap": float(gaps.max()), "truth": model}


def config(d: Path, name: str, *, q: str, tau: str | None = None, extra: str = "") -> Path:
    path = d / f"{name}.toml"
    tau_channels = TAU_IN_ONE
    path.write_text(CONFIG.format(q=d / q, tau=d / (tau or q), extra=extra, tau_channels=tau_channels))
    return path


def estimate(path: Path) -> tuple[np.ndarray, np.ndarray, list[str]]:
    said: list[str] = []
    run = identify(load_config(path), progress=said.append)
    return run.result.values, run.result.std, said


@pytest.fixture(scope="module")
def clean(logs):
    d, _ = logs
    return estimate(config(d, "no_time", q="no_time.csv", extra="fs = 1000.0"))


def test_clean_log_recovers_the_true_parameters(logs, clean):
    _, info = logs
    model = info["truth"]
    values, std, _ = clean
    truth = model.base_parameters().values(model.parameters)
    z = np.abs(values - truth) / std
    assert np.max(z) < 4.5, (np.max(z), np.argmax(z))


@pytest.mark.parametrize("q, tau, extra", [
    ("clean.csv", None, ""),                       # q and tau in one file with its time column, no fs
    ("clean.csv", None, "fs = 1000.0"),            # one file, fs agreeing with the time column
    ("q.csv", "tau.csv", "fs = 1000.0"),           # two files with time columns, fs in the config
    ("q.csv", "tau.csv", ""),                      # two files, no fs
])
@pytest.mark.slow
@pytest.mark.e2e
def test_every_time_column_layout_gives_the_estimate_of_the_plain_file(logs, clean, q, tau, extra):
    d, _ = logs
    values, _, said = estimate(config(d, "layout", q=q, tau=tau, extra=extra))
    np.testing.assert_allclose(values, clean[0], rtol=1e-9, atol=1e-12)
    assert any("time column, 24000 samples at 1000 Hz; 0 repeated" in s for s in said), said


def test_irregular_stamps_are_resampled_and_reported(logs, clean):
    d, info = logs
    values, _, said = estimate(config(d, "jitter", q="jitter.csv"))
    z = np.abs(values - clean[0]) / clean[1]
    assert np.max(z) < 3.0, (np.max(z), np.argmax(z))
    text = next(s for s in said if "jitter.csv" in s and "repeated" in s)
    assert f"{info['repeated']} repeated row(s)" in text
    gap = float(re.search(r"largest gap ([0-9.]+) ms", text).group(1))
    assert gap == pytest.approx(info["largest_gap"] * 1e3, rel=1e-3) and 8.8 < gap < 9.2
    rms = float(re.search(r"jitter ([0-9.e-]+) ms RMS", text).group(1))
    assert rms == pytest.approx(0.1 / np.sqrt(3), rel=0.1)  # uniform on +-0.1 ms
    assert "resampled onto a uniform clock" in text


@pytest.mark.slow
@pytest.mark.e2e
def test_start_and_end_give_the_estimate_of_a_file_cut_by_hand(logs):
    d, _ = logs
    windowed = estimate(config(d, "window", q="clean.csv", extra="start = 3.0\nend = 20.0"))[0]
    by_hand = estimate(config(d, "cut", q="cut.csv"))[0]
    np.testing.assert_allclose(windowed, by_hand, rtol=1e-9, atol=1e-12)


def cli_error(cfg: Path, capsys) -> str:
    rc = main(["identify", str(cfg), "--out", str(cfg.parent / "out")])
    err = capsys.readouterr().err
    last = err.strip().splitlines()[-1]
    assert rc == 2 and last.startswith("dynid: error:") and "Traceback" not in err, err
    return last


def test_time_going_back_is_one_line_naming_file_and_sample(tmp_path, capsys):
    model = dynid.load_model("puma560")
    t = np.arange(4000) / FS
    q, tau = torques(model, t)
    t[2500] = t[2498]  # goes back
    write(tmp_path / "back.csv", t, qtau(q, tau))
    last = cli_error(config(tmp_path, "back", q="back.csv"), capsys)
    assert "back.csv" in last and "sample 2500" in last and "line 2502" in last and "goes back" in last
    assert "sort the rows" in last.lower()


@pytest.mark.slow
@pytest.mark.e2e
def test_a_long_hole_is_one_line_naming_file_and_sample(tmp_path, capsys):
    model = dynid.load_model("puma560")
    t = np.arange(6000) / FS
    q, tau = torques(model, t)
    keep = np.ones(t.size, bool)
    keep[3000:3020] = False  # 21 ms without a sample
    write(tmp_path / "hole.csv", t[keep], qtau(q[keep], tau[keep]))
    last = cli_error(config(tmp_path, "hole", q="hole.csv"), capsys)
    assert "hole.csv" in last and "sample 3000" in last and "t = 3.02 s" in last and "max_gap = 10" in last
    # the fix works: a larger max_gap, or a window that leaves the hole out
    for extra in ("max_gap = 25", "start = 3.1"):
        assert main(["identify", str(config(tmp_path, "fixed", q="hole.csv", extra=extra)),
                     "--out", str(tmp_path / "out")]) == 0


def test_fs_disagreeing_with_the_time_column_names_both(logs, capsys):
    d, _ = logs
    last = cli_error(config(d, "disagree", q="clean.csv", extra="fs = 500.0"), capsys)
    assert "500 Hz" in last and "1000 Hz" in last and "clean.csv" in last and "remove fs" in last


def test_files_that_do_not_overlap_are_refused(tmp_path, capsys):
    model = dynid.load_model("puma560")
    t = np.arange(3000) / FS
    q, tau = torques(model, t)
    write(tmp_path / "q.csv", t, dict(zip(JOINTS, q.T, strict=True)))
    write(tmp_path / "tau.csv", t + 10.0, {f"tau{i + 1}": tau[:, i] for i in range(6)})
    last = cli_error(config(tmp_path, "apart", q="q.csv", tau="tau.csv"), capsys)
    assert "do not overlap" in last and "q.csv" in last and "tau.csv" in last


@pytest.mark.slow
@pytest.mark.e2e
def test_tau_on_its_own_clock_is_interpolated_onto_q(logs, clean, tmp_path):
    """tau logged by another clock (500 Hz, 0.37 ms late, starting later): same estimate within the noise."""
    d, info = logs
    model = info["truth"]
    t = np.arange(int(DURATION * 500)) / 500 + 0.00037 + 1.0
    t = t[t < DURATION]
    _, tau = torques(model, t)
    tau += np.random.default_rng(5).normal(0, SIGMA_TAU, tau.shape)
    write(tmp_path / "tau500.csv", t, {f"tau{i + 1}": tau[:, i] for i in range(6)})
    path = config(tmp_path, "two_clocks", q=str(d / "q.csv"), tau="tau500.csv")
    values, std, said = estimate(path)
    assert any("overlap over 1.00037" in s for s in said), said
    truth = model.base_parameters().values(model.parameters)
    z = np.abs(values - truth) / std  # its own noise (half the samples of tau): against the truth
    assert np.max(z) < 4.5, (np.max(z), np.argmax(z))


@pytest.mark.parametrize("extra, words", [
    ("start = 5.0\nend = 2.0", ["start = 5.0", "not before end"]),
    ('start = "a"', ["start = 'a'", "a number"]),
    ("end = true", ["end = True"]),
    ("max_gap = 0.5", ["max_gap = 0.5", ">= 1"]),
    ("stop = 3.0", ["unknown key", "stop"]),
])
def test_bad_window_keys_are_named(logs, extra, words):
    d, _ = logs
    with pytest.raises(ConfigError) as exc:
        load_config(config(d, "bad", q="clean.csv", extra=extra))
    for w in words:
        assert w in str(exc.value), (w, str(exc.value))


def test_a_window_outside_the_record_is_refused(logs, capsys):
    d, _ = logs
    last = cli_error(config(d, "outside", q="clean.csv", extra="end = 30.0"), capsys)
    assert "end = 30 s is outside the record" in last and "0..23.999 s" in last


def _stamps_over_blocks() -> tuple[np.ndarray, np.ndarray]:
    """Stamps t0 + h slot + jitter over three and a bit of `timebase.BLOCK` steps, with holes of 2 and 3 periods in
    different blocks (one on a block's edge): (t, slots)."""
    from dynid.pipeline.timebase import BLOCK

    h, n = 2e-3, 3 * BLOCK + 123
    slots = np.arange(n, dtype=float)
    for at, extra in ((1000, 1.0), (BLOCK, 2.0), (2 * BLOCK + 77, 1.0)):
        slots[at:] += extra
    rng = np.random.default_rng(25)
    return 4.5 + h * slots + rng.uniform(-0.05, 0.05, n) * h, slots


def test_the_clock_fitted_over_blocks_is_the_least_squares_line_of_the_stamps():
    # oracle: the stamps' own construction (their slots) and NumPy's least-squares line through them (polyfit).
    # Error bound: every n-term sum is within n eps of exact (n = 2e5: 4e-11 relative), so h to 1e-10 relative and
    # t0 and the jitter to s_mean dh + eps t < 1e-8 s (the jitter itself is 1e-4 s)
    from dynid.io import Channel
    from dynid.pipeline.timebase import stream

    t, slots = _stamps_over_blocks()
    s = stream([Channel("time", "s", t, t)], "f.csv", True, 5.0)
    h_ls, t0_ls = np.polyfit(slots, t, 1)
    jitter = t - (t0_ls + h_ls * slots)
    assert s.h == pytest.approx(h_ls, rel=1e-10) and s.t0 == pytest.approx(t0_ls, abs=1e-8)
    assert s.jitter_max == pytest.approx(np.abs(jitter).max(), abs=1e-8)
    assert s.jitter_rms == pytest.approx(np.sqrt(np.mean(jitter**2)), abs=1e-8)
    assert s.largest_gap == np.diff(t).max() and not s.uniform and s.repeated == 0  # holes: resampled
    assert np.array_equal(s.t, t)


def test_holes_in_several_blocks_name_the_first_and_count_them_all():
    from dynid.io import Channel, GapError
    from dynid.pipeline.timebase import stream

    t, _ = _stamps_over_blocks()
    with pytest.raises(GapError, match=r"sample 1000 .*over max_gap = 1.5 \(3 such gap\(s\) in all\)"):
        stream([Channel("time", "s", t, t)], "f.csv", True, 1.5)  # holes of 2, 3 and 2 periods (jitter 0.1)


def test_a_parquet_clock_stays_in_the_file_and_gives_the_estimate_of_the_held_clock(logs, tmp_path):
    """The plan keeps a Parquet file's clock as rows of the file (`sources.FileClock`), read back a window at a
    time. Oracles: pyarrow's own read of the time column, cut to start..end by hand (the windows' stamps, bit for
    bit); and the run on the same rows as CSV, whose clock the plan holds (the estimate to the last bit)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from dynid.pipeline.sources import FileClock, clock_read, clock_window, plan_robot_test

    d, _ = logs
    clean = np.loadtxt(d / "clean.csv", delimiter=",", skiprows=1)
    names = ["time", *(f"j{i + 1}" for i in range(6)), *(f"tau{i + 1}" for i in range(6))]
    pq.write_table(pa.table({n: clean[:, i] for i, n in enumerate(names)}), tmp_path / "clean.parquet",
                   row_group_size=4000)  # six row groups: windows across their edges
    window = "start = 2.5\nend = 20.0"
    cfg = load_config(config(d, "pq", q=str(tmp_path / "clean.parquet"), extra=window))
    plan = plan_robot_test(cfg, cfg.tests[0])
    t = pq.read_table(tmp_path / "clean.parquet", columns=["time"]).column(0).to_numpy()
    t = t[(t >= 2.5) & (t <= 20.0)]
    assert isinstance(plan.clock, FileClock) and plan.samples == t.size
    assert plan.clock[0] == t[0] and plan.clock[-1] == t[-1]
    for lo, hi in ((0, t.size), (3990, 4017), (1500, 9000), (t.size - 7, t.size)):
        w = clock_read(clock_window(plan, lo, hi))
        assert w.first == lo and np.array_equal(w.clock, t[lo:hi])
    on_file = estimate(config(d, "pq", q=str(tmp_path / "clean.parquet"), extra=window))
    held = estimate(config(d, "csv", q="clean.csv", extra=window))
    assert np.array_equal(on_file[0], held[0]) and np.array_equal(on_file[1], held[1])
