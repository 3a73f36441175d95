"""A car plan's pass over a Parquet log's stamps a block at a time (issue 28: the planning pass's memory bounded).

Oracles: the plan with the stamps held whole (`_stream_in_blocks` answering None: the code before, its whole-array
checks, np.median of the steps, the clock cut by a mask and matched against the file's rows) for logs that are the
file's own uniform clock, cut by start and end, across row groups; the same for logs the pass hands back (gaps,
jitter, repeated rows, a skipped sample, stamps going back), whose errors must name the same sample; np.median for
the steps' counted median; tracemalloc for the pass's memory against the log's length.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import tracemalloc

import numpy as np
import pytest

from dynid.io import GapError, TimeBaseError
from dynid.pipeline import sources
from dynid.pipeline.config import load_config
from dynid.pipeline.sources import FileClock, _StepCounts, plan_car_test
from dynid.vehicle.description import load_vehicle
from dynid.vehicle.estimate import required_channels

pytestmark = pytest.mark.skipif(importlib.util.find_spec("pyarrow") is None, reason="pyarrow not installed")

VEHICLE = load_vehicle("peugeot406")
NAMES = required_channels(spin=False, suite=VEHICLE.suite)


def write_log(folder, t: np.ndarray, start=None, end=None, row_group: int = 3000):
    """A Parquet logger file of the suite's channels (zeros: the plan reads stamps and units) on the stamps t, and
    its config (segments of 2 s)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    folder.mkdir(parents=True, exist_ok=True)
    units = VEHICLE.suite.units
    names = NAMES
    zero = pa.array(np.zeros(t.size))
    fields = [pa.field("time", pa.float64(), metadata={b"unit": b"s"})]
    fields += [pa.field(q, pa.float64(), metadata={b"unit": units[q].encode()}) for q in names]
    table = pa.Table.from_arrays([pa.array(t), *([zero] * len(names))], schema=pa.schema(fields))
    pq.write_table(table, folder / "log.parquet", row_group_size=row_group)
    cut = "".join(f"{k} = {v!r}\n" for k, v in (("start", start), ("end", end)) if v is not None)
    cfg = folder / "identify.toml"
    cfg.write_text(f'[model]\ntemplate = "peugeot406"\n\n[[tests]]\nname = "log"\nfile = "log.parquet"\n{cut}\n'
                   "[conditioning]\nsegment = 2.0\n", encoding="utf-8")
    return cfg


def plan(cfg_path, say=None):
    cfg = load_config(cfg_path)
    return plan_car_test(cfg, cfg.tests[0], NAMES, VEHICLE.suite.units, cfg.car.segment, lambda fs: 40, say)


def held(cfg_path, monkeypatch, say=None):
    """The plan with the stamps held whole (the code before)."""
    with monkeypatch.context() as m:
        m.setattr(sources, "_stream_in_blocks", lambda *a: None)
        return plan(cfg_path, say)


def clock_rows(p) -> tuple[int, int] | np.ndarray:
    return (p.clock.first, p.clock.size) if isinstance(p.clock, FileClock) else p.clock


def assert_same_plan(new, old, blocks: bool) -> None:
    """Every field the same bits, but the fitted step when planned in blocks: the pass's block sums against the old
    BLAS dot, whose rounding over n centred products is within n eps of the sum (the products one-signed: d ~ h c),
    so 1e-10 relative for the logs here (n <= 1e5)."""
    assert isinstance(new.clock, FileClock) is isinstance(old.clock, FileClock)
    a, b = clock_rows(new), clock_rows(old)
    assert a == b if isinstance(a, tuple) else np.array_equal(a, b)
    assert new.fs == old.fs and new.segments == old.segments and new.spans == old.spans
    assert new.samples == old.samples and new.file_names == old.file_names and new.factors == old.factors
    np.testing.assert_allclose(new.base_steps, old.base_steps, rtol=1e-10, atol=0)
    if not blocks:
        assert new.base_steps == old.base_steps  # the pass handed back: the old code's plan itself
    assert dataclasses.replace(new, clock=None, base_steps=()) == dataclasses.replace(old, clock=None, base_steps=())


FS = 625.0
N = 40_000


@pytest.mark.parametrize("start, end, row_group, n", [
    (None, None, 3000, N),  # the whole log
    (101.5, None, 3000, N),  # the clock's first row not the file's
    (103.0001, 140.0, 4096, N),  # a window inside, its ends between stamps and row groups
    (None, 112.0, N, N),  # one row group
    (100.0, 100.0 + 1499 / FS, 7, 1500),  # the window at the log's own stamps; row groups of 7 rows (many blocks)
])
def test_a_uniform_parquet_log_s_plan_is_the_held_stamps_plan(tmp_path, monkeypatch, start, end, row_group, n):
    t = 100.0 + np.arange(n) / FS  # stamps not from 0: their rounding varies the steps
    cfg = write_log(tmp_path, t, start, end, row_group)
    new, old = plan(cfg), held(cfg, monkeypatch)
    assert isinstance(new.clock, FileClock)
    assert_same_plan(new, old, blocks=True)
    cut = t[(t >= (start or -np.inf)) & (t <= (end or np.inf))]
    assert new.samples == cut.size and new.fs == 1 / float(np.median(np.diff(cut)))  # np.median's bits
    assert new.spans[0][0] == cut[0] and new.spans[-1][1] == cut[-1]


def test_a_clock_rounded_to_microseconds_is_uniform_with_its_jitter(tmp_path, monkeypatch):
    """600 Hz stamps rounded to 1 µs (a logger's integer clock): steps of 1666 and 1667 µs, a jitter of 0.2 µs RMS,
    within 1e-3 of a step: the file's own clock, planned in blocks; the report's figures the same to their printed
    digits (the fits' difference, ~1e-13 of the step, moves the jitter by ~1e-5 of itself). Of a clean clock
    (k / 625) the jitter is the stamps' rounding, 1e-12 ms, which that difference does move."""
    t = np.round(np.arange(N) / 600.0, 6)
    cfg = write_log(tmp_path, t)
    said_new, said_old = [], []
    new, old = plan(cfg, said_new.append), held(cfg, monkeypatch, said_old.append)
    assert isinstance(new.clock, FileClock)
    assert_same_plan(new, old, blocks=True)
    assert said_new == said_old and "jitter 0.000" in said_new[0]


@pytest.mark.parametrize("kind", ["jitter", "skipped", "repeated", "gap_in", "many_steps_uniform"])
def test_logs_the_pass_hands_back_plan_as_before(tmp_path, monkeypatch, kind):
    """Not the file's own uniform clock (resampled, or its repeated rows merged): the plan of the stamps held
    whole, to the bit, the clock held."""
    rng = np.random.default_rng(7)
    t = 5.0 + np.arange(N) / FS
    if kind == "jitter":
        t = t + rng.uniform(-0.05, 0.05, N) / FS
    elif kind == "skipped":  # one sample missing: a hole of 2 periods, under max_gap
        t = np.delete(t, 12_345)
    elif kind == "repeated":
        t = np.insert(t, 20_000, t[20_000])
    elif kind == "gap_in":  # a hole of 5 periods (under max_gap) before the test's start
        t = np.concatenate((t[:1000], t[1005:]))
    elif kind == "many_steps_uniform":  # jitter within 1e-3 of a step but of many values: uniform, held whole
        t = t + rng.uniform(-1e-4, 1e-4, N) / FS
    cfg = write_log(tmp_path, t, start=7.0 if kind == "gap_in" else None)
    new, old = plan(cfg), held(cfg, monkeypatch)
    assert_same_plan(new, old, blocks=kind == "gap_in")  # its start cuts the hole off: the rest is uniform


@pytest.mark.parametrize("kind, sample, error", [
    ("gap", 30_001, GapError),
    ("back", 25_000, TimeBaseError),
    ("nan", 17_003, TimeBaseError),
])
def test_bad_stamps_are_refused_naming_the_same_sample(tmp_path, monkeypatch, kind, sample, error):
    t = np.arange(N) / FS
    if kind == "gap":
        t[sample:] += 1.0  # 625 periods missing before it
    elif kind == "back":
        t[sample] = t[sample - 2]
    else:
        t[sample] = np.nan
    cfg = write_log(tmp_path, t)
    with pytest.raises(error) as new:
        plan(cfg)
    with pytest.raises(error) as old:
        held(cfg, monkeypatch)
    assert str(new.value) == str(old.value) and f"sample {sample}" in str(new.value)
    assert new.value.sample == sample


@pytest.mark.parametrize("values", [
    [3.0], [1.0, 2.0], [2.0, 1.0, 2.0, 2.0], [0.1, 0.2, 0.3, 0.1 + 0.2], list(range(10)) * 3 + [7.5],
])
def test_the_counted_median_is_np_median_s(values):
    rng = np.random.default_rng(len(values))
    x = np.array(values)
    for _ in range(5):
        rng.shuffle(x)
        counts = _StepCounts()
        for part in np.array_split(x, 3):
            counts.add(part)
        assert counts.median() == float(np.median(x))


def test_random_few_valued_medians_are_np_median_s():
    rng = np.random.default_rng(3)
    for n in (1, 2, 3, 10, 101, 1000, 1001):
        x = rng.choice(0.0016 + rng.normal(0, 1e-15, 7), n)
        counts = _StepCounts()
        for part in np.array_split(x, 4):
            counts.add(part)
        assert counts.median() == float(np.median(x))


def test_the_planning_pass_s_memory_does_not_grow_with_the_log(tmp_path):
    """tracemalloc's peak through the plan of a log 4 x longer (row groups of 20k samples): the pass holds a
    block's stamps and its steps, not the log's (the stamps held whole took 24 bytes a sample: 3.6 MB more here)."""
    peaks = []
    for n in (50_000, 200_000):
        cfg = write_log(tmp_path / f"n{n}", np.arange(n) / FS, row_group=10_000)
        plan(cfg)  # the imports and caches once
        tracemalloc.start()
        try:
            p = plan(cfg)
            peaks.append(tracemalloc.get_traced_memory()[1])
        finally:
            tracemalloc.stop()
        assert isinstance(p.clock, FileClock)
    assert peaks[1] - peaks[0] < 1e6, peaks
