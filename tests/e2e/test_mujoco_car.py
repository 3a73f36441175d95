"""A car dynid did not simulate: the MuJoCo test car of ../shared/data/mujoco-car/, through `dynid identify` with the
example's vehicle file (examples/mujoco_car/, written from the data's README as a user would).

Oracles: the data's truth.json (MuJoCo's model, in dynid's names) and its `tire_fit` (a straight line
Fz = kt q + F0 fitted on the sine run's TRUE deflections and loads). The channels of `ideal/` are the true values,
so with the sensors' delays not compensated (they have none) the joints are exact up to the filters: the chassis,
suspension and bar parameters are held to the bounds of issue 24. The tire: its contact is nonlinear, so a line
fits the sine's load range (16 N RMS in MuJoCo's own fit) and not the spiral's; the paper's line with its
unloaded-radius offset must give the truth's line on the sine, and the model-fit verdict must call the tire groups
misfits once the spiral is in (their parameters are then not results). The example's vehicle file therefore
declares the progressive law with the lateral-force term (as a user would once the verdict says the line does not
fit), and every tire group fits with it.
"""

import pytest
from mujoco_car import identify, mujoco_truth

# The MuJoCo car's files through `dynid identify`, three configurations (about 15 s).
pytestmark = [pytest.mark.slow, pytest.mark.e2e]

TIRE_PARAMETERS = {f"{term}{tire}" for term in ("K", "OFF") for tire in (15, 24, 33, 42)}


@pytest.fixture(scope="module")
def truth() -> dict:
    return mujoco_truth()


def _errors(res: dict, truth: dict) -> dict[str, float]:
    """Each estimated parameter's error against truth.json, in fractions of its scale (the report's); the tire
    law's parameters left out (truth.json has the sine's line only: the tests below compare with it)."""
    true = {p["label"]: p["value"] for p in truth["true_parameters"]}
    tire = {f"{p}{t}" for p in ("kt", "off", "ktq", "ktfy") for t in (15, 24, 33, 42)}
    out = {p["label"]: (p["value"] - true[p["label"]]) / p["scale"] for p in res["parameters"]
           if p["label"] in true and p["label"] not in tire and p["flag"] != "known"}
    assert {"XX6", "ZZ6", "M6", "ks9", "h36", "fs27", "karr"} <= set(out), sorted(out)
    return out


CHASSIS_AND_SUSPENSION = ("x", "y", "z", "yaw", "pitch", "roll", "susp9", "susp18", "susp27", "susp36")


@pytest.fixture(scope="module")
def ideal_all(truth, tmp_path_factory):
    return identify(tmp_path_factory.mktemp("mj"), "ideal", ["sine", "spiral", "braking"], compensate_delays=False)


@pytest.fixture(scope="module")
def ideal_line(truth, tmp_path_factory):
    return identify(tmp_path_factory.mktemp("mj"), "ideal", ["sine", "spiral", "braking"], compensate_delays=False,
                    tire="paper")


@pytest.fixture(scope="module")
def ideal_sine_line(truth, tmp_path_factory):
    return identify(tmp_path_factory.mktemp("mj"), "ideal", ["sine"], compensate_delays=False, tire="paper")


def test_ideal_channels_give_every_parameter_within_one_percent(truth, ideal_all):
    """Issue 24, ideal/ with the sensors declared ideal and the example's files: every chassis, suspension and bar
    parameter within 1 % of its scale of the truth (dry friction 5 %), validation below 0.5 % in every chassis and
    suspension group and below 2 % in the tire groups. Measured: worst h27 -0.69 %, fs9 +0.92 %; chassis groups
    <= 0.01 %, suspensions <= 0.064 %, tires 1.46 / 0.82 / 0.83 / 0.32 %. Mass, CoG, and the inertias at the CoG
    against the README's figures (roll -0.48 %)."""
    res, eng = ideal_all
    for name, e in _errors(res, truth).items():
        assert abs(e) <= (0.05 if name.startswith("fs") else 0.01), (name, e)
    direct = res["validation"]["direct"]
    for group in CHASSIS_AND_SUSPENSION:
        assert direct[group] < 0.005, (group, direct)
    for tire in (15, 24, 33, 42):
        assert direct[f"tire{tire}"] < 0.02 and res["validation"]["fit"][f"tire{tire}"]["fits"], direct
    v = truth["vehicle"]
    assert eng["mass_total"] == pytest.approx(v["total_mass"]["value"], rel=0.005)
    x_g, _, z_g = v["chassis_com_frame6"]["value"]  # sprung CoG in frame 6: height above the wheel centres, ahead
    assert eng["cgs_ahead_rear"] == pytest.approx(z_g, abs=2.5e-3)
    assert eng["cgs_height"] == pytest.approx(x_g + v["geometry"]["wheel_radius"], abs=2.5e-3)
    for key, value in (("Ixx", 450.0), ("Iyy", 1900.0), ("Izz", 2100.0)):
        assert eng[key] == pytest.approx(value, rel=0.01), key


def test_tire_equation_with_its_offset_gives_the_true_line_on_the_sine(truth, ideal_sine_line):
    """The paper's line kt q + off = Fz on the sine: MuJoCo's line through its true deflections and loads (kt
    169-178 kN/m, F0 2.6 and 3.6 kN, i.e. unloaded radii 0.325 and 0.330 m where the geometric one is 0.31 m). The
    estimate's deflections come from the ideal lasers through the chassis attitude; 1 % of kt is 0.05 mm over the
    sine's 6 mm range."""
    res, _ = ideal_sine_line
    values = {p["label"]: p for p in res["parameters"]}
    fit = truth["vehicle"]["tire_fit"]
    for tire, corner in zip((15, 24, 33, 42), ("rl", "rr", "fl", "fr"), strict=True):
        assert values[f"kt{tire}"]["value"] == pytest.approx(fit[corner]["kt"], rel=0.01)
        assert values[f"off{tire}"]["value"] == pytest.approx(fit[corner]["F0"], abs=10.0)
        assert res["validation"]["fit"][f"tire{tire}"]["fits"]
        assert values[f"kt{tire}"]["flag"] != "misfit"


def test_a_line_does_not_fit_the_spiral_s_load_range_and_says_so(ideal_line):
    """Over the three runs the contact's nonlinearity leaves the paper's tire groups' residual several times what
    the sensors explain (MuJoCo's lines over the spiral differ by up to 2x): those groups are misfits and their kt
    and offsets are flagged, not presented as results; the chassis and suspension groups still fit."""
    res, _ = ideal_line
    fit = res["validation"]["fit"]
    flags = {p["label"]: p["flag"] for p in res["parameters"]}
    misfits = [g for g, f in fit.items() if not f["fits"]]
    assert misfits and all(g.startswith("tire") for g in misfits)
    for g in misfits:
        assert fit[g]["ratio"] > 3.0
        tire = g[len("tire"):]
        assert flags[f"kt{tire}"] == "misfit" and flags[f"off{tire}"] == "misfit"
    for g in CHASSIS_AND_SUSPENSION:
        assert fit[g]["fits"], (g, fit[g])


@pytest.fixture(scope="module")
def ideal_progressive(truth, tmp_path_factory):
    return identify(tmp_path_factory.mktemp("mj"), "ideal", ["sine", "spiral", "braking"], compensate_delays=False,
                    tire="progressive")


def test_a_progressive_tire_fits_the_spiral_s_load_range_better(ideal_line, ideal_progressive):
    """[wheels] tire_law = "progressive": kt q + ktq q² + off (the Magic Formula's vertical law, qFz1 and qFz2). Over
    the three runs the contact stiffens with its load: every ktq comes out > 0 (progressive), and the tire groups'
    residual falls by a third or more on every tire and by half over the four (measured: 4.6, 5.2, 3.5, 1.5 % with
    the line; 2.1, 3.2, 1.1, 0.9 % with the law). What is left is mostly the outer wheels' lateral force, which
    this law does not model. The tire equations share no parameter with the others: every chassis, suspension and
    bar estimate is the line's."""
    line, law = ({p["label"]: p for p in r["parameters"]} for r in (ideal_line[0], ideal_progressive[0]))
    before, after = ({t: r[0]["validation"]["direct"][f"tire{t}"] for t in (15, 24, 33, 42)}
                     for r in (ideal_line, ideal_progressive))
    for tire in (15, 24, 33, 42):
        assert law[f"ktq{tire}"]["value"] > 0
        assert after[tire] < 0.7 * before[tire], (tire, before, after)
    assert sum(after.values()) < 0.55 * sum(before.values()), (before, after)
    tire = {f"{p}{t}" for p in ("kt", "off", "ktq") for t in (15, 24, 33, 42)}
    for name, p in line.items():
        if name not in tire:
            assert law[name]["value"] == pytest.approx(p["value"], rel=1e-7, abs=1e-6), name


def test_the_lateral_force_term_brings_every_tire_group_below_two_percent(ideal_progressive, ideal_all):
    """[wheels] tire_lateral_force = true (the example's): kt q + ktq q² + off - ktfy Fy² q = Fz, Fy the
    transducer's lateral force (the Magic Formula's qFcy form, its sign free). Issue 24's bound for the tire groups
    on ideal/ is 2 %; the progressive law alone leaves 2.1 and 3.2 % at the rear (measured), mostly the spiral's
    outer wheels. With the term: 1.46, 0.81, 0.82, 0.32 % (measured), each group at most its progressive residual.
    The tire equations share no parameter with the others: every other estimate is the progressive law's."""
    law, lat = ({p["label"]: p for p in r["parameters"]} for r in (ideal_progressive[0], ideal_all[0]))
    before, after = ({t: r[0]["validation"]["direct"][f"tire{t}"] for t in (15, 24, 33, 42)}
                     for r in (ideal_progressive, ideal_all))
    for tire in (15, 24, 33, 42):
        assert after[tire] < 0.02 and after[tire] <= before[tire], (tire, before, after)
        assert lat[f"ktfy{tire}"]["unit"] == "1/(N·m)" and lat[f"ktfy{tire}"]["a_priori"] == 0.0
        assert ideal_all[0]["validation"]["fit"][f"tire{tire}"]["fits"]
    tire = {f"{p}{t}" for p in ("kt", "off", "ktq") for t in (15, 24, 33, 42)}
    for name, p in law.items():
        if name not in tire:
            assert lat[name]["value"] == pytest.approx(p["value"], rel=1e-7, abs=1e-6), name


@pytest.fixture(scope="module")
def ideal_step_friction(truth, tmp_path_factory):
    return identify(tmp_path_factory.mktemp("mj"), "ideal", ["sine", "spiral", "braking"], compensate_delays=False,
                    conditioning="friction_lowpass = false\nmin_speed = 0.01")


def test_friction_columns_through_the_loads_low_pass_bring_the_suspensions_within_one_percent(
        truth, ideal_all, ideal_step_friction):
    """[conditioning] friction_lowpass = true (the default): the dampers' dry-friction columns through the loads'
    low-pass (W and Y through the same filters); with the example's min_speed = 0.02 (MuJoCo smooths the Coulomb
    friction at very low rates, its README says). A sharp sign(rate) column (friction_lowpass = false) with rows
    from 1 cm/s misses issue 24's 1 % on ideal/ (ks -1.35 %, h27 +2.67 %, karr +2.59 %, measured); the example's
    files give every spring, damper and bar within 0.7 % and every suspension group's residual below half the
    other's (measured 0.064 / 0.064 / 0.045 / 0.054 % against 0.24 / 0.25 / 0.15 / 0.14 %)."""
    before, after = _errors(ideal_step_friction[0], truth), _errors(ideal_all[0], truth)
    names = [f"{kind}{c}" for kind in ("ks", "h") for c in (9, 18, 27, 36)] + ["karf", "karr"]
    assert max(abs(before[n]) for n in names) > 0.01  # the sharp column misses (so this test can tell)
    assert max(abs(after[n]) for n in names) <= 0.01
    for corner in (9, 18, 27, 36):
        group = f"susp{corner}"
        assert ideal_all[0]["validation"]["direct"][group] < 0.5 * ideal_step_friction[0]["validation"]["direct"][group]


@pytest.fixture(scope="module")
def noise_all(truth, tmp_path_factory):
    return identify(tmp_path_factory.mktemp("mj"), "noise", ["sine", "spiral", "braking"], compensate_delays=True)


@pytest.fixture(scope="module")
def noise_line(truth, tmp_path_factory):
    return identify(tmp_path_factory.mktemp("mj"), "noise", ["sine", "spiral", "braking"], compensate_delays=True,
                    tire="paper")


def test_the_sensor_chain_s_files_with_the_example_s_files(truth, noise_all):
    """noise/ (the same runs through the paper's Table-1 sensor chain, seed 406) with the example's files and every
    default: the Table-1 dynamics undone, each test's zero offsets estimated with the parameters. Mass, CoG,
    inertias, springs, dampers, dry friction and bars to the bounds of issue 24; every tire group fits at the noise
    level; every estimate outside the tire law within 3 σ total of the truth. Measured: mass -0.05 %, CoG +0.2 and
    +0.1 mm, roll +0.36 % (σ total 1.3 %), pitch +0.51 %, yaw +1.06 %, springs <= 0.43 %, dampers <= 2.95 %, dry
    friction <= 2.6 %, bars <= 0.6 %, tire groups 0.70-1.38 x what the sensors explain, largest |z| 1.65."""
    res, eng = noise_all
    values = {p["label"]: p for p in res["parameters"]}
    true = {p["label"]: p["value"] for p in truth["true_parameters"]}
    v = truth["vehicle"]
    assert eng["mass_total"] == pytest.approx(v["total_mass"]["value"], rel=0.005)
    x_g, _, z_g = v["chassis_com_frame6"]["value"]
    assert eng["cgs_ahead_rear"] == pytest.approx(z_g, abs=2.5e-3)
    assert eng["cgs_height"] == pytest.approx(x_g + v["geometry"]["wheel_radius"], abs=2.5e-3)
    for key, value in (("Ixx", 450.0), ("Iyy", 1900.0), ("Izz", 2100.0)):
        assert eng[key] == pytest.approx(value, rel=0.02), key
    for corner in (9, 18, 27, 36):
        assert values[f"ks{corner}"]["value"] == pytest.approx(true[f"ks{corner}"], rel=0.03)
        assert values[f"h{corner}"]["value"] == pytest.approx(true[f"h{corner}"], rel=0.05)
        assert values[f"fs{corner}"]["value"] == pytest.approx(true[f"fs{corner}"], rel=0.10)
    for bar in ("karf", "karr"):
        assert values[bar]["value"] == pytest.approx(true[bar], rel=0.05)
    for tire in (15, 24, 33, 42):
        assert res["validation"]["fit"][f"tire{tire}"]["fits"], res["validation"]["fit"]
    tire_law = {f"{p}{t}" for p in ("kt", "off", "ktq", "ktfy") for t in (15, 24, 33, 42)}
    for p in res["parameters"]:
        if p["truth"] is None or p["flag"] == "known" or p["label"] in tire_law:
            continue
        assert abs(p["value"] - p["truth"]) <= 3.0 * p["std_total"], p


def test_the_paper_s_line_on_the_sensor_chain_s_files_is_the_ideal_channels_line(noise_line, ideal_line):
    """With the paper's line, each tire's kt from noise/ within 5 % of the line the ideal channels give over the
    same three runs (the contact is nonlinear: the line depends on the load range, so it is the same runs' line,
    not truth.json's sine-only one; ideal/'s line on the sine alone is MuJoCo's to 1 %, tested above). The line
    misfits (flagged), so those groups are left out of the offsets' estimate. Measured -0.8, -3.3, +4.8, -0.2 %."""
    noisy = {p["label"]: p["value"] for p in noise_line[0]["parameters"]}
    ideal = {p["label"]: p["value"] for p in ideal_line[0]["parameters"]}
    for tire in (15, 24, 33, 42):
        assert noisy[f"kt{tire}"] == pytest.approx(ideal[f"kt{tire}"], rel=0.05), tire
