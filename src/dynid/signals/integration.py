"""Time integration by the cumulative trapezoidal rule (paper §6.2: "without phase shift").

Why trapezoids: for a sinusoid of angular frequency w the rule's transfer function
is (h/2)(1 + z^-1)/(1 - z^-1) = -j (h/2) cot(w h / 2): exactly the -90 degrees of a
true integrator and no more, so the integral neither lags nor leads the other
channels; only its gain is off, by (w h/2) cot(w h/2) ~ 1 - (w h)^2 / 12. A
rectangle (cumulative sum) rule would add half a sample of delay.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _checks
from .errors import SignalError


def integrate(xd: ArrayLike, fs: float, x0: ArrayLike = 0.0, axis: int = 0, check_finite: bool = True
              ) -> NDArray[np.float64]:
    """Running integral of uniformly sampled `xd`, same length as the input.

    x[0] = x0 and x[k] = x0 + h * (xd[0]/2 + xd[1] + ... + xd[k-1] + xd[k]/2), h = 1/fs.
    Exact for signals linear in time; error at time t at most t h^2 max|xd''| / 12.

    Parameters
    ----------
    xd : array (..., N, ...), N >= 1 along `axis`, unit u/s.
    fs : sample rate in Hz.
    x0 : value at the first sample, unit u: a scalar, or an array of the shape of one
        sample (the shape of `xd` without `axis`), or anything broadcasting to it.
    axis : time axis.
    check_finite : False: xd is not scanned for NaN or infinities (`signals.lowpass`'s); x0 always is.

    Returns
    -------
    array, same shape as `xd`, unit u.
    """
    a = _checks.as_float(xd, "xd")
    ax = _checks.time_axis(a, axis, "xd")
    fs = _checks.rate(fs)
    if a.shape[ax] < 1:
        raise SignalError("xd has no samples along the time axis")
    if check_finite:
        _checks.finite(a, "xd", ax)
    start = _checks.as_float(x0, "x0", min_ndim=0)
    sample_shape = a.shape[:ax] + a.shape[ax + 1 :]
    try:
        start = np.broadcast_to(start, sample_shape)
    except ValueError as exc:
        raise SignalError(
            f"x0 of shape {start.shape} does not fit one sample of xd, shape {sample_shape} "
            f"(xd is {a.shape} with time along axis {ax})"
        ) from exc
    _checks.finite(start.reshape(1, -1), "x0", 0, "give a finite initial value")
    # scipy's cumulative_trapezoid(initial=0) plus x0, written into one output (its temporaries cost more
    # than the sums on long records)
    x = np.moveaxis(a, ax, 0)
    out = np.empty(x.shape)
    out[0] = 0.0
    np.add(x[1:], x[:-1], out=out[1:])
    out[1:] *= 0.5 / fs
    np.cumsum(out[1:], axis=0, out=out[1:])
    out += start
    return np.moveaxis(out, 0, ax)
