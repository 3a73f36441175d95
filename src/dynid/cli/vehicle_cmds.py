"""`dynid vehicle list|new|show` (vehicle files) and the text of `dynid model show --template NAME`."""

from __future__ import annotations

import argparse
import json
import tomllib
from importlib.util import find_spec
from pathlib import Path

from ..atomic import add_force, refuse_overwrite, write_atomic
from ..shipped import CAR_TEMPLATE, DEMO_VEHICLE
from .model_table import format_table
from .usage import command

TEMPLATES = (CAR_TEMPLATE,)


def show_template(name: str) -> str:
    """The full text for a template: MDH table, the three parameter sets, consistency, base parameters."""
    import numpy as np  # start-up: numpy (--help 0.1 s)

    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..model import ModelError
    from ..model.consistency import check_physical

    if name not in TEMPLATES:
        raise ModelError(f"no car template {name!r}; templates: {', '.join(TEMPLATES)}")
    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..vehicle import parameters as params
    from ..vehicle.car_model import car_template
    from ..vehicle.description import demo_vehicle
    from ..vehicle.equations import car_base_parameters
    from ..vehicle.statics import rest_state

    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..vehicle.template import CHASSIS, CORNERS, WHEELS, corner_of, paper_parameter_names, role

    demo = demo_vehicle()  # the template's values: the demo vehicle's a priori and truth sets, the paper's estimates
    geometry = demo.geometry
    sets = [params.a_priori(), params.paper_estimates(), params.truth()]
    tree = car_template(geometry, sets[0].values, name=demo.name)
    chosen = {n for n, src in sets[1].sources.items() if src.startswith(params.CHOSEN)}  # in every set alike
    out: list[str] = []
    add = out.append
    add(f"{tree.name}: {tree.n} frames, {tree.p} parameters ({len(paper_parameter_names())} identified), "
        f"gravity {list(tree.gravity)} m/s²")
    add("Ground: x0 right, y0 forward (at zero yaw), z0 up. Chassis frame 6: x6 up, y6 right, z6 forward "
        "(the roll axis); origin on the rear axle, midway between the rear wheel centres, at their height.")
    f, r = geometry.front, geometry.rear
    add(f"Geometry: half tracks {f.half_track} m front / {r.half_track} m rear, axles at z6 = {f.position} m and "
        f"{r.position} m (wheelbase {geometry.wheelbase:.3g} m), wheel radius {geometry.wheel_radius} m,")
    add(f"  dampers tilted {np.degrees(f.damper_lateral_tilt):.3g}°/{np.degrees(r.damper_lateral_tilt):.3g}° "
        f"inboard (front/rear), kingpin {np.degrees(f.kingpin_inclination):.3g}° inclination, "
        f"{np.degrees(f.caster):.3g}° caster, {f.kingpin_offset} m offset (front)")
    add("")
    lines = format_table(tree).splitlines()
    add(f"{lines[0]}  role")
    for fr, line in zip(tree.frames, lines[1:], strict=True):
        where = "" if fr.j <= CHASSIS else f", {CORNERS[corner_of(fr.j)]}"
        add(f"{line}  {role(fr.j)}{where}{' (chassis)' if fr.j == 6 else ''}")
    add("Constant joints (half track, half wheelbase) keep their value in r; their q is 0.")
    add("")
    add("Centre of mass of the chassis in frame 6, m (MX6, MY6, MZ6 / M6):")
    for s in sets:
        c = s.centre_of_mass(6)
        add(f"  {s.name:<16} ({c[0]:.3f}, {c[1]:.3f}, {c[2]:.3f})   M6 = {s['M6']:.6g} kg")
    add("")
    add("Parameters (the paper's order and labels; * = chosen, not in the paper; - = not given):")
    add(f"  {'label':>7} {'a priori':>12} {'estimated':>12} {'%σ':>6} {'truth':>12}")
    for n in paper_parameter_names():
        cells = []
        for s in sets:
            v = s.values[n]
            mark = "*" if n in chosen else ""
            # the paper gives no a priori fs and off: the a priori set's zeros there are "not given"
            not_given = (s is sets[0] and n.startswith(("FS", "OFF"))) or s.sources.get(n, "").startswith("not given")
            cells.append("-" if not_given else f"{v:.6g}{mark}")
        sd = params.PAPER_RELATIVE_STD.get(n)
        add(f"  {tree.label(n):>7} {cells[0]:>12} {cells[1]:>12} {'' if sd is None else f'{sd:.2f}':>6} {cells[2]:>12}")
    add("  truth: estimates, except YY6 (a priori pitch inertia at the centre of mass) and off (static preloads "
        "at the design position)")
    add("")
    add("Physical consistency (chassis and wheels):")
    for s in sets:
        bad = check_physical(s.values)
        add(f"  {s.name}: {'realisable' if not bad else 'NOT realisable'}")
        for v in bad:
            add(f"    {v.message}")
    add("")
    gen = car_base_parameters(tree, "generic")
    car = car_base_parameters(tree, "car")
    add("Base parameters of the 14 equations (x y z yaw pitch roll, dampers 9 18 27 36, tires 15 24 33 42):")
    add(f"  every joint moving (numeric method on random states): {gen.rank} of 48 - "
        + ("the paper's X is a base set, nothing regroups" if not gen.regrouped and not gen.eliminated
           else f"regrouped {' '.join(gen.regrouped)}; eliminated {' '.join(gen.eliminated)}"))
    add(f"  the car's motion (half track, wheelbase, steering, camber, caster, kingpin still): {car.rank} of 48;")
    add(f"  regrouped: {' '.join(tree.label(n) for n in car.regrouped) or 'none'}; "
        f"eliminated: {' '.join(car.eliminated) or 'none'}")
    for n, e in zip(car.names, car.expressions, strict=True):
        if e != n:
            add(f"    {tree.label(n):>6} = {e}")
    add("  The wheel masses do not regroup into M6: the wheel centres move along the dampers, so M6 is the chassis")
    add(f"  alone and the car's mass is M6 + {' + '.join(f'M{w}' for w in WHEELS)}. The tabulated joints' small motion")
    add("  separates YY of the wheels only weakly: identify with the car's base set or give the wheel inertias")
    add("  as known.")
    add("")
    rs = rest_state(car_template(geometry, sets[2].values), demo.tables)
    add("Truth set at rest on flat ground: vertical loads (N) " + ", ".join(
        f"{CORNERS[i]} {rs.loads[i]:.1f}" for i in range(4)) + f"; total {rs.loads.sum():.1f} N")
    return "\n".join(out)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add `vehicle` to the top-level `dynid` sub-commands."""

    p = command(subparsers, "vehicle", help="vehicle files: the shipped ones, a starting file, what a file describes",
                description="A car is a vehicle file (TOML: geometry, sensors, tables, a priori and known values; "
                            "docs/vehicle.md). These commands list the shipped ones, write a file to start from, "
                            "and show what a file describes.",
                examples=[f"dynid vehicle show {DEMO_VEHICLE}", "dynid vehicle list",
                          'dynid vehicle new "My car" --out mycar.toml'])
    sub = p.add_subparsers(dest="vehicle_command", required=True, metavar="SUBCOMMAND")
    lst = command(sub, "list", help="the shipped vehicles",
                  description="List the vehicles shipped with dynid, with their descriptions: their names can be "
                              "given wherever a vehicle is asked for (demo --vehicle, a config's [model] vehicle).",
                  examples="dynid vehicle list")
    lst.set_defaults(func=cmd_list)
    new = command(sub, "new",
                  help=f"write a commented starting vehicle file (the shipped {DEMO_VEHICLE}'s values, to edit)",
                  description=f"Write a commented vehicle file to start from: the shipped {DEMO_VEHICLE}'s geometry, "
                              "sensors, tables and values, under your car's name, each to replace with your "
                              "car's. An existing file is not replaced.",
                  examples='dynid vehicle new "My car" --out mycar.toml')
    new.add_argument("name", help="the car's name, as the reports will show it")
    new.add_argument("--out", required=True, help="the file to write (.toml); an existing file is not replaced")
    add_force(new)
    new.set_defaults(func=cmd_new)
    show = command(sub, "show", help="frames, parameters, base parameters and the a priori set's consistency",
                   description="Show what a vehicle file describes: its frames, its parameters (a priori, known "
                               "and truth values), its base parameters, and whether its a priori set is physically "
                               "consistent.",
                   examples=[f"dynid vehicle show {DEMO_VEHICLE}", "dynid vehicle show mycar.toml"])
    show.add_argument("vehicle", help="a shipped vehicle's name or a vehicle file")
    show.set_defaults(func=cmd_show)


def cmd_list(args: argparse.Namespace) -> int:
    # the shipped files are read as TOML, not loaded as vehicles: loading one builds its tables and template
    # (NumPy, SciPy: two seconds) for three numbers; tests/vehicle/test_vehicle_file.py loads every shipped vehicle.
    # find_spec locates dynid.vehicle without running its __init__ (which imports all of it).
    spec = find_spec("dynid.vehicle")
    folder = Path(next(iter(spec.submodule_search_locations))) / "vehicles"  # type: ignore[union-attr]
    for path in sorted(folder.glob("*.toml")):
        v = tomllib.loads(path.read_text(encoding="utf-8"))
        axles = v["axles"]
        print(f"{path.stem:<14} {v['name']}: wheelbase {axles['wheelbase_m']:.3g} m, tracks "
              f"{2 * axles['front']['half_track_m']:.3g} / {2 * axles['rear']['half_track_m']:.3g} m, "
              f"{'with' if 'truth' in v else 'no'} simulation truth")
    return 0


def cmd_new(args: argparse.Namespace) -> int:
    from ..vehicle.description import VehicleError, vehicle_path  # start-up: the library, 1-5 s (--help 0.1 s)

    out = Path(args.out)
    if not args.name.strip():
        raise VehicleError(f"name {args.name!r}: give the car's name (text), as the reports will show it, e.g. "
                           "dynid vehicle new \"My car\" --out mycar.toml")
    if out.suffix != ".toml":
        raise VehicleError(f"{out}: a vehicle file ends in .toml")
    refuse_overwrite([out], args.force)
    source = vehicle_path(DEMO_VEHICLE)
    text = source.read_text(encoding="utf-8")
    demo = tomllib.loads(text)["name"]  # the shipped car it starts from, by the name its file gives
    head = [f"# A vehicle file for dynid, started from the shipped {demo}: replace every value with your car's",
            "# (data sheets, the K&C bench, the wheels weighed on a bench). docs/vehicle.md documents each key."]
    lines = [line for line in text.splitlines() if not line.startswith("# ")]
    for i, line in enumerate(lines):  # JSON's string escapes are TOML's
        if line.startswith("name = "):
            lines[i] = f"name = {json.dumps(args.name)}"
        elif line.startswith("description = "):
            said = f"Started from the {demo} shipped with dynid: every value is that car's"
            lines[i] = f"description = {json.dumps(said)}"
        elif line.startswith("unloaded_radius_known = "):  # the demo car is simulated; a real tire's radius is not
            lines[i] = "unloaded_radius_known = false  # true only if radius_m is the unloaded radius to 0.1 mm"
    write_atomic(out, "\n".join(head + lines).rstrip() + "\n" + _sheet_hint(source))
    print(f"wrote {out}: edit it, then `dynid vehicle show {out}`")
    return 0


def _sheet_hint(source: Path) -> str:
    """A commented [a_priori.chassis]: the a priori chassis of the file a new one starts from, as a data sheet
    gives it."""
    from ..vehicle.description import chassis_sheet_keys, load_vehicle  # start-up: the library, 1-5 s (--help 0.1 s)

    v = load_vehicle(source)
    keys = chassis_sheet_keys(v.a_priori.values, v.geometry)
    keys.pop("cog_above_wheel_centres_m")
    return ("\n# The chassis can be given as a data sheet gives it, instead of XX6 ... M6 (remove those):"
            "\n# CoG and inertia at the CoG in ISO 8855 axes (x forward, y left, z up; docs/engineering.md)\n"
            "# [a_priori.chassis]\n" + "".join(f"# {k} = {x:.4g}\n" for k, x in keys.items()))


def cmd_show(args: argparse.Namespace) -> int:
    from ..vehicle.description import load_vehicle  # start-up: the library, 1-5 s (--help 0.1 s)

    print(show_vehicle(load_vehicle(args.vehicle)))
    return 0


def chassis_sheet_text(v) -> list[str]:
    """The chassis of each parameter set as a data sheet gives it, under the keys of [a_priori.chassis] (13
    significant digits: they read back to XX6..M6 to 1e-12)."""
    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..vehicle.description import CHASSIS_PARAMETERS, chassis_sheet_keys

    sets = [("a priori", v.a_priori.values)]
    sets += [("truth", v.truth.values)] if v.truth is not None else []
    sets += [("known", v.known)] if all(n in v.known for n in CHASSIS_PARAMETERS) else []
    sheets = [(name, chassis_sheet_keys(values, v.geometry)) for name, values in sets]
    out = ["The chassis (sprung mass) as a data sheet gives it: CoG ahead of the rear axle, above the ground at design "
           "ride height (or the wheel centres), to the left; inertia at the CoG in ISO 8855 axes (x forward, y left, "
           "z up), products as the matrix's entries (-∫xz dm). [a_priori.chassis] (and [truth.chassis], "
           "[known.chassis]) take these keys in place of XX6..M6:",
           f"  {'key':<26}" + "".join(f" {name:>20}" for name, _ in sheets)]
    for key in sheets[0][1]:
        out.append(f"  {key:<26}" + "".join(f" {d[key]:>20.13g}" for _, d in sheets))
    return out


def show_vehicle(v) -> str:
    """Frames, parameter sets, known values, base parameters and the a priori set's physical consistency."""
    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..model.consistency import check_physical
    from ..model.tree import CURVE_TERMS
    from ..vehicle.equations import car_base_parameters, identified

    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..vehicle.template import CHASSIS, CORNERS, WHEELS, corner_of, meaning, paper_parameter_names, role

    tree = v.template()
    g = v.geometry
    out = [f"{v.name} ({v.source}): {tree.n} frames, {len(paper_parameter_names())} parameters of the paper",
           "Frame 6 (chassis): x6 up, y6 right, z6 forward; origin on the rear axle, midway between the rear wheel "
           "centres, at their height.",
           f"Wheelbase {g.wheelbase:.4g} m; half tracks {g.front.half_track:.4g} m front, {g.rear.half_track:.4g} m "
           f"rear; wheel radius {g.wheel_radius:.4g} m; inertial unit at {list(g.imu_position)} m in frame 6.",
           "Sensors: inertial unit, dynamometric wheels, steering-wheel angle, "
           + ("Correvit" if v.correvit else "GNSS/INS velocity (no Correvit)") + ", "
           + ("height lasers" if v.lasers else "no height lasers (heights from the wheel loads through the known kt)")
           + ", " + ("cameras" if v.cameras else "damper potentiometers (no cameras: steering and camber from the "
                     "tables)") + "."]
    out += [*v.logger.summary(v.suite.rate), ""]
    lines = format_table(tree).splitlines()
    out.append(f"{lines[0]}  role")
    for fr, line in zip(tree.frames, lines[1:], strict=True):
        where = "" if fr.j <= CHASSIS else f", {CORNERS[corner_of(fr.j)]}"
        out.append(f"{line}  {role(fr.j)}{where}")
    out += ["", f"  {'parameter':>9} {'a priori':>12} {'truth':>12} {'known':>10}  {'unit':<6}  corner, quantity"]
    # a damper's h, or its curve's slopes (a priori with [dampers] law = "curve", truth with a curve in [truth])
    names = [m for n in paper_parameter_names()
             for m in ((n,) if not n.startswith("FV") else (n, *(f"{t}{n[2:]}" for t in CURVE_TERMS)))]
    sets = [v.a_priori.values, {} if v.truth is None else v.truth.values, v.known]
    for n in (n for n in names if any(n in s for s in sets)):
        a, t, k = (f"{s[n]:.6g}" if n in s else "" for s in sets)
        m = meaning(n)
        what = f"  {m.unit:<6}  {m.text()}" if m is not None else ""
        out.append(f"  {tree.label(n):>9} {a:>12} {t:>12} {k:>10}{what}")
    known = tree.with_values(v.known).with_known(set(v.known)) if v.known else tree
    base = car_base_parameters(known, "car")
    out += ["", f"Base parameters with the car's own motion (constant and tabulated joints still): {base.rank} "
            f"identified of {len(identified(known))} not known; regrouped: "
            f"{' '.join(tree.label(n) for n in base.regrouped) or 'none'}"]
    for n, e in zip(base.names, base.expressions, strict=True):
        if e != n:
            out.append(f"    {tree.label(n):>6} = {e}")
    out += ["", *chassis_sheet_text(v)]
    bad = check_physical(v.a_priori.values, frames=[6, *WHEELS])
    out += ["", "A priori chassis and wheels: " + ("physically realisable" if not bad else "NOT realisable:")]
    out += [f"  {b.message}" for b in bad]
    return "\n".join(out)
