"""How far a kernel is from this machine's arithmetic limit (issue 16, item 3), measured, not guessed.

- `peak_flops()`: one core's peak double-precision rate, from a small fused multiply-add loop (Numba, fastmath:
  64 independent accumulators in L1, so vector lanes and both FMA ports can be busy), counting an FMA as 2
  operations. It is the ceiling a compute-bound kernel can approach, on this CPU, in this run.
- `operations(tree, model, **opts)`: the kernel's arithmetic, counted on SYMORO-style customised symbolic model
  of the same tree (multiplications + additions; sines and cosines counted apart): the least work known for it.
- `roofline_line(...)`: operations per sample, achieved operations per second, fraction of the peak.
"""

from __future__ import annotations

import time

import numpy as np


def peak_flops(seconds: float = 0.3) -> float:
    """Double-precision operations per second of one core (an FMA counts 2), best of 3 runs."""
    from numba import njit

    # 64 accumulators in a local array of literal size: LLVM keeps them in vector registers and the chains are
    # independent, so the loop runs at the FMA units' rate (an array passed in, or a size known only at run
    # time, left it load/store-bound at a quarter of that here)
    @njit(fastmath=True, cache=False)
    def fma(a, b, n):
        x = np.ones(64)
        for _ in range(n):
            for k in range(64):
                x[k] = x[k] * a + b
        return x.sum()

    fma(0.999999, 1e-6, 10)  # compile
    n = 1000
    while True:
        t = time.perf_counter()
        fma(0.999999, 1e-6, n)
        if time.perf_counter() - t > seconds / 3:
            break
        n *= 4
    best = min(_timed(fma, n) for _ in range(3))
    return 2.0 * 64 * n / best


def _timed(fn, n) -> float:
    t = time.perf_counter()
    fn(0.999999, 1e-6, n)
    return time.perf_counter() - t


def operations(tree, model: str, **opts) -> tuple[int, int]:
    """(multiplications + additions, functions) of the customised symbolic model of `tree`."""
    from dynid.symbolic import build

    c = build(tree, model, **opts).ops()
    return c.mult + c.add, c.func


def roofline_line(name: str, ops: int, funcs: int, us_per_sample: float, peak: float) -> str:
    achieved = ops / (us_per_sample * 1e-6)
    return (f"{name:<44} {ops:>7} ops + {funcs:>3} sin/cos per sample  {us_per_sample:>8.3f} µs  "
            f"{achieved / 1e9:>6.2f} Gop/s  {100 * achieved / peak:>5.1f} % of peak")
