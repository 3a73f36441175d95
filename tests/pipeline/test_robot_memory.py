"""A robot test's identification rows are built a segment at a time (issue 18): memory does not grow with the
full-rate regressor, and the rows do not depend on the segmenting.

Oracle: the same test done as one segment (the whole record at once, as before the segmenting). The
segments overlap by the decimation filters' transient to 1e-9 of their weight, so the stitched rows equal the
whole record's to that level times the signal (measured 5e-12 relative); 1e-9 leaves room for any CPU's
rounding of the filters (recursions of ~1e4 steps at 1e-16 each)."""

from __future__ import annotations

import os
import tracemalloc

import numpy as np
import pytest

from dynid import load_model
from dynid.pipeline.robot import Conditioning, JointTest, joint_system

FS = 1000.0


def _test(n: int) -> JointTest:
    model = load_model("tx40")
    t = np.arange(n) / FS
    q = np.stack([0.5 * np.sin(2 * np.pi * (0.3 + 0.1 * j) * t + j) + 0.2 * np.sin(2 * np.pi * 1.7 * (1 + 0.1 * j) * t)
                  for j in range(6)], axis=1)
    qd = np.gradient(q, 1 / FS, axis=0)
    tau = model.inverse_dynamics(q, qd, np.gradient(qd, 1 / FS, axis=0))
    return JointTest("sines", FS, q, tau)


@pytest.mark.parametrize("segment_bytes", [2**20, 3 * 2**20 + 12345], ids=["1 MiB", "odd size"])
@pytest.mark.slow
def test_segmented_rows_equal_the_whole_records(segment_bytes):
    model = load_model("tx40")
    base = model.base_parameters()
    test, c = _test(30000), Conditioning(cutoff=20.0, decimate=(10, 10))
    whole = joint_system(model, test, base, c, segment_bytes=2**40)
    parts = joint_system(model, test, base, c, segment_bytes=segment_bytes)
    assert parts.W.shape == whole.W.shape and np.array_equal(parts.groups, whole.groups)
    assert np.array_equal(parts.t, whole.t)
    assert np.max(np.abs(parts.W - whole.W)) <= 1e-9 * np.max(np.abs(whole.W))
    assert np.max(np.abs(parts.Y - whole.Y)) <= 1e-9 * np.max(np.abs(whole.Y))


@pytest.mark.slow
def test_memory_does_not_grow_with_the_full_rate_regressor():
    """100 s at 1 kHz: the full-rate W of the TX40's 60 base columns would be 275 MiB; built in 16 MiB segments,
    the peak stays under half of it (measured 80 MiB: the conditioned joint signals, one segment's W and its
    decimation work space)."""
    model = load_model("tx40")
    base = model.base_parameters()
    n = 100_000
    test, c = _test(n), Conditioning(cutoff=20.0, decimate=(10, 10))
    full_w = n * 6 * len(base.columns) * 8
    tracemalloc.start()
    try:
        joint_system(model, test, base, c, segment_bytes=16 * 2**20)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < full_w / 2, (peak / 2**20, full_w / 2**20)


ROBOT_CONFIG = """
[model]
example = "tx40"

[[tests]]
name = "sines"
files = {{ q = "{file}", tau = "{file}" }}

[channels]
q = {{ channels = ["q1", "q2", "q3", "q4", "q5", "q6"], unit = "rad" }}
tau = {{ channels = ["tau1", "tau2", "tau3", "tau4", "tau5", "tau6"], unit = "N*m" }}

[conditioning]
cutoff = 20.0
decimate = [10, 10]
"""


def robot_log(folder, n: int = 30000):
    """The sines test as a logger file (Parquet, a time column) and its config."""
    from dynid.io import Channel, Recording, write_recording

    test = _test(n)
    t = np.arange(n) / FS
    chans = [Channel(f"q{j + 1}", "rad", test.q[:, j], t) for j in range(6)]
    chans += [Channel(f"tau{j + 1}", "N*m", test.tau[:, j], t) for j in range(6)]
    write_recording(Recording.from_channels(chans), folder / "sines.parquet")
    cfg = folder / "robot.toml"
    cfg.write_text(ROBOT_CONFIG.format(file="sines.parquet"))
    return cfg


@pytest.mark.slow
def test_rows_read_a_chunk_at_a_time_from_the_file_equal_the_whole_records(tmp_path, monkeypatch):
    """The identification reads a robot's file a chunk at a time (each chunk's window with the filter's and the
    decimation's transients around it): its rows equal those of the whole record read at once, to the filters'
    tails (1e-9, as above)."""
    from dynid.pipeline import robot
    from dynid.pipeline.config import load_config
    from dynid.pipeline.run import load_joint_test, robot_systems
    from dynid.pipeline.schedulers import LocalScheduler

    cfg = load_config(robot_log(tmp_path))
    model = load_model("tx40")
    base = model.base_parameters()
    whole = joint_system(model, load_joint_test(cfg, cfg.tests[0], model.n), base, cfg.conditioning,
                         segment_bytes=2**40)
    chunk = 300 * robot.chunk_sample_bytes(model, base, cfg.conditioning)  # 300-sample chunks
    monkeypatch.setattr(robot, "CHUNK_BYTES", chunk)
    said: list[str] = []
    parts = robot_systems(cfg, model, base, LocalScheduler(2), said.append, all_rows=True)["identify"].rows["sines"]
    chunks = robot.robot_chunks(30000, FS, model, base, cfg.conditioning)
    assert len(chunks) > 50 and any(m == f"segments done {len(chunks)}/{len(chunks)}" for m in said), said
    assert parts.W.shape == whole.W.shape and np.array_equal(parts.groups, whole.groups)
    assert np.array_equal(parts.t, whole.t)
    assert np.max(np.abs(parts.W - whole.W)) <= 1e-9 * np.max(np.abs(whole.W))
    assert np.max(np.abs(parts.Y - whole.Y)) <= 1e-9 * np.max(np.abs(whole.Y))


@pytest.mark.slow
def test_a_bad_sample_deep_in_a_chunked_file_is_named_by_the_tests_sample(tmp_path, monkeypatch):
    """A chunk counts its samples from 0; the error names the test's sample (and its time), as the whole read did."""
    from dynid.io import Channel, DataError, Recording, read_recording, write_recording
    from dynid.pipeline import robot
    from dynid.pipeline.config import load_config
    from dynid.pipeline.run import identify

    cfg = robot_log(tmp_path)
    chans = dict(read_recording(tmp_path / "sines.parquet").channels)
    bad = chans["q3"].values.copy()
    bad[25000] = np.nan
    chans["q3"] = Channel("q3", "rad", bad, chans["q3"].time)
    write_recording(Recording.from_channels(list(chans.values())), tmp_path / "sines.parquet")
    monkeypatch.setattr(robot, "CHUNK_BYTES", 300 * 528)  # 300-sample chunks of the TX40's: 25000 is in a late one
    with pytest.raises(DataError) as exc:
        identify(load_config(cfg))
    assert "channel 'q3', sample 25000 (t = 25 s): value is nan" in str(exc.value), str(exc.value)
    assert exc.value.sample == 25000


@pytest.mark.parametrize("jitter", [0.0, 0.05], ids=["holes", "holes and jitter"])
def test_windows_anywhere_in_a_file_with_holes_equal_the_whole_read(tmp_path, jitter):
    """A window read for one chunk equals the whole file read at once (the old whole-file path: one window over
    every sample) to 1e-9 of the signal, wherever it starts: inside, at or just after a hole as long as max_gap
    allows (the window must reach a sample beyond it), on a uniform or a jittered clock (resampled: the cubic's
    end effect must have died out within the window's margin)."""
    from dynid.io import Channel, Recording, write_recording
    from dynid.pipeline.config import load_config
    from dynid.pipeline.sources import plan_robot_test, read_robot_window

    n = 30000
    test = _test(n)
    rng = np.random.default_rng(7)
    t = (np.arange(n) + jitter * rng.uniform(-1, 1, n)) / FS
    keep = np.ones(n, bool)
    keep[10001:10010 if not jitter else 10009] = False  # 10 periods (9 with jitter): max_gap = 10 refuses longer
    keep[20001:20009] = False
    t, q, tau = t[keep], test.q[keep], test.tau[keep]
    chans = [Channel(f"q{j + 1}", "rad", q[:, j], t) for j in range(6)]
    chans += [Channel(f"tau{j + 1}", "N*m", tau[:, j], t) for j in range(6)]
    write_recording(Recording.from_channels(chans), tmp_path / "sines.parquet")
    (tmp_path / "robot.toml").write_text(ROBOT_CONFIG.format(file="sines.parquet"))
    cfg = load_config(tmp_path / "robot.toml")
    plan = plan_robot_test(cfg, cfg.tests[0])
    whole = read_robot_window(plan, 0, plan.samples)
    for lo in (10000, 10001, 10005, 10009, 10010, 15000, 19990, 20001, 20009):
        for quantity in ("q", "tau"):
            part = read_robot_window(plan, lo, lo + 500)[quantity]
            ref = whole[quantity][lo:lo + 500]
            assert np.max(np.abs(part - ref)) <= 1e-9 * np.max(np.abs(ref)), (lo, quantity)


def test_a_blocks_derivatives_are_the_whole_windows_bits():
    """Oracle: `filtered_derivatives` over the whole window (what a chunk held before). A W block's qd, qdd come
    from the filtered positions two samples beyond it, so they are the same element-wise differences: the same
    bits, at the window's ends (its one-sided formulas) and inside."""
    from dynid.pipeline.robot import _block_derivatives
    from dynid.signals import filtered_derivatives

    q = _test(5000).q
    whole = filtered_derivatives(q, FS, 20.0, order=4, nderiv=2)
    for a, z in ((0, 700), (1, 2), (2, 3000), (1234, 4321), (4000, 4999), (4000, 5000), (0, 5000)):
        block = _block_derivatives(whole[0], a, z, FS)
        for got, ref in zip(block, whole, strict=True):
            assert np.array_equal(got, ref[a:z]), (a, z)


@pytest.mark.slow
def test_the_robot_map_holds_one_chunk_at_a_time_on_this_machines_threads(tmp_path, monkeypatch):
    """Oracle: the same map on one thread (the chunks' jobs one by one, their blocks on one thread). On a
    LocalScheduler of 2 workers the chunks run one after another, each on 2 threads (`run.chunk_scheduler`), never
    two at once (their first-stage outputs held once, the next chunk's window read ahead: issue 25), and the
    factors and rows are the same bits."""
    import itertools
    import threading
    import time

    from dynid.pipeline import robot, run
    from dynid.pipeline.config import load_config
    from dynid.pipeline.schedulers import LocalScheduler, Staged

    cfg = load_config(robot_log(tmp_path, 12000))
    model = load_model("tx40")
    base = model.base_parameters()
    monkeypatch.setattr(robot, "CHUNK_BYTES", 2000 * robot.chunk_sample_bytes(model, base, cfg.conditioning))
    monkeypatch.setattr(robot, "BLOCK_BYTES", 2**18)  # a few blocks a chunk: the threads share them
    spans, lock, real = [], threading.Lock(), run.reduce_robot_chunk

    def timed(job, read, ready):
        t0 = time.perf_counter()
        out = real.finish(job, read, ready)
        with lock:
            spans.append((t0, time.perf_counter(), getattr(job, "threads", 1)))
        return out

    # the chunks' finishes timed (their W blocks), the next chunk's read ahead as it runs (`schedulers.Staged`)
    monkeypatch.setattr(run, "reduce_robot_chunk", Staged(real.first, timed))
    two = run.robot_systems(cfg, model, base, LocalScheduler(2), lambda _m: None, all_rows=True)["identify"]
    spans.sort()
    assert len(spans) > 3
    assert all(b0 >= a1 for (_, a1, _), (b0, _, _) in itertools.pairwise(spans)), "two chunks at once"
    assert all(k == min(2, os.cpu_count() or 1) for _, _, k in spans)
    one = run.robot_systems(cfg, model, base, LocalScheduler(1), lambda _m: None, all_rows=True)["identify"]
    assert np.array_equal(two.rows["sines"].W, one.rows["sines"].W)
    assert np.array_equal(two.rows["sines"].Y, one.rows["sines"].Y)
    assert np.array_equal(two.ls.solve().values, one.ls.solve().values)


def test_a_huge_worker_count_runs_a_chunk_on_the_machines_threads():
    """`[compute] workers = 1000000000` is valid (as many as there are): a chunk's W blocks then run on the
    machine's threads, each holding one block; sized by the count asked for, the run asked for 22 GB."""
    from dynid.pipeline.run import chunk_scheduler
    from dynid.pipeline.schedulers import LocalScheduler

    mapper, threads = chunk_scheduler(LocalScheduler(10**9))
    assert threads == (os.cpu_count() or 1) and mapper.workers == 1
    assert chunk_scheduler(LocalScheduler(1))[1] == 1


@pytest.mark.slow
def test_a_chunks_w_buffers_are_made_by_the_thread_that_read_it(tmp_path, monkeypatch):
    """A chunk's W block buffers (`robot.chunk_buffers`) are made at the end of its read, on the thread that read it
    ahead (in the heap its transients left free: issue 25), not by the calling thread beside the next read. Oracle
    for the rows: the buffers made by `chunk_rows` itself on the calling thread (as before): the same bits."""
    import threading

    from dynid.pipeline import reduce, robot, run
    from dynid.pipeline.config import load_config
    from dynid.pipeline.schedulers import LocalScheduler

    cfg = load_config(robot_log(tmp_path, 12000))
    model = load_model("tx40")
    base = model.base_parameters()
    monkeypatch.setattr(robot, "CHUNK_BYTES", 2000 * robot.chunk_sample_bytes(model, base, cfg.conditioning))
    monkeypatch.setattr(robot, "BLOCK_BYTES", 2**18)
    made, real = [], reduce.chunk_buffers

    def recorded(*args):
        made.append(threading.get_ident())
        return real(*args)

    monkeypatch.setattr(reduce, "chunk_buffers", recorded)
    ahead = run.robot_systems(cfg, model, base, LocalScheduler(2), lambda _m: None, all_rows=True)["identify"]
    chunks = robot.robot_chunks(12000, FS, model, base, cfg.conditioning)
    assert len(made) == len(chunks) > 3 and threading.get_ident() not in made
    monkeypatch.setattr(reduce, "chunk_buffers", lambda *_a: None)  # chunk_rows makes them, on this thread
    here = run.robot_systems(cfg, model, base, LocalScheduler(2), lambda _m: None, all_rows=True)["identify"]
    assert np.array_equal(ahead.rows["sines"].W, here.rows["sines"].W)
    assert np.array_equal(ahead.rows["sines"].Y, here.rows["sines"].Y)
    assert np.array_equal(ahead.ls.solve().values, here.ls.solve().values)


@pytest.mark.slow
def test_a_chunk_in_order_takes_the_first_stage_outputs_of_the_chunk_before(tmp_path, monkeypatch):
    """This machine's map does a test's chunks in order: each chunk takes the first decimation stage's outputs the
    chunk before made on its span (the decimation's transient around their border) instead of W's blocks there.
    Oracle: the same chunks done apart (as a cluster's workers do them): the rows equal to the filters' tails
    (1e-9, as above: both are the whole record's to that), and W's samples asked for fewer by the shared spans."""
    from dynid.pipeline import reduce, robot, run
    from dynid.pipeline.config import load_config
    from dynid.pipeline.schedulers import LocalScheduler

    cfg = load_config(robot_log(tmp_path))
    model = load_model("tx40")
    base = model.base_parameters()
    monkeypatch.setattr(robot, "CHUNK_BYTES", 8000 * robot.chunk_sample_bytes(model, base, cfg.conditioning))
    real, asked = robot.decimate_parallel_blocked, []

    def counted(rows, *args, **kwargs):
        def rows_counted(lo, hi):
            asked.append(hi - lo)
            return rows(lo, hi)
        return real(rows_counted, *args, **kwargs)

    monkeypatch.setattr(robot, "decimate_parallel_blocked", counted)
    jobs: list = []
    order = run.robot_systems(cfg, model, base, LocalScheduler(2), lambda _m: None, all_rows=True,
                              jobs_out=jobs)["identify"]
    in_order = sum(asked)
    # one dict for the map's chunks, empty once it is done: no first-stage outputs held after it (or met by a
    # second map over the same jobs, the HAC pass's)
    assert len(jobs) >= 3 and all(j.handoff is jobs[0].handoff for j in jobs) and jobs[0].handoff == {}
    asked.clear()
    monkeypatch.setattr(run, "RobotJob", lambda *a, **k: reduce.RobotJob(*a, **{**k, "handoff": None}))
    apart = run.robot_systems(cfg, model, base, LocalScheduler(2), lambda _m: None, all_rows=True)["identify"]
    chunks = robot.robot_chunks(30000, FS, model, base, cfg.conditioning)
    assert len(chunks) >= 3
    pad = robot._decimation_transient(FS, cfg.conditioning.decimate)  # each border's shared span: 2 pad
    assert in_order < sum(asked) - (len(chunks) - 1) * pad, (in_order, sum(asked), pad)
    a, b = order.rows["sines"], apart.rows["sines"]
    assert a.W.shape == b.W.shape and np.array_equal(a.t, b.t) and np.array_equal(a.groups, b.groups)
    assert np.max(np.abs(a.W - b.W)) <= 1e-9 * np.max(np.abs(b.W))
    assert np.max(np.abs(a.Y - b.Y)) <= 1e-9 * np.max(np.abs(b.Y))
