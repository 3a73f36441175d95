"""ROS 2 bags (issue 26, item 5): sensor_msgs/JointState from rosbag2 files, SQLite3 and MCAP.

Oracle: the CSV route of the same samples. A simulated puma560 log (q a Fourier trajectory, tau the model's
inverse dynamics at the instants the samples were taken, plus noise) with irregular stamps (jitter, holes) is
written both as a CSV (time column, written here with NumPy) and as a bag by rosbags' own writer, each message
serialized by rosbags' typestore; `dynid identify` on either gives the same estimate (1e-12). The bag's messages
name the joints in another order than the model, some in a third order, and carry a gripper joint the model
does not have (ignore_joints). Bad bags give exit 2 and one line naming the bag and the fix.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import dynid
from dynid.cli.main import main
from dynid.io import read_recording

pytest.importorskip("rosbags")
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

FS = 1000.0
DURATION = 12.0
JOINTS = ["waist", "shoulder", "elbow", "wrist_roll", "wrist_bend", "flange"]
STORE = get_typestore(Stores.ROS2_HUMBLE)
JS = STORE.types["sensor_msgs/msg/JointState"]
T0_NS = 1_732_700_000_123_456_789  # an epoch stamp, as a robot's clock gives

CONFIG = """
[model]
file = "puma_named.toml"

[[tests]]
name = "t"
{test}

[conditioning]
cutoff = 20.0
decimate = [10, 5]
"""


def fourier(t: np.ndarray, seed: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    w = 2 * np.pi * 0.1 * np.arange(1, 6)
    a, b = rng.normal(0, 0.25, (2, 6, 5)) / np.arange(1, 6)
    q0 = rng.uniform(-0.5, 0.5, 6)
    s, c = np.sin(np.multiply.outer(t, w)), np.cos(np.multiply.outer(t, w))
    return q0 + s @ a.T + c @ b.T, (c * w) @ a.T - (s * w) @ b.T, -(s * w**2) @ a.T - (c * w**2) @ b.T


def message(stamp_ns: int, names: list[str], q: np.ndarray, qd: np.ndarray, tau: np.ndarray):
    H, T = STORE.types["std_msgs/msg/Header"], STORE.types["builtin_interfaces/msg/Time"]
    return JS(header=H(stamp=T(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9), frame_id=""), name=names,
              position=np.asarray(q, float), velocity=np.asarray(qd, float), effort=np.asarray(tau, float))


def write_bag(path: Path, plugin, messages, topic: str = "/joint_states", others=()) -> Path:
    """A rosbag2 folder written by rosbags: messages = [(receive ns, JointState)]; others = [(topic, type)]."""
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conn = w.add_connection(topic, JS.__msgtype__, typestore=STORE)
        for name, msgtype in others:
            w.add_connection(name, msgtype, typestore=STORE)
        for ns, msg in messages:
            w.write(conn, ns, STORE.serialize_cdr(msg, JS.__msgtype__))
    return path


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    """The samples: irregular header stamps (jitter +-0.1 ms, holes of up to 8 samples), q, qd, tau."""
    d = tmp_path_factory.mktemp("bag")
    text = (Path(dynid.__file__).parent / "model" / "examples" / "puma560.toml").read_text()
    names = "\n".join(f'{j} = "{n}"' for j, n in enumerate(JOINTS, start=1))
    (d / "puma_named.toml").write_text(f"{text}\n[joints]\n{names}\n")
    model = dynid.load_model(d / "puma_named.toml")
    n = int(DURATION * FS)
    rng = np.random.default_rng(11)
    keep = np.ones(n, bool)
    for i, h in enumerate(rng.choice(np.arange(100, n - 100), 20, replace=False)):
        keep[h:h + (8 if i % 4 == 0 else rng.integers(1, 5))] = False
    stamp_ns = T0_NS + np.round((np.arange(n) / FS + rng.uniform(-1e-4, 1e-4, n)) * 1e9).astype(np.int64)[keep]
    t = (stamp_ns - stamp_ns[0]).astype(float) / 1e9
    q, qd, qdd = fourier(t)
    tau = model.inverse_dynamics(q, qd, qdd) + rng.normal(0, 0.05, (t.size, 6))
    # the CSV of the same samples (the oracle's route): time from the first stamp, numbers written exactly
    cols = ["time"] + [f"q{i}" for i in range(1, 7)] + [f"tau{i}" for i in range(1, 7)]
    with open(d / "log.csv", "w") as fh:
        fh.write(",".join(cols) + "\n")
        for row in np.column_stack([t, q, tau]).tolist():
            fh.write(",".join(map(repr, row)) + "\n")
    return d, stamp_ns, q, qd, tau


def bag_messages(stamp_ns, q, qd, tau, *, gripper: bool = True):
    """The driver's messages: joints in another order than the model's, every 7th in a third order, a gripper."""
    order = [2, 0, 1, 5, 3, 4]
    out = []
    for k, ns in enumerate(stamp_ns.tolist()):
        o = order if k % 7 else order[::-1]
        names = [JOINTS[i] for i in o] + (["gripper"] if gripper else [])
        tail = [0.01] if gripper else []
        out.append((ns + 250_000, message(ns, names, [*q[k, o], *tail], [*qd[k, o], *tail], [*tau[k, o], *tail])))
    return out


@pytest.fixture(scope="module", params=[StoragePlugin.SQLITE3, StoragePlugin.MCAP], ids=["sqlite3", "mcap"])
def bag(request, log):
    d, stamp_ns, q, qd, tau = log
    return write_bag(d / f"run_{request.param.name.lower()}", request.param, bag_messages(stamp_ns, q, qd, tau))


def identify_cli(d: Path, test: str, out: str, capsys=None) -> dict[str, float]:
    cfg = d / f"{out}.toml"
    cfg.write_text(CONFIG.format(test=test))
    rc = main(["identify", str(cfg), "--out", str(d / out)])
    assert rc == 0
    if capsys is not None:
        said = capsys.readouterr()
        text = said.out + said.err
        # the stamps checked and resampled as a CSV time column's are (tests/pipeline/test_robot_time.py)
        assert "resampled onto a uniform clock" in text and "jitter" in text, text
    data = json.loads((d / out / "results.json").read_text())
    return {p["name"]: p["value"] for p in data["parameters"]}


@pytest.fixture(scope="module")
def csv_estimate(log):
    d = log[0]
    return identify_cli(d, 'files = { q = "log.csv", tau = "log.csv" }\n'
                           '[channels]\nq = { channels = ["q1", "q2", "q3", "q4", "q5", "q6"], unit = "rad" }\n'
                           'tau = { channels = ["tau1", "tau2", "tau3", "tau4", "tau5", "tau6"], unit = "N.m" }',
                        "csv")


@pytest.mark.parametrize("which", ["folder", "storage file"])
def test_a_bag_gives_the_estimate_of_the_csv_of_the_same_samples(log, bag, csv_estimate, which, capsys):
    d = log[0]
    path = bag if which == "folder" else next(p for p in bag.iterdir() if p.suffix in (".db3", ".mcap"))
    capsys.readouterr()
    got = identify_cli(d, f'file = "{path}"\ntopic = "/joint_states"\nignore_joints = ["gripper"]',
                       f"{bag.name}_{which.replace(' ', '_')}", capsys)
    assert got.keys() == csv_estimate.keys()
    for name, value in csv_estimate.items():
        assert got[name] == pytest.approx(value, rel=1e-12, abs=1e-12 * max(map(abs, csv_estimate.values()))), name


def test_the_channels_are_the_header_stamps_and_the_messages_values(log, bag):
    """read_recording against rosbags' own deserializer, message by message (an independent decoder)."""
    from rosbags.rosbag2 import Reader

    rec = read_recording(bag)
    want_t, want = [], {}
    with Reader(bag) as r:
        for conn, _, raw in r.messages():
            m = STORE.deserialize_cdr(raw, conn.msgtype)
            ns = m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
            want_t.append(ns)
            for name, p, v, e in zip(m.name, m.position, m.velocity, m.effort, strict=True):
                for field, x in (("position", p), ("velocity", v), ("effort", e)):
                    want.setdefault(f"{name}.{field}", []).append(x)
    t = (np.array(want_t) - want_t[0]) / 1e9
    assert sorted(rec.channels) == sorted(want)
    for name, values in want.items():
        np.testing.assert_array_equal(rec.channels[name].values, values)
        np.testing.assert_array_equal(rec.channels[name].time, t)
    assert rec.metadata["time.start_ns"] == str(want_t[0]) and rec.metadata["topic"] == "/joint_states"


def test_messages_without_velocity_and_a_joint_in_some_messages_only(tmp_path):
    """An empty array is no sample (as an empty CSV cell), a joint absent from a message too."""
    msgs = []
    for k in range(10):
        names = ["a", "b"] if k % 2 else ["a"]
        vals = [k, 10 + k] if k % 2 else [k]
        msgs.append((k, message(T0_NS + k * 10**6, names, vals, [] if k < 5 else vals, vals)))
    rec = read_recording(write_bag(tmp_path / "b", StoragePlugin.MCAP, msgs))
    np.testing.assert_array_equal(rec.channels["a.position"].values, np.arange(10))
    np.testing.assert_array_equal(rec.channels["b.position"].values, [11, 13, 15, 17, 19])
    np.testing.assert_array_equal(rec.channels["b.position"].time, [0.001, 0.003, 0.005, 0.007, 0.009])
    np.testing.assert_array_equal(rec.channels["a.velocity"].values, [5, 6, 7, 8, 9])


def cli_error(d: Path, test: str, capsys) -> str:
    cfg = d / "bad.toml"
    cfg.write_text(CONFIG.format(test=test))
    rc = main(["identify", str(cfg), "--out", str(d / "bad_out")])
    err = capsys.readouterr().err.strip()
    last = err.splitlines()[-1]
    assert rc == 2 and last.startswith("dynid: error:") and "Traceback" not in err, err
    return last


@pytest.fixture
def small(log, tmp_path):
    d, stamp_ns, q, qd, tau = log
    model_file = tmp_path / "puma_named.toml"
    model_file.write_text((d / "puma_named.toml").read_text())
    return tmp_path, bag_messages(stamp_ns[:3000], q, qd, tau)


def test_a_missing_topic_lists_the_bags_topics(small, capsys):
    d, msgs = small
    write_bag(d / "b", StoragePlugin.SQLITE3, msgs, others=[("/tf", "tf2_msgs/msg/TFMessage")])
    last = cli_error(d, 'file = "b"\ntopic = "/joint_state"', capsys)
    assert "no topic '/joint_state'" in last and "/joint_states (sensor_msgs/msg/JointState)" in last
    assert "/tf (tf2_msgs/msg/TFMessage)" in last and "give one of them" in last


def test_several_joint_state_topics_ask_for_one(small, capsys):
    d, msgs = small
    write_bag(d / "b", StoragePlugin.MCAP, msgs, others=[("/arm2/joint_states", JS.__msgtype__)])
    last = cli_error(d, 'file = "b"\nignore_joints = ["gripper"]', capsys)
    assert "2 sensor_msgs/msg/JointState topics" in last and 'topic = "/arm2/joint_states"' in last


def test_a_joint_the_model_does_not_have(small, capsys):
    d, msgs = small
    write_bag(d / "b", StoragePlugin.MCAP, msgs)
    last = cli_error(d, 'file = "b"', capsys)
    assert "joint 'gripper'" in last and "not a joint of the model" in last and 'ignore_joints = ["gripper"]' in last


def stamp_of(m) -> int:
    return m.header.stamp.sec * 10**9 + m.header.stamp.nanosec


def without(m, joint: str):
    """The message m without `joint`."""
    keep = [i for i, n in enumerate(m.name) if n != joint]
    return message(stamp_of(m), [m.name[i] for i in keep], *(getattr(m, f)[keep] for f in ("position", "velocity",
                                                                                            "effort")))


def test_a_model_joint_missing_from_the_messages(small, capsys):
    d, msgs = small
    msgs = [(ns, without(m, "elbow")) for ns, m in msgs]
    write_bag(d / "b", StoragePlugin.SQLITE3, msgs)
    last = cli_error(d, 'file = "b"\nignore_joints = ["gripper"]', capsys)
    assert "joint 'elbow' is not in the messages" in last and "[joints]" in last


def test_mismatched_arrays_name_the_message(small, capsys):
    d, msgs = small
    ns, m = msgs[1234]
    msgs[1234] = (ns, message(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec, list(m.name), m.position,
                              m.velocity, m.effort[:5]))
    write_bag(d / "b", StoragePlugin.MCAP, msgs)
    last = cli_error(d, 'file = "b"\nignore_joints = ["gripper"]', capsys)
    stamp = f"{m.header.stamp.sec}.{m.header.stamp.nanosec:09d}"
    assert "message 1234" in last and stamp in last and "7 joint name(s) but 5 effort value(s)" in last


@pytest.mark.parametrize("storage", [".db3", ".mcap"])
def test_a_corrupt_bag_is_one_line(small, capsys, storage):
    d, msgs = small
    plugin = StoragePlugin.SQLITE3 if storage == ".db3" else StoragePlugin.MCAP
    folder = write_bag(d / "b", plugin, msgs)
    f = next(folder.glob(f"*{storage}"))
    data = bytearray(f.read_bytes())
    f.write_bytes(bytes(data[: len(data) // 2]))  # a recording cut short
    last = cli_error(d, f'file = "b/{f.name}"\nignore_joints = ["gripper"]', capsys)
    assert f.name in last and ("unreadable ROS 2 bag" in last or "not a rosbag2" in last), last


def test_unstamped_messages_are_refused(small, capsys):
    d, msgs = small
    msgs = [(ns, message(0, list(m.name), m.position, m.velocity, m.effort)) for ns, m in msgs]
    write_bag(d / "b", StoragePlugin.SQLITE3, msgs)
    last = cli_error(d, 'file = "b"\nignore_joints = ["gripper"]', capsys)
    assert "all have the header stamp 0.000000000 s" in last and "does not stamp them" in last


def test_topic_on_a_csv_test_is_refused(log, capsys):
    d = log[0]
    last = cli_error(d, 'file = "log.csv"\ntopic = "/joint_states"', capsys)
    assert "topic is for a ROS 2 bag" in last


@pytest.mark.parametrize("plugin", [StoragePlugin.SQLITE3, StoragePlugin.MCAP], ids=["sqlite3", "mcap"])
@pytest.mark.parametrize("layouts", ["one layout", "two layouts"])
def test_windows_are_the_whole_reads_samples(log, tmp_path, plugin, layouts):
    """Windows of small blocks (dynid.io.windows) give, bit for bit, the whole bag's samples in their time span,
    also where a block's messages were checked to share one layout when indexed and are not compared again."""
    from dynid.io.windows import index_file, read_window, time_bases

    _, stamp_ns, q, qd, tau = log
    msgs = bag_messages(stamp_ns[:5000], q, qd, tau, gripper=False)
    if layouts == "one layout":
        msgs = [(ns, message(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec, JOINTS, q[k], qd[k], tau[k]))
                for k, (ns, m) in enumerate(msgs)]
    bag = write_bag(tmp_path / "b", plugin, msgs)
    whole = read_recording(bag)
    index = index_file(bag, block_rows=700)
    assert {b.group for b in index.blocks} == ({1} if layouts == "one layout" else {0})
    names = [f"{j}.{f}" for j in JOINTS for f in ("position", "effort")]
    (members, stamps, _), = time_bases(index, names)
    assert members == names
    np.testing.assert_array_equal(stamps, whole.channels[names[0]].time)
    for a, b in ((0.0, 5.0), (0.7, 1.9), (2.5, 2.5005), (4.0, 9.0)):
        got = read_window(index, names, a, b)
        for n in names:
            ch = whole.channels[n]
            keep = (ch.time >= a) & (ch.time <= b)
            np.testing.assert_array_equal(got.channels[n].values, ch.values[keep])
            np.testing.assert_array_equal(got.channels[n].time, ch.time[keep])


def test_a_panda_bag_without_the_gripper_holds_it_still(tmp_path):
    """The Panda imported from example-robot-data as it is (the fingers a mimic pair), its arm's /joint_states
    in a bag: the gripper, absent from the messages, is held still as with a CSV log
    (tests/pipeline/test_robot_gripper.py), and the estimate is that of the CSV of the same samples."""
    from test_robot_gripper import ARM, DURATION, FS, SIGMA, config, trajectory
    from test_urdf import robot_file

    from dynid import Model
    from dynid.model import save_tree
    from dynid.model.urdf import import_urdf
    from dynid.pipeline.config import load_config
    from dynid.pipeline.run import identify

    path = robot_file("panda")
    save_tree(import_urdf(path).tree, tmp_path / "panda.toml")
    t = np.arange(int(DURATION * FS)) / FS
    q, qd, qdd = trajectory(t, 7)
    tau = Model(import_urdf(path, joints=ARM).tree).inverse_dynamics(q, qd, qdd)
    tau += SIGMA * np.random.default_rng(7).normal(size=q.shape)
    stamp_ns = T0_NS + np.round(t * 1e9).astype(np.int64)
    t = (stamp_ns - stamp_ns[0]) / 1e9
    with open(tmp_path / "arm.csv", "w") as fh:  # the numbers written exactly (repr), as the bag holds them
        fh.write(",".join(["time [s]", *(f"q_{n} [rad]" for n in ARM), *(f"tau_{n} [N.m]" for n in ARM)]) + "\n")
        for row in np.column_stack([t, q, tau]).tolist():
            fh.write(",".join(map(repr, row)) + "\n")
    write_bag(tmp_path / "arm_bag", StoragePlugin.MCAP,
              [(ns, message(ns, ARM, q[k], qd[k], tau[k])) for k, ns in enumerate(stamp_ns.tolist())])
    said: list[str] = []
    via_csv = identify(load_config(config(tmp_path, "csv", tmp_path / "panda.toml", tmp_path / "arm.csv", ARM)))
    cfg = tmp_path / "bag.toml"
    cfg.write_text('[model]\nfile = "panda.toml"\n\n[[tests]]\nname = "excitation"\nfile = "arm_bag"\n\n'
                   "[conditioning]\ncutoff = 10.0\norder = 4\ndecimate = [5]\n")
    via_bag = identify(load_config(cfg), progress=said.append)
    assert any("panda_finger_joint1, panda_finger_joint2" in s and "held still" in s for s in said), said
    assert via_bag.result.names == via_csv.result.names
    np.testing.assert_allclose(via_bag.result.values, via_csv.result.values, rtol=1e-12,
                               atol=1e-12 * np.abs(via_csv.result.values).max())


@pytest.mark.parametrize("plugin", [StoragePlugin.SQLITE3, StoragePlugin.MCAP], ids=["sqlite3", "mcap"])
def test_a_topic_among_others_interleaved(tmp_path, plugin):
    """Two JointState topics recorded together (messages alternating, the other's in runs too): the topic asked for
    reads exactly its messages, in rosbags' order (rosbags' own reader as the oracle)."""
    from rosbags.rosbag2 import Reader

    with Writer(tmp_path / "b", version=9, storage_plugin=plugin) as w:
        arm = w.add_connection("/joint_states", JS.__msgtype__, typestore=STORE)
        other = w.add_connection("/gripper/joint_states", JS.__msgtype__, typestore=STORE)
        for k in range(3000):
            ns = T0_NS + k * 10**6
            w.write(arm, ns, STORE.serialize_cdr(message(ns, JOINTS, np.full(6, k), np.zeros(6), np.ones(6)),
                                                 JS.__msgtype__))
            for r in range(1 if k < 1500 else 3):  # alternating, then runs of three
                w.write(other, ns + r, STORE.serialize_cdr(message(ns + r, ["finger"], [-k], [], []), JS.__msgtype__))
    rec = read_recording(tmp_path / "b", topic="/joint_states")
    want = []
    with Reader(tmp_path / "b") as r:
        conns = [c for c in r.connections if c.topic == "/joint_states"]
        want = [STORE.deserialize_cdr(raw, c.msgtype).position[0] for c, _, raw in r.messages(conns)]
    np.testing.assert_array_equal(rec.channels["waist.position"].values, want)
    assert "finger.position" not in rec.channels
    grip = read_recording(tmp_path / "b", topic="/gripper/joint_states")
    assert len(grip.channels["finger.position"]) == 1500 + 3 * 1500 and "finger.velocity" not in grip.channels


@pytest.mark.parametrize("plugin", [StoragePlugin.SQLITE3, StoragePlugin.MCAP], ids=["sqlite3", "mcap"])
@pytest.mark.parametrize("mode", ["file", "message"])
def test_compressed_bags(tmp_path, plugin, mode):
    """rosbag2's zstd compression, of the whole storage file or of each message (`ros2 bag record
    --compression-mode`), read as the uncompressed bag, whole and by windows."""
    from rosbags.rosbag2 import CompressionFormat, CompressionMode

    from dynid.io.windows import index_file, read_window

    w = Writer(tmp_path / "b", version=9, storage_plugin=plugin)
    w.set_compression(CompressionMode.FILE if mode == "file" else CompressionMode.MESSAGE, CompressionFormat.ZSTD)
    with w:
        conn = w.add_connection("/joint_states", JS.__msgtype__, typestore=STORE)
        for k in range(2000):
            ns = T0_NS + k * 10**6
            w.write(conn, ns, STORE.serialize_cdr(message(ns, JOINTS, np.full(6, k), np.zeros(6), np.ones(6)),
                                                  JS.__msgtype__))
    rec = read_recording(tmp_path / "b")
    np.testing.assert_array_equal(rec.channels["waist.position"].values, np.arange(2000))
    np.testing.assert_array_equal(rec.channels["waist.position"].time, np.arange(2000) / 1000)
    got = read_window(index_file(tmp_path / "b", block_rows=300), ["flange.position"], 0.5, 1.2)
    np.testing.assert_array_equal(got.channels["flange.position"].values, np.arange(500, 1201))
