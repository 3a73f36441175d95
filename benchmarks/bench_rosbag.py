"""Benchmark of reading ROS 2 bags: 1 h of sensor_msgs/JointState at 1 kHz, 7 joints (3.6 M messages).

Target (issue 26): <= 10 s and <= 500 MB. The bag is written once per storage (SQLite3, MCAP; not timed, a few
minutes: the messages are made from one message serialized by rosbags' typestore, its stamp and numbers patched),
then each measurement runs in a fresh process so that its peak resident memory (getrusage) is its own:

- "index + plan": index_file and time_bases of the 14 channels an identification needs (positions and efforts):
  the pass `dynid identify` makes before reading its windows;
- "+ windows": the same, then every sample read in 60 s windows (`read_window`), as the identification's chunks
  read them: what reading a bag costs `dynid identify`;
- "read whole": read_recording of the 14 channels at once (8 bytes a sample each: 403 MB of numbers for an hour,
  besides the ~170 MB that importing dynid costs, so this one cannot fit 500 MB).

Times are wall clock and CPU (user + system): the machine is shared, and the CPU time is what an idle one takes.

Run: python benchmarks/bench_rosbag.py [--minutes 60] [--keep DIR]   (needs rosbags: pip install 'dynid[ros]')
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

JOINTS = [f"panda_joint{i}" for i in range(1, 8)]
FS = 1000
T0_NS = 1_732_700_000_000_000_000


def write_bag(path: Path, storage: str, n: int) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    js = store.types["sensor_msgs/msg/JointState"]
    header, stamp = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    one = js(header=header(stamp=stamp(sec=0, nanosec=0), frame_id="panda_link0"), name=JOINTS,
             position=np.full(7, 1.5), velocity=np.full(7, 2.5), effort=np.full(7, 3.5))
    raw = np.frombuffer(bytes(store.serialize_cdr(one, js.__msgtype__)), dtype=np.uint8)
    spots = {v: _find(raw, v) for v in (1.5, 2.5, 3.5)}
    plugin = StoragePlugin.SQLITE3 if storage == "sqlite3" else StoragePlugin.MCAP
    rng = np.random.default_rng(0)
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conn = w.add_connection("/joint_states", js.__msgtype__, typestore=store)
        for a in range(0, n, 100_000):
            k = np.arange(a, min(n, a + 100_000))
            ns = T0_NS + k * (10**9 // FS) + rng.integers(-50_000, 50_000, k.size)  # jittered header stamps
            buf = np.tile(raw, (k.size, 1))
            buf[:, 4:8] = (ns // 10**9).astype("<i4").view(np.uint8).reshape(-1, 4)
            buf[:, 8:12] = (ns % 10**9).astype("<u4").view(np.uint8).reshape(-1, 4)
            t = (k / FS)[:, None]
            for v, off in spots.items():
                x = np.sin(t * (1 + np.arange(7)) * 0.3 + v)
                buf[:, off:off + 56] = x.astype("<f8").view(np.uint8).reshape(-1, 56)
            for row, stamp_ns in zip(buf, ns.tolist(), strict=True):
                w.write(conn, stamp_ns + 200_000, row.tobytes())


def _find(raw: np.ndarray, value: float) -> int:
    """The offset of the 7 doubles equal to value in the serialized template."""
    pattern = np.full(7, value, "<f8").view(np.uint8).tobytes()
    return raw.tobytes().index(pattern)


def measure(what: str, path: str) -> None:
    """One measurement in this (fresh) process: prints wall s, CPU s (user + system: what an idle machine would
    take, the machine being shared), peak resident MB and the samples read."""
    from dynid.io import read_recording
    from dynid.io.windows import index_file, read_window, time_bases

    names = [f"{j}.{f}" for j in JOINTS for f in ("position", "effort")]
    t0, c0 = time.perf_counter(), time.process_time()
    if what == "read":
        n = len(read_recording(path, channels=names).channels[names[0]])
    else:
        index = index_file(path, channels=names)
        stamps = time_bases(index, names)[0][1]
        n = stamps.size
        if what == "windows":  # then every sample in 60 s windows, as `dynid identify` reads a test's chunks
            n = 0
            for a in np.arange(stamps[0], stamps[-1], 60.0):
                n += len(read_window(index, names, a, np.nextafter(a + 60.0, -np.inf)).channels[names[0]])
    dt, cpu = time.perf_counter() - t0, time.process_time() - c0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux
    print(f"{dt:.2f} {cpu:.2f} {peak:.0f} {n}")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--keep", help="a folder to write the bags in (kept; reused when present)")
    ap.add_argument("--measure", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.measure:
        measure(*args.measure)
        return 0
    n = int(args.minutes * 60 * FS)
    tmp = None if args.keep else tempfile.TemporaryDirectory()
    root = Path(args.keep or tmp.name)  # type: ignore[union-attr]
    root.mkdir(parents=True, exist_ok=True)
    print(f"{args.minutes:g} min at {FS} Hz, {len(JOINTS)} joints: {n} JointState messages")
    for storage in ("sqlite3", "mcap"):
        bag = root / f"bag_{storage}_{n}"
        if not bag.exists():
            t0 = time.perf_counter()
            write_bag(bag, storage, n)
            print(f"{storage}: written in {time.perf_counter() - t0:.0f} s (not timed), "
                  f"{sum(f.stat().st_size for f in bag.iterdir()) / 2**20:.0f} MB")
        for what, label in (("plan", "index + plan"), ("windows", "+ windows"), ("read", "read whole")):
            out = subprocess.run([sys.executable, __file__, "--measure", what, str(bag)], capture_output=True,
                                 text=True, check=True).stdout.split()
            dt, cpu, mb, got = float(out[0]), float(out[1]), float(out[2]), int(out[3])
            ok = "ok" if cpu <= 10 and mb <= 500 and got == n else "over target"
            print(f"{storage:>8} {label:<13} {dt:6.2f} s wall {cpu:6.2f} s CPU  peak {mb:5.0f} MB  ({got} samples)  "
                  f"{ok}")
    if tmp is not None:
        tmp.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
