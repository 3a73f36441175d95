"""Input checks shared by the signal functions; every failure is a `SignalError`.

Private: the public functions call these so that all of them word the same problem
the same way (what, where, what to do).
"""

from __future__ import annotations

import math
import numbers

import numpy as np
from numpy.lib.array_utils import normalize_axis_index
from numpy.typing import ArrayLike, NDArray

from .errors import SignalError

# Bytes of float64 work space one column block may use (a few copies are made of it).
BLOCK_BYTES = 16 * 2**20


def as_float(x: ArrayLike, name: str, min_ndim: int = 1) -> NDArray[np.float64]:
    """`x` as a float64 array with at least `min_ndim` dimensions."""
    if np.iscomplexobj(x):
        raise SignalError(f"{name} is complex; the signal functions take real signals only")
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise SignalError(f"{name} is not a numeric array: {exc}") from exc
    if a.ndim < min_ndim:
        raise SignalError(f"{name} has {a.ndim} dimension(s); it needs at least {min_ndim} (time is one of them)")
    return a


def time_axis(a: NDArray, axis: int, name: str) -> int:
    """`axis` normalised to 0..a.ndim-1."""
    if isinstance(axis, bool) or not isinstance(axis, numbers.Integral):
        raise SignalError(f"axis must be an integer, not {axis!r}")
    try:
        return normalize_axis_index(int(axis), a.ndim)
    except np.exceptions.AxisError as exc:
        raise SignalError(f"axis {axis} does not exist for {name} of shape {a.shape}") from exc


def rate(fs: float, name: str = "fs") -> float:
    """A sample rate (Hz) as a positive finite float."""
    try:
        value = float(fs)
    except (TypeError, ValueError) as exc:
        raise SignalError(f"{name} must be a number in Hz, not {fs!r}") from exc
    if not math.isfinite(value) or value <= 0.0:
        raise SignalError(f"{name} must be a positive finite sample rate in Hz, got {fs!r}")
    return value


def filter_order(order: int) -> int:
    """A Butterworth order (per pass) as an int >= 1."""
    if isinstance(order, bool) or not isinstance(order, numbers.Integral):
        raise SignalError(f"order must be an integer >= 1, not {order!r}")
    if order < 1:
        raise SignalError(f"order must be >= 1, got {order}")
    return int(order)


def cutoff_frequency(cutoff: float, fs: float) -> float:
    """A low-pass cut-off (Hz) strictly between 0 and the Nyquist frequency fs/2."""
    try:
        value = float(cutoff)
    except (TypeError, ValueError) as exc:
        raise SignalError(f"cutoff must be a number in Hz, not {cutoff!r}") from exc
    if not math.isfinite(value) or value <= 0.0:
        raise SignalError(f"cutoff must be a positive finite frequency in Hz, got {cutoff!r}")
    if value >= fs / 2.0:
        raise SignalError(
            f"cutoff {value:g} Hz is not below the Nyquist frequency fs/2 = {fs / 2.0:g} Hz; "
            "lower the cut-off or sample faster"
        )
    return value


def block_columns(n_rows: int) -> int:
    """How many float64 columns of `n_rows` samples fit in one work block."""
    return max(1, BLOCK_BYTES // (8 * max(n_rows, 1)))


def _first_bad(flat: NDArray[np.float64]) -> tuple[int, int, int] | None:
    """(row, column, count) of the first non-finite entry of a 2-D (N, C) array, row-major.

    Scans in blocks of columns so that the boolean mask never costs more than a block.
    """
    n, c = flat.shape
    step = block_columns(n)
    best: tuple[int, int] | None = None
    count = 0
    for c0 in range(0, c, step):
        bad = ~np.isfinite(flat[:, c0 : c0 + step])
        nbad = int(np.count_nonzero(bad))
        if nbad == 0:
            continue
        count += nbad
        rows = np.flatnonzero(bad.any(axis=1))
        row = int(rows[0])
        col = c0 + int(np.flatnonzero(bad[row])[0])
        if best is None or row < best[0]:
            best = (row, col)
    if best is None:
        return None
    return best[0], best[1], count


def finite(a: NDArray[np.float64], name: str, axis: int = 0, what: str = "fill or cut the gap first") -> None:
    """Raise if `a` holds a NaN or an infinity, naming the first bad sample and column.

    "First" is the smallest index along the time `axis`; among the columns at that
    sample, the first in C order. The column is given as an index into the other axes.
    """
    if a.size == 0:
        return
    # one reading pass, no mask: a NaN or an infinity makes the sum NaN or infinite, so a finite sum means every
    # entry is finite (finite entries whose sum overflows fall through to the scan, which finds none)
    with np.errstate(over="ignore", invalid="ignore"):  # inf - inf or an overflow: the scan decides
        total = np.sum(a)
    if np.isfinite(total):
        return
    moved = np.moveaxis(a, axis, 0)
    n = moved.shape[0]
    flat = moved.reshape(n, -1)
    found = _first_bad(flat)
    if found is None:
        return
    row, col, count = found
    other = moved.shape[1:]
    col_index = tuple(int(i) for i in np.unravel_index(col, other)) if other else ()
    full = list(col_index)
    full.insert(axis, row)
    value = a[tuple(full)]
    where = f"at sample {row}"
    if len(col_index) == 1:
        where += f", column {col_index[0]}"
    elif col_index:
        where += f", column {col_index}"
    raise SignalError(
        f"{name} has a non-finite value ({value}) {where} "
        f"({name}[{', '.join(str(i) for i in full)}]); {count} non-finite value(s) in all; {what}"
    )
