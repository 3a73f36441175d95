"""Parameter sets of the Peugeot 406 (SI units, chassis values in frame 6 about O6).

Three sets over the paper's 48 parameters, each value with its source:

- `a_priori()`: the paper's a priori values (Tables 2, 3, 5). The paper gives no a priori
  fs and off (0 here).
- `paper_estimates()`: the paper's weighted least-squares estimates (Tables 2, 3, 5).
  The chassis set is NOT physically realisable: moved to the centre of mass, YY6 (pitch,
  about the lateral axis y6) is about 12980 kg·m², more than XX + ZZ ≈ 3870 there.
- `truth(geometry, tables)`: a realisable set close to the estimates, for the simulator
  and the tests: the estimates everywhere except YY6 (the a priori pitch inertia at the
  centre of mass, moved to O6 with the estimated first moments) and the damper offsets
  (the static preloads that put every damper at its design position, q = 0, at rest on
  flat ground; the paper's offsets refer to its own, unknown, zero of the clearances).

Not in the paper's text, chosen and marked as such:
- XY6, YZ6: the values of a chassis symmetric about a vertical plane through its centre
  of mass containing z6, i.e. XY_G = YZ_G = 0: XY6 = -MX6 MY6 / M6, YZ6 = -MY6 MZ6 / M6.
- wheels (the paper's Table 4 is missing): the wheel link stands for the corner's
  unsprung mass (links 9-13 are massless): 35 kg (195/65 R15 tire on a steel rim about
  18 kg, dynamometric wheel about 7 kg, hub, brake and the share of the links about
  10 kg); about the wheel centre, ZZ = 1.05 kg·m² about the axle (a 12 kg tread ring at
  0.28 m plus rim, disc and hub) and XX = YY = 0.65 kg·m² about diameters.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .geometry import CarGeometry
from .statics import design_preloads
from .template import DAMPERS, TIRES, WHEELS, car_tree, paper_parameter_names

PAPER = "paper"
CHOSEN = "chosen (not in the paper)"
NOT_GIVEN = "not given by the paper (0)"

WHEEL = {"XX": 0.65, "YY": 0.65, "ZZ": 1.05, "M": 35.0}


@dataclass(frozen=True)
class ParameterSet:
    """Named values (dynid names, e.g. K9) with the source of each value."""

    name: str
    values: dict[str, float]
    sources: dict[str, str] = field(default_factory=dict)

    def __getitem__(self, key: str) -> float:
        return self.values[key]

    def centre_of_mass(self, body: int = 6) -> tuple[float, float, float]:
        """(MX, MY, MZ) / M of a body, m, in its frame."""
        v = self.values
        M = v[f"M{body}"]
        return (v[f"MX{body}"] / M, v[f"MY{body}"] / M, v[f"MZ{body}"] / M)


def _chassis(values: dict[str, float], sources: dict[str, str]) -> None:
    v = values
    v["XY6"] = -v["MX6"] * v["MY6"] / v["M6"]
    v["YZ6"] = -v["MY6"] * v["MZ6"] / v["M6"]
    sources["XY6"] = sources["YZ6"] = CHOSEN + ": symmetric chassis, XY_G = YZ_G = 0"


def _wheels(values: dict[str, float], sources: dict[str, str]) -> None:
    for w in WHEELS:
        for p, x in WHEEL.items():
            values[f"{p}{w}"] = x
            sources[f"{p}{w}"] = CHOSEN + ": plausible unsprung corner of a 406"


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
    chassis = {"XX6": 6810.44, "XZ6": -445.9, "YY6": 6567.0, "ZZ6": 668.56, "MX6": 537.24, "MY6": 5.81,
               "MZ6": 2368.21, "M6": 1685.0}
    susp = {9: (22000.0, 4200.0, None, None), 18: (22000.0, 4200.0, None, None),
            27: (20000.0, 3200.0, None, None), 36: (20000.0, 3200.0, None, None)}
    return _set("a priori", chassis, susp, (19780.0, 19185.0), (200000.0,) * 4, "a priori")


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
    """The realisable set for simulation (see the module doc); offsets from the static preloads.

    geometry, tables: those of the simulated car (defaults: the 406's); the offsets depend
    on them through the rest attitude.
    """

    est = paper_estimates()
    apr = a_priori()
    values, sources = dict(est.values), dict(est.sources)
    yy_g = apr["YY6"] - (apr["MX6"] ** 2 + apr["MZ6"] ** 2) / apr["M6"]
    values["YY6"] = yy_g + (values["MX6"] ** 2 + values["MZ6"] ** 2) / values["M6"]
    sources["YY6"] = (f"a priori YY at the centre of mass ({yy_g:.1f}) moved to O6 with the estimated first "
                      "moments (the estimated YY6 is not realisable)")
    _chassis(values, sources)
    tree = car_tree(CarGeometry() if geometry is None else geometry, {**values, **{f"OFF{d}": 0.0 for d in DAMPERS}})
    preloads = design_preloads(tree, tables)
    for d, f in zip(DAMPERS, preloads, strict=True):
        values[f"OFF{d}"] = float(f)
        sources[f"OFF{d}"] = "static preload: damper at its design position (q = 0) at rest on flat ground"
    return ParameterSet("truth", values, sources)
