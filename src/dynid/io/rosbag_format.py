"""ROS 2 bags (rosbag2): `sensor_msgs/msg/JointState` messages as channels (needs rosbags: the `ros` extra).

A bag is a folder holding metadata.yaml and its storage files, or one storage file: SQLite3
(.db3) or MCAP (.mcap), read through `rosbags` (a maintained pure-Python reader of both
storages: no ROS installation needed). One topic is read, a JointState one: the `topic`
option, or the bag's only JointState topic.

Each joint named in the messages gives up to three channels, "<joint>.position",
"<joint>.velocity" and "<joint>.effort", stamped by the messages' header stamps (not the
bag's receive times), in s from the first message's stamp (kept in the metadata as
"time.start_ns"), in the bag's order: irregular stamps stay as they are, as a CSV time
column's do. A message whose velocity or effort array is empty (ROS allows it) is no
sample of those channels, as an empty CSV cell; a joint missing from a message is no
sample of that joint's channels. An array whose length is neither 0 nor the number of
names is an error naming the message.

Units are empty: REP 103 says rad or m for a position and N·m or N for an effort,
by the joint's type, which the bag does not say (the identification takes them from
the model's joint types).

Decoding: the messages of a block that share one byte layout (the same header frame,
names and array lengths: a driver's usual output) are decoded at once with NumPy from
their CDR bytes; each layout is first checked against rosbags' own deserializer on one
message. MCAP chunks are walked here (rosbags' index and decompression), since rosbags'
message iterator costs ~8 µs a message (a 1 h, 1 kHz bag: 30 s).
"""

from __future__ import annotations

import gc
import os
import struct
import threading
from collections import OrderedDict
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from itertools import islice
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._optional import require
from ._table import Column, recording_from_columns
from .errors import FileFormatError
from .recording import Recording

JOINT_STATE = "sensor_msgs/msg/JointState"
FIELDS = ("position", "velocity", "effort")
EXTENSIONS = (".db3", ".mcap")
BLOCK_MESSAGES = 65536
Piece = list[bytes] | NDArray[np.uint8]  # messages: their CDR bytes, or rows of a (n, length) array of equal lengths
_MAX_LAYOUTS = 64  # layouts tried in one block before decoding its remaining messages one by one


def is_bag_folder(path: str | os.PathLike[str]) -> bool:
    """A folder holding a rosbag2 metadata.yaml."""
    p = Path(path)
    return p.is_dir() and (p / "metadata.yaml").is_file()


def is_bag(path: str | os.PathLike[str]) -> bool:
    """A ROS 2 bag: a bag folder, or a .db3 or .mcap file."""
    return is_bag_folder(path) or Path(path).suffix.lower() in EXTENSIONS


def bag_stat(path: str | os.PathLike[str]) -> tuple[int, int]:
    """(total size, latest modification time in ns) of a bag folder's files: a bag rewritten is seen."""
    size, mtime = 0, 0
    for f in sorted(Path(path).iterdir()):
        if f.is_file():
            st = f.stat()
            size += st.st_size
            mtime = max(mtime, st.st_mtime_ns)
    return size, mtime


def channel_name(joint: str, field: str) -> str:
    """The channel of one joint's field: "elbow_joint.position"."""
    return f"{joint}.{field}"


# --------------------------------------------------------------------------------------------------- opening a bag
def _rosbags() -> tuple[Any, Any]:
    rosbag2 = require("rosbags.rosbag2", "Reading ROS 2 bags")
    typesys = require("rosbags.typesys", "Reading ROS 2 bags")
    return rosbag2, typesys


class _Bag:
    """An open bag and its JointState topic's connections (`opened` shares them within a process)."""

    def __init__(self, path: str, topic: str | None) -> None:
        rosbag2, typesys = _rosbags()
        self.label = path
        self.lock = threading.Lock()
        try:
            self.reader = rosbag2.Reader(Path(path))
            self.reader.open()
        except FileNotFoundError as exc:
            raise FileFormatError(f"{path}: not a rosbag2 bag ({exc}); give a bag folder with metadata.yaml, or its "
                                  ".db3 or .mcap file", source=path) from None
        except Exception as exc:  # rosbags raises ReaderError, sqlite/apsw and struct errors on a damaged file
            raise FileFormatError(f"{path}: unreadable ROS 2 bag ({type(exc).__name__}: {_one_line(exc)}); is it "
                                  "complete (a recording stopped cleanly) and a rosbag2 .db3/.mcap or bag folder? "
                                  "Try `ros2 bag reindex` on it", source=path) from None
        self.typestore = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
        try:
            self.select(topic)
        except BaseException:
            self.close()
            raise

    def select(self, topic: str | None) -> None:
        """Read `topic` (None: the bag's only JointState topic) from now on; errors list the bag's topics."""
        self.topic, self.connections = self._topic(topic)

    def _topic(self, topic: str | None) -> tuple[str, list[Any]]:
        topics: dict[str, set[str]] = {}
        for c in self.reader.connections:
            topics.setdefault(c.topic, set()).add(c.msgtype)
        listing = ", ".join(f"{t} ({'/'.join(sorted(m))})" for t, m in sorted(topics.items())) or "none"
        if topic is None:
            joint = [t for t, m in sorted(topics.items()) if JOINT_STATE in m]
            if not joint:
                raise FileFormatError(f"{self.label}: no {JOINT_STATE} topic in the bag (topics: {listing}); record "
                                      "the joint states (ros2 bag record /joint_states)", source=self.label)
            if len(joint) > 1:
                raise FileFormatError(f"{self.label}: {len(joint)} {JOINT_STATE} topics ({', '.join(joint)}); name "
                                      f"the one to read: topic = \"{joint[0]}\" in the test", source=self.label)
            topic = joint[0]
        if topic not in topics:
            raise FileFormatError(f"{self.label}: no topic {topic!r} in the bag (topics: {listing}); give one of "
                                  "them as the test's topic", source=self.label, channel=topic)
        if JOINT_STATE not in topics[topic]:
            raise FileFormatError(f"{self.label}: topic {topic} holds {'/'.join(sorted(topics[topic]))}, not "
                                  f"{JOINT_STATE}; give a JointState topic (topics: {listing})",
                                  source=self.label, channel=topic)
        conns = [c for c in self.reader.connections if c.topic == topic and c.msgtype == JOINT_STATE]
        return topic, conns

    @property
    def count(self) -> int:
        return int(sum(c.msgcount for c in self.connections))

    def close(self) -> None:
        if getattr(self.reader, "is_open", False):
            self.reader.close()

    def runs(self, start: int | None = None, stop: int | None = None) -> Iterator[tuple[NDArray[np.int64], Piece]]:
        """The topic's messages with start <= receive time < stop, in bag order, as runs of (receive times ns, CDR
        bytes: a `Piece`) of any length: SQLite3 storages queried in bulk, indexed MCAP storages' chunks walked
        here (rosbags' chunk index and decompression), anything else through rosbags' message iterator."""
        try:
            storage = self.reader.storage
            storages = getattr(storage, "storages", [storage])
            per_message = getattr(getattr(storage, "metadata", None), "compression_mode", None) == "message"
            kinds = {type(s).__name__ for s in storages}
            if not per_message and kinds == {"Sqlite3Reader"}:
                for s in storages:
                    yield from _sqlite_runs(s, self.topic, start, stop)
            elif not per_message and kinds == {"McapReader"} and all(s.chunks for s in storages):
                for s in storages:
                    yield from _mcap_runs(s, self.topic, start, stop)
            else:
                it = self.reader.messages(self.connections, start=start, stop=stop)
                while True:
                    got = list(islice(it, BLOCK_MESSAGES))
                    if not got:
                        break
                    yield np.array([t for _, t, _ in got], dtype=np.int64), [d for _, _, d in got]
        except FileFormatError:
            raise
        except Exception as exc:
            raise FileFormatError(f"{self.label}: unreadable ROS 2 bag, topic {self.topic} "
                                  f"({type(exc).__name__}: {_one_line(exc)}); is the file complete? Try "
                                  "`ros2 bag reindex` on it", source=self.label, channel=self.topic) from None


_OPEN_BAGS = 4  # bags kept open per process
_open: OrderedDict[tuple, _Bag] = OrderedDict()
_open_lock = threading.Lock()


@contextmanager
def opened(path: str, topic: str | None) -> Iterator[_Bag]:
    """The bag open, held by this thread until the block ends. Bags stay open in the process (the last
    `_OPEN_BAGS`, reopened if the files change): rosbags counts a SQLite3 bag's messages when it opens it, a pass
    over the whole file (5 s for an hour at 1 kHz), which each window of the bag would pay again."""
    p = Path(path)
    stamp = bag_stat(p) if is_bag_folder(p) else (p.stat().st_size, p.stat().st_mtime_ns)
    key = (os.fspath(path), stamp)
    with _open_lock:
        bag = _open.pop(key, None)
    if bag is None:
        bag = _Bag(os.fspath(path), topic)
    with bag.lock:
        try:
            bag.select(topic)
            yield bag
        finally:
            with _open_lock:
                if key in _open:  # another thread opened it meanwhile: one is enough
                    bag.close()
                else:
                    _open[key] = bag
                while len(_open) > _OPEN_BAGS:
                    _, old = _open.popitem(last=False)
                    if old.lock.acquire(blocking=False):
                        old.close()
                        old.lock.release()


@contextmanager
def _no_gc() -> Iterator[None]:
    """The cyclic garbage collector paused while a run's row tuples are made (none holds a cycle): it would
    otherwise walk the ever larger heap of them, which doubles the time of a long bag's read."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def _ids(storage: Any, topic: str) -> list[int]:
    return [c.id for c in storage.connections if c.topic == topic and c.msgtype == JOINT_STATE]


def _sqlite_runs(storage: Any, topic: str, start: int | None, stop: int | None
                 ) -> Iterator[tuple[NDArray[np.int64], Piece]]:
    """A SQLite3 storage's messages of the topic, ordered by receive time as rosbags orders them."""
    ids = _ids(storage, topic)
    if not ids:
        return
    query = f"SELECT timestamp, data FROM messages WHERE topic_id IN ({','.join('?' * len(ids))})"
    args: list[int] = list(ids)
    if start is not None:
        query += " AND timestamp >= ?"
        args.append(start)
    if stop is not None:
        query += " AND timestamp < ?"
        args.append(stop)
    cursor = storage.dbconn.execute(query + " ORDER BY timestamp, id", args)
    while True:
        with _no_gc():
            rows = list(islice(cursor, BLOCK_MESSAGES))
            if not rows:
                return
            times, datas = zip(*rows, strict=True)
            del rows
        yield np.array(times, dtype=np.int64), list(datas)


def _mcap_runs(storage: Any, topic: str, start: int | None, stop: int | None
               ) -> Iterator[tuple[NDArray[np.int64], Piece]]:
    """An indexed MCAP storage's messages of the topic: each chunk's in receive-time order (stable), the chunks'
    merged by receive time (ties in file order), as rosbags' own iterator orders them. A run of message records
    of one length is found with NumPy, not record by record, and kept as rows of the chunk's bytes."""
    from rosbags.rosbag2.storage_mcap import decompress  # optional: rosbags (the ros extra)

    lo = -(2**63) if start is None else start
    hi = 2**63 - 1 if stop is None else stop
    ids = set(_ids(storage, topic))
    bio = storage.bio
    pending: list[tuple[NDArray[np.int64], list[Piece]]] = []  # chunks that may overlap in receive time
    latest = -(2**63)
    for chunk in sorted(storage.chunks, key=lambda c: c.chunk_start_offset):
        if chunk.message_end_time < lo or chunk.message_start_time >= hi or not any(
                chunk.channel_count.get(i, 0) for i in ids):
            continue
        bio.seek(chunk.chunk_start_offset + 9 + 24)
        (crc,) = struct.unpack("<I", bio.read(4))
        bio.seek(chunk.chunk_start_offset + 9 + 40 + len(chunk.compression))
        raw = decompress(bio.read(chunk.compressed_size), chunk.compression, chunk.uncompressed_size, crc)
        with _no_gc():
            t, d = _chunk_messages(raw, ids, lo, hi)
        if not t.size:
            continue
        if pending and t[0] >= latest:  # after every message pending (a recorder's usual file): they go first
            yield from _merged(pending)
            pending = []
        pending.append((t, d))
        latest = max(latest, int(t[-1]))
    if pending:
        yield from _merged(pending)


def _merged(runs: list[tuple[NDArray[np.int64], list[Piece]]]) -> Iterator[tuple[NDArray[np.int64], Piece]]:
    """Runs each in receive-time order merged by receive time, ties in the runs' order."""
    if len(runs) == 1:
        t, pieces = runs[0]
        yield from _with_times(t, pieces)
        return
    t = np.concatenate([t for t, _ in runs])
    d = _as_bytes([p for _, ps in runs for p in ps])
    order = np.argsort(t, kind="stable")
    yield t[order], [d[k] for k in order.tolist()]


def _with_times(t: NDArray[np.int64], pieces: list[Piece]) -> Iterator[tuple[NDArray[np.int64], Piece]]:
    at = 0
    for p in pieces:
        yield t[at:at + len(p)], p
        at += len(p)


def _chunk_messages(raw: bytes, ids: set[int], lo: int, hi: int) -> tuple[NDArray[np.int64], list[Piece]]:
    """The messages of the channels `ids` received in lo..hi-1 in one decompressed chunk, in receive-time order:
    their receive times and their bytes, runs of records of one length as rows of a (n, length) view."""
    arr = np.frombuffer(raw, dtype=np.uint8)
    end = len(raw)
    times: list[NDArray[np.int64]] = []
    pieces: list[Piece] = []
    pos = 0
    while pos < end:
        op, length = raw[pos], int.from_bytes(raw[pos + 1:pos + 9], "little")
        if op != 0x05:
            pos += 9 + length
            continue
        # a message record: op (1), length (8), channel id (2), sequence (4), log time (8), publish time (8), data
        step = 9 + length
        n = (end - pos) // step
        if n < 2 or raw[pos:pos + 11] != raw[pos + step:pos + step + 11]:  # a record alone (topics interleaved)
            channel, log_time = int.from_bytes(raw[pos + 9:pos + 11], "little"), int.from_bytes(
                raw[pos + 15:pos + 23], "little")
            if channel in ids and lo <= log_time < hi:
                times.append(np.array([log_time], dtype=np.int64))
                pieces.append([raw[pos + 31:pos + step]])
            pos += step
            continue
        k, probe = n, 64  # the run of records like this one (op, length, channel id): probed in growing steps
        while True:
            starts = pos + step * np.arange(min(probe, n))
            heads = arr[starts[:, None] + np.arange(11)]
            same = (heads == heads[0]).all(axis=1)
            if not same.all():
                k = int(np.argmin(same))
                break
            if probe >= n:
                break
            probe *= 8
        if int(heads[0, 9]) | int(heads[0, 10]) << 8 in ids:
            rows = arr[pos:pos + step * k].reshape(k, step)
            stamp = np.ascontiguousarray(rows[:, 15:23]).view("<u8")[:, 0].astype(np.int64)
            keep = (stamp >= lo) & (stamp < hi)
            if keep.any():
                times.append(stamp[keep])
                pieces.append(rows[:, 31:] if keep.all() else rows[keep, 31:])
        pos += step * k
    if not times:
        return np.empty(0, dtype=np.int64), []
    t = np.concatenate(times)
    order = np.argsort(t, kind="stable")
    if np.any(order != np.arange(order.size)):
        d = _as_bytes(pieces)
        return t[order], [[d[k] for k in order.tolist()]]
    return t, pieces


def _as_bytes(pieces: Sequence[Piece]) -> list[bytes]:
    return [m for p in pieces for m in (p if isinstance(p, list) else [row.tobytes() for row in p])]


def _split(pieces: list[Piece], c: int) -> tuple[list[Piece], list[Piece]]:
    """The first c messages of pieces, and the rest."""
    head: list[Piece] = []
    for i, p in enumerate(pieces):
        if c <= 0:
            return head, pieces[i:]
        if len(p) <= c:
            head.append(p)
            c -= len(p)
        else:
            return [*head, p[:c]], [p[c:], *pieces[i + 1:]]
    return head, []


# ------------------------------------------------------------------------------------------------------- decoding
@dataclass(frozen=True)
class _Layout:
    """Where a JointState message's parts lie in its CDR bytes."""

    little: bool
    names: tuple[str, ...]
    arrays: tuple[tuple[int, int], ...]  # per field: (offset of the doubles, count)
    size: int


def _layout(raw: bytes) -> _Layout:
    """Parse one JointState's CDR bytes (header stamp, frame id, names, then three float64 sequences)."""
    if len(raw) < 12 or raw[0] != 0 or raw[1] not in (0, 1):
        raise ValueError("not CDR-encoded (its encapsulation header is not CDR_BE/CDR_LE)")
    little = raw[1] == 1
    u32 = struct.Struct("<I" if little else ">I")
    pos = 12  # encapsulation (4), stamp sec (4), nanosec (4)

    def string(at: int) -> tuple[str, int]:
        (n,) = u32.unpack_from(raw, at)
        if n < 1 or at + 4 + n > len(raw):
            raise ValueError(f"a string of length {n} at byte {at} runs past the message's end")
        return raw[at + 4:at + 3 + n].decode("utf-8"), at + 4 + n

    def aligned(at: int, n: int) -> int:
        return 4 + (at - 4 + n - 1) // n * n

    _, pos = string(pos)  # frame id
    pos = aligned(pos, 4)
    (count,) = u32.unpack_from(raw, pos)
    pos += 4
    if count > len(raw):
        raise ValueError(f"{count} names cannot fit in {len(raw)} bytes")
    names = []
    for _ in range(count):
        name, pos = string(aligned(pos, 4))
        names.append(name)
    arrays = []
    for _ in FIELDS:
        pos = aligned(pos, 4)
        (k,) = u32.unpack_from(raw, pos)
        pos += 4
        if k:
            pos = aligned(pos, 8)
        arrays.append((pos, k))
        pos += 8 * k
        if pos > len(raw):
            raise ValueError(f"an array of {k} numbers runs past the message's end ({len(raw)} bytes)")
    if len(raw) - pos > 7:
        raise ValueError(f"{len(raw) - pos} bytes after the effort array")
    return _Layout(little, tuple(names), tuple(arrays), len(raw))


@dataclass
class Decoded:
    """A block of messages: stamps, and per field the joints' values (R, J) and whether each message has them."""

    stamps: NDArray[np.int64]  # (R,), ns
    joints: list[str]
    values: dict[str, NDArray[np.float64]]  # field -> (R, J), NaN where absent
    present: dict[str, NDArray[np.bool_] | None]  # field -> (R, J), None: every message has every joint's
    layouts: int = 1  # the number of byte layouts among the messages

    def mask(self, field: str, j: int) -> NDArray[np.bool_] | None:
        """Which messages have joint j's field (None: all)."""
        p = self.present[field]
        return None if p is None else p[:, j]

    def has(self, field: str, j: int) -> bool:
        """Some message has joint j's field."""
        p = self.present[field]
        return p is None or bool(p[:, j].any())


class _Decoder:
    """Decodes blocks of one topic's messages; `first` numbers the messages across blocks (for messages)."""

    def __init__(self, bag: _Bag) -> None:
        self.bag = bag
        self.checked: set[tuple] = set()
        self.trusted = False
        self.fields: tuple[str, ...] = FIELDS

    def where(self, index: int, stamp: int | None) -> str:
        at = "" if stamp is None else f", header stamp {stamp // 10**9}.{stamp % 10**9:09d} s"
        return f"{self.bag.label}: topic {self.bag.topic}, message {index}{at}"

    def layout(self, raw: bytes, index: int) -> _Layout:
        try:
            lay = _layout(raw)
        except (ValueError, struct.error, UnicodeDecodeError) as exc:
            raise FileFormatError(f"{self.where(index, None)}: not a readable JointState ({_one_line(exc)}); the bag "
                                  "is damaged or the topic's type is wrong", source=self.bag.label,
                                  channel=self.bag.topic, sample=index) from None
        stamp = _stamp(raw, lay.little)
        if len(set(lay.names)) != len(lay.names):
            twice = next(n for n in lay.names if lay.names.count(n) > 1)
            raise FileFormatError(f"{self.where(index, stamp)}: joint {twice!r} is named twice in the message; fix "
                                  "the publisher (each joint once)", source=self.bag.label, channel=self.bag.topic,
                                  sample=index)
        for field, (_, k) in zip(FIELDS, lay.arrays, strict=True):
            if k not in (0, len(lay.names)):
                raise FileFormatError(f"{self.where(index, stamp)}: {len(lay.names)} joint name(s) but {k} {field} "
                                      f"value(s) (JointState's arrays are empty or one value per name); fix the "
                                      "publisher, or cut the bag before this message", source=self.bag.label,
                                      channel=self.bag.topic, sample=index)
        key = (lay.little, lay.names, tuple(k for _, k in lay.arrays))
        if key not in self.checked:  # the layout checked once against rosbags' deserializer
            self._check(raw, lay, index, stamp)
            self.checked.add(key)
        return lay

    def _check(self, raw: bytes, lay: _Layout, index: int, stamp: int) -> None:
        try:
            msg = self.bag.typestore.deserialize_cdr(raw, JOINT_STATE)
        except Exception as exc:
            raise FileFormatError(f"{self.where(index, stamp)}: not a readable JointState ({_one_line(exc)}); the "
                                  "bag is damaged or the topic's type is wrong", source=self.bag.label,
                                  channel=self.bag.topic, sample=index) from None
        ours = [_doubles(raw, off, k, lay.little) for off, k in lay.arrays]
        theirs = [np.asarray(getattr(msg, f), dtype=np.float64) for f in FIELDS]
        same = (tuple(msg.name) == lay.names and _stamp(raw, lay.little) == msg.header.stamp.sec * 10**9
                + msg.header.stamp.nanosec and all(a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
                                                   for a, b in zip(ours, theirs, strict=True)))
        if not same:
            raise FileFormatError(f"{self.where(index, stamp)}: this message's layout is not decoded here as rosbags "
                                  "decodes it; please report it with the bag", source=self.bag.label,
                                  channel=self.bag.topic, sample=index)

    def decode(self, pieces: Sequence[Piece], first: int, one_layout: bool = False,
               fields: Sequence[str] = FIELDS) -> Decoded:
        """The messages of pieces (numbered first, first + 1, ...) decoded. one_layout: they are known to share the
        first's layout (an index's pass checked them, and the file is unchanged): not compared again. fields: the
        fields whose numbers are wanted (the others' `values` are empty (R, 0) arrays; `present` tells them all)."""
        self.trusted = one_layout
        self.fields = tuple(fields)
        if pieces and all(isinstance(p, np.ndarray) for p in pieces) and len({p.shape[1] for p in pieces}) == 1:
            buf = pieces[0] if len(pieces) == 1 else np.concatenate(pieces)  # type: ignore[arg-type]
            lay = self.layout(buf[0].tobytes(), first)
            if self._same(buf, lay).all():
                return self._single(buf, lay)
        return self._decode(_as_bytes(pieces), first)

    def _same(self, buf: NDArray[np.uint8], lay: _Layout) -> NDArray[np.bool_]:
        """Which rows have the layout of the first (its structure's bytes the same)."""
        if buf.shape[1] != lay.size:
            return np.zeros(buf.shape[0], dtype=bool)
        same = np.ones(buf.shape[0], dtype=bool)
        if buf.shape[0] > 1 and not self.trusted:
            for lo, hi in _structure(lay):
                same &= (buf[:, lo:hi] == buf[0, lo:hi]).all(axis=1)
        return same

    def _single(self, buf: NDArray[np.uint8], lay: _Layout) -> Decoded:
        """Messages of one layout: each field's numbers a (R, J) view of their bytes, no scatter."""
        R, J = buf.shape[0], len(lay.names)
        values: dict[str, NDArray[np.float64]] = {}
        present: dict[str, NDArray[np.bool_] | None] = {}
        for field, (off, k) in zip(FIELDS, lay.arrays, strict=True):
            if field not in self.fields:
                values[field] = np.empty((R, 0))
                present[field] = None if k else np.zeros((R, J), dtype=bool)
            elif k:
                values[field] = _block_doubles(buf, off, k, lay.little)
                present[field] = None
            else:
                values[field] = np.full((R, J), np.nan)
                present[field] = np.zeros((R, J), dtype=bool)
        return Decoded(_stamps(buf, lay.little), list(lay.names), values, present)

    def _decode(self, raws: list[bytes], first: int) -> Decoded:
        R = len(raws)
        lengths = np.fromiter(map(len, raws), dtype=np.int64, count=R)
        joints: dict[str, int] = {}
        parts: list[tuple[NDArray[np.intp], _Layout, NDArray[np.uint8]]] = []  # rows, layout, their bytes (n, L)
        todo = np.arange(R)
        tried = 0
        while todo.size:
            r0 = int(todo[0])
            lay = self.layout(raws[r0], first + r0)
            # messages of many layouts: one at a time
            rows = todo[:1] if tried >= _MAX_LAYOUTS else todo[lengths[todo] == lay.size]
            every = rows.size == R
            joined = b"".join(raws if every else [raws[k] for k in rows.tolist()])
            buf = np.frombuffer(joined, dtype=np.uint8).reshape(rows.size, lay.size)
            same = self._same(buf, lay)
            if not same.all():
                rows, buf, every = rows[same], buf[same], False
            if every:
                return self._single(buf, lay)
            parts.append((rows, lay, buf))
            for name in lay.names:
                joints.setdefault(name, len(joints))
            done = np.zeros(R, dtype=bool)
            done[rows] = True
            todo = todo[~done[todo]]
            tried += 1
        J = len(joints)
        stamps = np.empty(R, dtype=np.int64)
        values = {f: np.full((R, J), np.nan) if f in self.fields else np.empty((R, 0)) for f in FIELDS}
        present: dict[str, NDArray[np.bool_] | None] = {f: np.zeros((R, J), dtype=bool) for f in FIELDS}
        for rows, lay, buf in parts:
            stamps[rows] = _stamps(buf, lay.little)
            cols = np.array([joints[n] for n in lay.names], dtype=np.intp)
            for field, (off, k) in zip(FIELDS, lay.arrays, strict=True):
                if k:
                    if field in self.fields:
                        values[field][rows[:, None], cols[None, :]] = _block_doubles(buf, off, k, lay.little)
                    present[field][rows[:, None], cols[None, :]] = True  # type: ignore[index]
        return Decoded(stamps, list(joints), values, present, len(parts))


def _block_doubles(buf: NDArray[np.uint8], off: int, k: int, little: bool) -> NDArray[np.float64]:
    """(n, k) float64 from the bytes off..off + 8k of each row."""
    out = np.ascontiguousarray(buf[:, off:off + 8 * k]).view("<f8" if little else ">f8")
    return out if out.dtype == np.float64 else out.astype(np.float64)


def _structure(lay: _Layout) -> list[tuple[int, int]]:
    """The byte ranges that must be equal in messages of one layout: all but the stamp and the doubles."""
    keep = np.ones(lay.size + 2, dtype=bool)
    keep[0] = keep[-1] = False
    keep[1 + 4:1 + 12] = False
    for off, k in lay.arrays:
        keep[1 + off:1 + off + 8 * k] = False
    edges = np.flatnonzero(np.diff(keep.astype(np.int8)))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def _stamp(raw: bytes, little: bool) -> int:
    sec, nsec = struct.unpack_from("<iI" if little else ">iI", raw, 4)
    return sec * 10**9 + nsec


def _stamps(buf: NDArray[np.uint8], little: bool) -> NDArray[np.int64]:
    e = "<" if little else ">"
    sec = np.ascontiguousarray(buf[:, 4:8]).view(f"{e}i4")[:, 0].astype(np.int64)
    nsec = np.ascontiguousarray(buf[:, 8:12]).view(f"{e}u4")[:, 0].astype(np.int64)
    return sec * 10**9 + nsec


def _doubles(raw: bytes, off: int, k: int, little: bool) -> NDArray[np.float64]:
    return np.frombuffer(raw, dtype="<f8" if little else ">f8", count=k, offset=off).astype(np.float64)


def _one_line(exc: object) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


# --------------------------------------------------------------------------------------------------------- blocks
@dataclass(frozen=True)
class BagBlock:
    """A run of the topic's messages: receive times first..last (ns, inclusive: no other block has a message at
    them), their number, and their header stamps' span (s from the bag's first stamp)."""

    first: int  # index of the block's first message in the topic
    rows: int
    log_lo: int
    log_hi: int
    t_min: float
    t_max: float
    increasing: bool
    one_layout: bool = False  # every message of the block has the first's layout (checked when indexed)


@dataclass(frozen=True)
class BagScan:
    """What one pass over the topic found: its name, the first stamp (ns), the joints and the fields each has
    samples of, and the blocks."""

    topic: str
    t0_ns: int
    joints: tuple[str, ...]
    fields: dict[str, tuple[str, ...]]  # joint -> the fields with at least one sample
    blocks: tuple[BagBlock, ...]
    count: int
    # every channel's stamps (s) when they all share them (every message names the same joints, with the same
    # arrays filled: a driver's usual output), else None: a planner's pass over the stamps need not read the bag
    stamps: NDArray[np.float64] | None = None


def _batches(bag: _Bag, size: int, start: int | None = None, stop: int | None = None
             ) -> Iterator[tuple[NDArray[np.int64], list[Piece]]]:
    """The topic's messages in runs of at least `size` (receive times, pieces), cut only where the receive time
    grows, so that a run is exactly the messages of its receive-time span."""
    times: list[NDArray[np.int64]] = []
    pieces: list[Piece] = []
    n = 0
    for t, p in bag.runs(start, stop):
        times.append(t)
        pieces.append(p)
        n += t.size
        while n >= size:
            every = np.concatenate(times) if len(times) > 1 else times[0]
            grows = np.flatnonzero(every[size:] > every[size - 1:-1])
            if not grows.size:
                break  # the last receive time may go on in the next run
            c = size + int(grows[0])
            head, pieces = _split(pieces, c)
            yield every[:c], head
            times, n = [every[c:]], every.size - c
    if n:
        yield np.concatenate(times), pieces


def seconds(stamps: NDArray[np.int64], t0_ns: int) -> NDArray[np.float64]:
    """Header stamps (ns) as s from t0_ns (the difference exact in integers, then one rounding)."""
    return (stamps - np.int64(t0_ns)).astype(np.float64) / 1e9


def scan_bag(path: str | os.PathLike[str], *, topic: str | None = None, block_rows: int = BLOCK_MESSAGES
             ) -> BagScan:
    """One pass over the topic (memory: one block of messages): its blocks, joints and first stamp, every message
    decoded (so that a damaged one is reported now)."""
    label = os.fspath(path)
    blocks: list[BagBlock] = []
    joints: dict[str, set[str]] = {}
    t0: int | None = None
    n = 0
    shared: list[NDArray[np.float64]] | None = []  # the stamps while every channel has every message
    signature = None
    with opened(label, topic) as bag:
        dec = _Decoder(bag)
        for times, pieces in _batches(bag, block_rows):
            d = dec.decode(pieces, n, fields=())  # the stamps and which fields each joint has: no numbers
            if t0 is None:
                t0 = int(d.stamps[0])
            for j, name in enumerate(d.joints):
                have = joints.setdefault(name, set())
                have.update(f for f in FIELDS if d.has(f, j))
            t = seconds(d.stamps, t0)
            sig = (tuple(d.joints), tuple(f for f in FIELDS if d.present[f] is None))
            partial = any(p is not None and p.any() for p in d.present.values())
            if shared is not None and not partial and signature in (None, sig):
                shared.append(t)
                signature = sig
            else:
                shared = None
            blocks.append(BagBlock(n, t.size, int(times[0]), int(times[-1]), float(t.min()), float(t.max()),
                                   bool(np.all(t[1:] >= t[:-1])), d.layouts == 1))
            n += t.size
        name = bag.topic
    if not blocks:
        raise FileFormatError(f"{label}: topic {name} has no message; record the joint states", source=label,
                              channel=name)
    if n > 1 and all(b.t_min == b.t_max == 0.0 for b in blocks):
        raise FileFormatError(f"{label}: the {n} messages of topic {name} all have the header stamp "
                              f"{t0 // 10**9}.{t0 % 10**9:09d} s: the publisher does not stamp them; stamp each "
                              "message with the time its sample was taken (header.stamp)", source=label, channel=name)
    fields = {j: tuple(f for f in FIELDS if f in have) for j, have in joints.items()}
    stamps = None if shared is None else np.concatenate(shared)
    return BagScan(name, int(t0), tuple(joints), fields, tuple(blocks), n, stamps)  # type: ignore[arg-type]


def first_joints(path: str | os.PathLike[str], *, topic: str | None = None) -> tuple[str, ...]:
    """The joint names of the topic's first message (what a planner needs before indexing the bag)."""
    label = os.fspath(path)
    with opened(label, topic) as bag:
        for _, piece in bag.runs():
            if len(piece):
                first = piece[0] if isinstance(piece, list) else piece[0].tobytes()
                return _Decoder(bag).layout(first, 0).names
        raise FileFormatError(f"{label}: topic {bag.topic} has no message; record the joint states", source=label,
                              channel=bag.topic)


def block_columns(path: str | os.PathLike[str], topic: str, block: BagBlock, t0_ns: int, names: Sequence[str]
                  ) -> list[Column]:
    """The block's time column ("time", s) and the channels `names` ("joint.field") as table columns (a channel
    absent from a message has no sample there)."""
    label = os.fspath(path)
    with opened(label, topic) as bag:
        pieces = [p for _, p in bag.runs(block.log_lo, block.log_hi + 1)]
        got = sum(map(len, pieces))
        if got != block.rows:
            raise FileFormatError(f"{label}: topic {topic} has {got} message(s) received in "
                                  f"{block.log_lo}..{block.log_hi} ns where it had {block.rows} when indexed; index "
                                  "the bag again", source=label, channel=topic)
        d = _Decoder(bag).decode(pieces, block.first, block.one_layout, {n.rpartition(".")[2] for n in names})
    return _columns(d, t0_ns, names)


def _columns(d: Decoded, t0_ns: int, names: Sequence[str]) -> list[Column]:
    where = {channel_name(j, f): (f, k) for k, j in enumerate(d.joints) for f in FIELDS}
    cols = [Column("time", "s", seconds(d.stamps, t0_ns))]
    R = d.stamps.size
    for name in names:
        if name not in where:
            cols.append(Column(name, "", np.empty(0), np.zeros(R, dtype=bool)))
            continue
        f, k = where[name]
        mask = d.mask(f, k)
        values = np.ascontiguousarray(d.values[f][:, k])
        cols.append(Column(name, "", values, None) if mask is None or mask.all()
                    else Column(name, "", values[mask], mask))
    return cols


# ------------------------------------------------------------------------------------------------- whole-bag reader
def read_rosbag(path: str | os.PathLike[str], *, topic: str | None = None,
                channels: Sequence[str] | None = None) -> Recording:
    """Read a JointState topic of a ROS 2 bag into a `Recording` (layout in the module docstring).

    Parameters
    ----------
    path : a bag folder (with metadata.yaml), or a .db3 or .mcap storage file.
    topic : the JointState topic ("/joint_states"); None: the bag's only one.
    channels : keep only these channels ("joint.field"; the others listed in `Recording.skipped`).

    Memory: the channels kept (8 bytes a sample) and one block of messages.
    """
    label = os.fspath(path)
    with opened(label, topic) as bag:
        dec = _Decoder(bag)
        total = bag.count
        stamps = np.empty(total, dtype=np.int64)
        # channel -> [values, presence or None (every message so far has it)]; NaN where absent
        store: dict[str, list] = {}
        fields: dict[str, set[str]] = {}
        n = 0
        wanted = FIELDS if channels is None else {c.rpartition(".")[2] for c in channels}
        for _, pieces in _batches(bag, BLOCK_MESSAGES):
            d = dec.decode(pieces, n, fields=wanted)
            R = d.stamps.size
            if n + R > stamps.size:  # the bag's count was short (a bag folder's metadata): grow
                grow = n + R - stamps.size
                stamps = np.concatenate([stamps, np.empty(grow, dtype=np.int64)])
                for entry in store.values():
                    entry[0] = np.concatenate([entry[0], np.full(grow, np.nan)])
                    entry[1] = None if entry[1] is None else np.concatenate([entry[1], np.zeros(grow, bool)])
            stamps[n:n + R] = d.stamps
            seen = set()
            for k, joint in enumerate(d.joints):
                for f in FIELDS:
                    name = channel_name(joint, f)
                    if name not in store and not d.has(f, k):
                        continue
                    if channels is not None and name not in channels:
                        fields.setdefault(joint, set()).add(f)
                        continue
                    seen.add(name)
                    if name not in store:
                        store[name] = [np.full(stamps.size, np.nan), None if n == 0 else np.zeros(stamps.size, bool)]
                    entry = store[name]
                    entry[0][n:n + R] = d.values[f][:, k]
                    mask = d.mask(f, k)
                    if mask is not None and entry[1] is None:
                        entry[1] = np.ones(stamps.size, dtype=bool)
                    if entry[1] is not None:
                        entry[1][n:n + R] = True if mask is None else mask
            for name, entry in store.items():  # channels of joints this block's messages do not name
                if name not in seen:
                    if entry[1] is None:
                        entry[1] = np.ones(stamps.size, dtype=bool)
                    entry[1][n:n + R] = False
            n += R
        name_of_topic = bag.topic
    if n == 0:
        raise FileFormatError(f"{label}: topic {name_of_topic} has no message; record the joint states",
                              source=label, channel=name_of_topic)
    t0 = int(stamps[0])
    cols = [Column("time", "s", seconds(stamps[:n], t0))]
    del stamps
    for name in list(store):
        v, p = store.pop(name)
        v = v[:n]
        p = None if p is None else p[:n]
        cols.append(Column(name, "", v, None) if p is None or p.all() else Column(name, "", v[p], p))
    skipped = {channel_name(j, f): "not among the channels asked for" for j, fs in fields.items() for f in fs}
    if channels is not None:
        skipped.update({c: f"no such channel on topic {name_of_topic}" for c in channels
                        if c not in skipped and all(col.name != c for col in cols)})
    metadata = {"format": "rosbag", "topic": name_of_topic, "time.start_ns": str(t0)}
    return recording_from_columns(Path(label), cols, time="time", fs=None, metadata=metadata, skipped=skipped)
