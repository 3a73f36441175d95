"""Putting channels recorded on their own time bases onto one common clock.

Sensors of a vehicle run at different rates (inertial unit, clearances, steering,
wheels: Table 1 of the paper) and loggers stamp them separately; W and Y need every
channel at the same instants. `resample` interpolates one channel onto given times;
`common_clock` builds a uniform clock inside the span every channel covers.

Interpolation does not low-pass. Going to a coarser clock than the channel's own,
low-pass the channel first (`lowpass`, cut-off below the new Nyquist frequency), or
what lies above it aliases.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _checks
from .errors import SignalError

_DEGREE = {"linear": 1, "cubic": 3}


def _time_base(t: ArrayLike, name: str) -> NDArray[np.float64]:
    """A 1-D, finite, strictly increasing time base, else an error naming the sample."""
    a = _checks.as_float(t, name)
    if a.ndim != 1:
        raise SignalError(f"{name} must be 1-D (one time stamp per sample), got shape {a.shape}")
    _checks.finite(a, name, 0, "time stamps must be finite")
    step = np.diff(a)
    bad = np.flatnonzero(step <= 0.0)
    if bad.size:
        k = int(bad[0]) + 1
        kind = "duplicated" if step[k - 1] == 0.0 else "going backwards"
        raise SignalError(
            f"{name} is not strictly increasing: time stamp {kind} at sample {k} "
            f"({name}[{k}] = {float(a[k])!r} s after {name}[{k - 1}] = {float(a[k - 1])!r} s); "
            f"{bad.size} such sample(s) in all. Sort the samples and drop repeated stamps first"
        )
    return a


def resample(t: ArrayLike, x: ArrayLike, t_new: ArrayLike, kind: str = "cubic", axis: int = 0) -> NDArray[np.float64]:
    """Interpolate a channel sampled at times `t` onto the times `t_new`.

    Parameters
    ----------
    t : array (N,)
        The channel's own time stamps, s, strictly increasing (need not be uniform).
    x : array (..., N, ...)
        The channel's samples, N along `axis`, any unit; other indices are
        components interpolated alike.
    t_new : array (M,)
        Times wanted, s, each within [t[0], t[-1]] (no extrapolation); any order.
    kind : "cubic" or "linear"
        "cubic": not-a-knot cubic spline through the samples (smooth signals; error
        ~ h^4 |x''''|, needs N >= 4); "linear": straight lines between samples (error
        <= h^2 max|x''| / 8; for signals with jumps, or N >= 2).
    axis : time axis of `x`.

    Returns
    -------
    array, shape of `x` with N replaced by M along `axis`, unit of `x`.

    Raises
    ------
    SignalError
        non-finite, repeated or decreasing time stamps (with the sample index);
        `x` not matching `t`; a time in `t_new` outside [t[0], t[-1]] (with its index).
    """
    if kind not in _DEGREE:
        raise SignalError(f"kind must be 'cubic' or 'linear', not {kind!r}")
    degree = _DEGREE[kind]
    times = _time_base(t, "t")
    a = _checks.as_float(x, "x")
    ax = _checks.time_axis(a, axis, "x")
    if a.shape[ax] != times.size:
        raise SignalError(f"x has {a.shape[ax]} samples along axis {ax} but t has {times.size} time stamps")
    if times.size < degree + 1:
        raise SignalError(f"{kind} interpolation needs at least {degree + 1} samples, the channel has {times.size}")
    _checks.finite(a, "x", ax)
    new = _checks.as_float(t_new, "t_new")
    if new.ndim != 1:
        raise SignalError(f"t_new must be 1-D, got shape {new.shape}")
    _checks.finite(new, "t_new", 0, "time stamps must be finite")
    outside = np.flatnonzero((new < times[0]) | (new > times[-1]))
    if outside.size:
        k = int(outside[0])
        raise SignalError(
            f"t_new[{k}] = {float(new[k])!r} s is outside the channel's time span "
            f"[{float(times[0])!r}, {float(times[-1])!r}] s "
            f"({outside.size} time(s) outside in all); resample does not extrapolate: restrict t_new "
            "(see common_clock)"
        )
    # start-up: scipy.interpolate with the optimize and spatial it loads, 14 MB resident, only for a clock resampled
    from scipy.interpolate import make_interp_spline

    spline = make_interp_spline(times, a, k=degree, axis=ax)
    return np.asarray(spline(new), dtype=np.float64)


def common_clock(time_bases: Sequence[ArrayLike], fs: float) -> NDArray[np.float64]:
    """A uniform clock at `fs` covering the span that every time base covers.

    Parameters
    ----------
    time_bases : sequence of arrays (N_i,)
        Each channel's time stamps, s, strictly increasing.
    fs : float
        Rate of the common clock, Hz.

    Returns
    -------
    array (M,), s: t0, t0 + 1/fs, ... with t0 the latest start and every time at or
    before the earliest end, so that `resample` onto it never extrapolates.
    """
    fs = _checks.rate(fs)
    if len(time_bases) == 0:
        raise SignalError("no time bases given")
    bases = [_time_base(t, f"time_bases[{i}]") for i, t in enumerate(time_bases)]
    for i, b in enumerate(bases):
        if b.size == 0:
            raise SignalError(f"time_bases[{i}] is empty")
    start = max(float(b[0]) for b in bases)
    end = min(float(b[-1]) for b in bases)
    if start > end:
        first = max(range(len(bases)), key=lambda i: bases[i][0])
        last = min(range(len(bases)), key=lambda i: bases[i][-1])
        raise SignalError(
            f"the channels do not overlap in time: time_bases[{first}] starts at {start!r} s, "
            f"after time_bases[{last}] ends at {end!r} s"
        )
    count = math.floor((end - start) * fs) + 1
    clock = start + np.arange(count) / fs
    # Rounding of k / fs can push the last tick a hair past the end.
    return clock[clock <= end]
