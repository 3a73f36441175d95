"""Forward-backward second-order sections, compiled: scipy's `sosfiltfilt` (odd padding, steady-state
initial conditions), several times faster and without the GIL, so that threads filter in parallel; and the
single passes the package needs (backwards from a steady state, forwards from rest).

Every call of the car pipeline filters a few dozen channels of tens of thousands of samples; scipy's
generic loop spends ~4 ns per section and sample and holds the GIL between its steps. The kernel
below runs the same recursion (direct form II transposed, as scipy's sosfilt) per channel. Without
numba, scipy's sosfiltfilt is used: the same numbers to round-off (tested). scipy.signal is imported only
then: with numba, no identification loads it (48 MB resident, issue 25).
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import NDArray

from ._butterworth import sosfilt_zi

try:
    from numba import njit

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised only without numba
    HAVE_NUMBA = False


def _sections(sos, z0, z1, v):  # pragma: no cover - compiled
    """One sample of every channel (v, C) through every section in turn, in place: scipy sosfilt's recursion
    (direct form II transposed), the states z0, z1 (S, C) carried; the channels the inner loop (SIMD)."""
    for s in range(sos.shape[0]):
        b0, b1, b2, a1, a2 = sos[s, 0], sos[s, 1], sos[s, 2], sos[s, 4], sos[s, 5]
        for c in range(v.shape[0]):
            y = b0 * v[c] + z0[s, c]
            z0[s, c] = b1 * v[c] - a1 * y + z1[s, c]
            z1[s, c] = b2 * v[c] - a2 * y
            v[c] = y


def _filtfilt_columns(sos, zi, pad, ext):  # pragma: no cover - compiled
    """ext (n + 2 pad, C): rows pad .. pad + n - 1 hold the columns x on entry (the caller's copy: one copy whatever
    x's layout), every column odd-extended, then filtered forward then backward in place.
    The channels are the inner loop: their recursions are independent, so they run side by side
    (SIMD) instead of waiting on one channel's chain of dependent multiply-adds."""
    S = sos.shape[0]
    L, C = ext.shape
    n = L - 2 * pad
    # odd extension: 2 x[0] - x[pad..1], x, 2 x[-1] - x[-2..-pad-1] (x[k] = ext[pad + k]: read only there)
    for i in range(pad):
        for c in range(C):
            ext[i, c] = 2.0 * ext[pad, c] - ext[2 * pad - i, c]
            ext[n + pad + i, c] = 2.0 * ext[n + pad - 1, c] - ext[n + pad - 2 - i, c]
    z0 = np.empty((S, C))
    z1 = np.empty((S, C))
    v = np.empty(C)
    for direction in range(2):
        first = 0 if direction == 0 else L - 1
        for s in range(S):
            for c in range(C):
                z0[s, c] = zi[s, 0] * ext[first, c]
                z1[s, c] = zi[s, 1] * ext[first, c]
        for k in range(L):
            i = k if direction == 0 else L - 1 - k
            for c in range(C):
                v[c] = ext[i, c]
            _sections(sos, z0, z1, v)
            for c in range(C):
                ext[i, c] = v[c]


def _reverse_columns(coef, zi, x, out):  # pragma: no cover - compiled
    """x (C, n), channels first: channel c filtered once backwards in time (last sample first) through its own
    sections coef[:, :, c] (S, 5: b0, b1, b2, a1, a2; a0 = 1), from the steady state of its last sample (zi (S, 2, C)
    per unit input); out (C, n) the result, channels first (the C-order transposes of column-major (n, C) arrays;
    channels stacked as rows need no copy). The recursion is scipy sosfilt's (direct form II transposed), each
    channel's operations those of `_sections` in its order (the same bits), the channels the inner loop (SIMD).
    The samples go through a block of BLOCK rows (n, C) in turn: a channel's samples are read and written in runs
    of BLOCK, not one sample of every channel per step (C rows read and C written at once: 28 channels of a 60 s
    segment took 8.5 ms that way, 55 channels 23 ms, 8 channels 0.9 ms; the rows' streams, not the arithmetic)."""
    S = coef.shape[0]
    C, n = x.shape
    z0 = np.empty((S, C))
    z1 = np.empty((S, C))
    for s in range(S):
        for c in range(C):
            z0[s, c] = zi[s, 0, c] * x[c, n - 1]
            z1[s, c] = zi[s, 1, c] * x[c, n - 1]
    buf = np.empty((BLOCK, C))
    hi = n  # the block holds samples hi - 1, hi - 2, ..., lo in its rows 0, 1, ...
    while hi > 0:
        lo = max(0, hi - BLOCK)
        m = hi - lo
        for c in range(C):
            for t in range(m):
                buf[t, c] = x[c, hi - 1 - t]
        for t in range(m):
            for s in range(S):
                for c in range(C):
                    v = buf[t, c]
                    y = coef[s, 0, c] * v + z0[s, c]
                    z0[s, c] = coef[s, 1, c] * v - coef[s, 3, c] * y + z1[s, c]
                    z1[s, c] = coef[s, 2, c] * v - coef[s, 4, c] * y
                    buf[t, c] = y
        for c in range(C):
            for t in range(m):
                out[c, hi - 1 - t] = buf[t, c]
        hi = lo


BLOCK = 256  # samples per block of `_reverse_columns` (x 55 channels: 113 KB, in L2; 32 to 512 measured: 256 and 512
# the fastest, 64 up to 1.6 x slower)


def _forward_columns(sos, x, out):  # pragma: no cover - compiled
    """x (n, C): every column filtered once forwards in time from rest (zero state); out (n, C) the result.
    The recursion is scipy sosfilt's (direct form II transposed), the channels the inner loop."""
    S = sos.shape[0]
    n, C = x.shape
    z0 = np.zeros((S, C))
    z1 = np.zeros((S, C))
    v = np.empty(C)
    for i in range(n):
        for c in range(C):
            v[c] = x[i, c]
        _sections(sos, z0, z1, v)
        for c in range(C):
            out[i, c] = v[c]


if HAVE_NUMBA:  # the step first: the passes call the compiled one
    _sections = njit(inline="always")(_sections)
    _filtfilt_columns = njit(cache=True, nogil=True)(_filtfilt_columns)
    _reverse_columns = njit(cache=True, nogil=True)(_reverse_columns)
    _forward_columns = njit(cache=True, nogil=True)(_forward_columns)


def steady_state(sos: NDArray[np.float64]) -> NDArray[np.float64]:
    """scipy's sosfilt_zi(sos) (read-only; `_butterworth.sosfilt_zi`), cached: it solves a small linear system per
    section, and a pipeline
    asks for the same few filters' thousands of times (a third of the car joints' filtering time uncached)."""
    return _steady_state(np.ascontiguousarray(sos, dtype=np.float64).tobytes(), sos.shape)


@functools.lru_cache(maxsize=256)
def _steady_state(key: bytes, shape: tuple[int, ...]) -> NDArray[np.float64]:
    zi = sosfilt_zi(np.frombuffer(key).reshape(shape))
    zi.setflags(write=False)
    return zi


def sos_filtfilt(sos: NDArray[np.float64], a: NDArray[np.float64], axis: int, pad: int) -> NDArray[np.float64]:
    """`scipy.signal.sosfiltfilt(sos, a, axis, padtype="odd", padlen=pad)` (a float64, len > pad)."""
    if not HAVE_NUMBA:
        from scipy.signal import sosfiltfilt  # optional: scipy.signal, only without numba (48 MB, issue 25)

        return sosfiltfilt(sos, a, axis=axis, padtype="odd", padlen=pad)
    moved = np.moveaxis(a, axis, 0)
    n = moved.shape[0]
    ext = np.empty((n + 2 * pad, moved[0].size))
    # a's samples copied once, into the work array's middle: in any layout (channels stacked as rows, transposed:
    # NumPy's copy walks the destination's rows), without the C-order copy the kernel's indexing would need first
    ext[pad : pad + n] = moved.reshape(n, -1)
    sos = np.ascontiguousarray(sos / sos[:, 3:4])  # a0 = 1, as scipy normalises
    _filtfilt_columns(sos, steady_state(sos), pad, ext)
    return np.moveaxis(ext[pad : pad + n].reshape(moved.shape), 0, axis)


def sos_filtfilt_columns(sos: NDArray[np.float64], columns: list[NDArray[np.float64]], pad: int, width: int
                         ) -> NDArray[np.float64]:
    """`sos_filtfilt(sos, x, 0, pad)` of x (n, width) = the columns side by side ((n,) or (n, k) float64 each) then
    zero columns, (n, width) C order, without x: the columns are written straight into the work array's middle
    rows, a block of samples of every column at a time. A block of the C-order work array stays in cache while
    its rows fill; a whole column written at once touches a cache line per sample, and stacking the columns first
    sweeps memory twice (a 60 s segment's 43 channels: 5.6-6.3 -> 3.4-3.8 ms with the work array's allocation)."""
    n = len(columns[0])
    ext = np.empty((n + 2 * pad, width))
    mid = ext[pad : pad + n]
    step = max(1, FILL_BYTES // (8 * width))
    for lo in range(0, n, step):
        hi = min(n, lo + step)
        j = 0
        for a in columns:
            if a.ndim == 1:
                mid[lo:hi, j] = a[lo:hi]
                j += 1
            else:
                mid[lo:hi, j : j + a.shape[1]] = a[lo:hi]
                j += a.shape[1]
    mid[:, j:] = 0.0
    if not HAVE_NUMBA:
        from scipy.signal import sosfiltfilt  # optional: scipy.signal, only without numba (48 MB, issue 25)

        return sosfiltfilt(sos, mid, axis=0, padtype="odd", padlen=pad)
    sos = np.ascontiguousarray(sos / sos[:, 3:4])  # a0 = 1, as scipy normalises
    _filtfilt_columns(sos, steady_state(sos), pad, ext)
    return mid


FILL_BYTES = 768 * 1024  # of the work array per block of `sos_filtfilt_columns`' fill (43 columns: 2286 rows; 512 to
# 8192 rows measured, 2048 and 4096 the fastest, 512 1.3 x and whole columns 1.9 x slower)


def sosfilt_reversed(sos: NDArray[np.float64], x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Every column of x (n, C) float64 through `sos` once, backwards in time, from its last sample's steady state:
    `scipy.signal.sosfilt(sos, x[::-1], axis=0, zi=steady_state(sos)[..., None] * x[-1])[0][::-1]`, returned
    column-major (each channel's samples contiguous)."""
    # channels first: a column-major x (channels stacked as rows, transposed) is read as it is, a C-order one copied
    return sosfilt_reversed_rows([sos] * x.shape[1], np.ascontiguousarray(x.T)).T


def sosfilt_reversed_rows(soses: list[NDArray[np.float64]], x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Row c of x (C, n) float64 through its own soses[c] once, backwards in time, from its last sample's steady
    state (`sosfilt_reversed` of each row, in one pass: the rows side by side); (C, n), C order. The soses have the
    same number of sections."""
    C = x.shape[0]
    if len({sos.shape[0] for sos in soses}) > 1:
        raise ValueError(f"sosfilt_reversed_rows: filters of {sorted({s.shape[0] for s in soses})} sections")
    out = np.empty(x.shape)
    if not HAVE_NUMBA:
        from scipy.signal import sosfilt  # optional: scipy.signal, only without numba (48 MB, issue 25)

        for c in range(C):
            out[c] = sosfilt(soses[c], x[c, ::-1], zi=steady_state(soses[c]) * x[c, -1])[0][::-1]
        return out
    # the a0 = 1 sections (scipy normalises), their coefficients b0, b1, b2, a1, a2 and steady states per row
    coef = np.empty((soses[0].shape[0] if C else 0, 5, C))
    zi = np.empty((coef.shape[0], 2, C))
    cached: dict[int, tuple[NDArray, NDArray]] = {}
    for c, sos in enumerate(soses):
        if id(sos) not in cached:
            unit = np.ascontiguousarray(sos / sos[:, 3:4])
            cached[id(sos)] = unit[:, [0, 1, 2, 4, 5]], steady_state(unit)
        coef[:, :, c], zi[:, :, c] = cached[id(sos)]
    _reverse_columns(coef, zi, np.ascontiguousarray(x, dtype=np.float64), out)
    return out


def sosfilt_forward(sos: NDArray[np.float64], x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Every column of x (n, C) float64 through `sos` once, forwards from rest: `scipy.signal.sosfilt(sos, x,
    axis=0)`, (n, C)."""
    if not HAVE_NUMBA:
        from scipy.signal import sosfilt  # optional: scipy.signal, only without numba (48 MB, issue 25)

        return sosfilt(sos, x, axis=0)
    out = np.empty(x.shape)
    _forward_columns(np.ascontiguousarray(sos / sos[:, 3:4]), np.ascontiguousarray(x, dtype=np.float64), out)
    return out
