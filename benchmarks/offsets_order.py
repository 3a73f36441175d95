"""How far a linearised offsets' propagation would move an identification from today's (issue 28 item 3).

Run:  python benchmarks/offsets_order.py CONFIG [CONFIG ...]

Today each declared offset's columns C (the rows' residual moved by one σ, `reduce.offset_residuals`) are a secant:
the exact change at +σ. A forward-mode (or any first-order) sensitivity computed alongside the rows gives the
tangent instead; an order-2 forward mode (value, first and second derivatives: a jet) gives the second-order Taylor
polynomial at +σ. This identifies each config (one thread) three times: as today, with C the tangent (the central
difference (C(+σ) − C(−σ)) / 2, first order to O(σ³)) and with C the second-order polynomial (from C(±σ/2): twice
its odd part plus four times its even part, to O(σ³)), and prints the largest relative change of σ total and of the
values (with the offsets estimated, the default, the values move with C; propagated alone they do not).

Measured 2026-11-29 (h-offsets at fd92e1c), against today's:

    config                               first order (tangent)          second order (jet)
                                         σ total      values            σ total      values
    the demo (dynid demo, 406)           1.1e-5       3.7e-5            6.6e-9       2.0e-8
    examples/mujoco_car/identify.toml    1.4e-5       2.1e-3            4.6e-8       7.2e-8

So the issue's "first-order sensitivity ... equal to today's propagation to 1e-6" cannot hold on either: the
attitude's rows are curved in a gyro's or an inclinometer's offset (C(+σ) + C(−σ) is up to 5e-3 of C(+σ) for the
yaw rate on the demo; the accelerometers', lasers' and wheel loads' below 1e-9), and the offsets' estimate carries
the curvature into the values. A second-order one meets it with two decades to spare; first order suffices for every
channel the attitude does not reach.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

import dynid.pipeline.reduce as reduce
from dynid.pipeline.config import load_config
from dynid.pipeline.run import identify

sys.path.insert(0, str(Path(__file__).resolve().parent))
# every job in this thread: the patched `offset_residuals` is then the one the jobs call
from profile_car import Inline

TODAY = reduce.offset_residuals


def _at(args: tuple, factor: float) -> np.ndarray:
    """Today's columns with every offset scaled by `factor`."""
    *head, offsets, x = args
    return TODAY(*head, [(q, factor * b) for q, b in offsets], x)


def tangent(*args) -> np.ndarray:
    return (_at(args, 1.0) - _at(args, -1.0)) / 2


def second_order(*args) -> np.ndarray:
    plus, minus = _at(args, 0.5), _at(args, -0.5)
    return (plus - minus) + 2 * (plus + minus)


def _changes(config: str, columns: Callable[..., np.ndarray]) -> tuple[float, float]:
    """(σ total, values): the largest relative change against today's, C from `columns`."""
    cfg = load_config(config)
    reduce.offset_residuals = TODAY
    today = identify(cfg, scheduler=Inline()).result
    reduce.offset_residuals = columns
    try:
        other = identify(cfg, scheduler=Inline()).result
    finally:
        reduce.offset_residuals = TODAY
    return (float(np.max(np.abs(other.std_total - today.std_total) / np.abs(today.std_total))),
            float(np.max(np.abs(other.values - today.values) / np.abs(today.values))))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("configs", nargs="+")
    args = ap.parse_args()
    for config in args.configs:
        for name, f in (("first order (tangent)", tangent), ("second order (jet)", second_order)):
            s, v = _changes(config, f)
            print(f"{config}: {name:22s} σ total {s:.1e}  values {v:.1e}", flush=True)


if __name__ == "__main__":
    main()
