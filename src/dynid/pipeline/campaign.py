"""A campaign: several identifications at once (one car per config, or one load state per config).

On a Dask cluster the configs run side by side: each one's segments go to the cluster as soon as
its files are planned, so the workers see every config's tasks at once and none waits for another
to finish. On this machine's threads they run one after the other (the cores are already busy with
each one's segments). Each config keeps its own result; `summary` puts the figures an engineer
compares across them in one table (a car: total mass and centre of gravity with σ; every kind:
the estimated parameters and the overall direct and cross-validation errors).
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from ..progress import Count
from ..report.build import car_engineering
from ..vehicle.engineering import QUANTITIES
from .config import IdentifyConfig
from .run import IdentificationRun, identify
from .schedulers import LocalScheduler, Scheduler

Progress = Callable[[str], None]
CAR_FIGURES = ("mass_total", "cg_ahead_rear", "cg_height", "cg_lateral")


SUMMARY_FILE = "campaign.csv"  # the campaign's table, beside the configs' folders in the output folder


def campaign_names(paths: Sequence[Path]) -> list[str]:
    """One output folder name per config: its file's stem, with its folder's name where two stems agree; a stem that
    is the campaign table's name (campaign.csv.toml) gets "-config", so that neither replaces the other."""
    stems = [p.stem + "-config" if p.stem.casefold() == SUMMARY_FILE.casefold() else p.stem for p in paths]
    names = [f"{p.parent.name}-{stem}" if stems.count(stem) > 1 else stem for p, stem in zip(paths, stems, strict=True)]
    if len({n.casefold() for n in names}) < len(names):
        names = [f"{i + 1}-{n}" for i, n in enumerate(names)]
    return names


def identify_campaign(cfgs: Sequence[IdentifyConfig], scheduler: Scheduler | None = None,
                      progress: Progress | None = None, errors: tuple[type[Exception], ...] = ()
                      ) -> list[IdentificationRun | Exception]:
    """Every config's identification on one scheduler (module doc), in the configs' order. A config that fails with
    one of `errors` (bad input: a file, a channel, a config) gives its exception in its place, and the others run
    on: a campaign is not lost to one broken file."""
    say = progress or (lambda _m: None)
    scheduler = scheduler or LocalScheduler()
    names = campaign_names([c.path for c in cfgs])

    def one(k: int) -> IdentificationRun | Exception:
        try:
            tag = f"[{names[k]}] "  # a count keeps its numbers (a bar per config), prefixed as every message
            return identify(cfgs[k], progress=lambda m: say(m.prefixed(tag) if isinstance(m, Count) else tag + m),
                            scheduler=scheduler)
        except errors as exc:
            say(f"[{names[k]}] failed: {exc}")
            return exc

    if isinstance(scheduler, LocalScheduler) or len(cfgs) == 1:
        return [one(k) for k in range(len(cfgs))]
    with ThreadPoolExecutor(len(cfgs)) as pool:  # the client only plans and folds: the cluster does the work
        return list(pool.map(one, range(len(cfgs))))


def summary(names: Sequence[str], runs: Sequence[IdentificationRun | Exception]) -> tuple[list[str], list[list[str]]]:
    """The campaign's table: a header and a row of text cells per config (a failed one: its error, last column)."""
    done = [r for r in runs if not isinstance(r, Exception)]
    cars = [r for r in done if r.vehicle is not None]
    head = ["config", "model", "parameters", "direct error %", "cross error %"]
    figures: dict[str, tuple[str, str]] = {}
    if cars:
        figures = {k: (QUANTITIES[k][1], QUANTITIES[k][2]) for k in CAR_FIGURES}
        head += [f"{label} [{unit}]" for label, unit in figures.values()]
    failed = len(done) < len(runs)
    if failed:
        head.append("error")
    rows = []
    for name, run in zip(names, runs, strict=True):
        if isinstance(run, Exception):
            rows.append([name] + ["-"] * (len(head) - 2) + [str(run).splitlines()[0]])
            continue
        r = run.result
        errs = [run.errors.get(k, {}).get("overall") for k in ("direct", "cross")]
        row = [name, run.model.name, str(len(r.estimated_names))]
        row += ["-" if e is None else f"{100 * e:.3g}" for e in errs]
        if figures:
            q = {x.key: x for x in _car_figures(run)} if run.vehicle is not None else {}
            row += [f"{q[k].value:.6g} ± {q[k].std:.2g}" if k in q else "-" for k in figures]
        rows.append(row + ([""] if failed else []))
    return head, rows


def _car_figures(run: IdentificationRun) -> list:
    return car_engineering(run)[0]  # σ total where the offsets were declared, as in the report


def summary_text(head: list[str], rows: list[list[str]]) -> str:
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(head, widths, strict=True))]
    lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    return "\n".join(lines)


def summary_csv(head: list[str], rows: list[list[str]]) -> str:
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(head)
    w.writerows(rows)
    return out.getvalue()


__all__ = ["campaign_names", "identify_campaign", "summary", "summary_csv", "summary_text"]
