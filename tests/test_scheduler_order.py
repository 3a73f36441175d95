"""LocalScheduler starts the costliest jobs first and still folds in the jobs' order. Oracle: `tree_fold` of the
results in the jobs' order, with a combine that is not commutative (string concatenation shows any reordering)."""

from __future__ import annotations

from dataclasses import dataclass

from dynid.pipeline.schedulers import LocalScheduler, tree_fold


@dataclass(frozen=True)
class _Job:
    name: str
    cost: int = 1


def test_costliest_first_folded_in_order():
    jobs = [_Job(c, cost) for c, cost in zip("abcdefghij", (1, 1, 1, 1, 1, 1, 1, 1, 1, 5), strict=True)]
    jobs.append(_Job("k", 3))
    started: list[str] = []

    def fn(job: _Job) -> str:
        started.append(job.name)
        return job.name

    out = LocalScheduler(1).map_reduce(fn, jobs, lambda j: "all", lambda a, b: a + b)
    # one worker runs them as submitted: the costliest first, the rest in their order
    assert started == ["j", "k", *"abcdefghi"]
    assert out == {"all": tree_fold([j.name for j in jobs], lambda a, b: a + b)} == {"all": "abcdefghijk"}
    # two workers: whatever finishes first, the same fold
    assert LocalScheduler(2).map_reduce(fn, jobs, lambda j: j.cost > 1, lambda a, b: a + b) == {
        False: "abcdefghi", True: "jk"}
