"""A robot's identification memory is bounded by its factors, not its rows (issue 25 item 1): peak RSS of
`dynid identify` on a long log of a 7-joint arm (default 1 h at 1 kHz: 3.6 M samples, 14 channels).

    PYTHONPATH=src python benchmarks/bench_robot_memory.py [--seconds 3600] [--rate 1000] [--folder DIR]

The log (the Panda arm of example-robot-data's URDF, five harmonics per joint, torques by its inverse dynamics,
Parquet with a time column) is written once into --folder by a first process (kept for the next run); a second
process runs the identification alone and prints its own peak resident set (ru_maxrss), beside the same
process's RSS after the imports, its file-backed part at the end (RssFile: shared libraries' pages, Linux), and
the identification's wall time. Target: under 300 MB.

Measured 2026-11-29 (19:20-19:23 UTC, load average 1.6-1.7, nothing else of ours running), main with the gate at
32 MiB (`heap.RELEASE_GROWTH`: the 406 demo's identification releases twice, 18 ms each of its 4.0 s CPU) against
f15571e and ffe91d6, whole processes, 3 triples alternated after a warm-up each: peak 247-257 MiB against 344-395 and
389-396 (file-backed at the end 41-42 MB against 136-141); the identification's wall 15.3, 14.2, 15.4 s against
20.7, 14.9, 14.9 (f15571e) and 15.6, 14.2, 13.0 (ffe91d6): pair ratios to ffe91d6 0.98, 1.00, 1.18 (median 1.00);
process CPU 26.8, 24.6, 27.0 s against 27.4, 26.0, 24.1 (median of ratios 0.98). The host varied run to run by
~20 % (f15571e's 20.7 s).

Measured 2026-11-29 (18:20-18:25 UTC, load average 1.6-3.6 on the 2 cores: other sessions), this tree against
f15571e (the command above, the log kept in --folder), whole processes, 3 pairs alternated after a warm-up each,
medians: peak 235.0 MiB (233.2-237.6) against 345.1 (344.1-346.7): the target met; process CPU 23.85 s against 24.21
(pair ratios 0.920-1.012, median 1.005; system 0.83 s against 0.92), the identification's wall pair ratios 0.64-0.93
(median 0.92: the load). Two calls before (the same command): 18:03-18:07 (load 3.8-4.7), peak 236.4 (235.9-238.1)
against 349.6 (345.1-351.7), CPU pair ratios 0.971-1.102 (median 1.0005), wall 0.53-1.00 (median 0.74); 17:40-17:47
(load 3.8-8, before the 16 MiB gate): peak 239.0 (233.4-243.2) against 348.3 (345.7-351.1), CPU pair ratios
0.992-1.018 (median 0.992), wall 0.96-1.89 (median 1.016). The estimate, its sigmas, covariance, validation and
errors bit-equal (one hash each, both trees, the 1 h log and a 120 s one). What went: the shared libraries' pages
the process touched once (`heap.release_library_pages`, when LocalScheduler is made, where a local map starts and
once its first job is done, each when the file-backed pages grew by 16 MiB since the last: 15-40 ms a release; a 406
identification from files makes 3 with the gate as without, each giving back 18-100 MB: 71-87 ms of its 1.8-2.0 s
CPU, load ~4): an RSS trace (status and mallinfo2 every 3 ms, smaps at the running maximum) showed at the peak 131
MB file-backed, libllvmlite.so 67 of it (36 when llvmlite is imported: LLVM's static initialisers; 28 at the first
compiled call: numba compiling its runtime and linking the cached kernels; ~10 at the map's first chunk: its kernels
linked), pyarrow's libraries 33, NumPy's and the two OpenBLAS 10, libpython 4, libcrypto 3; none of LLVM's used
again once the kernels are loaded. Dropped (madvise, clean read-only file pages only: the page cache keeps them),
the map's file-backed part is 17-22 MB (the pages its chunks use, faulted back from the cache). The anonymous part
at the peak, now most of what is left (one trace, load 8-9; peak 256 MB, RssFile 22, RssAnon 234): glibc's heap 175
MB (in use 95-106, free 68-79 of it: the chunks' holes and a 23 MB top kept for the next chunk,
`heap.tune_threads`), ~60 outside it: Python's small-object arenas 48 (46 of 1 MiB, 46.5 MB of live objects: the
modules' code and data, numba's typing and lowering registries; sys._debugmallocstats after a 120 s log's
identification), the rest numba's compiled code and the threads' stacks (not broken down); at the map's start
RssAnon 111 (heap in use 54). The anonymous part moves by +-15 MB from run to run (where the chunks' arrays fall in
the heap). Not done: the heap's free 70-80 MB inside the map (the levers measured before: a trim after each chunk or
the arrays on pages of their own, +5-6 % CPU); the imported modules not needed by then (881 after the imports, 996
at the peak: pyarrow on the first read, numba's lowering registries with cffi and pycparser at the first compiled
call): not measured one by one.

Measured 2026-11-29 (16:38-16:49 UTC, load average 1.0-1.8: no other session of ours; the host varied, ffe91d6's
identification 13.5-17.3 s), this tree against ffe91d6 and 17cb88d, whole processes after a warm-up each, 6 pairs
against ffe91d6 (3 of them triples with 17cb88d), medians: the identification's wall 15.15 s against 15.7 (pair
ratios 0.88-1.10, median 0.97; 17cb88d 18.0), process CPU 26.4 s against 28.5 (0.93 x), peak 352 MiB (346-355)
against 388 (382-392; 17cb88d 345, 344-346): the wall back within the 5 % bound, the peak 7 MB over 17cb88d's (the
shared span's outputs held for the next chunk).

Measured 2026-11-29 (15:15-16:25 UTC, load average 2.6-8 on the 2 cores: other sessions; wall times not
comparable): where the map's time went (a timeline of each task's thread, perf_counter span and thread_time, the
tree before this paragraph): per chunk the read 34 ms of CPU (its joints' speeds decimated: 10.5 of it), the W
blocks ~270 on the two threads, the tail 18 on the calling thread (the second stage 14) while the next read ran on
the third: one core idle ~16 ms a chunk plus the last block's wait; and every chunk made W on its decimation
transient (4,900 samples a side: 65,400 of W for 55,600 kept, 15 %) though the chunks run in order. What went: a
chunk takes the first decimation stage's outputs the chunk before made on their shared span (`RobotJob.handoff`,
`decimate_parallel_blocked`'s known and share): 2 of its 19 W blocks skipped and the third begun where they end
(W's samples -13 %). Whole processes, 3 pairs alternated after a warm-up each, medians, against ffe91d6: CPU
0.949 x (pairs 0.781-0.955; 24.8 s against 29.3, load 2.6-4.7), peak 346.1 MiB (341.6-350.1) against 389.5, wall
0.69 x (0.64-1.05: the load); an earlier call (the first commit, load 3-5): CPU 0.926 x (0.907-1.015), peak 344.7
against 386.8. The estimate against 17cb88d's to 1.8e-11 relative (1.0e-15 of the largest value), sigmas 4.7e-12,
the covariance 9.3e-12 of sqrt(C_ii C_jj), the validation errors 5.5e-11: the shared span's outputs come from the
chunk before's window and blocks (the filters' tails, 1e-9 of the kept rows' weight, as any chunking). A
cluster's chunks make their own, so its estimate matches the threads' to 1e-9 of its largest value (its test's
bound now). Measured, not kept: the speeds decimated only when a joint has a speed threshold (none here: every
row kept, the same bits): CPU 0.90 x this tree (2 pairs, 0.89-0.91) but the peak 352.4-353.6 MiB against
344.6-350.2 (the shorter read makes the next chunk's W buffers while the tail still holds W1, likely): a lever once
the buffers wait for the tail.

Measured 2026-11-29 (14:15-14:16 UTC, a quiet machine: load average 1.2-1.6), this tree (the map one chunk at a
time, h-rmem6's buffers, one glibc arena for the threads) against ffe91d6 (two chunks side by side), whole
processes, 3 pairs alternated after a warm-up each, medians: peak 344 MiB (342-349) against 389 (388-392); the
identification's wall 14.5 s (14.2-14.9) against 13.0 (12.9-13.7): +11.5 %, over the 5 % bound that the loaded
figures below could not resolve; process CPU 25.7 s against 24.2 (+6 %). Why: after a chunk's W blocks its second
decimation stage, QR and rows run on one thread while the next chunk is read on the other, and the two do not take
the same time; the fix left is to start the next chunk's W blocks on the core that comes free. The next chunk's
read started with this chunk instead (not kept; 3 pairs, load 1.3-1.7): peak 377-386 MiB, wall 15.2-16.5 s
against 14.5-17.1: no faster, 40 MB more.

Measured 2026-11-29 (13:14-13:22 UTC, load average 7-11 on the 2 cores: other sessions): peak 348.8 MiB against
366.2 at 47066a3 (whole-process figures, 3 runs each alternated A B A B after a warm-up each, medians; 348.4-356.9
against 363.0-366.4), CPU 0.99 x (pairs 0.94-1.12; 28.6 s against 29.2), wall 1.03 x (0.68-1.17: the load); three
more calls of this tree (13:46-14:03 UTC, load 1.4-5, 3, 5 and 5 pairs): peak 345.6, 346.6, 348.5 against 360.3,
364.9, 362.8, CPU 0.97 x, 1.04 x, 1.01 x (pairs 0.89-1.20), wall 1.15 x, 0.97 x, 0.94 x (pairs 0.58-1.98: the
machine's other sessions); the estimate, its covariance, the validation errors and the plots' rows bit-equal (one
hash each, both trees). What went: a chunk's W block buffers (2 x 11.8 MB) made by the thread that read it, at the
end of its read, in the heap its transients left free (`robot.chunk_buffers`, `reduce.read_robot_chunk`; glibc's
arena of that thread), not by the calling thread beside the next chunk's read; the window's raw positions not held
once filtered; the row groups before the next chunk's window dropped from the block cache after each read
(`io.windows.forget_blocks_before`: one kept between chunks, not three; 1,804 column decodes against 1,819). Where
it goes (RSS traced every 5 ms, one run each, load 8-12): the map's start 240-248 MB, of it 131 file-backed
(RssFile: libllvmlite 69, the Arrow and NumPy libraries) and 109-117 anonymous; at the peak RssFile 132 and RssAnon
211-233; glibc's heaps at a chunk's end of blocks (malloc_info): the calling thread's 43-60 MB (67-86 at 47066a3),
the reader's 39-48 (6-18 free), two more of 18-22 each (8-15 free). So 300 MB leaves the anonymous memory 168, 55
over the map's start: one chunk's arrays are ~52. Measured, not taken: the W buffers and the first stage's output on
pages of their own (an anonymous mapping, unmapped when freed) and the heap trimmed after each read: 330.3 MiB
against 362.6 (328.1-337.4 against 360.1-365.8), CPU 1.057 x (pairs 1.049-1.115; system 1.9 s against 1.0: the pages
faulted in again each chunk), wall 1.061 x: over the 5 %; over this tree (one trace each): the first stage's output
alone on its own pages 348.5, no gain seen; the heap trimmed after each read 342.3, system time 2.1 s against 0.8;
the reader's cache bound at one block (a per-thread bound): 3,104 decodes against 1,819 (a window's stamps, q and
tau are three passes over the same two or three row groups); the W block at 4 MiB: the Panda's block is then 4 x its
overlap, 2,868 samples (not 1,741: -1.4 MB a buffer), and the blocks' bounds move the bits (the TX40 test log's rows
by 6.5e-15 relative), so not with bit-equal results; the positions filtered a joint at a time: no transient saved
(the filter already runs a few columns at once). The plots' rows (`run.PLOT_BYTES`, ~10 MB) left: fewer would change
the report.

Measured 2026-11-29 (11:02-11:16 UTC, load average 2-6 on the 2 cores: other sessions, and this branch's tests
during the second run): the wall time back (whole-process figures, 3 runs each alternated A B A B after a warm-up each,
medians, against 69ee46f). The next chunk's window read, health-checked and filtered on a second thread
(`schedulers.Staged`, `reduce.read_robot_chunk`), and a chunk's first W block no longer alone (the helpers' blocks
beside it; W1 still made by the calling thread): wall 0.998 x (pairs 0.987-1.036; 46.8 s against 45.2, loaded),
CPU 1.012 x (0.968-1.040; 27.3 s against 27.0), peak 364.4 MiB against 386.3 (359.5-372.6 against 384.5-395.1).
With the read started at the chunk's start instead (overlapping its W blocks; load 2-4): wall 1.048 x
(1.030-1.065), CPU 0.988 x, peak 364.8 against 381.5; so the read now starts once the blocks are done
(`blocks_done`: the decimation's second stage and the least squares run beside it). The estimate, its
covariance and the validation error bit-equal (run1 hashes 3d26269e5420, 6e375f886f0b, 8.9094008e-06). The cost:
~25 MB of the 47 the one-chunk map gained (338.1 at b5bdcc5, one chunk, nothing ahead): one run each (load 3-6,
ru_maxrss of the whole run): 347 at b5bdcc5, 355 with the read on the second thread but not overlapped (its glibc
arena: the read's arrays in a second heap), 372 overlapped (the next window, its q, tau and filtered q, ~11 MB,
and the read's transient beside this chunk's W1 and second stage). Not tried: the read's arrays made in the
calling thread's heap, or the overlap dropped where memory matters more than wall time.

Measured 2026-11-29 (10:04-10:30 UTC, load average 7-15 on the 2 cores: other sessions and this branch's tests):
this tree against 69ee46f (whole-process timing, 3 runs each alternated A B A B after a warm-up each, medians): peak
338.1 MiB against 385.2 (334.3-346.9 against 384.1-386.1), CPU 0.91 x (pairs 0.87-1.08; 30.6 s against 33.8), the
estimate, its covariance and the validation error bit-equal (one hash over the 8 runs); the TX40 example's estimate and
covariance bit-equal (one hash). What went: (1) one chunk in flight: a LocalScheduler of k threads maps a robot's
chunks one at a time, each chunk's W blocks done k at once (`run.chunk_scheduler`, `decimate_parallel_blocked`'s
threads: each block alone, written to its own rows, the same bits), so one chunk's window, filtered positions and
W1 are held, not two; RSS trace 388.6 -> 365.7 MB (one run each, load 5.5); (2) the chunk's arrays in the heap the
plan left free space in: glibc gives each thread its own arena, and a helper's W buffer or W1 grew the helper's
heap while the calling thread's sat free; the W buffers and W1 are now made by the calling thread, and one local
worker is the calling thread itself: 346.5 (load 9); (3) qd and qdd made a W block at a time from the filtered
positions (central differences read two samples beyond the block: the same bits), not held for the window: 341.9,
338.6 (load 11-13). A chunk's NumPy at its peak (55,600 samples, 2 threads, mallinfo2 in use): +52 MB over the
map's start (the window's q and tau 7.5, qf 3.7, W1 9.9, two W blocks 23.6, the blocks' work ~5), against 2 x
43-45 before. The map's wall: 89 % of a chunk's CPU is in its blocks (10 chunks on one thread, BLAS on one: 4.20
of 4.73 s), and the rest (the window's read, its health, the filter, the second stage, the QRs) now runs on one
thread: on an idle machine expect the map's wall ~10-15 % longer than two chunks side by side (not measured idle;
0.89 x under this load, noise).
Not met: 300 MB is ~38 MB away. The floor at the map's start is 240-253 MB (RSS traces, load 5-15), and 131 MB of
it file-backed pages (smaps at the map's start, one run: libllvmlite.so 69, numba's LLVM touched when the first
cached kernel loads; libarrow 15, libparquet 5, libarrow_compute 5, NumPy's 5, libpython 5), 116 anonymous (the
heap 28); the map adds ~90 (the chunk's ~52, the plots' rows ~10, heap pages ~25). Measured, not taken: the Parquet
block cache at 1, 2, 3 row groups a file (`windows.CACHE_BLOCKS`, one trace each, load 10-13; the chunks now read in
order): 328.8, 333.7, 338.1 MB (a cache for every reader of the process: the car's two workers read out of order;
a per-reader bound would take it); MALLOC_ARENA_MAX=1 (after (1), one run): 345.3 against 364.5; a trim after every
chunk (`schedulers.TRIM_EVERY = 1`, after (1)): 356.6. Levers left: the cache above (-9 MB), the window's raw q
freed once filtered (-3.7), the W block at 4 MiB (-12, ~+7 % CPU: its overlap), the next chunk's read and filter
overlapped with this one's blocks (the wall back, +11 MB held).

Measured 2026-11-29 (07:18-07:27 UTC, load average 4-12 on the 2 cores: other sessions): this tree (scipy.io
imported where a .mat file is read or written, so a Parquet robot run loads neither it nor scipy.sparse) against
fd92e1c (whole-process timing, 3 runs each alternated A B A B after a warm-up each, medians): after the imports
121.7 MB against 124.8, the peak 391.5 MiB against 387.0 (386-395 against 386-388: noise, the 3 MB under the map's
spread), CPU 1.03 x (pairs 1.02-1.04); the estimate and its sigmas bit-equal (every run), the validation error
equal. The 10 min log (one run each): 373.2 against 372.9 MiB: the peak does not grow with the log (the 1 h's ~15 MB
more is the two workers' chunk peaks meeting more often over 65 chunks than over 11). The stages, RSS traced every 5
ms (fd92e1c's code, two runs, load 7-10): after the imports 125, the plan 271-272 at its peak (the pass over the
stamps), 221-222 after it, the data-health check 254-255, the map's start 246-248, its peak 390 (two workers), after
it 362, the solve and the checks 383 (the map's heap left under them: the whole run's peak is the map's). One worker
([compute] workers = 1): 346 at the peak, +100 over the map's start for one chunk's 43 MB of NumPy: the rest is the
heap glibc keeps (mallinfo2 read at the peak, a run perturbed by the reads: 179 MB of arenas, 79 in use, 101 free).
Tried and left: glibc's mmap threshold fixed for a robot run (mallopt, M_MMAP_THRESHOLD; the thresholds
`heap.tune_malloc` sets restored after), timed as whole processes against this tree as above with
MALLOC_MMAP_THRESHOLD_ = 2 MiB (06:43-07:07 UTC, load 11-14): peak 361.5 against 384.4 (360.7-364.7 against
381.5-385.0), CPU 1.23 x (pairs 1.09-1.29: system time 8.0 s against 0.7, page faults), and traced one run each:
mmap at 8 MiB with the trim threshold at glibc's 128 KiB 363 MB (system 7.2 s), at 3 MiB 368 (8.9 s), at 8 MiB with
a 16 MiB trim threshold 383 (3.1 s), with 64 MiB 393 (1.6 s): the ~25 MB is the heap's free top handed back and
faulted in again, not the large arrays' own pages; 20-25 MB for +20 % of CPU, as the threshold trials below. Not
met: 300 MB is ~90 MB away, and the map's peak is two chunks' arrays (2 x 43 MB) and the heap glibc keeps between
them over a floor of ~240 MB (imports 122: NumPy, scipy.linalg with the numpy.testing and f2py its array-API layer
imports, 9 MB, Numba 52; pyarrow 31; Numba's registries ~37 on the first cached call; the Parquet block cache 24).
The levers left are the design ones: one chunk in flight with its W blocks shared by the two threads (one chunk's
window, filtered signals and W1 held instead of two: ~-30 MB of arrays, and the heap's share with them), each
chunk's arrays in buffers a worker reuses (no heap to fragment), the positions filtered per W block (the filtered q,
qd, qdd of the whole window, ~11 MB a worker, not held; round-off, not the same bits).

Measured 2026-11-29 (05:21-05:25 UTC, load 0.7-2, quieter than the runs below): this tree, CHUNK_BYTES = 28 MiB
(55,600 samples, 65 chunks, ~ as before), against b872084 (whole-process timing, 4 runs each alternated A B A B
after a warm-up each, medians): peak 388.9 MiB against 407.7 (388.1-390.9 against 402.3-412.1), CPU 0.971 x (pairs
0.90-1.10); the estimate against b872084's to 1.5e-11 relative (1.9e-15 of the largest value), the sigmas 4.8e-12,
the covariance 9.6e-12 of its largest entry, the validation errors 1.1e-11 (the chunks' ends moved by 100 samples:
round-off, as below); the TX40 example bit-equal (its 45,000 samples one chunk). What went: the W block buffer
(below). CHUNK_BYTES = 20 MiB (39,700 samples, 91 chunks), the same way (05:14-05:21 UTC, load 0.7-4): peak 373.7
MiB against 405.5 (369.3-375.8 against 401.4-408.9), CPU 1.126 x (pairs 0.91-1.23), and against main at 05:09-05:13
(load ~4): 374.6 against 405.2, 1.125 x (1.03-1.25): over the 5 % bound, so not the default; the 0.97 x measured for
it below was the load's noise. The chunk's length is still set by what a worker holds for it (`CHUNK_BYTES` over
`chunk_sample_bytes`), the budget to lower where memory matters more than CPU (between 55,600 and 39,700 samples:
~-1 MB of the peak and ~+1 % of the CPU per 1k samples fewer).

Not met (2026-11-29): 300 MB is ~90 MB away. The floor now (RSS traces of this tree, load 5-11): 125 MB after the
imports, 243-249 at the map's start, 263-271 inside the data-health check (before the map), then the map's plateau,
~385: per worker 43-45 MB of NumPy's at a chunk's peak (tracemalloc; at 39,700 samples, 50,664 read, 37.9: the
window's q and tau 5.4, the filtered q, qd, qdd 8.1, the W block 11.5, W1 ~7.5, the filters' work ~3.5), the plots'
rows ~10 MB, and glibc's heaps (their in-use blocks and the fragments between them: a trim after every job, a lower
trim threshold or one arena give back <= 20 MB). The levers left, measured: the chunk's length (each 1k samples ~0.5
MB of a worker's NumPy, and ~1 % of the map's CPU per 1k fewer near 40k: the 9,800-sample pad), the W block
(`BLOCK_BYTES`; its first-stage overlap, 1,434 of its 4,914 rows, computed and filtered twice: a smaller block costs
CPU that way, and a W block's overlap rows copied from the block before would save the regressor's share, ~4 % of a
chunk), the column gathers of the first stage (W2[:, cols] and its copy, 2.4 of 17.8 ms a block, ~13 % of a chunk: a
filter kernel reading W's columns in place would pay for shorter chunks), the second stage streamed (W1 whole per
chunk), the Parquet block cache (24 MB) and the plots' rows (PLOT_BYTES) in the floor.

Measured 2026-11-29 (04:19-04:28 UTC, load average 5-7.6 on the 2 cores: other sessions; CHUNK_BYTES then 20 MiB, 28
MiB since: see above): peak 373.8 MiB against main's 402.0 at b872084 (whole-process timing, 3 runs each alternated
A B A B after a warm-up each, medians; 372.6-376.8 against 399.7-408.1), CPU 0.97 x (pairs 0.96-1.12; 34.5 s against
35.1 s). What went: a chunk's length is set by what a worker holds for it (`robot.CHUNK_BYTES`, 20 MiB, over
`chunk_sample_bytes`: the window's q and tau, the filtered q, qd, qdd, and W1 at every column, 528 bytes a sample
for the Panda), no longer by a full-rate W it never holds whole (`SEGMENT_BYTES`, 128 MiB: 55,700 samples): 39,700
samples, 91 chunks instead of 65. The chunks' boundaries moved, so the bits did: against main's, the estimate to
2.0e-11 relative (1.6e-15 of the largest value), the sigmas to 4.0e-12, the covariance to 8e-12 of its largest entry
(3.1e-10 relative, an entry near zero), the validation errors to 1.8e-11 relative: round-off, amplified by this
noiseless log's residual (9e-6 of the torques: a change of 1e-16 in the rows is ~1e-11 of the residual); other
lengths give the same (96 MiB-equivalent chunks: 4.4e-12, 8.8e-12, 1.0e-11). The TX40 example's estimate, sigmas,
covariance and errors are bit-equal to main's. One run each (trace): 371 MB at 41,800 samples, 363 at 31,300, 375 at
39,700. CHUNK_BYTES = 16 MiB (31,700 samples, 114 chunks), timed as whole processes against main as above
(04:35-04:46 UTC, load 6-9): peak 366.3 MiB against 402.6 (365.8-369.0 against 399.0-406.0), CPU 1.054 x (pairs
0.97-1.14): -7.5 MB for ~+8 % of CPU against 20 MiB's, at the 5 % bound; not taken. Tried and left (two runs each,
trace): the W block one buffer per worker thread, reused across its chunks (`threading.local`): 371.7 and 371.5
against 373.3 and 372.3 with one per chunk, noise; W1 and the W block on pages of their own (an allocation over
glibc's 32 MiB mmap threshold, unmapped when freed): 412, worse (freeing it raises glibc's trim threshold to 64 MiB,
and the thread heaps keep more); glibc's trim threshold 4 or 16 MiB with the mmap threshold at 32 MiB (mallopt):
386.6 and 386.9 against 387 (not the heap's top, then: its in-use blocks, 100-150 MB through the map, and the
fragments between them). The blocks' live-column search `np.any(W2 != 0, axis=0)` as `W2.any(0)`: the same 0.55 ms a
block. The first stage's filter kernel reading the column block's columns from W where they are (a compiled `a[i,
cols[c]]` into its work array, no `a[:, cols]`): bit-equal (the same hash), the first stage's filtering of a 4,914 x
301 block 7.9-15.8 ms against 11.5-13.9 (min of 40, three tries, load ~3.5: not settled), and with CHUNK_BYTES = 16
MiB, timed as whole processes against main (04:53-05:05 UTC, load 3.4-10): peak 370.0 MiB against 406.5 (367.2-378.4
against 405.7-411.9), CPU 1.00 x (pairs 0.78-1.16): no clear gain over 20 MiB without it (373.8, 0.97 x), and one
more compiled kernel to load; not kept.

Measured 2026-11-29 (03:56-04:05 UTC, load average 2.5-5.5 on the 2 cores: other sessions): peak 387.9 MiB against
main's 401.5 at b872084 (whole-process timing, 3 runs each alternated A B A B after a warm-up each, medians; 387-391
against 401-403), CPU 0.92 x (pairs 0.80-0.96; 25.0 s against 29.6 s), the estimate, its sigmas, covariance and the
errors bit-equal to main's (one hash). What went: a chunk's W block is one buffer for all its blocks (19 for the
Panda), filled by the regressor's `out` (it writes only the entries that can be non-zero, so the structural zeros
stay): each block was a fresh zeroed 11.3 MB array (a calloc's memset, and the worker's heap grown by it). An RSS
trace (VmRSS and glibc's mallinfo2 sampled every 5 ms in a thread) shows what the map holds: at its start 244-251
MB, then a plateau of ~390 (main) for the whole map, not a rise and fall per chunk: glibc keeps what a chunk freed.
Measured, one run each on main: a trim after every job (`schedulers.TRIM_EVERY = 1`) 398 (malloc_trim gives back the
free blocks in the bins, not a thread heap's top, which glibc keeps up to its trim threshold, twice the mmap
threshold); MALLOC_ARENA_MAX=1 395; glibc's mmap threshold set to 2 MiB (every array over it on its own pages,
unmapped when freed) 372: the live arrays then, mmapped, are the two workers' 2 x 43 MB (tracemalloc's), the heap's
in-use blocks ~60 MB (23 of them the Parquet block cache before the map; the plots' rows, 10 MB, the filters' work).
One worker alone, trimmed after each job: a plateau of 330 over 244 at the start, 307 right after a trim. What one
chunk holds at its peak (tracemalloc, 55,700 samples, 66,664 read): the window's q and tau 7.1 MB, the filtered q,
qd, qdd 10.7 (with the filter's work 3.6), W1 9.5, the W block 11.3, the column blocks' work ~3.5: 43.4 MB. Against
the chunk's length: 43.4, 31.5, 25.6, 22.7 MB at 55,700, 27,800, 13,900 and 6,900 samples, and the thread CPU per
chunk 0.36, 0.25, 0.13, 0.085 s: each chunk computes W and its decimation on 9,800 more samples (the decimation's
transient, 4,900 a side) and filters 10,964 more, so half the length costs ~+20 % of the map's CPU. cProfile of 6
chunks (4.9 s): the first decimation stage 2.75 s (its filter kernel 1.4, NumPy's column gathers and copies around
it ~1.0), the regressor's kernel 0.7, the Parquet reads 0.16.

Measured 2026-11-28 (20:11-20:15 UTC, load average ~1.5 on the 2 cores: two other sessions): peak 408.5 MiB against
main's 483.2 at 95b12f4 (whole-process timing, 4 runs each alternated A B A B after a warm-up each, medians; 401-411
against 482-485), CPU 0.89 x (pairs 0.84-0.96; 41.6 s against 46.6 s), the estimate, its sigmas, covariance and the
errors bit-equal to main's (one hash over the 10 runs). What went: (1) the car's imports of pipeline/reduce.py into
the car's functions: a robot run loads no vehicle module nor scipy.interpolate, optimize or spatial (after the
imports 125 MB against 149); (2) the blocked decimation's work space (`decimation.WORK_BYTES`) 4 -> 1 MiB, the same
bits (each column filtered alone); (3) pyarrow's default pool the system allocator (`heap.arrow_system_pool`, unless
ARROW_DEFAULT_MEMORY_POOL is set) before the plan's first read: mimalloc's arenas held their pages; (4) the heap
trimmed after the map; (5) the estimate's physical-consistency check given to Clarabel without cvxpy
(`estimation.physical.feasible_standard`): cvxpy's import, 56 MB after the map, had set the peak (432-445 in RSS
traces, the map's own high water ~400-410). The peak is now the map's: one worker's chunk, traced alone, rises 66 MB
over the resident set before it (43 MB of it NumPy's, tracemalloc), two workers ~130-150 MB over the ~250 MB left
after the plan and the data-health check.

Measured 2026-11-27 (19:25-19:35 UTC) on the 2-core machine, busy (~5 other sessions and a test run): 1 h, 251,986
rows of 43 parameters, peak 508 MiB against main's 524 at d8e0370 (whole-process medians of 3, A B A B in one run;
CPU 1.05 x, range 0.92-1.09, wall 1.05 x: noise, the change removes work), 529 at 77e8e1a, 937 MB at 54648a4, 1,056
MB at 212feaf (the rows stacked whole). The estimate is bit-equal to main's. What went, last: scipy.signal (dynid's
Butterworth design, its steady states, the single passes and the kernel's autocorrelation are in
`signals._butterworth` and `signals._zero_phase`; scipy.signal only without numba): the resident set after the
imports 149 MB against 172, and no car or robot identification loads scipy.signal or, before the map, scipy.stats.
Before: pandas (pyarrow's to_numpy imported it), the heap the plan's pass over the stamps left (trimmed), half of
each worker's block of the full-rate W.

Measured 2026-11-27 (22:47-23:26 UTC, load average 7-13 on the 2 cores: other sessions, and this branch's test run
during the first call): peak 472 and 477 MiB against main's 508 and 505 at 07e3a6a (two whole-process timings, 3
runs each alternated A B A B, medians; -28..-36 MB); CPU 1.05 x (pairs 1.02-1.05, the call beside the test run) and
0.94 x (0.93-0.95): noise of +-5 %; the work added, timed alone: 0.28 s to compare the stamps when planned and 0.28
s to read the 65 chunks' stamps, ~1 % of the 58 s. What went: the clock (`sources.FileClock`: the rows of the file's
time column, read back by a chunk from the row groups it reads anyway, `io.windows.stamp_rows`, every stamp compared
once when planned): the resident set before the map 274 -> 245 MB (an RSS trace around the stages). The estimate,
its sigmas and the errors are bit-equal to main's. Tried and left, one run each on the loaded machine (peaks there
move by +-20 MB): the block cache off (windows.CACHE_BLOCKS = 0): -24 MB before the map, ~-20 at the peak, each
chunk decoding its two row groups again (40 ms of CPU a group here, ~+2.5 %); MALLOC_ARENA_MAX=1 (the two workers'
threads in one glibc arena): -22 MB, CPU equal in that pair, a lever like the thresholds. A correction to the floor
below: scipy.interpolate is first imported by `signals.resampling` (make_interp_spline, for `io.align`'s cubic
resampling of q off the clock), which every robot run imports, and again by the vehicle package
(`vehicle.table_poly`'s BSpline, through vehicle/__init__): both must go for its 18 MB (measured beside NumPy,
scipy.linalg and Numba).

Measured 2026-11-28 (01:25-02:40 UTC, load average 5-8 on the 2 cores: other sessions' tests and demos): peak 463.8
MiB against main's 467.4 at ae30552 (whole-process timing, 3 runs each alternated A B A B, medians; pairs' range
463-478 against 465-473: noise), CPU 1.04 x (0.99-1.07; wall 53-177 s a run: the load), the estimate, its sigmas and
the errors bit-equal to main's (and with one worker). What went: (1) W1, the first decimation stage's output, holds
W's live columns alone (`decimate_parallel_blocked`; 190 of 301 for the Panda): 15.7 -> 9.9 MB a worker, not seen at
the peak through the noise. (2) The car's imports off a robot's path (`signals.resampling` imports scipy.interpolate
where a clock is resampled; pipeline.config, pipeline.run and report.build import the vehicle package, pipeline.car,
pipeline.delays and report.tires in the car's functions): with pipeline/reduce.py's car imports moved too (a patch
for that file's owner, not in this tree) a robot run loads no vehicle module and no scipy.interpolate, optimize or
spatial: the resident set after the imports 149 -> 125 MB; the peak 450.6 MiB against main's 481.5 (3 runs each
alternated, medians; 446-454 against 462-484) and 449.4 against 469.5 in a second call (437-456 against 461-474),
estimate bit-equal; CPU not settled: 1.11 x and 1.16 x in those calls (pairs 0.95-1.24; the patched runs' system
time 5.3-8.9 s against 2.0-5.3, page faults), 0.99 x in a pair run side by side under /usr/bin/time (system 2.55 s,
364 k minor faults against 4.13 s, 849 k: the faults vary 2 x from run to run). Without that patch a robot still
loads them through pipeline.reduce (149 MB). Corrections to the floor below: "Numba's code generator, 47 MB" is
numba's target context refreshed before the first function it loads from its cache
(`numba.core.caching.Cache.load_overload`): 86 modules of its lowering registries (numba.np, numba.cpython, the
typed containers, cffi and pycparser) +37 MB, its typing +3 MB, 3 s of CPU here; the code generator itself is 4.6
MB, made at import (a dispatcher built by `_zero_phase`). The first such call is `robot.chunk_pad`'s
`border_samples` (its impulse response through `sosfilt_forward`), before the map, not the data-health check.
Skipping that refresh on a cache hit (a patched `load_overload`, only the runtime initialised) ran bit-equal at a
peak of 447 against 472.5 MiB, CPU 53.9 against 55.5 s (one run each): not kept, it patches a private numba method;
any compiled call on a robot's path brings the refresh. Tried and left, one run each: the block cache at 2 row
groups a file (`windows.CACHE_BLOCKS`, 3 now): 1,806 decodes against 1,775, peak 469 against 468; at 1: 3,017
decodes (+70 %), peak 460.5 (-8, within the noise), CPU 55.0 against 56.8 s. glibc's arenas: each worker already
trims after its chunk (`heap.trim_heap`), so the peak is the two workers' high water inside their chunks (~85 MB
each over the 290 MB before the map: the window's samples, their filtering, one block of W with the filter's work,
W1); a worker's arrays allocated once and reused would be the design lever, not tried.

Before 2026-11-29: 300 MB was ~165 MB away. The floor with the patch (an RSS trace, 2026-11-28, beside the A/B): 125
MB after the imports, 226 after the plan (pyarrow and the clock), 278 after the data-health check, trimmed to 224,
284 after the first compiled call (numba's registries, 40 of it measured alone), then the map: ~85-115 MB a worker
over that at the peak (the window's samples, their filtering, one block of W and the filter's work, W1), 463-518 MB
in all depending on how the two workers' chunks overlap. Before 2026-11-28: 300 MB was ~175 MB away. The floor
before the clock went (at 07e3a6a), measured as resident-set steps with one worker (peak 439 MB): 149 MB of imports
(NumPy 27, scipy.linalg 28, scipy.interpolate 23 with optimize and spatial: the vehicle modules that pipeline.run
and report.build import at the top load it, Numba 53, dynid 16), then the plan +94 (pyarrow 30 on the first read,
the clock 29: 3.6 M stamps held whole by `sources.RobotTestPlan`, the file's own stamps when uniform, so not a
formula; the rest the plan pass's heap), the data-health check +82 (Numba's code generator 47 on the first compiled
call, the Parquet block cache 3 row groups of 65,536 rows x 15 columns = 24 MB, constant in the log's length), so
318 MB before the first chunk. The map then adds ~60 MB per worker (its chunk's samples read and filtered, one 8 MiB
block of W with its transient, the first decimation stage's output for the chunk, 16 MB: all set by SEGMENT_BYTES
and BLOCK_BYTES, not by the log's length; smaller chunks cost CPU: 32 MiB chunks -31 MB, +30 % CPU, the 5.5 k-sample
decimation transient read around each chunk) and the plots' rows (`run.PLOT_BYTES`, ~10 MB). cvxpy (17 MB, and the
scipy.stats it imports, 20) comes after the map (the physical check of the estimate, a function-level import in
`estimation.physical`): not in the peak. glibc's thresholds (MALLOC_MMAP_THRESHOLD_, MALLOC_TRIM_THRESHOLD_) take
45-70 MB off at 1.8 x the CPU. Per worker, traced (tracemalloc, one chunk of 55,700 samples): 65 MB at its peak: the
window's q and tau 7, the filtered q, qd, qdd 10.7, the first stage's output W1 15.7 (only 190 of its 7 x 43 columns
are not structurally zero: 5.8 MB of it zeros), one block of W 11.3 and the filter's work 13; the rest of the map's
~215 MB over the base is not traced: glibc's free blocks (the two threads' arenas: one arena took 22 MB off) and the
plots' rows. The levers left: scipy.interpolate out of a robot's imports (signals.resampling and the vehicle
package), W1 without its zero columns, streaming the second decimation stage (changes the bits at 1e-15: the
overlaps), Numba's code generator on a robot's path. """

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ARM = [f"panda_joint{i}" for i in range(1, 8)]
CONFIG = """
[model]
file = "arm.toml"

[[tests]]
name = "long"
files = {{ q = "{log}", tau = "{log}" }}

[channels]
q = {{ channels = {q}, unit = "rad" }}
tau = {{ channels = {tau}, unit = "N*m" }}

[conditioning]
cutoff = 20.0
decimate = [10, 10]
"""

WRITE = """
import sys
from pathlib import Path
import numpy as np
# test_urdf.robot_file: tests/model/ (by layer), or tests/ in an older tree
sys.path[:0] = [str(Path(sys.argv[4]) / "tests" / "model"), str(Path(sys.argv[4]) / "tests")]
from test_urdf import robot_file
from dynid import Model
from dynid.io import Channel, Recording, write_recording
from dynid.model import save_tree
from dynid.model.urdf import import_urdf

folder, seconds, rate = Path(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
arm = import_urdf(robot_file("panda"), joints=[f"panda_joint{i}" for i in range(1, 8)]).tree
save_tree(arm, folder / "arm.toml")
n = int(round(seconds * rate))
t = np.arange(n) / rate
rng = np.random.default_rng(2)
w = 2 * np.pi * 0.1 * np.arange(1, 6)
a, b = rng.normal(0, 0.6, (2, 7, 5)) / np.arange(1, 6)
q, tau = np.empty((n, 7)), np.empty((n, 7))
model = Model(arm)
for s in range(0, n, 200_000):  # a block at a time: the writer's memory is not measured, but kept sane
    tt = t[s:s + 200_000]
    sn, cs = np.sin(np.multiply.outer(tt, w)), np.cos(np.multiply.outer(tt, w))
    q[s:s + 200_000] = sn @ a.T + cs @ b.T
    qd = (cs * w) @ a.T - (sn * w) @ b.T
    qdd = -(sn * w**2) @ a.T - (cs * w**2) @ b.T
    tau[s:s + 200_000] = model.inverse_dynamics(q[s:s + 200_000], qd, qdd)[:, :7]
chans = [Channel(f"q{j + 1}", "rad", q[:, j], t) for j in range(7)]
chans += [Channel(f"tau{j + 1}", "N*m", tau[:, j], t) for j in range(7)]
write_recording(Recording.from_channels(chans), folder / "long.parquet")
"""

RUN = """
import json, resource, sys, time, warnings
from dynid.pipeline.config import load_config
from dynid.pipeline.run import identify
warnings.simplefilter("ignore")
after_imports = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
t0 = time.perf_counter()
run = identify(load_config(sys.argv[1]))
wall = time.perf_counter() - t0
try:  # the file-backed pages (shared libraries) of the resident set, Linux
    with open("/proc/self/status") as f:
        file_mb = next(int(x.split()[1]) / 1024 for x in f if x.startswith("RssFile:"))
except (OSError, StopIteration):
    file_mb = None
print(json.dumps({"peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, "file_mb": file_mb,
                  "imports_mb": after_imports, "wall_s": wall, "rows": run.result.residual.n_rows,
                  "parameters": len(run.result.estimated_names),
                  "direct_overall": run.errors["direct"]["overall"]}))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3600.0)
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--folder", type=Path, default=Path(tempfile.gettempdir()) / "dynid_bench_robot_memory")
    args = ap.parse_args()
    root = Path(__file__).resolve().parents[1]
    folder = args.folder / f"{args.seconds:g}s_{args.rate:g}Hz"
    folder.mkdir(parents=True, exist_ok=True)
    if not (folder / "long.parquet").exists():
        print(f"writing the log ({args.seconds:g} s at {args.rate:g} Hz, 7 joints) into {folder}", flush=True)
        subprocess.run([sys.executable, "-c", WRITE, str(folder), str(args.seconds), str(args.rate), str(root)],
                       check=True)
    q = json.dumps([f"q{j}" for j in range(1, 8)])
    tau = json.dumps([f"tau{j}" for j in range(1, 8)])
    (folder / "identify.toml").write_text(CONFIG.format(log="long.parquet", q=q, tau=tau))
    out = subprocess.run([sys.executable, "-c", RUN, str(folder / "identify.toml")], check=True,
                         capture_output=True, text=True).stdout
    r = json.loads(out.strip().splitlines()[-1])
    verdict = "met" if r["peak_mb"] < 300 else "MISSED"
    print(f"robot identification, {args.seconds:g} s at {args.rate:g} Hz, 7 joints: {r['rows']} rows, "
          f"{r['parameters']} parameters, {r['wall_s']:.1f} s")
    shared = "" if r["file_mb"] is None else f"; file-backed at the end {r['file_mb']:.0f} MB"
    print(f"  peak RSS {r['peak_mb']:.0f} MB (after the imports {r['imports_mb']:.0f} MB{shared}); target < 300 MB: "
          f"{verdict}")


if __name__ == "__main__":
    main()
