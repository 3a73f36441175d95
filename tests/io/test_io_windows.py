"""Tests of dynid.io.windows: time windows and blocks of a file, read without reading it whole.

Oracle: the whole-file reader `read_recording(path, channels=..., **options)`, whose own
tests (test_io.py) check it against what was written. A window must equal its samples
with t0 <= t <= t1, and the blocks of `iter_blocks` must concatenate to them, bit for bit
(values and stamps compared as int64 views, so -0.0 / 0.0 and NaN payloads count). The
files are random (hypothesis): CSV with or without time column, units in the header or in
a unit row, decimal commas, a sparse multi-rate column, repeated stamps and stamps that go
back; Parquet with several row groups, a timestamp time column, integer, boolean and
null-sparse columns; MDF4 with two groups at different rates; MATLAB files.
"""

from __future__ import annotations

import importlib.util
import os
import pickle
import re
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dynid.io import (
    Channel,
    FileFormatError,
    FileIndex,
    MissingChannelError,
    Recording,
    index_file,
    iter_blocks,
    read_recording,
    read_window,
    time_bases,
    windows,
    write_recording,
)

HAVE_PYARROW = importlib.util.find_spec("pyarrow") is not None
HAVE_ASAMMDF = importlib.util.find_spec("asammdf") is not None
HAVE_H5PY = importlib.util.find_spec("h5py") is not None
HAVE_FSSPEC = importlib.util.find_spec("fsspec") is not None
needs_pyarrow = pytest.mark.skipif(not HAVE_PYARROW, reason="pyarrow not installed")
needs_asammdf = pytest.mark.skipif(not HAVE_ASAMMDF, reason="asammdf not installed")

SETTINGS = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


def assert_same_channel(got: Channel, want: Channel | None, mask: np.ndarray | None = None) -> None:
    """`got` holds exactly want's samples where mask is True (all of them without a mask), bit for bit."""
    if want is None:  # a channel the whole-file reader found no sample of
        assert len(got) == 0
        return
    m = np.ones(len(want), dtype=bool) if mask is None else mask
    assert got.unit == want.unit
    np.testing.assert_array_equal(bits(got.values), bits(want.values[m]))
    np.testing.assert_array_equal(bits(got.time), bits(want.time[m]))
    if want.lines is None:
        assert got.lines is None
    else:
        np.testing.assert_array_equal(got.lines, want.lines[m])


def check_windows_and_blocks(path: Path, names: list[str], windows_: list[tuple[float, float]], **options) -> FileIndex:
    """The oracle check: every window and the blocks against the whole-file read."""
    windows.clear_cache()
    block_rows = options.pop("block_rows", 7)
    index = index_file(path, block_rows=block_rows, **options)
    whole = read_recording(path, channels=names, **options)
    for t0, t1 in windows_:
        got = read_window(index, names, t0, t1)
        assert list(got.channels) == names
        for n in names:
            want = whole.channels.get(n)
            mask = None if want is None else (want.time >= t0) & (want.time <= t1)
            assert_same_channel(got.channels[n], want, mask)
    parts = list(iter_blocks(index, names))
    for n in names:
        want = whole.channels.get(n)
        got = [p.channels[n] for p in parts]
        if want is None:
            assert all(len(g) == 0 for g in got)
            continue
        joined = Channel(
            n,
            want.unit,
            np.concatenate([g.values for g in got]),
            np.concatenate([g.time for g in got]),
            None if want.lines is None else np.concatenate([g.lines for g in got]),
        )
        assert_same_channel(joined, want)
    # the time bases: every channel with samples in exactly one, whose stamps (and lines) are the channel's own
    bases = time_bases(index, names)
    for n in names:
        want = whole.channels.get(n)
        home = [b for b in bases if n in b[0]]
        if want is None or len(want) == 0:
            assert not home, n
            continue
        assert len(home) == 1, (n, [b[0] for b in bases])
        _, t, lines = home[0]
        np.testing.assert_array_equal(bits(t), bits(want.time))
        assert (lines is None) == (want.lines is None) and (lines is None or np.array_equal(lines, want.lines))
    assert pickle.loads(pickle.dumps(index)) == index
    assert hash(pickle.loads(pickle.dumps(index))) == hash(index)
    return index


# --------------------------------------------------------------------------------------------------------------------
# random data


@st.composite
def stamps(draw: st.DrawFn, *, back: bool = True, repeats: bool = True) -> np.ndarray:
    """Time stamps, s: steady steps with repeated stamps and (optionally) a few going back."""
    n = draw(st.integers(1, 60))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    steps = rng.choice([0.01, 0.0016, 0.1, 0.25], size=n) * rng.uniform(0.5, 1.5, size=n)
    if repeats and draw(st.booleans()):
        steps[rng.random(n) < 0.2] = 0.0
    if back and draw(st.booleans()):
        steps[rng.random(n) < 0.1] *= -3.0
    t = draw(st.sampled_from([0.0, -1.5, 1e3])) + np.cumsum(steps) - steps[0]
    return t


@st.composite
def window_list(draw: st.DrawFn, t: np.ndarray) -> list[tuple[float, float]]:
    """Windows on stamps, between them, around the record and empty (t1 < t0)."""
    lo, hi = float(np.min(t)), float(np.max(t))
    candidates = [*t.tolist(), lo - 1.0, hi + 1.0, lo - 1e-9, hi + 1e-9]
    if t.size > 1:
        candidates += ((t[1:] + t[:-1]) / 2).tolist()
    pick = st.sampled_from(candidates)
    out = [(lo - 2.0, hi + 2.0), (hi + 1.0, hi + 2.0), (lo - 2.0, lo - 1.0)]
    for _ in range(draw(st.integers(1, 6))):
        out.append((draw(pick), draw(pick)))  # in either order: t1 < t0 is an empty window
    return out


def values_for(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.normal(size=n) * 10.0 ** rng.integers(-6, 6, size=n)


def write_csv_text(
    path: Path,
    t: np.ndarray | None,
    columns: list[tuple[str, str, np.ndarray, np.ndarray | None]],
    *,
    units: str,
    decimal: str,
    blank_every: int = 0,
) -> None:
    """A CSV file written by hand (the test's own writer): units in the header, in a unit row, or none."""
    delim = ";" if decimal == "," else ","
    names = ([("time", "s")] if t is not None else []) + [(c[0], c[1]) for c in columns]

    def cell(v: float) -> str:
        s = repr(float(v))
        return s.replace(".", ",") if decimal == "," else s

    out = ["# test: windows\n"]
    if units == "header":
        out.append(delim.join(f"{n} [{u}]" if u else n for n, u in names) + "\n")
    else:
        out.append(delim.join(n for n, _ in names) + "\n")
        if units == "row":
            out.append(delim.join(u or "-" for _, u in names) + "\n")
    rows = len(columns[0][2]) if t is None else t.size
    for i in range(rows):
        cells = [] if t is None else [cell(t[i])]
        for _, _, v, present in columns:
            cells.append(cell(v[i]) if present is None or present[i] else "")
        out.append(delim.join(cells) + "\n")
        if blank_every and i % blank_every == blank_every - 1:
            out.append("\n")
    path.write_text("".join(out), encoding="utf-8")


# --------------------------------------------------------------------------------------------------------------------
# CSV


@SETTINGS
@given(data=st.data(), t=stamps(), units=st.sampled_from(["header", "row"]), decimal=st.sampled_from([".", ","]))
def test_csv_windows_and_blocks_equal_the_whole_file(data: st.DataObject, t: np.ndarray, units: str, decimal: str):
    seed = data.draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    sparse = rng.random(t.size) < 0.4
    cols = [
        ("roll", "deg", values_for(t.size, seed), None),
        ("Fz", "N", values_for(t.size, seed + 1), sparse),  # a slower channel: empty cells between its samples
        ("never", "m", values_for(t.size, seed + 2), np.zeros(t.size, dtype=bool)),
    ]
    wins = data.draw(window_list(t))
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "log.csv"
        write_csv_text(path, t, cols, units=units, decimal=decimal, blank_every=data.draw(st.sampled_from([0, 5])))
        options = {"decimal": decimal} if decimal == "," else {}
        index = check_windows_and_blocks(path, ["roll", "Fz", "never"], wins, **options)
        assert index.monotonic == bool(np.all(np.diff(t) >= 0))


@SETTINGS
@given(data=st.data(), t=stamps(), odd=st.sampled_from(["none", "blank", "nan", "inf", "empty", "extra cell"]))
def test_csv_blocks_of_plain_rows_parsed_whole_equal_the_whole_file(data: st.DataObject, t: np.ndarray, odd: str):
    """Every cell present, so the window reader parses a block of plain rows in one call (`parse_plain`); at
    most one line somewhere is not plain (a blank line, a literal nan or inf, an empty cell, a cell too many),
    so its block goes the line-by-line way: both against the whole-file read (`parse_rows`), bit for bit. A cell
    too many is refused by both, naming its line."""
    seed = data.draw(st.integers(0, 2**32 - 1))
    cols = [("roll", "deg", values_for(t.size, seed), None), ("Fz", "N", values_for(t.size, seed + 1), None)]
    at = data.draw(st.integers(0, t.size - 1))
    if odd in ("nan", "inf"):
        cols[1][2][at] = float(odd)
    elif odd == "empty":
        cols = [cols[0], ("Fz", "N", cols[1][2], np.arange(t.size) != at)]
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "log.csv"
        write_csv_text(path, t, cols, units="header", decimal=".")
        if odd in ("blank", "extra cell"):
            lines = path.read_text().split("\n")
            k = 2 + at  # the comment and the header first
            lines[k] = lines[k] + ",1.0" if odd == "extra cell" else lines[k] + "\n"
            path.write_text("\n".join(lines))
        if odd == "extra cell":
            for read in (lambda: read_recording(path), lambda: list(iter_blocks(index_file(path, block_rows=7),
                                                                                ["roll", "Fz"]))):
                with pytest.raises(FileFormatError, match=f"line {3 + at}: 4 cell"):
                    read()
            return
        check_windows_and_blocks(path, ["roll", "Fz"], data.draw(window_list(t)))


@SETTINGS
@given(n=st.integers(1, 80), fs=st.sampled_from([625.0, 1000.0 / 3.0, 7.3]), seed=st.integers(0, 2**32 - 1),
       data=st.data())
def test_csv_without_time_column_uses_the_file_row_over_fs(n: int, fs: float, seed: int, data: st.DataObject):
    # The stamps of a window are row / fs with row the FILE's row: np.arange(lo, hi) / fs equals
    # (np.arange(n) / fs)[lo:hi] bit for bit, which the oracle (whole file) checks here.
    rng = np.random.default_rng(seed)
    cols = [("a", "m", values_for(n, seed), None), ("b", "", values_for(n, seed + 1), rng.random(n) < 0.5)]
    wins = data.draw(window_list(np.arange(n) / fs))
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "log.csv"
        write_csv_text(path, None, cols, units=data.draw(st.sampled_from(["header", "none"])), decimal=".")
        check_windows_and_blocks(path, ["a", "b"], wins, fs=fs, block_rows=data.draw(st.sampled_from([1, 4, 1000])))


def test_uniform_stamps_of_a_part_are_those_of_the_whole() -> None:
    for fs in (625.0, 1000.0 / 3.0, 0.7, 7.3, 1e-3):
        whole = np.arange(100_000, dtype=np.float64) / fs
        for lo, hi in ((0, 10), (1234, 5678), (99_990, 100_000)):
            part = np.arange(lo, hi, dtype=np.int64).astype(np.float64) / fs
            np.testing.assert_array_equal(bits(part), bits(whole[lo:hi]))
            np.testing.assert_array_equal(bits(windows.uniform_time(hi - lo, fs, "x", lo)), bits(whole[lo:hi]))


def test_csv_with_crlf_line_ends_a_bom_and_a_units_row(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    lines = ["# car: 406", "t;ax;ay", "s;m/s^2;g"] + [f"{i / 100};{i * 0.5};{'' if i % 3 else i}" for i in range(50)]
    path.write_bytes(("\ufeff" + "\r\n".join(lines) + "\r\n").encode("utf-8"))
    index = check_windows_and_blocks(path, ["ax", "ay"], [(0.1, 0.2), (0.105, 0.33), (-1, 9)], block_rows=6)
    assert index.units == {"ax": "m/s^2", "ay": "g"}
    assert dict(index.metadata)["car"] == "406"


def test_csv_in_latin1_with_tabs_and_time_in_ms(tmp_path: Path) -> None:
    path = tmp_path / "log.tsv"
    lines = ["t [ms]\troll [°]\tv [km/h]"] + [f"{i * 1.6}\t{i * 0.01}\t{90 + i % 7}" for i in range(40)]
    path.write_bytes(("\n".join(lines) + "\n").encode("latin-1"))
    index = check_windows_and_blocks(
        path, ["roll", "v"], [(0.0016, 0.0096), (0.01, 0.02), (0.0, 0.0)], encoding="latin-1", block_rows=9
    )
    assert index.units == {"roll": "°", "v": "km/h"}


def test_csv_stamps_going_back_do_not_lose_rows(tmp_path: Path) -> None:
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.15, 0.25, 0.4, 0.5, 0.05, 0.6, 0.7, 0.7, 0.8])
    path = tmp_path / "log.csv"
    write_csv_text(path, t, [("a", "m", np.arange(t.size) * 1.5, None)], units="header", decimal=".")
    index = check_windows_and_blocks(path, ["a"], [(0.1, 0.2), (0.0, 0.06), (0.7, 0.7)], block_rows=3)
    assert not index.monotonic
    assert [b.increasing for b in index.blocks] == [True, False, False, True, True]
    got = read_window(index, ["a"], 0.04, 0.16)  # rows 1, 4 and 8, in three blocks
    np.testing.assert_array_equal(got.channels["a"].values, [1.5, 6.0, 12.0])
    np.testing.assert_array_equal(got.channels["a"].lines, [4, 7, 11])


# --------------------------------------------------------------------------------------------------------------------
# Parquet


# 40 examples, 7 s of CPU: slow; the quick run keeps Parquet windows against the whole file's values in
# test_window_reads_only_the_row_groups_it_overlaps, test_parquet_without_time_column_and_timestamp_channel and
# test_urls_read_through_fsspec_as_local_files[parquet]
@pytest.mark.slow
@needs_pyarrow
@SETTINGS
@given(t=stamps(), data=st.data())
def test_parquet_windows_and_blocks_equal_the_whole_file(t: np.ndarray, data: st.DataObject):
    import pyarrow as pa
    import pyarrow.parquet as pq

    seed = data.draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    n = t.size
    stamp = data.draw(st.sampled_from(["float", "us", "ns"]))
    if stamp == "float":
        time_col = pa.array(t, type=pa.float64())
    else:
        ticks = np.round(t * (1e6 if stamp == "us" else 1e9)).astype(np.int64) + 1_700_000_000 * 10**6
        time_col = pa.array(ticks, type=pa.timestamp(stamp))
    sparse = rng.random(n) < 0.5
    table = pa.table(
        {
            "time": time_col,
            "roll": pa.array(values_for(n, seed)),
            "gear": pa.array(rng.integers(-3, 7, size=n), type=pa.int32()),
            "brake": pa.array(rng.random(n) < 0.5),
            "Fz": pa.array(values_for(n, seed + 1), mask=~sparse),  # nulls: no sample at those rows
            "driver": pa.array(["x"] * n),  # not numeric: not a channel
        }
    )
    wins = data.draw(window_list(t))
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "log.parquet"
        pq.write_table(table, path, row_group_size=data.draw(st.integers(1, 25)))
        check_windows_and_blocks(path, ["roll", "gear", "brake", "Fz"], wins)


@needs_pyarrow
def test_parquet_without_time_column_and_timestamp_channel(tmp_path: Path) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    n = 103
    start = np.datetime64("2024-05-01T10:00:00", "ns").astype(np.int64)
    table = pa.table(
        {
            "a": pa.array(np.arange(n) * 0.25),
            "gps_time": pa.array(start + np.arange(n) * 1_600_000 + 7, type=pa.timestamp("ns")),
        }
    )
    path = tmp_path / "log.parquet"
    pq.write_table(table, path, row_group_size=10)
    check_windows_and_blocks(path, ["a", "gps_time"], [(0.0, 0.01), (0.05, 0.0721), (0.1, 9.0)], fs=625.0)


def row_groups_log(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[Recording, FileIndex, list[int]]:
    """A Parquet log of 3 channels in 20 row groups of 16 s (625 Hz), its index, and the row groups decoded from now
    on (the block cache emptied), in the order decoded."""
    import pyarrow.parquet as pq

    n, fs = 200_000, 625.0
    t = np.arange(n) / fs
    rec = Recording.from_channels([Channel(f"c{k}", "m", np.sin(t * (k + 1)), t) for k in range(3)])
    path = tmp_path / "big.parquet"
    write_recording(rec, path)
    table = pq.read_table(path)
    pq.write_table(table, path, row_group_size=10_000)
    index = index_file(path)
    read: list[int] = []
    original = pq.ParquetFile.read_row_group

    def counting(self, i, *args, **kwargs):
        read.append(i)
        return original(self, i, *args, **kwargs)

    monkeypatch.setattr(pq.ParquetFile, "read_row_group", counting)
    windows.clear_cache()
    return rec, index, read


@needs_pyarrow
def test_window_reads_only_the_row_groups_it_overlaps(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    rec, index, read = row_groups_log(tmp_path, monkeypatch)
    assert len(index.blocks) == 20 and index.monotonic
    got = read_window(index, ["c0", "c2"], 100.0, 130.0)  # rows 62500..81250: row groups 6, 7, 8
    assert sorted(set(read)) == [6, 7, 8]
    assert len(read) == 3 * 3  # time, c0, c2 of each
    np.testing.assert_array_equal(got.channels["c2"].values, rec.channels["c2"].values[62500:81251])
    read.clear()
    read_window(index, ["c0", "c2"], 125.0, 140.0)  # row groups 7 and 8, decoded by the last window: cached
    assert read == []
    windows.clear_cache()
    read_window(index, ["c0"], 125.0, 140.0)
    assert sorted(read) == [7, 7, 8, 8]


@needs_pyarrow
def test_a_reader_in_time_order_keeps_only_the_blocks_it_reads_again(tmp_path: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """Oracle: the row groups' time spans (16 s each: group 6 is 96-112 s, 7 is 112-128 s). After a window, the blocks
    wholly before the next window's start are dropped (`forget_blocks_before`): read again, they are decoded again;
    the others stay (the next window, in time order, decodes only what it did not share with this one)."""
    rec, index, read = row_groups_log(tmp_path, monkeypatch)
    read_window(index, ["c0"], 100.0, 130.0)  # row groups 6, 7, 8
    windows.forget_blocks_before(index, 125.0)  # a next window starting at 125 s: group 6 goes
    read.clear()
    read_window(index, ["c0"], 100.0, 110.0)
    assert sorted(set(read)) == [6]  # dropped, though the cache (CACHE_BLOCKS = 3) had kept it
    read.clear()
    got = read_window(index, ["c0"], 125.0, 150.0)  # groups 7 and 8 kept, 9 decoded
    assert sorted(set(read)) == [9]
    np.testing.assert_array_equal(got.channels["c0"].values, rec.channels["c0"].values[78125:93751])
    windows.forget_blocks_before(index, float("inf"))  # every block of the file
    read.clear()
    read_window(index, ["c0"], 125.0, 130.0)
    assert sorted(set(read)) == [7, 8]


def csv_parses(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The first rows of the CSV blocks parsed from now on (the block cache emptied), in the order parsed."""
    parsed: list[int] = []
    original = windows._csv_block

    def counting(index_: FileIndex, block: windows.Block):
        parsed.append(block.row0)
        return original(index_, block)

    monkeypatch.setattr(windows, "_csv_block", counting)
    windows.clear_cache()
    return parsed


def test_csv_window_parses_only_the_blocks_it_overlaps(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    n, fs = 5000, 100.0
    t = np.arange(n) / fs
    path = tmp_path / "log.csv"
    write_recording(Recording.from_channels([Channel("a", "m", np.cos(t), t)]), path)
    index = index_file(path, block_rows=500)  # 10 blocks of 5 s
    parsed = csv_parses(monkeypatch)
    got = read_window(index, ["a"], 12.0, 17.5)
    assert parsed == [1000, 1500]
    assert got.channels["a"].lines[0] == 1202  # row 1200 (12 s): header on line 1, row 0 on line 2


@pytest.mark.parametrize("blocks, kept", [(2, True), (windows.CACHE_BLOCKS + 2, False)])
def test_a_csv_of_few_blocks_is_parsed_once_for_its_time_bases_and_its_windows(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, blocks: int, kept: bool
) -> None:
    """The plan's time bases decode every block; a file of at most CACHE_BLOCKS blocks keeps them for the windows
    read next (the demo's CSVs were parsed twice: 15 % of its run), a longer one does not (memory per file bounded)."""
    n, fs = 100 * blocks, 100.0
    t = np.arange(n) / fs
    slow = Channel("s", "deg", np.sin(t[::4]), t[::4])  # another time base: empty cells between its samples
    path = tmp_path / "log.csv"
    write_recording(Recording.from_channels([Channel("a", "m", np.cos(t), t), slow]), path)
    index = index_file(path, block_rows=100)
    parsed = csv_parses(monkeypatch)
    bases = time_bases(index, ["a", "s"])
    assert sorted(len(b[1]) for b in bases) == [len(slow.time), n]
    got = read_window(index, ["a", "s"], 0.0, t[-1])
    want = read_recording(path, channels=["a", "s"])
    for name in ("a", "s"):
        np.testing.assert_array_equal(got.channels[name].values, want.channels[name].values)
        np.testing.assert_array_equal(got.channels[name].time, want.channels[name].time)
    assert sorted(parsed) == sorted([100 * i for i in range(blocks)] * (1 if kept else 2))


@needs_pyarrow
def test_changed_file_is_refused(tmp_path: Path) -> None:
    t = np.arange(100) / 10.0
    rec = Recording.from_channels([Channel("a", "m", t * 2, t)])
    path = tmp_path / "log.parquet"
    write_recording(rec, path)
    index = index_file(path)
    rec2 = Recording.from_channels([Channel("a", "m", t * 3, t)])
    write_recording(rec2, path)  # same size, most likely; another modification time
    st_ = path.stat()
    os.utime(path, ns=(st_.st_atime_ns, index.mtime_ns + 1_000_000))
    with pytest.raises(FileFormatError, match=r"changed since it was indexed.*index it again"):
        read_window(index, ["a"], 0.0, 1.0)
    with pytest.raises(FileFormatError, match="changed since it was indexed"):
        next(iter_blocks(index, ["a"]))


def test_errors_name_the_file_and_what_to_do(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    write_csv_text(path, np.arange(10) / 10, [("a", "m", np.arange(10.0), None)], units="header", decimal=".")
    index = index_file(path, block_rows=4)
    with pytest.raises(MissingChannelError, match=r"log\.csv.*'b'"):
        read_window(index, ["b"], 0, 1)
    with pytest.raises(MissingChannelError):
        index_file(path, channels=["a", "zz"])
    with pytest.raises(TypeError, match="unknown option"):
        index_file(path, sheet=2)
    with pytest.raises(ValueError, match="NaN"):
        read_window(index, ["a"], float("nan"), 1)
    bad = tmp_path / "bad.csv"
    bad.write_text("time,a\n0,1\n0.1,x\n0.2,3\n", encoding="utf-8")
    # A bad cell is the whole-file reader's error: when a window reads it (only the time column is parsed
    # by the index), or at once in the time column.
    bad_index = index_file(bad)
    for read in (lambda: read_window(bad_index, ["a"], 0.1, 0.1), lambda: read_recording(bad)):
        with pytest.raises(FileFormatError, match=r"bad\.csv, line 3, column 2 \('a'\): cannot read 'x'"):
            read()
    bad.write_text("time,a\n0,1\n,2\n", encoding="utf-8")
    with pytest.raises(FileFormatError, match=r"bad\.csv, line 3: the time column 'time' is empty"):
        index_file(bad)
    old_mac = tmp_path / "mac.csv"
    old_mac.write_bytes(b"time,a\r0,1\r0.1,2\r")
    with pytest.raises(FileFormatError, match="carriage return"):
        index_file(old_mac)
    path.unlink()
    with pytest.raises(FileNotFoundError, match=r"log\.csv"):
        read_window(index, ["a"], 0, 1)


# --------------------------------------------------------------------------------------------------------------------
# MDF and MAT


@needs_asammdf
@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(fast=stamps(), k=st.integers(2, 5), seed=st.integers(0, 2**32 - 1), data=st.data())
def test_mdf_two_groups_windows_and_blocks_equal_the_whole_file(
    fast: np.ndarray, k: int, seed: int, data: st.DataObject
) -> None:
    rng = np.random.default_rng(seed)
    n = fast.size
    slow = np.arange(0, n, k) * 0.0123 + 0.003  # another rate, another group
    rec = Recording.from_channels(
        [
            Channel("ax", "m/s^2", values_for(n, seed), fast),
            Channel("gear", "", rng.integers(0, 6, size=n).astype(np.float64), fast),
            Channel("h", "mm", values_for(slow.size, seed + 1), slow),
        ]
    )
    wins = data.draw(window_list(np.concatenate([fast, slow])))
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "log.mf4"
        write_recording(rec, path)
        index = check_windows_and_blocks(path, ["ax", "gear", "h"], wins, block_rows=data.draw(st.integers(1, 40)))
        assert {b.group for b in index.blocks} == {0, 1}


@needs_asammdf
def test_mdf_names_in_several_groups_and_one_group_indexed(tmp_path: Path) -> None:
    t1, t2 = np.arange(50) / 100.0, np.arange(20) / 40.0
    rec = Recording.from_channels([Channel("v", "m/s", t1 * 3, t1), Channel("w", "", t2 + 1, t2)])
    path = tmp_path / "log.mf4"
    write_recording(rec, path)
    index = index_file(path, channels=["w"], block_rows=8)
    assert index.names == ("w",) and {b.group for b in index.blocks} == {1}
    check_windows_and_blocks(path, ["v", "w"], [(0.1, 0.3), (0.0, 0.0)], block_rows=8)


def test_mat_is_read_whole_and_sliced(tmp_path: Path) -> None:
    t1, t2 = np.arange(60) / 100.0, np.arange(13) / 20.0
    rec = Recording.from_channels([Channel("v", "m/s", np.cos(t1), t1), Channel("w", "deg", t2 * 3, t2)])
    path = tmp_path / "log.mat"
    write_recording(rec, path)
    index = check_windows_and_blocks(path, ["v", "w"], [(0.1, 0.3), (0.05, 0.05), (0.7, 0.9), (-1, 0)])
    assert len(index.blocks) == 1


def write_v73(path: Path, t: np.ndarray, roll: np.ndarray, brake: np.ndarray, wheel_t_ms: np.ndarray) -> None:
    """A MATLAB v7.3 file as MATLAB lays it out (HDF5, dimensions reversed, MATLAB_class attributes)."""
    import h5py

    def put(where, name, data, cls):
        where[name] = data
        where[name].attrs["MATLAB_class"] = np.bytes_(cls)

    def text(where, name, value):
        put(where, name, np.array([[ord(c)] for c in value], dtype=np.uint16), "char")

    with h5py.File(path, "w", userblock_size=512) as fh:
        put(fh, "time", t[None, :], "double")  # a column vector, n x 1 in MATLAB
        put(fh, "roll", roll[None, :], "double")
        put(fh, "brake", brake.astype(np.uint8)[:, None], "logical")  # a row vector
        wheel = fh.create_group("wheel")
        wheel.attrs["MATLAB_class"] = np.bytes_("struct")
        put(wheel, "time", wheel_t_ms[None, :], "double")
        put(wheel, "values", np.cos(wheel_t_ms)[None, :], "double")
        text(wheel, "unit", "kN")
        text(wheel, "time_unit", "ms")
        units = fh.create_group("units")
        units.attrs["MATLAB_class"] = np.bytes_("struct")
        text(units, "roll", "deg")
        text(units, "time", "s")
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".ljust(116, b" ")
    with open(path, "r+b") as fh:
        fh.write(header + b"\0" * 8 + b"\x00\x02" + b"IM")


@pytest.mark.skipif(not HAVE_H5PY, reason="h5py not installed")
@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(t=stamps(), data=st.data())
def test_mat_v73_windows_read_slices_equal_the_whole_file(t: np.ndarray, data: st.DataObject) -> None:
    seed = data.draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    wheel_ms = np.sort(rng.uniform(-500, 4000, size=data.draw(st.integers(2, 40))))
    wins = data.draw(window_list(np.concatenate([t, wheel_ms / 1e3])))
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "log.mat"
        write_v73(path, t, values_for(t.size, seed), rng.random(t.size) < 0.5, wheel_ms)
        if t.size < 2:  # a 1-sample vector is a scalar to MATLAB (metadata): not a channel
            return
        rows = data.draw(st.integers(1, 9))
        index = check_windows_and_blocks(path, ["roll", "brake", "wheel"], wins, block_rows=rows)
        assert index.info("h5") is not None  # read in slices, not whole
        assert {b.group for b in index.blocks} == {0, 1}


# --------------------------------------------------------------------------------------------------------------------
# URLs through fsspec (optional)


@pytest.mark.skipif(not (HAVE_FSSPEC and HAVE_PYARROW and HAVE_ASAMMDF), reason="fsspec, pyarrow or asammdf missing")
@pytest.mark.parametrize("ext", ["csv", "parquet", "mf4"])
def test_urls_read_through_fsspec_as_local_files(tmp_path: Path, ext: str) -> None:
    import fsspec

    t1, t2 = np.arange(300) / 100.0, np.arange(40) / 13.0
    rec = Recording.from_channels([Channel("v", "m/s", np.sin(t1), t1), Channel("w", "deg", t2 * 3, t2)])
    local = tmp_path / f"log.{ext}"
    write_recording(rec, local)
    memory = f"memory://windows-test/{tmp_path.name}/log.{ext}"
    fs = fsspec.filesystem("memory")
    fs.pipe(memory.removeprefix("memory://"), local.read_bytes())
    for url in (memory, local.as_uri()):
        windows.clear_cache()
        want_index = index_file(local, block_rows=32)
        index = index_file(url, block_rows=32)
        assert index.path == url and index.blocks == want_index.blocks
        for t0, t1 in ((0.5, 1.2), (2.0, 9.0), (-1.0, 0.0)):
            got, want = read_window(index, ["v", "w"], t0, t1), read_window(want_index, ["v", "w"], t0, t1)
            for n in ("v", "w"):
                assert_same_channel(got.channels[n], want.channels[n])
        for got, want in zip(iter_blocks(index, ["w"]), iter_blocks(want_index, ["w"]), strict=True):
            assert_same_channel(got.channels["w"], want.channels["w"])
    index = index_file(memory)
    fs.pipe(memory.removeprefix("memory://"), local.read_bytes() + b"\n")  # rewritten, one byte longer
    with pytest.raises(FileFormatError, match="changed since it was indexed"):
        read_window(index, ["v"], 0.0, 1.0)


@pytest.mark.skipif(not HAVE_FSSPEC, reason="fsspec not installed")
def test_mat_url_is_refused_with_what_to_do(tmp_path: Path) -> None:
    t = np.arange(5) / 10
    local = tmp_path / "log.mat"
    write_recording(Recording.from_channels([Channel("v", "m/s", t, t)]), local)
    with pytest.raises(FileFormatError, match=r"local path only.*copy the file"):
        index_file(local.as_uri())


# --------------------------------------------------------------------------------------------------------------------
# speed


def test_windows_of_a_parquet_file_decode_each_row_group_about_once(tmp_path: Path, monkeypatch) -> None:
    """60 s windows overlapping by 5 s over 20 min of 20 channels at 625 Hz (12 row groups of dynid's 65536 rows):
    the cache serves the overlaps, so each row group's column is decoded once, as by one whole read. (Counted,
    not timed: a wall-clock bound fails on a busy machine; benchmarks/bench_fleet.py times the reading.)"""
    import pyarrow.parquet as pq

    n, fs = 750_000, 625.0
    t = np.arange(n) / fs
    rng = np.random.default_rng(0)
    rec = Recording.from_channels([Channel(f"c{k}", "m", rng.normal(size=n), t) for k in range(20)])
    path = tmp_path / "long.parquet"
    write_recording(rec, path)
    names = list(rec.channels)
    del rec
    groups = pq.ParquetFile(path).metadata.num_row_groups
    assert groups == -(-n // 65536)
    decoded: dict[tuple, int] = {}
    real = pq.ParquetFile.read_row_group

    def counting(self, i, columns=None, **kw):
        for c in columns or ["*"]:
            decoded[i, c] = decoded.get((i, c), 0) + 1
        return real(self, i, columns=columns, **kw)

    windows.clear_cache()
    index = index_file(path)
    monkeypatch.setattr(pq.ParquetFile, "read_row_group", counting)
    t0 = 0.0
    while t0 < n / fs:
        read_window(index, names, t0, t0 + 60.0)
        t0 += 55.0
    assert {c for _, c in decoded} == {"time", *names}
    assert len(decoded) == groups * (len(names) + 1) and max(decoded.values()) == 1, decoded


# --------------------------------------------------------------------------------------------------------------------
# Parquet footers parsed once per process while the file is unchanged


def footer_parses(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The files whose footer pyarrow parses from now on (a `ParquetFile` opened without `metadata`), in order."""
    import pyarrow.parquet as pq

    parsed: list[str] = []
    real = pq.ParquetFile.__init__

    def counting(self, source, *args, metadata=None, **kw):
        if metadata is None:
            parsed.append(os.fspath(source))
        real(self, source, *args, metadata=metadata, **kw)

    monkeypatch.setattr(pq.ParquetFile, "__init__", counting)
    windows.clear_cache()
    return parsed


def small_log(path: Path, seed: int, n: int = 1000, row_group_size: int = 300,
              compression: str = "snappy") -> Recording:
    import pyarrow as pa
    import pyarrow.parquet as pq

    t = np.arange(n) / 100.0
    rng = np.random.default_rng(seed)
    cols = {"time": t, "a": rng.normal(size=n), "b": rng.normal(size=n)}
    pq.write_table(pa.table(cols), path, row_group_size=row_group_size, compression=compression)
    return read_recording(path)


@needs_pyarrow
def test_a_parquet_footer_is_parsed_once_while_the_file_is_unchanged(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """Oracle: pyarrow's own footer parses, counted (a `ParquetFile` opened without metadata), and the whole-file
    reader for the windows' samples. Before, every window's row groups and every stamps' read opened the file
    and parsed its footer anew: 8 parses here."""
    path = tmp_path / "log.parquet"
    whole = small_log(path, seed=1)
    parsed = footer_parses(monkeypatch)
    index = index_file(path)
    assert time_bases(index, ["a", "b"])[0][1].size == 1000
    for k in range(20):
        t0 = 0.4 * k
        got = read_window(index, ["a", "b"], t0, t0 + 1.5)
        keep = (whole.channels["a"].time >= t0) & (whole.channels["a"].time <= t0 + 1.5)
        for n in ("a", "b"):
            assert_same_channel(got.channels[n], whole.channels[n], keep)
        windows.forget_blocks_before(index, t0 + 0.4)  # each window decodes again: the file is opened each time
    stamps = windows.stamp_rows(index, 10, 990, store=False)
    np.testing.assert_array_equal(bits(stamps), bits(whole.channels["a"].time[10:990]))
    assert parsed == [str(path)]
    windows.clear_cache()  # forgets the footers too
    read_window(index, ["a"], 0.0, 1.0)
    assert parsed == [str(path)] * 2


@needs_pyarrow
@pytest.mark.parametrize("how", ["in place, same size, new mtime", "replaced by a rename, another layout"])
def test_a_rewritten_parquet_file_is_read_anew(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, how: str) -> None:
    """Oracle: the whole-file reader on the new file. A file written over in place keeps its inode; with the same
    shape and no compression it keeps its size too: its modification time alone tells the new content (set 1 s on,
    as a logger's rewrite within the clock's tick would not). A stale footer would give the old row groups' layout
    (the renamed file's: 250 rows, not 300) and the old statistics."""
    path = tmp_path / "log.parquet"
    in_place = how.startswith("in place")
    small_log(path, seed=1, compression="none")
    parsed = footer_parses(monkeypatch)
    old = index_file(path)
    read_window(old, ["a"], 0.0, 5.0)
    size, mtime = path.stat().st_size, path.stat().st_mtime_ns
    if in_place:
        new = small_log(path, seed=2, compression="none")
        os.utime(path, ns=(mtime, mtime + 1_000_000_000))
        assert path.stat().st_size == size
    else:
        small_log(tmp_path / "next.parquet", seed=2, row_group_size=250)
        os.replace(tmp_path / "next.parquet", path)
        new = read_recording(path)
    parsed.clear()  # (the whole-file reader parses it too)
    index = index_file(path)
    assert parsed == [str(path)]  # the new file's footer
    assert [b.rows for b in index.blocks] == ([300, 300, 300, 100] if in_place else [250] * 4)
    got = read_window(index, ["a", "b"], 0.0, 10.0)
    for n in ("a", "b"):
        assert_same_channel(got.channels[n], new.channels[n])
    with pytest.raises(FileFormatError, match="changed since it was indexed"):
        read_window(old, ["a"], 0.0, 5.0)


@needs_pyarrow
def test_the_kept_footers_are_a_few_files_least_recently_used_out_first(tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """Oracle: the count of footer parses. FOOTER_FILES files stay; one more drops the one read longest ago."""
    keep = windows.FOOTER_FILES
    paths = [tmp_path / f"log{k}.parquet" for k in range(keep + 3)]
    for k, p in enumerate(paths):
        small_log(p, seed=k)
    parsed = footer_parses(monkeypatch)
    indexes = [index_file(p) for p in paths[:keep]]
    read_window(indexes[0], ["a"], 0.0, 1.0)  # log0 the most recently used now, log1 the least
    assert len(parsed) == keep and len(windows._footers) == keep
    for p in paths[keep:]:
        index_file(p)
        assert len(windows._footers) == keep
    parsed.clear()
    with windows._lock:
        windows._cache.clear()  # decoded blocks gone, footers kept: the windows below open their files
        windows._recent.clear()
        windows._used[0] = 0
    read_window(index_file(paths[-1]), ["a"], 0.0, 1.0)  # kept
    assert parsed == []
    read_window(indexes[1], ["a"], 0.0, 1.0)  # log1 was dropped first; log0 was read after it, but 3 more came
    assert parsed == [str(paths[1])]
    assert len(windows._footers) == keep


@needs_pyarrow
@pytest.mark.parametrize("cut", [False, True])
def test_windows_read_by_two_threads_share_the_footers(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                       cut: bool) -> None:
    """Oracle: the whole-file reader. Two threads read windows of more files than the footers kept, in turn, so
    footers are added and dropped while the other thread reads: every window holds its file's samples (cut: the
    footers kept cut per row group, `FOOTER_WHOLE`)."""
    from concurrent.futures import ThreadPoolExecutor

    if cut:
        monkeypatch.setattr(windows, "FOOTER_WHOLE", 0, raising=False)

    paths = [tmp_path / f"log{k}.parquet" for k in range(windows.FOOTER_FILES + 2)]
    wholes = [small_log(p, seed=k) for k, p in enumerate(paths)]
    windows.clear_cache()
    indexes = [index_file(p) for p in paths]

    def check(job: int) -> None:
        k = job % len(paths)
        t0 = 0.37 * (job % 23)
        got = read_window(indexes[k], ["a", "b"], t0, t0 + 1.0)
        time = wholes[k].channels["a"].time
        for n in ("a", "b"):
            assert_same_channel(got.channels[n], wholes[k].channels[n], (time >= t0) & (time <= t0 + 1.0))

    with ThreadPoolExecutor(2) as pool:
        list(pool.map(check, range(200)))
    assert len(windows._footers) <= windows.FOOTER_FILES


def many_groups_log(path: Path, groups: int, channels: int = 3, rows: int = 100) -> list[str]:
    """A Parquet log of `groups` row groups of `rows` rows at 100 Hz: a float time column, `channels` float
    channels c0.., the last with nulls (a second time base), a timestamp and a boolean channel. Its channels."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    n = groups * rows
    rng = np.random.default_rng(groups)
    cols = {"time": pa.array(np.arange(n) / 100.0)}
    for k in range(channels):
        cols[f"c{k}"] = pa.array(rng.normal(size=n), mask=(rng.random(n) < 0.3) if k == channels - 1 else None)
    start = np.datetime64("2024-05-01T10:00:00", "ns").astype(np.int64)
    cols["gps"] = pa.array(start + np.arange(n) * 10_000_000 + 3, type=pa.timestamp("ns"))
    cols["brake"] = pa.array(rng.random(n) < 0.5)
    pq.write_table(pa.table(cols), path, row_group_size=rows)
    return [c for c in cols if c != "time"]


@needs_pyarrow
def test_a_footer_kept_cut_per_row_group_reads_what_the_whole_file_holds(tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """Oracle: the whole-file reader, bit for bit. A file of 13 row groups (nulls: two time bases; a timestamp and
    a boolean channel) whose footer is kept cut per row group (`FOOTER_WHOLE` 0): windows inside a group, across
    groups and over the whole file, the blocks, the time bases and the plan's stamps a block at a time."""
    from dynid.io import parquet_format

    monkeypatch.setattr(windows, "FOOTER_WHOLE", 0, raising=False)
    path = tmp_path / "log.parquet"
    names = many_groups_log(path, 13)
    index = check_windows_and_blocks(path, names, [(0.0, 0.5), (0.37, 2.71), (9.99, 10.01), (-1.0, 99.0)])
    (kept,) = windows._footers.values()
    assert isinstance(kept[0], parquet_format.SplitFooter)  # the cut footer was the one read through
    whole = read_recording(path, channels=["c0"])
    np.testing.assert_array_equal(bits(windows.stamp_rows(index, 150, 1201)), bits(whole.channels["c0"].time[150:1201]))
    assert windows.one_time_base(index, ["c0", "c1"]) and not windows.one_time_base(index, names)


@needs_pyarrow
def test_what_is_kept_of_a_long_files_footer_does_not_grow_with_its_row_groups(tmp_path: Path,
                                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """Oracle: the bytes of what the process keeps for the file, pickled (a parsed footer pickles to its Thrift
    bytes, ~1/8 of its memory), for a file of 2 and of 8 row groups of 20 channels. Before, the parsed footer was
    kept whole: ~2 kB more per row group here, 1.9 MB an hour of a car's 60 channels at 625 Hz (a long log's
    identification's peak growing with its length); cut per row group, two offsets and a count per group."""
    monkeypatch.setattr(windows, "FOOTER_WHOLE", 0, raising=False)
    kept = []
    for groups in (2, 8):
        path = tmp_path / f"log{groups}.parquet"
        many_groups_log(path, groups, channels=20)
        windows.clear_cache()
        read_window(index_file(path), ["c0", "c19"], 0.5, 1.5)
        (entry,) = windows._footers.values()
        kept.append(len(pickle.dumps(entry[0])))
    # 3 int64 a row group (its bytes' start and end, its rows), and a few bytes of pickle's framing over the 6
    assert (kept[1] - kept[0]) / 6 <= 3 * 8 + 4, kept


@needs_pyarrow
def test_a_cut_footers_row_group_written_over_in_place_is_a_clear_error(tmp_path: Path,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """Oracle: the file's own bytes. A footer kept cut per row group reads a group's footer bytes again at each open:
    written over in place with its size and modification time kept (what the cache's key cannot see), they no longer
    parse. Before, pyarrow's OSError ("Couldn't deserialize thrift") came out naming no file; now a
    `FileFormatError` naming the file and the row group."""
    monkeypatch.setattr(windows, "FOOTER_WHOLE", 0)
    path = tmp_path / "log.parquet"
    many_groups_log(path, 10)
    windows.clear_cache()
    index = index_file(path)
    read_window(index, ["c0"], 0.0, 0.5)
    (kept,) = windows._footers.values()
    a, b = (int(x) for x in kept[0].spans[5])
    st = path.stat()
    with open(path, "r+b") as fh:
        fh.seek(kept[0].start + a)
        fh.write(b"\xff" * (b - a))
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    with pytest.raises(FileFormatError, match=re.escape(f"{path}: row group 5's footer no longer reads")):
        read_window(index, ["c0"], 5.1, 5.2)


@needs_pyarrow
@pytest.mark.parametrize("cut", [False, True])
def test_a_damaged_page_is_named_by_its_row_group_in_the_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                               cut: bool) -> None:
    """Oracle: pyarrow's own metadata, where c0's data page of row group 5 starts (its header overwritten). The
    error names row group 5, whether the footer is kept whole or cut per row group (`FOOTER_WHOLE` 0). Before, the
    cut footer's error named "row group 0": the group's number in its own one-group footer."""
    import pyarrow.parquet as pq

    if cut:
        monkeypatch.setattr(windows, "FOOTER_WHOLE", 0)
    path = tmp_path / "log.parquet"
    many_groups_log(path, 10)
    meta = pq.read_metadata(path)
    chunk = meta.row_group(5).column(meta.schema.names.index("c0"))
    with open(path, "r+b") as fh:
        fh.seek(chunk.dictionary_page_offset or chunk.data_page_offset)
        fh.write(b"\xff" * 16)
    windows.clear_cache()
    index = index_file(path)  # reads the time column only
    read_window(index, ["c0"], 0.0, 0.5)
    with pytest.raises(FileFormatError, match=re.escape(f"{path}: row group 5, column(s) c0: not readable")):
        read_window(index, ["c0"], 5.1, 5.2)


@needs_pyarrow
def test_the_time_bases_of_a_file_with_a_struct_column(tmp_path: Path) -> None:
    """Oracle: the whole-file reader. A struct column (a position's x and y: two Parquet leaf columns, one Arrow
    field, not a channel) before the channels: the time bases and whether they are one read from the right
    column's statistics. Before, the leaf columns were looked up by the Arrow fields' positions: IndexError."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    n = 1000
    rng = np.random.default_rng(3)
    pos = pa.array([{"x": float(i), "y": -float(i)} for i in range(n)])
    table = pa.table({"time": np.arange(n) / 100.0, "pos": pos, "a": rng.normal(size=n),
                      "b": pa.array(rng.normal(size=n), mask=rng.random(n) < 0.3)})
    path = tmp_path / "log.parquet"
    pq.write_table(table, path, row_group_size=300)
    whole = read_recording(path)
    index = index_file(path)
    assert windows.one_time_base(index, ["a"]) and not windows.one_time_base(index, ["a", "b"])
    for names in (["a"], ["a", "b"]):
        bases = time_bases(index, names)
        for n_ in names:
            (home,) = [b for b in bases if n_ in b[0]]
            np.testing.assert_array_equal(bits(home[1]), bits(whole.channels[n_].time))
