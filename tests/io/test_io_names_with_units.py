"""A unit written in a column's name ("j1 [deg]", what pandas gives after reading dynid's own CSV) is read the same
way in Parquet, MATLAB and MDF4 files as in a CSV header (issue 27, item 7).

Oracle: dynid's CSV of a robot's log (joint angles in degrees, torques in N.m, so that a unit dropped would show)
read by pandas and written back with pandas/pyarrow, scipy.io.savemat and asammdf: each copy identifies to the
CSV's estimate, which is the same numbers in another container.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import dynid
from dynid.io import Channel, FileFormatError, Recording, read_recording, write_recording
from dynid.io.mapping import ChannelMap, UnitOverrideWarning
from dynid.pipeline.config import ConfigError, load_config
from dynid.pipeline.run import identify

FS = 500.0
DURATION = 12.0

CONFIG = """
[model]
example = "puma560"

[[tests]]
name = "t"
files = {{ q = "{path}", tau = "{path}" }}

[channels]
q = {{ channels = ["j1", "j2", "j3", "j4", "j5", "j6"]{q_unit} }}
tau = {{ channels = ["tau1", "tau2", "tau3", "tau4", "tau5", "tau6"] }}

[conditioning]
cutoff = 20.0
decimate = [5, 5]
{extra}"""


@pytest.fixture(scope="module")
def csv_log(tmp_path_factory) -> Path:
    """dynid's CSV of a puma560 moving on a Fourier trajectory, q in deg (its header: "j1 [deg]", ...)."""
    d = tmp_path_factory.mktemp("names")
    model = dynid.load_model("puma560")
    t = np.arange(int(DURATION * FS)) / FS
    w = 2 * np.pi * 0.2 * np.arange(1, 4)
    a = np.random.default_rng(5).normal(0, 0.3, (6, 3)) / np.arange(1, 4)
    q = np.sin(np.multiply.outer(t, w)) @ a.T
    qd = (np.cos(np.multiply.outer(t, w)) * w) @ a.T
    qdd = -(np.sin(np.multiply.outer(t, w)) * w**2) @ a.T
    tau = model.inverse_dynamics(q, qd, qdd) + np.random.default_rng(6).normal(0, 0.05, q.shape)
    chans = {f"j{i + 1}": Channel(f"j{i + 1}", "deg", np.degrees(q[:, i]), t) for i in range(6)}
    chans |= {f"tau{i + 1}": Channel(f"tau{i + 1}", "N.m", tau[:, i], t) for i in range(6)}
    return write_recording(Recording(None, chans, {}), d / "log.csv", format="csv")


def _estimate(path: Path, q_unit: str = "", extra: str = "") -> np.ndarray:
    cfg = path.with_name(f"{path.stem}-{path.suffix[1:]}.toml")
    cfg.write_text(CONFIG.format(path=path.as_posix(), q_unit=q_unit, extra=extra))
    return identify(load_config(cfg)).result.values


def _copies(csv: Path) -> dict[str, Path]:
    """The CSV as pandas reads it, written as Parquet (pyarrow), MATLAB (scipy) and MDF4 (asammdf)."""
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    df = pd.read_csv(csv, comment="#")
    assert "time [s]" in df.columns and "j1 [deg]" in df.columns  # the names the readers must understand
    out = {"parquet": csv.with_suffix(".parquet")}
    df.to_parquet(out["parquet"])
    import scipy.io as sio

    out["mat"] = csv.with_suffix(".mat")
    sio.savemat(out["mat"], {c: df[c].to_numpy() for c in df.columns})
    asammdf = pytest.importorskip("asammdf")
    out["mf4"] = csv.with_suffix(".mf4")
    mdf = asammdf.MDF()
    mdf.append(df.set_index("time [s]"))  # the index becomes the time master, the columns its channels
    mdf.save(out["mf4"], overwrite=True)
    return out


def test_copies_with_units_in_their_names_identify_as_the_csv(csv_log):
    expected = _estimate(csv_log)
    for fmt, path in _copies(csv_log).items():
        rec = read_recording(path)
        assert rec.channels["j1"].unit == "deg" and rec.channels["tau1"].unit == "N.m", fmt
        np.testing.assert_allclose(_estimate(path), expected, rtol=1e-9, atol=1e-12, err_msg=fmt)


def test_a_name_unit_the_config_contradicts_is_treated_as_in_the_csv(csv_log):
    """The config says rad where the names say deg: the channel map warns naming both units; an identification
    refuses it with one line naming the channel, both units and the two fixes (issue 30: deg over a file's rad
    scaled the inertias by 57 with a 0.02 % residual), for the Parquet copy exactly as for the CSV; with
    unit_over_file = true (the file's header is what is wrong) the config's unit is taken, alike in both."""
    parquet = _copies(csv_log)["parquet"]
    cmap = ChannelMap.from_dict({"q": {"channel": "j1", "unit": "rad"}}, source="identify.toml")
    said = {}
    for path in (csv_log, parquet):
        with pytest.warns(UnitOverrideWarning) as caught:
            cmap.si_channels(read_recording(path))
        said[path.suffix] = str(caught[0].message).replace(str(path), "FILE")
        with pytest.raises(ConfigError) as refused:
            _estimate(path, ', unit = "rad"')
        msg = str(refused.value)
        assert "\n" not in msg and all(w in msg for w in ("'j1'", "'deg'", "'rad'", "unit_over_file = true")), msg
    assert said[".csv"] == said[".parquet"] and "'deg'" in said[".csv"] and "'rad'" in said[".csv"]
    over = ', unit = "rad", unit_over_file = true'
    # the values are degrees read as radians (what the override asserts): the data health check calls that out
    # (5 turns of a joint), so it only warns here, where the override's path is what is compared
    warn = '\n[identification]\ndata_health = "warn"\n'
    np.testing.assert_allclose(_estimate(parquet, over, warn), _estimate(csv_log, over, warn), rtol=1e-9, atol=1e-12)


def test_a_name_unit_the_file_contradicts_is_refused(tmp_path):
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    t = np.arange(10) / 10.0
    schema = pa.schema([pa.field("time [s]", pa.float64()),
                        pa.field("j1 [deg]", pa.float64(), metadata={b"unit": b"rad"})])
    path = tmp_path / "both.parquet"
    pq.write_table(pa.table([t, t], schema=schema), path)
    with pytest.raises(FileFormatError) as exc:
        read_recording(path)
    msg = str(exc.value)
    assert "both.parquet" in msg and "'j1 [deg]'" in msg and "'rad'" in msg and "\n" not in msg


def test_two_columns_giving_one_channel_are_refused(tmp_path):
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    path = tmp_path / "twice.parquet"
    pd.DataFrame({"time": [0.0, 0.1], "yaw [deg]": [1.0, 2.0], "yaw": [1.0, 2.0]}).to_parquet(path)
    with pytest.raises(FileFormatError, match="'yaw \\[deg\\]' and 'yaw' both give the channel 'yaw'"):
        read_recording(path)


def test_an_index_or_a_note_in_brackets_stays_in_the_name(tmp_path):
    """MDF array elements x[0], x[1] and a note (filtered) are not units: the names are kept whole."""
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    path = tmp_path / "names.parquet"
    pd.DataFrame({"time": [0.0, 0.1], "x[0]": [1.0, 2.0], "x[1]": [3.0, 4.0], "ay (filtered)": [0.0, 1.0]}
                 ).to_parquet(path)
    rec = read_recording(path)
    assert set(rec.channels) == {"x[0]", "x[1]", "ay (filtered)"}
    assert all(c.unit == "" for c in rec.channels.values())


@pytest.mark.slow
@pytest.mark.e2e
def test_parquet_copies_of_the_simulated_cars_csv_files_identify_as_them(tmp_path):
    """The issue's case: the quick demo's logger files as `dynid simulate` writes them (CSV, units in the header),
    read by pandas and written to Parquet by pyarrow, identify to the CSVs' estimate and σ."""
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    from dynid.pipeline.demo import simulate_tests, write_demo

    config = write_demo(tmp_path, simulate_tests(quick=True), seed=5)
    text = config.read_text()
    for csv in sorted((tmp_path / "data").glob("*.csv")):
        pd.read_csv(csv, comment="#").to_parquet(csv.with_suffix(".parquet"))
        text = text.replace(f'"data/{csv.name}"', f'"data/{csv.stem}.parquet"')
    assert ".csv" not in text
    copy = tmp_path / "parquet.toml"
    copy.write_text(text)
    a, b = identify(load_config(config)).result, identify(load_config(copy)).result
    assert list(a.names) == list(b.names)
    np.testing.assert_allclose(b.values, a.values, rtol=1e-9, atol=0)
    np.testing.assert_allclose(b.std, a.std, rtol=1e-9, atol=0)
