"""Where a benchmark's figures go: benchmarks/results/NAME.json, written atomically (a partial file never read)."""

from __future__ import annotations

import json
from pathlib import Path

HERE = Path(__file__).resolve().parent


def write_results(name: str, data: dict) -> None:
    """results/NAME.json, through a temporary file renamed over it; says where it went."""
    dest = HERE / "results" / f"{name}.json"
    dest.parent.mkdir(exist_ok=True)
    tmp = dest.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=2))
    tmp.replace(dest)
    print(f"wrote {dest.relative_to(HERE.parent)}")
