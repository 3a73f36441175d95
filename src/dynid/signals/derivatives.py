"""Time derivatives: central differences, and the paper's filtered (band-pass) derivatives.

Why filter before differencing: a difference quotient multiplies the spectrum by
about 2 pi f (once per derivative), so measurement noise, which is spread up to the
Nyquist frequency, dominates the result long before the signal does: at 625 Hz a
1 mm (rms) white noise on a damper clearance becomes about 0.4 m/s rms of velocity
noise and over 200 m/s^2 rms of acceleration noise (central differences applied
twice). Low-pass filtering first, with no phase (forward-backward), keeps the band
where the dynamics live and removes the rest;
the product "zero-phase Butterworth x central difference" is the paper's band-pass
derivative filter (§6.2): gain ~ 2 pi f up to the cut-off, then falling, and no lag.

Defaults: the paper uses order 5 to 8 and a cut-off around 3 Hz for dynamics around
1 Hz, the higher orders for the higher derivatives. Here `order` is the order of
one pass; forward-backward doubles it, so the default 4 already falls like an
8th-order filter. Rule of thumb: cut-off 2 to 5 times the highest frequency of
interest; the pass-band error at frequency f is about (tan(pi f/fs)/tan(pi fc/fs))^(2 order).
"""

from __future__ import annotations

import numbers

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _checks
from .errors import SignalError
from .filters import lowpass


def derivative(x: ArrayLike, fs: float, axis: int = 0, check_finite: bool = True) -> NDArray[np.float64]:
    """Time derivative of uniformly sampled `x` by central differences.

    Interior samples: (x[k+1] - x[k-1]) / (2 h), h = 1/fs; first and last samples:
    the second-order one-sided formulas (-3 x0 + 4 x1 - x2) / (2 h) and its mirror.
    Both are second-order accurate (error ~ h^2 x'''/6). For a sinusoid of frequency f
    the interior gain is sin(2 pi f h) / (2 pi f h) with no phase: the central
    difference itself adds no lag.

    This does not filter: on measured data use `filtered_derivatives`.

    Parameters
    ----------
    x : array (..., N, ...), N >= 3 along `axis`, unit u.
    fs : sample rate in Hz.
    axis : time axis.
    check_finite : False: x is not scanned for NaN or infinities (`lowpass`'s).

    Returns
    -------
    array, same shape as `x`, unit u/s.
    """
    a = _checks.as_float(x, "x")
    ax = _checks.time_axis(a, axis, "x")
    fs = _checks.rate(fs)
    n = a.shape[ax]
    if n < 3:
        raise SignalError(f"x has {n} samples along axis {ax}; a second-order derivative needs at least 3")
    if check_finite:
        _checks.finite(a, "x", ax)
    return _central_difference(a, fs, ax)


def _central_difference(a: NDArray[np.float64], fs: float, axis: int) -> NDArray[np.float64]:
    """`derivative` of a checked array (n >= 3): np.gradient's formulas, written into one output
    (np.gradient's own temporaries cost more than the differences themselves on long records)."""
    x = np.moveaxis(a, axis, 0)
    out = np.empty(x.shape)
    h2 = 2.0 * (1.0 / fs)  # np.gradient's 2 dx
    np.subtract(x[2:], x[:-2], out=out[1:-1])
    out[1:-1] /= h2
    out[0] = (-3.0 * x[0] + 4.0 * x[1] - x[2]) / h2
    out[-1] = (3.0 * x[-1] - 4.0 * x[-2] + x[-3]) / h2
    return np.moveaxis(out, 0, axis)


def filtered_derivatives(
    x: ArrayLike, fs: float, cutoff: float, order: int = 4, nderiv: int = 2, axis: int = 0
) -> tuple[NDArray[np.float64], ...]:
    """The zero-phase filtered signal and its first `nderiv` derivatives (paper §6.2).

    x is low-pass filtered forward-backward (`lowpass`), then differentiated by
    central differences (`derivative`) `nderiv` times in turn, so that q, qd and qdd
    come from one and the same band-pass operator and stay mutually consistent.
    For a sinusoid of frequency f the k-th output is the exact k-th derivative times
    |H(f)|^2 (sin(2 pi f h)/(2 pi f h))^k, h = 1/fs: a gain slightly below 1, no phase.

    Parameters
    ----------
    x : array (..., N, ...), unit u, time along `axis`.
    fs : sample rate in Hz.
    cutoff : cut-off of one pass in Hz, 0 < cutoff < fs/2 (paper: ~3 Hz for ~1 Hz dynamics).
    order : Butterworth order of one pass (forward-backward doubles it; paper: 5 to 8).
    nderiv : number of derivatives, >= 0 (2 gives position, velocity, acceleration).
    axis : time axis.

    Returns
    -------
    tuple of nderiv + 1 arrays, each the shape of `x`: the filtered signal (u), its
    first derivative (u/s), second (u/s^2), ...

    Notes
    -----
    The ends are spoiled by the filter transient: drop `border_samples(fs, cutoff,
    order)` samples at each end, plus one per derivative for the one-sided end formula.
    """
    if isinstance(nderiv, bool) or not isinstance(nderiv, numbers.Integral) or nderiv < 0:
        raise SignalError(f"nderiv must be an integer >= 0, not {nderiv!r}")
    out = [lowpass(x, fs, cutoff, order=order, axis=axis)]
    ax = _checks.time_axis(out[0], axis, "x")
    if nderiv and out[0].shape[ax] < 3:
        raise SignalError(f"x has {out[0].shape[ax]} samples along axis {ax}; a derivative needs at least 3")
    for _ in range(int(nderiv)):  # the low-pass checked x: its output is finite
        out.append(_central_difference(out[-1], fs, ax))
    return tuple(out)
