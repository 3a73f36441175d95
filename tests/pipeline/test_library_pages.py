"""pipeline.heap.release_library_pages: the shared libraries' clean pages dropped from this process's resident set,
by LocalScheduler where a map starts and once its first job is done, and nothing else. Oracle: the kernel's own
account of each mapping's resident and copied-on-write pages (/proc/self/smaps), in a fresh interpreter each (what
is resident is process-wide).

LLVM (llvmlite, numba's code generator) is the library of interest: its initialisers and numba's first compiled call
touch tens of MB of it that nothing uses once the kernels are loaded. The old code has no such release: a map's jobs
see LLVM's pages still resident."""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from dynid.pipeline.heap import RELEASE_GROWTH, _glibc

SRC = str(Path(__file__).resolve().parents[2] / "src")

pytestmark = [pytest.mark.skipif(_glibc() is None or not Path("/proc/self/smaps").exists(),
                                 reason="the pages are released through Linux's madvise, read in /proc/self/smaps")]
pytest.importorskip("numba")

SMAPS = """
import json, sys
def mappings():
    out, cur = {}, None
    for line in open("/proc/self/smaps"):
        p = line.split()
        if len(p) >= 5 and not p[0].endswith(":"):
            cur = out.setdefault(p[0], {"path": p[5] if len(p) > 5 else "", "perms": p[1]})
        elif p and p[0] in ("Rss:", "Anonymous:"):
            cur[p[0][:-1]] = int(p[1])
    return out
def llvm_clean_kb(maps):  # LLVM's resident pages that are the file's own (not copied on write)
    return sum(m["Rss"] - m["Anonymous"] for m in maps.values() if "llvmlite" in m["path"])
import numba
@numba.njit
def twice(x):
    return 2.0 * x
"""

RELEASE = SMAPS + """
from dynid.pipeline.heap import release_library_pages
assert twice(1.5) == 3.0  # LLVM initialised and used: its pages resident
before = mappings()
released = release_library_pages()
after = mappings()
@numba.njit
def thrice(x):
    return 3.0 * x
print(json.dumps({"released": released, "llvm_before": llvm_clean_kb(before), "llvm_after": llvm_clean_kb(after),
                  "before": before, "after": after, "works": [twice(2.0), thrice(2.0)]}))
"""

MAP = SMAPS + """
from dynid.pipeline.schedulers import LocalScheduler
scheduler = LocalScheduler(1)  # made before LLVM's first use: its own release (the imports' pages) not the map's
assert twice(1.5) == 3.0
ahead = llvm_clean_kb(mappings())
seen = []
def job(i):
    seen.append(llvm_clean_kb(mappings()))  # at the job's start
    if i == 0:  # the first job loads a kernel of its own: LLVM used again
        f = numba.njit(lambda x: x + float(i))
        assert f(1.0) == 1.0
    return i
total = scheduler.map_reduce(job, [0, 1, 2], lambda j: 0, lambda a, b: a + b)
assert total == {0: 3}
print(json.dumps({"ahead": ahead, "seen": seen}))
"""


def _run(code: str) -> dict:
    environ = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}
    out = subprocess.run([sys.executable, "-c", code], env=environ, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_llvms_clean_pages_leave_the_resident_set_and_the_copied_ones_stay():
    r = _run(RELEASE)
    assert r["llvm_before"] > 4096  # LLVM used: MBs of it resident (~40 MB here)
    assert r["released"] > 0
    # what stays is what this interpreter's own code between the two reads touched: none of LLVM's
    assert r["llvm_after"] < r["llvm_before"] / 20
    before, after = r["before"], r["after"]
    for key, m in before.items():
        if m["path"] and m["Anonymous"] > 0 and key in after:  # a library's relocated or written data: kept
            assert after[key]["Anonymous"] >= m["Anonymous"], (m["path"], m["perms"])
    assert r["works"] == [4.0, 6.0]  # the dropped code mapped back from the file on use, a new kernel compiled


def test_a_local_map_releases_them_where_it_starts_and_after_its_first_job():
    r = _run(MAP)
    seen = r["seen"]
    assert r["ahead"] > RELEASE_GROWTH // 1024  # LLVM resident before the map: enough for a release
    # the first job's start: released at the map's start (the compiled call before it had made LLVM resident); the
    # second's: released after the first job, which had used LLVM again; the third's: nothing since. A release is
    # done when the file-backed pages grew by RELEASE_GROWTH, so up to that may stay (~0 here; 69 MB unreleased)
    assert max(seen) < RELEASE_GROWTH // 1024, seen


def _smaps_entry(range_: str, perms: str, inode: str, path: str, rss: int, anonymous: int, swap: int) -> str:
    """One mapping of /proc/self/smaps as Linux 6.1 writes it (kB), the fields that do not matter here at 0."""
    return "\n".join([f"{range_} {perms} 00000000 fe:00 {inode}    {path}", "Size:  8 kB", "KernelPageSize: 4 kB",
                      "MMUPageSize: 4 kB", f"Rss:  {rss} kB", "Pss: 0 kB", "Shared_Clean: 0 kB", "Private_Clean: 0 kB",
                      "Private_Dirty: 0 kB", "Referenced: 0 kB", f"Anonymous:  {anonymous} kB", "LazyFree: 0 kB",
                      "AnonHugePages: 0 kB", f"Swap:  {swap} kB", "SwapPss: 0 kB", "Locked: 0 kB", "THPeligible: 0",
                      "VmFlags: rd mr mw me"])


def test_a_mapping_with_a_copied_page_in_swap_is_not_released(monkeypatch):
    """Oracle: the kernel's rule for a private file mapping's copied-on-write page. smaps' Anonymous counts those
    resident alone; one swapped out (a library's RELRO page, relocated then made read-only, on a machine with swap)
    counts in Swap, and MADV_DONTNEED would drop it too: the library's relocated pointers read back as the file's.
    A made-up smaps (the kernel's own would need swap and memory pressure) and a madvise that records its calls."""
    import dynid.pipeline.heap as heap

    smaps = "\n".join([
        _smaps_entry("7f0000000000-7f0000002000", "r--p", "11", "/lib/a.so", 8, 0, 0),  # the file's own: released
        _smaps_entry("7f0000002000-7f0000004000", "r--p", "11", "/lib/a.so", 4, 0, 4),  # its RELRO, a page swapped
        _smaps_entry("7f0000004000-7f0000006000", "r--p", "11", "/lib/a.so", 8, 4, 0),  # its RELRO, resident
        _smaps_entry("7f0000006000-7f0000008000", "rw-p", "11", "/lib/a.so", 8, 0, 0),  # writable
        _smaps_entry("7f0000008000-7f000000a000", "r--p", "0", "", 8, 0, 0),  # anonymous
        _smaps_entry("7f000000a000-7f000000c000", "r-xp", "12", "/lib/b.so", 8, 0, 0),  # code: released
    ]) + "\n"
    files = {"/proc/self/smaps": smaps, "/proc/self/status": "Name: python\nRssFile: 1048576 kB\n"}
    advised = []

    class Libc:
        def madvise(self, addr, size, advice):
            advised.append((addr.value, size.value, advice))
            return 0

    monkeypatch.setattr(heap, "open", lambda path, *a, **k: io.StringIO(files[path]), raising=False)
    monkeypatch.setattr(heap, "_glibc", Libc)
    monkeypatch.setattr(heap, "_released_to", [-heap.RELEASE_GROWTH])
    assert heap.release_library_pages() == 2 * 8192
    assert advised == [(0x7F0000000000, 8192, heap.MADV_DONTNEED), (0x7F000000A000, 8192, heap.MADV_DONTNEED)]
