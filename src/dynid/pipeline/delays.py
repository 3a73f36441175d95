"""The channel groups' delays relative to the wheel force transducers, as the equations' residual says, against
the declared ones (`vehicle.dynamics`).

On a few segments of each identification test every group of `CarSetup.delay_groups` is taken one sample
later than declared and the rows are built again (`reduce.reduce_car_segment`); `estimation.shifts` then finds
the extra delay of each group that minimises the weighted residual of the chassis and suspension equations
jointly with the parameters (a Gauss-Newton step from the estimate), with its σ from the curvature of the
residual sum of squares. Where a group is more than a sample off, the step is repeated about the delays found
(the residual is not linear in a delay of tens of milliseconds), at most `MAX_STEPS` times. The estimated delay
of a group is the declared one plus that extra delay.

A group whose estimate differs from the declared delay by more than a sample (and by more than 3 σ) is a
mismatch: the logger's dynamics are not the declared ones, and every estimate is biased by the channels'
misalignment. The run then says so (group, both figures, the fix) and adds the shift of the estimates that the
estimated delays imply (the joint fit's parameters minus the estimate) to their σ total as one more systematic
source, "delay mismatch": the estimates it moves beyond their uncertainty are flagged "uncertain", and the
engineering figures' σ carries it. It does not correct the delays itself: the residual of a model that misfits
can look like a delay, and the declared dynamics are the engineer's statement to fix (`[sensors.dynamics]` in
the vehicle file).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..estimation.shifts import ShiftEstimate
from ..estimation.systematic import SystematicUncertainty
from ..vehicle.dynamics import GROUPS, REFERENCE, LoggerDynamics, group_channels

DELAY_SEGMENTS = 2  # segments per identification test on which the delays are evaluated (spread over it)
MISMATCH_SIGMAS = 3.0  # and a mismatch is more than a sample and more than this many σ
MAX_STEPS = 4  # Gauss-Newton steps at most; a step below a tenth of a sample ends them
DELAY_SOURCE = "delay mismatch"  # the systematic source's name: "delay mismatch: imu, clearances"


@dataclass(frozen=True)
class GroupDelay:
    """One channel group: declared and estimated delay relative to the reference (s), σ of the estimate, whether
    the equations determine it (to a sample: a σ above is reported as not determined, its estimate as None)."""

    group: str
    label: str
    channels: tuple[str, ...]
    declared: float
    estimated: float
    std: float
    determined: bool

    @property
    def residual(self) -> float:
        return self.estimated - self.declared

    def mismatch(self, sample: float) -> bool:
        return bool(self.determined and abs(self.residual) > sample
                    and abs(self.residual) > MISMATCH_SIGMAS * self.std)


@dataclass(frozen=True)
class DelayCheck:
    """The groups' delays, the sample period (s), whether the declared delays were compensated, the segments and
    Gauss-Newton steps the estimate took, and the estimates' shift at the estimated delays (over `names`)."""

    groups: tuple[GroupDelay, ...]
    sample: float
    compensated: bool
    segments: int
    steps: int
    names: tuple[str, ...]
    shift: np.ndarray
    reference: float = 0.0  # the reference group's declared (compensated) delay, s

    @property
    def mismatched(self) -> list[GroupDelay]:
        return [g for g in self.groups if g.mismatch(self.sample)]

    def warnings(self) -> list[str]:
        """One sentence per mismatched group: the group, both figures and the fix."""
        what = "declared" if self.compensated else "compensated (compensate_delays = false: none)"
        return [f"the {g.label} ({_prefixes(g.group)}) lag the wheel force transducers by "
                f"{_ms(g.estimated)} ± {_ms(g.std, sign=False)} ms in these files, {_ms(g.residual)} ms from the "
                f"{_ms(g.declared)} ms {what}: the logger's dynamics are not the declared ones, and the estimates "
                "the misalignment moves carry it in their σ total (flagged where it exceeds the flag threshold). "
                "Fix: declare the logger's dynamics in the vehicle file's [sensors.dynamics] (docs/vehicle.md), "
                f"e.g. {self._suggestion(g)}" for g in self.mismatched]

    def _suggestion(self, g: GroupDelay) -> str:
        """A declaration the data agree with: "none" for a group aligned with the transducers (themselves
        "none"), else its delay as the data say it (the transducers' own added)."""
        absolute = g.estimated + self.reference
        if abs(g.estimated) <= self.sample and abs(self.reference) <= self.sample:
            return f'{g.group} = "none" (or default = "none": every channel aligned by the logger)'
        if absolute < 0:
            return (f"the transducers' own delay (wft = {{ delay_ms = {-1e3 * absolute:.3g} }}: the {g.label} lead "
                    "them)")
        return f"{g.group} = {{ delay_ms = {1e3 * absolute:.3g} }}"

    def text(self) -> str:
        """The terminal's table and the warnings."""
        head = (f"Channel delays relative to the wheel force transducers (ms; one sample = {1e3 * self.sample:.2f} "
                f"ms; estimated from the chassis and suspension equations' residual on {self.segments} segment(s), "
                f"{self.steps} step(s)):")
        lines = [head, f"  {'group':<9} {'declared':>9} {'estimated':>10} {'σ':>6} {'difference':>11}  verdict"]
        for g in self.groups:
            if g.determined:
                verdict = "MISMATCH" if g.mismatch(self.sample) else "ok"
                lines.append(f"  {g.group:<9} {_ms(g.declared):>9} {_ms(g.estimated):>10} {_ms(g.std, False):>6} "
                             f"{_ms(g.residual):>11}  {verdict}")
            else:
                lines.append(f"  {g.group:<9} {_ms(g.declared):>9} {'-':>10} {'-':>6} {'-':>11}  not determined "
                             "by these equations")
        lines += [f"WARNING: {w}" for w in self.warnings()]
        return "\n".join(lines)

    def to_dict(self) -> dict:
        return {
            "reference": f"{REFERENCE[1][0]} ({_prefixes(REFERENCE[0])})",
            "sample_ms": 1e3 * self.sample,
            "compensated": self.compensated,
            "segments": self.segments,
            "steps": self.steps,
            "groups": [{"group": g.group, "label": g.label, "channels": list(g.channels),
                        "declared_ms": 1e3 * g.declared,
                        "estimated_ms": 1e3 * g.estimated if g.determined else None,
                        "std_ms": 1e3 * g.std if g.determined else None,
                        "difference_ms": 1e3 * g.residual if g.determined else None,
                        "determined": g.determined, "mismatch": g.mismatch(self.sample)} for g in self.groups],
            "warnings": self.warnings(),
        }

    def systematic(self, names: tuple[str, ...], current: SystematicUncertainty | None) -> SystematicUncertainty:
        """`current` (the offsets', or None) with the estimates' shift at the estimated delays added as a source,
        "delay mismatch: imu, clearances" (the mismatched groups)."""
        shifts = dict(current.shifts) if current is not None else {}
        cov = np.array(current.covariance, dtype=float) if current is not None else np.zeros((len(names),) * 2)
        d = self.shift[[self.names.index(n) for n in names]]
        shifts[f"{DELAY_SOURCE}: " + ", ".join(g.group for g in self.mismatched)] = d
        return SystematicUncertainty(tuple(names), cov + np.outer(d, d), shifts)


def delay_check(estimate: ShiftEstimate, lags: dict[str, float], logger: LoggerDynamics, compensated: bool,
                fs: float, segments: int, steps: int, shift: np.ndarray) -> DelayCheck:
    """The groups' delays from the last step's `estimate` about `lags` (group -> s later than compensated, where
    the step was taken) and the declared dynamics on a logger at fs; shift: the estimates' change at the
    estimated delays. A group's declared delay is its channels' median (the inertial unit's rates and
    accelerations, not its two inclinometers, whose band is narrower but which only steer the attitude below
    0.2 Hz), relative to the reference's."""
    channels = list(logger.channels)
    lag = logger.lags(fs)
    ref = float(np.median([lag[n] for n in group_channels(REFERENCE[0], channels)])) if compensated else 0.0
    out = []
    for k, g in enumerate(estimate.sources):
        members = tuple(group_channels(g, channels))
        declared = float(np.median([lag[n] for n in members])) - ref if compensated else 0.0
        det = bool(estimate.determined[k]) and float(estimate.std[k]) <= 1.0 / fs
        extra = lags.get(g, 0.0) + (float(estimate.values[k]) if det else 0.0)
        out.append(GroupDelay(g, GROUPS[g][0], members, declared, declared + extra,
                              float(estimate.std[k]) if det else float("nan"), det))
    return DelayCheck(tuple(out), 1.0 / fs, compensated, segments, steps, estimate.names, shift, ref)


def _prefixes(group: str) -> str:
    return ", ".join(p + "*" for p in GROUPS[group][1])


def _ms(x: float, sign: bool = True) -> str:
    return f"{1e3 * x:+.2f}" if sign else f"{1e3 * x:.2f}"


__all__ = ["DELAY_SEGMENTS", "DELAY_SOURCE", "DelayCheck", "GroupDelay", "delay_check"]
