"""Segments reduced anywhere, combined exactly: accumulator merges against the one-pass batch estimators, the
car identification on a Dask LocalCluster (2 worker processes on the loopback interface) against this machine's
threads, a worker killed mid-run, and a campaign of three configs against each config run alone."""

from __future__ import annotations

import os
import re
import signal
import threading

import numpy as np
import pytest

from dynid.estimation import Method, StreamingLS, ols, wls
from dynid.estimation.iv import InstrumentSums
from dynid.estimation.systematic import BiasAccumulator
from dynid.pipeline.config import load_config
from dynid.pipeline.run import identify
from dynid.pipeline.schedulers import LocalScheduler, tree_fold

# the rows are reduced in another order (a tree of QR factors instead of one after the other): the estimates move
# by round-off amplified by the weighted system's condition number (~1e3 on the car), far below 1e-9 relative
REL = 1e-9


def _system(rng, m=400, p=5, groups=("a", "b", "c")):
    W = rng.normal(size=(m, p)) * np.logspace(0, 2, p)
    g = np.array(groups)[rng.integers(0, len(groups), m)]
    scale = {k: 10.0 ** i for i, k in enumerate(groups)}
    Y = W @ np.arange(1.0, p + 1) + rng.normal(size=m) * np.array([scale[x] for x in g]) * 0.1
    return W, Y, g


def test_merged_accumulators_equal_the_batch_estimators():
    rng = np.random.default_rng(3)
    W, Y, g = _system(rng)
    names = [f"x{k}" for k in range(W.shape[1])]
    cuts = np.sort(rng.choice(np.arange(1, len(Y)), 6, replace=False))
    parts = []
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(Y)], strict=True):
        s = StreamingLS(names)
        s.add(W[a:b], Y[a:b], g[a:b])
        parts.append(s)
    merged = tree_fold(parts, StreamingLS.merge)
    assert merged.n_rows == len(Y) and merged.group_rows == {k: int((g == k).sum()) for k in merged.group_rows}
    for got, want in ((merged.solve(), ols(W, Y, names)), (merged.solve_weighted(), wls(W, Y, g, names))):
        np.testing.assert_allclose(got.values, want.values, rtol=1e-11)
        np.testing.assert_allclose(got.std, want.std, rtol=1e-9)
    # merge is pure: the parts still hold their own rows
    assert sum(p.n_rows for p in parts) == len(Y)


def test_merged_sums_equal_one_pass_sums():
    rng = np.random.default_rng(4)
    W, Y, g = _system(rng, m=120, p=4)
    Z, dW, dY = (W + rng.normal(size=W.shape), rng.normal(size=W.shape), rng.normal(size=len(Y)))
    cols, none = np.arange(4), np.array([], dtype=int)
    whole_iv, whole_b = InstrumentSums(cols, none, np.array([])), BiasAccumulator(cols, none, np.array([]))
    whole_iv.add(W, Y, Z, g)
    whole_b.add("s", W, Y, dW, dY, g, 2.0, Z=Z, dZ=dW)
    halves_iv, halves_b = [], []
    for rows in (slice(0, 50), slice(50, None)):
        i, b = InstrumentSums(cols, none, np.array([])), BiasAccumulator(cols, none, np.array([]))
        i.add(W[rows], Y[rows], Z[rows], g[rows])
        b.add("s", W[rows], Y[rows], dW[rows], dY[rows], g[rows], 2.0, Z=Z[rows], dZ=dW[rows])
        halves_iv.append(i)
        halves_b.append(b)
    iv, bias = halves_iv[0].merge(halves_iv[1]), halves_b[0].merge(halves_b[1])
    assert iv.rows == whole_iv.rows
    for k in whole_iv.terms:
        for got, want in zip(iv.terms[k], whole_iv.terms[k], strict=True):
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
        for got, want in zip(bias.terms["s"][k], whole_b.terms["s"][k], strict=True):
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())


# ----------------------------------------------------------------------------------------- the car on Dask
distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def car_config(tmp_path_factory):
    """The quick demo's noise-free files, identified in 4 s segments (several per test, so the fold matters)."""
    from dynid.pipeline.demo import simulate_tests, write_demo

    out = tmp_path_factory.mktemp("cluster")
    config = write_demo(out, simulate_tests(quick=True), seed=2, noise=True, fmt="parquet")
    text = config.read_text()
    text = re.sub(r"\[conditioning\]", "[conditioning]\nsegment = 4.0", text) if "[conditioning]" in text \
        else text + "\n[conditioning]\nsegment = 4.0\n"
    config.write_text(text)
    return config


def _same(a, b, rel=REL):
    ra, rb = a.result, b.result
    assert list(ra.names) == list(rb.names)
    np.testing.assert_allclose(rb.values, ra.values, rtol=rel, atol=0)
    np.testing.assert_allclose(rb.std, ra.std, rtol=rel, atol=0)
    assert ra.weights.keys() == rb.weights.keys()
    np.testing.assert_allclose([rb.weights[k] for k in ra.weights], list(ra.weights.values()), rtol=rel)
    np.testing.assert_allclose(rb.systematic.covariance, ra.systematic.covariance, rtol=1e-8,
                               atol=1e-12 * np.abs(ra.systematic.covariance).max())
    for kind in ("direct", "cross"):
        assert a.errors[kind].keys() == b.errors[kind].keys()
        np.testing.assert_allclose([b.errors[kind][k] for k in a.errors[kind]], list(a.errors[kind].values()),
                                   rtol=rel)


@pytest.fixture(scope="module")
def threads_run(car_config):
    said: list[str] = []
    run = identify(load_config(car_config), progress=said.append, scheduler=LocalScheduler(2))
    return run, said


@pytest.fixture(scope="module")
def cluster():
    """2 single-threaded worker processes on the loopback interface, for this module's tests; bounded in time: a
    cluster that hangs ends the test run (SIGALRM) instead of CI's whole budget."""
    from dynid.pipeline.schedulers import DaskScheduler

    signal.alarm(900)  # the module takes ~100 s on 2 cores
    try:
        with DaskScheduler("local", workers=2) as s:
            yield s
    finally:
        signal.alarm(0)


@pytest.mark.slow
@pytest.mark.e2e
def test_a_local_cluster_gives_the_threads_result(car_config, threads_run, cluster):
    run, said = threads_run
    segments = [m for m in said if m.startswith("segments done")]
    total = int(segments[-1].split("/")[1].split()[0])
    assert total > len(run.config.tests), said  # several segments per test: the fold has a shape
    assert 0.3 < run.result.value("M6") / 1645 < 3  # a real identification, not an empty one
    said_cluster: list[str] = []
    other = identify(load_config(car_config), progress=said_cluster.append, scheduler=cluster)
    _same(run, other)
    done = [m for m in said_cluster if m.startswith("segments done")]
    assert done[-1].startswith(f"segments done {total}/{total} on Dask cluster local (2 worker(s))"), done


@pytest.mark.slow
@pytest.mark.e2e
def test_a_worker_killed_mid_run_changes_nothing(car_config, threads_run, cluster):
    client = cluster.client
    pids = client.run(os.getpid)  # {worker address: pid}
    killed = threading.Event()

    def progress(message: str) -> None:
        if message.startswith("segments done") and not killed.is_set():
            killed.set()
            os.kill(next(iter(pids.values())), signal.SIGKILL)  # a worker lost with its results and tasks

    other = identify(load_config(car_config), progress=progress, scheduler=cluster)
    assert killed.is_set()
    _same(threads_run[0], other)


@pytest.mark.slow
@pytest.mark.e2e
def test_a_campaign_gives_each_config_its_own_result(car_config, threads_run, cluster, tmp_path):
    from dynid.pipeline.campaign import campaign_names, identify_campaign, summary

    text = car_config.read_text()
    configs = [car_config]
    # a second load state: the same files with the front springs weighed on a bench; a third: OLS
    changes = {"bench.toml": lambda t: t.replace("[identification]", "[identification]\nknown = { ks9 = 24425.0 }"),
               "ols.toml": lambda t: re.sub(r'method = "\w+"', 'method = "ols"', t)}
    for name, change in changes.items():
        c = car_config.parent / name
        c.write_text(change(text))
        configs.append(c)
    cfgs = [load_config(c) for c in configs]
    runs = identify_campaign(cfgs, cluster)
    _same(threads_run[0], runs[0])
    for cfg, run in zip(cfgs[1:], runs[1:], strict=True):
        _same(identify(cfg, scheduler=LocalScheduler(2)), run)
    assert "ks9" not in runs[1].result.estimated_names and runs[2].result.method is Method.OLS
    head, rows = summary(campaign_names(configs), runs)
    assert [r[0] for r in rows] == ["identify", "bench", "ols"] and "total mass [kg]" in head
    mass = head.index("total mass [kg]")
    for run, row in zip(runs, rows, strict=True):
        value = float(row[mass].split(" ± ")[0])
        assert value == pytest.approx(run.result.value("M6") + 140.0, rel=1e-5)  # the wheels: 4 x 35 kg, known


@pytest.mark.slow
@pytest.mark.e2e
def test_a_robot_on_the_cluster_gives_the_threads_result(cluster, tmp_path, monkeypatch):
    """A robot's chunks (read from its file by the workers) stack into the same rows, hence the same estimate, to
    the decimation filters' tails: this machine's threads do a test's chunks in order, each taking the first
    decimation stage's outputs the chunk before made on their shared span, where a cluster's worker makes them
    from its own window, whose start is an edge at 1e-9 of the kept rows' weight (`robot.chunk_rows`' before).
    Both are the whole record's rows to that 1e-9 (test_robot_memory). How far that moves an estimate is the
    problem's conditioning's, not bounded by the rows alone (Cauchy-Schwarz gives |dθ_i| <= σ_i |dr| / s, loose on
    noise-free rows), so the tolerance is a measured one: 3.4e-13 of the largest value apart (2.0e-9 relative at a
    near-zero XZ6, 3.7e-10 of its σ), against 1e-9 of the largest value, kept under a tenth of every σ (0.064 σ
    at most here): it can never pass a change the estimate's own uncertainty would notice."""
    from test_robot_memory import robot_log

    from dynid.pipeline import robot

    monkeypatch.setattr(robot, "CHUNK_BYTES", 2**20)  # several chunks (the client cuts them)
    cfg = load_config(robot_log(tmp_path))
    threads = identify(cfg, scheduler=LocalScheduler(2))
    other = identify(cfg, scheduler=cluster)
    largest = np.max(np.abs(threads.result.values))
    assert REL * largest < 0.1 * np.min(threads.result.std), (largest, np.min(threads.result.std))
    np.testing.assert_allclose(other.result.values, threads.result.values, rtol=REL, atol=REL * largest)
    np.testing.assert_allclose(other.result.std, threads.result.std, rtol=REL, atol=0)
    assert other.errors["direct"] == pytest.approx(threads.errors["direct"], rel=REL)


@pytest.mark.slow
@pytest.mark.e2e
def test_a_broken_config_does_not_lose_the_campaign(car_config, threads_run, tmp_path, capsys):
    """One config's file is cut short: the others' folders and campaign.csv are written, its error is in the table
    and on stderr, and the command exits with 2."""
    import shutil

    from dynid.cli.main import main

    broken_dir = tmp_path / "broken"
    shutil.copytree(car_config.parent, broken_dir)
    data = next(p for p in sorted((broken_dir / "data").glob("*.parquet")))
    data.write_bytes(data.read_bytes()[: len(data.read_bytes()) // 3])  # a truncated Parquet file
    broken = broken_dir / "broken.toml"
    broken.write_text(car_config.read_text())
    out = tmp_path / "campaign"
    code = main(["identify", str(car_config), str(broken), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "dynid: error: broken: " in err and data.name in err, err
    table = (out / "campaign.csv").read_text().splitlines()
    assert table[0].endswith(",error") and table[1].startswith("identify,") and table[2].startswith("broken,")
    assert (out / "identify" / "results.json").exists() and not (out / "broken").exists()
    import json

    values = {p["name"]: p["value"] for p in json.loads((out / "identify" / "results.json").read_text())["parameters"]}
    assert values["M6"] == pytest.approx(threads_run[0].result.value("M6"), rel=REL)
