"""What this machine can hold: work that would not fit is refused up front with its size and the fix, not
left to swap or to a MemoryError deep inside."""

from __future__ import annotations

import os


def memory_budget() -> float:
    """Bytes one array (or one step's arrays) may take: half the machine's physical memory (8 GiB where the
    system does not say), and at most half the process's address-space limit when one is set (`ulimit -v`: the
    libraries already take a few hundred MB of it; beyond it the allocation fails with a MemoryError half-way)."""
    try:
        budget = 0.5 * os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        budget = 8 * 2.0**30
    return min(budget, 0.5 * address_space_limit())


def address_space_limit() -> float:
    """The process's address-space limit in bytes (`ulimit -v`, RLIMIT_AS), inf without one."""
    try:
        import resource  # optional: POSIX only (not on Windows)
    except ImportError:  # not on this system (Windows)
        return float("inf")
    soft = resource.getrlimit(resource.RLIMIT_AS)[0]
    return float("inf") if soft == resource.RLIM_INFINITY or soft <= 0 else float(soft)


def budget_text() -> str:
    """What `memory_budget` is half of, for an error message."""
    return ("half this process's address-space limit (ulimit -v)" if address_space_limit() < float("inf")
            and memory_budget() == 0.5 * address_space_limit() else "half this machine's memory")
