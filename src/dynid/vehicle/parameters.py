"""Parameter sets of the car template (SI units, chassis values in frame 6 about O6), each value with its source.

- `a_priori()`, `truth(geometry, tables)`: the demo vehicle's (the shipped file `dynid.shipped.DEMO_VEHICLE` names):
  its [a_priori] set, and its [truth] set with the damper offsets it leaves out solved (the static preloads that
  put every damper at its design position, q = 0, at rest on flat ground: `Vehicle.truth`). The file is the one
  place their numbers live.
- `paper_estimates()`: the paper's weighted least-squares estimates (Tables 2, 3, 5), with `PAPER_RELATIVE_STD`
  their %σ: a publication's figures, which no vehicle file holds. The chassis set is NOT physically realisable:
  moved to the centre of mass, YY6 (pitch, about the lateral axis y6) is about 12980 kg·m², more than
  XX + ZZ ≈ 3870 there.

Not in the paper's text, chosen for its estimates and marked as such:
- XY6, YZ6: the values of a chassis symmetric about a vertical plane through its centre
  of mass containing z6, i.e. XY_G = YZ_G = 0: XY6 = -MX6 MY6 / M6, YZ6 = -MY6 MZ6 / M6.
- wheels (the paper's Table 4 is missing): the wheel link stands for the corner's
  unsprung mass (links 9-13 are massless): 35 kg (195/65 R15 tire on a steel rim about
  18 kg, dynamometric wheel about 7 kg, hub, brake and the share of the links about
  10 kg); about the wheel centre, ZZ = 1.05 kg·m² about the axle (a 12 kg tread ring at
  0.28 m plus rim, disc and hub) and XX = YY = 0.65 kg·m² about diameters.
"""

from __future__ import annotations

from dataclasses import replace

from .description import demo_vehicle
from .parameter_set import ParameterSet
from .template import TIRES, WHEELS, paper_parameter_names

PAPER = "paper"
CHOSEN = "chosen (not in the paper)"
NOT_GIVEN = "not given by the paper (0)"

WHEEL = {"XX": 0.65, "YY": 0.65, "ZZ": 1.05, "M": 35.0}


def _chassis(values: dict[str, float], sources: dict[str, str]) -> None:
    v = values
    v["XY6"] = -v["MX6"] * v["MY6"] / v["M6"]
    v["YZ6"] = -v["MY6"] * v["MZ6"] / v["M6"]
    sources["XY6"] = sources["YZ6"] = CHOSEN + ": symmetric chassis, XY_G = YZ_G = 0"


def _wheels(values: dict[str, float], sources: dict[str, str]) -> None:
    for w in WHEELS:
        for p, x in WHEEL.items():
            values[f"{p}{w}"] = x
            sources[f"{p}{w}"] = CHOSEN + ": plausible unsprung corner of the paper's car"


def _set(name: str, chassis: dict[str, float], susp: dict[int, tuple], kar: tuple[float, float],
         kt: tuple[float, ...], tag: str) -> ParameterSet:
    values = dict(chassis)
    sources = {k: f"{PAPER}, {tag}, Table 2" for k in chassis}
    for d, (ks, h, fs, off) in susp.items():
        for p, x in (("K", ks), ("FV", h), ("FS", fs), ("OFF", off)):
            values[f"{p}{d}"] = 0.0 if x is None else x
            sources[f"{p}{d}"] = NOT_GIVEN if x is None else f"{PAPER}, {tag}, Table 3"
    values["karf"], values["karr"] = kar
    sources["karf"] = sources["karr"] = f"{PAPER}, {tag}, Table 3"
    for t, x in zip(TIRES, kt, strict=True):
        values[f"K{t}"] = x
        sources[f"K{t}"] = f"{PAPER}, {tag}, Table 5"
    _chassis(values, sources)
    _wheels(values, sources)
    assert set(values) == set(paper_parameter_names())
    return ParameterSet(name, values, sources)


def a_priori() -> ParameterSet:
    """The demo vehicle's a priori set (its file's [a_priori]; a copy)."""
    v = demo_vehicle().a_priori
    return ParameterSet(v.name, dict(v.values), dict(v.sources))


def paper_estimates() -> ParameterSet:
    chassis = {"XX6": 6877.46, "XZ6": -590.92, "YY6": 16697.76, "ZZ6": 714.26, "MX6": 357.43, "MY6": -2.06,
               "MZ6": 2446.61, "M6": 1644.11}
    susp = {9: (24425.0, 4131.7, 12.60, 589.08), 18: (20798.0, 4445.2, 30.41, -14.58),
            27: (27478.0, 3143.2, 28.56, 420.94), 36: (26073.0, 3869.1, 35.87, 1018.87)}
    return _set("paper estimates", chassis, susp, (18342.0, 21662.0),
                (216502.50, 217816.21, 232581.41, 230549.08), "estimated")


# %σ of the estimates (the paper's Tables 2, 3, 5), by dynid name
PAPER_RELATIVE_STD = {
    "XX6": 0.30, "XZ6": 0.56, "YY6": 1.72, "ZZ6": 1.01, "MX6": 0.29, "MY6": 3.26, "MZ6": 0.07, "M6": 0.10,
    "FS9": 7.95, "OFF9": 0.38, "K9": 1.42, "FV9": 1.17, "FS18": 3.31, "OFF18": 13.38, "K18": 1.73, "FV18": 1.13,
    "karr": 0.82, "FS27": 4.49, "OFF27": 1.67, "K27": 1.32, "FV27": 1.54, "FS36": 3.34, "OFF36": 0.80,
    "K36": 1.53, "FV36": 1.36, "karf": 1.05, "K15": 0.32, "K24": 0.31, "K33": 0.37, "K42": 0.37,
}


def truth(geometry=None, tables=None) -> ParameterSet:
    """The demo vehicle's truth set (its file's [truth], the damper offsets it leaves out the static preloads;
    a copy), for the simulator and the tests.

    geometry, tables: those of the simulated car (defaults: the demo vehicle's); the offsets depend on them
    through the rest attitude.
    """
    v = demo_vehicle()
    if geometry is not None or tables is not None:
        v = replace(v, geometry=v.geometry if geometry is None else geometry, tables=v.tables if tables is None
                    else tables)
    t = v.truth
    if t is None:
        raise ValueError(f"{v.source}: the demo vehicle has no [truth] set")
    return ParameterSet(t.name, dict(t.values), dict(t.sources))
