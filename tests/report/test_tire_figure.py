"""The tire figure's measured points: every one drawn up to SCATTER_MAX a panel, evenly spaced ones beyond, and the
legend saying so (an hour's 290k wheel samples drawn whole cost 1.9 s of the report's CPU)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from matplotlib.collections import PathCollection

from dynid.report import tires as report_tires
from dynid.vehicle.tire_curves import ALPHA_PURE, KAPPA_PURE, TireSamples


def samples(n: int, seed: int = 0) -> TireSamples:
    """n samples a wheel of each corner, rolling at 20 m/s, every one in both panels' selections: |α| and |κ| within
    half the pure-slip bounds (the free-rolling slip, the median κ of the free-rolling samples, is near 0)."""
    rng = np.random.default_rng(seed)
    N = 4 * n
    alpha = rng.uniform(-0.5, 0.5, N) * ALPHA_PURE
    kappa = rng.uniform(-0.25, 0.25, N) * KAPPA_PURE
    fz = rng.uniform(3000.0, 5000.0, N)
    return TireSamples(np.full(N, "t"), np.repeat(np.arange(4), n), np.tile(np.arange(n) / 50.0, 4), alpha, kappa,
                       np.zeros(N), np.full(N, 20.0), -20.0 * kappa * fz, -15.0 * alpha * fz, fz)


@pytest.mark.parametrize("n", [0, 1, 9_999, 10_000, 10_001, 29_999, 290_000])
def test_shown_every_sample_up_to_the_cap_then_evenly_spaced(n):
    mask = np.zeros(n + 7, bool)
    mask[3 : 3 + n] = True
    idx, some = report_tires.shown(mask)
    assert len(idx) <= report_tires.SCATTER_MAX
    if n <= report_tires.SCATTER_MAX:
        assert np.array_equal(idx, np.arange(3, 3 + n)) and some == ""
        return
    k = -(-n // report_tires.SCATTER_MAX)  # the least stride that fits: k - 1 would draw too many
    assert -(-n // (k - 1)) > report_tires.SCATTER_MAX
    assert np.array_equal(idx, np.arange(3, 3 + n, k))  # the first sample, then every k-th: none outside the mask
    assert some == f", 1 in {k} of {n:,}"


@pytest.mark.parametrize(("n", "expected"), [(1_000, 2_000), (30_000, 10_000)])
def test_tire_figure_draws_the_shown_points(monkeypatch, n, expected):
    """Each panel's scatter holds its axle's samples (2 wheels of n), thinned to 1 in 6 over the cap (60,000 of
    them); the legend says it."""
    drawn = []

    def capture(fig, plt, dpi: float = 90) -> bytes:
        drawn.extend(c for ax in fig.axes for c in ax.collections if isinstance(c, PathCollection))
        texts = [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]
        drawn.append(texts)
        plt.close(fig)
        return b""

    monkeypatch.setattr(report_tires, "_png", capture)
    report_tires.tire_figure(SimpleNamespace(samples=samples(n), lateral={}, longitudinal={}))
    *collections, texts = drawn
    assert [len(c.get_offsets()) for c in collections] == [expected] * 4
    if expected < 2 * n:
        assert texts == ["measured (pure slip, 1 in 6 of 60,000)"] * 2 + ["measured (1 in 6 of 60,000)"] * 2
    else:
        assert texts == ["measured (pure slip)"] * 2 + ["measured"] * 2  # the lateral panels, then the others
