"""Parallel decimation of an identification system (Gautier's method).

The identification system Y = W X is sampled at the measurement rate (625 Hz for
the car), far faster than the dynamics (~1 Hz): it has many more rows than it needs,
and the high-frequency part of each column is mostly noise and model error. Parallel
decimation low-passes every column of W and Y with the SAME zero-phase filter, then
keeps one sample in `factor`. Because the filter F is linear and applied alike to
every column, F(Y) = F(W X) = F(W) X: the decimated system has exactly the same
solution as the original when the original is consistent, while the rows left
carry only the band that the model describes. The same filter on both sides is
what makes this legitimate; filtering W and Y differently would bias X.

Conventions: time is axis 0; W is (N, m, p) with m equation rows per sample and p
parameter columns (or (N, p) with one row per sample), Y is (N, m) (or (N,)). The
kept samples are 0, factor, 2 factor, ...: output sample k is at time
t[0] + k factor / fs.
"""

from __future__ import annotations

import dataclasses
import numbers
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _checks
from ._zero_phase import sos_filtfilt
from .borders import border_samples
from .errors import SignalError
from .filters import design_lowpass, pad_length


@dataclass(frozen=True)
class _Stage:
    """One filter-and-keep-one-in-factor stage."""

    factor: int
    fs: float  # input rate, Hz
    cutoff: float  # Hz
    sos: NDArray[np.float64]
    n_in: int

    @property
    def n_out(self) -> int:
        return -(-self.n_in // self.factor)


def _factors(factor: int | Sequence[int]) -> tuple[int, ...]:
    items = tuple(factor) if isinstance(factor, (list, tuple)) else (factor,)
    if not items:
        raise SignalError("factor is an empty sequence; give at least one decimation factor")
    for f in items:
        if isinstance(f, bool) or not isinstance(f, numbers.Integral) or f < 2:
            raise SignalError(f"each decimation factor must be an integer >= 2, got {f!r} in {factor!r}")
    return tuple(int(f) for f in items)


def _stages(n: int, factors: tuple[int, ...], fs: float, order: int, cutoff) -> list[_Stage]:
    if cutoff is None:
        cutoffs: tuple = (None,) * len(factors)
    elif isinstance(cutoff, (list, tuple)):
        if len(cutoff) != len(factors):
            raise SignalError(f"{len(cutoff)} cut-offs for {len(factors)} decimation stages; give one per stage")
        cutoffs = tuple(cutoff)
    elif len(factors) == 1:
        cutoffs = (cutoff,)
    else:
        raise SignalError(
            f"one cut-off for {len(factors)} decimation stages; give a sequence of one per stage, or None"
        )
    stages = []
    rate = fs
    for i, (f, c) in enumerate(zip(factors, cutoffs, strict=True), start=1):
        nyquist_out = rate / (2.0 * f)
        if c is None:
            c = 0.8 * nyquist_out
        c = _checks.cutoff_frequency(c, rate)
        if c >= nyquist_out:
            raise SignalError(
                f"decimation stage {i}: cut-off {c:g} Hz is not below the Nyquist frequency after decimation, "
                f"fs/(2 factor) = {rate:g}/(2*{f}) = {nyquist_out:g} Hz; what lies between would alias. "
                "Lower it (default 0.8 of that) or decimate less"
            )
        stage = _Stage(f, rate, c, design_lowpass(rate, c, order), n)
        pad = pad_length(stage.sos)
        if n <= pad:
            raise SignalError(
                f"decimation stage {i} (factor {f} at {rate:g} Hz) gets {n} samples; its order-{order} "
                f"zero-phase filter pads {pad} samples at each end and needs at least {pad + 1}. "
                "Use a longer record, fewer or smaller factors, or a lower order"
            )
        stages.append(stage)
        n = stage.n_out
        rate /= f
    return stages


def _decimate_columns(
    a: NDArray[np.float64], stages: list[_Stage], block: int, columns: NDArray[np.intp] | None = None,
    compact: bool = False,
) -> NDArray[np.float64]:
    """Filter and decimate the columns (all, or those listed) of a 2-D (N, C) array, `block` at a time;
    the columns not listed are left zero (compact: left out, the output's columns are the listed ones, in order)."""
    columns = np.arange(a.shape[1]) if columns is None else columns
    out = np.zeros((stages[-1].n_out, len(columns) if compact else a.shape[1]))
    for c0 in range(0, len(columns), block):
        cols = columns[c0 : c0 + block]
        work = a[:, cols]  # (N, block): the filter runs the block's columns side by side
        for s in stages:
            work = sos_filtfilt(s.sos, work, 0, pad_length(s.sos))[:: s.factor]
        out[:, slice(c0, c0 + len(cols)) if compact else cols] = work
    return out


def decimate_parallel(
    W: ArrayLike,
    Y: ArrayLike | None,
    factor: int | Sequence[int],
    fs: float,
    order: int = 8,
    cutoff: float | Sequence[float] | None = None,
    *,
    block_columns: int | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Low-pass every column of W and Y with the same zero-phase filter, keep one sample in `factor`.

    Parameters
    ----------
    W : array (N, m, p) or (N, p)
        Observation matrix per sample: m equation rows, p parameter columns.
    Y : array (N, m) or (N,), or None
        Right-hand side per sample, matching W ((N, p) goes with (N,)); None: W alone
        (any array whose columns all need the same treatment), and Yd is None.
    factor : int >= 2, or a sequence of them
        Decimation factor, or factors applied in turn (the TX40 reference uses
        (10, 10): 100 in two stages, each with its own filter; one stage of 100 would
        need a filter with a cut-off very close to zero in normalised frequency).
    fs : float
        Sample rate of W and Y, Hz.
    order : int
        Butterworth order of one pass (forward-backward doubles it).
    cutoff : float, sequence of floats, or None
        Anti-alias cut-off in Hz, one per stage for a sequence of factors; each must
        be below the stage's output Nyquist frequency fs_in / (2 factor). None: 0.8 of
        that frequency at every stage.
    block_columns : int or None
        Columns filtered at once; None picks blocks of about 16 MB of input, so that
        the work space (a few times a block) stays small beside W whatever N, m, p.

    Returns
    -------
    (Wd, Yd) : arrays (Nd, m, p) or (Nd, p), and (Nd, m) or (Nd,), with
        Nd = ceil(N / prod(factors)) (rounded up at each stage); sample rate
        fs / prod(factors). Same units as W and Y.

    Notes
    -----
    The first and last rows carry the anti-alias filter's end transient
    (`border_samples(fs, cutoff, order)` samples at the input rate). Cut the full-rate
    data to the part you trust before decimating, or drop the corresponding rows after.
    """
    Wa = _checks.as_float(W, "W", min_ndim=2)
    fs = _checks.rate(fs)
    order = _checks.filter_order(order)
    if Wa.ndim == 3:
        expected = Wa.shape[:2]
    elif Wa.ndim == 2:
        expected = Wa.shape[:1]
    else:
        raise SignalError(f"W must be (N, m, p) or (N, p), got shape {Wa.shape}")
    Ya = None if Y is None else _checks.as_float(Y, "Y")
    if Ya is not None and Ya.shape != expected:
        raise SignalError(
            f"Y has shape {Ya.shape}, W has shape {Wa.shape}: Y must be {expected}, one value per sample and "
            "equation row of W"
        )
    n = Wa.shape[0]
    stages = _stages(n, _factors(factor), fs, order, cutoff)
    W2 = Wa.reshape(n, -1)
    _checks.finite(Wa, "W", 0, "remove or repair those samples before decimating")
    if Ya is not None:
        _checks.finite(Ya, "Y", 0, "remove or repair those samples before decimating")
    if block_columns is None:
        block = _checks.block_columns(n)
    elif isinstance(block_columns, bool) or not isinstance(block_columns, numbers.Integral) or block_columns < 1:
        raise SignalError(f"block_columns must be an integer >= 1 or None, not {block_columns!r}")
    else:
        block = int(block_columns)
    nd = stages[-1].n_out
    # identification matrices are mostly structural zeros (a joint's row holds only its subtree's
    # parameters): the filter maps zero to zero, so only the other columns are filtered
    live = np.flatnonzero(np.any(W2 != 0, axis=0))
    Wd = _decimate_columns(W2, stages, block, live).reshape((nd, *Wa.shape[1:]))
    if Ya is None:
        return Wd, None
    return Wd, _decimate_columns(Ya.reshape(n, -1), stages, block).reshape((nd, *Ya.shape[1:]))


# the first stage's transient is taken to this fraction of its kernel's weight around each block: a block's outputs
# are then the whole input's to a few units of round-off (border_samples' rule; its tail sums floor near 1e-16)
ROUND_OFF = 1e-15
# columns filtered side by side in the blocked path: a few copies of this are its work space (decimate_parallel's
# 16 MB blocks cost a worker ~50 MB beside its block of W; each column is filtered alone, so any width gives the
# same bits: 1 MiB, against 4, takes ~10 MB off a worker's high water at no measured CPU)
WORK_BYTES = 2**20


def _blocks(n: int, f: int, fs: float, cutoff: float, order: int, block_samples: int
            ) -> tuple[list[int], list[int], int]:
    """The blocks of `decimate_parallel_blocked`: their own samples' starts and ends, and the overlap read around
    each (on the first stage's grid: a block's outputs are those of the input samples it owns)."""
    ov = -(-border_samples(fs, cutoff, order, tol=ROUND_OFF) // f) * f
    step = max(f, int(block_samples) // f * f, 4 * ov)
    starts = list(range(0, n, step))
    if len(starts) > 1 and n - starts[-1] < step // 2:  # no short last block: it merges with the one before
        starts.pop()
    return starts, [*starts[1:], n], ov


@dataclass(frozen=True)
class FirstStage:
    """The first stage's outputs of `decimate_parallel_blocked` for a run of its input samples: W1 (k, len(held)),
    W's columns `held` (full-width indices, sorted; the others zero), and Y1 (k, m): output i is input sample
    start + i factor[0] of the input they were made on."""

    W1: NDArray[np.float64]
    held: NDArray[np.intp]
    Y1: NDArray[np.float64]


def blocked_rows(n: int, factor: int | Sequence[int], fs: float, order: int = 8,
                 cutoff: float | Sequence[float] | None = None, *, block_samples: int) -> int:
    """The most input samples `decimate_parallel_blocked` asks `rows` for at once (a block and its overlaps): the
    size of a buffer that `rows` can fill for every block."""
    stages = _stages(n, _factors(factor), _checks.rate(fs), _checks.filter_order(order), cutoff)
    starts, ends, ov = _blocks(n, stages[0].factor, fs, stages[0].cutoff, order, block_samples)
    return max(min(n, e + ov) - max(0, a - ov) for a, e in zip(starts, ends, strict=True))


def decimate_parallel_blocked(
    rows: Callable[[int, int], tuple[NDArray[np.float64], NDArray[np.float64]]],
    n: int,
    factor: int | Sequence[int],
    fs: float,
    order: int = 8,
    cutoff: float | Sequence[float] | None = None,
    *,
    block_samples: int,
    threads: int = 1,
    blocks_done: Callable[[], None] | None = None,
    known: FirstStage | None = None,
    share: tuple[int, Callable[[FirstStage], None]] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """`decimate_parallel(W, Y, ...)` of the W (n, m, p) and Y (n, m) that `rows(0, n)` would give, without ever
    holding them at the input rate: the first stage filters and decimates blocks of about `block_samples` input
    samples (each asked for by `rows(lo, hi)`, W (hi - lo, m, p) and Y (hi - lo, m) of input samples lo..hi), read
    with the stage's transient to `ROUND_OFF` of its weight beyond the block's own samples; the later stages run
    on the first's output, `factor[0]` times smaller. The outputs equal `decimate_parallel`'s to round-off (the
    same bits when one block covers the input); what is held is one block at the input rate and the first
    stage's output, and a few copies of `WORK_BYTES` (the columns filtered side by side).

    threads: blocks done at once on that many threads (one block each at a time: `rows` is then called from
    them together and must be safe so, each call's W its own until it returns the next block's). The outputs
    are the same bits for any count: each block is computed alone, its outputs written to their own rows.
    blocks_done: called on the calling thread once every block is in (`rows` is not called again), before the
    later stages.

    known: the first stage's outputs of this input's first samples, made beforehand on the same samples (the chunk
    before's, `share`): the blocks wholly inside them are not computed, the first one left starts where they end,
    the others are the bits they would be without them (the known rows and that block's differ by the round-off
    of the blocks' bounds: `ROUND_OFF`). share: (h, give):
    give(outputs of the input samples h.. up to the stage's overlap before the input's end, those that do not
    see it), called once the blocks are in; h a multiple of factor[0]."""
    factors = _factors(factor)
    fs = _checks.rate(fs)
    order = _checks.filter_order(order)
    if isinstance(threads, bool) or not isinstance(threads, numbers.Integral) or threads < 1:
        raise SignalError(f"threads must be an integer >= 1, not {threads!r}")
    stages = _stages(n, factors, fs, order, cutoff)
    first, f = stages[0], factors[0]
    starts, ends, ov = _blocks(n, f, fs, first.cutoff, order, block_samples)
    if known is not None:  # the blocks whose outputs are all known are skipped (the grid kept: the others' bits)
        if len(known.W1) != len(known.Y1) or len(known.W1) > first.n_out:
            raise SignalError(f"known first-stage outputs: W1 {known.W1.shape}, Y1 {known.Y1.shape} for an input "
                              f"of {first.n_out} first-stage outputs: give at most that many rows of each")
        skip = sum(-(-e // f) <= len(known.W1) for e in ends)
        starts, ends = starts[skip:], ends[skip:]
        if starts:  # the first block left starts where the known outputs end (its own bits then, the others' kept)
            starts[0] = max(starts[0], f * len(known.W1))
    # W1: the first stage's output of W's live columns alone (`held`, full-width indices, sorted), the structural
    # zeros (a joint's row holds only its subtree's parameters: 111 of a 7-joint arm's 301) never stored
    out: dict = {"W1": None, "Y1": None, "held": np.zeros(0, dtype=np.intp) if known is None else known.held,
                 "shape": None}
    lock = threading.Lock()
    caller, made = threading.get_ident(), threading.Event()

    def one(a: int, e: int) -> None:
        lo, hi = max(0, a - ov), min(n, e + ov)
        W, Y = rows(lo, hi)
        Wa, Ya = _checks.as_float(W, "W", min_ndim=3), _checks.as_float(Y, "Y")
        if Wa.shape[0] != hi - lo or Ya.shape != Wa.shape[:2]:
            raise SignalError(f"rows({lo}, {hi}) gave W {Wa.shape} and Y {Ya.shape}: W must be "
                              f"({hi - lo}, m, p) and Y ({hi - lo}, m)")
        _checks.finite(Wa, "W", 0, "remove or repair those samples before decimating")
        _checks.finite(Ya, "Y", 0, "remove or repair those samples before decimating")
        stage = [dataclasses.replace(first, n_in=hi - lo)]
        keep = slice((a - lo) // f, (a - lo) // f + -(-(e - a) // f))  # output k of the block is input lo + k f
        W2 = Wa.reshape(hi - lo, -1)
        live = np.flatnonzero(np.any(W2 != 0, axis=0))  # structural zeros stay zero (decimate_parallel)
        block = max(1, WORK_BYTES // (8 * (hi - lo)))
        Wb = _decimate_columns(W2, stage, block, live, compact=True)[keep]
        Yb = _decimate_columns(Ya.reshape(hi - lo, -1), stage, block)[keep].reshape(-1, *Ya.shape[1:])
        shape = Wa.shape[1:]
        del W, Wa, W2
        if threading.get_ident() != caller:
            made.wait()  # W1 and Y1 made by the calling thread's first block, in its heap (glibc's arena)
        with lock:  # W1 widened and written by one block at a time
            if out["Y1"] is None:
                out["shape"] = shape
                out["Y1"] = np.zeros((first.n_out, *Yb.shape[1:]))
                if known is not None:
                    out["Y1"][: len(known.Y1)] = known.Y1
            W1, held = out["W1"], out["held"]
            if W1 is None or not np.isin(live, held).all():  # a column live for the first time: W1 widened (rare)
                wider = np.union1d(held, live)
                grown = np.zeros((first.n_out, len(wider)))
                if W1 is not None:
                    grown[:, np.searchsorted(wider, held)] = W1
                elif known is not None:
                    grown[: len(known.W1), np.searchsorted(wider, held)] = known.W1
                out["W1"], out["held"] = W1, held = grown, wider
            W1[a // f : -(-e // f), np.searchsorted(held, live)] = Wb
            out["Y1"][a // f : -(-e // f)] = Yb

    todo = iter(zip(starts, ends, strict=True))
    failed = threading.Event()  # a block's error (or Ctrl-C): the other threads take no new block

    def guarded(a: int, e: int) -> None:
        try:
            one(a, e)
        except BaseException:
            failed.set()
            raise

    def drain() -> None:
        """Blocks, the next one free, until none is left (this thread's rows() buffer reused for each)."""
        while not failed.is_set():
            with lock:
                item = next(todo, None)
            if item is None:
                return
            guarded(*item)

    helpers = max(0, min(threads, len(starts)) - 1)  # the calling thread is one of the `threads`
    if not starts:  # every output known
        made.set()
    elif helpers == 0:
        drain()
    else:
        # the first block the calling thread's: W1 and Y1 made by it, in its heap (glibc's arena), not a helper's;
        # the helpers' blocks meanwhile, written once it is (`made`)
        mine = next(todo)
        with ThreadPoolExecutor(helpers) as pool:
            running: list = []
            try:  # the helpers released whatever happens once they are submitted (a Ctrl-C between included)
                running += [pool.submit(drain) for _ in range(helpers)]
                guarded(*mine)
            finally:
                made.set()
            drain()
            for done in running:
                done.result()
    if blocks_done is not None:
        blocks_done()
    if out["Y1"] is None:  # no block computed: every output known (W's shape is then the known columns' bound)
        raise SignalError("decimate_parallel_blocked: every first-stage output known, no block to compute; give "
                          "fewer known rows")
    W1, Y1, held, shape = out["W1"], out["Y1"], out["held"], out["shape"]
    if share is not None:  # the rows that do not see this input's end (its last block's overlap), copied
        h, give = share
        if h % f:
            raise SignalError(f"share from input sample {h}: not a multiple of the first factor {f}")
        z = (n - ov) // f
        if h // f < z:
            give(FirstStage(W1[h // f : z].copy(), held.copy(), Y1[h // f : z].copy()))
    width = int(np.prod(shape))
    n1 = first.n_out
    if len(stages) == 1:
        full = np.zeros((n1, width))
        full[:, held] = W1
        return full.reshape(n1, *shape), Y1
    rest = stages[1:]
    block = max(1, WORK_BYTES // (8 * n1))
    live = np.flatnonzero(np.any(W1 != 0, axis=0))  # of the held columns (their filtered outputs all zero: left out)
    nd = rest[-1].n_out
    Wd = np.zeros((nd, width))
    Wd[:, held[live]] = _decimate_columns(W1, rest, block, live, compact=True)
    return Wd.reshape((nd, *shape)), _decimate_columns(Y1.reshape(n1, -1), rest, block).reshape((nd, *Y1.shape[1:]))
