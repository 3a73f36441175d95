"""Tests of dynid.io.health's bookkeeping of what a channel scan found: what it keeps does not grow with the findings.

Oracle: the data themselves (spikes and out-of-range runs put at known samples; the finding's count, first spans,
last end, values and largest value read from where they were put), and the old code's sizes: a scan held every
span it found, a tuple and a value each, for as long as the identification ran.
"""

from __future__ import annotations

import pickle

import numpy as np

from dynid.io.health import ERROR, WARNING, ChannelScan

FS = 625.0
BLOCK = 6250  # 10 s


def spiky(blocks: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """White noise (σ 0.01, fixed seed) with a spike of +-0.3 every second from 0.5 s: (t, x, the spikes' samples)."""
    rng = np.random.default_rng(7)
    n = blocks * BLOCK
    t = np.arange(n) / FS
    x = 0.01 * rng.standard_normal(n)
    at = np.arange(312, n, 625)
    x[at] += 0.3 * np.where(np.arange(at.size) % 2, -1.0, 1.0)
    return t, x, at


def scanned(t: np.ndarray, x: np.ndarray, merged: bool, **options) -> ChannelScan:
    """A scan fed block by block (merged: each block's own scan, merged in time order, as the map's fold does)."""
    if not merged:
        scan = ChannelScan("x", "deg/s", **options)
        for a in range(0, t.size, BLOCK):
            scan.add(t[a:a + BLOCK], x[a:a + BLOCK])
        return scan
    parts = []
    for a in range(0, t.size, BLOCK):
        parts.append(ChannelScan("x", "deg/s", **options))
        parts[-1].add(t[a:a + BLOCK], x[a:a + BLOCK])
    while len(parts) > 1:
        parts = [parts[i].merge(parts[i + 1]) if i + 1 < len(parts) else parts[i] for i in range(0, len(parts), 2)]
    return parts[0]


def test_a_scan_keeps_the_same_bytes_whatever_the_count_of_spikes_it_finds():
    """20 spikes against 80 (2 and 8 blocks of 10 s), fed in order or merged: the scan's pickled bytes the same
    within a few bytes (its counts' integers). Before, every spike's span and value were kept: ~60 bytes each."""
    for merged in (False, True):
        sizes = []
        for blocks in (2, 8):
            t, x, at = spiky(blocks)
            scan = scanned(t, x, merged)
            (found,) = scan.findings()
            assert found.kind == "spike" and found.detail.startswith(f"{at.size} spike(s)")
            sizes.append(len(pickle.dumps(scan)))
        assert sizes[1] - sizes[0] <= 16, sizes


def test_a_spike_finding_says_the_count_the_first_spans_the_last_and_the_largest():
    """The finding's words from where the spikes were put: their count, the first three times, the last one, the
    largest in absolute value (the first of equals), whether the scan was fed in order or merged."""
    t, x, at = spiky(3)
    top = x[at][np.argmax(np.abs(x[at]))]
    first = "; ".join(f"t = {v:.6g} s" for v in t[at[:3]])
    for merged in (False, True):
        (found,) = scanned(t, x, merged).findings()
        assert found.severity == WARNING
        assert found.detail == f"{at.size} spike(s) ({first} ...; up to {top:g} deg/s)", found.detail
        assert (found.t_start, found.t_end) == (t[at[0]], t[at[-1]])
        assert found.share == at.size / t.size


def test_an_out_of_range_finding_lists_the_first_values_as_written():
    """Six runs beyond a declared range of +-1 (values 1.5, 2, 2.5, 3, -4 and 1.5 again, 3 samples each, at known
    times) in three blocks: the values sorted as text, the first three and "...", six spans, the first three
    times and the last end."""
    t = np.arange(3 * BLOCK) / FS
    x = np.zeros(t.size)
    starts = [1000, 3000, 7000, 9000, 13000, 17000]
    for a, v in zip(starts, (1.5, 2.0, 2.5, 3.0, -4.0, 1.5), strict=True):
        x[a:a + 3] = v
    for merged in (False, True):
        found = [f for f in scanned(t, x, merged, limits=(-1.0, 1.0)).findings() if f.kind == "out of range"]
        assert len(found) == 1
        f = found[0]
        assert f.severity == ERROR and f.share == 18 / t.size
        spans = "; ".join(f"t = {t[a]:.6g}..{t[a + 2]:.6g} s" for a in starts[:3])
        assert f.detail == ("beyond the sensor's declared range (-1..1 deg/s) on 18 sample(s), "
                            f"{100 * 18 / t.size:.3g} % of the test (-4 deg/s, 1.5 deg/s, 2 deg/s, ...), in 6 span(s) "
                            f"({spans} ...)"), f.detail
        assert (f.t_start, f.t_end) == (t[starts[0]], t[starts[-1] + 2])
