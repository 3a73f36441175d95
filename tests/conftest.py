import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

SHARED = Path(__file__).resolve().parents[1].parent / "shared"
TX40_DATA = SHARED / "data" / "tx40"


@pytest.fixture(scope="session")
def tx40_data() -> Path:
    if not (TX40_DATA / "TX40_bp_5.csv").exists():
        pytest.skip(f"real TX40 data not found at {TX40_DATA} (shared/ is beside the repository in CI)")
    return TX40_DATA
