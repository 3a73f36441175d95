"""Identification of a robot from joint positions and joint torques (Gautier's method).

Positions are low-passed without phase shift and differentiated by central differences;
the filter transient is trimmed; W (base columns) and the torques are decimated in
parallel per joint; samples where a joint barely moves are dropped from that joint's
equations (the sign of its Coulomb friction is uncertain there); the rows of every
test are stacked per joint, and each joint is one equation group for weighted LS.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..dynamics import BaseParameters, Model
from ..model.tree import FIXED, INERTIAL, ModelError, Tree, freeze
from ..signals import border_samples, decimate_parallel, derivative, filtered_derivatives
from ..signals.decimation import FirstStage, blocked_rows, decimate_parallel_blocked

Array = np.ndarray


@dataclass(frozen=True)
class Conditioning:
    """How measurements become identification rows.

    cutoff (Hz) and order: zero-phase Butterworth on positions before differentiation
    (the paper: order 5-8 around 3 Hz for a car's ~1 Hz dynamics; a fast arm needs tens
    of Hz). border: seconds trimmed at each end (None: the filter's own transient length).
    decimate: parallel-decimation factors. min_speed: per joint (1-based), rad/s or m/s
    below which that joint's rows are dropped.
    """

    cutoff: float = 25.0
    order: int = 4
    border: float | None = None
    decimate: tuple[int, ...] = (10, 10)
    min_speed: Mapping[int, float] = field(default_factory=dict)


@dataclass(frozen=True)
class JointTest:
    """One test: positions q and joint forces tau, (N, n) each, sampled at fs Hz."""

    name: str
    fs: float
    q: Array
    tau: Array


@dataclass
class GroupedSystem:
    """Stacked identification system: W (m, p), Y (m,), groups (m,) labels, t (m,) sample times, and the
    instruments Z (m, p) of an IDIM-IV pass (None otherwise); kept: which rows of the full (equations x
    samples) grid these are, where a row selection made them (None otherwise)."""

    W: Array
    Y: Array
    groups: Array
    t: Array
    Z: Array | None = None
    kept: Array | None = None

    @staticmethod
    def stack(parts: Sequence[GroupedSystem]) -> GroupedSystem:
        Z = None if any(p.Z is None for p in parts) else np.concatenate([p.Z for p in parts])
        return GroupedSystem(*(np.concatenate([getattr(p, k) for p in parts]) for k in ("W", "Y", "groups", "t")), Z)


@dataclass(frozen=True)
class DataJoints:
    """Which joints a robot's data files give: the model (with the joints the data do not give frozen), the frame
    of each data column, in order, and a note saying what was frozen ("" if nothing)."""

    tree: Tree
    columns: tuple[int, ...]
    note: str = ""


def data_joints(tree: Tree, k: int, selection: Sequence[str] | None = None, source: str = "") -> DataJoints:
    """The joints k data columns are, in frame order:

    - with a selection (joint names: the identified chain, the config's [model] joints), those joints; every
      other moving joint is frozen at 0 with the joints that mimic it (`model.tree.freeze`);
    - else k = n: one column per frame (as the model file's frames; the columns of fixed frames and mimic joints
      are not read); k = the joints with an equation (`Tree.equations`: neither fixed nor mimic); or k = those
      less the joints that others mimic (a gripper's): those are frozen at 0 with their mimics, and said so.
    Anything else is a one-line ModelError naming the counts and the joints."""
    where = f"{source}: " if source else ""
    if selection is not None:
        try:
            frames = [tree.frame_of(name) for name in selection]
        except ModelError as exc:
            raise ModelError(f"{where}[model] joints: {exc}; give names of the model file's [joints] table, or leave "
                             "joints out") from None
        followers = [j for j in frames if j in tree.mimic]
        if followers:
            j = followers[0]
            raise ModelError(f"{where}[model] joints: {tree.joint_names.get(j, j)!r} mimics "
                             f"{tree.joint_names.get(tree.mimic[j].master)!r}; select that joint (its mimics follow)")
        held = {j: 0.0 for j in tree.equations if j not in frames}
        out = freeze(tree, held) if held else tree
        note = (f"joints not selected in [model] joints, held still at 0: {', '.join(out.frozen)}" if held else "")
        if k != len(out.equations):
            raise ModelError(f"{where}the data give {k} joint columns; [model] joints selects {len(out.equations)}")
        return DataJoints(out, out.equations, note)
    if k == tree.n:
        return DataJoints(tree, tuple(range(1, tree.n + 1)))
    if k == len(tree.equations):
        return DataJoints(tree, tree.equations)
    masters = sorted({m.master for m in tree.mimic.values()})
    if masters and k == len(tree.equations) - len(masters):
        out = freeze(tree, dict.fromkeys(masters, 0.0))
        return DataJoints(out, out.equations, f"not in the data (the data give {k} joints), held still at 0 with "
                                              f"the joints that mimic them: {', '.join(out.frozen)}")
    named = ", ".join(tree.joint_names.get(j, str(j)) for j in tree.equations)
    raise ModelError(f"{where}the data give {k} joint columns; model {tree.name!r} has {tree.n} frames, "
                     f"{len(tree.equations)} of them joints with an equation ({named}): give one column per joint, "
                     "or choose the identified joints with [model] joints = [...] (the others are held still)")


def to_frames(a: Array, columns: Sequence[int], n: int) -> Array:
    """(N, k) data columns as (N, n) frame columns (0 in the frames without data: fixed, mimic or frozen)."""
    if len(columns) == n:
        return a
    out = np.zeros((a.shape[0], n))
    out[:, np.asarray(columns) - 1] = a
    return out


def condition(test: JointTest, c: Conditioning) -> tuple[Array, Array, Array, Array, slice]:
    """Filtered q, qd, qdd and the kept slice (borders trimmed), tau on the same samples."""
    q, qd, qdd = filtered_derivatives(test.q, test.fs, c.cutoff, order=c.order, nderiv=2)
    b = border_samples(test.fs, c.cutoff, c.order) if c.border is None else round(c.border * test.fs)
    keep = slice(b, test.q.shape[0] - b)
    return q[keep], qd[keep], qdd[keep], test.tau[keep], keep


# the full-rate regressor of one segment: W is built and decimated a segment at a time, so that memory
# does not grow with the record (a 445 MB log once asked for one 12 GiB W)
SEGMENT_BYTES = 128 * 2**20
DECIMATION_ORDER = 8  # decimate_parallel's default, whose transient sets the segments' overlap
# a chunk's full-rate W is built and put through the first decimation stage a block of this size at a time (with
# the stage's transient around it): a worker holds one block, not the chunk's W (128 MiB for the Panda arm)
BLOCK_BYTES = 8 * 2**20  # a W block; 4 MiB measured: -13 MB per worker for +6.6 % CPU (each block's overlap)


def joint_system(
    model: Model, test: JointTest, base: BaseParameters, c: Conditioning, rows: Sequence[int] | None = None,
    segment_bytes: int = SEGMENT_BYTES,
) -> GroupedSystem:
    """The decimated, per-joint identification rows of one test on the base parameters.

    A record whose full-rate W would exceed `segment_bytes` is done in segments that overlap by the decimation
    filter's transient: each segment's decimated rows are those a whole-record decimation gives, to the
    filter's tail beyond the overlap (1e-9 of the signal), so the result does not depend on the segmenting."""
    rows = list(model.tree.equations) if rows is None else list(rows)
    q, qd, qdd, tau, keep = condition(test, c)
    Y = tau[:, np.array(rows) - 1]
    t = (np.arange(test.q.shape[0])[keep] / test.fs)
    D = int(np.prod(c.decimate))
    n = q.shape[0]
    length = max(D, segment_bytes // (8 * len(rows) * len(base.columns)) // D * D)  # samples, a multiple of D
    pad = 0 if n <= length else _decimation_transient(test.fs, c.decimate)
    Wd_parts, Yd_parts, speed_parts = [], [], []
    for start in range(0, n, length):
        end = min(n, start + length)
        lo, hi = max(0, start - pad), min(n, end + pad)  # lo = start - pad stays on the decimation grid (pad % D == 0)
        W = np.ascontiguousarray(model.regressor(q[lo:hi], qd[lo:hi], qdd[lo:hi], rows=rows, cols=list(base.columns)))
        # decimate W, Y and the speeds with the same filter, so that the speed test sees the decimated samples
        Wd, Yd = decimate_parallel(W, Y[lo:hi], c.decimate, test.fs, order=DECIMATION_ORDER)
        del W
        speed, _ = decimate_parallel(qd[lo:hi], None, c.decimate, test.fs, order=DECIMATION_ORDER)  # as W's columns
        kept = slice((start - lo) // D, -(-(end - lo) // D))  # output k is input lo + k D
        Wd_parts.append(Wd[kept])
        Yd_parts.append(Yd[kept])
        speed_parts.append(speed[kept])
    Wd, Yd, speed = (np.concatenate(p) for p in (Wd_parts, Yd_parts, speed_parts))
    td = t[::D][: Wd.shape[0]]
    parts = []
    for i, j in enumerate(rows):
        ok = np.abs(speed[:, j - 1]) >= c.min_speed.get(j, 0.0)
        parts.append(GroupedSystem(Wd[ok, i], Yd[ok, i], np.full(int(ok.sum()), f"joint{j}"), td[ok]))
    return GroupedSystem.stack(parts)


# a worker's arrays that grow with its chunk's length, per chunk: the chunk's length is what keeps them under this
# (`chunk_sample_bytes`); beside them it holds one W block (`BLOCK_BYTES`) and the pads' samples (`chunk_pad`).
# Shorter chunks cost CPU: each computes W and its decimation on the decimation's transient around it (9,800 samples
# for the Panda arm at 1 kHz, decimate = [10, 10]) and filters a bit more: 28 MiB is 55,600 samples of the Panda's,
# as its full-rate W's 128 MiB set before W was built a block at a time; 20 MiB (39,700) took ~30 MB off the peak of
# benchmarks/bench_robot_memory.py at +12 % of its CPU
CHUNK_BYTES = 28 * 2**20


def chunk_sample_bytes(model: Model, base: BaseParameters, c: Conditioning) -> int:
    """Bytes a worker holds per sample of its chunk (`chunk_rows`): the window's q and tau and the filtered q, qd,
    qdd (the model's frames each), and W1, the first decimation stage's output of W (every column: a bound). qd and
    qdd are made a W block at a time since, so this over-counts them: kept as it was, the chunks' boundaries (and
    the estimate's bits) stay where they were."""
    return 8 * (5 * model.n + -(-len(model.tree.equations) * len(base.columns) // c.decimate[0]))


def robot_chunks(n_samples: int, fs: float, model: Model, base: BaseParameters, c: Conditioning,
                 chunk_bytes: int | None = None) -> tuple[tuple[int, int], ...]:
    """The kept samples of a test of n_samples (its filter borders trimmed) cut into chunks, each a multiple of the
    whole decimation factor long, what a worker holds for its samples under `chunk_bytes` (`CHUNK_BYTES`,
    `chunk_sample_bytes`): one job each (`chunk_rows`)."""
    b = _border(fs, c)
    D = int(np.prod(c.decimate))
    length = max(D, (chunk_bytes or CHUNK_BYTES) // chunk_sample_bytes(model, base, c) // D * D)
    return tuple((s, min(n_samples - b, s + length)) for s in range(b, n_samples - b, length))


def chunk_pad(fs: float, c: Conditioning) -> int:
    """Samples read beyond a chunk's ends: the decimation's transient, and the zero-phase filter's (to 1e-12 of
    its weight) with the central differences' stencil, so that a chunk's rows are the whole record's."""
    return _decimation_transient(fs, c.decimate) + border_samples(fs, c.cutoff, c.order, tol=1e-12) + 4


def chunk_rows(model: Model, base: BaseParameters, c: Conditioning, q: Array | None, tau: Array, fs: float, first: int,
               chunk: tuple[int, int], n_samples: int, rows: Sequence[int] | None = None, gains: Array | None = None,
               payload: tuple[int, Array] | None = None, threads: int = 1,
               filtered: tuple[Array, Array] | None = None,
               blocks_done: Callable[[], None] | None = None, buffers: list[Array] | None = None,
               before: FirstStage | None = None, after: Callable[[FirstStage], None] | None = None) -> GroupedSystem:
    """The rows `joint_system` gives for the kept samples chunk = (s, e) of a test of n_samples, from the samples
    first..first + len(q) of it (q, tau), which reach `chunk_pad` beyond s and e or the record's ends: filtered
    and differentiated there, W and the torques on the chunk and its decimation transient, decimated, the chunk's
    own outputs kept (on the whole record's decimation grid), the slow rows dropped.

    gains: (len(q), n, k) columns appended to W on the same samples (drive gains identified: `sources.driven`),
    filtered and decimated as W's. payload: (frame, its 10 standard parameters about the frame's origin): a known
    body fixed to that link, whose torque (the link's regressor columns times them) is taken off the torques.
    threads: the chunk's W blocks done on that many threads at once (`decimate_parallel_blocked`; the same bits):
    one chunk's samples, filtered positions and first-stage output held, not one per thread's chunk.
    filtered: `chunk_filtered`'s (qf, speed) of these arguments, made beforehand (the next chunk's, on another
    thread while this one's decimation finishes: `reduce.read_robot_chunk`; q is then not read: None will do);
    made here when None. blocks_done: called once the W blocks are done and their buffers freed (the decimation's
    later stages and the rows' own selection left). buffers: `chunk_buffers` of these arguments, made beforehand
    (by the thread that read the chunk, in the heap its reading left free: `reduce.read_robot_chunk`); made here
    when None.

    after: given the first decimation stage's outputs this chunk made on the next chunk's span (from the start of
    the next chunk's decimation transient, `_chunk_span`, to this chunk's own transient's end less the first
    stage's overlap: the outputs that do not see this chunk's end; not called for a test's last chunk); before:
    those outputs of the chunk before, taken as this chunk's instead of computing W there again (W's samples -13 %
    for the Panda's 55,600-sample chunks: 2 of 19 blocks skipped, the third shortened; benchmarks/
    bench_robot_memory.py). The rows differ by round-off: each output is made from a window and blocks of its own,
    both reaching its filters' transients to 1e-12 and `ROUND_OFF`; but where a joint's filtered speed is zero to
    round-off at a sample, its Coulomb column's sign(q̇) there may differ (as between any two chunkings: 1.1e-7
    of W's largest in that column's rows around it, for a sine test turning at a sample). Only in the chunks' order,
    by one process: chunks done apart (a cluster's) make their own."""
    rows = list(model.tree.equations) if rows is None else list(rows)
    s, e = chunk
    if filtered is None:
        if q is None:
            raise ValueError("chunk_rows needs the window's positions q or their `chunk_filtered` (qf, speed)")
        filtered = chunk_filtered(c, q, fs, first, chunk, n_samples)
    qf, speed = filtered
    D = int(np.prod(c.decimate))
    lo, hi = _chunk_span(c, fs, chunk, n_samples)
    o = lo - first
    eq, cols = np.array(rows) - 1, list(base.columns)
    extra = 0 if gains is None else gains.shape[2]
    spare = list(chunk_buffers(base, c, fs, chunk, n_samples, rows, extra, threads) if buffers is None else buffers)
    block_samples = _block_samples(len(rows), len(cols), extra)
    taken: dict[int, Array] = {}

    def block(a: int, z: int) -> tuple[Array, Array]:
        """W and Y of the chunk's samples a..z (its full-rate W never whole: `decimate_parallel_blocked`)."""
        w = slice(o + a, o + z)
        qb, qdb, qddb = _block_derivatives(qf, o + a, o + z, fs)
        buffer = taken.get(threading.get_ident())
        if buffer is None:  # this thread's first block (list.pop and a dict's item set are atomic under the GIL)
            buffer = taken[threading.get_ident()] = spare.pop()
        W = model.regressor(qb, qdb, qddb, rows=rows, cols=cols, out=buffer[: z - a])
        Y = tau[w][:, eq]
        if payload is not None:
            j, Xp = payload
            Y = Y - model.regressor(qb, qdb, qddb, rows=rows, cols=[f"{k}{j}" for k in INERTIAL]) @ Xp
        if gains is not None:
            W = np.concatenate([W, gains[w][:, eq, :]], axis=2)
        return W, Y

    def freed() -> None:
        taken.clear()
        spare.clear()
        if buffers is not None:
            buffers.clear()
        if blocks_done is not None:
            blocks_done()

    # the next chunk's span starts `h` into this one's (on the decimation grid: a multiple of the first factor)
    last = e >= n_samples - _border(fs, c)
    share = None if after is None or last else (_chunk_span(c, fs, (e, e), n_samples)[0] - lo, after)
    Wd, Yd = decimate_parallel_blocked(block, hi - lo, c.decimate, fs, order=DECIMATION_ORDER,
                                       block_samples=block_samples, threads=threads, blocks_done=freed,
                                       known=before, share=share)
    k = np.arange((s - lo) // D, -(-(e - lo) // D))  # output k is input lo + k D
    Wd, Yd, speed, td = Wd[k], Yd[k], speed[k], (lo + k * D) / fs
    parts = []
    for i, j in enumerate(rows):
        ok = np.abs(speed[:, j - 1]) >= c.min_speed.get(j, 0.0)
        parts.append(GroupedSystem(Wd[ok, i], Yd[ok, i], np.full(int(ok.sum()), f"joint{j}"), td[ok]))
    return GroupedSystem.stack(parts)


def chunk_buffers(base: BaseParameters, c: Conditioning, fs: float, chunk: tuple[int, int], n_samples: int,
                  rows: Sequence[int], extra: int = 0, threads: int = 1) -> list[Array]:
    """The W block buffers `chunk_rows` fills for the chunk's blocks, one a thread, zeroed: the regressor writes
    only its entries that can be non-zero, so the structural zeros stay (`Model.regressor`'s out; a fresh zeroed
    block each time cost a calloc of BLOCK_BYTES). extra: W's columns beyond the base parameters' (drive gains)."""
    lo, hi = _chunk_span(c, fs, chunk, n_samples)
    most = blocked_rows(hi - lo, c.decimate, fs, order=DECIMATION_ORDER,
                        block_samples=_block_samples(len(rows), len(base.columns), extra))
    return [np.zeros((most, len(rows), len(base.columns))) for _ in range(threads)]


def _chunk_span(c: Conditioning, fs: float, chunk: tuple[int, int], n_samples: int) -> tuple[int, int]:
    """The samples a chunk's W is made on: its own and its decimation transient, inside the filter borders (on the
    decimation grid: s - border and the transient are multiples of the whole factor)."""
    b, pad = _border(fs, c), _decimation_transient(fs, c.decimate)
    return max(b, chunk[0] - pad), min(n_samples - b, chunk[1] + pad)


def _block_samples(rows: int, cols: int, extra: int) -> int:
    return BLOCK_BYTES // (8 * rows * (cols + extra))


def chunk_filtered(c: Conditioning, q: Array, fs: float, first: int, chunk: tuple[int, int],
                   n_samples: int) -> tuple[Array, Array]:
    """`chunk_rows`' filtered positions of its window q (samples first..first + len(q)) and its joints' speeds
    decimated as W's columns over the chunk and its decimation transient (the rows' speed test sees the decimated
    samples): what a chunk needs before its W blocks, without the model."""
    # the filtered positions held for the chunk, their derivatives (`filtered_derivatives`' central differences)
    # made a block at a time from them: the same bits, 2 of the 3 filtered arrays not held (7.5 MB for the Panda's)
    (qf,) = filtered_derivatives(q, fs, c.cutoff, order=c.order, nderiv=0)
    lo, hi = _chunk_span(c, fs, chunk, n_samples)
    speed, _ = decimate_parallel(derivative(qf, fs)[lo - first : hi - first], None, c.decimate, fs,
                                 order=DECIMATION_ORDER)
    return qf, speed


def _block_derivatives(qf: Array, a: int, z: int, fs: float) -> tuple[Array, Array, Array]:
    """qf[a:z] and its first two derivatives there, the bits `filtered_derivatives` gives over the whole of qf:
    central differences read two samples beyond each end (interior samples are element-wise), and at qf's own
    ends its one-sided formulas."""
    e0, e1 = max(0, a - 2), min(qf.shape[0], z + 2)
    qd = derivative(qf[e0:e1], fs)
    qdd = derivative(qd, fs)
    return qf[a:z], qd[a - e0 : z - e0], qdd[a - e0 : z - e0]


def in_joint_order(parts: Sequence[GroupedSystem]) -> GroupedSystem:
    """Chunks' rows (each stacked joint by joint) as one test's: joint by joint, in time within each."""
    sys = GroupedSystem.stack(parts)
    order = np.argsort(np.array([int(g[5:]) for g in sys.groups]), kind="stable")
    return GroupedSystem(sys.W[order], sys.Y[order], sys.groups[order], sys.t[order])


def _border(fs: float, c: Conditioning) -> int:
    return border_samples(fs, c.cutoff, c.order) if c.border is None else round(c.border * fs)


def _decimation_transient(fs: float, factors: Sequence[int]) -> int:
    """Input samples over which a decimation's zero-phase filters still weigh the record's end (1e-9 of the
    weight), each stage's transient at its own rate, rounded up to a multiple of the total factor."""
    D, pad, rate, before = int(np.prod(factors)), 0, fs, 1
    for f in factors:
        pad += border_samples(rate, 0.8 * rate / (2.0 * f), DECIMATION_ORDER, tol=1e-9) * before + f * before
        rate, before = rate / f, before * f
    return -(-pad // D) * D


PRODUCTS = ("XY", "XZ", "YZ")
FIRST_MOMENTS = ("MX", "MY", "MZ")


def link_length(tree: Tree, j: int, X: Array | None = None) -> float:
    """A link's size (m) from the model file's a priori values and geometry: the largest of the distance from
    O_j to its centre of mass, the distances from O_j to its children's origins (the joint-to-joint lengths of
    the MDH table) and its radius of gyration about the centre of mass (sqrt(tr I_G / 2m), the RMS distance of
    its mass from the centre of mass). 0 for a link without a priori mass and children."""
    block = tree.inertial_block(X)[j]
    m, ms = block[9], block[6:9]
    sizes = [0.0]
    if m > 0:
        com = ms / m
        I_o = _inertia(block)
        I_g = I_o - m * (float(com @ com) * np.eye(3) - np.outer(com, com))
        sizes += [float(np.linalg.norm(com)), float(np.sqrt(max(np.trace(I_g), 0.0) / (2.0 * m)))]
    for k in tree.children[j]:
        f = tree.frames[k - 1]
        p = np.array([f.d, -f.r * np.sin(f.alpha), f.b + f.r * np.cos(f.alpha)])  # |Rz(gamma) p| = |p|
        sizes.append(float(np.linalg.norm(p)))
    return max(sizes)


def link_box(tree: Tree, j: int, X: Array | None = None) -> tuple[Array, Array]:
    """The extent of link j (m, in frame j) where its centre of mass must lie: the box spanning O_j, its children's
    origins and its a priori centre of mass, widened on every side by its radius of gyration about that centre
    of mass and by a tenth of its size (`link_length`)."""
    block = tree.inertial_block(X)[j]
    m = block[9]
    points = [np.zeros(3)]
    pad = 0.1 * link_length(tree, j, X)
    if m > 0:
        com = block[6:9] / m
        points.append(com)
        I_g = _inertia(block) - m * (float(com @ com) * np.eye(3) - np.outer(com, com))
        pad += float(np.sqrt(max(np.trace(I_g), 0.0) / (2.0 * m)))
    for k in tree.children[j]:
        f = tree.frames[k - 1]
        points.append(_rz(f.gamma) @ np.array([f.d, -f.r * np.sin(f.alpha), f.b + f.r * np.cos(f.alpha)]))
    P = np.array(points)
    return P.min(axis=0) - pad, P.max(axis=0) + pad


def _rz(t: float) -> Array:
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def standard_scales(tree: Tree, X: Array | None = None) -> Array:
    """(p,) the engineering scale of each standard parameter from the values X (default the model file's a priori
    set), all about O_j in frame j as the parameters are:

    - a product of inertia XY_j against sqrt(XX_j YY_j) (XZ, YZ alike): the largest |XY_j| that a real body with
      those moments can have (the inertia is positive semidefinite), so the scale of the product's possible size.
      For a thin link (a forearm: moments 0.19, 0.19 and 0.004 kg.m2 about its long axis) it lies between the
      smallest principal moment, which would call a 0.1 degree tilt of its principal axes uncertain, and the
      largest, which would hide a product as large as the thin axis' moment;
    - a first moment MX_j against the link's mass times its size (`link_length`), so that 5 % of it (the flag's
      95 % interval at 2.5 %) is a centre-of-mass shift of 1/20 of the link;
    - every other parameter against its own |value|.

    0 where X says nothing (no mass, no inertia)."""
    X = tree.parameters if X is None else np.asarray(X, dtype=float)
    out = np.abs(X).astype(float)
    blocks = tree.inertial_block(X)
    for f in tree.frames:
        if f.sigma == FIXED and not np.any(blocks[f.j]):
            continue
        i0 = tree.index[f"XX{f.j}"]
        xx, yy, zz = np.abs(blocks[f.j, [0, 3, 5]])
        bound = {"XY": np.sqrt(xx * yy), "XZ": np.sqrt(xx * zz), "YZ": np.sqrt(yy * zz)}
        for k, kind in enumerate(("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M")):
            if kind in PRODUCTS:
                out[i0 + k] = bound[kind]
            elif kind in FIRST_MOMENTS:
                out[i0 + k] = abs(blocks[f.j, 9]) * link_length(tree, f.j, X)
    return out


def robot_scales(tree: Tree, base: BaseParameters, values: Mapping[str, float] | None = None) -> dict[str, float]:
    """The engineering scale of each base parameter, against which the "uncertain" flag judges its σ.

    A base parameter X_B = X_k + sum_i beta_i X_i regroups standard parameters, each with its own scale s
    (`standard_scales`, from the model file's a priori values and geometry), so its scale is
    s_k + sum_i |beta_i| s_i: the size its value would have if every part it sums had its own size, whatever
    cancels (XX_jR = XX_j - YY_j + ... is near zero for a symmetric link, its σ is not measured against that).
    A parameter is never judged against less than its own estimate, |value| (values: the estimates by base
    name): a scale of 0 (nothing a priori) leaves the default, |value|."""
    s = standard_scales(tree)
    out = {}
    for r, (name, col) in enumerate(zip(base.names, base.columns, strict=True)):
        scale = float(s[col])
        if base.regrouped_columns:
            scale += float(np.abs(base.beta[r]) @ s[list(base.regrouped_columns)])
        if values is not None and name in values:
            scale = max(scale, abs(float(values[name])))
        if scale > 0:
            out[name] = scale
    return out


def _inertia(block: Array) -> Array:
    xx, xy, xz, yy, yz, zz = block[:6]
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
