"""`Channel`: one logged signal on its own time base, in the file's unit.

Below `checks`, `align` and `recording`, which all take channels (so that none of them imports another
for the type).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import DataError


@dataclass(frozen=True, eq=False)
class Channel:
    """One channel of a measurement file.

    Attributes
    ----------
    name : str
        As in the file (without the unit).
    unit : str
        As written in the file ("deg", "km/h", "N·m", ...); "" when the file gives none.
    values : array (n,), float64, in `unit`.
    time : array (n,), float64, s, the channel's own time stamps.
    lines : array (n,) of int, or None
        For text files, the file line (1-based) each sample was read from, so that
        errors can name it; None for binary formats.
    """

    name: str
    unit: str
    values: NDArray[np.float64]
    time: NDArray[np.float64]
    lines: NDArray[np.int64] | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        values = _vector(self.values, f"channel {self.name!r}: values")
        time = _vector(self.time, f"channel {self.name!r}: time")
        if values.size != time.size:
            raise DataError(
                f"channel {self.name!r} has {values.size} values but {time.size} time stamps", channel=self.name
            )
        if self.lines is not None and np.shape(self.lines) != values.shape:
            raise DataError(f"channel {self.name!r}: lines must match the values, shape {values.shape}")
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "time", time)
        object.__setattr__(self, "unit", "" if self.unit is None else str(self.unit))

    def __len__(self) -> int:
        return int(self.values.size)

    @property
    def span(self) -> tuple[float, float]:
        """(first, last) time stamp, s."""
        if self.time.size == 0:
            raise DataError(f"channel {self.name!r} has no samples", channel=self.name)
        return float(self.time[0]), float(self.time[-1])

    @property
    def rate(self) -> float:
        """Nominal sample rate, Hz: 1 / the median step of the time stamps (nan below 2 samples, or when most
        stamps repeat or go back: no rate to tell)."""
        if self.time.size < 2:
            return float("nan")
        step = float(np.median(np.diff(self.time)))
        return 1.0 / step if step > 0 else float("nan")

    def line(self, k: int) -> int | None:
        """File line of sample k, or None when the format has no lines."""
        return None if self.lines is None else int(self.lines[k])


def _vector(x: ArrayLike, what: str) -> NDArray[np.float64]:
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise DataError(f"{what} are not numbers: {exc}") from None
    if a.ndim != 1:
        a = np.squeeze(a)
        if a.ndim != 1:
            raise DataError(f"{what} must be one value per sample (1-D), got shape {np.shape(x)}")
    return a
