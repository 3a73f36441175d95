"""pipeline.heap: pyarrow's default pool made the system allocator before a robot's first Parquet read, unless the
user chose one. Oracle: pyarrow's own report of its default pool's backend, in a fresh interpreter each (the
variable is read once per process, and the pool set is process-wide)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("pyarrow")

SRC = str(Path(__file__).resolve().parents[2] / "src")

PROBE = """
import json, sys
{before}
from dynid.pipeline.heap import arrow_system_pool
changed = arrow_system_pool()
import pyarrow as pa
print(json.dumps({{"changed": changed, "backend": pa.default_memory_pool().backend_name}}))
"""


def _probe(before: str = "", env: dict[str, str] | None = None) -> dict:
    environ = {k: v for k, v in os.environ.items() if k != "ARROW_DEFAULT_MEMORY_POOL"}
    environ.update(env or {})
    environ["PYTHONPATH"] = SRC + os.pathsep + environ.get("PYTHONPATH", "")
    out = subprocess.run([sys.executable, "-c", PROBE.format(before=before)], env=environ, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_system_pool_before_pyarrow_is_imported():
    assert _probe() == {"changed": True, "backend": "system"}


def test_system_pool_after_pyarrow_is_imported():
    # pyarrow already loaded (its default pool made): the pool itself is set
    assert _probe("import pyarrow.parquet") == {"changed": True, "backend": "system"}


@pytest.mark.parametrize("before", ["", "import pyarrow"])
def test_the_users_pool_is_kept(before):
    import pyarrow as pa

    other = next((b for b in pa.supported_memory_backends() if b != "system"), None)
    if other is None:
        pytest.skip("this pyarrow has no allocator but the system's")
    assert _probe(before, {"ARROW_DEFAULT_MEMORY_POOL": other}) == {"changed": False, "backend": other}

