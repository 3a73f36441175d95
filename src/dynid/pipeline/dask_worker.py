"""What a Dask worker process needs before its first segment (imported only with dask.distributed):
glibc's adaptive heap thresholds, which the nanny's MALLOC_TRIM_THRESHOLD_ turns off (`heap`)."""

from __future__ import annotations

from distributed.diagnostics.plugin import WorkerPlugin

from .heap import tune_malloc


class MallocTuning(WorkerPlugin):
    """`heap.tune_malloc` in each worker process, those restarted after a loss included."""

    name = "dynid-malloc-tuning"

    def setup(self, worker) -> None:
        tune_malloc()
