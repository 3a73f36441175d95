"""Tables of columns (CSV, Parquet) <-> recordings of channels on their own time bases.

A table has one time column (or a sample rate given by the caller) and one column per
channel. A channel logged slower than the table's rows has empty cells (CSV) or nulls
(Parquet) where it has no sample: those rows are not samples of that channel, so each
channel gets back its own time base. A NaN written in a cell is a sample whose value
is NaN (the data checks report it); only an empty cell means "no sample".
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .checks import check_time
from .errors import FileFormatError
from .recording import Channel, Recording
from .units import unit_factor

TIME_NAMES = ("time", "t", "Time", "TIME")


@dataclass
class Column:
    """One column as read: name, unit as written, its samples, and which of the R rows hold them.

    `present` is None when every row holds a sample (then `values` is (R,)), else a
    boolean (R,) and `values` holds only the samples of the rows where it is True
    (compacted as soon as the column is read, so that a table is never held twice).
    """

    name: str
    unit: str
    values: NDArray[np.float64]
    present: NDArray[np.bool_] | None = None


def find_time_column(names: Sequence[str], time: str | None, fs: float | None, source: str) -> str | None:
    """The name of the time column, or None when the caller gives fs; errors say what to pass."""
    if time is not None:
        if fs is not None:
            raise FileFormatError(f"{source}: give either time= (a column) or fs= (a sample rate), not both")
        if time not in names:
            raise FileFormatError(
                f"{source}: no column {time!r} to use as time; columns: {', '.join(names)}", source=source
            )
        return time
    found = [n for n in TIME_NAMES if n in names]
    if found and fs is not None:
        raise FileFormatError(
            f"{source}: the file has a time column {found[0]!r} and fs = {fs} was given too; "
            "drop fs (the time column is used) or pass time=None after renaming the column",
            source=source,
        )
    if found:
        return found[0]
    if fs is None:
        raise FileFormatError(
            f"{source}: no time column (looked for {', '.join(TIME_NAMES)}) and no sample rate: "
            f"pass fs= (Hz) if the rows are equally spaced, or time= with the time column's name. "
            f"Columns: {', '.join(names)}",
            source=source,
        )
    return None


def time_in_seconds(values: NDArray[np.float64], unit: str, name: str, source: str) -> NDArray[np.float64]:
    """A time column converted to s (an empty unit means s); error if its unit is not a time."""
    if unit.strip() == "":
        return values
    factor, si = unit_factor(unit, channel=name, source=source)
    if si != "s":
        raise FileFormatError(
            f"{source}: time column {name!r} has unit {unit!r}, which is not a time (s, ms, us, min, h)",
            source=source,
            channel=name,
        )
    return values * factor if factor != 1.0 else values


def uniform_time(n: int, fs: float, source: str, row0: int = 0) -> NDArray[np.float64]:
    """row0/fs, (row0+1)/fs, ..., (row0+n-1)/fs: the times of n rows starting at file row row0.

    Each stamp is (row index as an exact float64) / fs, so the stamps of rows read in
    pieces are bit for bit those of the whole file.
    """
    try:
        rate = float(fs)
    except (TypeError, ValueError):
        raise FileFormatError(f"{source}: fs must be a sample rate in Hz, not {fs!r}", source=source) from None
    if not np.isfinite(rate) or rate <= 0.0:
        raise FileFormatError(f"{source}: fs must be a positive sample rate in Hz, not {fs!r}", source=source)
    return np.arange(row0, row0 + n, dtype=np.int64).astype(np.float64) / rate


def recording_from_columns(
    source: Path,
    columns: Sequence[Column],
    *,
    time: str | None,
    fs: float | None,
    lines: NDArray[np.int64] | None = None,
    metadata: Mapping[str, str] | None = None,
    skipped: Mapping[str, str] | None = None,
    row0: int = 0,
) -> Recording:
    """Channels from table columns: each channel keeps the rows where it has a sample.

    `lines` (R,) are the file lines of the rows (text formats), for messages. A time
    column with a missing cell is an error naming the row. `row0` is the file row of
    the first row given (a part of the file read on its own; without a time column
    the stamps are row / fs).
    """
    label = str(source)
    names = [c.name for c in columns]
    time_name = find_time_column(names, time, fs, label)
    skipped = dict(skipped or {})
    t = table_time(columns, time_name, fs, label, lines, row0)
    channels: dict[str, Channel] = {}
    # Channels present on the same rows share one index, time base and line array (one
    # per logging rate), which saves memory and lets alignment group them at once.
    bases: list[tuple[NDArray[np.bool_], NDArray[np.intp], NDArray[np.float64], NDArray[np.int64] | None]] = []
    for col in columns:
        if col.name == time_name:
            continue
        if col.present is None or col.present.all():
            channels[col.name] = Channel(col.name, col.unit, col.values, t, lines)
            continue
        found = next((b for b in bases if np.array_equal(b[0], col.present)), None)
        if found is None:
            idx = np.flatnonzero(col.present)
            found = (col.present, idx, t[idx], None if lines is None else lines[idx])
            bases.append(found)
        _, idx, t_sub, lines_sub = found
        if idx.size == 0:
            skipped[col.name] = "no samples (every cell empty or null)"
            continue
        channels[col.name] = Channel(col.name, col.unit, col.values, t_sub, lines_sub)
    meta = dict(metadata or {})
    if time_name is None:
        meta.setdefault("fs", repr(float(fs)))  # type: ignore[arg-type]
    return Recording(source, channels, meta, skipped)


def table_time(
    columns: Sequence[Column],
    time_name: str | None,
    fs: float | None,
    label: str,
    lines: NDArray[np.int64] | None = None,
    row0: int = 0,
) -> NDArray[np.float64]:
    """The time stamps (R,) in s of the rows of a table: its time column, or row / fs without one.

    A time column with a missing cell is an error naming the line (text) or the file row.
    """
    if time_name is None:
        rows = (columns[0].values.size if columns[0].present is None else columns[0].present.size) if columns else 0
        return uniform_time(rows, fs, label, row0)  # type: ignore[arg-type]
    tcol = next(c for c in columns if c.name == time_name)
    if tcol.present is not None and not tcol.present.all():
        r = int(np.flatnonzero(~tcol.present)[0])
        where = f"line {int(lines[r])}" if lines is not None else f"row {row0 + r}"
        raise FileFormatError(
            f"{label}, {where}: the time column {time_name!r} is empty there; every row needs a time stamp",
            source=label,
            channel=time_name,
            line=None if lines is None else int(lines[r]),
        )
    return time_in_seconds(tcol.values, tcol.unit, time_name, label)


@dataclass
class Grid:
    """A recording laid out as a table: the union of the time stamps, one column per channel."""

    time: NDArray[np.float64]  # (R,), s
    names: list[str]
    units: list[str]
    values: list[NDArray[np.float64]]  # each (R,), NaN where absent
    present: list[NDArray[np.bool_] | None]  # each (R,), None where the channel has every row


def grid_of(recording: Recording, time_name: str = "time") -> Grid:
    """Lay the recording out on the union of its channels' time stamps (one row per distinct time)."""
    label = recording.label
    chans = list(recording.channels.values())
    if not chans:
        raise FileFormatError(f"{label}: the recording has no channel to write", source=label)
    if time_name in recording.channels:
        raise FileFormatError(
            f"{label}: a channel is named {time_name!r}, the name of the time column written; rename it",
            source=label,
            channel=time_name,
        )
    base = chans[0].time
    if all(ch.time is base or np.array_equal(ch.time, base) for ch in chans):
        return Grid(
            base, [c.name for c in chans], [c.unit for c in chans], [c.values for c in chans], [None] * len(chans)
        )
    distinct: list[NDArray[np.float64]] = []
    which: list[int] = []
    for ch in chans:
        for i, b in enumerate(distinct):
            if ch.time is b or np.array_equal(ch.time, b):
                which.append(i)
                break
        else:
            check_time(ch, source=label)  # the union layout needs strictly increasing stamps
            distinct.append(ch.time)
            which.append(len(distinct) - 1)
    union = np.unique(np.concatenate(distinct))
    positions = [np.searchsorted(union, b) for b in distinct]
    masks = []
    for pos in positions:
        mask = np.zeros(union.size, dtype=bool)
        mask[pos] = True
        masks.append(None if mask.all() else mask)
    values = []
    for ch, i in zip(chans, which, strict=True):
        col = np.full(union.size, np.nan)
        col[positions[i]] = ch.values
        values.append(col)
    return Grid(union, [c.name for c in chans], [c.unit for c in chans], values, [masks[i] for i in which])
