"""Tests of dynid.signals against closed forms.

Oracles used (none is the code under test run a second time):
- the Butterworth magnitude in closed form: the digital design is the bilinear
  transform of the analog prototype with the cut-off prewarped, so one pass has
  |H(f)|^2 = 1 / (1 + (tan(pi f/fs) / tan(pi fc/fs))^(2 n)), and forward-backward
  multiplies a sinusoid by exactly that, with no phase;
- the exact gains of the difference formulas on sinusoids: the central difference
  gives sin(w h)/(w h) times the true derivative, the cumulative trapezoid gives
  (w h/2) cot(w h/2) times the true integral;
- Taylor / Peano error bounds of central differences, trapezoids and interpolation;
- linearity: a consistent system Y = W X stays consistent under any linear filter
  applied alike to every column, so least squares gives back X.
"""

from __future__ import annotations

import re
import tracemalloc

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import butter, sosfilt

from dynid.signals import (
    SignalError,
    border_samples,
    common_clock,
    decimate_parallel,
    derivative,
    filtered_derivatives,
    integrate,
    lowpass,
    resample,
    trim,
)

FS = 625.0  # the paper's 1.6 ms sample time
H = 1.0 / FS


def power_gain(f, fs, fc, order):
    """Closed-form |H(f)|^2 of a digital Butterworth low-pass of one pass (= the forward-backward gain)."""
    rho = np.tan(np.pi * np.asarray(f) / fs) / np.tan(np.pi * fc / fs)
    return 1.0 / (1.0 + rho ** (2 * order))


def sine_fit(t, y, w):
    """Amplitude and phase (rad) of the sinusoid of angular frequency w that best fits y(t)."""
    basis = np.column_stack([np.sin(w * t), np.cos(w * t)])
    (s, c), *_ = np.linalg.lstsq(basis, y, rcond=None)
    return float(np.hypot(s, c)), float(np.arctan2(c, s))


# ---------------------------------------------------------------- lowpass


def test_lowpass_sinusoid_in_pass_band_has_no_lag_and_unit_amplitude():
    f, fc, order = 1.0, 3.0, 4
    t = np.arange(int(20 * FS)) * H
    x = np.sin(2 * np.pi * f * t)
    y = lowpass(x, FS, fc, order)
    causal = sosfilt(butter(order, fc, fs=FS, output="sos"), x)  # one pass: delays, to show the test can tell

    # Cross-correlation over a window of whole periods in the middle, lags -50..50.
    period = int(FS / f)
    window = np.arange(7 * period, 13 * period)
    lags = np.arange(-50, 51)

    def xcorr(out):
        return np.array([out[window] @ x[window - k] for k in lags])

    assert lags[np.argmax(xcorr(y))] == 0
    assert lags[np.argmax(xcorr(causal))] > 5
    amplitude, phase = sine_fit(t[window], y[window], 2 * np.pi * f)
    assert abs(phase) < 1e-7
    assert amplitude == pytest.approx(power_gain(f, FS, fc, order), abs=1e-7)
    assert amplitude == pytest.approx(1.0, abs=2e-4)  # (1/3)^8 = 1.5e-4 of pass-band droop


def test_lowpass_gain_follows_butterworth_formula_on_every_channel_along_axis():
    fc, order = 3.0, 4
    freqs = np.array([0.5, 2.0, 3.0, 4.5])  # at the cut-off the forward-backward gain is exactly 1/2
    t = np.arange(int(24 * FS)) * H
    x = np.sin(2 * np.pi * freqs[:, None] * t[None, :] + 0.3)  # channels on axis 0, time on axis 1
    y = lowpass(x, FS, fc, order, axis=1)
    assert y.shape == x.shape
    window = slice(int(8 * FS), int(16 * FS))  # whole periods of every frequency, far from the ends
    for i, f in enumerate(freqs):
        amplitude, phase = sine_fit(t[window], y[i, window], 2 * np.pi * f)
        assert amplitude == pytest.approx(power_gain(f, FS, fc, order), abs=1e-6)
        assert abs(phase - 0.3) < 1e-5
    assert power_gain(3.0, FS, fc, order) == pytest.approx(0.5)


def test_lowpass_errors_name_the_problem():
    x = np.zeros(1000)
    with pytest.raises(SignalError, match=r"Nyquist.*312\.5 Hz"):
        lowpass(x, FS, 312.5)
    with pytest.raises(SignalError, match="order"):
        lowpass(x, FS, 3.0, order=0)
    with pytest.raises(SignalError, match="positive"):
        lowpass(x, -FS, 3.0)


def test_lowpass_too_short_message_gives_true_counts():
    with pytest.raises(SignalError) as info:
        lowpass(np.ones(10), FS, 3.0, order=4)
    message = str(info.value)
    have = int(re.search(r"has (\d+) samples", message).group(1))
    need = int(re.search(r"at least (\d+)", message).group(1))
    assert have == 10
    # The stated minimum is the true one: it works at `need` samples and fails just below.
    assert lowpass(np.ones(need), FS, 3.0, order=4) == pytest.approx(np.ones(need))
    with pytest.raises(SignalError):
        lowpass(np.ones(need - 1), FS, 3.0, order=4)


def test_lowpass_nan_message_names_first_sample_and_column():
    x = np.zeros((200, 3))
    x[70, 0] = np.nan
    x[40, 2] = np.inf
    x[40, 1] = np.nan  # same sample as the inf, earlier column: reported first
    with pytest.raises(SignalError, match=r"sample 40, column 1") as info:
        lowpass(x, FS, 3.0)
    assert "3 non-finite" in str(info.value)
    xt = np.zeros((3, 200))
    xt[2, 55] = np.nan
    with pytest.raises(SignalError, match=r"sample 55, column 2"):
        lowpass(xt, FS, 3.0, axis=1)
    w = np.zeros((200, 2, 4))
    w[9, 1, 3] = np.nan
    with pytest.raises(SignalError, match=r"sample 9, column \(1, 3\)"):
        lowpass(w, FS, 3.0)



@pytest.mark.parametrize("values", [[1e308, 1e308, -1e308], [np.inf, -np.inf, 0.0], [np.inf, 1.0, 2.0],
                                    [-1e308, -1e308, np.nan], [0.5, -0.25, 3.0]])
def test_finite_check_agrees_with_isfinite_whatever_the_sum(values):
    """Oracle: np.isfinite on every entry. The check's fast path reads the sum: finite entries whose sum overflows
    must still pass, and an inf with a -inf (sum NaN) or a NaN among huge values must still be caught."""
    from dynid.signals._checks import finite

    x = np.zeros((50, 3))
    x[17] = values
    if np.isfinite(x).all():
        finite(x, "x")
    else:
        with pytest.raises(SignalError, match="sample 17"):
            finite(x, "x")


# ---------------------------------------------------------------- derivatives

AMPS = np.array([0.8, 0.5, 0.3])
FREQS = np.array([0.3, 0.7, 1.1])  # Hz: "dynamics around 1 Hz"
PHASES = np.array([0.2, 1.0, -0.7])


def sum_of_sines(t, k=0):
    """k-th analytic derivative of sum_i A_i sin(w_i t + phi_i)."""
    w = 2 * np.pi * FREQS
    return np.sum(
        AMPS[:, None] * w[:, None] ** k * np.sin(w[:, None] * t[None, :] + PHASES[:, None] + k * np.pi / 2), 0
    )


def test_central_difference_meets_taylor_bound():
    t = np.arange(2000) * H
    xd = derivative(sum_of_sines(t), FS)
    # Central difference: error <= h^2/6 max|x'''|; one-sided end formula: <= h^2/3 max|x'''|.
    m3 = np.sum(AMPS * (2 * np.pi * FREQS) ** 3)
    err = np.abs(xd - sum_of_sines(t, 1))
    assert err[1:-1].max() <= H**2 / 6 * m3
    assert max(err[0], err[-1]) <= H**2 / 3 * m3
    with pytest.raises(SignalError, match="at least 3"):
        derivative(np.ones(2), FS)


@pytest.mark.parametrize("order", [4, 6])
def test_filtered_derivatives_match_analytic_derivatives(order):
    fc = 3.0
    t = np.arange(int(16 * FS)) * H
    q, qd, qdd = filtered_derivatives(sum_of_sines(t), FS, fc, order=order)
    # Far from the ends: beyond the border for tol = 1e-9 (plus the 2 samples of the
    # one-sided end formulas) the end transient is ~1e-9 of the amplitude, and its
    # derivatives ~ (2 pi fc)^k times that: negligible next to the bounds below.
    n = border_samples(FS, fc, order, tol=1e-9) + 2
    assert 2 * n < t.size - FS  # at least one second left to test
    w = 2 * np.pi * FREQS
    # Per component the operator multiplies the k-th derivative by G (sinc)^k, with
    # G = |H|^2 the forward-backward gain and sinc = sin(w h)/(w h) the central
    # difference gain. 1 - G = rho^2n / (1 + rho^2n) <= rho^2n, and
    # 1 - sinc^k <= k (w h)^2 / 6, so 1 - G sinc^k <= rho^2n + k (w h)^2 / 6, and the
    # error is at most sum_i A_i w_i^k (rho_i^2n + k (w_i h)^2 / 6).
    rho = np.tan(np.pi * FREQS / FS) / np.tan(np.pi * fc / FS)
    gain = power_gain(FREQS, FS, fc, order)
    sinc = np.sin(w * H) / (w * H)
    for k, out in enumerate((q, qd, qdd)):
        exact = sum_of_sines(t, k)[n:-n]
        bound = np.sum(AMPS * w**k * (rho ** (2 * order) + k * (w * H) ** 2 / 6))
        assert np.abs(out[n:-n] - exact).max() <= bound
        # Sharper: the output is the analytic derivative with each component scaled by
        # its closed-form gain, to the end-transient level.
        scaled = np.sum(
            (AMPS * w**k * gain * sinc**k)[:, None]
            * np.sin(w[:, None] * t[None, n:-n] + PHASES[:, None] + k * np.pi / 2),
            0,
        )
        assert np.abs(out[n:-n] - scaled).max() <= 1e-8 * np.sum(AMPS * w**k)


def test_filtered_derivatives_count_and_batch():
    t = np.arange(3000) * H
    x = np.stack([sum_of_sines(t), 2 * sum_of_sines(t)], axis=1)
    outs = filtered_derivatives(x, FS, 3.0, nderiv=1)
    assert len(outs) == 2 and all(o.shape == x.shape for o in outs)
    np.testing.assert_allclose(outs[1][:, 1], 2 * outs[1][:, 0], rtol=1e-12, atol=1e-12)  # linearity
    assert len(filtered_derivatives(x, FS, 3.0, nderiv=0)) == 1
    with pytest.raises(SignalError, match="nderiv"):
        filtered_derivatives(x, FS, 3.0, nderiv=-1)


# ---------------------------------------------------------------- integration


def test_trapezoid_integral_of_cos_within_bound_and_in_phase():
    w = 2 * np.pi * 1.3
    t = np.arange(int(10 * FS)) * H
    x = integrate(np.cos(w * t), FS)
    # Composite trapezoid on [0, t]: |error| <= t h^2 max|f''| / 12 = t h^2 w^2 / 12.
    err = np.abs(x - np.sin(w * t) / w)
    assert np.all(err <= t * H**2 * w**2 / 12 + 1e-15)
    # No phase shift: exactly sin(w t)/w times the gain (w h/2) cot(w h/2).
    np.testing.assert_allclose(x, (H / 2) / np.tan(w * H / 2) * np.sin(w * t), rtol=0, atol=1e-13)


def test_trapezoid_error_is_second_order():
    w, duration = 2 * np.pi * 1.3, 2.1
    errors = []
    for fs in (100.0, 200.0):
        t = np.arange(int(duration * fs) + 1) / fs
        errors.append(np.abs(integrate(np.cos(w * t), fs) - np.sin(w * t) / w).max())
    assert errors[0] / errors[1] == pytest.approx(4.0, rel=0.02)


@settings(max_examples=30, deadline=None)
@given(
    fs=st.floats(1.0, 5000.0),
    n=st.integers(1, 300),
    a=st.floats(-100.0, 100.0),
    b=st.floats(-100.0, 100.0),
)
def test_trapezoid_is_exact_on_linear_rates(fs, n, a, b):
    t = np.arange(n) / fs
    x0 = np.array([1.5, -2.0])
    xd = np.stack([a + b * t, b - a * t])  # channels on axis 0, time on axis 1
    x = integrate(xd, fs, x0=x0, axis=1)
    exact = np.stack([x0[0] + a * t + b * t**2 / 2, x0[1] + b * t - a * t**2 / 2])
    np.testing.assert_allclose(x, exact, rtol=1e-10, atol=1e-10 * (1 + abs(a) + abs(b)) * (1 + t[-1] ** 2))


def test_integrate_rejects_mismatched_x0():
    with pytest.raises(SignalError, match="x0"):
        integrate(np.ones((10, 3)), FS, x0=np.ones(4))


# ---------------------------------------------------------------- borders


def test_beyond_border_a_record_filters_as_if_it_were_endless():
    fc, order, tol = 3.0, 4, 1e-3
    rng = np.random.default_rng(1)
    long = rng.standard_normal(12000)  # white noise: the hardest case for the ends
    a, b = 4000, 8000
    seg = long[a:b]
    endless = lowpass(long, FS, fc, order)[a:b]  # the segment's ends are > 6 s from the record's
    err = np.abs(lowpass(seg, FS, fc, order) - endless)
    n = border_samples(FS, fc, order, tol)
    # The end extension (odd reflection 2 x0 - x[k], then a steady start) is within
    # 3 max|x| and the true continuation within max|x| (the long record is scaled
    # alike): mismatch E <= 4 max|x|, error <= E tol ||g||_1, and ||g||_1 = 1.38 < 2 for this filter.
    bound = 8 * tol * np.abs(long).max()
    assert err[n:-n].max() <= bound
    assert err[:n].max() > bound  # and the first samples really are spoiled


def test_border_samples_scales_with_time_constant():
    n = border_samples(FS, 3.0, 4)
    assert border_samples(2 * FS, 3.0, 4) == pytest.approx(2 * n, rel=0.01)
    assert border_samples(FS, 6.0, 4) == pytest.approx(n / 2, rel=0.01)
    assert border_samples(FS, 3.0, 4, tol=1e-6) > n > border_samples(FS, 3.0, 4, tol=1e-2)
    with pytest.raises(SignalError, match="tol"):
        border_samples(FS, 3.0, 4, tol=0.0)


def test_trim():
    x = np.arange(30).reshape(3, 10)
    np.testing.assert_array_equal(trim(x, 2, axis=1), x[:, 2:8])
    np.testing.assert_array_equal(trim(x, 0, axis=1), x)
    with pytest.raises(SignalError, match="leaves nothing"):
        trim(x, 5, axis=1)
    with pytest.raises(SignalError, match="n must be"):
        trim(x, -1)


# ---------------------------------------------------------------- decimation


def lstsq_stacked(W, Y):
    p = W.shape[-1]
    return np.linalg.lstsq(W.reshape(-1, p), Y.reshape(-1), rcond=None)[0]


@pytest.mark.parametrize("factor", [10, (10, 10)])
def test_decimated_consistent_system_gives_back_parameters(factor):
    rng = np.random.default_rng(7)
    n, m, p = 24000, 3, 6
    W = rng.standard_normal((n, m, p)) + np.sin(2 * np.pi * 0.4 * np.arange(n) * H)[:, None, None]
    X = rng.uniform(-3.0, 3.0, p) * 10.0 ** rng.integers(-2, 3, p)
    Y = np.einsum("nmp,p->nm", W, X)
    Wd, Yd = decimate_parallel(W, Y, factor, FS, block_columns=4)
    total = np.prod(factor)
    assert Wd.shape == (-(-n // total), m, p) and Yd.shape == (Wd.shape[0], m)
    x_dec = lstsq_stacked(Wd, Yd)
    assert np.linalg.norm(x_dec - X) <= 1e-10 * np.linalg.norm(X)
    if factor == 10:
        # The same system filtered (same filter on every column) but not decimated.
        cutoff = 0.8 * FS / (2 * 10)
        x_full = lstsq_stacked(lowpass(W, FS, cutoff, 8), lowpass(Y, FS, cutoff, 8))
        assert np.linalg.norm(x_dec - x_full) <= 1e-10 * np.linalg.norm(X)


def test_structural_zero_columns_stay_zero_and_the_others_are_filtered_alike():
    # Identification matrices are mostly structural zeros; decimation skips them (zero in, zero out)
    # and must filter the other columns exactly as if they were alone.
    rng = np.random.default_rng(3)
    n, m, p = 6000, 2, 5
    W = rng.standard_normal((n, m, p))
    W[:, 0, 1] = 0.0
    W[:, :, 3] = 0.0
    Y = rng.standard_normal((n, m))
    Wd, Yd = decimate_parallel(W, Y, 10, FS, block_columns=3)
    assert not Wd[:, 0, 1].any() and not Wd[:, :, 3].any()
    cutoff = 0.8 * FS / (2 * 10)
    np.testing.assert_allclose(Wd, lowpass(W, FS, cutoff, 8)[::10], rtol=0, atol=1e-12)
    np.testing.assert_allclose(Yd, lowpass(Y, FS, cutoff, 8)[::10], rtol=0, atol=1e-12)
    W_alone, no_y = decimate_parallel(W, None, 10, FS)  # W without a right-hand side
    assert no_y is None
    np.testing.assert_allclose(W_alone, lowpass(W, FS, cutoff, 8)[::10], rtol=0, atol=1e-12)


def test_decimation_passes_band_and_stops_aliases():
    n, factor, order = 12000, 10, 8
    t = np.arange(n) * H
    cutoff = 0.8 * FS / (2 * factor)  # 25 Hz; new Nyquist 31.25 Hz
    freqs = np.array([[1.0, 40.0], [2.0, 100.0]])  # 40 Hz would alias to 22.5 Hz, 100 Hz to 25 Hz
    W = np.sin(2 * np.pi * freqs[None, :, :] * t[:, None, None] + 0.1)
    Y = np.cos(2 * np.pi * np.array([0.5, 45.0])[None, :] * t[:, None])
    Wd, Yd = decimate_parallel(W, Y, factor, FS, order=order, block_columns=1)
    td = t[::factor]
    k = border_samples(FS, cutoff, order, tol=1e-9) // factor + 1
    expect_w = power_gain(freqs, FS, cutoff, order)[None] * np.sin(2 * np.pi * freqs[None] * td[:, None, None] + 0.1)
    expect_y = power_gain(np.array([0.5, 45.0]), FS, cutoff, order)[None] * np.cos(
        2 * np.pi * np.array([0.5, 45.0])[None] * td[:, None]
    )
    np.testing.assert_allclose(Wd[k:-k], expect_w[k:-k], rtol=0, atol=1e-6)
    np.testing.assert_allclose(Yd[k:-k], expect_y[k:-k], rtol=0, atol=1e-6)
    assert np.abs(Wd[k:-k, 0, 1]).max() < 1e-3  # the would-be alias is gone


def test_two_stage_decimation_gain_is_product_of_stage_gains():
    n, f = 30000, 0.5
    t = np.arange(n) * H
    W = np.sin(2 * np.pi * f * t)[:, None]  # (N, p) with p = 1
    Wd, Yd = decimate_parallel(W, np.zeros(n), (10, 10), FS)
    assert Wd.shape == (300, 1) and Yd.shape == (300,)
    gain = power_gain(f, FS, 0.8 * FS / 20, 8) * power_gain(f, FS / 10, 0.8 * FS / 200, 8)
    td = t[::100]
    k = border_samples(FS / 10, 0.8 * FS / 200, 8, tol=1e-9) // 10 + 1
    np.testing.assert_allclose(Wd[k:-k, 0], gain * np.sin(2 * np.pi * f * td[k:-k]), rtol=0, atol=1e-6)


def test_decimation_errors():
    n = 2000
    W, Y = np.zeros((n, 2, 3)), np.zeros((n, 2))
    with pytest.raises(SignalError, match="Y must be"):
        decimate_parallel(W, np.zeros(n), 10, FS)
    with pytest.raises(SignalError, match="integer >= 2"):
        decimate_parallel(W, Y, 1, FS)
    with pytest.raises(SignalError, match=r"stage 1.*alias"):
        decimate_parallel(W, Y, 10, FS, cutoff=40.0)
    with pytest.raises(SignalError, match="one per stage"):
        decimate_parallel(W, Y, (10, 10), FS, cutoff=20.0)
    with pytest.raises(SignalError, match=r"stage 2 \(factor 10 at 62\.5 Hz\) gets 25 samples"):
        decimate_parallel(W[:250], Y[:250], (10, 10), FS)
    W[123, 1, 2] = np.nan
    with pytest.raises(SignalError, match=r"W has .* at sample 123, column \(1, 2\)"):
        decimate_parallel(W, Y, 10, FS)


# ---------------------------------------------------------------- resampling


def smooth(t):
    return np.sin(2 * np.pi * 0.5 * t) + 0.3 * np.cos(2 * np.pi * 1.3 * t + 0.4)


def smooth_bound(k):
    """max |d^k/dt^k smooth|."""
    return (2 * np.pi * 0.5) ** k + 0.3 * (2 * np.pi * 1.3) ** k


def test_resample_jittered_channel_onto_common_clock():
    rng = np.random.default_rng(3)
    t = np.arange(1000) / 100.0 + rng.uniform(-2e-3, 2e-3, 1000) + 0.05  # a 100 Hz sensor with jitter
    h_max = np.diff(t).max()
    clock = common_clock([t, np.linspace(-1.0, 9.0, 50)], FS)
    assert clock[0] == t[0] and clock[-1] <= 9.0 and clock[-1] > 9.0 - 1 / FS
    np.testing.assert_allclose(np.diff(clock), 1 / FS, rtol=1e-9)
    x = np.stack([smooth(t), -2 * smooth(t)], axis=1)
    cubic = resample(t, x, clock)
    linear = resample(t, x[:, 0], clock, kind="linear")
    exact = smooth(clock)
    # Linear interpolation: |error| <= h^2 max|x''| / 8 (exact bound). Cubic spline:
    # O(h^4 max|x''''|); the clamped spline's constant is 5/384, the not-a-knot
    # spline's is larger near the ends, so take a generous 1.
    assert np.abs(linear - exact).max() <= h_max**2 * smooth_bound(2) / 8
    assert np.abs(cubic[:, 0] - exact).max() <= h_max**4 * smooth_bound(4)
    assert np.abs(cubic[:, 1] + 2 * exact).max() <= 2 * h_max**4 * smooth_bound(4)
    # Along another axis: components first, time second.
    np.testing.assert_allclose(resample(t, x.T, clock, axis=1), cubic.T, rtol=0, atol=1e-12)


def test_resample_errors_name_the_sample():
    t = np.arange(10.0)
    x = np.sin(t)
    t_dup = t.copy()
    t_dup[6] = t_dup[5]
    with pytest.raises(SignalError, match=r"duplicated at sample 6"):
        resample(t_dup, x, [1.0, 2.0])
    t_back = t.copy()
    t_back[4] = 2.5
    with pytest.raises(SignalError, match=r"backwards at sample 4"):
        resample(t_back, x, [1.0, 2.0])
    with pytest.raises(SignalError, match=r"t_new\[2\] = 9\.5 s is outside"):
        resample(t, x, [0.0, 9.0, 9.5, -1.0])
    x_nan = x.copy()
    x_nan[7] = np.nan
    with pytest.raises(SignalError, match="sample 7"):
        resample(t, x_nan, [1.0])
    t_nan = t.copy()
    t_nan[3] = np.nan
    with pytest.raises(SignalError, match=r"t has .* at sample 3"):
        resample(t_nan, x, [1.0])
    with pytest.raises(SignalError, match="9 time stamps"):
        resample(t[:9], x, [1.0])
    with pytest.raises(SignalError, match="do not overlap"):
        common_clock([t, t + 20.0], FS)


def test_decimation_of_paper_sized_system_works_in_blocks():
    # A 60 s test at 625 Hz, 14 equations, 48 parameters: the car's identification
    # system, 200 MB. Filtering it in column blocks must not copy it whole.
    n, m, p = 37500, 14, 48
    W = np.ones((n, m, p))
    Y = np.ones((n, m))
    tracemalloc.start()
    try:
        Wd, _ = decimate_parallel(W, Y, (10, 10), FS)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < W.nbytes / 2
    assert Wd.shape == (375, m, p)
    np.testing.assert_allclose(Wd, 1.0, rtol=1e-9)  # a constant passes unchanged (DC gain 1)


@pytest.mark.parametrize("order", [1, 2, 3, 4, 8])
@pytest.mark.parametrize("columns", [1, 3, 28])
def test_reversed_filter_of_columns_equals_scipy_sosfilt_of_each_reversed_column(order, columns):
    """Oracle: scipy's sosfilt of each column run backwards from its last sample's steady state (what
    `undo_lowpass_phase` does for one channel). The same recursion in the same order: equal to round-off
    (a contraction into FMA changes the last bits of a sum of a few terms; the filter's gain is bounded)."""
    from scipy.signal import butter, sosfilt, sosfilt_zi

    from dynid.signals.filters import undo_lowpass_phase, undo_lowpass_phase_columns

    x = np.cumsum(np.random.default_rng(columns).standard_normal((4000, columns)), axis=0) + 5.0
    sos = butter(order, 30.0, fs=FS, output="sos")
    got = undo_lowpass_phase_columns(x, FS, 30.0, order)
    assert got.shape == x.shape and got.flags.f_contiguous
    for c in range(columns):
        ref = sosfilt(sos, x[::-1, c], zi=sosfilt_zi(sos) * x[-1, c])[0][::-1]
        np.testing.assert_allclose(got[:, c], ref, rtol=0, atol=1e-12 * np.abs(ref).max())
        np.testing.assert_allclose(undo_lowpass_phase(x[:, c], FS, 30.0, order), ref, rtol=0,
                                   atol=1e-12 * np.abs(ref).max())


@pytest.mark.parametrize("orders", [(1, 2), (2,), (3, 4), (8, 7)])
@pytest.mark.parametrize("rows, n", [(1, 3000), (9, 700), (55, 2000)])
def test_reversed_filter_of_rows_each_with_its_own_filter_equals_scipy_sosfilt(orders, rows, n):
    """Oracle: scipy's sosfilt of each row run backwards from its last sample's steady state, each row with its own
    cut-off and order (the orders of one call give the same number of sections); rows and lengths that do not fill
    the kernel's sample blocks or its vectors. The same recursion in the same order: equal to round-off (an FMA
    contraction changes the last bits of a sum of a few terms; the filter's gain is bounded)."""
    from scipy.signal import butter, sosfilt, sosfilt_zi

    from dynid.signals.filters import undo_lowpass_phase_rows

    x = np.cumsum(np.random.default_rng(rows).standard_normal((rows, n)), axis=1) + 5.0
    filters = [(float(np.random.default_rng(c).uniform(2.0, 250.0)), orders[c % len(orders)]) for c in range(rows)]
    got = undo_lowpass_phase_rows(x, FS, filters)
    assert got.shape == x.shape and got.flags.c_contiguous
    for c, (cutoff, order) in enumerate(filters):
        sos = butter(order, cutoff, fs=FS, output="sos")
        ref = sosfilt(sos, x[c, ::-1], zi=sosfilt_zi(sos) * x[c, -1])[0][::-1]
        np.testing.assert_allclose(got[c], ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_reversed_filter_of_rows_refuses_filters_of_different_section_counts():
    from dynid.signals.filters import undo_lowpass_phase_rows

    with pytest.raises(ValueError, match="sections"):
        undo_lowpass_phase_rows(np.ones((2, 100)), FS, [(30.0, 2), (30.0, 4)])


@pytest.mark.parametrize("order", [1, 2, 3, 4, 5, 8])
@pytest.mark.parametrize("shape, axis", [((5000,), 0), ((3000, 7), 0), ((4, 2000, 3), 1), ((6, 1500), -1)])
def test_compiled_zero_phase_filter_equals_scipy_sosfiltfilt(order, shape, axis):
    from scipy.signal import butter, sosfiltfilt

    from dynid.signals._zero_phase import sos_filtfilt
    from dynid.signals.filters import pad_length

    sos = butter(order, 4.0, fs=FS, output="sos")
    x = np.random.default_rng(order).standard_normal(shape)
    ref = sosfiltfilt(sos, x, axis=axis, padtype="odd", padlen=pad_length(sos))
    got = sos_filtfilt(sos, x, axis, pad_length(sos))
    assert got.shape == ref.shape
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


@pytest.mark.parametrize("factor", [10, (10, 10), (5, 4, 3)])
def test_blocked_decimation_is_the_whole_inputs_without_holding_it(factor):
    """Oracle: `decimate_parallel` on the whole input held at once. The blocked path filters the first stage over
    blocks read with its transient to ROUND_OFF (1e-15) of the kernel's weight around them: each output differs
    from the whole input's by at most 1e-15 x the extension's mismatch (a few times the signal's largest value)
    plus the recursions' round-off (the state's error ~1e-16 per step, damped by the filter: ~1e-14 over the
    block, measured 1e-14 on random walks), so 1e-12 of the largest output bounds it on any CPU. One block over
    everything is the same computation: the same bits. Structural zeros stay exactly zero, and the blocks asked
    for cover the input without holding more than a block and its overlap."""
    from dynid.signals.decimation import decimate_parallel_blocked

    rng = np.random.default_rng(5)
    n = 30007
    W = np.cumsum(rng.normal(size=(n, 3, 5)), axis=0)  # random walks: all frequencies, the worst for the tails
    W[:, 1, 2] = 0.0
    Y = np.cumsum(rng.normal(size=(n, 3)), axis=0)
    Wd, Yd = decimate_parallel(W, Y, factor, FS)
    asked = []

    def rows(lo, hi):
        asked.append((lo, hi))
        return W[lo:hi], Y[lo:hi]

    Wb, Yb = decimate_parallel_blocked(rows, n, factor, FS, block_samples=3000)
    assert len(asked) > 3 and asked[0][0] == 0 and asked[-1][1] == n
    assert max(hi - lo for lo, hi in asked) < n / 2
    assert Wb.shape == Wd.shape and Yb.shape == Yd.shape
    assert np.max(np.abs(Wb - Wd)) <= 1e-12 * np.max(np.abs(Wd))
    assert np.max(np.abs(Yb - Yd)) <= 1e-12 * np.max(np.abs(Yd))
    assert np.all(Wb[:, 1, 2] == 0.0)
    one = decimate_parallel_blocked(rows, n, factor, FS, block_samples=n)
    assert np.array_equal(one[0], Wd) and np.array_equal(one[1], Yd)


@pytest.mark.parametrize("threads", [2, 3])
def test_blocked_decimation_on_threads_is_one_threads_to_the_bit(threads):
    """Oracle: the same call on one thread. Each block is computed alone (the same samples, the same filter per
    column) and written to its own rows, so any thread count gives the same bits, a column first live in a later
    block (W1 widened while other blocks run) included; rows() is asked for every block once."""
    import threading

    from dynid.signals.decimation import decimate_parallel_blocked

    rng = np.random.default_rng(6)
    n = 30007
    W = np.cumsum(rng.normal(size=(n, 3, 5)), axis=0)
    W[:, 1, 2] = 0.0
    W[: n // 2, 2, 4] = 0.0  # live from the middle on only
    Y = np.cumsum(rng.normal(size=(n, 3)), axis=0)
    asked = []

    def rows(lo, hi):
        asked.append((lo, hi))
        return W[lo:hi].copy(), Y[lo:hi]

    one = decimate_parallel_blocked(rows, n, (10, 10), FS, block_samples=3000)
    once = sorted(asked)
    asked.clear()
    done = []  # blocks_done: once, on the calling thread, after every block is asked for
    many = decimate_parallel_blocked(rows, n, (10, 10), FS, block_samples=3000, threads=threads,
                                     blocks_done=lambda: done.append((len(asked), threading.get_ident())))
    assert sorted(asked) == once and len(once) > 3
    assert done == [(len(once), threading.get_ident())]
    assert np.array_equal(one[0], many[0]) and np.array_equal(one[1], many[1])
    assert np.all(many[0][:, 1, 2] == 0.0) and np.any(many[0][:, 2, 4] != 0.0)
    with pytest.raises(SignalError, match="threads"):
        decimate_parallel_blocked(rows, n, 10, FS, block_samples=3000, threads=0)


@pytest.mark.parametrize("factor", [10, (10, 10)])
def test_blocked_decimation_takes_the_first_stage_outputs_an_overlapping_input_shared(factor):
    """Two overlapping inputs of one record X, A = X[:na] and B = X[h:], done in turn (a robot's chunks in order):
    A shares its first-stage outputs of B's samples (those that do not see A's end), B takes them as known and
    asks rows() for none of their samples but the first block's overlap. Oracle: X's whole first stage by
    `decimate_parallel` (one stage of factor 10: the first stage's filter), then its later stages on B's part;
    B's outputs are X's interior ones from both inputs' blocks (each to ROUND_OFF of its kernel, the recursions'
    round-off ~1e-14: the bound of the test above, 1e-12 of the largest output), where B done alone has the edge
    of its start. The blocks after the first left are asked as without the known outputs."""
    from dynid.signals.decimation import FirstStage, decimate_parallel_blocked

    rng = np.random.default_rng(7)
    n, na, h = 40007, 22000, 12000
    X = np.cumsum(rng.normal(size=(n, 2, 4)), axis=0)
    X[:, 1, 3] = 0.0
    Y = np.cumsum(rng.normal(size=(n, 2)), axis=0)
    shared: list[FirstStage] = []
    decimate_parallel_blocked(lambda lo, hi: (X[lo:hi], Y[lo:hi]), na, factor, FS, block_samples=3000,
                              share=(h, shared.append))
    (known,) = shared
    assert 0 < len(known.W1) * 10 < na - h and len(known.Y1) == len(known.W1)
    asked: list[tuple[int, int]] = []

    def rows(lo, hi):
        asked.append((lo, hi))
        return X[h + lo : h + hi], Y[h + lo : h + hi]

    Wb, Yb = decimate_parallel_blocked(rows, n - h, factor, FS, block_samples=3000, known=known, threads=2)
    with_known = sorted(asked)
    asked.clear()
    alone = decimate_parallel_blocked(rows, n - h, factor, FS, block_samples=3000)
    first_left = len(known.W1) * 10
    assert min(lo for lo, _ in with_known) >= first_left - 1000  # the first block's overlap (the stage's: < 1000)
    assert with_known[1:] == [b for b in sorted(asked) if b[0] > with_known[0][0]]
    W1 = decimate_parallel(X, Y, 10, FS)
    if factor == 10:
        Wd, Yd = W1[0][h // 10 :], W1[1][h // 10 :]
    else:
        Wd, Yd = decimate_parallel(W1[0][h // 10 :], W1[1][h // 10 :], 10, FS / 10)
    assert np.max(np.abs(Wb - Wd)) <= 1e-12 * np.max(np.abs(Wd))
    assert np.max(np.abs(Yb - Yd)) <= 1e-12 * np.max(np.abs(Yd))
    assert np.all(Wb[:, 1, 3] == 0.0)
    assert np.max(np.abs(alone[0] - Wd)) > 1e-6 * np.max(np.abs(Wd))  # alone, B's start is an edge


@pytest.mark.parametrize("where", ["calling thread", "helper"])
def test_blocked_decimation_on_threads_stops_at_a_blocks_error(where):
    """A block's error (a bad sample, Ctrl-C) ends the call once the blocks in flight are done: no thread takes a
    new block after it (a chunk's other blocks, seconds of W for a long arm's chunk, were all computed before the
    error came out). Oracle: the count of blocks asked for, against the call's 11 (a thread count of 2: the failing
    block and the other thread's one in flight; its rows() wait for the error to be raised first)."""
    import threading

    from dynid.signals.decimation import decimate_parallel_blocked

    n = 30000
    W = np.ones((n, 2, 3))
    Y = np.ones((n, 2))
    caller, raised, asked = threading.get_ident(), threading.Event(), []

    def rows(lo, hi):
        asked.append(lo)
        if (threading.get_ident() == caller) == (where == "calling thread"):
            raised.set()
            raise RuntimeError("a bad block")
        raised.wait(30)  # the other thread's block ends after the error
        return W[lo:hi], Y[lo:hi]

    with pytest.raises(RuntimeError, match="a bad block"):
        decimate_parallel_blocked(rows, n, (10, 10), FS, block_samples=3000, threads=2)
    assert len(asked) <= 3, asked


# (fs, cut-off) pairs: the paper's 3 Hz at 625 Hz, a fast arm's 20 Hz at 1 kHz, a very low and a near-Nyquist
# cut-off (poles at 1e-5 of the unit circle, poles on the negative axis), the quarter rate (a pole at the origin)
DESIGNS = [(625.0, 3.0), (1000.0, 20.0), (1000.0, 0.01), (100.0, 49.9), (100.0, 25.0), (2.0, 0.7), (62.5, 4.0)]


@pytest.mark.parametrize("order", range(1, 9))
@pytest.mark.parametrize("fs, cutoff", DESIGNS)
def test_butterworth_sections_are_scipys(order, fs, cutoff):
    """Oracle: scipy.signal.butter(order, cutoff, fs=fs, output="sos"). Same formulas: each pole through exp, tan,
    a complex product and a quotient (a few ulp), a coefficient from one or two of them (-2 Re p, |p|^2: a few ulp
    of |p| <= 1), the gain a product of `order` factors (order ulp): within 8 order ulp of the coefficient's size
    (|a1| <= 2, |a2| <= 1; the numerator relative to its own largest term, the gain's scale), with the same pairing,
    order of the sections and the first-order section's zero at the origin (exactly zero in both)."""
    from scipy.signal import butter

    from dynid.signals._butterworth import butter_lowpass_sos

    ref = butter(order, cutoff, fs=fs, output="sos")
    got = butter_lowpass_sos(order, cutoff, fs)
    assert got.shape == ref.shape
    assert np.array_equal(got == 0, ref == 0)  # the same structural zeros: the same pairing
    tol = 8 * order * np.finfo(float).eps
    np.testing.assert_allclose(got[:, 3:], ref[:, 3:], rtol=0, atol=2 * tol)
    scale = np.abs(ref[:, :3]).max(axis=1, keepdims=True)
    np.testing.assert_allclose(got[:, :3] / scale, ref[:, :3] / scale, rtol=0, atol=tol)


@pytest.mark.parametrize("order", range(1, 9))
@pytest.mark.parametrize("fs, cutoff", DESIGNS)
def test_sections_steady_state_is_scipys_sosfilt_zi(order, fs, cutoff):
    """Oracle: scipy.signal.sosfilt_zi on scipy's own design. Each section's 2 x 2 system (I - A) z = B has the
    determinant 1 + a1 + a2 = (1 - p)(1 - conj p), small for a low cut-off: a solution carries a few ulp times
    kappa = (1 + |a1| + |a2|) / |1 + a1 + a2| of the section's largest state (the same LAPACK call gives the same
    bits; another solver, or a LAPACK with FMA, stays within that), and the sections' DC-gain scale one ulp per
    section before: within 4 (order + kappa) ulp of the section's largest state."""
    from scipy.signal import butter, sosfilt_zi

    from dynid.signals._butterworth import sosfilt_zi as zi

    sos = butter(order, cutoff, fs=fs, output="sos")
    ref, got = sosfilt_zi(sos), zi(sos)
    kappa = (1 + np.abs(sos[:, 4]) + np.abs(sos[:, 5])) / np.abs(1 + sos[:, 4] + sos[:, 5])
    tol = 4 * (order + kappa) * np.finfo(float).eps * np.abs(ref).max(axis=1)
    assert np.all(np.abs(got - ref).max(axis=1) <= tol)


@pytest.mark.parametrize("order", [1, 2, 5, 8])
def test_forward_pass_and_autocorrelation_are_scipys(order):
    """Oracles: scipy.signal.sosfilt from rest (the same recursion: equal to round-off, the filter's gain bounded)
    and fftconvolve(h, h[::-1]) (another FFT of the same length: each lag within a few ulp x log2(length) of the
    largest, lag 0)."""
    from scipy.signal import butter, fftconvolve, sosfilt

    from dynid.signals._zero_phase import sosfilt_forward
    from dynid.signals.borders import _autocorrelation

    sos = butter(order, 20.0, fs=1000.0, output="sos")
    x = np.random.default_rng(order).standard_normal((3000, 3))
    ref = sosfilt(sos, x, axis=0)
    np.testing.assert_allclose(sosfilt_forward(sos, x), ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    h = sosfilt(sos, np.r_[1.0, np.zeros(4999)])
    ref = fftconvolve(h, h[::-1])[h.size - 1:]
    np.testing.assert_allclose(_autocorrelation(h), ref, rtol=0, atol=64 * np.finfo(float).eps * ref[0])


def test_identification_does_not_import_scipy_signal():
    """scipy.signal (48 MB resident with the scipy.stats it loads: issue 25's memory target) stays out of the
    pipeline: importing it, designing, filtering, decimating and the borders, in a fresh process."""
    import subprocess
    import sys

    code = ("import sys, numpy as np\nimport dynid.pipeline.run\nfrom dynid.signals import border_samples, "
            "decimate_parallel, filtered_derivatives\nx = np.cumsum(np.ones((5000, 2)), axis=0)\n"
            "filtered_derivatives(x, 1000.0, 20.0, nderiv=2)\ndecimate_parallel(x, None, (10,), 1000.0)\n"
            "border_samples(1000.0, 20.0, 4, tol=1e-12)\nprint(sorted(m for m in sys.modules "
            "if m.startswith('scipy.signal')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_unchecked_filters_differences_and_integrals_are_the_checked_ones():
    """check_finite=False skips the NaN scan alone: on finite input the same bits as the checked call (the oracle),
    and on a NaN no error (the caller's check stands for it)."""
    from dynid.signals import derivative, integrate, lowpass

    x = np.random.default_rng(11).standard_normal((3000, 3)).cumsum(axis=0)
    for f in (lambda a, **k: lowpass(a, FS, 4.0, **k), lambda a, **k: derivative(a, FS, **k),
              lambda a, **k: integrate(a, FS, **k)):
        np.testing.assert_array_equal(f(x, check_finite=False), f(x))
        bad = x.copy()
        bad[100, 1] = np.nan
        with pytest.raises(SignalError, match="non-finite"):
            f(bad)
        assert np.isnan(f(bad, check_finite=False)[100:102, 1]).any()


def test_lowpass_of_columns_is_the_lowpass_of_their_stack():
    """`lowpass_columns` writes the columns straight into the filter's work array, a block of samples at a time;
    oracle: `lowpass` of the same columns stacked (np.column_stack), the same bits, for 1-D and 2-D columns, zero
    columns after them (width), and records longer and shorter than a fill block."""
    from dynid.signals import lowpass_columns

    rng = np.random.default_rng(13)
    for n in (200, 30011):
        cols = [rng.standard_normal(n).cumsum(), rng.standard_normal((n, 3)).cumsum(axis=0), rng.standard_normal(n)]
        ref = lowpass(np.column_stack(cols), FS, 4.0, order=4)
        got = lowpass_columns(cols, FS, 4.0, order=4)
        assert got.shape == (n, 5) and got.flags.c_contiguous
        np.testing.assert_array_equal(got, ref)
        wide = lowpass_columns(cols, FS, 4.0, order=4, width=8)
        np.testing.assert_array_equal(wide[:, :5], ref)
        np.testing.assert_array_equal(wide[:, 5:], 0.0)


def test_lowpass_of_columns_names_the_bad_column_and_sample():
    from dynid.signals import lowpass_columns

    x = np.ones(500)
    y = np.ones((500, 2))
    y[321, 1] = np.inf
    with pytest.raises(SignalError, match=r"columns\[1\] has a non-finite value \(inf\) at sample 321, column 1"):
        lowpass_columns([x, y], FS, 4.0)
    with pytest.raises(SignalError, match=r"columns\[1\] has shape \(400,\)"):
        lowpass_columns([x, np.ones(400)], FS, 4.0)
    with pytest.raises(SignalError, match="width 2 is less than the columns' 3"):
        lowpass_columns([x, np.ones((500, 2))], FS, 4.0, width=2)
    with pytest.raises(SignalError, match="needs at least"):
        lowpass_columns([np.ones(10)], FS, 4.0)


def test_lowpass_of_columns_without_numba_is_scipys(monkeypatch):
    """Without numba the filled work array goes through scipy's sosfiltfilt: the compiled result to round-off (the
    recursions' order is the same; 1e-12 of the largest output bounds a few thousand steps' roundings)."""
    from dynid.signals import _zero_phase, lowpass_columns

    cols = [np.random.default_rng(14).standard_normal((3000, 2)).cumsum(axis=0), np.linspace(0.0, 1.0, 3000)]
    ref = lowpass_columns(cols, FS, 4.0, width=4)
    monkeypatch.setattr(_zero_phase, "HAVE_NUMBA", False)
    got = lowpass_columns(cols, FS, 4.0, width=4)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
