"""Tests of dynid.io: measurement files, units, channel maps, alignment and data checks.

Oracles (none is the code under test run a second time):
- round trips: what is written is known exactly (the synthetic recording), so the
  channels read back must equal it bit for bit (floats are written exactly);
- units: conversion factors computed by hand from their definitions (pi/180 rad per
  degree, 1/3.6 m/s per km/h, 9.80665 m/s^2 per g, 0.44704 m/s per mph, 2 pi/60 rad/s
  per rpm, ...);
- alignment: closed-form signals (sines, a ramp) sampled on known clocks, with the
  interpolation error bounds of cubic splines (h^4) and straight lines (exact on a ramp);
- data checks: crafted files with the fault at a known line, channel and sample, whose
  messages must name them.
"""

from __future__ import annotations

import importlib.util
import math
import os
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dynid.io import (
    STANDARD_GRAVITY,
    Channel,
    ChannelMap,
    DataError,
    FileFormatError,
    GapError,
    MappingError,
    MissingChannelError,
    MissingDependencyError,
    Recording,
    RecordTooShortError,
    SaturationWarning,
    TimeBaseError,
    UnitOverrideWarning,
    UnknownUnitError,
    check_length,
    read_recording,
    to_si,
    unit_factor,
    write_recording,
)
from dynid.signals import border_samples

HAVE_PYARROW = importlib.util.find_spec("pyarrow") is not None
HAVE_ASAMMDF = importlib.util.find_spec("asammdf") is not None
HAVE_H5PY = importlib.util.find_spec("h5py") is not None

FORMATS = [
    pytest.param("csv", id="csv"),
    pytest.param("parquet", id="parquet", marks=pytest.mark.skipif(not HAVE_PYARROW, reason="pyarrow not installed")),
    pytest.param("mat", id="mat"),
    pytest.param("mf4", id="mf4", marks=pytest.mark.skipif(not HAVE_ASAMMDF, reason="asammdf not installed")),
]

DEG = math.pi / 180.0
KMH = 1.0 / 3.6


def multirate() -> Recording:
    """A synthetic car log: inertial unit at 625 Hz, speed at 100 Hz, clearance at 200 Hz starting late."""
    t_imu = np.arange(1250) / 625.0  # 0 .. 1.9984 s
    t_speed = np.arange(201) / 100.0  # 0 .. 2 s
    t_clear = 0.0125 + np.arange(390) / 200.0  # 0.0125 .. 1.9575 s
    rng = np.random.default_rng(7)
    return Recording.from_channels(
        [
            Channel(
                "roll", "deg", 2.0 * np.sin(2 * np.pi * 0.8 * t_imu) + 1e-3 * rng.standard_normal(t_imu.size), t_imu
            ),
            Channel("yaw_rate", "deg/s", 5.0 * np.cos(2 * np.pi * 0.5 * t_imu), t_imu),
            Channel("speed", "km/h", 90.0 + 2.0 * np.sin(2 * np.pi * 0.3 * t_speed), t_speed),
            Channel("z9", "mm", 120.0 + 8.0 * np.sin(2 * np.pi * 1.1 * t_clear), t_clear),
        ],
        metadata={"test": "sine steering 90 km/h", "seed": "7"},
    )


# ---------------------------------------------------------------------------------------------
# Units


@pytest.mark.parametrize(
    ("unit", "factor", "si"),
    [
        ("rad", 1.0, "rad"),
        ("deg", math.pi / 180, "rad"),
        ("°", math.pi / 180, "rad"),
        ("deg/s", math.pi / 180, "rad/s"),
        ("°/s", math.pi / 180, "rad/s"),
        ("rad/s", 1.0, "rad/s"),
        ("rpm", 2 * math.pi / 60, "rad/s"),
        ("rev/s", 2 * math.pi, "rad/s"),
        ("tr/s", 2 * math.pi, "rad/s"),
        ("m", 1.0, "m"),
        ("mm", 0.001, "m"),
        ("cm", 0.01, "m"),
        ("km", 1000.0, "m"),
        ("m/s", 1.0, "m/s"),
        ("km/h", 1 / 3.6, "m/s"),
        ("mph", 1609.344 / 3600, "m/s"),
        ("m/s²", 1.0, "m/s^2"),
        ("m/s^2", 1.0, "m/s^2"),
        ("m/s2", 1.0, "m/s^2"),
        ("g", 9.80665, "m/s^2"),
        ("N", 1.0, "N"),
        ("kN", 1000.0, "N"),
        ("daN", 10.0, "N"),
        ("N·m", 1.0, "N*m"),
        ("Nm", 1.0, "N*m"),
        ("N.m", 1.0, "N*m"),
        ("N*m", 1.0, "N*m"),
        ("N m", 1.0, "N*m"),
        ("kN·m", 1000.0, "N*m"),
        ("kg", 1.0, "kg"),
        ("s", 1.0, "s"),
        ("ms", 0.001, "s"),
        ("Hz", 1.0, "Hz"),
        ("bar", 1e5, "Pa"),
        ("Pa", 1.0, "Pa"),
        ("%", 0.01, "1"),
        ("-", 1.0, "1"),
        ("", 1.0, "1"),
        ("[deg]", math.pi / 180, "rad"),
        ("KM/H", 1 / 3.6, "m/s"),
        ("deg/sec", math.pi / 180, "rad/s"),
    ],
)
def test_unit_table_matches_hand_factors(unit: str, factor: float, si: str) -> None:
    values = np.array([0.0, 1.0, -2.5, 1234.5])
    out, got_si = to_si(values, unit)
    assert got_si == si
    np.testing.assert_allclose(out, values * factor, rtol=1e-15, atol=0)
    assert values[1] == 1.0  # the input is not scaled in place


def test_standard_gravity_is_the_defined_value() -> None:
    assert STANDARD_GRAVITY == 9.80665


def test_unknown_unit_names_channel_unit_and_known_units() -> None:
    with pytest.raises(UnknownUnitError) as info:
        to_si([1.0], "furlong/fortnight", channel="speed_raw", source="test.csv")
    msg = str(info.value)
    assert "test.csv" in msg and "'speed_raw'" in msg and "'furlong/fortnight'" in msg
    for known in ("deg", "km/h", "N*m", "rpm", "bar", "%"):
        assert known in msg
    assert info.value.unit == "furlong/fortnight" and info.value.channel == "speed_raw"
    with pytest.raises(UnknownUnitError, match="Did you mean 'km/h'"):
        unit_factor("km/hh")


# ---------------------------------------------------------------------------------------------
# Round trips


def _assert_same_channels(a: Recording, b: Recording) -> None:
    assert a.names == b.names
    for name in a.names:
        ca, cb = a.channel(name), b.channel(name)
        assert ca.unit == cb.unit, name
        np.testing.assert_array_equal(ca.time, cb.time, err_msg=name)
        np.testing.assert_array_equal(ca.values, cb.values, err_msg=name)


@pytest.mark.parametrize("fmt", FORMATS)
def test_round_trip_keeps_every_channel_on_its_own_time_base(tmp_path: Path, fmt: str) -> None:
    rec = multirate()
    path = tmp_path / f"sine.{fmt}"
    assert write_recording(rec, path) == path
    back = read_recording(path)
    _assert_same_channels(rec, back)
    assert back.metadata["test"] == "sine steering 90 km/h" and back.metadata["seed"] == "7"
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary file left


@pytest.mark.parametrize("fmt", FORMATS)
def test_reading_only_some_channels(tmp_path: Path, fmt: str) -> None:
    """channels= keeps exactly those channels, equal to a whole read's; the rest are named as not read,
    so that a missing-channel error still shows them."""
    rec = multirate()
    path = write_recording(rec, tmp_path / f"sine.{fmt}")
    keep = rec.names[1:3]
    part, whole = read_recording(path, channels=keep), read_recording(path)
    assert part.names == keep
    for n in keep:
        np.testing.assert_array_equal(part.channel(n).values, whole.channel(n).values)
        np.testing.assert_array_equal(part.channel(n).time, whole.channel(n).time)
    assert all("not among the channels asked for" in part.skipped[n] for n in rec.names if n not in keep)
    with pytest.raises(MissingChannelError, match=f"'{rec.names[0]}' \\(in the file but not read: not among"):
        part.require([rec.names[0]])


@st.composite
def sparse_recordings(draw) -> Recording:
    """Channels on random subsets of a common grid, values any floats including NaN and infinities."""
    n = draw(st.integers(3, 25))
    grid = np.cumsum(draw(st.lists(st.floats(1e-6, 10.0), min_size=n, max_size=n))) - 1.0
    chans = []
    for j in range(draw(st.integers(1, 4))):
        keep = np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)))
        keep[j % n] = True  # at least one sample
        vals = draw(st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=n, max_size=n))
        chans.append(
            Channel(f"ch{j}", draw(st.sampled_from(["", "deg", "km/h", "N·m"])), np.array(vals)[keep], grid[keep])
        )
    return Recording.from_channels(chans)


@pytest.mark.parametrize("fmt", [f for f in FORMATS if f.values[0] in ("csv", "parquet")])
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rec=sparse_recordings())
def test_round_trip_of_any_sparse_recording(tmp_path: Path, fmt: str, rec: Recording) -> None:
    """Empty cells (no sample) and NaN cells (a sample whose value is NaN) come back apart, floats bit for bit."""
    back = read_recording(write_recording(rec, tmp_path / f"any.{fmt}"))
    assert back.names == rec.names
    for name in rec.names:
        a, b = rec.channel(name), back.channel(name)
        assert a.unit == b.unit
        np.testing.assert_array_equal(b.time, a.time)
        assert np.array_equal(b.values, a.values, equal_nan=True)
        real = ~np.isnan(a.values)
        assert np.array_equal(np.signbit(b.values[real]), np.signbit(a.values[real]))  # -0.0 stays -0.0


def test_round_trips_give_the_same_aligned_channels(tmp_path: Path) -> None:
    rec = multirate()
    names = ["roll", "yaw_rate", ("speed", "linear"), "z9"]
    reference = rec.aligned(names, fs=250.0)
    formats = ["csv", "mat"] + (["parquet"] if HAVE_PYARROW else []) + (["mf4"] if HAVE_ASAMMDF else [])
    for fmt in formats:
        back = read_recording(write_recording(rec, tmp_path / f"x.{fmt}"))
        got = back.aligned(names, fs=250.0)
        np.testing.assert_array_equal(got.t, reference.t)
        for n in reference.names:
            np.testing.assert_array_equal(got[n], reference[n], err_msg=f"{fmt}: {n}")
    # The common clock lies inside every channel's span (clearance starts late, IMU ends early).
    assert reference.t[0] == 0.0125 and reference.t[-1] <= 1.9575
    assert reference.fs == pytest.approx(250.0)


def test_mf4_keeps_one_group_per_rate(tmp_path: Path) -> None:
    asammdf = pytest.importorskip("asammdf")
    path = write_recording(multirate(), tmp_path / "x.mf4")
    with asammdf.MDF(path) as mdf:
        assert len(mdf.groups) == 3  # 625 Hz (roll, yaw_rate), 100 Hz, 200 Hz
        assert mdf.get("roll").unit == "deg"


def test_csv_layout_written(tmp_path: Path) -> None:
    path = write_recording(multirate(), tmp_path / "x.csv")
    lines = path.read_text().splitlines()
    assert lines[0] == "# test: sine steering 90 km/h"
    assert lines[2] == "time [s],roll [deg],yaw_rate [deg/s],speed [km/h],z9 [mm]"
    assert lines[3].startswith("0.0,") and lines[3].endswith(",")  # z9 has no sample at t = 0


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rec=sparse_recordings(), repeat=st.integers(1, 3))
def test_csv_cells_are_each_value_s_shortest_repr(tmp_path: Path, rec: Recording, repeat: int) -> None:
    """The writer formats each distinct value once (by bit pattern); the text must be the per-cell repr all the
    same: the oracle writes every cell itself, -0.0 as -0.0, NaN of any payload as nan, no sample as empty."""
    chans = [Channel(c.name, c.unit, np.tile(c.values, repeat), np.concatenate(
        [c.time + 1000.0 * k for k in range(repeat)])) for c in rec.channels.values()]  # the grid spans < 250 s
    rec = Recording.from_channels(chans)
    text = write_recording(rec, tmp_path / "any.csv").read_text().splitlines()
    times = np.unique(np.concatenate([c.time for c in chans]))
    rows = []
    for t in times.tolist():
        cells = [repr(t)]
        for c in chans:
            hit = np.flatnonzero(c.time == t)
            cells.append(repr(float(c.values[hit[0]])) if hit.size else "")
        rows.append(",".join(cells))
    assert text[-len(rows):] == rows


def test_csv_cells_keep_signed_zeros_and_the_extremes_apart(tmp_path: Path) -> None:
    """0.0 and -0.0 compare equal but are written apart; NaN of any sign or payload is nan; repr's switches to
    exponent notation (below 1e-4, from 1e16) and the subnormals kept: the text is repr's, cell by cell."""
    special = [0.0, -0.0, np.nan, -np.nan, np.inf, -np.inf, 1e-5, 1e-4, 1e16, 9999999999999998.0, 0.1 + 0.2, 5e-324,
               np.frombuffer(np.array([0x7FF8000000000001], dtype=np.int64).tobytes())[0]]
    values = np.array(special * 3)
    rng = np.random.default_rng(3)
    values = values[rng.permutation(values.size)]
    t = np.arange(values.size) / 8.0
    path = write_recording(Recording.from_channels([Channel("x", "", values, t), Channel("y", "m", -values, t)]),
                           tmp_path / "z.csv")
    expected = [f"{a!r},{float(b)!r},{float(-b)!r}" for a, b in zip(t.tolist(), values, strict=True)]
    assert path.read_text().splitlines()[-values.size:] == expected


# ---------------------------------------------------------------------------------------------
# Same data, different units -> same SI result


def _unit_pair_files(tmp_path: Path, fmt: str) -> tuple[Path, Path, np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(500) / 100.0
    roll_rad = 0.05 * np.sin(2 * np.pi * 0.7 * t)
    speed_ms = 25.0 + np.cos(t)
    acc_ms2 = 3.0 * np.sin(t)
    in_deg = Recording.from_channels(
        [
            Channel("roll", "deg", roll_rad * 180.0 / math.pi, t),
            Channel("speed", "km/h", speed_ms * 3.6, t),
            Channel("ay", "g", acc_ms2 / 9.80665, t),
        ]
    )
    in_rad = Recording.from_channels(
        [Channel("roll", "rad", roll_rad, t), Channel("speed", "m/s", speed_ms, t), Channel("ay", "m/s^2", acc_ms2, t)]
    )
    a = write_recording(in_deg, tmp_path / f"deg.{fmt}")
    b = write_recording(in_rad, tmp_path / f"rad.{fmt}")
    return a, b, roll_rad, speed_ms, acc_ms2


@pytest.mark.parametrize("fmt", FORMATS)
def test_deg_kmh_g_and_rad_ms_files_give_the_same_si_values(tmp_path: Path, fmt: str) -> None:
    a, b, roll, speed, acc = _unit_pair_files(tmp_path, fmt)
    cmap = ChannelMap.from_dict({"phi": "roll", "vx": {"channel": "speed"}, "ay": {"channel": "ay"}})
    si_a = cmap.apply(read_recording(a))
    si_b = cmap.apply(read_recording(b))
    for q, truth in (("phi", roll), ("vx", speed), ("ay", acc)):
        np.testing.assert_allclose(si_a[q][1], truth, rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(si_b[q][1], truth, rtol=1e-14, atol=1e-15)
        np.testing.assert_array_equal(si_a[q][0], si_b[q][0])
    al = cmap.aligned(read_recording(a), fs=50.0)
    assert al.units == {"phi": "rad", "vx": "m/s", "ay": "m/s^2"}


def test_channel_map_scale_offset_sign_and_vector_quantities() -> None:
    t = np.arange(10) * 0.01
    raw = np.linspace(-3.0, 5.0, 10)
    rec = Recording.from_channels(
        [Channel("clear_rl", "mm", raw, t), Channel("J1", "", raw, t), Channel("J2", "", 2 * raw, t)], source="m.csv"
    )
    cmap = ChannelMap.from_dict(
        {
            "z9": {"channel": "clear_rl", "scale": 1.5, "offset": -12.5, "sign": -1},
            "q": {"channels": ["J1", "J2"], "unit": "deg", "sign": [1, -1]},
        }
    )
    out = cmap.apply(rec)
    np.testing.assert_allclose(out["z9"][1], -(1.5 * raw - 12.5) * 1e-3, rtol=1e-15)
    assert out["q"][1].shape == (10, 2)
    np.testing.assert_allclose(out["q"][1][:, 0], raw * DEG, rtol=1e-15)
    np.testing.assert_allclose(out["q"][1][:, 1], -2 * raw * DEG, rtol=1e-15)
    al = cmap.aligned(rec)
    assert al["q"].shape == (10, 2) and al.units["q"] == "rad"
    np.testing.assert_array_equal(al.t, t)


def test_channel_map_errors_name_the_quantity_and_what_to_do(tmp_path: Path) -> None:
    with pytest.raises(MappingError, match=r"quantity 'phi': unknown key\(s\) 'units'"):
        ChannelMap.from_dict({"phi": {"channel": "roll", "units": "deg"}})
    with pytest.raises(MappingError, match="sign must be"):
        ChannelMap.from_dict({"phi": {"channel": "roll", "sign": 2}})
    with pytest.raises(UnknownUnitError, match="'degs'"):
        ChannelMap.from_dict({"phi": {"channel": "roll", "unit": "degs"}})
    t = np.arange(5) * 0.1
    rec = Recording.from_channels([Channel("J1", "", t, t), Channel("v", "m/s", t, t)], source="tx40.csv")
    with pytest.raises(UnknownUnitError, match=r"tx40.csv.*'J1'.*no unit.*add unit"):
        ChannelMap.from_dict({"q": "J1"}).apply(rec)
    with pytest.warns(UnitOverrideWarning, match="'m/s'.*'km/h'"):
        ChannelMap.from_dict({"v": {"channel": "v", "unit": "km/h"}}).apply(rec)
    toml = tmp_path / "ident.toml"
    toml.write_text('[channels]\nphi = { channel = "J1", unit = "deg" }\n', encoding="utf-8")
    cmap = ChannelMap.from_toml(toml)
    np.testing.assert_allclose(cmap.apply(rec)["phi"][1], t * DEG)


# ---------------------------------------------------------------------------------------------
# Readers: layouts


def test_csv_variants_unit_row_parentheses_semicolons_decimal_comma_and_ms(tmp_path: Path) -> None:
    a = tmp_path / "a.csv"
    a.write_text("Time,roll,speed\ns,deg,km/h\n0,1,2\n0.5,3,4\n")
    ra = read_recording(a)
    assert ra.channel("roll").unit == "deg" and ra.channel("speed").unit == "km/h"
    np.testing.assert_array_equal(ra.channel("speed").time, [0.0, 0.5])
    b = tmp_path / "b.csv"
    b.write_text("t (ms);roll (deg);Fz [kN]\n0;1,5;2\n500;2,5;3\n", encoding="utf-8")
    rb = read_recording(b, decimal=",")
    np.testing.assert_array_equal(rb.channel("roll").values, [1.5, 2.5])
    np.testing.assert_array_equal(rb.channel("Fz").time, [0.0, 0.5])  # ms -> s
    assert rb.channel("Fz").unit == "kN"
    c = tmp_path / "c.txt"
    c.write_text("J1,J2\n1,2\n3,4\n5,6\n")
    rc = read_recording(c, fs=5000.0)
    np.testing.assert_array_equal(rc.channel("J2").time, [0.0, 2e-4, 4e-4])
    with pytest.raises(FileFormatError, match=r"c.txt: no time column.*pass fs="):
        read_recording(c)


def test_csv_parsed_in_blocks_keeps_line_numbers(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from dynid.io import csv_format

    monkeypatch.setattr(csv_format, "BLOCK_LINES", 7)
    rows = [f"{k * 0.01!r},{k}.5," + ("" if k % 3 else f"{2 * k}") for k in range(40)]
    rows.insert(20, "")  # a blank line in the middle
    path = tmp_path / "blocks.csv"
    path.write_text("time,a,b\n" + "\n".join(rows) + "\n")
    rec = read_recording(path)
    np.testing.assert_array_equal(rec.channel("a").values, np.arange(40) + 0.5)
    np.testing.assert_array_equal(rec.channel("b").values, 2 * np.arange(0, 40, 3))
    lines_b = rec.channel("b").lines
    expected = [2 + k + (k >= 20) for k in range(0, 40, 3)]
    np.testing.assert_array_equal(lines_b, expected)


def test_parquet_from_other_tools_timestamps_units_and_text_columns(tmp_path: Path) -> None:
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    stamps = np.datetime64("2024-05-02T10:00:00") + np.arange(4) * np.timedelta64(1600, "us")
    table = pa.table(
        {
            "Time": pa.array(stamps, type=pa.timestamp("us")),
            "roll": pa.array([0.0, 1.0, None, 3.0]),
            "gear": pa.array([3, 3, 4, 4], type=pa.int8()),
            "driver": pa.array(["a", "b", "c", "d"]),
        }
    )
    schema = table.schema.set(1, table.schema.field("roll").with_metadata({b"unit": b"deg"}))
    path = tmp_path / "logger.parquet"
    pq.write_table(table.cast(schema), path)
    rec = read_recording(path)
    np.testing.assert_array_equal(rec.channel("gear").time, [0.0, 0.0016, 0.0032, 0.0048])
    np.testing.assert_array_equal(rec.channel("roll").time, [0.0, 0.0016, 0.0048])  # the null is no sample
    assert rec.channel("roll").unit == "deg" and rec.channel("gear").unit == ""
    assert "not numeric" in rec.skipped["driver"] and rec.metadata["Time.start"].startswith("2024-05-02T10:00:00")
    pandas = pytest.importorskip("pandas")
    frame = pandas.DataFrame({"t": [0.0, 0.5, 1.0], "speed": [1.0, 2.0, 3.0]})
    frame.to_parquet(tmp_path / "pandas.parquet")
    np.testing.assert_array_equal(read_recording(tmp_path / "pandas.parquet").channel("speed").time, [0.0, 0.5, 1.0])


def test_mat_struct_channels_units_and_v73(tmp_path: Path) -> None:
    import scipy.io

    t = np.arange(6) * 0.1
    path = tmp_path / "log.mat"
    scipy.io.savemat(
        path,
        {
            "time": t,
            "roll": np.sin(t),
            "units": {"roll": "deg"},
            "wheel": {"time": t[:3], "values": np.ones(3), "unit": "kN"},
            "note": "track A",
            "M": np.ones((6, 2)),
        },
    )
    rec = read_recording(path)
    assert rec.channel("roll").unit == "deg" and rec.channel("wheel").unit == "kN"
    np.testing.assert_array_equal(rec.channel("wheel").time, t[:3])
    assert "matrix" in rec.skipped["M"]
    with pytest.raises(MissingChannelError, match=r"'M' \(in the file but not read: matrix"):
        rec.channel("M")


def _write_v73(path: Path) -> None:
    h5py = pytest.importorskip("h5py")
    with h5py.File(path, "w", userblock_size=512) as fh:
        fh["time"] = (np.arange(4) * 0.5)[None, :]  # MATLAB 1x4, stored transposed
        fh["time"].attrs["MATLAB_class"] = np.bytes_("double")
        fh["roll"] = np.arange(4.0)[None, :]
        fh["roll"].attrs["MATLAB_class"] = np.bytes_("double")
        units = fh.create_group("units")
        units.attrs["MATLAB_class"] = np.bytes_("struct")
        units["roll"] = np.array([[ord(c)] for c in "deg"], dtype=np.uint16)
        units["roll"].attrs["MATLAB_class"] = np.bytes_("char")
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".ljust(116, b" ")
    with open(path, "r+b") as fh:
        fh.write(header + b"\0" * 8 + b"\x00\x02" + b"IM")


@pytest.mark.skipif(not HAVE_H5PY, reason="h5py not installed")
def test_mat_v73_read_through_h5py(tmp_path: Path) -> None:
    path = tmp_path / "new.mat"
    _write_v73(path)
    rec = read_recording(path)
    np.testing.assert_array_equal(rec.channel("roll").values, [0.0, 1.0, 2.0, 3.0])
    np.testing.assert_array_equal(rec.channel("roll").time, [0.0, 0.5, 1.0, 1.5])
    assert rec.channel("roll").unit == "deg"


@pytest.mark.skipif(not HAVE_H5PY, reason="h5py not installed (needed to craft the file)")
def test_mat_v73_without_h5py_says_resave_or_install(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from dynid.io import _optional

    path = tmp_path / "new.mat"
    _write_v73(path)
    real = _optional.importlib.import_module

    def no_h5py(name: str, *args, **kwargs):
        if name.startswith("h5py"):
            raise ImportError("No module named 'h5py'")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(_optional.importlib, "import_module", no_h5py)
    with pytest.raises(MissingDependencyError) as info:
        read_recording(path)
    msg = str(info.value)
    assert "new.mat" in msg and "v7.3" in msg and "pip install h5py (dynid's 'mat73' extra)" in msg and "-v7" in msg


def test_missing_optional_package_names_the_extra(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from dynid.io import _optional

    def nothing(name: str, *args, **kwargs):
        raise ImportError(f"No module named {name!r}")

    monkeypatch.setattr(_optional.importlib, "import_module", nothing)
    with pytest.raises(MissingDependencyError, match=r"Parquet.*pip install pyarrow \(dynid's 'parquet' extra\)"):
        write_recording(multirate(), tmp_path / "x.parquet")
    with pytest.raises(MissingDependencyError, match=r"MDF.*pip install asammdf \(dynid's 'mdf' extra\)"):
        write_recording(multirate(), tmp_path / "x.mf4")
    assert list(tmp_path.iterdir()) == []


def test_mf4_duplicate_names_and_text_channels(tmp_path: Path) -> None:
    asammdf = pytest.importorskip("asammdf")
    t1, t2 = np.arange(10) * 0.1, np.arange(20) * 0.05
    mdf = asammdf.MDF(version="4.10")
    mdf.append([asammdf.Signal(np.ones(10), t1, name="speed", unit="km/h")])
    mdf.append(
        [
            asammdf.Signal(np.zeros(20), t2, name="speed", unit="m/s"),
            asammdf.Signal(np.array([b"on"] * 20), t2, name="state", encoding="utf-8"),
        ]
    )
    path = tmp_path / "dup.mf4"
    mdf.save(path, overwrite=True)
    mdf.close()
    rec = read_recording(path)
    assert set(rec.names) == {"speed@0", "speed@1"}
    assert rec.channel("speed@1").unit == "m/s" and "state" in rec.skipped
    with pytest.raises(MissingChannelError, match=r"'speed' \(close: 'speed@\d', 'speed@\d'\)"):
        rec.channel("speed")


def test_unknown_extension_and_unknown_option(tmp_path: Path) -> None:
    with pytest.raises(FileFormatError, match=r"log.xyz.*'.xyz'.*format="):
        read_recording(tmp_path / "log.xyz")
    path = write_recording(multirate(), tmp_path / "x.csv")
    with pytest.raises(TypeError, match=r"unknown option.*sheet"):
        read_recording(path, sheet=1)
    if HAVE_ASAMMDF:  # an option given as None is "not given", whatever the format
        mf4 = write_recording(multirate(), tmp_path / "x.mf4")
        assert read_recording(mf4, fs=None).names == multirate().names
        with pytest.raises(TypeError, match=r"reading mdf: unknown option\(s\) fs; options of this format: none"):
            read_recording(mf4, fs=625.0)
    with pytest.raises(FileNotFoundError, match=r"nope\.csv"):
        read_recording(tmp_path / "nope.csv")


@pytest.mark.skipif(
    not (Path(__file__).resolve().parents[2].parent / "shared/data/tx40/pos_read_data.csv").exists(),
    reason="shared TX40 data not beside the repository",
)
def test_real_tx40_csv_reads_with_a_sample_rate() -> None:
    path = Path(__file__).resolve().parents[2].parent / "shared/data/tx40/pos_read_data.csv"
    rec = read_recording(path, fs=5000.0)
    assert rec.names == tuple(f"Joint_{j}" for j in range(1, 7))
    assert len(rec.channel("Joint_1")) == 45000 and rec.channel("Joint_6").time[-1] == pytest.approx(8.9998)
    q = ChannelMap.from_dict({"q": {"channels": list(rec.names), "unit": "rad"}}).apply(rec)["q"][1]
    assert q.shape == (45000, 6) and np.isfinite(q).all()


# ---------------------------------------------------------------------------------------------
# Alignment


def test_aligned_cubic_and_linear_against_closed_forms() -> None:
    t_fast = np.arange(0, 2.0, 1 / 500)
    t_slow = 0.003 + np.arange(0, 1.99, 1 / 50)
    rec = Recording.from_channels(
        [Channel("s", "m", np.sin(2 * np.pi * t_fast), t_fast), Channel("ramp", "m", 3.0 * t_slow - 1.0, t_slow)]
    )
    al = rec.aligned({"s": "cubic", "ramp": "linear"}, fs=333.0)
    assert al.t[0] == t_slow[0] and al.t[-1] <= t_slow[-1] and al.fs == pytest.approx(333.0)
    h = 1 / 500
    # not-a-knot cubic: error <= C h^4 max|x''''|, C < 1/16 (interior); x'''' = (2 pi)^4
    assert np.max(np.abs(al["s"] - np.sin(2 * np.pi * al.t))) <= (2 * np.pi) ** 4 * h**4 / 16
    np.testing.assert_allclose(al["ramp"], 3.0 * al.t - 1.0, rtol=0, atol=1e-13)  # linear is exact on a ramp
    t_given = np.array([0.5, 0.75, 1.0])
    np.testing.assert_allclose(rec.aligned(["ramp"], t=t_given)["ramp"], 3.0 * t_given - 1.0, atol=1e-13)
    # neither fs nor t: the fastest channel's own stamps inside the common span, copied as they are
    auto = rec.aligned(["s", ("ramp", "linear")])
    inside = (t_fast >= t_slow[0]) & (t_fast <= t_slow[-1])
    np.testing.assert_array_equal(auto.t, t_fast[inside])
    np.testing.assert_array_equal(auto["s"], rec.channel("s").values[inside])
    np.testing.assert_allclose(auto["ramp"], 3.0 * auto.t - 1.0, rtol=0, atol=1e-13)
    # all on one base: that base, values untouched
    same = rec.aligned(["s"])
    np.testing.assert_array_equal(same.t, t_fast)
    np.testing.assert_array_equal(same["s"], rec.channel("s").values)


def test_aligned_errors_name_the_channel() -> None:
    t = np.arange(100) * 0.01
    late = 5.0 + t
    rec = Recording.from_channels([Channel("a", "m", t, t), Channel("b", "m", t, late)], source="f.csv")
    with pytest.raises(DataError, match=r"f.csv: the channels do not overlap.*'b' starts at 5 s.*'a' ends at 0.99 s"):
        rec.aligned(["a", "b"], fs=100.0)
    with pytest.raises(DataError, match=r"f.csv, channel 'a': covers 0..0.99 s, not the clock asked for"):
        rec.aligned(["a"], t=[0.5, 1.5])
    with pytest.raises(DataError, match="either fs"):
        rec.aligned(["a"], fs=10.0, t=[0.5])
    with pytest.raises(MissingChannelError, match=r"2 channel\(s\) needed.*'A' \(close: 'a'\); 'zz'"):
        rec.aligned(["A", "zz"])


# ---------------------------------------------------------------------------------------------
# Data checks, each triggered by a crafted file


def test_bad_cell_names_file_line_and_column(tmp_path: Path) -> None:
    path = tmp_path / "bad.csv"
    path.write_text("time,roll,speed\n0,1,2\n0.1,1.5,2\n0.2,1.7,x2\n0.3,1.8,2\n")
    with pytest.raises(FileFormatError) as info:
        read_recording(path)
    msg = str(info.value)
    assert "bad.csv, line 4, column 3 ('speed')" in msg and "'x2'" in msg
    assert info.value.line == 4 and info.value.channel == "speed"
    path.write_text("time,roll,speed\n0,1,2\n0.1,1.5\n")
    with pytest.raises(FileFormatError, match=r"bad.csv, line 3: 2 cell\(s\) but the header has 3"):
        read_recording(path)


def test_missing_channel_lists_needed_and_available(tmp_path: Path) -> None:
    path = write_recording(multirate(), tmp_path / "track.csv")
    rec = read_recording(path)
    cmap = ChannelMap.from_dict({"phi": "Roll", "vx": "speed", "z27": "z27_clearance"})
    with pytest.raises(MissingChannelError) as info:
        cmap.apply(rec)
    msg = str(info.value)
    assert "track.csv" in msg and "2 channel(s) needed" in msg
    assert "'Roll' (close: 'roll')" in msg and "'z27_clearance'" in msg
    assert "Needed: Roll, speed, z27_clearance" in msg and "roll, yaw_rate, speed, z9" in msg
    assert info.value.needed == ("Roll", "z27_clearance")


def test_nan_in_values_names_line_channel_sample_and_time(tmp_path: Path) -> None:
    path = tmp_path / "nan.csv"
    rows = [f"{k * 0.01!r},{math.sin(k)!r},{k}" for k in range(30)]
    rows[17] = "0.17,nan,17"
    path.write_text("time,roll [deg],k\n" + "\n".join(rows) + "\n")
    rec = read_recording(path)
    rec.aligned(["k"])  # the other channel is fine
    with pytest.raises(GapError) as info:
        rec.aligned(["roll", "k"])
    msg = str(info.value)
    assert "nan.csv, line 19, channel 'roll', sample 17 (t = 0.17 s)" in msg
    assert info.value.sample == 17 and info.value.line == 19


def test_gap_in_time_stamps(tmp_path: Path) -> None:
    t = np.concatenate([np.arange(50), np.arange(80, 120)]) * 0.01
    rec = Recording.from_channels([Channel("ax", "m/s^2", np.cos(t), t)])
    path = write_recording(rec, tmp_path / "gap.mat")
    with pytest.raises(GapError) as info:
        read_recording(path).check()
    msg = str(info.value)
    assert "gap.mat, channel 'ax', sample 50 (t = 0.8 s)" in msg and "0.31 s between sample 49 (t = 0.49 s)" in msg
    read_recording(path).check(gap_factor=None)  # skipping the gap check is allowed


@pytest.mark.parametrize(("second", "word"), [("0.01", "repeats"), ("0.005", "goes back from")])
def test_duplicated_or_backward_time_stamps(tmp_path: Path, second: str, word: str) -> None:
    path = tmp_path / "clock.csv"
    path.write_text(f"time,a\n0,1\n0.01,2\n{second},3\n0.03,4\n0.04,5\n")
    rec = read_recording(path)
    with pytest.raises(TimeBaseError) as info:
        rec.aligned(["a"], fs=100.0)
    msg = str(info.value)
    assert f"clock.csv, line 4, channel 'a', sample 2 (t = {float(second):g} s)" in msg
    assert f"sample 2 (t = {float(second):g} s, line 4) {word} sample 1 (t = 0.01 s, line 3)" in msg


def test_saturated_channel_is_flagged_with_its_time_span(tmp_path: Path) -> None:
    t = np.arange(400) / 100.0
    force = np.clip(25.0 * np.sin(2 * np.pi * 0.25 * t), -20.0, 20.0)  # a +-20 kN sensor, clipped
    path = write_recording(Recording.from_channels([Channel("Fz_FL", "kN", force, t)]), tmp_path / "wheel.csv")
    rec = read_recording(path)
    # |25 sin(pi t / 2)| >= 20  <=>  t in [a, 2 - a] (at +20) and [2 + a, 4 - a] (at -20), a = 2 asin(0.8) / pi
    a = 2 / math.pi * math.asin(0.8)
    first, last = math.ceil(100 * a), math.floor(100 * (2 - a))
    expected = [(first, last), (first + 200, last + 200)]
    with pytest.warns(SaturationWarning) as record:
        spans = rec.saturation(limits={"Fz_FL": (-20.0, 20.0)})
    msg = str(record[0].message)
    assert "wheel.csv, channel 'Fz_FL'" in msg and "2 span(s)" in msg
    assert f"t = {first / 100:g}..{last / 100:g} s at 20 kN (samples {first}..{last})" in msg
    assert f"t = {(first + 200) / 100:g}..{(last + 200) / 100:g} s at -20 kN" in msg
    assert [(s.first, s.last) for s in spans["Fz_FL"]] == expected
    with pytest.warns(SaturationWarning):
        own = rec.saturation()["Fz_FL"]  # the channel's own extremes as the limits
    assert [(s.first, s.last) for s in own] == expected
    smooth = Recording.from_channels([Channel("s", "m", np.sin(2 * np.pi * t), t)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert smooth.saturation() == {}


def test_record_too_short_for_the_filter() -> None:
    border = border_samples(625.0, 3.0, 6)
    assert check_length(2 * border + 1, 625.0, 3.0, 6) == border
    with pytest.raises(RecordTooShortError) as info:
        check_length(2 * border, 625.0, 3.0, 6, channel="roll", source="short.mf4")
    msg = str(info.value)
    assert "short.mf4, channel 'roll'" in msg and f"has {2 * border} samples" in msg
    assert f"needs more than {2 * border}" in msg and "order-6 low-pass at 3 Hz" in msg


# ---------------------------------------------------------------------------------------------
# Atomic writes


@pytest.mark.parametrize("fmt", FORMATS)
def test_failed_write_leaves_no_partial_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fmt: str) -> None:
    target = tmp_path / f"out.{fmt}"
    target.write_bytes(b"old content")

    real_replace = os.replace

    def broken_replace(src, dst):
        if Path(dst) != target:
            return real_replace(src, dst)  # a library's own renames
        assert Path(src).parent == tmp_path and Path(src).stat().st_size > 0  # written in full, beside the target
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(OSError, match="disk full"):
        write_recording(multirate(), target)
    assert target.read_bytes() == b"old content"
    assert [p.name for p in tmp_path.iterdir()] == ["out." + fmt]


def test_writer_crash_midway_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from dynid.io import csv_format

    def crash(out, recording, grid, delimiter):
        out.write("time [s],roll\n0.0,")
        raise RuntimeError("killed")

    monkeypatch.setattr(csv_format, "_write_grid", crash)
    with pytest.raises(RuntimeError, match="killed"):
        write_recording(multirate(), tmp_path / "x.csv")
    assert list(tmp_path.iterdir()) == []


def test_recording_rejects_inconsistent_channels() -> None:
    with pytest.raises(DataError, match="3 values but 2 time stamps"):
        Channel("a", "m", [1.0, 2.0, 3.0], [0.0, 1.0])
    t = np.arange(3.0)
    with pytest.raises(DataError, match="two channels are named 'a'"):
        Recording.from_channels([Channel("a", "m", t, t), Channel("a", "m", t, t)])


@pytest.mark.parametrize("whole", [True, False])
def test_a_line_without_end_is_refused_at_the_bound(tmp_path: Path, monkeypatch, whole: bool) -> None:
    """A reader bounds a line before it knows its length (issue 30): a file whose line runs past the bound (here
    lowered to 4 kB; 16 MiB by default) is refused naming that line, by the whole-file and the window readers."""
    from dynid.io import csv_format
    from dynid.io.windows import index_file

    monkeypatch.setattr(csv_format, "MAX_LINE", 4096)
    rows = "\n".join(f"{k / 100},{k}" for k in range(50))
    for where, text in ((1, "t," + "x" * 5000 + "\n" + rows + "\n"), (20, "t,a\n" + rows[:200] + "1" * 5000 + "\n")):
        path = tmp_path / f"long{where}.csv"
        path.write_text(text)
        with pytest.raises(FileFormatError) as exc:
            read_recording(path) if whole else index_file(path)
        msg = str(exc.value)
        assert "\n" not in msg and "longer than 4,096 characters" in msg, msg
        assert f"line {where if where == 1 else 2 + rows[:200].count(chr(10))}" in msg, msg


@pytest.mark.parametrize("bound", ["MAX_ROW_GROUPS", "MAX_FOOTER"])
def test_a_parquet_file_past_its_index_bounds_is_refused(tmp_path: Path, monkeypatch, bound: str) -> None:
    """Opening a Parquet file holds its footer (every row group's metadata) and indexes each row group: a file past
    either bound (lowered here: 10 row groups, a 100-byte footer) is refused with one line before that, by the
    whole-file and the window readers."""
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    from dynid.io import parquet_format
    from dynid.io.windows import index_file

    path = tmp_path / "groups.parquet"
    t = np.arange(200) / 100.0
    pq.write_table(pa.table({"time": t, "a": np.sin(t)}), path, row_group_size=10)  # 20 row groups
    read_recording(path)  # within the default bounds
    monkeypatch.setattr(parquet_format, bound, 10 if bound == "MAX_ROW_GROUPS" else 100)
    for read in (read_recording, index_file):
        with pytest.raises(FileFormatError) as exc:
            read(path)
        msg = str(exc.value)
        assert "\n" not in msg and str(path) in msg and "fewer, larger row groups" in msg, msg
