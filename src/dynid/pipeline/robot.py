"""Identification of a robot from joint positions and joint torques (Gautier's method).

Positions are low-passed without phase shift and differentiated by central differences;
the filter transient is trimmed; W (base columns) and the torques are decimated in
parallel per joint; samples where a joint barely moves are dropped from that joint's
equations (the sign of its Coulomb friction is uncertain there); the rows of every
test are stacked per joint, and each joint is one equation group for weighted LS.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..dynamics import BaseParameters, Model
from ..signals import border_samples, decimate_parallel, filtered_derivatives

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


def condition(test: JointTest, c: Conditioning) -> tuple[Array, Array, Array, Array, slice]:
    """Filtered q, qd, qdd and the kept slice (borders trimmed), tau on the same samples."""
    q, qd, qdd = filtered_derivatives(test.q, test.fs, c.cutoff, order=c.order, nderiv=2)
    b = border_samples(test.fs, c.cutoff, c.order) if c.border is None else round(c.border * test.fs)
    keep = slice(b, test.q.shape[0] - b)
    return q[keep], qd[keep], qdd[keep], test.tau[keep], keep


def joint_system(
    model: Model, test: JointTest, base: BaseParameters, c: Conditioning, rows: Sequence[int] | None = None
) -> GroupedSystem:
    """The decimated, per-joint identification rows of one test on the base parameters."""
    rows = list(range(1, model.n + 1)) if rows is None else list(rows)
    q, qd, qdd, tau, keep = condition(test, c)
    W = np.ascontiguousarray(model.regressor(q, qd, qdd, rows=rows, cols=list(base.columns)))
    Y = tau[:, np.array(rows) - 1]
    t = (np.arange(test.q.shape[0])[keep] / test.fs)
    # decimate W, Y and the speeds with the same filter, so that the speed test sees the decimated samples
    Wd, Yd = decimate_parallel(W, Y, c.decimate, test.fs)
    speed, _ = decimate_parallel(qd, qd[:, 0], c.decimate, test.fs)  # the speeds as the columns of one row
    td = t[:: int(np.prod(c.decimate))][: Wd.shape[0]]
    parts = []
    for i, j in enumerate(rows):
        ok = np.abs(speed[:, j - 1]) >= c.min_speed.get(j, 0.0)
        parts.append(GroupedSystem(Wd[ok, i], Yd[ok, i], np.full(int(ok.sum()), f"joint{j}"), td[ok]))
    return GroupedSystem.stack(parts)
