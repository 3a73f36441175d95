"""What this machine can hold: work that would not fit is refused up front with its size and the fix, not
left to swap or to a MemoryError deep inside."""

from __future__ import annotations

import os


def memory_budget() -> float:
    """Bytes one array (or one step's arrays) may take: half the machine's physical memory, or 8 GiB where
    the system does not say."""
    try:
        return 0.5 * os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return 8 * 2.0**30
