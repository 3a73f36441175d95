"""The ends of a filtered record: how many samples the filter transient spoils, and cutting them.

The rule (`border_samples`). Forward-backward filtering applies the symmetric kernel
g = h * h(-.) (h the impulse response of one pass) to the record extended beyond
its ends. The extension (reflection, then a steady-state start) is a guess, not the
true continuation. The output k samples inside an end depends on the samples beyond
that end only through the kernel weights at lags larger than k, so if the guess is
wrong by at most E there, the output is wrong by at most E * sum_{j > k} |g[j]|.
The backward pass also starts from a guessed state at the far end, wrong by an
amount that reaches k samples inside only through sum_{j > k} |h[j]|.
`border_samples` is the smallest k for which both tails are at most `tol` times the
whole kernel's absolute sum: beyond it, the output is within about tol x (the
mismatch of the extension, a few times the signal's amplitude) of the output of the
same filter on an endless record. Computed numerically from the designed filter's
impulse response, not from a rule of thumb.
"""

from __future__ import annotations

import functools
import math
import numbers

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _checks
from ._zero_phase import sosfilt_forward
from .errors import SignalError
from .filters import design_lowpass

_MAX_RESPONSE = 2**26  # samples of impulse response we are willing to compute


def _tail_start(kernel: NDArray[np.float64], total: float, tol: float) -> int:
    """Smallest k >= 0 with sum_{j > k} |kernel[j]| <= tol * total (kernel[0] is lag 0)."""
    mag = np.abs(kernel)
    # tail[k] = sum_{j >= k}; summed from the small end for accuracy at small tol.
    tail = np.cumsum(mag[::-1])[::-1]
    beyond = np.append(tail[1:], 0.0)  # sum_{j > k}
    return int(np.argmax(beyond <= tol * total))


def _fast_length(n: int) -> int:
    """The smallest 2^a 3^b 5^c >= n: a length the FFT does fast (scipy.fft.next_fast_len(n, real=True))."""
    best = 1 << max(0, (n - 1).bit_length())
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            m = p35 << max(0, (-(-n // p35) - 1).bit_length())  # p35 times the smallest power of 2 reaching n
            best = min(best, m)
            p35 *= 3
        p5 *= 5
    return best


def _autocorrelation(h: NDArray[np.float64]) -> NDArray[np.float64]:
    """sum_j h[j] h[j + k] for the lags k = 0..len(h)-1, by FFT (scipy's fftconvolve(h, h[::-1])[len(h) - 1:],
    zero-padded to the same fast length): NumPy's FFT, not scipy.signal's import (48 MB, issue 25)."""
    n = h.size
    length = _fast_length(2 * n - 1)
    H = np.fft.rfft(h, length)
    return np.fft.irfft(H * H.conj(), length)[:n]


def border_samples(fs: float, cutoff: float, order: int, tol: float = 1e-3) -> int:
    """Samples at EACH end of a `lowpass(x, fs, cutoff, order)` output to distrust.

    Rule (module docstring): the smallest k such that the absolute weight the
    zero-phase kernel, and the single pass, give to samples more than k beyond an end
    is at most `tol` of their total absolute weight. Conservative: it bounds the
    worst case over all ways the record could continue, whereas smooth records do
    better.

    Parameters
    ----------
    fs, cutoff, order : as for `lowpass` (Hz, Hz, order of one pass).
    tol : relative weight left outside, 0 < tol < 1. The default 1e-3 leaves errors
        of order 0.1 % of the signal's amplitude; use 1e-6 or less before
        differentiating twice.

    Returns
    -------
    int, number of samples at each end. It scales like fs / cutoff: for a 3 Hz
    cut-off with order 4 it is about 1 s of record at tol 1e-3 (608 samples at
    625 Hz) and 2 s at tol 1e-6, whatever fs.
    """
    fs = _checks.rate(fs)
    order = _checks.filter_order(order)
    cutoff = _checks.cutoff_frequency(cutoff, fs)
    try:
        tol = float(tol)
    except (TypeError, ValueError) as exc:
        raise SignalError(f"tol must be a number in (0, 1), not {tol!r}") from exc
    if not 0.0 < tol < 1.0:
        raise SignalError(f"tol must be in (0, 1), got {tol}")
    return _border_samples(fs, cutoff, order, tol)


@functools.lru_cache(maxsize=256)
def _border_samples(fs: float, cutoff: float, order: int, tol: float) -> int:
    """`border_samples` of checked arguments, cached: a pipeline asks for the same few filters' once per segment and
    stage, and each answer filters an impulse and transforms its response (0.5 ms)."""
    sos = design_lowpass(fs, cutoff, order)
    poles = np.concatenate([np.roots(section[3:]) for section in sos])
    radius = float(np.max(np.abs(poles)))
    # First guess of the response length from the slowest pole's decay, then doubled
    # until the truncated part is negligible against tol.
    n = 64 + (math.ceil(math.log(1e-3 * tol) / math.log(radius)) if 0.0 < radius < 1.0 else 0)
    if n > _MAX_RESPONSE or radius >= 1.0:  # refused before allocating (a 1e-9 Hz cut-off asked for 52 TiB)
        raise SignalError(
            f"the impulse response of the order-{order} low-pass at cutoff {cutoff:g} Hz for fs = {fs:g} Hz is "
            f"longer than {_MAX_RESPONSE} samples; raise the cut-off (or lower fs: decimate)"
        )
    while True:
        impulse = np.zeros(n)
        impulse[0] = 1.0
        h = sosfilt_forward(sos, impulse[:, None])[:, 0]
        if np.sum(np.abs(h[n // 2 :])) <= 1e-3 * tol * np.sum(np.abs(h)):
            break
        if n >= _MAX_RESPONSE:
            raise SignalError(
                f"the impulse response of the order-{order} low-pass at {cutoff:g} Hz for fs = {fs:g} Hz "
                f"is longer than {_MAX_RESPONSE} samples; lower fs (decimate) or raise the cut-off"
            )
        n *= 2
    g = _autocorrelation(h)  # lags 0..n-1 of the symmetric kernel
    g_total = abs(g[0]) + 2.0 * float(np.sum(np.abs(g[1:])))
    return max(_tail_start(g, g_total, tol), _tail_start(h, float(np.sum(np.abs(h))), tol))


def trim(x: ArrayLike, n: int, axis: int = 0) -> NDArray:
    """`x` without its first and last `n` samples along `axis` (a view, not a copy).

    Parameters
    ----------
    x : array (..., N, ...) with N > 2 n along `axis`.
    n : samples to drop at each end, >= 0 (typically `border_samples(...)`).
    axis : time axis.

    Returns
    -------
    array (..., N - 2 n, ...).
    """
    a = np.asarray(x)
    if a.ndim == 0:
        raise SignalError("x is a scalar; trim needs an array with a time axis")
    ax = _checks.time_axis(a, axis, "x")
    if isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < 0:
        raise SignalError(f"n must be an integer >= 0, not {n!r}")
    size = a.shape[ax]
    if 2 * n >= size:
        raise SignalError(
            f"trimming {n} samples at each end of {size} along axis {ax} leaves nothing; "
            "use a longer record, a higher cut-off or a lower tol"
        )
    index = [slice(None)] * a.ndim
    index[ax] = slice(int(n), size - int(n))
    return a[tuple(index)]
