"""CSV measurement files.

Layout read (and written):

    # test: sine steering 90 km/h          <- optional comment lines "# key: value" (metadata)
    time [s],roll [deg],speed (km/h),Fz    <- header: names, units as "name [unit]" or "name (unit)"
    s,deg,km/h,N                           <- optional unit row (instead of, or agreeing with, the above)
    0.0,0.12,90.1,4012.5
    0.0016,0.13,,4013.0                    <- empty cell: that channel has no sample at this time

The time column is named time, t, Time or TIME (or `time=`), in s unless its unit says
otherwise; without one the caller gives the sample rate `fs`. The delimiter is ",",
";" or a tab (guessed from the header unless given); `decimal=","` reads decimal
commas. Numbers are parsed by NumPy in blocks of lines; a cell that is not a number
is an error naming the file, the line, the column and the cell. "nan" in a cell is a
sample whose value is NaN (reported by the data checks), an empty cell is no sample.
"""

from __future__ import annotations

import csv
import io
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass
from itertools import islice
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..atomic import atomic_path
from ..textfiles import encoding_problem
from ._table import TIME_NAMES, Column, Grid, grid_of, recording_from_columns
from .errors import FileFormatError
from .recording import Recording
from .units import split_unit  # the header's "name [unit]": the rule every format's reader shares

BLOCK_LINES = 65536  # lines parsed per NumPy call
_DECIMAL_COMMA = re.compile(r"^[+-]?\d*,\d+([eE][+-]?\d+)?$")
def _is_number(cell: str, decimal: str) -> bool:
    s = cell.strip()
    if decimal == ",":
        s = s.replace(",", ".")
    try:
        float(s)
    except ValueError:
        return False
    return True


def _guess_delimiter(header: str, path: Path) -> str:
    if path.suffix.lower() == ".tsv":
        return "\t"
    counts = {d: header.count(d) for d in ("\t", ";", ",")}
    best = max(counts, key=lambda d: counts[d])
    return best if counts[best] > 0 else ","


# the longest line read: 10 000 channels of 25 characters is 250 kB; a file with no line end (a binary file named
# .csv, one giant line) is refused at this length instead of held whole
MAX_LINE = 16 * 2**20


def bounded_lines(fh, label: str, start: int = 1, limit: int | None = None) -> Iterator[tuple[int, str | bytes]]:
    """(number, line) of a text or binary file, each line with its end, none longer than `limit` characters (bytes,
    default MAX_LINE): a longer one is a FileFormatError naming the line, read no further than the limit."""
    limit = MAX_LINE if limit is None else limit
    number = start
    while True:
        line = fh.readline(limit + 1)
        if not line:
            return
        if len(line) > limit:
            raise FileFormatError(f"{label}, line {number}: longer than {limit:,} characters (no line end found): "
                                  "not a CSV of samples; check the file (a binary file named .csv?) and its line ends",
                                  source=label, line=number)
        yield number, line
        number += 1


def _numbered_lines(fh: io.TextIOBase, start: int, label: str = "") -> Iterator[tuple[int, str]]:
    for number, line in bounded_lines(fh, label, start):
        yield number, line.rstrip("\r\n")


def read_csv(
    path: str | os.PathLike[str],
    *,
    fs: float | None = None,
    time: str | None = None,
    delimiter: str | None = None,
    decimal: str = ".",
    units_row: bool | None = None,
    units_in_header: bool = True,
    encoding: str = "utf-8-sig",
) -> Recording:
    """Read a CSV file into a `Recording` (layout in the module docstring).

    Parameters
    ----------
    path : the file.
    fs : Hz, sample rate when the file has no time column (rows equally spaced, first at 0 s).
    time : name of the time column if it is not time/t/Time/TIME.
    delimiter : "," ";" or "\\t"; None guesses from the header line.
    decimal : "." or "," (then the delimiter must not be ",").
    units_row : whether the line after the header holds units; None: yes if its cell in
        the time column (or, without one, any cell) is not a number.
    units_in_header : read "name [unit]" / "name (unit)" headers as name and unit.
    encoding : text encoding (a UTF-8 byte-order mark is skipped).

    Returns
    -------
    Recording; channels in the header's order, values as in the file (units not converted).
    """
    path = Path(path)
    label = str(path)
    if decimal not in (".", ","):
        raise FileFormatError(f"{label}: decimal must be '.' or ',', not {decimal!r}", source=label)
    try:
        return _read_csv(path, label, fs, time, delimiter, decimal, units_row, units_in_header, encoding)
    except UnicodeDecodeError as exc:
        utf8 = encoding.lower().replace("_", "-") in ("utf-8", "utf-8-sig", "utf8")
        why = encoding_problem(path) if utf8 else f"not {encoding} text ({exc.reason})"
        raise FileFormatError(f"{label}: {why}", source=label) from None


@dataclass
class CsvHeader:
    """What the lines before the data say: columns, units, delimiter, metadata, where the data start."""

    names: list[str]
    units: list[str]
    delimiter: str
    metadata: dict[str, str]
    data_line: int  # the number (1-based) of the first line after the header and the unit row
    pending: list[tuple[int, str]]  # lines read while looking for a unit row that are data


def _read_csv(path: Path, label: str, fs: float | None, time: str | None, delimiter: str | None, decimal: str,
              units_row: bool | None, units_in_header: bool, encoding: str) -> Recording:
    with open(path, encoding=encoding, newline="") as fh:
        lines = _numbered_lines(fh, 1, label)
        head = read_header(lines, path, label, time, delimiter, decimal, units_row, units_in_header)
        data, present, line_numbers = parse_rows(
            _chain(head.pending, lines), len(head.names), head.names, head.delimiter, decimal, label
        )
    columns = columns_of(data, present, head)
    del data
    return recording_from_columns(path, columns, time=time, fs=fs, lines=line_numbers, metadata=head.metadata)


def read_header(lines: Iterator[tuple[int, str]], path: Path, label: str, time: str | None, delimiter: str | None,
                decimal: str, units_row: bool | None, units_in_header: bool) -> CsvHeader:
    """Read the comment lines, the header and the unit row (if any) from numbered lines; errors name the line.

    Shared by `read_csv` and the window reader (`dynid.io.windows`), so that both see the
    same columns and units. Consumes the first line after the header.
    """
    metadata: dict[str, str] = {"format": "csv"}
    header_no, header = 0, None
    for number, text in lines:
        stripped = text.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            key, sep, value = stripped.lstrip("#").partition(":")
            if sep and key.strip():
                metadata[key.strip()] = value.strip()
            continue
        header_no, header = number, text
        break
    if header is None:
        raise FileFormatError(f"{label}: no header line (the file is empty or has only comments)", source=label)
    delim = delimiter or _guess_delimiter(header, path)
    if decimal == "," and delim == ",":
        raise FileFormatError(f"{label}: decimal ',' needs another delimiter (';' or tab)", source=label)
    cells = next(csv.reader([header], delimiter=delim))
    if len(cells) > 1 and all(_is_number(c, decimal) for c in cells):
        raise FileFormatError(
            f"{label}, line {header_no}: the first line that is not a comment holds numbers, not the columns' names; "
            "give the header (\"time [s],q1 [rad],...\") as the first line (is it commented out with '#'?)",
            source=label, line=header_no)
    names: list[str] = []
    units: list[str] = []
    for j, cell in enumerate(cells):
        name, unit = split_unit(cell) if units_in_header else (cell.strip(), "")
        if not name:
            raise FileFormatError(
                f"{label}, line {header_no}, column {j + 1}: empty column name in the header",
                source=label,
                line=header_no,
            )
        if name in names:
            raise FileFormatError(
                f"{label}, line {header_no}: columns {names.index(name) + 1} and {j + 1} are both named {name!r}",
                source=label,
                line=header_no,
            )
        names.append(name)
        units.append(unit)
    ncol = len(names)
    time_col = time if time is not None else next((n for n in TIME_NAMES if n in names), None)
    first = next(lines, None)
    pending: list[tuple[int, str]] = []
    data_line = header_no + 1
    if first is not None:
        number, text = first
        row = next(csv.reader([text], delimiter=delim)) if text.strip() else []
        is_units = units_row
        if is_units is None and row:
            if time_col is not None and time_col in names and names.index(time_col) < len(row):
                is_units = not _is_number(row[names.index(time_col)], decimal)
            else:
                is_units = any(c.strip() and not _is_number(c, decimal) for c in row)
        if is_units:
            for j, cell in enumerate(row[:ncol]):
                unit = cell.strip().strip("[]()").strip()
                if unit and units[j] and unit != units[j]:
                    raise FileFormatError(
                        f"{label}, line {number}, column {j + 1} ({names[j]!r}): the unit row says {unit!r} "
                        f"but the header says {units[j]!r}",
                        source=label,
                        channel=names[j],
                        line=number,
                    )
                units[j] = units[j] or unit
            metadata["units_row"] = str(number)
            data_line = number + 1
        else:
            pending.append(first)
    return CsvHeader(names, units, delim, metadata, data_line, pending)


def columns_of(data: NDArray[np.float64], present: NDArray[np.bool_] | None, head: CsvHeader) -> list[Column]:
    """Parsed rows (R, C) and their presence as one `Column` per header column (samples compacted)."""
    data = np.ascontiguousarray(data.T)  # one contiguous row per channel
    present = None if present is None else np.ascontiguousarray(present.T)
    columns = []
    for j in range(len(head.names)):
        mask = None if present is None or present[j].all() else present[j]
        columns.append(Column(head.names[j], head.units[j], data[j] if mask is None else data[j][mask], mask))
    return columns


def _chain(first: list[tuple[int, str]], rest: Iterator[tuple[int, str]]) -> Iterator[tuple[int, str]]:
    yield from first
    yield from rest


def parse_rows(
    lines: Iterator[tuple[int, str]], ncol: int, names: list[str], delim: str, decimal: str, label: str
) -> tuple[NDArray[np.float64], NDArray[np.bool_] | None, NDArray[np.int64]]:
    """All data rows: values (R, C) (NaN where empty), presence (R, C) or None if no cell is empty, line numbers.

    Blank lines are skipped. A cell's number does not depend on which lines are parsed
    with it, so a file parsed in pieces gives the whole file's values bit for bit.
    """
    blocks, masks, numbers = [], [], []
    any_missing = False
    while True:
        raw = list(islice(lines, BLOCK_LINES))
        if not raw:
            break
        chunk = [(n, t) for n, t in raw if t.strip()]
        if not chunk:
            continue
        nums = np.fromiter((n for n, _ in chunk), dtype=np.int64, count=len(chunk))
        values, mask = _parse_block(chunk, ncol, names, delim, decimal, label)
        blocks.append(values)
        masks.append(mask)
        numbers.append(nums)
        any_missing = any_missing or mask is not None
    if not blocks:
        return np.empty((0, ncol)), None, np.empty(0, dtype=np.int64)
    data = np.concatenate(blocks) if len(blocks) > 1 else blocks[0]
    present = None
    if any_missing:
        present = np.concatenate(
            [m if m is not None else np.ones(b.shape, dtype=bool) for m, b in zip(masks, blocks, strict=True)]
        )
    return data, present, np.concatenate(numbers)


def parse_plain(text: str, ncol: int, delim: str, decimal: str) -> NDArray[np.float64] | None:
    """The rows of `text` (data lines, "\n" line ends, the last one's optional) in one parse when every line is a
    plain row (ncol numbers, no empty cell, no quote, no nan or inf, no blank line, "." decimals); else None, and
    the caller parses line by line (`parse_rows`). The numbers are `parse_rows`' bit for bit (the same NumPy
    parser on the same text), without its per-line lists, joins and checks: a logger's usual block, whole.

    Only one-character searches before the parse (memchr speed; a two-character one such as ",," costs a tenth
    of the parse): NumPy refuses an empty cell itself, and skips a blank line, which the row count then tells."""
    if not text or decimal != "." or "\r" in text or '"' in text or _may_name_values(text):
        return None
    try:
        values = np.loadtxt(io.StringIO(text), delimiter=delim, dtype=np.float64, ndmin=2, comments=None)
    except ValueError:
        return None
    rows = text.count("\n") + (not text.endswith("\n"))
    return values if values.shape == (rows, ncol) else None


def _may_name_values(text: str) -> bool:
    """Whether a cell may read nan or inf (in any case): the letters alone, each found at memory speed (a lowered
    copy of the text would cost more than the search)."""
    return any(letter in text for letter in "nNiI")


def _has_empty(text: str, d: str) -> bool:
    """Whether a line of `text` (no blank line) has an empty cell: two delimiters in a row, or one at a line's end."""
    return d * 2 in text or text.startswith(d) or text.endswith(d) or f"\n{d}" in text or f"{d}\n" in text


def _fill_empty(text: str, delim: str) -> str:
    """Write 'nan' into the empty cells of newline-separated, delimited lines (no blank line)."""
    d = delim
    text = f"\n{text}\n".replace(f"\n{d}", f"\nnan{d}").replace(f"{d}\n", f"{d}nan\n")
    # Two passes: the first fills every other cell of a run of empty cells, the second the rest.
    text = text.replace(d + d, f"{d}nan{d}").replace(d + d, f"{d}nan{d}")
    return text[1:-1]


def _parse_block(
    chunk: list[tuple[int, str]], ncol: int, names: list[str], delim: str, decimal: str, label: str
) -> tuple[NDArray[np.float64], NDArray[np.bool_] | None]:
    text = "\n".join(t for _, t in chunk)
    if decimal == ",":
        text = text.replace(",", ".")
    if '"' not in text and not (_may_name_values(text) and ("nan" in (lowered := text.lower()) or "inf" in lowered)):
        has_empty = _has_empty(text, delim)
        filled = _fill_empty(text, delim) if has_empty else text
        try:
            values = np.loadtxt(io.StringIO(filled), delimiter=delim, dtype=np.float64, ndmin=2, comments=None)
        except ValueError:
            values = None
        if values is not None and values.shape == (len(chunk), ncol):
            if not has_empty:
                return values, None
            # No literal NaN in the block, so every NaN is an empty cell.
            return values, ~np.isnan(values)
    return _parse_block_slowly(chunk, ncol, names, delim, decimal, label)


def _parse_block_slowly(
    chunk: list[tuple[int, str]], ncol: int, names: list[str], delim: str, decimal: str, label: str
) -> tuple[NDArray[np.float64], NDArray[np.bool_] | None]:
    """Cell by cell: tells an empty cell from 'nan', and names the line and column of a bad cell."""
    values = np.full((len(chunk), ncol), np.nan)
    present = np.ones((len(chunk), ncol), dtype=bool)
    for i, (number, text) in enumerate(chunk):
        cells = next(csv.reader([text], delimiter=delim)) if '"' in text else text.split(delim)
        if len(cells) > ncol and not any(c.strip() for c in cells[ncol:]):
            cells = cells[:ncol]  # trailing delimiters
        if len(cells) != ncol:
            raise FileFormatError(
                f"{label}, line {number}: {len(cells)} cell(s) but the header has {ncol} column(s); "
                "fix the row (a missing or extra delimiter?)",
                source=label,
                line=number,
            )
        for j, cell in enumerate(cells):
            s = cell.strip()
            if not s:
                present[i, j] = False
                continue
            if decimal == ",":
                s = s.replace(",", ".")
            try:
                if not s.isascii() or "_" in s:  # float() reads '1_000' and other scripts' digits: no logger's
                    raise ValueError(s)
                values[i, j] = float(s)
            except ValueError:
                comma = decimal != "," and _DECIMAL_COMMA.match(s)
                fix = ("a decimal comma: export the file with '.' as the decimal mark (0.42, not 0,42)" if comma
                       else "fix the cell, or leave it empty if the channel has no sample at that time")
                raise FileFormatError(
                    f"{label}, line {number}, column {j + 1} ({names[j]!r}): cannot read {cell!r} as a number; "
                    f"{fix}",
                    source=label,
                    channel=names[j],
                    line=number,
                ) from None
    return values, (None if present.all() else present)


def _header_cell(name: str, unit: str) -> str:
    if unit:
        return f"{name} [{unit}]"
    # A name that would read back as "name [unit]" gets an explicit empty unit.
    return f"{name} []" if split_unit(name)[1] or name != split_unit(name)[0] else name


def write_csv(recording: Recording, path: str | os.PathLike[str], *, delimiter: str = ",") -> Path:
    """Write the recording as CSV (module docstring), atomically; floats written exactly (shortest repr).

    Channels on different time bases share one time column (the union of their time
    stamps); a channel's cells are empty at the times it has no sample. Metadata
    becomes "# key: value" lines. Returns the path written.
    """
    path = Path(path)
    grid = grid_of(recording)
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8", newline="") as out:
        _write_grid(out, recording, grid, delimiter)
    return path


def _write_grid(out: io.TextIOBase, recording: Recording, grid: Grid, delimiter: str) -> None:
    for key, value in recording.metadata.items():
        if key in ("format", "units_row"):
            continue
        out.write(f"# {_one_line(key).replace(':', '_')}: {_one_line(value)}\n")
    writer = csv.writer(out, delimiter=delimiter, lineterminator="\n")
    writer.writerow(["time [s]"] + [_header_cell(n, u) for n, u in zip(grid.names, grid.units, strict=True)])
    columns = []
    for col, present in zip([grid.time, *grid.values], [None, *grid.present], strict=True):
        cells = _cells(col)
        if present is not None:
            cells[~present] = ""  # no sample at that time
        columns.append(cells.tolist())
    if grid.time.size:
        out.write("\n".join(map(delimiter.join, zip(*columns, strict=True))))  # zip reuses its row tuple
        out.write("\n")


def _cells(values: NDArray[np.float64]) -> NDArray[np.object_]:
    """Each value's shortest repr (exact: float() reads it back to the bit), formatted once per distinct value: a
    logger's channel repeats its quantised values (a demo file has 1 distinct value in 7), so this is 3-5 times
    faster than a repr per cell. Distinct by bit pattern, so -0.0 stays -0.0."""
    distinct, where = np.unique(np.ascontiguousarray(values, dtype=np.float64).view(np.int64), return_inverse=True)
    text = np.array(list(map(float.__repr__, distinct.view(np.float64).tolist())), dtype=object)
    return text[where.reshape(-1)]


def _one_line(text: str) -> str:
    return " ".join(str(text).split())
