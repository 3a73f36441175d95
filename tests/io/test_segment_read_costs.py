"""A car segment's read and data-health scan with their per-segment overheads removed (issue 28): each shortcut
against what it stands for.

- a Parquet window's channels that share a time base share one time array (cut and concatenated once), and its
  values are read-only views of the decoded buffers: still the whole file's samples, bit for bit;
- `stream(fit=False)` (a segment's base, whose clock the plan fitted): the same merged stamps and samples as the
  full stream, the same refusal of stamps going back;
- `_on_clock`'s consecutive-stamps shortcut: the rows of the search it replaces, on the clock and off it;
- `read_segment`: a channel whose factor to SI is 1 is the file's samples, read-only (nothing downstream may write
  into what the health scan reads after the rows);
- `ChannelScan.add` finding non-finite samples from the block's extremes: what a scan of the finite samples alone
  finds, whatever the channel's shape (noisy, clipped, held, spiky, still);
- `car_scans`, its settings made once per process and vehicle: fresh scans each call, the settings a new vehicle
  object gives, and another vehicle's own settings.
"""

from __future__ import annotations

import dataclasses
import importlib.util
from types import SimpleNamespace

import numpy as np
import pytest

from dynid.io import Channel, TimeBaseError, read_recording, unit_factor
from dynid.io.health import ChannelScan
from dynid.io.windows import clear_cache, index_file, read_window
from dynid.pipeline import health
from dynid.pipeline.sources import _on_clock, read_segment, segment_window
from dynid.pipeline.timebase import stream
from dynid.vehicle.description import load_vehicle

HAVE_PYARROW = importlib.util.find_spec("pyarrow") is not None


def write_parquet(path, t, columns, row_group_size):
    import pyarrow as pa
    import pyarrow.parquet as pq

    fields = [pa.field("time", pa.float64(), metadata={b"unit": b"s"})]
    arrays = [pa.array(t)]
    for name, (unit, values, mask) in columns.items():
        fields.append(pa.field(name, pa.float64(), metadata={b"unit": unit.encode()}))
        arrays.append(pa.array(values, mask=mask))
    pq.write_table(pa.Table.from_arrays(arrays, schema=pa.schema(fields)), path, row_group_size=row_group_size)


@pytest.mark.skipif(not HAVE_PYARROW, reason="pyarrow not installed")
def test_a_parquet_window_shares_its_time_bases_and_equals_the_whole_file(tmp_path):
    n = 1000
    rng = np.random.default_rng(3)
    t = np.arange(n) / 625.0
    slow = np.zeros(n, dtype=bool)
    slow[::5] = True  # a 125 Hz channel: nulls between its samples
    columns = {"a": ("m/s", rng.normal(size=n), None), "b": ("deg", rng.normal(size=n), None),
               "c": ("N", rng.normal(size=n), ~slow)}
    path = tmp_path / "f.parquet"
    write_parquet(path, t, columns, row_group_size=300)  # 4 row groups: windows across them
    whole = read_recording(path)
    clear_cache()
    index = index_file(path)
    for t0, t1 in ((0.1, 0.4), (0.3, 1.2), (0.0, 2.0), (0.47, 0.49)):
        rec = read_window(index, ["a", "b", "c"], t0, t1)
        a, b, c = (rec.channels[k] for k in "abc")
        assert a.time is b.time  # one time array for the dense base, not one copy per channel
        assert c.time is not a.time
        for k in "abc":
            want = whole.channels[k]
            keep = (want.time >= t0) & (want.time <= t1)
            got = rec.channels[k]
            np.testing.assert_array_equal(got.time, want.time[keep])
            assert np.array_equal(got.values.view(np.uint64), want.values[keep].view(np.uint64))
            if k != "c" and t1 < 0.48:  # inside the first row group: a view of its decoded (cached) buffer, which
                assert not got.values.flags.writeable  # nobody may write into (c's nulls: its samples compacted)


def test_stream_without_the_fit_merges_and_refuses_as_the_full_stream():
    t = np.array([0.0, 0.1, 0.1, 0.2, 0.3, 0.3, 0.3, 0.4, 0.5])
    x = np.arange(t.size, dtype=float) ** 2
    chans = [Channel("x", "m", x, t), Channel("y", "m", -x, t)]
    full, light = stream(chans, "f", True, np.inf), stream(chans, "f", True, np.inf, fit=False)
    np.testing.assert_array_equal(light.t, full.t)
    assert light.t.size == 6  # repeated stamps merged
    for k in ("x", "y"):
        np.testing.assert_array_equal(light.channels[k].values, full.channels[k].values)
        np.testing.assert_array_equal(light.channels[k].time, full.channels[k].time)
    back = np.array([0.0, 0.1, 0.2, 0.15, 0.3])
    for fit in (True, False):
        with pytest.raises(TimeBaseError, match="time goes back"):
            stream([Channel("x", "m", np.zeros(5), back)], "f", True, np.inf, fit=fit)


def _rows_by_search(t, clock):
    """The rows of the stamps from the clock's first instant to its last when every instant is a stamp, else None:
    each instant looked up on its own (the oracle)."""
    at = [int(np.flatnonzero(t == c)[0]) if np.any(t == c) else -1 for c in clock]
    return None if min(at) < 0 else (at[0], at[-1] + 1)


@pytest.mark.parametrize("pick", ["consecutive", "every other", "off the stamps", "past the end", "one"])
def test_on_clock_cuts_the_rows_each_instant_names(pick):
    t = np.arange(100) * 0.01 + 3.0
    clock = {"consecutive": t[10:60], "every other": t[10:60:2], "off the stamps": t[10:60] + 0.004,
             "past the end": np.append(t[90:], 4.5), "one": t[7:8]}[pick]
    s = SimpleNamespace(t=t, channels={"x": Channel("x", "m", np.sin(t), t)})
    got = _on_clock(s, clock)
    want = _rows_by_search(t, clock)
    if want is None:
        assert got is None
    else:
        np.testing.assert_array_equal(got["x"].time, t[want[0]:want[1]])
        np.testing.assert_array_equal(got["x"].values, np.sin(t)[want[0]:want[1]])


def signal(kind: str, n: int, rng) -> np.ndarray:
    t = np.arange(n) / 625.0
    x = 20.0 * np.sin(2 * np.pi * 0.7 * t) + rng.normal(0, 0.3, n)
    if kind == "clipped":
        x = np.minimum(x, 12.0)
    elif kind == "held":
        x = np.repeat(np.round(x[::5], 1), 5)[:n]
    elif kind == "spiky":
        x[[500, 1700]] += [400.0, -300.0]
    elif kind == "still":
        x = np.full(n, 2.5)
    elif kind == "at the range":
        x = np.clip(x, -15.0, 15.0)
    return x


@pytest.mark.parametrize("kind", ["noisy", "clipped", "held", "spiky", "still", "at the range"])
def test_a_scan_with_non_finite_samples_finds_what_the_finite_samples_show(kind):
    rng = np.random.default_rng(7)
    n = 3000
    t = np.arange(n) / 625.0
    x = signal(kind, n, rng)
    bad = x.copy()
    at = rng.choice(n, 40, replace=False)
    bad[at] = rng.choice([np.nan, np.inf, -np.inf], at.size)
    finite = np.isfinite(bad)
    scans = []
    for values, keep in ((bad, slice(None)), (x, finite)):
        s = ChannelScan("x", "m", (-15.0, 15.0), 0.0, min_run=62)
        for a in range(0, n, 1000):  # blocks, as the segments feed them
            s.add(t[a:a + 1000][keep[a:a + 1000]] if keep is finite else t[a:a + 1000],
                  values[a:a + 1000][keep[a:a + 1000]] if keep is finite else values[a:a + 1000])
        scans.append(s)
    with_bad, alone = ([f.as_dict() for f in s.findings()] for s in scans)
    assert with_bad == alone
    assert scans[0].n == scans[1].n == int(finite.sum())
    if kind != "noisy":
        assert alone  # each shape but plain noise is a finding: the comparison judged something


def _window(vehicle_suite_names, fs=625.0):
    names = {q: f"file_{q}" for q in vehicle_suite_names}
    index = SimpleNamespace(channels=tuple((f"file_{q}", "deg") for q in vehicle_suite_names))
    index.units = dict(index.channels)
    return SimpleNamespace(quantity_names=names, factors=dict.fromkeys(names, np.pi / 180.0), index=index, fs=fs)


def _settings(scans):
    return {q: (s.name, s.unit, s.limits, s.resolution, s.still, s.min_run) for q, s in scans.items()}


def test_car_scans_are_fresh_each_call_with_the_settings_of_their_vehicle():
    vehicle = load_vehicle("peugeot406")
    quantities = ["imu_yaw_rate", "steering_wheel", "steer_fl", "not_in_the_suite"]
    w = _window(quantities)
    first, again = health.car_scans(w, vehicle), health.car_scans(w, vehicle)
    assert all(first[q] is not again[q] for q in quantities)  # the scans are fed: never shared
    first["imu_yaw_rate"].add(np.arange(10.0), np.arange(10.0))
    assert again["imu_yaw_rate"].n == 0
    # the memo's settings are those a vehicle object not seen before gives (made anew)
    fresh = dataclasses.replace(vehicle)
    assert fresh is not vehicle
    assert _settings(health.car_scans(w, fresh)) == _settings(first)
    yaw = vehicle.suite["imu_yaw_rate"]  # its declared range in the file's unit (deg/s: the window's factor)
    k = unit_factor(yaw.unit)[0] / (np.pi / 180.0)
    np.testing.assert_allclose(first["imu_yaw_rate"].limits, sorted(v * k for v in yaw.range), rtol=1e-12)
    assert first["not_in_the_suite"].limits is None
    # another rate, another file's units: their own settings
    assert health.car_scans(_window(quantities, fs=100.0), vehicle)["imu_yaw_rate"].min_run == 10
    assert first["imu_yaw_rate"].min_run == 62
    # another vehicle (no cameras fitted): its own suite's settings, not the memo's of the first
    other = dataclasses.replace(vehicle, cameras=False)
    assert "steer_fl" in vehicle.suite.names and "steer_fl" not in other.suite.names
    got = health.car_scans(w, other)
    want = {q: (q in other.suite.names) for q in quantities}
    assert {q: got[q].resolution != 0.0 for q in quantities} == want


@pytest.mark.skipif(not HAVE_PYARROW, reason="pyarrow not installed")
def test_a_segment_channel_in_si_already_is_the_file_s_samples_read_only(tmp_path):
    n = 800
    t = np.arange(n) / 625.0
    rng = np.random.default_rng(5)
    path = tmp_path / "f.parquet"
    write_parquet(path, t, {"ax": ("m/s^2", rng.normal(size=n), None), "yaw": ("deg/s", rng.normal(size=n), None)},
                  row_group_size=256)
    index = index_file(path)
    plan = SimpleNamespace(test="t", index=index, file_names=("ax", "yaw"),
                           quantity_names={"imu_ax": "ax", "imu_yaw_rate": "yaw"},
                           factors={"imu_ax": 1.0, "imu_yaw_rate": np.pi / 180.0}, clock=t, fs=625.0, timed=True,
                           max_gap=2.0, base_steps=(1 / 625.0,), segments=(), spans=())
    whole = read_recording(path)
    w = segment_window(plan, 100, 700)
    got = read_segment(w)
    want_ax = whole.channels["ax"].values[100:700]
    assert np.array_equal(got["imu_ax"].view(np.uint64), want_ax.view(np.uint64))
    assert not got["imu_ax"].flags.writeable
    np.testing.assert_array_equal(got["imu_yaw_rate"], whole.channels["yaw"].values[100:700] * (np.pi / 180.0))
