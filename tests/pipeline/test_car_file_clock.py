"""A car plan's clock left in its Parquet file (issue 28: peak memory bounded for any log length).

The plan of a Parquet log whose clock is the file's own stamps holds them as rows of the file (`sources.FileClock`),
not as an array of 8 bytes a sample; each segment reads its own back. Oracles: pyarrow's own read of the time
column, cut to start..end by hand (every window's stamps and the segments' edges, bit for bit); the pickled plan's
size against the log's length (what a job or a worker process is sent); the same rows as CSV, whose clock the plan
still holds; and the identification with the clock held in memory, the code before (`_file_clock` answering None):
the same estimates, σ, covariance, validation and data health, bit for bit.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import itertools
import pickle

import numpy as np
import pytest

from dynid.io import read_recording
from dynid.pipeline import sources
from dynid.pipeline.config import load_config
from dynid.pipeline.sources import (
    FileClock,
    clock_at,
    clock_read,
    plan_car_test,
    read_segment,
    segment_edges,
    segment_window,
)
from dynid.vehicle.description import load_vehicle
from dynid.vehicle.estimate import required_channels

pytestmark = pytest.mark.skipif(importlib.util.find_spec("pyarrow") is None, reason="pyarrow not installed")

VEHICLE = load_vehicle("peugeot406")
FS = 625.0
START, END = 1.5, None  # the plan cuts the file's first 1.5 s: the clock's first row is not the file's


def write_log(folder, n: int, fmt: str = "parquet", row_group: int = 3000):
    """A logger file of the suite's channels (noise; the plan reads stamps and units), n samples at 625 Hz, and its
    config; (config path, the stamps as written)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(n)
    t = np.arange(n) / FS
    units = VEHICLE.suite.units
    names = required_channels(spin=False, suite=VEHICLE.suite)
    x = rng.normal(size=(n, len(names)))
    if fmt == "parquet":
        fields = [pa.field("time", pa.float64(), metadata={b"unit": b"s"})]
        fields += [pa.field(q, pa.float64(), metadata={b"unit": units[q].encode()}) for q in names]
        table = pa.Table.from_arrays([pa.array(t), *(pa.array(x[:, k]) for k in range(len(names)))],
                                     schema=pa.schema(fields))
        pq.write_table(table, folder / "log.parquet", row_group_size=row_group)  # windows across row groups
    else:
        header = ",".join(["time [s]", *(f"{q} [{units[q]}]" for q in names)])
        np.savetxt(folder / "log.csv", np.column_stack([t, x]), delimiter=",",
                   header=header, comments="", fmt="%.17g")
    cfg = folder / "identify.toml"
    cfg.write_text(f'[model]\ntemplate = "peugeot406"\n\n[[tests]]\nname = "log"\nfile = "log.{fmt}"\n'
                   f"start = {START}\n\n[conditioning]\nsegment = 2.0\n", encoding="utf-8")
    return cfg, t


def plan_of(cfg_path):
    cfg = load_config(cfg_path)
    return plan_car_test(cfg, cfg.tests[0], required_channels(spin=False, suite=VEHICLE.suite), VEHICLE.suite.units,
                         cfg.car.segment, lambda fs: 40)


def file_stamps(path) -> np.ndarray:
    import pyarrow.parquet as pq

    return pq.read_table(path, columns=["time"]).column(0).to_numpy()


def test_a_parquet_car_plan_leaves_its_clock_in_the_file(tmp_path):
    cfg, _ = write_log(tmp_path, 20_000)
    plan = plan_of(cfg)
    t = file_stamps(tmp_path / "log.parquet")
    t = t[t >= START]
    assert isinstance(plan.clock, FileClock) and plan.samples == t.size and len(plan.segments) > 3
    for lo, hi in ((0, t.size), (0, 1), (2990, 3017), (1500, 9000), (t.size - 7, t.size)):
        w = clock_read(segment_window(plan, lo, hi))
        assert w.first == lo and isinstance(w.clock, np.ndarray) and np.array_equal(w.clock, t[lo:hi])
    for lo, hi in plan.segments:  # each segment's window still in the file until its job reads it
        w = segment_window(plan, lo, hi)
        assert isinstance(w.clock, FileClock) and np.array_equal(clock_read(w).clock, t[lo:hi])
        assert w.span == (t[lo], t[hi - 1])  # its read's bounds known without its stamps
    # the part of the test each segment's health answers for: from its first stamp to the next's, the last to the end
    firsts = [lo for lo, _ in plan.segments]
    want = [(t[a], t[b], False) for a, b in itertools.pairwise(firsts)] + [(t[firsts[-1]], t[-1], True)]
    assert segment_edges(plan) == want
    rows = [*firsts, plan.samples - 1]
    assert np.array_equal(clock_at(plan.clock, rows), t[rows])  # stamps of any samples, in one pass
    assert np.array_equal(clock_at(plan.clock, [-1, 0, 2999, 3000, 5]), t[[-1, 0, 2999, 3000, 5]])
    with pytest.raises(IndexError, match="of a clock of"):
        clock_at(plan.clock, [plan.samples])


def test_a_car_plan_s_size_does_not_grow_with_the_log_s_length(tmp_path):
    """The pickled plan (what the map's jobs are cut from, and a cluster's workers are sent): 4 x the samples add
    only the index's row groups (~0.01 byte a sample here), not 8 bytes a sample of held stamps."""
    short, long = (pickle.dumps(plan_of(write_log(tmp_path / f"n{n}", n, row_group=20_000)[0]))
                   for n in (20_000, 80_000))
    assert len(long) - len(short) < 0.1 * 60_000


def test_a_csv_car_log_keeps_its_clock_and_reads_the_same_segments(tmp_path):
    """A CSV log cannot be a file clock: the plan holds its stamps, as before; the same rows as Parquet give the
    same segments, their stamps and samples (written with 17 digits: the same doubles)."""
    plans = {fmt: plan_of(write_log(tmp_path / fmt, 20_000, fmt)[0]) for fmt in ("csv", "parquet")}
    held, in_file = plans["csv"], plans["parquet"]
    assert isinstance(held.clock, np.ndarray) and isinstance(in_file.clock, FileClock)
    assert held.segments == in_file.segments
    t = read_recording(tmp_path / "csv" / "log.csv").channel("imu_ax").time
    assert np.array_equal(held.clock, t[t >= START])
    for lo, hi in held.segments[:2]:
        a, b = read_segment(segment_window(held, lo, hi)), read_segment(segment_window(in_file, lo, hi))
        assert a.keys() == b.keys() and all(np.array_equal(a[q], b[q]) for q in a)


@pytest.mark.slow  # ~9 s: two identifications of the quick demo
def test_a_parquet_car_identification_equals_the_held_clock_s(tmp_path, monkeypatch):
    """The quick demo's tests as Parquet (row groups of 2000 samples, segments of 4 s across them): identified with
    the clocks in the files, and with them held (the code before), the same numbers to the bit."""
    import pyarrow.parquet as pq

    from dynid.pipeline.demo import simulate_tests, write_demo
    from dynid.pipeline.run import identify

    cfg = load_config(write_demo(tmp_path, simulate_tests(quick=True), fmt="parquet"))
    for spec in cfg.tests:
        path = spec.files["channels"]
        pq.write_table(pq.read_table(path), path, row_group_size=2000)
    cfg = dataclasses.replace(cfg, car=dataclasses.replace(cfg.car, segment=4.0))
    assert all(isinstance(plan_of_spec(cfg, s).clock, FileClock) for s in cfg.tests)
    in_file = identify(cfg)
    monkeypatch.setattr(sources, "_file_clock", lambda index, clock: None)
    monkeypatch.setattr(sources, "_stream_in_blocks", lambda *a: None)  # the stamps held whole
    assert isinstance(plan_of_spec(cfg, cfg.tests[0]).clock, np.ndarray)
    held = identify(cfg)
    a, b = in_file.result, held.result
    assert a.names == b.names and np.array_equal(a.values, b.values)
    assert np.array_equal(a.std, b.std, equal_nan=True) and np.array_equal(a.covariance, b.covariance)
    assert a.validation == b.validation and in_file.health == held.health


def plan_of_spec(cfg, spec):
    return plan_car_test(cfg, spec, required_channels(spin=False, suite=VEHICLE.suite), VEHICLE.suite.units,
                         cfg.car.segment, lambda fs: 40)


def test_a_car_plan_and_its_segments_read_through_a_footer_cut_per_row_group_are_the_same(tmp_path, monkeypatch):
    """A long log's footer is kept cut per row group (`io.windows.FOOTER_WHOLE`, 0 here: this short log's too): the
    plan (its clock, segments, rates) and every segment's channels equal those read through the footer kept whole,
    the code before, bit for bit."""
    from dynid.io import parquet_format, windows

    cfg, _ = write_log(tmp_path, 20_000)
    windows.clear_cache()
    whole = plan_of(cfg)
    want = [read_segment(segment_window(whole, lo, hi)) for lo, hi in whole.segments]
    monkeypatch.setattr(windows, "FOOTER_WHOLE", 0)
    windows.clear_cache()
    cut = plan_of(cfg)
    assert any(isinstance(k[0], parquet_format.SplitFooter) for k in windows._footers.values())
    assert pickle.dumps(cut) == pickle.dumps(whole)
    for (lo, hi), a in zip(cut.segments, want, strict=True):
        b = read_segment(segment_window(cut, lo, hi))
        assert a.keys() == b.keys() and all(np.array_equal(a[q].view(np.int64), b[q].view(np.int64)) for q in a)
