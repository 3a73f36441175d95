"""MATLAB .mat measurement files (scipy.io; v7.3 HDF5 files through h5py, the `mat73` extra).

Layouts read (and written):

- a time vector `time` (or t, Time, TIME, or `time=`), in s, and one numeric vector per
  channel of the same length;
- a channel with its own time base as a struct with fields `time` and `values` (or
  `data`), and optionally `unit`;
- an optional struct `units` with one char field per channel (units.roll = 'deg',
  units.time = 's' for the time vector);
- an optional struct `metadata` of char fields;
- a unit in a variable's name ("j1 [deg]", which scipy.io.savemat writes from a pandas
  column) read as a CSV header's (io.units.name_and_unit).

Scalars go to the metadata; text, matrices and cells are not read (listed in
`Recording.skipped` with the reason). Without a time vector, the caller gives the
sample rate `fs` for the plain vectors.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import atomic_path
from ._optional import require
from ._table import TIME_NAMES, time_in_seconds, uniform_time
from .errors import FileFormatError
from .recording import Channel, Recording
from .units import channel_names

_VALID_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,62}$")
_RESERVED = {"time", "units", "metadata"}
_HDF5_NUMERIC = {
    b"double",
    b"single",
    b"int8",
    b"uint8",
    b"int16",
    b"uint16",
    b"int32",
    b"uint32",
    b"int64",
    b"uint64",
    b"logical",
}


def _text(value: Any) -> str | None:
    """A MATLAB char value as str ('' for an empty char array), None if it is not text."""
    if isinstance(value, str):
        return value
    if isinstance(value, np.ndarray) and value.dtype.kind == "U":
        return "".join(value.ravel().tolist())
    return None


def _is_hdf5(path: Path) -> bool:
    with open(path, "rb") as fh:
        head = fh.read(128)
    return head.startswith(b"MATLAB 7.3") or (len(head) >= 128 and head[124:126] in (b"\x00\x02", b"\x02\x00"))


def is_v73(path: Path) -> bool:
    """Whether the file is a MATLAB v7.3 file (HDF5 based: its vectors can be read in slices)."""
    return _is_hdf5(path)


def _load(path: Path) -> dict[str, Any]:
    import scipy.io as sio  # start-up: a run that reads no .mat file does not load it (3.4 MB with scipy.sparse)

    label = str(path)
    try:
        return sio.loadmat(path, simplify_cells=True)
    except NotImplementedError:
        pass  # v7.3, HDF5 based
    except (ValueError, TypeError, OSError) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise FileFormatError(f"{label}: not a readable MATLAB file ({exc})", source=label) from None
    if not _is_hdf5(path):
        raise FileFormatError(f"{label}: scipy cannot read this MATLAB file", source=label)
    try:
        h5py = require("h5py", f"{label} is a MATLAB v7.3 (HDF5) file; reading it")
    except ImportError as exc:
        raise type(exc)(
            f"{exc}. Or re-save it in MATLAB as v7: save('{path.name}', '-v7') (scipy reads v4 to v7 files)"
        ) from None
    with h5py.File(path, "r") as fh:
        return {name: _hdf5_value(h5py, fh[name]) for name in fh if not name.startswith("#")}


def _hdf5_value(h5py: Any, obj: Any) -> Any:
    """A v7.3 variable as loadmat(simplify_cells=True) would give it; None when not supported (cells...)."""
    cls = obj.attrs.get("MATLAB_class", b"")
    cls = cls.encode() if isinstance(cls, str) else bytes(cls)
    if isinstance(obj, h5py.Group):
        if cls in (b"struct", b""):
            return {k: _hdf5_value(h5py, obj[k]) for k in obj if not k.startswith("#")}
        return None
    if obj.attrs.get("MATLAB_empty", 0):
        return "" if cls == b"char" else np.empty(0)
    data = np.asarray(obj[()])
    if cls == b"char":
        return "".join(chr(c) for c in data.T.ravel().tolist())
    if cls in _HDF5_NUMERIC or (not cls and data.dtype.kind in "fiub"):
        arr = data.T.squeeze()  # HDF5 keeps MATLAB's column-major dims reversed
        return arr.item() if arr.ndim == 0 else arr
    return None


def read_mat(path: str | os.PathLike[str], *, fs: float | None = None, time: str | None = None) -> Recording:
    """Read a MATLAB .mat file into a `Recording` (layouts in the module docstring).

    Parameters
    ----------
    path : the file.
    fs : Hz, sample rate of the plain vectors when there is no time vector.
    time : name of the time vector if it is not time/t/Time/TIME.
    """
    path = Path(path)
    label = str(path)
    if not path.exists():
        raise FileNotFoundError(f"{label}: no such file")
    variables = {k: v for k, v in _load(path).items() if not k.startswith("__")}
    metadata = {"format": "mat"}
    units: dict[str, str] = {}
    if isinstance(variables.get("units"), Mapping):
        for k, v in variables.pop("units").items():
            text = _text(v)
            if text is not None:
                units[k] = text.strip()
    if isinstance(variables.get("metadata"), Mapping):
        for k, v in variables.pop("metadata").items():
            text = _text(v)
            metadata[k] = text if text is not None else repr(v)
    # a unit written in a variable's name ("j1 [deg]", as scipy.io.savemat writes a pandas column) as in a CSV
    # header; MATLAB's own names never hold one
    stored = {k: _text(v.get("unit", v.get("units", ""))) or "" if isinstance(v, Mapping) else units.get(k, "")
              for k, v in variables.items()}
    named = channel_names(list(stored.items()), label)
    units.update({name: unit for name, unit in named if unit})
    variables = {name: v for (name, _), v in zip(named, variables.values(), strict=True)}
    time_name = time if time is not None else next((n for n in TIME_NAMES if n in variables), None)
    if time is not None and time not in variables:
        raise FileFormatError(f"{label}: no variable {time!r} to use as time; variables: {', '.join(variables)}")
    if time_name is not None and fs is not None:
        raise FileFormatError(f"{label}: the file has a time vector {time_name!r}; drop fs=", source=label)
    shared = None
    if time_name is not None:
        tv = variables.pop(time_name)
        if not isinstance(tv, np.ndarray) or tv.ndim != 1 or tv.dtype.kind not in "fiu":
            raise FileFormatError(
                f"{label}: the time variable {time_name!r} is not a numeric vector "
                f"(got {type(tv).__name__} {getattr(tv, 'shape', '')})",
                source=label,
            )
        shared = time_in_seconds(tv.astype(np.float64), units.get(time_name, ""), time_name, label)
    channels: dict[str, Channel] = {}
    skipped: dict[str, str] = {}
    for name, value in variables.items():
        if isinstance(value, Mapping):
            ch, why = _struct_channel(name, value, units, label)
        else:
            ch, why = _vector_channel(name, value, shared, fs, units, metadata, label)
        if ch is not None:
            channels[name] = ch
        elif why:
            skipped[name] = why
    if not channels:
        hint = "" if shared is not None or fs is not None else " (no time vector was found: pass fs= or time=)"
        raise FileFormatError(f"{label}: no channel could be read{hint}; not read: {skipped}", source=label)
    return Recording(path, channels, metadata, skipped)


def _struct_channel(name: str, value: Mapping, units: dict[str, str], label: str) -> tuple[Channel | None, str]:
    data = value.get("values", value.get("data"))
    tv = value.get("time")
    if not isinstance(data, np.ndarray) or not isinstance(tv, np.ndarray):
        return None, "struct without numeric fields time and values (or data)"
    if data.ndim != 1 or tv.ndim != 1 or data.dtype.kind not in "fiub":
        return None, f"struct with values of shape {data.shape}: one vector per channel is read"
    if data.size != tv.size:
        raise FileFormatError(
            f"{label}: variable {name!r}: {data.size} values but {tv.size} time stamps", source=label, channel=name
        )
    unit = _text(value.get("unit", value.get("units", units.get(name, "")))) or ""
    t = time_in_seconds(tv.astype(np.float64), _text(value.get("time_unit", "")) or "", f"{name}.time", label)
    return Channel(name, unit.strip(), data.astype(np.float64), t), ""


def _vector_channel(
    name: str,
    value: Any,
    shared: np.ndarray | None,
    fs: float | None,
    units: dict[str, str],
    metadata: dict[str, str],
    label: str,
) -> tuple[Channel | None, str]:
    if isinstance(value, bool | int | float | np.number):
        metadata[name] = repr(value.item() if isinstance(value, np.number) else value)
        return None, ""
    text = _text(value)
    if text is not None:
        metadata.setdefault(name, text)
        return None, "text"
    if isinstance(value, np.ndarray) and value.dtype.kind == "c":
        return None, "complex values, not a real vector (store the real part, or magnitude and phase apart)"
    if not isinstance(value, np.ndarray) or value.dtype.kind not in "fiub":
        return None, f"{type(value).__name__} (cell or object), not a numeric vector"
    if value.ndim != 1:
        return None, f"matrix of shape {value.shape}: store one vector per channel"
    if shared is not None:
        if value.size != shared.size:
            return (
                None,
                f"{value.size} samples but the time vector has {shared.size}: give it its own time "
                "(a struct with fields time and values)",
            )
        t = shared
    elif fs is not None:
        t = uniform_time(value.size, fs, label)
    else:
        return None, "no time vector for it (pass fs= or time=)"
    return Channel(name, units.get(name, "").strip(), value.astype(np.float64), t), ""


def write_mat(recording: Recording, path: str | os.PathLike[str]) -> Path:
    """Write the recording as a MATLAB v5/v7 .mat file (compressed), atomically.

    All channels on one time base: a `time` vector and one vector per channel;
    otherwise each channel is a struct (time, values, unit). Units go in `units`,
    metadata in `metadata`. Channel names must be MATLAB names (a letter, then
    letters, digits or _, at most 63) and not time, units or metadata.
    """
    path = Path(path)
    label = recording.label
    chans = list(recording.channels.values())
    if not chans:
        raise FileFormatError(f"{label}: the recording has no channel to write", source=label)
    bad = [c.name for c in chans if not _VALID_NAME.match(c.name) or c.name in _RESERVED]
    if bad:
        raise FileFormatError(
            f"{label}: channel name(s) not usable as MATLAB variables: {', '.join(map(repr, bad))}; "
            "MATLAB names start with a letter, then letters, digits or _ (63 at most), and time, units "
            "and metadata are taken: rename these channels",
            source=label,
            channel=bad[0],
        )
    base = chans[0].time
    shared = all(c.time is base or np.array_equal(c.time, base) for c in chans)
    content: dict[str, Any] = {}
    if shared:
        content["time"] = base
        for c in chans:
            content[c.name] = c.values
    else:
        for c in chans:
            content[c.name] = {"time": c.time, "values": c.values, "unit": c.unit}
    content["units"] = {"time": "s", **{c.name: c.unit for c in chans}}
    meta = {k: str(v) for k, v in recording.metadata.items() if k != "format" and _VALID_NAME.match(k)}
    if meta:
        content["metadata"] = meta
    import scipy.io as sio  # start-up: as in _load

    with atomic_path(path) as tmp:
        sio.savemat(tmp, content, appendmat=False, format="5", do_compression=True, oned_as="column")
    return path
