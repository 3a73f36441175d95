"""The channel scan's holds and spikes (io/health.py) with its steps, sizes and pairs written into reused arrays.
Oracles: the formulas they replaced (np.diff(starts, append=n) for the holds' lengths; the pairs
np.where(the signs differ, min of the two sizes, 0) over np.diff of the holds' values, a spike where a pair exceeds
SPIKE times the sizes' 99th percentile and twice the resolution), on held, quantised, noisy signals with spikes
scanned in blocks of different lengths one after another and on two threads at once (each thread's arrays
reused: a longer block's values must not leak into a shorter one's)."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from dynid.io.health import SPIKE, ChannelScan, _held


def _signal(seed: int, n: int, hold: int, res: float) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 625.0
    x = np.sin(2 * np.pi * 0.7 * t) + 0.01 * rng.standard_normal(n)
    x[rng.integers(5, n - 5, 6)] += rng.choice([-1.0, 1.0], 6) * 0.5  # one-sample spikes
    if hold > 1:  # a held sensor: each value repeated
        x = np.repeat(x[::hold], hold)[:n]
    if res:
        x = np.round(x / res) * res
    return t, x


def _expected_spikes(t: np.ndarray, x: np.ndarray, res: float) -> list[float]:
    """The spikes' start times by the formulas the scan's in-place arithmetic replaced."""
    new = np.r_[True, x[1:] != x[:-1]]
    starts = np.flatnonzero(new)
    y = x[starts]
    step = np.diff(y)
    size = np.abs(step)
    sign = np.signbit(step)
    pair = np.where(sign[:-1] != sign[1:], np.minimum(size[:-1], size[1:]), 0.0)
    big = SPIKE * float(np.quantile(size, 0.99))
    hit = np.flatnonzero((pair > big) & (pair > 2 * res)) + 1
    return [float(t[starts[k]]) for k in hit]


@pytest.mark.parametrize("hold", [1, 3])
def test_held_lengths_are_the_differences_of_the_starts(hold):
    _, x = _signal(1, 5000, hold, 0.001)
    starts, lengths = _held(x)
    if hold == 1 and starts is None:
        return
    np.testing.assert_array_equal(lengths, np.diff(starts, append=x.size))


def test_spikes_in_blocks_one_after_another_and_on_two_threads():
    cases = [(seed, n, hold, res) for seed, (n, hold, res) in enumerate(
        [(30000, 1, 0.0), (2000, 1, 0.001), (12000, 3, 0.001), (3000, 1, 0.0), (25000, 1, 0.01)])]

    def scan(case) -> list[float]:
        t, x = _signal(*case)
        s = ChannelScan("x", "", None, case[3])
        s.add(t, x)
        return [a for a, _ in s.spikes.spans]

    expected = [_expected_spikes(*_signal(*c)[:2], c[3]) for c in cases]
    assert all(expected), "each signal must hold spikes for the test to mean anything"
    assert [scan(c) for c in cases] == expected  # long, short, long, short: the reused arrays overwritten
    got: dict[int, list] = {}

    def worker(k: int) -> None:
        got[k] = [scan(c) for c in (cases if k == 0 else cases[::-1])]

    threads = [threading.Thread(target=worker, args=(k,)) for k in (0, 1)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert got[0] == expected and got[1] == expected[::-1]
