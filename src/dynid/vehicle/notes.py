"""What the car's run and report say in words: the chassis frame the parameters are given in, the sprung and the
total mass, the physical-consistency verdict, what the sensors not fitted change, the demo's test plan, what the
damper curves are and how the engineering figures were computed. Numbers the report rounds come in as its text (the
report's rounding is its own)."""

from __future__ import annotations

from collections.abc import Sequence

from ..dynamics import BaseParameters
from ..model import check_physical
from .engineering import damper_vertical
from .sensors import gnss_point
from .template import CHASSIS, WHEELS

# the report's words over the parameter tables: the chassis parameters are in the paper's axes, defined in them
FRAME6_TEXT = ("The chassis parameters are the paper's, about the origin of its chassis frame 6 (on the rear axle, "
               "midway between the rear wheel centres, at their height) in that frame's axes: x6 up, y6 right, z6 "
               "forward. So XX6 is the yaw inertia, YY6 the pitch and ZZ6 the roll one, about that point; MX6, MY6 "
               "and MZ6 are M6 times the centre of gravity's height above the wheel centres, its offset to the right "
               "and its distance ahead of the rear axle. \"The car in engineering terms\" gives them about the centre "
               "of gravity in ISO 8855 axes.")

TEST_PLAN = (
    "Test plan: identified on the sine, the spiral, the braking AND a double lane change, cross-validated on a "
    "step steer and a gentler braking. The paper identified on the sine and cross-validated on the braking, but "
    "a sine and a spiral move the front dampers 16 mm in roll and under 1 mm in heave: the spring stiffness ks "
    "and the anti-roll bar karf are then separated by less than a millimetre of signal, and YY6 by almost no "
    "pitch (noise-free files: ks36 +2.2 %, karf -1.6 %; with the sensor suite, five seeds: ks up to -14 %, karf "
    "up to +8 %). The braking's 20 mm of heave and its pitch separate them. The lane change adds a fourth set of "
    "zero offsets, drawn anew at each test's zeroing: the offsets, not the noise, dominate the chassis products "
    "of inertia (XY6 sigma total 1.7 % of the smallest principal moment on three tests, 1.3 % on four, "
    "ten seeds).\n")  # the demo's tests (pipeline.demo.TESTS): why the braking moved to the identification

# the report's words over the damper curves' tables (car_model.car_template(damper_knees=...))
DAMPER_CURVES_TEXT = ("Each damper's viscous force is a piecewise-linear curve of its clearance rate (bump, the wheel "
                      "moving towards the body, is positive): four slopes identified in place of h, below and above "
                      "the knees of the vehicle file's [dampers]. The dry friction fs is its own row of the suspension "
                      "table. The band is the estimate's 95 % interval at each rate (the slopes' covariance "
                      "included).")


def masses_note(result, tree) -> str:
    """What M6 is and how it makes the car's total mass (the demo prints a total beside a table that shows M6)."""
    if "M6" not in result.names:
        return ""
    wheels = [f"M{w}" for w in WHEELS]
    m_w = sum(result.value(n) if n in result.names else tree.values.get(n, 0.0) for n in wheels)
    known = all(n not in result.estimated_names for n in wheels)
    m6 = result.value("M6")
    return (f"M6 = {m6:.1f} kg is the sprung mass: the chassis body alone, what the chassis equations weigh above the "
            f"suspensions. The car's total mass adds the four wheels (unsprung, {m_w:.1f} kg, "
            f"{'known from the bench' if known else 'estimated'}): {m6 + m_w:.1f} kg.\n")


def consistency_text(result, base: BaseParameters, tree=None) -> str:
    """Whether the estimated chassis and wheels are physically realisable (only meaningful without regrouping);
    parameters fixed as known take the tree's values."""

    if base.regrouped:
        return ("Inertial parameters regroup in this base set (" + ", ".join(base.regrouped)
                + "): the physical-consistency check applies to standard parameters only.")
    values = {n: tree.values.get(n, 0.0) for n in (tree.known if tree is not None else ())}
    values.update(zip(result.names, (float(v) for v in result.values), strict=True))
    problems = check_physical(values, frames=[CHASSIS, *WHEELS])
    if not problems:
        return "The estimated chassis and wheels are physically realisable (mass > 0, inertia at the centre of " \
               "mass positive definite, triangle inequalities hold)."
    return "NOT physically realisable:\n" + "\n".join(f"  {p}" for p in problems)


def sensors_note(vehicle) -> str:
    """What the sensors not fitted change (empty for the paper's suite)."""
    out = ""
    if not vehicle.cameras:
        out += ("No cameras: the damper clearances come from potentiometers, the steering and camber joints from the "
                "kinematic tables at the measured clearance and steering-wheel angle.\n")
    if not vehicle.lasers:
        out += ("No height lasers: the chassis height and the tire deflections come from the wheel loads through the "
                "known tire stiffness (kt15, kt24, kt33, kt42 from the vehicle file's [known]); the tire equations "
                "are then identities and are left out, so the tire stiffness cannot be identified from these tests.\n")
    if not vehicle.correvit:
        out += ("No Correvit: the horizontal velocity over ground comes from the GNSS/INS at its antenna point "
                f"{list(gnss_point(vehicle.geometry))} m in frame 6.\n")
    used = [t for t in vehicle.defaulted_tables if t.endswith(".caster") or not vehicle.cameras]
    if used:
        which = "every caster table" if len(used) == 4 and all(t.endswith(".caster") for t in used) else \
            ", ".join(used)
        out += (f"Kinematic tables not in the vehicle file, dynid's defaults used ({which}): a 406-class saloon's, "
                "whose anti-dive caster (+1 deg/100 mm front) and wind-up (-0.5 deg/100 mm rear) turn the hubs, and "
                "the measured wheel wrenches with them, as the dampers move. If the car's differ, give them in "
                "[tables] (zeros where nothing moves): on the MuJoCo test car, which has none, they turned the "
                "wrenches by a quarter of a degree under braking and the pitch inertia by 4 %.\n")
    return out


def engineering_text(sprung: str, unsprung: str, total: str, estimated: Sequence[str], uncertainty: str,
                     geometry) -> str:
    """How "the car in engineering terms" was computed: the sprung, unsprung and total masses (the report's rounded
    numbers, kg), the uncertainty the figures carry ("total": with the sensor offsets) and each formula's
    assumptions, with the vehicle geometry's wheel radius and damper axes."""
    wheels_known = all(f"M{w}" not in estimated for w in WHEELS)
    return (
        f"M6 in the chassis table is the SPRUNG mass, {sprung} kg: the chassis body "
        "alone, what the chassis equations weigh above the suspensions. The car's total mass adds the four "
        f"wheels (the unsprung corners), {unsprung} kg "
        f"{'known from the bench (the vehicle file or config, not identified)' if wheels_known else 'estimated'}: "
        f"{total} kg in all.\n\n"
        "Each figure is computed from the estimated parameters and the vehicle geometry; σ is propagated to first "
        "order with the estimate's full covariance, "
        + ("statistical and the declared sensor offsets (σ total)" if uncertainty == "total"
           else "statistical only (no sensor offsets declared)")
        + "; bench-known parameters count as exact. Heights are above flat ground at design ride height (wheel "
        f"centres at the unloaded tire radius, {geometry.wheel_radius:g} m). Inertia is about the centre "
        "of gravity in ISO 8855 vehicle axes (x forward, y left, z up), products as the inertia matrix's entries "
        "(Ixz = −∫xz dm). The springs act along the damper axes (the template's slides): with c the vertical "
        "component of an axle's damper axis "
        f"(front {damper_vertical(geometry, True):.4f}, rear {damper_vertical(geometry, False):.4f}), "
        "a vertical wheel travel z moves the damper z/c, so the wheel rate is ks/c², the anti-roll bar's in roll "
        "2 k_ar/c² (one wheel alone: half) and the damping h/c². Ride frequency and damping ratio per axle: the "
        "wheel rates in series with the tires, on the axle's share of the sprung mass, one degree of freedom "
        "(unsprung masses and dry friction left out). Roll stiffness: springs and anti-roll bar at the wheels, "
        "K = (ks_l + ks_r + 4 k_ar) t²/c² (t the half track), tires not counted; the roll gradient counts them in "
        "series and turns about the slides' roll axis (roll centres t·tan(damper lateral tilt) below the ground); "
        "the pitch gradient turns about the ground (no anti-dive). Corner weights: on a level scale with no "
        "diagonal preload. Each formula and its assumptions: docs/engineering.md.")
