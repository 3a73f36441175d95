"""A simulated test as a logger writes it: channels with units, one file per test, a JSON sidecar.

`channels(result, seed, noise=True, truth=False)` gives {name: (unit, values)} on the 625 Hz
clock: the paper's sensor suite (dynid.vehicle.sensors) applied to the simulated motion,
plus the truth channels when asked. `write_test(result, path, format, seed, truth)`
writes the file through dynid.io (CSV, Parquet, MDF4; atomic) and `<stem>.json` beside it:
the manoeuvre and its parameters, the seed, the simulator settings, the tire parameters,
the true parameter set (dynid names, paper labels, values, sources), the sensor table and
the channel list.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path

import numpy as np

from ...atomic import OutputError, write_atomic
from ..sensors import SensorSuite, paper_suite, truth_channel_names, truth_channel_units
from ..template import TIRES

FORMATS = {"csv": ".csv", "parquet": ".parquet", "mf4": ".mf4"}


def channels(result, seed: int | None = 0, noise: bool = True, truth: bool = False,
             suite: SensorSuite | None = None) -> dict[str, tuple[str, np.ndarray]]:
    """name -> (unit, values (N,)) of the logged channels, `time` first (s)."""
    suite = paper_suite(result.sim.geometry) if suite is None else suite
    ideal = result.ideal_channels(suite)
    meas = suite.measure(ideal, np.random.default_rng(seed), noise=noise)
    out: dict[str, tuple[str, np.ndarray]] = {"time": ("s", result.time)}
    out.update({c.name: (c.unit, meas[c.name]) for c in suite})
    if truth:
        pris = [f.j for f in result.tree.frames if f.sigma == 1]
        units = truth_channel_units(42, pris)
        arrays = {"q": result.q, "qd": result.qd, "qdd": result.qdd}
        for name in truth_channel_names():
            if name.startswith("true_wft_"):
                out[name] = (units[name], ideal[name[5:]])
                continue
            v = name[5:].rstrip("0123456789")
            j = int(name[5 + len(v):])
            out[name] = (units[name], arrays[v][:, j - 1])
    return out


def check_output(path: str | os.PathLike[str], format: str | None = None) -> tuple[Path, str]:
    """(path, format) after checking that the folder exists and is writable and the format is known."""
    path = Path(path)
    fmt = format or {v: k for k, v in FORMATS.items()}.get(path.suffix.lower())
    if fmt not in FORMATS:
        raise OutputError(f"{path}: cannot tell the file format; use --format one of {', '.join(FORMATS)} "
                          f"or an extension {', '.join(FORMATS.values())}")
    implied = {v: k for k, v in FORMATS.items()}.get(path.suffix.lower())
    if implied is not None and implied != fmt:  # Parquet bytes in a .csv file would fool every reader
        raise OutputError(f"{path}: --format {fmt} but the extension says {implied}; give the file the extension "
                          f"{FORMATS[fmt]} or drop --format")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        what = "is a file, not a folder" if folder.exists() else "does not exist"
        raise OutputError(f"{path}: the folder {folder} {what}; create it or choose another --out")
    if not os.access(folder, os.W_OK):
        raise OutputError(f"{path}: the folder {folder} is not writable; choose another --out")
    if path.is_dir():
        raise OutputError(f"{path} is a folder; give a file name")
    return path, fmt


def _json_safe(x):
    if isinstance(x, dict):
        return {str(k): _json_safe(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_json_safe(v) for v in x]
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def sidecar(result, seed: int | None, noise: bool, truth: bool, names: list[str],
            suite: SensorSuite | None = None) -> dict:
    """The JSON sidecar of a test (see the module doc)."""

    sim = result.sim
    tree = result.tree
    sources = getattr(sim.parameters, "sources", {})
    params = [{"name": n, "label": tree.label(n), "value": float(tree.values.get(n, 0.0)),
               "source": sources.get(n, "simulator: tire damping c_t (FV on the tire joint)"
                                     if n.rstrip("0123456789") == "FV" and int(n[2:]) in TIRES else "")}
              for n in tree.parameter_names if tree.values.get(n, 0.0) != 0.0]
    suite = paper_suite(sim.geometry) if suite is None else suite
    return _json_safe({
        "generator": "dynid.vehicle.sim",
        "manoeuvre": {"name": result.manoeuvre.name, "parameters": result.manoeuvre.params},
        "seed": seed, "noise": noise, "truth_channels": truth,
        "sample_time": float(sim.settings.dt), "samples": int(result.time.size),
        "settings": dataclasses.asdict(sim.settings),
        "damper_dry_friction": "fs * tanh(qd / v_s), v_s = settings.friction_speed (m/s): fs sign(qd) past a few v_s",
        # the knees (v-, v+) in m/s of the dampers that drive with a curve (hbl hbh hrl hrh in true_parameters)
        "damper_knees": {str(j): list(k) for j, k in sorted(tree.knees.items())},
        "tires": [t.as_dict() for t in sim.tires],
        "tree": tree.name,
        "true_parameters": params,
        "contact_lost_samples": int((~result.contact).any(axis=1).sum()),
        "sensors": suite.table(),
        "channels": names,
    })


def write_test(result, path: str | os.PathLike[str], format: str | None = None, seed: int | None = 0,
               truth: bool = False, noise: bool = True, suite: SensorSuite | None = None) -> tuple[Path, Path]:
    """Write the test's file and its sidecar (both atomic); returns (file, sidecar). suite: the sensors fitted
    (default: the paper's suite on the car's geometry)."""
    path, fmt = check_output(path, format)
    ch = channels(result, seed, noise, truth, suite)
    _write_channels(ch, path, fmt, {"manoeuvre": result.manoeuvre.name, "seed": str(seed)})
    side = path.with_suffix(".json")
    write_atomic(side, json.dumps(sidecar(result, seed, noise, truth, list(ch), suite), indent=1))
    return path, side


def _write_channels(ch: dict[str, tuple[str, np.ndarray]], path: Path, fmt: str, meta: dict[str, str]) -> None:
    try:
        # start-up: dynid.io costs 0.12 s after the simulator (measured); a simulated test in CSV needs none of it
        from ...io import Channel, Recording, write_recording
    except ImportError:  # the io layer is optional here: CSV by hand
        if fmt != "csv":
            raise OutputError(f"{path}: writing {fmt} needs dynid.io") from None
        _write_csv(ch, path)
        return
    t = ch["time"][1]
    rec = Recording.from_channels([Channel(n, u, v, t) for n, (u, v) in ch.items() if n != "time"],
                                  metadata=meta)
    write_recording(rec, path, {"mf4": "mdf"}.get(fmt, fmt))


def _write_csv(ch: dict[str, tuple[str, np.ndarray]], path: Path) -> None:
    """Fallback CSV: header of names, a units row, then the samples (repr floats), atomically."""
    names = list(ch)
    cols = np.column_stack([ch[n][1] for n in names])
    lines = [",".join(names), ",".join(ch[n][0] for n in names)]
    lines += [",".join(repr(float(x)) for x in row) for row in cols]
    write_atomic(path, "\n".join(lines) + "\n")
