"""Identification rows of the car: the paper's 14 equations, decimated in parallel per equation group."""

from __future__ import annotations

import numpy as np

from ..dynamics import BaseParameters, Model
from ..signals import decimate_parallel
from ..vehicle import Aerodynamics, aero_wrench, car_identification
from ..vehicle.estimate import CarTrajectory
from .robot import GroupedSystem


def car_system(
    model: Model,
    traj: CarTrajectory,
    fs: float,
    decimate: tuple[int, ...] = (5, 10),
    base: str | BaseParameters = "generic",
    aero: Aerodynamics | None = None,
) -> tuple[GroupedSystem, BaseParameters]:
    """W, Y and groups of one test: each of the 14 equations' columns of W and its Y through the same
    anti-alias filter and decimation (Gautier's parallel decimation), then stacked group by group."""
    aw = aero_wrench(model, traj.q, traj.qd, aero) if aero is not None else None
    eq = car_identification(model, traj.q, traj.qd, traj.qdd, traj.wheel_wrenches, aw, base=base)
    rows, N = len(eq.rows), len(traj.t)
    W = eq.W.reshape(rows, N, -1).transpose(1, 0, 2)
    Y = eq.Y.reshape(rows, N).T
    if decimate:
        W, Y = decimate_parallel(W, Y, decimate, fs)
        t = traj.t[:: int(np.prod(decimate))][: W.shape[0]]
    else:
        t = traj.t
    n = W.shape[0]
    labels = eq.groups.reshape(rows, N)[:, 0]
    sys = GroupedSystem(W.transpose(1, 0, 2).reshape(rows * n, -1), Y.T.reshape(-1), np.repeat(labels, n),
                        np.tile(t, rows))
    return sys, eq.base
