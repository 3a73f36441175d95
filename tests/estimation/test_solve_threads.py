"""An identification runs its BLAS on one thread, its solves included (issue 28).

The map's workers already did; the solves after it (the offsets' QRs of a few hundred rows by ~85 columns) ran on
OpenBLAS's threads, which cost 1.5 ms -> 145 ms of CPU per QR on a loaded 2-core machine. Oracle: threadpoolctl's
own report of the BLAS libraries' thread counts, read from inside the solve while the caller allows two.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_robot_flags import run, ur5_tree
from threadpoolctl import threadpool_info, threadpool_limits

from dynid.estimation.streaming import StreamingLS


@pytest.mark.slow
def test_the_solve_runs_blas_on_one_thread(tmp_path, monkeypatch):
    seen: list[list[int]] = []
    solve = StreamingLS.solve_weighted

    def spy(self, *a, **k):
        seen.append([d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"])
        return solve(self, *a, **k)

    monkeypatch.setattr(StreamingLS, "solve_weighted", spy)
    with threadpool_limits(limits=2, user_api="blas"):
        run(tmp_path, ur5_tree(), np.full(6, 1.0), "threads")
    assert seen and all(n == [1] * len(n) for n in seen), seen
