"""`dynid plan`'s optimised input (issue 29 item 3): a steering-and-pedal run designed for the plan's binding target.

When the standard tests cannot meet a target in the track time allowed, the plan asks for one run more designed for
it, as `dynid excite` does for arms. The input is a table the steering and pedal robots play back every `STEP` s (the
design grid): the steering-wheel angle and the longitudinal acceleration demand (the pedal: negative brakes), each a
multisine of random phases and amplitudes (steering up to 2 Hz, pedal up to 0.5 Hz, both faded in and out over a
second, the pedal of zero mean so the speed comes back). Each draw is fitted to the driver's and track's limits on
the simulated car (`fit_to_limits`: its steering and pedal scaled until the design grid's peaks of lateral and
longitudinal acceleration reach `MARGIN` of their limits, its speed and run length checked), reduced once like a
candidate (noise-free with the offsets, and the noisy draws), and scored by the binding target's predicted σ total
with the plan's other tests; the best of `designs` draws is kept (a random search: each score is a simulation and a
reduction, too dear for a gradient). The driver gets it as a steering-robot file (time, steering-wheel angle,
pedal) and a plot (`write_robot_file`, `plot_input`).
"""

from __future__ import annotations

import io
import math
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..atomic import write_atomic
from ..vehicle.sim.manoeuvres import Manoeuvre, table_manoeuvre
from .demo import simulated_car
from .plan import (
    Candidate,
    Envelope,
    Limits,
    Piece,
    Progress,
    TestPlan,
    envelope,
    predict_all,
    reduce_candidates,
    road_signals,
    typical,
)

STEP = 0.1  # s: the design grid, where the limits are held (the robots interpolate linearly between its samples)
MARGIN = 0.9  # of each acceleration limit the design's peaks reach on the design grid (the rest: what lies between)
STEER_MAX, PEDAL_MAX = 2.0, 0.5  # Hz: the highest lines of the steering and of the pedal


@dataclass
class InputDesign:
    """A designed run: its table (`manoeuvre.table`), the peaks it reached on the simulated car, and its score."""

    manoeuvre: Manoeuvre
    envelope: Envelope
    seed: int
    sigma: float = math.nan  # the binding target's predicted σ total with the plan's other tests
    piece: Piece | None = None
    result: object = None  # the noise-free SimulationResult

    @property
    def time(self) -> np.ndarray:
        return np.arange(self.manoeuvre.table.shape[1]) * self.manoeuvre.params["step"]


def input_shape(rng: np.random.Generator, duration: float, step: float = STEP) -> tuple[np.ndarray, np.ndarray]:
    """(steering, pedal) on the design grid, each of unit peak: multisines at k / duration Hz of random phases and
    amplitudes (module doc), faded in and out over a second (a quintic: no step in the robots' acceleration)."""
    t = np.arange(round(duration / step) + 1) * step
    fade = np.minimum(_smoothstep(t - 1.0), _smoothstep(duration - 1.0 - t))  # straight first and last second

    def multisine(f_max: float) -> np.ndarray:
        k = np.arange(1, max(1, int(f_max * duration)) + 1)
        amp = rng.uniform(0.2, 1.0, k.size)
        x = np.sum(amp[:, None] * np.sin(2 * np.pi * k[:, None] * t[None] / duration + rng.uniform(0, 2 * np.pi,
                                                                                                   k.size)[:, None]),
                   axis=0) * fade
        return x / np.max(np.abs(x))

    steering, pedal = multisine(STEER_MAX), multisine(PEDAL_MAX)
    pedal -= fade * np.sum(pedal) / np.sum(fade)  # zero mean: the speed comes back
    return steering, pedal / np.max(np.abs(pedal))


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10.0 + x * (-15.0 + 6.0 * x))


def fit_to_limits(sim, steering: np.ndarray, pedal: np.ndarray, limits: Limits, speed: float, step: float = STEP,
                  iterations: int = 4) -> tuple[Manoeuvre, object, Envelope]:
    """The table of these shapes scaled to the limits on the simulated car: from the linear bicycle model's steady
    gain, steering and pedal rescaled by MARGIN x limit / the design grid's peak (the car is nearly linear there)
    until both peaks lie within 2 % below their targets; refused (ValueError) if the speed or length breaks a
    limit. Returns the manoeuvre, its noise-free run and its peaks."""
    c = sim.car_constants()
    v = speed / 3.6
    h_scale = MARGIN * limits.lateral_acceleration * c["ratio"] * (c["wheelbase"] / v**2 + c["understeer"])
    a_scale = MARGIN * limits.longitudinal_acceleration
    every = max(1, round(step / sim.settings.dt))
    for _ in range(iterations):
        m = table_manoeuvre(step, h_scale * steering, a_scale * pedal, speed)
        r = sim.run(m)
        a_side, a_head, _, _ = road_signals(r)
        lat, lon = (float(np.max(np.abs(x[::every]))) for x in (a_side, a_head))
        goal_lat, goal_lon = MARGIN * limits.lateral_acceleration, MARGIN * limits.longitudinal_acceleration
        if 0.98 * goal_lat <= lat <= goal_lat and 0.98 * goal_lon <= lon <= goal_lon:
            break
        h_scale *= 0.99 * goal_lat / lat
        a_scale *= 0.99 * goal_lon / lon
    else:
        raise ValueError(f"the input's peaks ({lat:.2f}, {lon:.2f} m/s²) did not settle within 2 % of {MARGIN} x "
                         "the limits")
    env = envelope(r)
    bad = env.violations(limits)
    if bad:
        raise ValueError(f"the designed input breaks the limits ({'; '.join(bad)}): shorten it or lower its speed")
    return m, r, env


def optimise_input(plan: TestPlan, duration: float = 20.0, speed: float = 80.0, designs: int = 6, seed: int = 2929,
                   progress: Progress | None = None, work: Path | None = None) -> InputDesign:
    """The best of `designs` random inputs (module doc) of `duration` s at `speed` km/h for `plan`'s binding
    target: the one whose predicted σ total, with the plan's tests that fit beside it in the track time allowed
    (`fitting`), is the smallest."""

    say = progress or (lambda _m: None)
    sim = simulated_car(plan.vehicle)
    k = binding_target(plan)
    rng = np.random.default_rng(seed)
    best: InputDesign | None = None
    for d in range(designs):
        say(f"input design {d + 1}/{designs}: fitting it to the limits on the simulated car")
        steering, pedal = input_shape(rng, duration)
        try:
            m, r, env = fit_to_limits(sim, steering, pedal, plan.spec.limits, speed)
        except ValueError as exc:
            say(f"input design {d + 1}: dropped ({exc})")
            continue
        with tempfile.TemporaryDirectory(prefix="dynid-input-") as tmp:
            pieces, _ = reduce_candidates({"input": r}, plan.vehicle, Path(work or tmp) / f"design{d}",
                                          seed + 7 * d, say)
        design = InputDesign(m, env, seed, piece=pieces["input"], result=r)
        design.sigma = sigma_with(plan, [design.piece], k, duration)
        say(f"input design {d + 1}: {plan.score.targets[k].key} σ total {design.sigma:.4g}")
        if best is None or design.sigma < best.sigma:
            best = design
    if best is None:
        raise ValueError(f"none of {designs} input designs stayed within the limits ({plan.spec.limits.text()})")
    return best


def binding_target(plan: TestPlan) -> int:
    """The index of the target the plan meets with the least margin (its 9-in-10 σ over its bound the largest)."""
    return int(np.argmax(plan.reported / np.array([t.limit for t in plan.score.targets])))


def sigma_with(plan: TestPlan, extra: Sequence[Piece], k: int, duration: float = 0.0) -> float:
    """Target k's predicted σ total (the draws' RMS, `plan.typical`) of `extra` (runs of `duration` s of driving
    in all) with the plan's tests that fit beside them in the track time allowed (`fitting`)."""

    draws = predict_all([*[plan.pieces[t] for t in fitting(plan, duration)], *extra], plan.estimate)
    return float(plan.score.sigmas(typical(draws))[k])


def fitting(plan: TestPlan, duration: float) -> list[str]:
    """The plan's tests that fit beside a run of `duration` s in the track time allowed ([limits] time; all without
    a limit), taken in the plan's order (the search's: the most useful first) while they fit: an input that only
    helps with tests the track time leaves no room for is scored without them."""
    if plan.spec.limits.time is None:
        return list(plan.plan)
    left, out = plan.spec.limits.time - duration, []
    for key in plan.plan:
        if plan.candidates[key].duration <= left:
            out.append(key)
            left -= plan.candidates[key].duration
    return out


def write_robot_file(design: InputDesign, path: str | Path) -> Path:
    """The steering-robot file: time (s), steering-wheel angle (deg), pedal (the longitudinal acceleration demand,
    m/s², negative: braking) on the design grid; the run starts straight at the speed its header gives."""

    h, a, _ = design.manoeuvre.table
    lines = [f"# dynid plan: optimised input, start straight at {design.manoeuvre.params['speed']:g} km/h; the "
             "robots interpolate linearly between samples; pedal = longitudinal acceleration demand (negative: brake)",
             "time_s,steering_wheel_deg,pedal_mps2"]
    lines += [f"{t:.3f},{math.degrees(x):.4f},{y:.4f}" for t, x, y in zip(design.time, h, a, strict=True)]
    return write_atomic(Path(path), "\n".join(lines) + "\n")


def plot_input(design: InputDesign, limits: Limits, path: str | Path) -> Path:
    """The input (steering-wheel angle, pedal) and what it drove on the simulated car (lateral and longitudinal
    acceleration, speed) against the limits, as a PNG."""
    # start-up: matplotlib 0.3 s (pyplot 1 s), only when the plot is drawn
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # start-up: as above


    h, a, _ = design.manoeuvre.table
    a_side, a_head, v, _ = road_signals(design.result)
    t_sim = design.result.time
    fig, ax = plt.subplots(4, 1, figsize=(8, 8), sharex=True)
    ax[0].plot(design.time, np.degrees(h))
    ax[0].set_ylabel("steering wheel (deg)")
    ax[1].plot(design.time, a, label="pedal demand")
    ax[1].set_ylabel("pedal (m/s²)")
    for i, (x, lim, what) in enumerate(((a_side, limits.lateral_acceleration, "lateral (m/s²)"),
                                        (a_head, limits.longitudinal_acceleration, "longitudinal (m/s²)"))):
        ax[2].plot(t_sim, x, label=what, color=f"C{i}")
        ax[2].axhline(lim, color=f"C{i}", ls="--", lw=0.8)
        ax[2].axhline(-lim, color=f"C{i}", ls="--", lw=0.8)
    ax[2].legend(loc="upper right", fontsize=8)
    ax[2].set_ylabel("acceleration")
    ax[3].plot(t_sim, 3.6 * v)
    ax[3].axhline(limits.speed, color="C3", ls="--", lw=0.8)
    ax[3].set_ylabel("speed (km/h)")
    ax[3].set_xlabel("time (s)")
    fig.tight_layout()

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    return write_atomic(Path(path), buf.getvalue())


def optimised_plan(plan: TestPlan, duration: float = 20.0, speed: float = 80.0, designs: int = 6,
                   progress: Progress | None = None) -> tuple[TestPlan, InputDesign]:
    """The plan searched again with an optimised input for its binding target among the candidates (the standard
    ones could not meet every target, or not in the time allowed), and the input."""

    design = optimise_input(plan, duration, speed, designs, progress=progress)
    key = plan.score.targets[binding_target(plan)].key
    name = f"optimised steering and pedal input, {speed:g} km/h (for {plan.labels.get(key, key)})"
    cand = Candidate("optimised", name, "dynid plan (issue 29 item 3)", "table", {}, duration)
    return plan.with_candidate(cand, design.piece, design.result, design.envelope), design
