import sys
from pathlib import Path

import pytest
from threadpoolctl import threadpool_limits

# the shared helpers (oracles.py, mujoco_car.py, tx40_case.py) beside this file, and every layer's folder: a test
# module takes another's fixtures by its name (test_urdf's robots, test_car_truth's judge), wherever it lives
HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))
sys.path[1:1] = sorted(str(d) for d in HERE.iterdir() if d.is_dir() and not d.name.startswith((".", "_")))

SHARED = Path(__file__).resolve().parents[1].parent / "shared"
TX40_DATA = SHARED / "data" / "tx40"


@pytest.fixture(scope="session")
def tx40_data() -> Path:
    if not (TX40_DATA / "TX40_bp_5.csv").exists():
        pytest.skip(f"real TX40 data not found at {TX40_DATA} (shared/ is beside the repository in CI)")
    return TX40_DATA


@pytest.fixture(scope="session", autouse=True)
def _blas_on_one_thread():
    """BLAS on one thread, as an identification runs it (pipeline/run.py, schedulers.py, plan.py, excitation.py and
    tire_curves.py hold threadpool_limits(1)): the tests that call the estimators directly (StreamingLS,
    solve_with_offsets, wls_pc, the Monte Carlo oracles) ran theirs on OpenBLAS's threads, whose wake-ups on small
    matrices doubled their CPU on this 2-core machine (test_plan's reported-sigma pair: 18.0 and 19.6 s user
    against 10.5 and 9.9 s). A test that needs more threads sets its own limit inside (test_solve_threads)."""
    with threadpool_limits(limits=1, user_api="blas"):
        yield
