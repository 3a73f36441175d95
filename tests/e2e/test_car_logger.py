"""Car logger files as real loggers write them (issue "Your car", item 5): a start..end window, irregular time
stamps (jitter, repeated rows, short gaps), channels at several rates in one MDF4 file.

Data: the demo's six simulated tests (`simulate_tests(quick=True)`), written without noise. Oracles:

- window: the same rows cut out of the CSV file by hand (its text lines), to 1e-9 relative;
- jitter, repeated rows, gaps: the estimates of the clean files of the same truth. The truth is made
  band-limited first (every channel low-passed at B = 20 Hz, zero phase: a logger's anti-alias filter;
  the suite's 125 Hz holds are not band-limited), so that its value at any instant is defined; the
  irregular file samples it (its cubic spline) at the jittered instants;
- several rates: the estimates of the single-rate file of the same band-limited truth.

Tolerances. A resampled channel errs by the cubic spline's error, at most 5/384 S^4 |x''''| for nodes S apart
(taken x 2 for the splines' ends and the truth's own spline). That is a small additive error on the channel, as
the sensor's noise is, and goes through the identification as the noise does: errors of RMS rho times the
noise's part in the identification's band (cutoff fc: accuracy x sqrt(2 fc / sensor rate) for white noise at
the sensor's rate; the errors are all counted as in the band) move each estimate by about rho times its
standard deviation under that noise, sigma_noise (the WLS sigma of the same tests written with the suite's
noise): 3 rho sigma_noise, rho the largest over the channels and tests. Jittered stamps add the error of the
clock fitted to them (a least-squares line): its offset moves every channel together, which a time-invariant
model does not see; its rate, off by eps, rescales time, and a parameter of dimension T^k (|k| <= 2: masses
and inertias k = 2, damping 1, stiffness 0) by (1 + eps)^k: 2 eps |X| more.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import CubicSpline
from scipy.signal import butter, sosfiltfilt

from dynid.io import DataError, GapError, TimeBaseError
from dynid.pipeline.config import ConfigError, load_config
from dynid.pipeline.run import identify, load_car_channels

# Every test identifies the quick demo's car from re-timed logger files (about 25 s in all).
pytestmark = [pytest.mark.slow, pytest.mark.e2e]

FS = 625.0  # the demo's logger
H = 1 / FS
B = 20.0  # Hz: the band limit of the truth
SPLINE = 5 / 384  # the cubic spline's error constant
JITTER = 0.1 * H  # the stamps' jitter: uniform on +-JITTER


def read(path: Path) -> tuple[list[str], np.ndarray]:
    """A demo CSV: its header lines (comments, names with units) and its rows (time first)."""
    lines = path.read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    return lines[:k + 1], np.loadtxt(lines[k + 1:], delimiter=",", ndmin=2)


def write(path: Path, head: list[str], rows: np.ndarray) -> Path:
    np.savetxt(path, rows, delimiter=",", fmt="%.17g", header="\n".join(head), comments="")
    return path


def with_tests(config: Path, out: Path, extra: dict[str, str] | None = None, ext: str = "csv",
               name: str = "identify.toml") -> Path:
    """The config, written as `out`/`name`: each test's file in `out`/data (extension `ext`), `extra[key]` lines
    added to the test of file `key`."""
    text = config.read_text()
    for key in re.findall(r'file = "data/(\w+)\.csv"', text):
        text = text.replace(f'file = "data/{key}.csv"', f'file = "data/{key}.{ext}"\n' + (extra or {}).get(key, ""))
    text = re.sub(r"offsets = \{[^}]*\}", "offsets = {  }", text)  # the offsets' propagation: not needed here
    text = re.sub(r'truth = "[^"]*"\n', "", text)  # nor the sidecar's true values
    path = out / name
    path.write_text(text)
    return path


def values(config: Path) -> np.ndarray:
    return identify(load_config(config)).result.values


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    from dynid.pipeline.demo import simulate_tests, write_demo

    tests = simulate_tests(quick=True)
    out = tmp_path_factory.mktemp("demo")
    noisy = tmp_path_factory.mktemp("noisy")
    write_demo(noisy, tests, seed=1, noise=True, fmt="csv")
    return write_demo(out, tests, seed=1, noise=False, fmt="csv"), with_tests(noisy / "identify.toml", noisy)


@pytest.fixture(scope="module")
def sigma_noise(demo):
    """The estimates' standard deviations under the suite's noise (same tests, noisy files)."""
    return identify(load_config(demo[1])).result.std


@pytest.fixture(scope="module")
def band_limited(demo, tmp_path_factory):
    """The noise-free files low-passed at B; each test from 0.5 s to 0.5 s before its end, both half a sample
    off a sample instant (so that a clock fitted to jittered stamps keeps the same samples)."""
    out = tmp_path_factory.mktemp("band_limited")
    (out / "data").mkdir()
    sos = butter(4, B, fs=FS, output="sos")
    files, window = {}, {}
    for f in sorted((demo[0].parent / "data").glob("*.csv")):
        head, rows = read(f)
        rows[:, 1:] = sosfiltfilt(sos, rows[:, 1:], axis=0)
        files[f.stem] = (head, rows)
        write(out / "data" / f.name, head, rows)
        start, end = (float(np.floor(s * FS) + 0.5) / FS for s in (0.5, float(rows[-1, 0]) - 0.5))
        window[f.stem] = f"start = {start!r}\nend = {end!r}\n"
    return with_tests(demo[0], out, window), files


@pytest.fixture(scope="module")
def band_limited_values(band_limited):
    return values(band_limited[0])


def test_a_window_equals_the_rows_cut_by_hand(demo, tmp_path):
    config = demo[0]
    lines = (config.parent / "data" / "sine.csv").read_text().splitlines(keepends=True)
    k = next(i for i, line in enumerate(lines) if not line.startswith("#")) + 1
    kept = [line for line in lines[k:] if 1.0 <= float(line.split(",", 1)[0]) <= 10.0]
    assert len(kept) == 9 * 625 + 1
    cut = tmp_path / "data"
    shutil.copytree(config.parent / "data", cut)
    (cut / "sine.csv").write_text("".join(lines[:k] + kept))
    by_hand = values(with_tests(config, tmp_path))
    windowed = values(with_tests(config, config.parent, {"sine": "start = 1.0\nend = 10.0\n"}, name="window.toml"))
    np.testing.assert_allclose(windowed, by_hand, rtol=1e-9, atol=0)


def jittered(t: np.ndarray, x: np.ndarray, rng) -> tuple[np.ndarray, np.ndarray]:
    """The truth sampled as a logger does: stamps off by up to 10 % of a step, 4 holes of 1 or 2 missing rows,
    20 rows written twice. Returns the stamps and the values there (the truth's spline)."""
    n = t.size
    stamp = t + rng.uniform(-JITTER, JITTER, n)
    keep = np.ones(n, bool)
    for s in rng.choice(np.arange(1000, n - 1000), 4, replace=False):
        keep[s:s + 1 + s % 2] = False
    rows = np.flatnonzero(keep)
    inside = rows[(rows > 1000) & (rows < n - 1000)]  # well inside the windows
    rows = np.sort(np.concatenate([rows, rng.choice(inside, 20, replace=False)]))
    return stamp[rows], CubicSpline(t, x, axis=0)(stamp[rows])


def noise_in_band(sensor, fc: float) -> float:
    """The RMS of a sensor's white noise (accuracy, 1 sigma, at its own rate) below fc."""
    return sensor.accuracy * np.sqrt(2 * fc / sensor.rate)


def suite():
    """The sensors of the channels the identification reads (not the spin torques the files also hold)."""
    from dynid.vehicle.description import load_vehicle
    from dynid.vehicle.estimate import required_channels

    read = set(required_channels(spin=False))
    return {c.name: c for c in load_vehicle("peugeot406").suite if c.name in read}


def test_jitter_repeated_rows_and_holes_are_resampled_and_reported(band_limited, band_limited_values, sigma_noise,
                                                                   tmp_path):
    config, files = band_limited
    (tmp_path / "data").mkdir()
    sensors = suite()
    fc = load_config(config).car.cutoff
    rng = np.random.default_rng(5)
    rho, eps, stamps = 0.0, 0.0, {}
    for key, (head, rows) in files.items():
        t, x = rows[:, 0], rows[:, 1:]
        st, xs = jittered(t, x, rng)
        stamps[key] = st
        write(tmp_path / "data" / f"{key}.csv", head, np.column_stack([st, xs]))
        u = np.unique(st)
        used = (t > t[0] + 0.5) & (t < t[-1] - 0.5)  # the window
        # the clock's rate: the slope of the stamps' least-squares line, 3 sigma (n stamps of jitter sigma_j)
        count = np.count_nonzero((u > t[0] + 0.5) & (u < t[-1] - 0.5))
        eps = max(eps, 3 * JITTER / np.sqrt(3) * np.sqrt(12 / (count**3 - count)) / H)
        # the splines: the truth's own (nodes H apart) and the resampling's (its nodes' spacing, holes too)
        spacing = np.diff(u)[np.clip(np.searchsorted(u, t) - 1, 0, u.size - 2)]
        d4 = np.pad(np.abs(np.diff(x, 4, axis=0)) / H**4, ((2, 2), (0, 0)), mode="edge")
        error = 2 * SPLINE * (2 * H**4 + spacing[:, None] ** 4) * d4
        spread = np.sqrt(np.mean(error[used] ** 2, axis=0))
        names = [re.sub(r"\s*\[.*", "", c) for c in head[-1].split(",")[1:]]
        rho = max([rho] + [e / noise_in_band(sensors[n], fc) for n, e in zip(names, spread, strict=True)
                           if n in sensors])
    assert rho < 1e-3 and eps < 1e-5  # far below the noise: a tolerance far inside the estimates' sigma
    irregular = with_tests(config, tmp_path)  # the windows of the clean files
    cfg = load_config(irregular)
    for spec in cfg.tests:  # the check, reported for each file
        said: list[str] = []
        load_car_channels(cfg, spec, progress=said.append)
        key = spec.files["channels"].stem
        text = next(s for s in said if "repeated" in s)
        assert text.startswith(f"{spec.name}: {spec.files['channels']}: time column, ") and "resampled" in text, text
        assert "samples at 625 Hz; 20 repeated row(s) (identical time stamps) averaged" in text, text
        jitter = float(re.search(r"jitter ([0-9.e-]+) ms RMS", text).group(1))
        assert jitter == pytest.approx(JITTER * 1e3 / np.sqrt(3), rel=0.05)  # uniform on +-10 % of a step
        gap = float(re.search(r"largest gap ([0-9.]+) ms", text).group(1))
        assert gap == pytest.approx(np.diff(np.unique(stamps[key])).max() * 1e3, rel=5e-3)
        assert f"{spec.name}: every channel on one uniform 625 Hz clock" in said[-1], said
    got = values(irregular)
    tol = 3 * rho * sigma_noise + 2 * eps * np.abs(band_limited_values)
    assert np.all(np.abs(got - band_limited_values) <= tol), np.max(np.abs(got - band_limited_values) / tol)


def test_channels_at_two_rates_in_an_mdf4_file_give_the_single_rate_estimates(band_limited, band_limited_values,
                                                                              sigma_noise, tmp_path):
    """The 125 Hz sensors (inertial unit, Correvit, cameras) logged at their own rate in a channel group of
    their own, the others at 625 Hz. Uniform nodes T apart: the spline's error at a frequency stays at it (and at
    images beyond 100 Hz), so within the identification's band (cutoff fc) it is the error on the channel's part
    in that band: at most 5/384 T^4 |x''''| of that part (RMS for RMS: the spline is shift-invariant there)."""
    import asammdf

    config, files = band_limited
    (tmp_path / "data").mkdir()
    sensors = suite()
    settings = load_config(config).car
    fc = settings.cutoff
    band = butter(settings.order, fc, fs=FS, output="sos")  # the identification's band
    slow_rate = FS / 5
    rho = 0.0
    for key, (head, rows) in files.items():
        t = rows[:, 0]
        mdf = asammdf.MDF(version="4.10")
        fast, slow = [], []
        for j, cell in enumerate(head[-1].split(",")[1:], start=1):
            name, unit = re.fullmatch(r"\s*(.*?)\s*\[(.*)\]\s*", cell).groups()
            if name in sensors and sensors[name].rate < FS:
                assert sensors[name].rate == slow_rate
                slow.append(asammdf.Signal(rows[::5, j], t[::5], name=name, unit=unit))
                d4 = np.diff(sosfiltfilt(band, rows[:, j]), 4) / H**4
                error = 2 * SPLINE * (1 / slow_rate) ** 4 * np.sqrt(np.mean(d4**2))
                rho = max(rho, error / noise_in_band(sensors[name], fc))
            else:
                fast.append(asammdf.Signal(rows[:, j], t, name=name, unit=unit))
        mdf.append(fast)
        mdf.append(slow)
        mdf.save(tmp_path / "data" / f"{key}.mf4", overwrite=True)
        mdf.close()
    assert rho < 0.01
    two_rates = with_tests(config, tmp_path, ext="mf4")
    cfg = load_config(two_rates)
    said: list[str] = []
    load_car_channels(cfg, cfg.tests[0], progress=said.append)
    text = next(s for s in said if "several rates" in s)
    assert "625 Hz (37), 125 Hz (18)" in text and "onto the 625 Hz clock of the fastest" in text, text
    got = values(two_rates)
    tol = 3 * rho * sigma_noise
    assert np.all(np.abs(got - band_limited_values) <= tol), np.max(np.abs(got - band_limited_values) / tol)


@pytest.fixture
def broken(demo, tmp_path):
    """A copy of the demo whose sine file the test rewrites: (config, header lines, data lines)."""
    config = demo[0]
    shutil.copytree(config.parent / "data", tmp_path / "data")
    lines = (tmp_path / "data" / "sine.csv").read_text().splitlines(keepends=True)
    k = next(i for i, line in enumerate(lines) if not line.startswith("#")) + 1
    return config, lines[:k], lines[k:]


def test_time_going_back_is_refused_with_file_line_sample_and_fix(broken, tmp_path):
    config, head, rows = broken
    time = rows[2498].split(",", 1)[0]
    rows[2500] = time + "," + rows[2500].split(",", 1)[1]  # the stamp of two rows before
    (tmp_path / "data" / "sine.csv").write_text("".join(head + rows))
    with pytest.raises(TimeBaseError) as exc:
        identify(load_config(with_tests(config, tmp_path)))
    assert type(exc.value) is TimeBaseError and isinstance(exc.value, DataError)
    text = str(exc.value)
    line = len(head) + 2500 + 1
    assert f"sine.csv, line {line}, sample 2500" in text and "time goes back" in text, text
    assert "Sort the rows by time" in text and "start, end in the test" in text, text
    assert exc.value.line == line and exc.value.sample == 2500


def test_a_hole_over_max_gap_is_refused_and_the_fixes_work(broken, tmp_path):
    config, head, rows = broken
    del rows[3000:3020]  # 21 sample periods without a sample
    (tmp_path / "data" / "sine.csv").write_text("".join(head + rows))
    with pytest.raises(GapError) as exc:
        identify(load_config(with_tests(config, tmp_path)))
    assert type(exc.value) is GapError and isinstance(exc.value, DataError)
    text = str(exc.value)
    assert f"sine.csv, line {len(head) + 3000 + 1}, sample 3000 (t = 4.832 s)" in text, text
    assert "33.6 ms" in text and "max_gap = 10" in text and "raise max_gap in the test" in text, text
    for extra in ("max_gap = 25\n", "start = 5.0\n"):
        cfg = load_config(with_tests(config, tmp_path, {"sine": extra}))
        said: list[str] = []
        channels, _, fs = load_car_channels(cfg, cfg.tests[0], progress=said.append)
        assert fs == pytest.approx(FS, rel=1e-9)
        n = len(next(iter(channels.values())))
        assert n == (7501 if "max_gap" in extra else 7501 - 5 * 625), n
        assert ("largest gap 33.6 ms" if "max_gap" in extra else "largest gap 1.6 ms") in said[0], said


def test_fs_with_a_time_column_is_checked_and_a_window_outside_is_refused(demo, tmp_path):
    config = demo[0]
    cfg = load_config(with_tests(config, config.parent, {"sine": "fs = 625.0\n"}, name="fs.toml"))
    assert load_car_channels(cfg, cfg.tests[0])[2] == pytest.approx(FS, rel=1e-9)
    for extra, words in (("fs = 500.0\n", ["fs = 500 Hz", "say 625 Hz", "remove fs"]),
                         ("end = 30.0\n", ["end = 30 s is outside the record", "0..12 s"])):
        cfg = load_config(with_tests(config, config.parent, {"sine": extra}, name="variant.toml"))
        with pytest.raises(DataError) as exc:
            load_car_channels(cfg, cfg.tests[0])
        for w in words:
            assert w in str(exc.value), (w, str(exc.value))


@pytest.mark.parametrize("extra, words", [
    ("start = 5.0\nend = 2.0\n", ["start = 5.0", "not before end"]),
    ('end = "a"\n', ["end = 'a'", "a number"]),
    ("max_gap = 0.5\n", ["max_gap = 0.5", ">= 1"]),
    ("stop = 3.0\n", ["unknown key 'stop'"]),
])
def test_car_window_keys_are_read_and_checked(demo, extra, words):
    config = demo[0]
    spec = load_config(with_tests(config, config.parent, {"sine": "start = 1.5\nend = 9\nmax_gap = 4\n"},
                                     name="keys.toml")).tests[0]
    assert (spec.start, spec.end, spec.max_gap) == (1.5, 9.0, 4.0)
    with pytest.raises(ConfigError) as exc:
        load_config(with_tests(config, config.parent, {"sine": extra}, name="variant.toml"))
    for w in words:
        assert w in str(exc.value), (w, str(exc.value))
