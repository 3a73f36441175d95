"""Parquet measurement files (needs pyarrow: the `parquet` extra).

A table with a time column (time, t, Time or TIME, or `time=`; float seconds, or a
timestamp column, then made relative to its first row with the start kept in the
metadata) or a sample rate from the caller, and one numeric column per channel.
Units come from each field's metadata, key b"unit" (or b"units"), or from the column's
name as in a CSV header: "imu_yaw_rate [deg/s]" is the channel imu_yaw_rate in deg/s
(what pandas gives after reading dynid's own CSV; io.units.name_and_unit); the recording's
metadata from the schema metadata key b"dynid.metadata" (JSON object of strings).
Nulls mean "no sample at this row" (multi-rate channels in one table); NaN values
are samples whose value is NaN. Text and other non-numeric columns are not read
(listed in `Recording.skipped`).
"""

from __future__ import annotations

import json
import os
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import atomic_path
from ._optional import require
from ._table import TIME_NAMES, Column, grid_of, recording_from_columns
from .errors import FileFormatError
from .recording import Recording
from .units import channel_names, name_and_unit

META_KEY = b"dynid.metadata"
ROW_GROUP_ROWS = 65536
_TICKS_PER_SECOND = {"s": 1.0, "ms": 1e3, "us": 1e6, "ns": 1e9}


def _unit_of(field: Any) -> str:
    meta = field.metadata or {}
    raw = meta.get(b"unit", meta.get(b"units", b""))
    return raw.decode("utf-8", errors="replace") if isinstance(raw, bytes) else str(raw)


def field_channels(fields: Sequence[Any], label: str) -> list[tuple[str, str]]:
    """The (channel name, unit) of each field: a unit written in the name taken as a CSV header's, agreeing with
    the field's unit metadata if it has one; two fields giving one channel are an error."""
    return channel_names([(f.name, _unit_of(f)) for f in fields], label)


def read_parquet(
    path: str | os.PathLike[str],
    *,
    fs: float | None = None,
    time: str | None = None,
    channels: Sequence[str] | None = None,
) -> Recording:
    """Read a Parquet file into a `Recording` (layout in the module docstring).

    Parameters
    ----------
    path : the file.
    fs : Hz, sample rate when there is no time column.
    time : name of the time column if it is not time/t/Time/TIME.
    channels : read only these columns (and the time column); the others are listed in
        `Recording.skipped` as not read. A logger file often holds many more channels than
        an identification needs: this saves their memory and reading time.
    """
    pa = require("pyarrow", "Reading Parquet files")
    path = Path(path)
    label = str(path)
    pfile = open_parquet(path, label)
    schema = pfile.schema_arrow
    metadata = schema_metadata(schema)
    columns, skipped = [], {}
    wanted = None if channels is None else set(channels) | {time, *TIME_NAMES} - {None}
    for field, (name, _) in zip(schema, field_channels(list(schema), label), strict=True):
        if wanted is not None and name not in wanted and field.name not in wanted:
            skipped[field.name] = "not among the channels asked for"
            continue
        if not is_numeric(pa, field.type):
            skipped[field.name] = f"column of type {field.type}, not numeric"
            continue
        # One column at a time: the memory peak is the data plus one column, not twice the file.
        col = read_columns(pfile, label, [field.name]).column(0)
        if pa.types.is_timestamp(field.type):
            start = col[0].as_py() if len(col) else None
            if start is not None:
                metadata.setdefault(f"{field.name}.start", start.isoformat())
        columns.append(convert_column(pa, field, col, first_tick(pa, col), label))
        del col
    if not columns:
        raise FileFormatError(f"{label}: no numeric column in the file", source=label)
    return recording_from_columns(path, columns, time=time, fs=fs, metadata=metadata, skipped=skipped)


# bounds on what opening a file holds before its data are read: the footer (every row group's metadata, read whole
# by pyarrow) and the row groups (one index entry and one read each). An hour of 60 channels at 625 Hz is a footer of
# tens of kB in a few row groups; a file appended row by row can have millions
MAX_FOOTER = 64 * 2**20
MAX_ROW_GROUPS = 100_000


def _footer_length(path: Any, filesystem: Any) -> int | None:
    """The footer's length from the file's last 8 bytes (length, b"PAR1"); None when it cannot be read so (another
    filesystem, a short file: pyarrow then says what is wrong)."""
    if filesystem is not None:
        return None
    try:
        with open(path, "rb") as fh:
            fh.seek(0, os.SEEK_END)
            if fh.tell() < 12:
                return None
            fh.seek(-8, os.SEEK_END)
            tail = fh.read(8)
    except OSError:
        return None
    return int.from_bytes(tail[:4], "little") if tail[4:] == b"PAR1" else None


def open_parquet(path: Any, label: str, filesystem: Any = None, metadata: Any = None) -> Any:
    """A `pyarrow.parquet.ParquetFile`; a file that is not Parquet, or whose footer or row-group count passes the
    bounds (MAX_FOOTER, MAX_ROW_GROUPS), is a one-line `FileFormatError`. metadata: the file's footer
    (`ParquetFile.metadata`) parsed before, by a caller sure the file is unchanged since: not read again."""
    pa = require("pyarrow", "Reading Parquet files")
    pq = require("pyarrow.parquet", "Reading Parquet files")
    footer = _footer_length(path, filesystem) if metadata is None else None
    if footer is not None and footer > MAX_FOOTER:
        raise FileFormatError(f"{label}: its Parquet footer is {footer:,} bytes (more than {MAX_FOOTER:,}): too many "
                              "row groups or columns to index; rewrite it with fewer, larger row groups (pyarrow's "
                              "row_group_size of 100 000 rows or more)", source=label)
    try:
        pfile = pq.ParquetFile(path, metadata=metadata, filesystem=filesystem)
    except (pa.ArrowInvalid, OSError) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise FileFormatError(f"{label}: not a readable Parquet file ({' '.join(str(exc).split())})",
                              source=label) from None
    groups = pfile.metadata.num_row_groups
    if groups > MAX_ROW_GROUPS:
        raise FileFormatError(f"{label}: {groups:,} row groups (more than {MAX_ROW_GROUPS:,}); rewrite it with "
                              "fewer, larger row groups (pyarrow's row_group_size of 100 000 rows or more)",
                              source=label)
    return pfile


# A long file's footer, cut per row group. pyarrow parses a footer whole (every row group's column chunks, ~8 times
# its size in the file once parsed: 1.9 MB an hour of 60 channels at 625 Hz in 65536-row groups), and reads a row
# group only through a parsed footer. A window reads a row group or two, so a long file's footer is kept as the
# bytes around the row-group list and each group's place in the file: a window's row group is read through a footer
# of that group alone, made from those bytes and the group's own (a 7 kB read, 0.3 ms more than a kept footer's open)
# and the memory kept does not grow with the file. The footer is Thrift's compact protocol (parquet.thrift): the
# FileMetaData struct's fields 3 (num_rows, i64) and 4 (row_groups, list<RowGroup>) are rewritten, every other byte,
# each RowGroup's included (its column chunks' offsets are the file's), kept as it is.
_STRUCT, _LIST, _SET, _MAP = 12, 9, 10, 11


def _varint(b: bytes, i: int) -> tuple[int, int]:
    out = shift = 0
    while True:
        x = b[i]
        i += 1
        out |= (x & 0x7F) << shift
        shift += 7
        if not x & 0x80:
            return out, i


def _skip(b: bytes, i: int, kind: int) -> int:
    """The position after a compact-protocol value of type `kind` at b[i]."""
    if kind in (1, 2):  # a bool field's value is in its header
        return i
    if kind == 3:  # byte
        return i + 1
    if kind in (4, 5, 6):  # i16, i32, i64: zigzag varints
        return _varint(b, i)[1]
    if kind == 7:  # double
        return i + 8
    if kind == 8:  # binary: a length, then the bytes
        n, i = _varint(b, i)
        return i + n
    if kind in (_LIST, _SET):
        head = b[i]
        i += 1
        n, item = head >> 4, head & 15
        if n == 15:
            n, i = _varint(b, i)
        for _ in range(n):
            i = i + 1 if item in (1, 2) else _skip(b, i, item)  # a bool element is a byte
        return i
    if kind == _MAP:
        n, i = _varint(b, i)
        if n:
            types = b[i]
            i += 1
            for _ in range(n):
                i = _skip(b, _skip(b, i, types >> 4), types & 15)
        return i
    if kind == _STRUCT:
        while True:
            head = b[i]
            i += 1
            if head == 0:  # stop
                return i
            if head >> 4 == 0:  # the field id in full (a zigzag i16) after the header
                i = _varint(b, i)[1]
            i = _skip(b, i, head & 15)
    raise ValueError(f"unknown compact-protocol type {kind}")


def _fields(b: bytes) -> dict[int, tuple[int, int, int]]:
    """The top-level struct's fields: id -> (type, its value's first byte, the byte after it)."""
    out, i, fid = {}, 0, 0
    while b[i]:
        head = b[i]
        i += 1
        if head >> 4:
            fid += head >> 4
        else:
            z, i = _varint(b, i)
            fid = (z >> 1) ^ -(z & 1)
        start = i
        i = _skip(b, i, head & 15)
        out[fid] = (head & 15, start, i)
    return out


def _uvarint(v: int) -> bytes:
    out = bytearray()
    while v >= 0x80:
        out.append((v & 0x7F) | 0x80)
        v >>= 7
    out.append(v)
    return bytes(out)


@dataclass(frozen=True)
class SplitFooter:
    """A Parquet file's footer cut per row group (the comment above): where the footer starts in the file, its bytes
    before num_rows's value, between it and the row-group list, after the list, and each row group's bytes in the
    footer (start, end) with its rows. Kept in place of the parsed footer: its size does not grow with the file."""

    start: int
    before: bytes
    between: bytes
    after: bytes
    spans: np.ndarray  # (row groups, 2) int64
    rows: np.ndarray  # (row groups,) int64

    def group_metadata(self, path: str | os.PathLike[str], group: int) -> Any:
        """The footer of row group `group` alone (a `FileMetaData` whose row group 0 is that group)."""
        pa = require("pyarrow", "Reading Parquet files")
        pq = require("pyarrow.parquet", "Reading Parquet files")
        a, b = (int(x) for x in self.spans[group])
        with open(path, "rb") as fh:
            fh.seek(self.start + a)
            own = fh.read(b - a)
        # num_rows the group's (a zigzag varint: 2 x rows), a list of one RowGroup, the group's bytes
        body = b"".join((self.before, _uvarint(2 * int(self.rows[group])), self.between, bytes([0x10 | _STRUCT]),
                         own, self.after))
        # the group's bytes are read again at each open, long after the footer was cut: a file written over in place
        # (its size and modification time unchanged, which the cache's key cannot see) gives other bytes there
        try:
            meta = pq.read_metadata(pa.BufferReader(body + struct.pack("<i", len(body)) + b"PAR1"))
            same = (len(own) == b - a and meta.num_row_groups == 1
                    and meta.row_group(0).num_rows == int(self.rows[group]))
        except (OSError, pa.ArrowException):
            same = False
        if not same:
            raise FileFormatError(f"{path}: row group {group}'s footer no longer reads as when the file was opened: "
                                  "the file was written over while being read; index it again (index_file)",
                                  source=str(path))
        return meta


def split_footer(path: str | os.PathLike[str], metadata: Any) -> SplitFooter | None:
    """The local file's footer cut per row group (`SplitFooter`), checked against pyarrow's parse of it
    (`metadata`: the count of row groups and their rows); None where it cannot be (an encrypted footer, a layout
    this reader does not know): the caller keeps the parsed footer then."""
    try:
        with open(path, "rb") as fh:
            fh.seek(-8, os.SEEK_END)
            n, magic = struct.unpack("<i4s", fh.read(8))
            if magic != b"PAR1":
                return None
            fh.seek(-8 - n, os.SEEK_END)
            start = fh.tell()
            b = fh.read(n)
        fields = _fields(b)
        if fields.get(3, (0,))[0] != 6 or fields.get(4, (0,))[0] != _LIST or fields[3][2] > fields[4][1]:
            return None
        i = fields[4][1]
        head = b[i]
        i += 1
        count, item = head >> 4, head & 15
        if count == 15:
            count, i = _varint(b, i)
        spans = []
        for _ in range(count):
            spans.append((i, _skip(b, i, _STRUCT)))
            i = spans[-1][1]
        rows = np.array([metadata.row_group(g).num_rows for g in range(metadata.num_row_groups)], dtype=np.int64)
        if item != _STRUCT or i != fields[4][2] or len(spans) != len(rows):
            return None
        # the row-group list's header is the first byte(s) of field 4's value; num_rows's value is rewritten
        before, between = b[:fields[3][1]], b[fields[3][2]:fields[4][1]]
        return SplitFooter(start, before, between, b[fields[4][2]:], np.array(spans, dtype=np.int64).reshape(-1, 2),
                           rows)
    except (OSError, IndexError, ValueError, struct.error):
        return None


def read_columns(pfile: Any, label: str, columns: list[str], group: int | None = None,
                 named: int | None = None) -> Any:
    """`pfile.read_row_group(group, columns)` (group None: the whole file's); a damaged data page (pyarrow's
    OSError or ArrowException, which name no file) is a one-line `FileFormatError` naming the file and the row
    group (`named`, when `pfile` holds the group under another number: a footer cut per row group's group 0)."""
    pa = require("pyarrow", "Reading Parquet files")
    try:
        if group is None:
            return pfile.read(columns=columns, use_pandas_metadata=False)
        return pfile.read_row_group(group, columns=columns, use_pandas_metadata=False)
    except (OSError, pa.ArrowException) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        where = "" if group is None else f"row group {group if named is None else named}, "
        shown = ", ".join(columns[:3]) + (", ..." if len(columns) > 3 else "")
        raise FileFormatError(
            f"{label}: {where}column(s) {shown}: not readable Parquet data ({' '.join(str(exc).split())}); the file is "
            "damaged or cut short: write it (or copy it) again", source=label) from None


def schema_metadata(schema: Any) -> dict[str, str]:
    """The recording's metadata stored in the schema (b"dynid.metadata"), with format = parquet."""
    metadata = {"format": "parquet"}
    schema_meta = schema.metadata or {}
    if META_KEY in schema_meta:
        try:
            stored = json.loads(schema_meta[META_KEY].decode("utf-8"))
            metadata.update({str(k): str(v) for k, v in stored.items()})
        except (ValueError, AttributeError):
            metadata["metadata_error"] = "dynid.metadata is not a JSON object"
    return metadata


def is_numeric(pa: Any, kind: Any) -> bool:
    """Whether a column of this Arrow type is read as a channel (timestamps, floats, integers, booleans)."""
    return bool(
        pa.types.is_timestamp(kind) or pa.types.is_floating(kind) or pa.types.is_integer(kind)
        or pa.types.is_boolean(kind)
    )


def first_tick(pa: Any, col: Any) -> int | None:
    """The integer tick of a timestamp column's first row (0 if that row is null), None for other columns."""
    if not pa.types.is_timestamp(col.type) or len(col) == 0:
        return None
    return int(to_numpy(pa, col.slice(0, 1).cast(pa.int64()).fill_null(0), np.int64)[0])


def to_numpy(pa: Any, col: Any, dtype: type, copy: bool = True) -> np.ndarray:
    """A primitive Arrow array or chunked array (float64, int64 or boolean, without nulls where it matters) as a
    NumPy copy, from its buffers: pyarrow's own ``to_numpy`` imports pandas to check for it (64 MB of resident
    memory on the first Parquet read, a third of a robot run's floor, for nothing). copy=False: a read-only view of
    the Arrow buffer when the column is one chunk of that dtype (it keeps the buffer alive; a copy costs its page
    faults, a third of a Parquet window's read)."""
    dtype = np.dtype(dtype)
    parts = []
    for ch in getattr(col, "chunks", [col]):
        n = len(ch)
        if n == 0:
            continue
        buf = ch.buffers()[1]
        if pa.types.is_boolean(ch.type):  # bit-packed, least significant bit first
            bits = np.unpackbits(np.frombuffer(buf, np.uint8), bitorder="little")
            parts.append(bits[ch.offset:ch.offset + n].astype(bool))
        else:
            parts.append(np.frombuffer(buf, dtype=dtype, count=n, offset=dtype.itemsize * ch.offset))
    if not copy and len(parts) == 1 and parts[0].dtype == dtype:
        parts[0].flags.writeable = False  # Arrow's buffers are immutable (pyarrow's may still lend them writable)
        return parts[0]
    return np.concatenate(parts).astype(dtype, copy=False) if parts else np.empty(0, dtype)


def convert_column(pa: Any, field: Any, col: Any, tick0: int | None, label: str = "", copy: bool = True) -> Column:
    """One numeric Arrow column (or a run of its rows) as a `Column` of float64 samples.

    A timestamp column becomes seconds since `tick0`, the integer tick of the FILE's
    first row (exact integer difference, then one division: epoch ns do not fit a
    float64), so rows converted in pieces equal the whole column bit for bit. Integers
    and booleans are cast to float64; nulls are rows without a sample. The column is named by its channel
    ("yaw_rate [deg/s]" is yaw_rate, in deg/s); `label` names the file in an error. copy=False: a float64 column
    without nulls is a read-only view of its Arrow buffer (`to_numpy`).
    """
    name, unit = name_and_unit(field.name, _unit_of(field), label)
    kind = field.type
    if pa.types.is_timestamp(kind):
        ticks = to_numpy(pa, col.cast(pa.int64()).fill_null(0), np.int64)
        if ticks.size:
            values = (ticks - np.int64(tick0 if tick0 is not None else ticks[0])) / _TICKS_PER_SECOND[kind.unit]
        else:
            values = ticks.astype(np.float64)
        unit = "s"
    else:
        values = to_numpy(pa, col.cast(pa.float64()), np.float64, copy)
    present = ~to_numpy(pa, col.is_null(), bool) if col.null_count else None
    return Column(name, unit, values if present is None else values[present], present)


def write_parquet(recording: Recording, path: str | os.PathLike[str], *, compression: str = "snappy") -> Path:
    """Write the recording as Parquet, atomically (a time column "time" in s, nulls where a channel has no sample).

    Units go in each field's metadata (b"unit"), the recording's metadata in the
    schema metadata (b"dynid.metadata", JSON). Returns the path written.
    """
    pa = require("pyarrow", "Writing Parquet files")
    pq = require("pyarrow.parquet", "Writing Parquet files")
    path = Path(path)
    grid = grid_of(recording)
    fields = [pa.field("time", pa.float64(), nullable=False, metadata={b"unit": b"s"})]
    arrays = [pa.array(grid.time, type=pa.float64())]
    for name, unit, values, present in zip(grid.names, grid.units, grid.values, grid.present, strict=True):
        fields.append(pa.field(name, pa.float64(), metadata={b"unit": unit.encode("utf-8")}))
        mask = None if present is None else ~present
        arrays.append(pa.array(values, type=pa.float64(), mask=mask))
    meta = {k: v for k, v in recording.metadata.items() if k != "format"}
    schema = pa.schema(fields, metadata={META_KEY: json.dumps(meta).encode("utf-8")})
    table = pa.Table.from_arrays(arrays, schema=schema)
    with atomic_path(path) as tmp:
        # row groups of 65536 rows: the smallest unit a reader decodes, so a time window of a long file costs
        # about its own rows (pyarrow's default, a million rows, is 470 MB for 55 channels)
        pq.write_table(table, tmp, compression=compression, row_group_size=ROW_GROUP_ROWS)
    return path
