"""`read_recording` / `write_recording`: one entry point for every file format, chosen by extension or name.

| format    | extensions           | read options         | needs                     |
| --------- | -------------------- | -------------------- | ------------------------- |
| "csv"     | .csv .txt .tsv       | fs, time, delimiter, decimal, units_row, units_in_header, encoding | - |
| "parquet" | .parquet .pq         | fs, time             | pyarrow (extra `parquet`) |
| "mat"     | .mat                 | fs, time             | scipy; h5py for v7.3 (extra `mat73`) |
| "mdf"     | .mf4 .mdf            | -                    | asammdf (extra `mdf`)     |
| "rosbag"  | .db3 .mcap, a bag folder | topic            | rosbags (extra `ros`)     |

A ROS 2 bag (a folder with metadata.yaml, or its .db3 / .mcap file) is read only
(`dynid.io.rosbag_format`). Writing: "csv", "parquet", "mat", "mdf", always atomically (a temporary file in the
same folder, renamed over the target when complete).
"""

from __future__ import annotations

import inspect
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from ..textfiles import NotAFileError, regular_file
from .csv_format import read_csv, write_csv
from .errors import FileFormatError
from .mat_format import read_mat, write_mat
from .mdf_format import read_mdf, write_mdf
from .parquet_format import read_parquet, write_parquet
from .recording import Recording
from .rosbag_format import is_bag_folder, read_rosbag

READERS: dict[str, Callable[..., Recording]] = {
    "csv": read_csv,
    "parquet": read_parquet,
    "mat": read_mat,
    "mdf": read_mdf,
    "rosbag": read_rosbag,
}
WRITERS: dict[str, Callable[..., Path]] = {
    "csv": write_csv,
    "parquet": write_parquet,
    "mat": write_mat,
    "mdf": write_mdf,
}
EXTENSIONS = {
    ".csv": "csv",
    ".txt": "csv",
    ".tsv": "csv",
    ".parquet": "parquet",
    ".pq": "parquet",
    ".mat": "mat",
    ".mf4": "mdf",
    ".mdf": "mdf",
    ".db3": "rosbag",
    ".mcap": "rosbag",
}
ALIASES = {"mf4": "mdf", "mdf4": "mdf", "pq": "parquet", "matlab": "mat", "tsv": "csv", "txt": "csv",
           "ros": "rosbag", "ros2": "rosbag", "bag": "rosbag"}


_COMPRESSED = {".gz": "gunzip", ".zip": "unzip", ".bz2": "bunzip2", ".xz": "unxz", ".zst": "unzstd",
               ".7z": "7z x"}


def format_of(path: str | os.PathLike[str], format: str | None = None) -> str:
    """The format name for `path` ("csv", "parquet", "mat", "mdf" or "rosbag"), from `format` or the extension (a
    folder with a metadata.yaml is a ROS 2 bag)."""
    if format is not None:
        name = ALIASES.get(format.lower(), format.lower())
        if name not in READERS:
            raise FileFormatError(f"unknown format {format!r}; known: {', '.join(READERS)}", source=str(path))
        return name
    if is_bag_folder(path):
        return "rosbag"
    suffix = Path(path).suffix.lower()
    if suffix in _COMPRESSED:
        raise FileFormatError(f"{path}: a compressed file ({suffix}); decompress it first ({_COMPRESSED[suffix]} "
                              f"{Path(path).name}) and give the file inside", source=str(path))
    if suffix not in EXTENSIONS:
        raise FileFormatError(
            f"{path}: cannot tell the format from the extension {suffix or '(none)'!r}; pass format= one of "
            f"{', '.join(READERS)} (extensions known: {', '.join(EXTENSIONS)})",
            source=str(path),
        )
    return EXTENSIONS[suffix]


def _check_options(func: Callable[..., Any], fmt: str, options: dict[str, Any], what: str) -> None:
    params = inspect.signature(func).parameters
    allowed = [p for p, v in params.items() if v.kind is inspect.Parameter.KEYWORD_ONLY]
    unknown = [k for k, v in options.items() if k not in allowed and v is not None]  # None: not given
    if unknown:
        raise TypeError(
            f"{what} {fmt}: unknown option(s) {', '.join(unknown)}; "
            f"options of this format: {', '.join(allowed) or 'none'}"
        )


def read_recording(
    path: str | os.PathLike[str],
    format: str | None = None,
    *,
    channels: Sequence[str] | None = None,
    **options: Any,
) -> Recording:
    """Read a measurement file into a `Recording` (channels with units, each on its own time base).

    Parameters
    ----------
    path : the file.
    format : "csv", "parquet", "mat" or "mdf"; None: from the extension.
    channels : keep only these channels (the others are listed in `Recording.skipped`); Parquet
        files then read only those columns, the other formats are read whole and trimmed.
    options : the format's options (module docstring), e.g. fs= for a CSV without time column;
        an option set to None counts as not given (so fs=None may be passed for any format).

    Values are as in the file (units not converted: see `ChannelMap` / `to_si`). The
    data checks run when channels are used (`Recording.aligned`, `ChannelMap.apply`,
    `Recording.check`), so a bad channel that is not used does not stop the reading.
    """
    path = Path(path)
    fmt = format_of(path, format)
    reader = READERS[fmt]
    _check_options(reader, fmt, options, "reading")
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    try:
        if not (fmt == "rosbag" and is_bag_folder(path)):
            regular_file(path)  # a named pipe would block the reader for ever, /dev/zero never end
    except NotAFileError as exc:
        raise FileFormatError(str(exc), source=str(path)) from None
    params = inspect.signature(reader).parameters
    kwargs = {k: v for k, v in options.items() if k in params}
    if channels is not None and "channels" in params:
        return reader(path, channels=list(channels), **kwargs)
    rec = reader(path, **kwargs)
    if channels is not None:
        keep = set(channels)
        rec.skipped.update({n: "not among the channels asked for" for n in rec.channels if n not in keep})
        rec.channels = {n: c for n, c in rec.channels.items() if n in keep}
    return rec


def write_recording(
    recording: Recording, path: str | os.PathLike[str], format: str | None = None, **options: Any
) -> Path:
    """Write `recording` to `path` atomically (never a partial file); returns the path.

    format : "csv", "parquet", "mat" or "mdf"; None: from the extension.
    """
    fmt = format_of(path, format)
    writer = WRITERS[fmt]
    _check_options(writer, fmt, options, "writing")
    params = inspect.signature(writer).parameters
    return writer(recording, Path(path), **{k: v for k, v in options.items() if k in params})
