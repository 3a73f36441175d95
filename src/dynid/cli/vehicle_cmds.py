"""Text of `dynid model show --template NAME` for the shipped car template."""

from __future__ import annotations

import numpy as np

from ..model import ModelError
from ..model.consistency import check_physical
from .main import format_table

TEMPLATES = ("peugeot406",)


def show_template(name: str) -> str:
    """The full text for a template: MDH table, the three parameter sets, consistency, base parameters."""
    if name not in TEMPLATES:
        raise ModelError(f"no car template {name!r}; templates: {', '.join(TEMPLATES)}")
    from ..vehicle import parameters as params
    from ..vehicle.equations import car_base_parameters
    from ..vehicle.geometry import CarGeometry
    from ..vehicle.statics import rest_state
    from ..vehicle.template import CORNERS, WHEELS, car_template, paper_parameter_names, role

    geometry = CarGeometry()
    sets = [params.a_priori(), params.paper_estimates(), params.truth(geometry)]
    tree = car_template(geometry, sets[0].values)
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
        where = "" if fr.j <= 6 else f", {CORNERS[(fr.j - 7) // 9]}"
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
            src = s.sources.get(n, "")
            v = s.values[n]
            mark = "*" if src.startswith("chosen") else ""
            cells.append("-" if src.startswith("not given") else f"{v:.6g}{mark}")
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
    rs = rest_state(car_template(geometry, sets[2].values))
    add("Truth set at rest on flat ground: vertical loads (N) " + ", ".join(
        f"{CORNERS[i]} {rs.loads[i]:.1f}" for i in range(4)) + f"; total {rs.loads.sum():.1f} N")
    return "\n".join(out)
