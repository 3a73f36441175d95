"""The car's tree as dynid uses it: the template's 42 frames (`template.car_tree`) with a parameter set, the demo
vehicle's a priori values by default (`parameters.a_priori`). Describing the car solves nothing: its rest on flat
ground is solved where it is needed (`statics.rest_state`: the simulator, a vehicle's truth offsets), and raises
there when a wheel would float.

Above the template and the parameter sets, so that neither needs the other to describe the car.
"""

from __future__ import annotations

from collections.abc import Mapping

from ..model.tree import Tree
from .geometry import CarGeometry, demo_geometry
from .parameters import a_priori
from .template import car_tree


def car_template(
    geometry: CarGeometry | None = None,
    values: dict[str, float] | None = None,
    name: str = "car",
    known: set[str] | frozenset[str] = frozenset(),
    tire_offsets: bool = False,
    tire_law: str = "paper",
    damper_knees: Mapping[int, tuple[float, float]] | None = None,
    damper_friction: dict[int, tuple[str, float]] | None = None,
    tire_lateral_force: bool = False,
) -> Tree:
    """The 42-frame tree of the car, with a parameter set (default: the demo vehicle's a priori values) and a
    geometry (default: the demo vehicle's); name: the tree's (a vehicle's template has the vehicle's).

    values: parameter name or label -> value (e.g. `parameters.truth().values`); known:
    parameters taken as known rather than identified (moved to Y by `car_identification`).
    tire_offsets: each tire equation gets a constant, off15 ... off42: kt * q + off = Fz. A real tire's
    unloaded radius is not known to the 0.1 mm that kt * q needs (0.1 mm is 20 N), so off = kt * (R0 - R)
    is identified with kt (R0 the unloaded radius, R the vehicle file's radius); False is the paper's
    equation (R is the unloaded radius).
    tire_law: "paper" (kt q = the load along the wheel's vertical) or "progressive" (kt q + ktq q² (+ off), ktq15
    ... ktq42: the Magic Formula's vertical law Fz = (qFz1 rho / R0 + qFz2 (rho / R0)^2) Fz0 of the deflection rho
    from the unloaded radius, written about dynid's q = rho + R0 - R: a tire stiffens as its contact patch grows).
    damper_knees: damper frame -> (v-, v+) (m/s of the clearance, v- < 0 < v+; bump is q' > 0): those dampers'
    viscous term h q' becomes a piecewise-linear curve of four slopes, hbl hbh (bump, below and above v+) and hrl
    hrh (rebound, above and below v-), each its own parameter (model.tree's FVPL FVPH FVNL FVNH); an infinite knee
    drops that side's high-speed slope (one slope per direction); the other dampers keep h. A curved damper's h in
    `values` is the value of each of its slopes that `values` does not give.
    damper_friction: damper frame -> (shape, vs) of its dry friction's law (`Tree.friction_law`); default sign(qd).
    tire_lateral_force: with the progressive law, each tire's equation gets - ktfy Fy² q (ktfy15 ... ktfy42, 1/(N·m)),
    Fy the measured lateral force of the wheel's transducer: the form of the Magic Formula's vertical stiffness
    falling with the lateral force, (1 - (qFcy Fy / Fz0)²) in MF 6.1/6.2, i.e. ktfy = kt qFcy² / Fz0², its sign left
    free (docs/vehicle.md, 'The tire equation'). A load term of the tree (model.tree), whose column
    `car_identification` builds from the measured wrench.
    """
    geometry = demo_geometry() if geometry is None else geometry
    tree = car_tree(geometry, a_priori().values if values is None else values, name, tire_offsets, tire_law,
                    damper_knees, damper_friction, tire_lateral_force)
    return tree.with_known(set(known)) if known else tree
