"""Measurement files: channels with units, multi-rate alignment, unit conversion, data checks.

The file boundary of the pipeline (DESIGN §2: SI inside, converted once here).

- `read_recording(path, format=None, **options) -> Recording`: CSV, Parquet, MATLAB
  .mat, ASAM MDF4; `write_recording(recording, path, format=None)`, atomic.
- `Channel` (name, unit as written, values (n,), time (n,) s) and `Recording`
  (source, channels, metadata): `.channel(name)`, `.aligned(names, fs=... | t=...)`,
  `.check()`, `.saturation()`.
- `to_si(values, unit) -> (values, si_unit)`, `unit_factor`, `known_units`.
- Windows of a file read without reading it whole (`windows`): `index_file(path, ...) ->
  FileIndex` (one streaming pass), `read_window(index, channels, t0, t1)`,
  `iter_blocks(index, channels)`, bit for bit the whole-file reader's samples.
- `ChannelMap`: model quantity -> channel, unit, scale, offset, sign; `.apply(recording)`
  gives SI values on each channel's time base, `.aligned(recording, fs=...)` on one clock.
- Checks (`check_*`) and errors: every error is a `DataError` (a `ValueError`) naming the
  file, line, channel, sample index and time, and saying what to do.

Formats other than CSV and MATLAB v5/v7 need optional packages (imported on first use;
`MissingDependencyError` names the one to install): pyarrow (Parquet), asammdf (MDF),
h5py (MATLAB v7.3).
"""

from .align import Aligned, align
from .checks import (
    Span,
    check_channel,
    check_channels,
    check_finite,
    check_gaps,
    check_length,
    check_saturation,
    check_time,
)
from .errors import (
    DataError,
    DataWarning,
    FileFormatError,
    GapError,
    MappingError,
    MissingChannelError,
    MissingDependencyError,
    RecordTooShortError,
    SaturationWarning,
    TimeBaseError,
    UnitOverrideWarning,
    UnknownUnitError,
)
from .files import format_of, read_recording, write_recording
from .mapping import ChannelMap, QuantitySpec
from .recording import Channel, Recording
from .units import STANDARD_GRAVITY, known_units, normalize_unit, to_si, unit_factor
from .windows import Block, FileIndex, index_file, iter_blocks, read_window, time_bases

__all__ = [
    "STANDARD_GRAVITY",
    "Aligned",
    "Block",
    "Channel",
    "ChannelMap",
    "DataError",
    "DataWarning",
    "FileFormatError",
    "FileIndex",
    "GapError",
    "MappingError",
    "MissingChannelError",
    "MissingDependencyError",
    "QuantitySpec",
    "RecordTooShortError",
    "Recording",
    "SaturationWarning",
    "Span",
    "TimeBaseError",
    "UnitOverrideWarning",
    "UnknownUnitError",
    "align",
    "check_channel",
    "check_channels",
    "check_finite",
    "check_gaps",
    "check_length",
    "check_saturation",
    "check_time",
    "format_of",
    "index_file",
    "iter_blocks",
    "known_units",
    "normalize_unit",
    "read_recording",
    "read_window",
    "time_bases",
    "to_si",
    "unit_factor",
    "write_recording",
]
