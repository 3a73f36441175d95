"""The report an engineer shares (issue 17): HTML tables with units, values rounded to their uncertainty, the
car's engineering figures against hand computations on the simulator's truth, results as data (JSON, CSV).

Oracles: hand-worked rounding cases; the compact SUV's documented figures (docs/vehicle.md: 1850 kg, centre of
mass 0.68 m above the ground and 1.59 m ahead of the rear axle, yaw 3300, pitch 3150, roll 760 kg·m², yaw-roll
product -150 kg·m² about it) recomputed from its [truth] set; the static axle loads from the rest-state solver;
the propagated σ against a Monte-Carlo of the covariance. One quick demo (module fixture) and one small robot
run give real reports, parsed with the standard library's HTML parser.
"""

import csv
import io
import json
import math
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from dynid.report.build import split_notes
from dynid.report.format import decimals, parameter_unit, round_to_uncertainty
from dynid.vehicle.description import load_vehicle
from dynid.vehicle.engineering import car_quantities, damper_vertical, engineering_figures

# ------------------------------------------------------------------ rounding


@pytest.mark.parametrize("value, sigma, expected", [
    (1645.19, 1.3, ("1645.2", "1.3")),            # σ in units: one decimal
    (24533.0, 255.0, ("24530", "260")),           # σ in hundreds: the value to tens
    (216502.5, 3790.0, ("216500", "3800")),       # thousands
    (0.012345, 0.00067, ("0.01235", "0.00067")),  # small
    (-0.5287, 4.6, ("-0.5", "4.6")),              # negative, |value| < σ
    (-590.92, 2.5, ("-590.9", "2.5")),            # negative
    (0.0, 0.0123, ("0.000", "0.012")),            # zero value
    (-0.00004, 0.012, ("0.000", "0.012")),        # rounds to zero: no "-0.000"
    (0.3456, 0.0996, ("0.35", "0.10")),           # σ rounds up into the next decade: still two digits
    (9.96, 0.996, ("10.0", "1.0")),
    (12.34, 0.0, ("12.34", "0")),                 # σ = 0: the value as it is
    (12.34, float("nan"), ("12.34", "")),         # no σ (a known parameter)
    (float("nan"), 1.0, ("", "1.0")),             # no value
])
def test_values_are_rounded_to_two_digits_of_their_uncertainty(value, sigma, expected):
    assert round_to_uncertainty(value, sigma) == expected


def test_decimals_is_none_without_a_usable_sigma():
    assert decimals(0.0) is None and decimals(float("nan")) is None and decimals(-1.0) is None
    assert decimals(float("inf")) is None
    assert decimals(255.0) == -1 and decimals(1.3) == 1


def test_units_follow_the_parameter_kind_and_the_joint_type():
    import dynid
    from dynid.vehicle import car_template

    car = car_template()
    assert [parameter_unit(n, car) for n in ("XX6", "MZ6", "M6", "K9", "FV9", "FS9", "OFF9", "K15", "karf")] == [
        "kg·m²", "kg·m", "kg", "N/m", "N·s/m", "N", "N", "N/m", "N/m"]
    tx40 = dynid.load_model("tx40").tree
    assert [parameter_unit(n, tx40) for n in ("ZZ1", "FV1", "FS1", "OFF1", "IA3", "Iam6", "fvm6")] == [
        "kg·m²", "N·m·s/rad", "N·m", "N·m", "kg·m²", "kg·m²", "N·m·s/rad"]


# ------------------------------------------------------------------ the car in engineering terms


def test_the_compact_suv_truth_gives_back_its_documented_figures():
    v = load_vehicle("compact_suv")
    q = car_quantities({**v.truth.values, **v.known}, v.geometry)
    assert q["mass_total"] == pytest.approx(1850.0) and q["mass_sprung"] == pytest.approx(1670.0)
    assert q["cgs_height"] == pytest.approx(0.68, abs=0.005)       # 0.32 above the wheel centres + 0.358
    assert q["cgs_ahead_rear"] == pytest.approx(1.59, abs=1e-9)
    assert q["cgs_behind_front"] == pytest.approx(2.79 - 1.59, abs=1e-9)
    assert q["cgs_lateral"] == pytest.approx(-3.34 / 1670)          # MY6 > 0 is to the right: ISO y < 0
    assert (q["Izz"], q["Iyy"], q["Ixx"], q["Ixz"]) == pytest.approx((3300.0, 3150.0, 760.0, -150.0), abs=1e-6)
    assert q["front_share_sprung"] == pytest.approx(57.0, abs=0.05)  # "57 % on the front axle" (sprung)
    # whole car: the wheels on the axles, by hand
    assert q["cg_ahead_rear"] == pytest.approx((1670 * 1.59 + 90 * 2.79) / 1850)
    assert q["front_share"] == pytest.approx(100 * (1670 * 1.59 + 90 * 2.79) / 1850 / 2.79)
    # roll stiffness by hand: front dampers tilted 10° and 2°, rear vertical; half tracks 0.79 m; N·m/deg
    c2 = 1 / (1 + math.tan(math.radians(10)) ** 2 + math.tan(math.radians(2)) ** 2)
    front = (30400 + 30900 + 4 * 25300) * 0.79**2 / c2 * math.pi / 180
    rear = (28100 + 27600 + 4 * 15200) * 0.79**2 * math.pi / 180
    assert q["roll_front"] == pytest.approx(front) and q["roll_rear"] == pytest.approx(rear)
    assert q["roll_front_share"] == pytest.approx(100 * front / (front + rear))
    assert damper_vertical(v.geometry, False) == 1.0


def test_the_406_a_priori_centre_of_mass_is_the_design_notes():
    """DESIGN §5: the a priori first moments put the centre of mass at (0.319, 0.003, 1.405) m in frame 6."""
    v = load_vehicle("peugeot406")
    q = car_quantities({**v.a_priori.values, **v.known}, v.geometry)
    assert q["cgs_ahead_rear"] == pytest.approx(1.405, abs=5e-4)
    assert q["cgs_height"] == pytest.approx(0.319 + v.geometry.wheel_radius, abs=5e-4)
    assert q["cgs_lateral"] == pytest.approx(-0.003, abs=5e-4)


def test_static_axle_loads_agree_with_the_rest_state():
    from dynid.vehicle import car_template, rest_state

    v = load_vehicle("compact_suv")
    values = {**v.truth.values, **v.known}
    rest = rest_state(car_template(v.geometry, values, name=v.name), v.tables)
    q = car_quantities(values, v.geometry)
    front = rest.loads[2:].sum()
    assert front / rest.loads.sum() == pytest.approx(q["front_share"] / 100, abs=0.005)  # pitch moves it a little
    assert rest.loads.sum() == pytest.approx(q["front_load"] + q["rear_load"], rel=1e-3)


def test_propagated_sigma_matches_a_monte_carlo_of_the_covariance():
    v = load_vehicle("compact_suv")
    values = {**v.truth.values, **v.known}
    names = ["XX6", "XZ6", "YY6", "ZZ6", "MX6", "MY6", "MZ6", "M6", "K27", "K36", "karf", "K9", "K18", "karr"]
    x = np.array([values[n] for n in names])
    rng = np.random.default_rng(17)
    A = rng.normal(size=(len(names), len(names)))
    corr = np.corrcoef(A @ A.T + len(names) * np.eye(len(names)))  # a correlated, positive-definite matrix
    sd = 0.01 * np.abs(x) + 1.0
    C = corr * np.outer(sd, sd)
    got = {q.key: q.std for q in engineering_figures(values, v.geometry, names, C)}
    draws = rng.multivariate_normal(x, C, size=6000)
    sampled = [car_quantities({**values, **dict(zip(names, d, strict=True))}, v.geometry) for d in draws]
    for key in ("mass_total", "cgs_height", "cgs_ahead_rear", "cg_height", "Ixx", "Iyy", "Izz", "Ixz",
                "front_share", "roll_front", "roll_front_share"):
        mc = np.std([s[key] for s in sampled])
        assert got[key] == pytest.approx(mc, rel=0.06), key  # 6000 draws: ~1 % sampling error, mild nonlinearity


def test_a_robot_verdict_in_the_notes_goes_to_the_consistency_section():
    notes = ("Test plan: something.\nPhysical consistency of the estimates: NOT physically realisable:\n"
             "  XX2: not positive\n  M3 < 0\nA later note.")
    verdict, other = split_notes(notes)
    assert verdict == ["Physical consistency of the estimates: NOT physically realisable:", "XX2: not positive",
                       "M3 < 0"]
    assert other == ["Test plan: something.", "A later note."]


# ------------------------------------------------------------------ real reports, parsed


class _Tables(HTMLParser):
    """Tables (caption, head, rows of cell texts), <pre> classes and images of a page."""

    def __init__(self):
        super().__init__()
        self.tables, self.pre, self.images, self._cell, self._row, self._where = [], [], [], None, None, None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table":
            self.tables.append({"caption": "", "head": [], "rows": [], "class": a.get("class", "")})
        elif tag == "caption":
            self._where = "caption"
        elif tag == "tr":
            self._row = []
        elif tag in ("td", "th"):
            self._cell = []
        elif tag == "pre":
            self.pre.append(a.get("class", ""))
        elif tag == "img":
            self.images.append(a.get("src", ""))

    def handle_endtag(self, tag):
        if tag == "caption":
            self._where = None
        elif tag in ("td", "th") and self._cell is not None:
            self._row.append("".join(self._cell).strip())
            self._cell = None
        elif tag == "tr" and self._row is not None:
            t = self.tables[-1]
            (t["rows"] if t["head"] else t["head"]).extend([self._row] if t["head"] else self._row)
            self._row = None

    def handle_data(self, data):
        if self._where == "caption":
            self.tables[-1]["caption"] += data
        elif self._cell is not None:
            self._cell.append(data)


def parse(path: Path) -> _Tables:
    p = _Tables()
    p.feed(path.read_text())
    return p


@pytest.fixture(scope="module")
def car(tmp_path_factory):
    """The quick demo, once: identified, then written."""
    from dynid.pipeline.demo import run_demo
    from dynid.pipeline.run import write_outputs

    out = tmp_path_factory.mktemp("car")
    run = run_demo(out, quick=True)
    write_outputs(run, out, "demo")
    return run, out


@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    """A small robot run: the Puma 560 on 6 s of consistent, slightly noisy torques; a cross-validation test."""
    import dynid
    from dynid.pipeline.config import load_config
    from dynid.pipeline.run import identify, write_outputs

    d = tmp_path_factory.mktemp("robot")
    m = dynid.load_model("puma560")
    t = np.arange(0, 6, 1 / 200.0)
    rng = np.random.default_rng(0)
    a, w, p = rng.uniform(0.3, 1, 6), rng.uniform(0.5, 2, 6), rng.uniform(0, 6, 6)
    q = a * np.sin(np.outer(t, w) + p)
    tau = m.inverse_dynamics(q, a * w * np.cos(np.outer(t, w) + p), -a * w**2 * np.sin(np.outer(t, w) + p))
    tau = tau + rng.normal(0, 0.05, tau.shape)
    head = ",".join(f"j{i}" for i in range(1, 7))
    np.savetxt(d / "q.csv", q, delimiter=",", header=head, comments="")
    np.savetxt(d / "tau.csv", tau, delimiter=",", header=head, comments="")
    files = f'files = {{ q = "{(d / "q.csv").as_posix()}", tau = "{(d / "tau.csv").as_posix()}" }}'
    (d / "identify.toml").write_text(
        f'[model]\nexample = "puma560"\n\n[[tests]]\nname = "t"\nfs = 200.0\n{files}\n\n'
        f'[[tests]]\nname = "v"\nrole = "validate"\nfs = 200.0\n{files}\n\n'
        '[channels]\nq = { channels = ["j1", "j2", "j3", "j4", "j5", "j6"], unit = "rad" }\n'
        'tau = { channels = ["j1", "j2", "j3", "j4", "j5", "j6"], unit = "N.m" }\n\n'
        "[conditioning]\ncutoff = 10.0\ndecimate = [2]\n")
    run = identify(load_config(d / "identify.toml"))
    write_outputs(run, d / "out", "robot")
    return run, d / "out"


def _table(page: _Tables, caption: str) -> dict:
    found = [t for t in page.tables if t["caption"] == caption]
    assert found, (caption, [t["caption"] for t in page.tables])
    return found[0]


@pytest.mark.slow
@pytest.mark.e2e
def test_the_car_report_has_the_papers_tables_with_units(car):
    run, out = car
    page = parse(out / "report.html")
    assert not [c for c in page.pre if c != "config"]  # no <pre> table left: only the config's listing
    for title, names in run.sections:
        t = _table(page, title)
        assert t["head"][:3] == ["parameter", "corner, quantity", "unit"]
        for col in ("a priori", "truth", "estimate", "σ total", "%σ", "%σ total", "95 % interval", "flag"):
            assert col in t["head"], col
        assert [r[0] for r in t["rows"]] == [run.result.labels[n] for n in names]
    chassis = {r[0]: r for r in _table(page, "Chassis (paper Table 2)")["rows"]}
    assert chassis["M6"][2] == "kg" and chassis["XX6"][2] == "kg·m²" and chassis["MX6"][2] == "kg·m"
    susp = {r[0]: r for r in _table(page, "Suspensions and anti-roll bars (paper Table 3)")["rows"]}
    assert [susp[k][2] for k in ("ks9", "h9", "fs9", "off9", "karf")] == ["N/m", "N·s/m", "N", "N", "N/m"]
    assert susp["ks9"][1] == "spring, rear left" and susp["karf"][1] == "anti-roll bar, front axle"
    # the estimate is rounded to two digits of σ total
    head = _table(page, "Chassis (paper Table 2)")["head"]
    i = run.result.index("M6")
    assert chassis["M6"][head.index("estimate")] == round_to_uncertainty(run.result.values[i],
                                                                         run.result.std_total[i])[0]
    text = (out / "report.html").read_text()
    assert "SPRUNG mass" in text and "total mass" in text  # M6 against the total: explained
    assert "base set" in text and "XX6 = XX6" not in text
    assert "Physical consistency" in text and "SHA-256" in text and "identify.toml" in text
    assert len(page.images) >= 4 and all(s.startswith("data:image/png;base64,") for s in page.images)
    eng = _table(page, "Masses")
    assert eng["rows"][0][0] == "total mass" and eng["rows"][0][1] == "kg"
    assert _table(page, "Inertia of the sprung mass about its CoG (ISO 8855)")["rows"][0][1] == "kg·m²"


@pytest.mark.slow
@pytest.mark.e2e
def test_the_car_results_as_data(car):
    run, out = car
    data = json.loads((out / "results.json").read_text())
    p = {q["name"]: q for q in data["parameters"]}
    assert p["K9"]["unit"] == "N/m" and p["M6"]["unit"] == "kg"
    assert (p["K9"]["corner"], p["K9"]["quantity"]) == ("rear left", "spring")
    lo, hi = p["M6"]["interval_95"]
    assert lo < p["M6"]["value"] < hi and hi - lo == pytest.approx(2 * 1.959964 * p["M6"]["std_total"])
    for key in ("value", "std", "rel_std_percent", "a_priori", "truth", "flag", "paper_rule", "scale", "std_total"):
        assert key in p["M6"], key  # the schema kept
    eng = {q["key"]: q for q in data["engineering"]["quantities"]}
    assert data["engineering"]["uncertainty"] == "total"
    assert eng["mass_total"]["value"] == pytest.approx(p["M6"]["value"] + 4 * 35.0)
    assert eng["mass_total"]["std"] == pytest.approx(p["M6"]["std_total"], rel=1e-4)  # the wheels are known
    assert {f["role"] for f in data["provenance"]["files"]} >= {"config", "vehicle (shipped)"}
    rows = list(csv.DictReader(io.StringIO((out / "parameters.csv").read_text())))
    assert [r["name"] for r in rows] == list(run.result.names) and rows[0]["unit"] == "kg·m²"
    by = {r["label"]: r for r in rows}
    assert (by["ks9"]["corner"], by["ks9"]["quantity"], by["ks9"]["unit"]) == ("rear left", "spring", "N/m")
    assert (by["kt42"]["corner"], by["kt42"]["quantity"]) == ("front right", "tire vertical stiffness")
    eng_rows = {r["key"]: r for r in csv.DictReader(io.StringIO((out / "engineering.csv").read_text()))}
    assert eng_rows["roll_front"]["unit"] == "N·m/deg" and eng_rows["ride_frequency_front"]["unit"] == "Hz"
    assert eng_rows["roll_gradient"]["unit"] == "deg/g" and float(eng_rows["corner_front_left"]["std"]) > 0
    sig = list(csv.DictReader(io.StringIO((out / "validation.csv").read_text())))
    tests = {(r["validation"], r["test"]) for r in sig}
    assert ("direct", "sine steering 90 km/h") in tests and ("cross", "step steer 80 km/h") in tests
    units = {r["equation"]: r["unit"] for r in sig}
    assert units["roll"] == "N·m" and units["z"] == "N" and units["susp9"] == "N"
    assert not list(out.rglob(".*.tmp*"))


@pytest.mark.slow
@pytest.mark.e2e
def test_one_axis_convention_iso_8855_in_the_validation(car):
    """The chassis equations are the paper's joints 1-6 in its ground frame (x0 right, y0 forward): the report
    names them in ISO 8855 terms and gives their signals in ISO signs, validation.csv beside the paper's name."""
    from dynid.report.build import validation_signals

    run, out = car
    page = parse(out / "report.html")
    # one validation for a car and a robot (issue 25): the car's table has the NRMSE too
    rows = [r[0] for r in _table(page, "Relative error per equation group and NRMSE (1: no better than the mean)")
            ["rows"]]
    assert rows[:6] == ["Y_E force", "X_E force", "Z_E force", "yaw moment", "pitch moment", "roll moment"]
    text = (out / "report.html").read_text()
    assert "x0 right, y0 forward, z0 up" in text and "Y_E force = −x" in text  # the paper's frames, where they must be
    assert "x6 up, y6 right, z6 forward. So XX6 is the yaw inertia" in text  # its chassis parameters
    sig = list(csv.DictReader(io.StringIO((out / "validation.csv").read_text())))
    paper = validation_signals(run)
    for equation, quantity, sign in (("x", "Y_E force", -1), ("y", "X_E force", 1), ("pitch", "pitch moment", -1),
                                     ("roll", "roll moment", 1)):
        got = [r for r in sig if r["equation"] == equation and r["validation"] == "cross"]
        assert {r["quantity"] for r in got} == {quantity}
        test = got[0]["test"]
        _, Y, WX = paper["cross"][test][equation]
        mine = [r for r in got if r["test"] == test]
        assert [float(r["measured"]) for r in mine] == pytest.approx(sign * Y, rel=1e-8, abs=1e-6)
        assert [float(r["predicted"]) for r in mine] == pytest.approx(sign * WX, rel=1e-8, abs=1e-6)


def test_a_figure_is_shown_at_its_drawn_size():
    """A figure 3 inches wide is 288 CSS px (96 an inch) whatever its pixels: the PNG's resolution says so."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dynid.report.figures import REPORT_DPI, _png
    from dynid.report.html import figure_html, png_css_size

    fig = plt.figure(figsize=(3.0, 2.0))
    png = _png(fig, plt, REPORT_DPI)
    assert png_css_size(png) == pytest.approx((288.0, 192.0), abs=0.5)
    assert 'width="288" height="192" style="--w:288px"' in figure_html("a", png)
    assert png_css_size(b"GIF89a...") is None


def test_a_panel_the_test_barely_moves_says_not_excited():
    """One rule (estimation.not_excited) for the cross-validation table's * and the plots' panels: RMS of the test's
    Y below twice the identification's residual RMS there. The demo's braking printed 220 % and 378 % for the
    lateral force: noise over noise."""
    from dynid.estimation import EXCITED_FACTOR, not_excited
    from dynid.report.build import panel_corners
    from dynid.vehicle.axes import CHASSIS_AXES

    assert EXCITED_FACTOR == 2.0
    assert not_excited({"a": 1.9, "b": 2.1, "c": 0.0}, {"a": 1.0, "b": 1.0}) == ["a"]  # no noise figure: judged
    t = np.linspace(0, 1, 400)
    rng = np.random.default_rng(1)
    quiet, loud = rng.normal(0, 1.0, t.size), 50 * np.sin(6 * t)
    signals = {"direct": {"braking": {"x": (t, quiet, 0 * t), "y": (t, loud, loud + 0.5)}},
               "cross": {"sine": {"x": (t, loud, 1.01 * loud)}}}
    corners = panel_corners(signals, {"x": 1.0, "y": 1.0}, CHASSIS_AXES)  # a car's equations
    assert corners[("Y_E force", "braking")] == "not excited"  # RMS 1 against 2 × 1
    assert corners[("X_E force", "braking")] == f"{100 * 0.5 * np.sqrt(t.size) / np.linalg.norm(loud):.1f} %"
    assert corners[("Y_E force", "sine")] == "1.0 %"


@pytest.mark.slow
@pytest.mark.e2e
def test_the_papers_rule_is_folded_not_beside_every_flag(car):
    run, out = car
    page = parse(out / "report.html")
    for title, _ in run.sections:
        assert "paper rule" not in _table(page, title)["head"]
    text = (out / "report.html").read_text()
    poor = [n for n, f in zip(run.result.names, run.result.flags, strict=True) if f == "poor"]
    assert poor and f"The paper&#x27;s rule (§7.2): {len(poor)} of" in text
    rule = [t for t in page.tables if "rule" in t["class"].split()]
    assert [r[0] for r in rule[0]["rows"]] == [run.result.labels[n] for n in poor]
    rows = list(csv.DictReader(io.StringIO((out / "parameters.csv").read_text())))
    assert [r["name"] for r in rows if r["paper_rule"] == "poor"] == poor  # kept in the CSV


@pytest.mark.slow
@pytest.mark.e2e
def test_the_car_sigma_against_a_monte_carlo_of_the_estimates_covariance(car):
    from dynid.report.build import _covariance

    run, _ = car
    r = run.result
    C, _ = _covariance(r)
    names = list(r.estimated_names)
    values = {**run.model.tree.values, **r.estimates}
    geometry = run.vehicle.geometry
    got = {q.key: q.std for q in engineering_figures(values, geometry, names, C)}
    rng = np.random.default_rng(3)
    draws = rng.multivariate_normal([values[n] for n in names], C, size=3000)
    sampled = [car_quantities({**values, **dict(zip(names, d, strict=True))}, geometry) for d in draws]
    for key in ("cgs_height", "cg_ahead_rear", "Izz", "roll_front", "front_share", "corner_front_left",
                "wheel_rate_rear_left", "ride_frequency_front", "damping_ratio_rear", "roll_gradient",
                "pitch_gradient"):
        assert got[key] == pytest.approx(np.std([s[key] for s in sampled]), rel=0.10), key


def test_the_validation_figures_drawn_apart_are_the_ones_drawn_here(robot):
    """build_report draws the validation figures in a forked process (report.apart): the files written are the
    bytes validation_figures gives in this process."""
    from dynid.report.build import _car_equations, validation_figures, validation_signals

    run, out = robot
    chassis, split = _car_equations(run)
    here = validation_figures(validation_signals(run), run.model.tree, run.residual_rms, chassis, split)
    assert here and [(out / f"figure_validation{k}.png").read_bytes() for k in range(1, len(here) + 1)] == [
        png for _, png in here]


def test_the_robot_report_has_units_and_per_joint_plots(robot):
    _, out = robot
    page = parse(out / "report.html")
    assert not [c for c in page.pre if c != "config"]
    t = page.tables[0]
    rows = {r[0]: r for r in t["rows"]}
    assert t["head"][:2] == ["parameter", "unit"]
    assert rows["FV1"][1] == "N·m·s/rad" and rows["ZZ1"][1] == "kg·m²" and rows["MX2"][1] == "kg·m"
    valid = _table(page, "Relative error per equation group and NRMSE (1: no better than the mean)")
    assert {r[1] for r in valid["rows"] if r[0].startswith("joint")} == {"N·m"}
    assert valid["head"][2:] == ["direct ‖Y − W X‖/‖Y‖", "cross ‖Y − W X‖/‖Y‖", "direct RMS(Y − W X)/std(Y)",
                                 "cross RMS(Y − W X)/std(Y)"]
    assert len(page.images) >= 2
    sig = list(csv.DictReader(io.StringIO((out / "validation.csv").read_text())))
    assert {(r["validation"], r["test"]) for r in sig} == {("direct", "t"), ("cross", "v")}
    assert {r["unit"] for r in sig} == {"N·m"}
    data = json.loads((out / "results.json").read_text())
    assert data["parameters"][0]["unit"] == "kg·m²"


# ------------------------------------------------------------------ the report on any screen (issue 27)

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="no chromium: the layout tests need a real browser")

# runs in the page once it has loaded (its images decoded), measures what a reader sees and writes it as JSON into
# the page that holds it; the page is framed at the screen's width (headless Chromium's window is at least 500 px)
_MEASURE = """<script>
window.addEventListener("load", function () {
 var de = document.documentElement, out = {viewport: de.clientWidth, width: de.scrollWidth, tables: [], figures: []};
 var nav = document.querySelector("nav");
 out.nav = [nav.scrollWidth, nav.clientWidth];
 function box(e) { var r = e.getBoundingClientRect(); return [r.left, r.right]; }
 document.querySelectorAll("table").forEach(function (t) {
  var heads = Array.from(t.tHead.rows[0].cells), pins = heads.filter(function (h) {
   return h.classList.contains("pin"); }), cells = [];
  pins.forEach(function (h) { var k = heads.indexOf(h);
   Array.from(t.rows).forEach(function (r) { if (r.cells[k]) cells.push(r.cells[k]); }); });
  out.tables.push({caption: t.caption ? t.caption.textContent : "",
                   pins: pins.map(function (h) { return h.textContent; }),
                   box: box(t.closest(".tablewrap") || t.parentElement), first: box(heads[0]), table: t.scrollWidth,
                   pinned: cells.map(box)});
 });
 document.querySelectorAll("figure img").forEach(function (im) {
  out.figures.push({drawn: +im.getAttribute("width"), shown: im.getBoundingClientRect().width,
                    box: box(im.closest(".figwrap") || im.parentElement)});
 });
 var pre = parent.document.createElement("pre");
 pre.id = "layout"; pre.textContent = JSON.stringify(out); parent.document.body.appendChild(pre);
});
</script>"""


def measure_layout(page: Path, width: int) -> dict:
    """The report at a screen `width` CSS px wide, as headless Chromium lays it out (see _MEASURE)."""
    import html

    framed = page.read_text().replace("</body>", _MEASURE + "</body>")
    host = page.parent / f"layout_{width}.html"
    host.write_text(f'<!DOCTYPE html><html><body style="margin:0"><iframe style="border:0;width:{width}px;'
                    f'height:900px" srcdoc="{html.escape(framed, quote=True)}"></iframe></body></html>')
    dom = subprocess.run([CHROMIUM, "--headless", "--disable-gpu", "--no-sandbox", "--hide-scrollbars",
                          "--window-size=1400,1000", "--virtual-time-budget=10000", "--dump-dom", host.as_uri()],
                         check=True, capture_output=True, text=True, timeout=120).stdout
    host.unlink()
    found = re.search(r'<pre id="layout">(.*?)</pre>', dom, re.S)
    assert found, dom[-2000:]
    return json.loads(html.unescape(found.group(1)))


@needs_chromium
@pytest.mark.parametrize("width", [1366, 390])
@pytest.mark.parametrize("which", ["car", "robot"])
@pytest.mark.slow
@pytest.mark.e2e
def test_the_report_reads_on_a_laptop_and_a_phone(which, width, request):
    """Issue 27: at 390 px the contents line wrapped nowhere (the page was 1187 px wide) and the parameter tables'
    estimates sat off-screen. Now the page is never wider than the screen, every table's pinned estimate is in view
    inside its scroll box without scrolling (a car's corner and quantity too), and a figure never shrinks below
    85 % of its drawn size."""
    _, out = request.getfixturevalue(which)
    m = measure_layout(out / "report.html", width)
    assert m["viewport"] == width
    assert m["width"] <= m["viewport"], "the page is wider than the screen"
    assert m["nav"][0] <= m["nav"][1], "the contents line does not wrap"
    pinned = [t for t in m["tables"] if t["pins"]]
    assert len(pinned) >= (10 if which == "car" else 1)  # the car's engineering and parameter tables
    assert all("estimate" in t["pins"] or "ours" in t["pins"] for t in pinned)
    if which == "car":  # the parameter tables keep the corner and quantity in view too
        assert sum(t["pins"] == ["corner, quantity", "estimate"] for t in pinned) == len(request.getfixturevalue(
            "car")[0].sections)
    for t in m["tables"]:
        left, right = t["box"]
        assert right <= m["viewport"] + 0.5, t["caption"]
        assert left - 0.5 <= t["first"][0] and t["first"][1] <= right + 0.5, t["caption"]  # the name
        for a, b in t["pinned"]:
            assert left - 0.5 <= a and b <= right + 0.5, (t["caption"], (a, b), t["box"])
    assert any(t["table"] > t["box"][1] - t["box"][0] for t in pinned) == (width == 390)  # it did scroll
    assert len(m["figures"]) >= (5 if which == "car" else 2)
    for f in m["figures"]:
        assert f["drawn"] > 0 and f["box"][1] <= m["viewport"] + 0.5
        assert f["shown"] >= 0.85 * f["drawn"] - 0.5  # legible: scrolls in its box rather than shrinking
        if width == 1366:
            assert f["shown"] == pytest.approx(f["drawn"], abs=1)  # a laptop shows it whole at its drawn size


def test_terminal_validation_names_the_chassis_equations_as_the_report():
    """One axis convention (issue 27): the terminal's validation table names a car's chassis equations by their ISO
    8855 names, as the report does (vehicle.axes), and says how results.json's paper names map to them."""
    from dynid.report.tables import validation_table
    from dynid.vehicle.axes import CHASSIS_AXES

    errors = {"direct": {g: 0.01 * (k + 1) for k, g in enumerate([*CHASSIS_AXES, "susp9"])}}
    lines = validation_table(errors, kind="car").splitlines()
    for k, g in enumerate(CHASSIS_AXES):
        label, value = lines[1 + k].rsplit(None, 2)[0].strip(), lines[1 + k].split()[-2]
        assert label == CHASSIS_AXES[g].label and float(value) == pytest.approx(k + 1)
    assert lines[7].split()[0] == "susp9"
    assert "Y_E force = -x" in lines[-1] and "pitch moment = -pitch" in lines[-1]


def test_a_robot_run_is_shown_without_the_car_axes():
    """The ISO 8855 names are the car's (vehicle.axes), read by the run's kind: a robot whose equation groups are
    named x, y, pitch (a floating base) keeps its names and signs, and its report and terminal table import no
    car knowledge (a fresh interpreter: nothing of dynid.vehicle loaded)."""
    import subprocess
    import sys

    code = """
import sys
import numpy as np
from dynid.report.build import panel_corners, validation_csv
from dynid.report.tables import validation_table
text = validation_table({"direct": {"x": 0.01, "pitch": 0.02, "q1": 0.03}})
t = np.linspace(0, 1, 50)
signals = {"direct": {"run": {"x": (t, np.sin(9 * t), np.sin(9 * t))}}}
print(sorted(panel_corners(signals, {"x": 1e-9})))
print(text)
print([m for m in sys.modules if m.startswith("dynid.vehicle")])
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    corners, *table, loaded = out.strip().splitlines()
    assert corners == "[('x', 'run')]" and loaded == "[]"
    assert [line.split()[0] for line in table[1:]] == ["x", "pitch", "q1"]  # no Y_E force, no note under them
