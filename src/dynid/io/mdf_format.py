"""ASAM MDF measurement files (.mf4, .mdf; through asammdf, the `mdf` extra).

Every channel keeps the time base of its channel group (the group's time master), so
multi-rate loggers come out as they were recorded. Values are physical (the file's
conversions applied); units come from each channel's unit field, or from its name as in
a CSV header ("imu_yaw_rate [deg/s]" is imu_yaw_rate in deg/s; io.units.name_and_unit,
a contradiction between the two an error). Text channels, array
channels and groups whose master is not time (angle, distance) are not read (listed
in `Recording.skipped`). A name that occurs in several groups is read as
"name@group" for each group. The header's comment is read as metadata (a JSON
object of strings when dynid wrote the file) and its start time as
metadata["start_time"].
"""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import atomic_path
from ._optional import require
from .errors import FileFormatError
from .recording import Channel, Recording
from .units import name_and_unit

_TIME_SYNC = 1  # MDF4 sync type of a time master


def read_mdf(path: str | os.PathLike[str]) -> Recording:
    """Read an MDF file into a `Recording`, each channel on its own group's time base."""
    path = Path(path)
    label = str(path)
    mdf = open_mdf(path, label)
    with mdf:
        metadata = {"format": "mdf", "mdf_version": str(mdf.version)}
        _header_metadata(mdf, metadata)
        wanted, skipped = channel_places(mdf, label)
        channels = {}
        # Group by group (less memory at once), one time array per group shared by its channels.
        for group in sorted({g for _, _, g, _ in wanted}):
            channels.update(group_channels(mdf, [w for w in wanted if w[2] == group], skipped, source=label))
    if not channels:
        raise FileFormatError(f"{label}: no numeric channel in the file; not read: {skipped}", source=label)
    return Recording(path, channels, metadata, skipped)


def open_mdf(path: Path, label: str) -> Any:
    """An open `asammdf.MDF` (use it as a context manager); a file that is not MDF is a one-line error."""
    asammdf = require("asammdf", "Reading MDF files")
    if not path.exists():
        raise FileNotFoundError(f"{label}: no such file")
    try:
        return asammdf.MDF(path)
    except Exception as exc:  # asammdf raises many kinds for a file that is not MDF
        raise FileFormatError(f"{label}: not a readable MDF file ({type(exc).__name__}: {exc})", source=label) from None


def channel_places(mdf: Any, label: str = "") -> tuple[list[tuple[str, str, int, int]], dict[str, str]]:
    """The channels read: (key, name, group, index) each, key the channel's name without a unit written in it
    (`name_and_unit`), "key@group" for a name in several groups.

    Also the channels not read with the reason (groups whose master is not time).
    """
    masters = dict(mdf.masters_db)
    wanted, skipped = [], {}
    seen: dict[str, str] = {}
    for name, places in mdf.channels_db.items():
        for group, index in places:
            if masters.get(group) == index:
                continue
            bare = name_and_unit(name, "")[0]
            key = bare if len(places) == 1 else f"{bare}@{group}"
            if seen.setdefault(key, name) != name:
                raise FileFormatError(f"{label}: the channels {seen[key]!r} and {name!r} both give the channel "
                                      f"{key!r}; rename one", source=label, channel=key)
            if not _time_master(mdf, group, masters):
                skipped[key] = "its group's master channel is not time (angle or distance based)"
                continue
            wanted.append((key, name, group, index))
    return wanted, skipped


def group_channels(
    mdf: Any,
    members: list[tuple[str, str, int, int]],
    skipped: dict[str, str],
    record_offset: int = 0,
    record_count: int | None = None,
    source: str = "",
) -> dict[str, Channel]:
    """The channels `members` (all of one group) as `Channel`s, on the group's master as time base.

    `record_offset` / `record_count` read a run of the group's records only (asammdf
    decodes each record the same way whatever the run, so pieces equal the whole).
    Channels whose samples are not numeric vectors go to `skipped`. A unit in a channel's name contradicting
    its unit field is an error naming `source`.
    """
    channels = {}
    signals = mdf.select(
        [(name, g, index) for _, name, g, index in members],
        copy_master=False,
        record_offset=record_offset,
        record_count=record_count,
    )
    base = None
    for (key, name, _, _), sig in zip(members, signals, strict=True):
        samples = np.asarray(sig.samples)
        if samples.ndim != 1 or samples.dtype.kind not in "fiub":
            skipped[key] = f"samples of type {samples.dtype} and shape {samples.shape}, not numbers"
            continue
        stamps = np.asarray(sig.timestamps, dtype=np.float64)
        if base is None or (stamps is not base and not np.array_equal(base, stamps)):
            base = stamps
        unit = name_and_unit(name, str(sig.unit or ""), source)[1]
        channels[key] = Channel(key, unit, samples.astype(np.float64, copy=False), base)
    return channels


def _time_master(mdf, group: int, masters: dict[int, int]) -> bool:
    index = masters.get(group)
    if index is None:
        return True  # no master: asammdf gives sample indices as time; keep (rare)
    sync = getattr(mdf.groups[group].channels[index], "sync_type", _TIME_SYNC)
    return sync in (0, _TIME_SYNC)  # MDF3 masters report 0


def _header_metadata(mdf, metadata: dict[str, str]) -> None:
    header = mdf.header
    text = getattr(header, "description", "") or ""
    if text:
        try:
            stored = json.loads(text)
        except ValueError:
            stored = None
        if isinstance(stored, dict):
            metadata.update({str(k): str(v) for k, v in stored.items()})
        else:
            metadata["comment"] = text
    start = getattr(header, "start_time", None)
    if start is not None:
        metadata.setdefault("start_time", start.isoformat())


def write_mdf(recording: Recording, path: str | os.PathLike[str]) -> Path:
    """Write the recording as MDF 4.10, atomically: one channel group per distinct time base.

    Units go in each channel's unit field, the metadata (JSON) in the header comment.
    Returns the path written.
    """
    asammdf = require("asammdf", "Writing MDF files")
    path = Path(path)
    label = recording.label
    chans = list(recording.channels.values())
    if not chans:
        raise FileFormatError(f"{label}: the recording has no channel to write", source=label)
    groups: list[list[Channel]] = []
    for ch in chans:
        for members in groups:
            base = members[0].time
            if ch.time is base or np.array_equal(ch.time, base):
                members.append(ch)
                break
        else:
            groups.append([ch])
    mdf = asammdf.MDF(version="4.10")
    try:
        for members in groups:
            signals = [
                asammdf.Signal(samples=ch.values, timestamps=ch.time, name=ch.name, unit=ch.unit) for ch in members
            ]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                mdf.append(signals, comment=f"{members[0].rate:.6g} Hz" if len(members[0]) > 1 else "")
        meta = {k: v for k, v in recording.metadata.items() if k not in ("format", "mdf_version", "start_time")}
        if meta:
            mdf.header.comment = json.dumps(meta)
        with atomic_path(path) as tmp:
            written = Path(mdf.save(tmp, overwrite=True))
            if written != tmp:  # asammdf may adjust the name; keep the atomic rename on our temp file
                os.replace(written, tmp)
    finally:
        mdf.close()
    return path
