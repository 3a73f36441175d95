"""The C heap between segments: what glibc keeps after NumPy frees a segment's temporaries.

A segment allocates and frees hundreds of MB of arrays. glibc keeps freed blocks below its
mmap threshold in the heap, fragmented, so a long run's resident memory creeps up though nothing
is in use: `trim_heap` hands them back after each map of segments and after a test's plan (a few ms).
On a Dask worker, whose nanny sets MALLOC_TRIM_THRESHOLD_ (which turns glibc's adaptive mmap
threshold off: every array over 128 kB a fresh mmap, page-faulted and zeroed, 1.8 x the time of a
segment: 249 ms against 137 ms), `tune_malloc` restores what the adaptive threshold converges to.
`tune_threads` sets the heap up for `LocalScheduler`'s threads, once, before they and the plan's reads start.
Each thread had its own arena, grown in heaps of at most 64 MB that glibc unmaps once their top is free, the
heap's top beyond the adaptive trim threshold was handed back at each free, and a trim every 8th segment handed
back the rest: a segment's arrays were mapped, faulted and zeroed afresh, segment after segment (an hour of car
data on 2 threads: 250-310k page faults, 17 % of the CPU samples in the kernel zeroing pages). On one arena whose
top is kept until the map ends (`trim_heap` then), the next segment reuses them: 85-135k, of which the
segments' stages 9-22k (benchmarks/profile_car.py --threads 2), the rest the plan's, the solve's and the tire
fit's, each after a trim.
Each does nothing where there is no glibc. `arrow_system_pool` has pyarrow allocate from that same heap (its
own default, mimalloc or jemalloc, keeps its arenas' pages after the Parquet reads: a 1 h robot log's ~30 MB;
and gives back freed ones that the next segment's read faults in again).
The resident set also counts every page of a shared library the process ever touched: the imports' (LLVM's
static initialisers when llvmlite loads, ~36 MB) and Numba's first compiled call (LLVM compiling its runtime and
linking the cached kernels, ~28 MB more) leave 131 MB of them, a third of a robot map's peak, most never used
again. `release_library_pages` drops the clean pages of the read-only file mappings from this process's page
table (the page cache keeps them: one that is used again is mapped back from it, a minor fault) when a local
scheduler is made, where its map starts and once the map's first job has loaded the kernels the others use.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
from functools import cache

M_TRIM_THRESHOLD, M_MMAP_THRESHOLD, M_ARENA_MAX = -1, -3, -8  # glibc's mallopt parameters
MADV_DONTNEED = 4  # Linux's madvise advice: a range's pages dropped (a private file mapping's reread from the file)
# a release (reading /proc/self/smaps, 15-40 ms beside a robot map's heap) is done when the file-backed resident set
# grew by this much since the last: a map whose kernels were loaded before it gives back ~3 MB, not worth the read.
# 32 MiB: the 406 demo's identification releases twice (18 ms each of its 4.0 s CPU; three times at 16 MiB), a 1 h
# robot map peaks at 251-256 MiB (235 at 16 MiB: the map's own growth, ~10 MB of pages, then stays)
RELEASE_GROWTH = 32 * 2**20
_released_to = [-RELEASE_GROWTH]  # the file-backed resident bytes the last release left
MMAP_THRESHOLD = 32 * 2**20  # glibc's largest adaptive value on 64-bit systems
TRIM_THRESHOLD = 2 * MMAP_THRESHOLD  # as the adaptive rule sets it
THREADS_TRIM_THRESHOLD = 2**30  # a map's free heap top kept: at most what its jobs held at once (the peak stays)
ARROW_POOL = "ARROW_DEFAULT_MEMORY_POOL"  # pyarrow's own switch, read once: when its default pool is first made


@cache
def _glibc():
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        libc.malloc_trim  # noqa: B018 - musl has neither malloc_trim nor mallopt
        libc.mallopt  # noqa: B018
    except (OSError, AttributeError):
        return None
    return libc


def trim_heap() -> None:
    """Hand the heap's free blocks back to the system."""
    libc = _glibc()
    if libc is not None:
        libc.malloc_trim(0)


def release_library_pages() -> int:
    """Drop this process's resident pages of its read-only private file mappings (shared libraries' code and
    constants) that it never wrote (module doc), when they grew by RELEASE_GROWTH since the last release; bytes of
    mappings released (0: none, or no glibc on Linux).
    A mapping with a page copied on write (a library's relocated data, read-only after relocation), resident or
    swapped out, is left alone: dropping those pages would revert them to the file's. The mappings are read, then
    advised: a library unloaded and its range mapped again in between (dlclose, which Python's extension modules
    never call) is the one race."""
    libc = _glibc()
    if libc is None or _file_resident() - _released_to[0] < RELEASE_GROWTH:
        return 0
    try:
        with open("/proc/self/smaps") as f:
            text = f.read()
    except OSError:
        return 0
    released = 0
    for lo, hi in _clean_file_maps(text):
        if libc.madvise(ctypes.c_void_p(lo), ctypes.c_size_t(hi - lo), MADV_DONTNEED) == 0:
            released += hi - lo
    _released_to[0] = _file_resident()
    return released


def _clean_file_maps(smaps: str) -> list[tuple[int, int]]:
    """The ranges of `smaps` (/proc/self/smaps' text) that are a file's own, private and read-only, with pages
    resident (most have none: a system call saved) and none copied on write: no anonymous page resident and none in
    swap (a relocated page swapped out is not the file's either). A mapping whose counts are missing is not one."""
    out = []
    span, fields = None, {}
    for line in (*smaps.splitlines(), None):  # None: the last mapping's end
        if line is None or (line and line[:1] in "0123456789abcdef"):  # a mapping (its fields' names: capitals)
            if span is not None and fields.get("Rss", 0) and fields.get("Anonymous") == 0 and fields.get("Swap") == 0:
                out.append(span)
            if line is None:
                break
            # range, perms, offset, device, inode[, path]: the file's own, private, read-only
            head = line.split(maxsplit=5)
            lo, hi = (int(x, 16) for x in head[0].split("-"))
            span = (lo, hi) if head[4] != "0" and head[1][1] == "-" and head[1][3] == "p" else None
            fields = {}
        elif span is not None and line.startswith(("Rss:", "Anonymous:", "Swap:")):
            name, value = line.split()[:2]
            fields[name[:-1]] = int(value)
    return out


def _file_resident() -> int:
    """This process's file-backed resident bytes (RssFile), 0 where /proc says nothing."""
    try:
        with open("/proc/self/status") as f:
            return next((int(x.split()[1]) * 1024 for x in f if x.startswith("RssFile:")), 0)
    except OSError:
        return 0


def tune_malloc() -> bool:
    """glibc's thresholds set as above (False where there is no glibc)."""
    libc = _glibc()
    return libc is not None and bool(libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)) \
        and bool(libc.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD))


def tune_threads() -> bool:
    """glibc's mmap threshold fixed at MMAP_THRESHOLD, the heap's top kept up to THREADS_TRIM_THRESHOLD and one
    arena for the threads started from now on (module doc; False where there is no glibc). A thread started before
    keeps its own arena, and so does a thread that takes over an exited thread's."""
    libc = _glibc()
    return libc is not None and bool(libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)) \
        and bool(libc.mallopt(M_TRIM_THRESHOLD, THREADS_TRIM_THRESHOLD)) and bool(libc.mallopt(M_ARENA_MAX, 1))


def arrow_system_pool() -> bool:
    """pyarrow's default memory pool the system allocator, as ARROW_DEFAULT_MEMORY_POOL=system would make it, unless
    the user set that variable (their choice kept: False). Before pyarrow is imported the variable is set (pyarrow
    reads it once; a process started from this one inherits it); after, the pool itself. Buffers already allocated
    stay in their pool."""
    if os.environ.get(ARROW_POOL):
        return False
    if "pyarrow" not in sys.modules:  # not imported here: a robot's CSV logs never load it
        os.environ[ARROW_POOL] = "system"
        return True
    pa = sys.modules["pyarrow"]
    pa.set_memory_pool(pa.system_memory_pool())
    return True
