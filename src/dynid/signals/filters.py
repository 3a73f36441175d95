"""Zero-phase Butterworth low-pass filtering (forward-backward, like MATLAB `filtfilt`).

Paper §6.2: every measurement is low-pass filtered forward then backward, so the
filter adds no phase (no lag between channels, which matters because W and Y mix
positions, velocities, accelerations and forces sampled at the same instants).

Conventions of this module, shared by the derivative and decimation modules:
- `cutoff` and `fs` in Hz; `order` is the order of ONE pass. Forward-backward
  squares the magnitude: the effective response is |H(f)|^2, i.e. twice the
  roll-off of `order` (order 4 falls like an 8th-order filter) and -6 dB, not
  -3 dB, at the cut-off. In the digital design (bilinear transform, prewarped)
  |H(f)|^2 = 1 / (1 + (tan(pi f / fs) / tan(pi cutoff / fs))^(2 order)).
- The filter is designed as second-order sections (numerically safe at the low
  cut-off to sample-rate ratios of vehicle data, 3 Hz at 625 Hz).
- Ends: like `filtfilt`, the record is extended at each end by an odd reflection of
  3 x (number of filter taps) samples and the filter state starts in steady state.
  This keeps the ends usable for smooth signals but does not make them exact: see
  `border_samples` for how many end samples to distrust.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _checks
from ._butterworth import butter_lowpass_sos
from ._zero_phase import sos_filtfilt, sos_filtfilt_columns, sosfilt_reversed, sosfilt_reversed_rows
from .errors import SignalError


def design_lowpass(fs: float, cutoff: float, order: int) -> NDArray[np.float64]:
    """Digital Butterworth low-pass of one pass as second-order sections, shape (ceil(order/2), 6).

    Package helper; arguments are assumed already checked. The design is cached: a pipeline asks
    for the same few filters thousands of times (each caller gets its own copy: scipy's sosfilt
    wants a writable array).
    """
    return _design(float(fs), float(cutoff), int(order)).copy()


@functools.lru_cache(maxsize=256)
def _design(fs: float, cutoff: float, order: int) -> NDArray[np.float64]:
    sos = butter_lowpass_sos(order, cutoff, fs)  # scipy.signal.butter(..., output="sos"), without its import
    sos.setflags(write=False)
    return sos


def pad_length(sos: NDArray[np.float64]) -> int:
    """Samples of odd-reflection padding added at each end, 3 x (number of taps), as `filtfilt`.

    A section whose b2 and a2 are both zero (odd orders) is first order: it does not
    add a tap. The record must be strictly longer than this.
    """
    taps = 2 * sos.shape[0] + 1
    taps -= min(int(np.count_nonzero(sos[:, 2] == 0)), int(np.count_nonzero(sos[:, 5] == 0)))
    return 3 * taps


def apply_zero_phase(sos: NDArray[np.float64], a: NDArray[np.float64], axis: int, name: str, context: str) -> NDArray:
    """Forward-backward `sos` along `axis` of a checked float array, with the length check.

    Package helper: `context` says which filter this is, for the error message.
    """
    pad = pad_length(sos)
    n = a.shape[axis]
    if n <= pad:
        raise SignalError(
            f"{name} has {n} samples along axis {axis}; {context} pads {pad} samples at each end "
            f"and needs at least {pad + 1}. Use a longer record or a lower order"
        )
    return sos_filtfilt(sos, a, axis, pad)


def undo_lowpass_phase(x: NDArray[np.float64], fs: float, cutoff: float, order: int) -> NDArray[np.float64]:
    """x (1-D) with the phase of a causal digital Butterworth low-pass (the design of `design_lowpass`) undone:
    the same filter run backwards in time from the last sample's steady state. Zero phase overall; the gain
    becomes |H|^2 (within 0.2 % of 1 below a fifth of the cut-off). Package helper: a sensor's declared band
    limit (vehicle.estimate.compensate); arguments assumed checked, cutoff < fs / 2."""
    return sosfilt_reversed(design_lowpass(fs, cutoff, order), np.asarray(x, dtype=np.float64)[:, None])[:, 0]


def undo_lowpass_phase_columns(x: NDArray[np.float64], fs: float, cutoff: float, order: int) -> NDArray[np.float64]:
    """`undo_lowpass_phase` of every column of x (N, C) float64 in one compiled pass (the channels side by side),
    returned column-major (N, C). Package helper: arguments assumed checked, cutoff < fs / 2."""
    return sosfilt_reversed(design_lowpass(fs, cutoff, order), x)


def undo_lowpass_phase_rows(x: NDArray[np.float64], fs: float, filters: list[tuple[float, int]]
                            ) -> NDArray[np.float64]:
    """`undo_lowpass_phase` of row c of x (C, N) float64 with its own (cutoff, order) = filters[c], all rows in one
    compiled pass (the channels side by side, whatever their filter); (C, N), C order. Package helper: arguments
    assumed checked, each cutoff < fs / 2; the orders give the same number of sections (ceil(order / 2))."""
    soses = {f: design_lowpass(fs, *f) for f in dict.fromkeys(filters)}
    return sosfilt_reversed_rows([soses[f] for f in filters], x)


def lowpass(x: ArrayLike, fs: float, cutoff: float, order: int = 4, axis: int = 0, check_finite: bool = True
            ) -> NDArray[np.float64]:
    """Zero-phase Butterworth low-pass of `x` along `axis`.

    Parameters
    ----------
    x : array (..., N, ...)
        Real samples, N along `axis` (time is axis 0 by default), any unit.
        Every other index is an independent channel filtered the same way.
    fs : float
        Sample rate in Hz (the paper's 1.6 ms sample time is fs = 625 Hz).
    cutoff : float
        Cut-off frequency in Hz of one pass, 0 < cutoff < fs/2. The forward-backward
        gain there is 1/2 (-6 dB).
    order : int
        Butterworth order of one pass, >= 1. Forward-backward doubles it: the
        default 4 gives the magnitude of an 8th-order filter with no phase.
    axis : int
        Time axis.
    check_finite : bool
        False: x is not scanned for NaN or infinities (a caller that checked its inputs and filters what it
        computed from them: the scan reads every sample); a non-finite value then spreads over its column.

    Returns
    -------
    array, same shape as `x`, float64, same unit.

    Raises
    ------
    SignalError
        cutoff not in (0, fs/2); order < 1; fewer samples than the end padding needs
        (the message gives both numbers); a NaN or infinity in `x` (the message gives
        the first bad sample index and column).
    """
    a = _checks.as_float(x, "x")
    ax = _checks.time_axis(a, axis, "x")
    fs = _checks.rate(fs)
    order = _checks.filter_order(order)
    cutoff = _checks.cutoff_frequency(cutoff, fs)
    if check_finite:
        _checks.finite(a, "x", ax, "filtering would spread it over the whole record; fill or cut the gap first")
    sos = design_lowpass(fs, cutoff, order)
    return apply_zero_phase(sos, a, ax, "x", f"the order-{order} zero-phase low-pass")


def lowpass_columns(columns: Sequence[ArrayLike], fs: float, cutoff: float, order: int = 4, width: int | None = None,
                    check_finite: bool = True) -> NDArray[np.float64]:
    """`lowpass` (axis 0) of the columns side by side, without stacking them first: columns[i] (N,) or (N, k), the
    samples along axis 0; returns (N, width) C order, the columns in turn then zero columns. width: at least their
    number (default it); the compiled filter runs its channels in vectors of 8, so 6 or 7 columns given 8 cost less.
    Each column's result is `lowpass`'s of it alone (the same bits). Raises as `lowpass` (a non-finite value names
    columns[i] and its sample)."""
    arrays = [_checks.as_float(a, f"columns[{i}]") for i, a in enumerate(columns)]
    if not arrays:
        raise SignalError("lowpass_columns: no columns given")
    fs = _checks.rate(fs)
    order = _checks.filter_order(order)
    cutoff = _checks.cutoff_frequency(cutoff, fs)
    n = arrays[0].shape[0]
    count = 0
    for i, a in enumerate(arrays):
        if a.ndim > 2 or a.shape[0] != n:
            raise SignalError(f"columns[{i}] has shape {a.shape}; every column needs ({n},) or ({n}, k) (the first's "
                              "samples)")
        if check_finite:
            _checks.finite(a, f"columns[{i}]", 0, "filtering would spread it over the whole record; fill or cut the "
                           "gap first")
        count += 1 if a.ndim == 1 else a.shape[1]
    width = count if width is None else int(width)
    if width < count:
        raise SignalError(f"lowpass_columns: width {width} is less than the columns' {count}")
    sos = design_lowpass(fs, cutoff, order)
    pad = pad_length(sos)
    if n <= pad:
        raise SignalError(f"columns[0] has {n} samples along axis 0; the order-{order} zero-phase low-pass pads {pad} "
                          f"samples at each end and needs at least {pad + 1}. Use a longer record or a lower order")
    return sos_filtfilt_columns(sos, arrays, pad, width)
