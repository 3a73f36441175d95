"""How the car's results are judged and laid out: each parameter's engineering scale (the uncertainty flag's
yardstick) and the legend's words for it, the paper's tables of parameters, and the split of the equation groups
into the validation figures (chassis, suspensions, tires). The pipeline and the report read them from here."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .template import CHASSIS, CHASSIS_GROUPS, DAMPERS, TIRES, WHEELS

COM_SCALE = 0.2  # m: a first moment's scale is M6 x 0.2 m, so that 5 % of it is 1 cm of centre-of-mass shift
# how the car's scales were chosen, for the flag's legend (after "its value")
SCALE_RULE = f"; the smallest principal moment for a product of inertia, M6 × {COM_SCALE:g} m for a first moment"


def car_scales(values: Mapping[str, float]) -> dict[str, float]:
    """The engineering scale of the parameters whose value may be near zero: products of inertia against the
    smallest principal moment of the chassis inertia about O6, first moments against a centre-of-mass shift
    (M6 x COM_SCALE), a tire's lateral-force term ktfy against kt / (M6 g / 4)². The others are judged against
    their own value (the default)."""
    v = {n: float(values.get(n, 0.0)) for n in ("XX6", "XY6", "XZ6", "YY6", "YZ6", "ZZ6", "M6")}
    inertia = np.array([[v["XX6"], v["XY6"], v["XZ6"]], [v["XY6"], v["YY6"], v["YZ6"]],
                        [v["XZ6"], v["YZ6"], v["ZZ6"]]])
    out = dict.fromkeys(("XY6", "XZ6", "YZ6"), abs(float(np.linalg.eigvalsh(inertia).min())))
    out.update(dict.fromkeys(("MX6", "MY6", "MZ6"), COM_SCALE * abs(v["M6"])))
    # a tire's lateral-force term (-ktfy Fy² q), near 0 on a tire that keeps its stiffness: against the ktfy that
    # takes its whole kt away at a lateral force of a quarter of the sprung weight (the Magic Formula's qFcy = 1)
    load = abs(v["M6"]) * 9.81 / 4
    for n in values:
        if n.startswith("KFY") and load > 0:
            out[n] = abs(float(values.get(f"K{n[3:]}", 0.0))) / load**2
    return {n: s for n, s in out.items() if n in values}


def car_sections(names: list[str]) -> list[tuple[str, list[str]]]:
    """The paper's tables: chassis (Table 2), suspensions and anti-roll bars (Table 3), wheels, tires (Table 5)."""

    def joint(n: str) -> int | None:
        digits = n[len(n.rstrip("0123456789")):]
        return int(digits) if digits else None

    chassis = [n for n in names if joint(n) == CHASSIS]
    susp = [n for n in names if joint(n) in DAMPERS] + [n for n in names if joint(n) is None]
    wheels = [n for n in names if joint(n) in WHEELS]
    tires = [n for n in names if joint(n) in TIRES]
    sections = [("Chassis (paper Table 2)", chassis), ("Suspensions and anti-roll bars (paper Table 3)", susp),
                ("Wheels", wheels), ("Tire vertical stiffness (paper Table 5)", tires)]
    return [(title, group) for title, group in sections if group]


PAPER_FIGURES = {"chassis": "4 and 7", "suspensions": "5 and 8", "tires": "6"}  # the paper's validation figures


def equation_sections(groups: list[str]) -> list[tuple[str, list[str], str]]:
    """The paper's figure split of the car's equation groups: chassis, suspensions, tires (and any other), each
    with the paper's figures that show it ("" for none)."""
    out = [("chassis", [g for g in CHASSIS_GROUPS if g in groups]),
           ("suspensions", [g for g in groups if g.startswith("susp")]),
           ("tires", [g for g in groups if g.startswith("tire")])]
    rest = [g for g in groups if not any(g in s for _, s in out)]
    return [(t, s, PAPER_FIGURES.get(t, "")) for t, s in [*out, ("other", rest)] if s]
