"""Signal conditioning (paper §6.2): filtering, differentiation, integration, resampling, decimation.

Pure functions over NumPy arrays, batched: time is axis 0 unless `axis` says
otherwise, every other index is an independent channel. Rates and cut-offs in Hz,
everything else in SI. Bad input raises `SignalError` (a `ValueError`) naming the
sample, column or stage at fault.

- `lowpass`: zero-phase (forward-backward) Butterworth low-pass; `lowpass_columns`: of
  separate channels side by side, without stacking them first.
- `derivative`, `filtered_derivatives`: central differences, and the paper's
  band-pass derivative (zero-phase low-pass, then central differences).
- `integrate`: cumulative trapezoidal rule, no phase shift.
- `border_samples`, `trim`: the ends a filter transient spoils, and cutting them off.
- `decimate_parallel`: the same anti-alias filter on every column of W and Y, then
  keep one sample in `factor` (Gautier's parallel decimation).
- `resample`, `common_clock`: channels on their own time bases onto one clock.
"""

from .borders import border_samples, trim
from .decimation import decimate_parallel
from .derivatives import derivative, filtered_derivatives
from .errors import SignalError
from .filters import lowpass, lowpass_columns
from .integration import integrate
from .resampling import common_clock, resample

__all__ = [
    "SignalError",
    "border_samples",
    "common_clock",
    "decimate_parallel",
    "derivative",
    "filtered_derivatives",
    "integrate",
    "lowpass",
    "lowpass_columns",
    "resample",
    "trim",
]
