"""Time windows of a measurement file, read without reading the file whole.

A long test (an hour of 55 channels at 625 Hz) is processed as overlapping time
segments, each read on its own, possibly on another machine, so that the memory needed
does not grow with the file's length. This module is that reading layer:

- `index_file(path, ...) -> FileIndex`: one streaming pass over the file (bounded memory)
  that records where its rows lie in time, block by block. The index is small
  (O(rows / block) entries), picklable, and holds everything a reader needs, so that a
  worker given (index, channels, t0, t1) opens the file and reads only what the window needs.
- `read_window(index, channels, t0, t1) -> Recording`: the samples with t0 <= t <= t1.
- `iter_blocks(index, channels) -> Iterator[Recording]`: the file as consecutive blocks,
  one in memory at a time (a planning pass reads the time bases and checks them).

Both give, bit for bit, what `read_recording(path, channels=...)` gives restricted to the
window (or cut into the blocks): the numbers are parsed and converted by the same
functions as the whole-file readers (`csv_format.parse_rows`, `parquet_format.convert_column`,
`mdf_format.group_channels`, `_table.recording_from_columns`).

What a block is, per format:

| format  | block                                                 | a window reads                     |
| ------- | ----------------------------------------------------- | ---------------------------------- |
| csv     | `block_rows` consecutive lines of data (byte range)   | the blocks its time span overlaps  |
| parquet | one row group (the writer's `row_group_size`)         | the row groups it overlaps         |
| mdf     | `block_rows` consecutive records of one channel group | each group's records it overlaps   |
| mat 7.3 | `block_rows` consecutive rows of one time vector      | slices of each vector it overlaps  |
| mat v5  | the whole file (scipy cannot read a v5 file in parts) | the whole file (cached), sliced    |
| rosbag  | `block_rows` consecutive messages of the topic        | the blocks its time span overlaps  |

The index of a MAT file is built from the file read whole, once (v7.3 files are then
read in slices: HDF5 datasets; v5 files, MATLAB's default below 2 GB, are not streamed).

Each block records its first and last time stamp (min and max: NaN stamps left out) and
whether its stamps never go back. A window reads every block whose [min, max] meets
[t0, t1] and keeps the rows inside, so stamps that go back (a bad logger) never make a
window drop rows; `FileIndex.monotonic` tells whether the file's stamps never go back,
which a planner should check (a window of a file whose stamps go back may read many blocks).

Channels: every channel asked for is in the window's `Recording`, with 0 samples when it
has none in the window (or none at all in the file: `read_recording` lists those in
`Recording.skipped` instead). The time column is not a channel. MDF channels are named as
`read_mdf` names them ("name@group" for a name in several groups). In MDF and MAT v7.3
files a block holds the channels of one group (time base) only, the others come out with
0 samples in that block; `iter_blocks` yields the groups' blocks merged by first stamp.

Recently decoded blocks are kept in a per-process cache, at most `CACHE_BLOCKS` (3) blocks
of a file and `CACHE_BYTES` (512 MiB) in all, least recently used out first (0 turns it
off), so that windows read in time order decode each CSV block or Parquet row group about
once: a Parquet row group is the smallest unit pyarrow decodes, and other writers often make
them a million rows long (pyarrow's default), far longer than a window. The memory a window
needs is therefore bounded by the cache and the row-group size, not by the file's length;
dynid's `write_parquet` writes row groups of 65536 rows, which need far less. A Parquet file's footer (its
metadata, which lists every row group) is parsed once per process too, for at most `FOOTER_FILES` (4) files, and
again when the file's size or modification time changes; a local file's footer of more than `FOOTER_WHOLE` bytes is
kept cut per row group (`parquet_format.SplitFooter`), a window's row group read through a footer of its own, so
that what is kept does not grow with the file's length.

The CSV index parses only the time column (and checks every row has a stamp); the other
cells are parsed, and a bad one reported as `read_csv` reports it, when a window reads them.

A file changed on disk (size or modification time) since it was indexed is refused:
the index would point at the wrong bytes.

Paths may be URLs (s3://, file://, memory://...) when fsspec is installed (with the
package of the scheme, e.g. s3fs): CSV, Parquet and MDF files are then read through it,
ranges only; MATLAB files need a local path. fsspec is not a dependency of dynid.
"""

from __future__ import annotations

import heapq
import os
import threading
import zlib
from collections import OrderedDict
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from datetime import datetime
from itertools import islice
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
from numpy.typing import NDArray

from ..textfiles import NotAFileError, encoding_problem, regular_file
from . import csv_format, mat_format, mdf_format, parquet_format, rosbag_format
from ._optional import require
from ._table import (
    TIME_NAMES,
    Column,
    find_time_column,
    recording_from_columns,
    table_time,
    time_in_seconds,
    uniform_time,
)
from .checks import missing_error
from .errors import DataError, FileFormatError
from .files import READERS, _check_options, format_of
from .mat_format import read_mat
from .recording import Channel, Recording

CACHE_BYTES = 512 * 2**20  # decoded blocks kept per process (least recently used dropped first)

_EMPTY_F = np.empty(0, dtype=np.float64)
_EMPTY_I = np.empty(0, dtype=np.int64)


@dataclass(frozen=True)
class Block:
    """One block of a file's rows and where it lies in time.

    row0 : index of the block's first row in the file (MDF: first record in its group).
    rows : number of rows (CSV: of data rows, blank lines not counted; MDF: records).
    t_min, t_max : s, smallest and largest time stamp in the block, NaN stamps left out
        (+inf and -inf when the block has none: no window meets it).
    increasing : the block's stamps never go back (non-decreasing, no NaN).
    group : Parquet row group; MDF channel group; MATLAB v7.3 time vector (0, 1, ...); ROS 2 bag: 1 when every
        message of the block has one byte layout (checked when indexed: a window decodes them without comparing);
        0 otherwise.
    offset, end : CSV: the byte range [offset, end) of the block's lines; ROS 2 bag: the first and last receive
        time (ns) of the block's messages (no other block has a message received at those times).
    line : CSV only, the number (1-based) of the block's first line.
    """

    row0: int
    rows: int
    t_min: float
    t_max: float
    increasing: bool
    group: int = 0
    offset: int = 0
    end: int = 0
    line: int = 0


@dataclass(frozen=True)
class FileIndex:
    """Where a file's rows lie in time: small, picklable, enough to read any time window without scanning the file.

    Built once (`index_file`) and shipped to the workers with each task.

    path : the file, as given.
    format : "csv", "parquet", "mdf" or "mat".
    size, mtime_ns : the file's size and modification time when indexed (a changed file is refused).
    options : the reader options given (fs, time, and the CSV options), as (name, value) pairs.
    channels : (name, unit) of every channel a window may ask for, in file order.
    blocks : the blocks in file order (MDF: group by group, each in record order).
    metadata, skipped : what the whole-file reader puts in `Recording.metadata` / `.skipped`.
    time_column : table formats: the time column's name, or None when t = row / fs.
    extra : what the format's reader needs, as (name, value) pairs: the CSV header (names,
        units, delimiter, decimal, encoding), the first tick of each Parquet timestamp
        column, each MDF channel's (name, group, index) place.
    """

    path: str
    format: str
    size: int
    mtime_ns: int
    options: tuple[tuple[str, Any], ...]
    channels: tuple[tuple[str, str], ...]
    blocks: tuple[Block, ...]
    metadata: tuple[tuple[str, str], ...] = ()
    skipped: tuple[tuple[str, str], ...] = ()
    time_column: str | None = None
    extra: tuple[tuple[str, Any], ...] = ()

    @property
    def units(self) -> dict[str, str]:
        """Channel name -> unit as written in the file."""
        return dict(self.channels)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.channels)

    @property
    def rows(self) -> int:
        """Rows of the file (MDF: records of every group)."""
        return sum(b.rows for b in self.blocks)

    @property
    def span(self) -> tuple[float, float]:
        """(first, last) time stamp of the file, s: the min and max over the blocks (+inf, -inf if none)."""
        return min((b.t_min for b in self.blocks), default=np.inf), max((b.t_max for b in self.blocks), default=-np.inf)

    @property
    def monotonic(self) -> bool:
        """The stamps never go back: within each block, and from a block to the next (MDF: within each group)."""
        last: dict[int, float] = {}
        for b in self.blocks:
            if b.rows == 0:
                continue
            key = b.group if self.format == "mdf" else 0
            if not b.increasing or b.t_min < last.get(key, -np.inf):
                return False
            last[key] = b.t_max
        return True

    def __hash__(self) -> int:  # `extra` holds dicts; what identifies an index is the file and its blocks
        return hash((self.path, self.format, self.size, self.mtime_ns, self.options, self.channels, self.blocks))

    def option(self, name: str, default: Any = None) -> Any:
        return dict(self.options).get(name, default)

    def info(self, name: str, default: Any = None) -> Any:
        return dict(self.extra).get(name, default)


# --------------------------------------------------------------------------------------------------------------------
# public entry points


def index_file(
    path: str | os.PathLike[str],
    *,
    channels: Sequence[str] | None = None,
    fs: float | None = None,
    time: str | None = None,
    format: str | None = None,
    block_rows: int = 65536,
    **csv_options: Any,
) -> FileIndex:
    """One streaming pass over the file (memory bounded by a block, whatever the file's length) to build its index.

    Parameters
    ----------
    path : the file: a local path, or a URL when fsspec is installed (not for MATLAB files).
    channels : the channels windows will ask for (an error now if one is missing); None: all.
        For MDF files only the groups holding them are indexed.
    fs : Hz, sample rate of a table without time column (CSV, Parquet, MAT).
    time : the time column's name if it is not time/t/Time/TIME.
    format : "csv", "parquet", "mdf" or "mat"; None: from the extension.
    block_rows : rows per block: CSV lines after the header (blank lines count), MDF records
        of a group; Parquet blocks are the file's row groups, a MAT file is one block.
    csv_options : delimiter, decimal, units_row, units_in_header, encoding, as `read_csv`.

    The index holds the reader options: read the windows with the same index.
    """
    label = os.fspath(path)
    fmt = format_of(path, format)
    options = {"fs": fs, "time": time, **csv_options}
    _check_options(READERS[fmt], fmt, options, "reading")
    options = {k: v for k, v in options.items() if v is not None}
    if int(block_rows) < 1:
        raise DataError(f"{label}: block_rows must be a positive number of rows, not {block_rows!r}", source=label)
    p = Path(path)
    stat = _stat(label)
    builder = {"csv": _index_csv, "parquet": _index_parquet, "mdf": _index_mdf, "mat": _index_mat,
               "rosbag": _index_rosbag}[fmt]
    index = builder(p, label, options, int(block_rows), stat)
    if channels is not None:
        asked = list(channels)
        units = index.units
        if any(n not in units for n in asked):
            raise missing_error(asked, units, source=label, skipped=dict(index.skipped))
        index = _restricted(index, asked)
    if _stat(label) != stat:
        raise FileFormatError(
            f"{label}: the file changed while it was indexed (is it still being written?); index it again when "
            "it is complete",
            source=label,
        )
    return index


def read_window(index: FileIndex, channels: Sequence[str], t0: float, t1: float) -> Recording:
    """The samples of `channels` whose time stamp t satisfies t0 <= t <= t1, read from the blocks that overlap.

    Bit for bit what `read_recording(index.path, channels=channels, **options)` gives
    restricted to the window (values, time, units, and `lines` for CSV). Every channel
    asked for is in the result, with 0 samples when it has none in the window. An empty
    window (t1 < t0) gives 0 samples everywhere. MATLAB v5 files are read whole (and
    cached), v7.3 files in slices. A window of a file whose stamps go back reads every
    block whose [min, max] meets it, and keeps the rows inside, in file order.
    """
    names = _asked(index, channels)
    lo, hi = _window(index, t0, t1)
    _check_unchanged(index)
    pieces: dict[str, list[Channel]] = {n: [] for n in names}
    hit = [i for i, b in enumerate(index.blocks) if b.rows and b.t_min <= hi and b.t_max >= lo] if lo <= hi else []
    grouped = _grouped(index)
    if grouped:  # the groups of the channels asked for
        groups = {_group_of(index, n) for n in names}
        hit = [i for i in hit if index.blocks[i].group in groups]
    tables = (_block_recording(index, i, names, (lo, hi)) for i in hit)
    for rec in _runs(index, hit, names) if grouped else tables:
        kept: dict[int, tuple] = {}  # a block's channels share their time stamps: each array cut once
        for n in names:
            ch = rec.channels.get(n)
            if ch is not None and len(ch):
                pieces[n].append(_inside(ch, lo, hi, kept))
    return _assembled(index, names, pieces)


def iter_blocks(index: FileIndex, channels: Sequence[str], keep: bool = False) -> Iterator[Recording]:
    """The file as consecutive disjoint blocks of rows, one `Recording` each, one block in memory at a time.

    Per channel, the concatenation of the blocks' samples is bit for bit
    `read_recording(index.path, channels=channels, ...)`. Blocks are those of the index
    (module docstring): CSV runs of `block_rows` lines, Parquet row groups, MDF runs of
    `block_rows` records of one group (yielded merged in time order by first stamp, each
    group's in record order; a block's other groups' channels have 0 samples), MAT the
    whole file. Every channel asked for is in every block, with 0 samples if it has none there.
    `keep`: the decoded blocks stay in the cache (`CACHE_BLOCKS` of them per file), for windows read next.
    """
    names = _asked(index, channels)
    _check_unchanged(index)
    if _grouped(index):
        yield from _iter_grouped(index, names)
        return
    for i, b in enumerate(index.blocks):
        if b.rows == 0 and index.format != "mat":
            continue
        _check_unchanged(index)  # a file rewritten while a long pass reads it: not a mix of two files
        rec = _block_recording(index, i, names, store=keep)
        yield _assembled(index, names, {n: [rec.channels[n]] if n in rec.channels else [] for n in names})


TimeBase = tuple[list[str], NDArray[np.float64], "NDArray[np.int64] | None"]


def time_bases(index: FileIndex, channels: Sequence[str]) -> list[TimeBase]:
    """The channels' time bases over the whole file: [(channel names, time stamps, file lines or None)], each
    base's stamps as `read_recording` gives them to its channels, from a pass that keeps only stamps (8 bytes per
    sample per base, whatever the number of channels).

    A Parquet file whose columns have no null (its row groups' statistics say so) is one base on its time column,
    and only that column is decoded. Otherwise the blocks are read one at a time, and a base is the channels
    whose stamps are its own in every block (a channel with no sample at all is in none)."""
    names = _asked(index, channels)
    if index.format == "parquet" and _parquet_dense(index, names):
        return [(names, _parquet_stamps(index), None)]
    if index.format == "rosbag":  # every channel on the messages' stamps, kept by the index's pass in this process
        with _lock:
            hit = _cache.get(_key(index, "stamps"))
        if hit is not None:
            return [(names, hit[0], None)]
    # partition refinement: the channels start as one base, split in each block by their stamps there (a channel
    # without samples in a block has the empty stamps), so a base is the channels sharing their stamps everywhere
    bases: list[tuple[list[str], list, list]] = [(list(names), [], [])]
    # a file of a few blocks is decoded once for its bases and its windows (a demo's CSV: 15 % of the run parsing)
    few = sum(1 for b in index.blocks if b.rows) <= CACHE_BLOCKS
    for block in iter_blocks(index, names, keep=few):
        refined = []
        for members, times, lines in bases:
            classes: list[tuple[Channel, list[str]]] = []
            for n in members:
                ch = block.channels[n]
                home = next((c for c in classes if np.array_equal(c[0].time, ch.time)), None)
                if home is None:
                    classes.append((ch, [n]))
                else:
                    home[1].append(n)
            for ch, ms in classes:  # a base that splits leaves each part a copy of its stamps so far
                t, ln = (times, lines) if len(classes) == 1 else (list(times), list(lines))
                if ch.time.size:
                    t.append(ch.time)
                    ln.append(ch.lines)
                refined.append((ms, t, ln))
        bases = refined
    return [(m, np.concatenate(t), None if any(x is None for x in ln) else np.concatenate(ln))
            for m, t, ln in bases if t]


# a Parquet file of more row groups than this, of fewer rows than TINY_ROW_GROUP each on average, is refused: each
# group is read on its own (a 1500-row file of 1-row groups took 5 minutes), and a logger writes thousands of rows
# per group (a row group per second of a 1 kHz log is fine)
MANY_ROW_GROUPS = 256
TINY_ROW_GROUP = 100


def _parquet_dense(index: FileIndex, names: list[str]) -> bool:
    """Every row of every column asked for holds a sample (statistics of every row group say no null)."""
    pfile, _, _ = _open_parquet(index.path)
    meta = pfile.metadata
    # the statistics are per leaf column: a struct column (a GPS position's x and y) has several, a top-level
    # column is the leaf whose path is its name
    leaves = (meta.schema.column(i) for i in range(meta.num_columns))
    where = {c.path: i for i, c in enumerate(leaves) if c.path == c.name}
    columns = index.info("columns", {})
    for g in range(meta.num_row_groups):
        rg = meta.row_group(g)
        for n in names:
            st = rg.column(where[columns.get(n, n)]).statistics
            if st is None or not st.has_null_count or st.null_count:
                return False
    return True


def _parquet_stamps(index: FileIndex) -> NDArray[np.float64]:
    """The file's time column (or row / fs), decoded block by block as the whole-file reader decodes it."""
    _check_unchanged(index)
    opened: dict[int | None, tuple] = {}
    out = np.empty(sum(b.rows for b in index.blocks))  # filled block by block: no list of parts to concatenate
    at = 0
    for b in index.blocks:
        if index.time_column is None:
            part = uniform_time(b.rows, index.option("fs"), index.path, b.row0)
        elif b.rows:
            col = _parquet_column(index, b, index.time_column, opened, store=False)
            part = table_time([col], index.time_column, None, index.path, None, b.row0)
        else:
            continue
        out[at:at + part.size] = part
        at += part.size
    return out[:at]


def stamp_rows(index: FileIndex, lo: int, hi: int, store: bool = True) -> NDArray[np.float64]:
    """Stamps lo..hi of a Parquet file's time column (or row / fs), the rows of `_parquet_stamps` (what `time_bases`
    gives a dense file), decoded block by block as it decodes them, so the same bits: a planner's clock read back
    a window at a time instead of held whole. store: keep the decoded blocks (a window's read next needs them)."""
    out = np.empty(max(0, hi - lo))
    at = 0
    for _, part in stamp_blocks(index, lo, hi, store):
        out[at:at + part.size] = part
        at += part.size
    return out[:at]


def stamp_blocks(index: FileIndex, lo: int = 0, hi: int | None = None, store: bool = False,
                 only: Callable[[int, int], bool] | None = None) -> Iterator[tuple[int, NDArray[np.float64]]]:
    """(first row, stamps) of each block's part of the rows lo..hi (None: to the end) of a Parquet file's stamps,
    the same bits as `stamp_rows`, the file opened once (its footer parsed once: ~20 ms for 6 h of a car's
    channels): a pass over a long log's stamps a block at a time. only(first row, rows): the blocks decoded (all)."""
    if index.format != "parquet":
        raise ValueError(f"stamp_rows reads a Parquet file's stamps, not a {index.format} file's")
    _check_unchanged(index)
    hi = index.rows if hi is None else hi
    opened: dict[int | None, tuple] = {}
    row = 0  # the block's first row among the stamps
    for b in index.blocks:
        if row >= hi:
            break
        if not b.rows or row + b.rows <= lo or (only is not None and not only(row, b.rows)):
            row += b.rows
            continue
        if index.time_column is None:
            part = uniform_time(b.rows, index.option("fs"), index.path, b.row0)
        else:
            col = _parquet_column(index, b, index.time_column, opened, store=store)
            part = table_time([col], index.time_column, None, index.path, None, b.row0)
        first = max(lo - row, 0)
        yield row + first, part[first:hi - row]
        row += part.size


def one_time_base(index: FileIndex, channels: Sequence[str]) -> bool:
    """The channels are one time base, the file's stamps (`time_bases` gives them so without reading a block): a
    Parquet file whose columns asked for have no null."""
    return index.format == "parquet" and _parquet_dense(index, _asked(index, channels))


def clear_cache() -> None:
    """Forget the decoded blocks and the Parquet footers kept by this process."""
    with _lock:
        _footers.clear()
        _cache.clear()
        _recent.clear()
        _used[0] = 0


# --------------------------------------------------------------------------------------------------------------------
# where the file is: a local path, or a URL opened through fsspec (if installed)


def _where(path: str) -> tuple[Any, str] | None:
    """(fsspec filesystem, path in it) for a URL with a scheme (s3://, file://, memory://...); None for a local path."""
    if "://" not in path:
        return None
    try:
        import fsspec  # optional: fsspec
    except ImportError:
        raise FileFormatError(
            f"{path}: reading a URL needs the package fsspec (pip install fsspec, and the one for its scheme, "
            "e.g. s3fs); or give a local path",
            source=path,
        ) from None
    return fsspec.core.url_to_fs(path)


def _stat(path: str) -> tuple[int, int]:
    """(size in bytes, modification time in ns) of the file; FileNotFoundError if there is none.

    Through fsspec, the time is the one the store reports (mtime, LastModified, created...;
    0 when it reports none: then only a change of size is seen).
    """
    where = _where(path)
    if where is None and rosbag_format.is_bag_folder(path):
        return rosbag_format.bag_stat(path)
    if where is None:
        st = _local_stat(path)
        return st.st_size, st.st_mtime_ns
    fs, inner = where
    try:
        info = fs.info(inner)
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such file") from None
    stamp = next(
        (info[k] for k in ("mtime", "LastModified", "last_modified", "updated", "created") if info.get(k) is not None),
        0,
    )
    if isinstance(stamp, datetime):
        ns = round(stamp.timestamp() * 1e9)
    else:
        try:
            ns = round(float(stamp) * 1e9)
        except (TypeError, ValueError):
            ns = zlib.crc32(str(stamp).encode())  # an opaque version tag: compared for equality only
    return int(info.get("size") or 0), ns


def _local_stat(path: str) -> os.stat_result:
    try:
        return regular_file(path)  # a named pipe would block the index for ever, /dev/zero never end
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such file") from None
    except NotAFileError as exc:
        raise FileFormatError(str(exc), source=path) from None


def _open_binary(path: str) -> BinaryIO:
    where = _where(path)
    if where is None:
        return open(path, "rb")  # the caller closes it
    fs, inner = where
    if "file" in ((fs.protocol,) if isinstance(fs.protocol, str) else tuple(fs.protocol)):
        return open(inner, "rb")  # a plain file object for a local file (asammdf accepts no fsspec local opener)
    return fs.open(inner, "rb")


# Parquet footers (FileMetaData) kept per process, least recently used dropped first: a file's windows each open
# it, and parsing its footer, which lists every row group's column chunks, cost 0.3 ms for 10 min of 56 columns and
# 7 ms for 6 h, each time. In memory a footer is ~8 times its size in the file: ~11 MB for 6 h of 56 columns; so a
# local file's footer over FOOTER_WHOLE bytes in the file (~1 h of 60 channels at 625 Hz in 65536-row groups) is kept
# cut per row group instead (`parquet_format.SplitFooter`: its bytes around the row-group list and each group's place,
# a few kB whatever the length), and a window opens its row group through a footer of that group alone (0.3 ms more
# than through a kept footer, a 60 s segment's two groups 0.7 ms of its ~150 ms). An hour of such a log's `identify`:
# 156 opens, 0.2 s of CPU in all (the cut once 0.08 s: it walks the footer in Python, ~60 ms an hour of data), its
# CPU within the noise of the footer kept whole (12.2 against 12.9 s, load 5); kept: 10.5 kB (4 h: 13 kB), not 1.9 MB.
FOOTER_FILES = 4
FOOTER_WHOLE = 256 * 2**10
# file key -> (FileMetaData or SplitFooter, Arrow schema)
_footers: OrderedDict[tuple, tuple[Any, Any]] = OrderedDict()


def _footer_key(path: str, where: tuple[Any, str] | None) -> tuple:
    """What identifies a file's content: its resolved path (a local file: also its device and inode, a file
    replaced by a rename is another), size and modification time, so a file rewritten is read anew."""
    if where is None:
        st = _local_stat(path)
        return os.path.realpath(path), st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns
    return (path, *_stat(path))


def _open_parquet(path: str, group: int | None = None) -> tuple[Any, Any, int | None]:
    """(a `ParquetFile`, its Arrow schema, None: the file's every row group is in it at its own index; or 0: it holds
    `group` alone, as its row group 0); the footer parsed (and the schema built) once per process while the file is
    unchanged (`FOOTER_FILES`), both immutable and so shared by the threads. group: the row group to read (None: the
    whole footer asked for); a footer kept cut per row group (`FOOTER_WHOLE`) gives a file of that group alone, or,
    for None, the whole footer parsed anew and not kept."""
    where = _where(path)
    key = _footer_key(path, where)
    with _lock:
        kept = _footers.get(key)
        if kept is not None:
            _footers.move_to_end(key)
    if kept is not None and isinstance(kept[0], parquet_format.SplitFooter):
        if group is not None:
            meta = kept[0].group_metadata(path, group)
            return parquet_format.open_parquet(path, path, metadata=meta), kept[1], 0
        return parquet_format.open_parquet(path, path), kept[1], None
    meta = None if kept is None else kept[0]
    if where is None:
        pfile = parquet_format.open_parquet(path, path, metadata=meta)
    else:
        fs, inner = where
        pfile = parquet_format.open_parquet(inner, path, filesystem=fs, metadata=meta)
    if kept is None:
        full = pfile.metadata
        split = (parquet_format.split_footer(path, full) if where is None and full.serialized_size > FOOTER_WHOLE
                 else None)
        kept = (full if split is None else split, pfile.schema_arrow)
        if _footer_key(path, where) != key:  # rewritten while its footer was read: not kept under the old key
            return pfile, kept[1], None
        with _lock:
            _footers[key] = kept
            _footers.move_to_end(key)
            while len(_footers) > FOOTER_FILES:
                _footers.popitem(last=False)
    return pfile, kept[1], None


# --------------------------------------------------------------------------------------------------------------------
# shared helpers


def _asked(index: FileIndex, channels: Sequence[str]) -> list[str]:
    if isinstance(channels, str):
        channels = [channels]
    names = list(dict.fromkeys(channels))
    units = index.units
    if any(n not in units for n in names):
        raise missing_error(names, units, source=index.path, skipped=dict(index.skipped))
    return names


def _window(index: FileIndex, t0: float, t1: float) -> tuple[float, float]:
    try:
        lo, hi = float(t0), float(t1)
    except (TypeError, ValueError):
        raise DataError(f"{index.path}: a window is two times in s, not {t0!r}, {t1!r}", source=index.path) from None
    if np.isnan(lo) or np.isnan(hi):
        raise DataError(f"{index.path}: window [{t0}, {t1}] s: a bound is NaN", source=index.path)
    return lo, hi


def _check_unchanged(index: FileIndex) -> None:
    try:
        size, mtime_ns = _stat(index.path)
    except FileNotFoundError:
        raise FileNotFoundError(f"{index.path}: no such file (it was indexed, then moved or deleted)") from None
    if (size, mtime_ns) != (index.size, index.mtime_ns):
        raise FileFormatError(
            f"{index.path}: the file changed since it was indexed (size {index.size} -> {size} bytes, or its "
            "modification time); index it again (index_file) before reading windows",
            source=index.path,
        )


def _inside(ch: Channel, lo: float, hi: float, kept: dict[int, tuple] | None = None) -> Channel:
    """The channel's samples with lo <= t <= hi. kept: id(time) -> (time, its mask, its time and lines kept), so
    that channels sharing a time base share the kept time (and lines), computed once."""
    memo = None if kept is None else kept.get(id(ch.time))
    if memo is None or memo[0] is not ch.time or memo[4] is not ch.lines:
        keep = (ch.time >= lo) & (ch.time <= hi)
        every = bool(keep.all())
        memo = (ch.time, keep, None if every else ch.time[keep],
                None if every or ch.lines is None else ch.lines[keep], ch.lines, every)
        if kept is not None:
            kept[id(ch.time)] = memo
    if memo[5]:
        return ch
    return Channel(ch.name, ch.unit, ch.values[memo[1]], memo[2], memo[3])


def _assembled(index: FileIndex, names: list[str], pieces: dict[str, list[Channel]]) -> Recording:
    """One recording of the pieces of each channel, in order; 0-sample channels for those without any. Channels
    whose pieces share their time stamps (and lines) share the assembled ones: one concatenation each."""
    units = index.units
    text = index.format == "csv"
    out = {}
    joined: dict[tuple[int, ...], tuple] = {}  # ids of the pieces' arrays -> (the pieces, their concatenation)
    for n in names:
        got = pieces[n]
        if len(got) == 1:
            out[n] = got[0]
        elif not got:
            out[n] = Channel(n, units[n], _EMPTY_F, _EMPTY_F, _EMPTY_I if text else None)
        else:
            lines = _joined([c.lines for c in got], joined) if text else None
            values = np.concatenate([c.values for c in got])
            out[n] = Channel(n, got[0].unit, values, _joined([c.time for c in got], joined), lines)
    return Recording(Path(index.path), out, dict(index.metadata), dict(index.skipped))


def _joined(arrays: list[NDArray], memo: dict[tuple[int, ...], tuple]) -> NDArray:
    """np.concatenate(arrays), the same array for the same arrays (memo: their ids -> (them, the result); the
    arrays kept in it so that an id is not reused while it lives)."""
    key = tuple(id(a) for a in arrays)
    hit = memo.get(key)
    if hit is None:
        hit = memo[key] = (arrays, np.concatenate(arrays))
    return hit[1]


def _stamp_summary(t: NDArray[np.float64]) -> tuple[float, float, bool]:
    """(min, max, never goes back) of a block's stamps, NaN left out of min and max (+inf, -inf if none)."""
    finite = t[~np.isnan(t)]
    if finite.size == 0:
        return float("inf"), float("-inf"), t.size == 0
    increasing = finite.size == t.size and bool(np.all(t[1:] >= t[:-1]))
    return float(finite.min()), float(finite.max()), increasing


def _restricted(index: FileIndex, names: list[str]) -> FileIndex:
    keep = set(names)
    chans = tuple((n, u) for n, u in index.channels if n in keep)
    if index.format != "mdf":
        return replace(index, channels=chans)
    places = {k: v for k, v in index.info("places").items() if k in keep}
    groups = {g for _, g, _ in places.values()}
    extra = tuple((k, places if k == "places" else v) for k, v in index.extra)
    blocks = tuple(b for b in index.blocks if b.group in groups)
    return replace(index, channels=chans, blocks=blocks, extra=extra)


# a bounded LRU cache of decoded blocks, shared by the threads of a process ------------------------------------------

_cache: OrderedDict[tuple, tuple[Any, int]] = OrderedDict()
_recent: dict[tuple, OrderedDict[Any, list[tuple]]] = {}  # per file: its cached blocks, most recent last -> keys
_used = [0]
_lock = threading.Lock()
CACHE_BLOCKS = 3  # blocks kept per file: a window's last ones, which the next (overlapping) window reads again


def _cached(key: tuple, make: Callable[[], Any], size: Callable[[Any], int], store: bool = True) -> Any:
    """The value of `key` from the cache, or made (and kept if `store` and it fits).

    Keys are `_key(index, block, ...)`. Windows read in time order need again only the
    blocks at the end of the last window, so a file keeps at most `CACHE_BLOCKS` blocks
    (its least recently used go first), and all files at most `CACHE_BYTES`.
    """
    file, block = key[:4], key[4]
    with _lock:
        hit = _cache.get(key)
        if hit is not None:
            _cache.move_to_end(key)
            blocks = _recent.get(file)
            if blocks is not None and block in blocks:
                blocks.move_to_end(block)
            return hit[0]
    value = make()
    if not store:
        return value
    nbytes = size(value)
    with _lock:
        if nbytes <= CACHE_BYTES and key not in _cache:
            _cache[key] = (value, nbytes)
            _used[0] += nbytes
            blocks = _recent.setdefault(file, OrderedDict())
            blocks.setdefault(block, []).append(key)
            blocks.move_to_end(block)
            while len(blocks) > CACHE_BLOCKS:
                for old in blocks.popitem(last=False)[1]:
                    _drop(old)
            while _used[0] > CACHE_BYTES and _cache:
                _drop(next(iter(_cache)))
    return value


def forget_blocks_before(index: FileIndex, t: float) -> None:
    """The file's kept blocks whose stamps all come before t (s) dropped from the cache: a reader whose windows come
    in time order, alone on the file, never reads them again (a robot's chunks: after a window's read, the cache
    holds the block the next window begins in, 8 MB of a Parquet log's row group, not the window's two or three)."""
    named = {b.group if index.format == "parquet" else i: b for i, b in enumerate(index.blocks)}
    with _lock:
        blocks = _recent.get(_key(index))
        for block in [k for k in blocks or () if k in named and named[k].t_max < t]:
            for key in blocks.pop(block):
                _drop(key)


def _drop(key: tuple) -> None:
    gone = _cache.pop(key, None)
    if gone is not None:
        _used[0] -= gone[1]


def _key(index: FileIndex, *rest: Any) -> tuple:
    return (index.path, index.size, index.mtime_ns, index.options, *rest)


def _columns_nbytes(cols: Any) -> int:
    columns, lines = cols if isinstance(cols, tuple) else (cols, None)
    total = 0 if lines is None else lines.nbytes
    for c in columns if isinstance(columns, list) else [columns]:
        total += c.values.nbytes + (0 if c.present is None else c.present.nbytes)
    return total


# tables (CSV, Parquet) -----------------------------------------------------------------------------------------------


def _block_recording(
    index: FileIndex, i: int, names: list[str], window: tuple[float, float] | None = None, store: bool = True
) -> Recording:
    """Block i as a recording of `names` (CSV and Parquet: through `recording_from_columns`, as the whole file).

    With a `window` (t0, t1), only its rows (a block is often much longer than a window:
    a Parquet row group of a million rows), so that a window costs its rows, not the block's.
    `store`: keep the decoded block in the cache (not when iterating over the blocks, each read once).
    """
    if index.format == "mat":
        rec = _cached(_key(index, "mat"), lambda: _read_mat(index), _recording_nbytes, store)
        return Recording(rec.source, {n: rec.channels[n] for n in names if n in rec.channels}, rec.metadata)
    block = index.blocks[i]
    time_name = index.time_column
    wanted = ([time_name] if time_name is not None else []) + [n for n in names if n != time_name]
    if index.format == "rosbag":  # every channel of the index decoded at once: q's and tau's windows share it
        lines = None
        columns = _cached(_key(index, i), lambda: _bag_block(index, block), _columns_nbytes, store)
        by_name = {c.name: c for c in columns}
        cols = [by_name[n] for n in wanted]
    elif index.format == "csv":
        columns, lines = _cached(_key(index, i), lambda: _csv_block(index, block), _columns_nbytes, store)
        by_name = {c.name: c for c in columns}
        cols = [by_name[n] for n in wanted]
        if time_name is None and not cols:
            cols = columns[:1]  # the row count of a table without time column
    else:
        lines = None
        opened: dict[int | None, tuple] = {}  # each row group's file, opened on its first column not in the cache
        cols = [_parquet_column(index, block, n, opened, store) for n in wanted]
    label = Path(index.path)
    row0 = block.row0
    if window is not None:
        t = table_time(cols, time_name, index.option("fs"), index.path, lines, row0)
        lo, hi = window
        if block.increasing:  # the stamps are sorted: the window is a run of rows
            a, b = int(np.searchsorted(t, lo, "left")), int(np.searchsorted(t, hi, "right"))
            if (a, b) != (0, t.size):
                cols, lines, row0 = [_rows_of(c, slice(a, b)) for c in cols], _rows(lines, slice(a, b)), row0 + a
        elif time_name is not None:  # (without time column, t = row / fs always increases)
            keep = (t >= lo) & (t <= hi)
            cols, lines = [_rows_of(c, keep) for c in cols], _rows(lines, keep)
    return recording_from_columns(
        label, cols, time=index.option("time"), fs=index.option("fs"), lines=lines, row0=row0
    )


def _rows(lines: NDArray[np.int64] | None, sel: slice | NDArray[np.bool_]) -> NDArray[np.int64] | None:
    return None if lines is None else lines[sel]


def _rows_of(col: Column, sel: slice | NDArray[np.bool_]) -> Column:
    """The rows `sel` (a run of rows, or a mask over them) of a column whose samples are compacted."""
    if col.present is None:
        return Column(col.name, col.unit, col.values[sel], None)
    present = col.present[sel]
    if isinstance(sel, slice):  # the samples of rows [a, b): those after the samples of rows [0, a)
        first = int(np.count_nonzero(col.present[: sel.start]))
        values = col.values[first : first + int(np.count_nonzero(present))]
    else:
        values = col.values[sel[col.present]]
    return Column(col.name, col.unit, values, present)


# CSV -----------------------------------------------------------------------------------------------------------------


def _csv_encodings(encoding: str, label: str) -> tuple[str, str]:
    """(encoding of the first line, of the others): a UTF-8 byte-order mark only at the start of the file."""
    utf8 = encoding.lower().replace("_", "-") in ("utf-8", "utf-8-sig", "utf8")
    rest = "utf-8" if utf8 else encoding
    try:
        one_byte = "\n".encode(rest) == b"\n" and "\r".encode(rest) == b"\r"
    except LookupError:
        raise FileFormatError(f"{label}: unknown text encoding {encoding!r}", source=label) from None
    if not one_byte:
        raise FileFormatError(
            f"{label}: encoding {encoding} does not write a line end as one byte; windows of this file cannot be "
            "read: convert it to UTF-8, or read it whole (read_recording)",
            source=label,
        )
    return encoding, rest


def _decode_error(label: str, p: Path, encoding: str, exc: UnicodeDecodeError) -> FileFormatError:
    utf8 = encoding.lower().replace("_", "-") in ("utf-8", "utf-8-sig", "utf8")
    why = encoding_problem(p) if utf8 and _where(label) is None else f"not {encoding} text ({exc.reason})"
    return FileFormatError(f"{label}: {why}", source=label)


def _lines_of(raw: bytes, first_line: int, encoding: str, label: str, text: str | None = None
              ) -> list[tuple[int, str]]:
    """Numbered lines of a byte range, as `read_csv`'s text reading (newline="") gives them (text: the range
    already decoded)."""
    if raw.count(b"\r") != raw.count(b"\r\n"):
        raise FileFormatError(
            f"{label}: a line ends with a lone carriage return (old Mac line ends); windows of this file cannot be "
            "read: convert its line ends to \\n, or read it whole (read_recording)",
            source=label,
        )
    parts = (raw.decode(encoding) if text is None else text).split("\n")
    if parts and parts[-1] == "":
        parts.pop()
    return [(first_line + k, line.rstrip("\r\n")) for k, line in enumerate(parts)]


def _csv_head(index: FileIndex) -> csv_format.CsvHeader:
    h = index.info("header")
    return csv_format.CsvHeader(list(h["names"]), list(h["units"]), h["delimiter"], {}, 0, [])


def _csv_columns(
    numbered: list[tuple[int, str]], head: csv_format.CsvHeader, decimal: str, label: str
) -> tuple[list[Column], NDArray[np.int64]]:
    data, present, lines = csv_format.parse_rows(
        iter(numbered), len(head.names), head.names, head.delimiter, decimal, label
    )
    return csv_format.columns_of(data, present, head), lines


def _csv_block(index: FileIndex, block: Block) -> tuple[list[Column], NDArray[np.int64]]:
    label = index.path
    encoding = index.option("encoding", "utf-8-sig")
    _, rest = _csv_encodings(encoding, label)
    with _open_binary(index.path) as fh:
        fh.seek(block.offset)
        raw = fh.read(block.end - block.offset)
    try:
        text = raw.decode(rest if block.offset else encoding)
    except UnicodeDecodeError as exc:
        raise _decode_error(label, Path(index.path), encoding, exc) from None
    head, decimal = _csv_head(index), index.option("decimal", ".")
    values = csv_format.parse_plain(text, len(head.names), head.delimiter, decimal)
    if values is not None:  # every line a plain row (a logger's usual block): one parse
        return csv_format.columns_of(values, None, head), block.line + np.arange(len(values), dtype=np.int64)
    return _csv_columns(_lines_of(raw, block.line, "", label, text), head, decimal, label)


def _csv_stamps(
    numbered: list[tuple[int, str]],
    head: csv_format.CsvHeader,
    time_name: str | None,
    decimal: str,
    fs: float | None,
    label: str,
    row0: int,
) -> NDArray[np.float64]:
    """The time stamps of a block's data rows, parsing only the time column's cells when the rows are plain.

    Python's float() and NumPy's loadtxt both round correctly, so the stamps are the
    ones `parse_rows` gives; any irregular row (quotes, an empty or bad time cell, too few
    cells) sends the block through the full parse, which raises `read_csv`'s error for it.
    The other columns' cells are checked when a window reads them.
    """
    rows = [text for _, text in numbered if text.strip()]
    if time_name is None:
        return uniform_time(len(rows), fs, label, row0)  # type: ignore[arg-type]
    k = head.names.index(time_name)
    delim = head.delimiter
    try:
        if any('"' in r for r in rows):
            raise ValueError
        cells = [r.split(delim, k + 1)[k] for r in rows]
        if decimal == ",":
            cells = [c.replace(",", ".") for c in cells]
        values = np.fromiter(map(float, cells), dtype=np.float64, count=len(cells))
    except (ValueError, IndexError):
        columns, lines = _csv_columns(numbered, head, decimal, label)
        return table_time(columns, time_name, fs, label, lines, row0)
    return table_time([Column(time_name, head.units[k], values)], time_name, fs, label, None, row0)


def _index_csv(p: Path, label: str, options: dict[str, Any], block_rows: int, stat: tuple[int, int]) -> FileIndex:
    encoding = options.get("encoding", "utf-8-sig")
    decimal = options.get("decimal", ".")
    if decimal not in (".", ","):
        raise FileFormatError(f"{label}: decimal must be '.' or ',', not {decimal!r}", source=label)
    first_enc, rest_enc = _csv_encodings(encoding, label)
    offsets: dict[int, int] = {}
    blocks: list[Block] = []
    try:
        with _open_binary(label) as fh:
            def header_lines() -> Iterator[tuple[int, str]]:
                number = 0
                while True:
                    pos = fh.tell()
                    raw = fh.readline(csv_format.MAX_LINE + 1)
                    if not raw:
                        return
                    number += 1
                    if len(raw) > csv_format.MAX_LINE:
                        raise FileFormatError(f"{label}, line {number}: longer than {csv_format.MAX_LINE:,} "
                                              "characters (no line end found): not a CSV of samples; check the file",
                                              source=label, line=number)
                    offsets[number] = pos
                    yield number, _lines_of(raw, number, first_enc if pos == 0 else rest_enc, label)[0][1]

            head = csv_format.read_header(
                header_lines(), p, label, options.get("time"), options.get("delimiter"), decimal,
                options.get("units_row"), options.get("units_in_header", True),
            )
            offset = offsets.get(head.data_line, fh.tell())
            fh.seek(offset)
            line, row0 = head.data_line, 0
            time_name = find_time_column(head.names, options.get("time"), options.get("fs"), label)
            while True:
                raw_lines = [x for _, x in islice(csv_format.bounded_lines(fh, label, line), block_rows)]
                if not raw_lines:
                    break
                raw = b"".join(raw_lines)
                numbered = _lines_of(raw, line, first_enc if offset == 0 else rest_enc, label)
                t = _csv_stamps(numbered, head, time_name, decimal, options.get("fs"), label, row0)
                rows = t.size
                lo, hi, inc = _stamp_summary(t)
                blocks.append(Block(row0, rows, lo, hi, inc, offset=offset, end=offset + len(raw), line=line))
                offset += len(raw)
                line += len(raw_lines)
                row0 += rows
    except UnicodeDecodeError as exc:
        raise _decode_error(label, p, encoding, exc) from None
    # The channels as the whole-file reader makes them (units from the header / unit row).
    channels = tuple((n, u) for n, u in zip(head.names, head.units, strict=True) if n != time_name)
    header = {"names": tuple(head.names), "units": tuple(head.units), "delimiter": head.delimiter}
    metadata = dict(head.metadata)
    if time_name is None:
        metadata.setdefault("fs", repr(float(options["fs"])))
    return FileIndex(
        label, "csv", *stat, tuple(sorted(options.items())), channels, tuple(blocks),
        tuple(metadata.items()), (), time_name, (("header", header),),
    )


# Parquet -------------------------------------------------------------------------------------------------------------


def _index_parquet(p: Path, label: str, options: dict[str, Any], block_rows: int, stat: tuple[int, int]) -> FileIndex:
    pa = require("pyarrow", "Reading Parquet files")
    pfile, schema, _ = _open_parquet(label)
    metadata = parquet_format.schema_metadata(schema)
    fields = [f for f in schema if parquet_format.is_numeric(pa, f.type)]
    skipped = {f.name: f"column of type {f.type}, not numeric" for f in schema if f not in fields}
    if not fields:
        raise FileFormatError(f"{label}: no numeric column in the file", source=label)
    named = parquet_format.field_channels(fields, label)  # "yaw_rate [deg/s]" is the channel yaw_rate
    raw = {name: f.name for f, (name, _) in zip(fields, named, strict=True)}
    time_name = find_time_column(list(raw), options.get("time"), options.get("fs"), label)
    meta = pfile.metadata
    groups = range(meta.num_row_groups)
    if meta.num_row_groups > MANY_ROW_GROUPS and meta.num_rows < TINY_ROW_GROUP * meta.num_row_groups:
        raise FileFormatError(
            f"{label}: {meta.num_row_groups} row groups of {meta.num_rows / meta.num_row_groups:.3g} row(s) on "
            "average; each is read on its own, so reading it would take minutes: rewrite it with larger row groups "
            "(pyarrow.parquet.write_table(table, path, row_group_size=65536), or your logger's export setting)",
            source=label)
    first = next((g for g in groups if meta.row_group(g).num_rows), None)
    ticks: dict[str, int] = {}
    stamps = [f for f in fields if pa.types.is_timestamp(f.type)]
    if stamps and first is not None:
        table = parquet_format.read_columns(pfile, label, [f.name for f in stamps], first)
        for f in stamps:
            col = table.column(f.name)
            ticks[f.name] = parquet_format.first_tick(pa, col)
            start = col[0].as_py()
            if start is not None:
                metadata.setdefault(f"{f.name}.start", start.isoformat())
    blocks, row0 = [], 0
    tfield = next((f for f in fields if f.name == raw.get(time_name)), None)
    for g in groups:
        rows = meta.row_group(g).num_rows
        if tfield is not None:
            col = parquet_format.read_columns(pfile, label, [tfield.name], g).column(0)
            column = parquet_format.convert_column(pa, tfield, col, ticks.get(tfield.name), label)
            t = table_time([column], time_name, None, label, None, row0)
        else:
            t = uniform_time(rows, options.get("fs"), label, row0)
        lo, hi, inc = _stamp_summary(t)
        blocks.append(Block(row0, rows, lo, hi, inc, group=g))
        row0 += rows
    if time_name is None:
        metadata.setdefault("fs", repr(float(options["fs"])))
    channels = tuple((name, "s" if pa.types.is_timestamp(f.type) else unit)
                     for f, (name, unit) in zip(fields, named, strict=True) if name != time_name)
    return FileIndex(
        label, "parquet", *stat, tuple(sorted(options.items())), channels, tuple(blocks),
        tuple(metadata.items()), tuple(skipped.items()), time_name, (("first_ticks", ticks), ("columns", raw)),
    )


def _parquet_column(index: FileIndex, block: Block, name: str, opened: dict[int | None, tuple], store: bool
                    ) -> Column:
    """opened: the file opened for the caller's reads, by the first column not in the cache: under None when its
    every row group is in it, else under the group it alone holds (a footer kept cut per row group: only the last
    group's file kept, a pass over the blocks holds one file open, not one per group)."""
    def make() -> Column:
        pa = require("pyarrow", "Reading Parquet files")
        hit = opened.get(None) or opened.get(block.group)
        if hit is None:
            hit = _open_parquet(index.path, block.group)
            opened.clear()
            opened[None if hit[2] is None else block.group] = hit
        pfile, schema, own = hit
        group = block.group if own is None else own
        column = index.info("columns", {}).get(name, name)  # the file's name of the channel
        field = schema.field(column)
        col = parquet_format.read_columns(pfile, index.path, [column], group, block.group).column(0)
        # read-only views of the decoded buffers, not copies: what the cache keeps is shared by every window anyway
        return parquet_format.convert_column(pa, field, col, index.info("first_ticks", {}).get(column), index.path,
                                             copy=False)

    return _cached(_key(index, block.group, name), make, _columns_nbytes, store)


# MDF -----------------------------------------------------------------------------------------------------------------


def _open_mdf_stream(index_path: str) -> tuple[Any, Any]:
    """The MDF opened from a file object: asammdf then reads a record range by seeking to it.

    (Opened by path, asammdf 8.8's `select` reads every record of the group and slices.)
    """
    asammdf = require("asammdf", "Reading MDF files")
    fh = _open_binary(index_path)
    try:
        return fh, asammdf.MDF(fh)
    except Exception as exc:  # asammdf raises many kinds for a file that is not MDF
        fh.close()
        raise FileFormatError(
            f"{index_path}: not a readable MDF file ({type(exc).__name__}: {exc})", source=index_path
        ) from None


def _index_mdf(p: Path, label: str, options: dict[str, Any], block_rows: int, stat: tuple[int, int]) -> FileIndex:
    fh, mdf = _open_mdf_stream(label)
    try:
        with mdf:
            metadata = {"format": "mdf", "mdf_version": str(mdf.version)}
            mdf_format._header_metadata(mdf, metadata)
            wanted, skipped = mdf_format.channel_places(mdf, label)
            channels: list[tuple[str, str]] = []
            places: dict[str, tuple[str, int, int]] = {}
            blocks: list[Block] = []
            for group in sorted({g for _, _, g, _ in wanted}):
                members = [w for w in wanted if w[2] == group]
                cycles = int(mdf.groups[group].channel_group.cycles_nr)
                # The channels' kinds and units from one record (or none): what read_mdf would keep.
                probe = mdf_format.group_channels(mdf, members, skipped, 0, min(cycles, 1), source=label)
                for key, name, g, idx in members:
                    if key in probe:
                        channels.append((key, probe[key].unit))
                        places[key] = (name, g, idx)
                for row0 in range(0, cycles, block_rows):
                    count = min(block_rows, cycles - row0)
                    t = np.asarray(mdf.get_master(group, record_offset=row0, record_count=count), dtype=np.float64)
                    lo, hi, inc = _stamp_summary(t)
                    blocks.append(Block(row0, count, lo, hi, inc, group=group))
    finally:
        fh.close()
    if not channels:
        raise FileFormatError(f"{label}: no numeric channel in the file; not read: {skipped}", source=label)
    return FileIndex(
        label, "mdf", *stat, (), tuple(channels), tuple(blocks), tuple(metadata.items()),
        tuple(skipped.items()), None, (("places", places),),
    )


def _mdf_read(mdf: Any, index: FileIndex, group: int, names: list[str], row0: int, count: int) -> dict[str, Channel]:
    places = index.info("places")
    members = [(n, *places[n]) for n in names if places[n][1] == group]
    if not members:
        return {}
    return mdf_format.group_channels(mdf, members, {}, row0, count, source=index.path)


def _grouped(index: FileIndex) -> bool:
    """Files read as groups of rows on their own time bases: MDF channel groups, MATLAB v7.3 time vectors."""
    return index.format == "mdf" or (index.format == "mat" and index.info("h5") is not None)


def _group_of(index: FileIndex, name: str) -> int:
    return index.info("places")[name][1] if index.format == "mdf" else index.info("h5")[name][2]


@contextmanager
def _group_reader(index: FileIndex) -> Iterator[Callable[[int, list[str], int, int], dict[str, Channel]]]:
    """A function (group, names, row0, count) -> the channels of `names` in that group, rows [row0, row0 + count)."""
    if index.format == "mdf":
        fh, mdf = _open_mdf_stream(index.path)
        try:
            with mdf:
                yield lambda g, names, row0, count: _mdf_read(mdf, index, g, names, row0, count)
        finally:
            fh.close()
        return
    h5py = require("h5py", f"{index.path} is a MATLAB v7.3 (HDF5) file; reading it")
    with h5py.File(index.path, "r") as fh:
        yield lambda g, names, row0, count: _h5_read(fh, index, g, names, row0, count)


def _runs(index: FileIndex, hit: list[int], names: list[str]) -> Iterator[Recording]:
    """The hit blocks, contiguous runs of a group read in one call, as recordings (in group order)."""
    runs: list[list[Block]] = []
    for i in hit:
        b = index.blocks[i]
        if runs and runs[-1][-1].group == b.group and runs[-1][-1].row0 + runs[-1][-1].rows == b.row0:
            runs[-1].append(b)
        else:
            runs.append([b])
    if not runs:
        return
    with _group_reader(index) as read:
        for run in runs:
            yield Recording(None, read(run[0].group, names, run[0].row0, sum(b.rows for b in run)))


def _iter_grouped(index: FileIndex, names: list[str]) -> Iterator[Recording]:
    groups = sorted({_group_of(index, n) for n in names})
    queues = {g: [b for b in index.blocks if b.group == g and b.rows] for g in groups}
    # Merge the groups' blocks by first stamp, each group's kept in record order.
    heap = [(_sort_time(q[0]), g, 0) for g, q in queues.items() if q]
    heapq.heapify(heap)
    with _group_reader(index) as read:
        while heap:
            _, g, k = heapq.heappop(heap)
            b = queues[g][k]
            _check_unchanged(index)
            got = read(g, names, b.row0, b.rows)
            if k + 1 < len(queues[g]):
                heapq.heappush(heap, (_sort_time(queues[g][k + 1]), g, k + 1))
            yield _assembled(index, names, {n: [got[n]] if n in got else [] for n in names})


def _sort_time(b: Block) -> float:
    return -np.inf if b.t_min > b.t_max else b.t_min  # a block without a finite stamp: as soon as its turn comes


# MAT -----------------------------------------------------------------------------------------------------------------


def _read_mat(index: FileIndex) -> Recording:
    opts = {k: index.option(k) for k in ("fs", "time") if index.option(k) is not None}
    return read_mat(index.path, **opts)


def _recording_nbytes(rec: Recording) -> int:
    seen: set[int] = set()
    total = 0
    for ch in rec.channels.values():
        for a in (ch.values, ch.time):
            if id(a) not in seen:
                seen.add(id(a))
                total += a.nbytes
    return total


def _index_mat(p: Path, label: str, options: dict[str, Any], block_rows: int, stat: tuple[int, int]) -> FileIndex:
    if _where(label) is not None:
        raise FileFormatError(
            f"{label}: MATLAB files are read from a local path only (scipy and h5py open files by name); "
            "copy the file to a local disk",
            source=label,
        )
    rec = read_mat(p, **options)
    if mat_format.is_v73(p):
        index = _index_h5(p, label, options, block_rows, stat, rec)
        if index is not None:
            return index
    lows, highs, inc, rows = [], [], True, 0
    for ch in rec.channels.values():
        lo, hi, up = _stamp_summary(ch.time)
        lows.append(lo)
        highs.append(hi)
        inc = inc and up
        rows = max(rows, len(ch))
    block = Block(0, rows, min(lows, default=np.inf), max(highs, default=-np.inf), inc)
    return FileIndex(
        label, "mat", *stat, tuple(sorted(options.items())),
        tuple((n, c.unit) for n, c in rec.channels.items()), (block,), tuple(rec.metadata.items()),
        tuple(rec.skipped.items()), None, (),
    )


# MATLAB v7.3 (HDF5): each vector a dataset, read in slices ------------------------------------------------------------


def _h5_slice(ds: Any, a: int, b: int) -> NDArray[Any]:
    """Elements [a, b) of a MATLAB vector dataset (stored (1, n) or (n, 1): MATLAB's dimensions reversed)."""
    if ds.ndim == 1:
        return np.asarray(ds[a:b])
    if ds.ndim == 2 and ds.shape[0] == 1:
        return np.asarray(ds[0, a:b])
    if ds.ndim == 2 and ds.shape[1] == 1:
        return np.asarray(ds[a:b, 0])
    raise FileFormatError(f"dataset {ds.name} of shape {ds.shape} is not a vector")


def _h5_read(fh: Any, index: FileIndex, group: int, names: list[str], row0: int, count: int) -> dict[str, Channel]:
    """Rows [row0, row0 + count) of the channels of `names` on time base `group`, converted as `read_mat` does."""
    sources = index.info("h5")
    units = index.units
    label = index.path
    out: dict[str, Channel] = {}
    t = None
    for n in names:
        data_path, time_path, g, time_unit, time_label = sources[n]
        if g != group:
            continue
        if t is None:
            if time_path is None:
                t = uniform_time(count, index.option("fs"), label, row0)
            else:
                raw = _h5_slice(fh[time_path], row0, row0 + count).astype(np.float64)
                t = time_in_seconds(raw, time_unit, time_label, label)
        values = _h5_slice(fh[data_path], row0, row0 + count).astype(np.float64)
        out[n] = Channel(n, units[n], values, t)
    return out


def _index_h5(
    p: Path, label: str, options: dict[str, Any], block_rows: int, stat: tuple[int, int], rec: Recording
) -> FileIndex | None:
    """The index of a v7.3 file whose channels can be read in slices; None to read it whole (a layout not foreseen).

    `rec` is the file read whole (once, here): where each channel's samples and stamps lie
    is taken from the file's datasets, then checked against `rec` on the first block of
    each time base, so that slices are only used where they give what `read_mat` gives.
    """
    h5py = require("h5py", f"{label} is a MATLAB v7.3 (HDF5) file; reading it")
    with h5py.File(p, "r") as fh:
        variables = [k for k in fh if not k.startswith("#")]
        units: dict[str, str] = {}
        if "units" in fh and isinstance(fh["units"], h5py.Group):
            for k, v in (mat_format._hdf5_value(h5py, fh["units"]) or {}).items():
                text = mat_format._text(v)
                if text is not None:
                    units[k] = text.strip()
        rest = [k for k in variables if k not in ("units", "metadata")]
        time = options.get("time")
        time_name = time if time is not None else next((n for n in TIME_NAMES if n in rest), None)
        sources: dict[str, tuple[str, str | None, int, str, str]] = {}
        bases: dict[str | None, int] = {}
        for n in rec.channels:
            obj = fh.get(n)
            if obj is None:
                return None
            if isinstance(obj, h5py.Group):
                data_path = f"{n}/values" if "values" in obj else f"{n}/data"
                time_path: str | None = f"{n}/time"
                unit_text = mat_format._hdf5_value(h5py, obj["time_unit"]) if "time_unit" in obj else ""
                time_unit, time_label = mat_format._text(unit_text) or "", f"{n}.time"
            else:
                data_path, time_path = n, time_name
                time_unit, time_label = units.get(time_name, "") if time_name else "", time_name or ""
            g = bases.setdefault(time_path, len(bases))
            sources[n] = (data_path, time_path, g, time_unit, time_label)
        index = FileIndex(
            label, "mat", *stat, tuple(sorted(options.items())),
            tuple((n, c.unit) for n, c in rec.channels.items()), (), tuple(rec.metadata.items()),
            tuple(rec.skipped.items()), time_name, (("h5", sources),),
        )
        blocks: list[Block] = []
        try:
            for g in range(len(bases)):
                members = [n for n in rec.channels if sources[n][2] == g]
                t = rec.channels[members[0]].time
                first = _h5_read(fh, index, g, members, 0, min(block_rows, t.size))
                for n in members:
                    want = rec.channels[n]
                    got = first[n]
                    k = len(got)
                    if not (np.array_equal(got.values.view(np.int64), want.values[:k].view(np.int64))
                            and np.array_equal(got.time.view(np.int64), want.time[:k].view(np.int64))):
                        return None
                for row0 in range(0, t.size, block_rows):
                    lo, hi, inc = _stamp_summary(t[row0 : row0 + block_rows])
                    blocks.append(Block(row0, min(block_rows, t.size - row0), lo, hi, inc, group=g))
        except (FileFormatError, KeyError, TypeError, ValueError):
            return None
    return replace(index, blocks=tuple(blocks))


# ROS 2 bags ----------------------------------------------------------------------------------------------------------


def _index_rosbag(p: Path, label: str, options: dict[str, Any], block_rows: int, stat: tuple[int, int]) -> FileIndex:
    """One pass over the bag's JointState topic (`rosbag_format.scan_bag`): blocks of messages, their stamps' spans."""
    scan = rosbag_format.scan_bag(label, topic=options.get("topic"), block_rows=block_rows)
    channels = tuple((rosbag_format.channel_name(j, f), "") for j in scan.joints for f in scan.fields[j])
    blocks = tuple(Block(b.first, b.rows, b.t_min, b.t_max, b.increasing, group=int(b.one_layout), offset=b.log_lo,
                         end=b.log_hi) for b in scan.blocks)
    metadata = (("format", "rosbag"), ("topic", scan.topic), ("time.start_ns", str(scan.t0_ns)))
    extra = (("topic", scan.topic), ("t0_ns", scan.t0_ns), ("joints", scan.joints))
    index = FileIndex(label, "rosbag", *stat, tuple(sorted(options.items())), channels, blocks, metadata, (), "time",
                      extra)
    if scan.stamps is not None:  # for `time_bases` (a planner's next step), without a second pass over the bag
        _cached(_key(index, "stamps"), lambda: scan.stamps, lambda a: a.nbytes)
    return index


def _bag_block(index: FileIndex, block: Block) -> list[Column]:
    b = rosbag_format.BagBlock(block.row0, block.rows, block.offset, block.end, block.t_min, block.t_max,
                               block.increasing, bool(block.group))
    return rosbag_format.block_columns(index.path, index.info("topic"), b, index.info("t0_ns"), index.names)
