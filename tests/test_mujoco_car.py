"""A car dynid did not simulate: the MuJoCo test car of ../shared/data/mujoco-car/, through `dynid identify` with the
example's vehicle file (examples/mujoco_car/, written from the data's README as a user would).

Oracles: the data's truth.json (MuJoCo's model, in dynid's names) and its `tire_fit` (a straight line
Fz = kt q + F0 fitted on the sine run's TRUE deflections and loads). The channels of `ideal/` are the true values,
so with the sensors' delays not compensated (they have none) the joints are exact up to the filters: the chassis,
suspension and bar parameters are held to the bounds of issue 24. The tire: its contact is nonlinear, so a line
fits the sine's load range (16 N RMS in MuJoCo's own fit) and not the spiral's; the tire equation with its
unloaded-radius offset must give the truth's line on the sine, and the model-fit verdict must call the tire groups
misfits once the spiral is in (their parameters are then not results).
"""

import pytest
from mujoco_car import identify, mujoco_truth

# The MuJoCo car's files through `dynid identify`, three configurations (about 15 s).
pytestmark = [pytest.mark.slow, pytest.mark.e2e]

TIRE_PARAMETERS = {f"{term}{tire}" for term in ("K", "OFF") for tire in (15, 24, 33, 42)}


@pytest.fixture(scope="module")
def truth() -> dict:
    return mujoco_truth()


@pytest.fixture(scope="module")
def ideal_all(truth, tmp_path_factory):
    return identify(tmp_path_factory.mktemp("mj"), "ideal", ["sine", "spiral", "braking"], compensate_delays=False)


@pytest.fixture(scope="module")
def ideal_sine(truth, tmp_path_factory):
    return identify(tmp_path_factory.mktemp("mj"), "ideal", ["sine"], compensate_delays=False)


def test_ideal_channels_give_mass_centre_of_gravity_suspensions_and_bars(truth, ideal_all):
    res, eng = ideal_all
    values = {p["label"]: p["value"] for p in res["parameters"]}
    true = {p["label"]: p["value"] for p in truth["true_parameters"]}
    v = truth["vehicle"]
    assert eng["mass_total"] == pytest.approx(v["total_mass"]["value"], rel=0.005)
    x_g, _, z_g = v["chassis_com_frame6"]["value"]  # sprung CoG in frame 6: height above the wheel centres, ahead
    assert eng["cgs_ahead_rear"] == pytest.approx(z_g, abs=2.5e-3)
    assert eng["cgs_height"] == pytest.approx(x_g + v["geometry"]["wheel_radius"], abs=2.5e-3)
    for corner in (9, 18, 27, 36):
        assert values[f"ks{corner}"] == pytest.approx(true[f"ks{corner}"], rel=0.03)
        assert values[f"h{corner}"] == pytest.approx(true[f"h{corner}"], rel=0.05)
        assert values[f"fs{corner}"] == pytest.approx(true[f"fs{corner}"], rel=0.10)
        assert values[f"off{corner}"] == pytest.approx(true[f"off{corner}"], rel=0.01)
    for bar in ("karf", "karr"):
        assert values[bar] == pytest.approx(true[bar], rel=0.05)
    # roll and yaw about the CoG (the README's 450 and 2100 kg.m2)
    assert eng["Ixx"] == pytest.approx(450.0, rel=0.02)
    assert eng["Izz"] == pytest.approx(2100.0, rel=0.02)


def test_tire_equation_with_its_offset_gives_the_true_line_on_the_sine(truth, ideal_sine):
    """kt q + off = Fz on the sine: MuJoCo's line through its true deflections and loads (kt 169-178 kN/m, F0 2.6 and
    3.6 kN, i.e. unloaded radii 0.325 and 0.330 m where the geometric one is 0.31 m). The estimate's deflections
    come from the ideal lasers through the chassis attitude; 1 % of kt is 0.05 mm over the sine's 6 mm range."""
    res, _ = ideal_sine
    values = {p["label"]: p for p in res["parameters"]}
    fit = truth["vehicle"]["tire_fit"]
    for tire, corner in zip((15, 24, 33, 42), ("rl", "rr", "fl", "fr"), strict=True):
        assert values[f"kt{tire}"]["value"] == pytest.approx(fit[corner]["kt"], rel=0.01)
        assert values[f"off{tire}"]["value"] == pytest.approx(fit[corner]["F0"], abs=10.0)
        assert res["validation"]["fit"][f"tire{tire}"]["fits"]
        assert values[f"kt{tire}"]["flag"] != "misfit"


def test_a_line_does_not_fit_the_spiral_s_load_range_and_says_so(ideal_all):
    """Over the three runs the contact's nonlinearity leaves the tire groups' residual several times what the sensors
    explain (MuJoCo's lines over the spiral differ by up to 2x): those groups are misfits and their kt and offsets
    are flagged, not presented as results; the chassis and suspension groups still fit."""
    res, _ = ideal_all
    fit = res["validation"]["fit"]
    flags = {p["label"]: p["flag"] for p in res["parameters"]}
    misfits = [g for g, f in fit.items() if not f["fits"]]
    assert misfits and all(g.startswith("tire") for g in misfits)
    for g in misfits:
        assert fit[g]["ratio"] > 3.0
        tire = g[len("tire"):]
        assert flags[f"kt{tire}"] == "misfit" and flags[f"off{tire}"] == "misfit"
    for g in ("x", "y", "z", "yaw", "roll", "susp9", "susp18", "susp27", "susp36"):
        assert fit[g]["fits"], (g, fit[g])


@pytest.fixture(scope="module")
def ideal_progressive(truth, tmp_path_factory):
    return identify(tmp_path_factory.mktemp("mj"), "ideal", ["sine", "spiral", "braking"], compensate_delays=False,
                    tire_law="progressive")


def test_a_progressive_tire_fits_the_spiral_s_load_range_better(ideal_all, ideal_progressive):
    """[wheels] tire_law = "progressive": kt q + ktq q² + off (the Magic Formula's vertical law, qFz1 and qFz2). Over
    the three runs the contact stiffens with its load: every ktq comes out > 0 (progressive), and the tire groups'
    residual falls by a third or more on every tire and by half over the four (measured: 4.6, 5.2, 3.5, 1.5 % with
    the line; 2.1, 3.2, 1.1, 0.9 % with the law). What is left is mostly the outer wheels' lateral force (the Magic
    Formula's qFcy: a cornering tire carries less load at the same deflection), which this law does not model. The
    tire equations share no parameter with the others: every chassis, suspension and bar estimate is the line's."""
    line, law = ({p["label"]: p for p in r["parameters"]} for r in (ideal_all[0], ideal_progressive[0]))
    before, after = ({t: r[0]["validation"]["direct"][f"tire{t}"] for t in (15, 24, 33, 42)}
                     for r in (ideal_all, ideal_progressive))
    for tire in (15, 24, 33, 42):
        assert law[f"ktq{tire}"]["value"] > 0
        assert after[tire] < 0.7 * before[tire], (tire, before, after)
    assert sum(after.values()) < 0.55 * sum(before.values()), (before, after)
    tire = {f"{p}{t}" for p in ("kt", "off", "ktq") for t in (15, 24, 33, 42)}
    for name, p in line.items():
        if name not in tire:
            assert law[name]["value"] == pytest.approx(p["value"], rel=1e-7, abs=1e-6), name


@pytest.fixture(scope="module")
def ideal_lateral(truth, tmp_path_factory):
    return identify(tmp_path_factory.mktemp("mj"), "ideal", ["sine", "spiral", "braking"], compensate_delays=False,
                    tire_law="progressive", lateral_force=True)


def test_the_lateral_force_term_brings_every_tire_group_below_two_percent(ideal_progressive, ideal_lateral):
    """[wheels] tire_lateral_force = true: kt q + ktq q² + off - ktfy Fy² q = Fz, Fy the transducer's lateral force
    (the Magic Formula's qFcy form, its sign free). Issue 24's bound for the tire groups on ideal/ is 2 %; the
    progressive law alone leaves 2.1 and 3.2 % at the rear (measured), mostly the spiral's outer wheels. With the
    term: 1.46, 0.81, 0.82, 0.32 % (measured), each group at most its progressive residual. The tire equations
    share no parameter with the others: every other estimate is the progressive law's."""
    law, lat = ({p["label"]: p for p in r["parameters"]} for r in (ideal_progressive[0], ideal_lateral[0]))
    before, after = ({t: r[0]["validation"]["direct"][f"tire{t}"] for t in (15, 24, 33, 42)}
                     for r in (ideal_progressive, ideal_lateral))
    for tire in (15, 24, 33, 42):
        assert after[tire] < 0.02 and after[tire] <= before[tire], (tire, before, after)
        assert lat[f"ktfy{tire}"]["unit"] == "1/(N·m)" and lat[f"ktfy{tire}"]["a_priori"] == 0.0
        assert ideal_lateral[0]["validation"]["fit"][f"tire{tire}"]["fits"]
    tire = {f"{p}{t}" for p in ("kt", "off", "ktq") for t in (15, 24, 33, 42)}
    for name, p in law.items():
        if name not in tire:
            assert lat[name]["value"] == pytest.approx(p["value"], rel=1e-7, abs=1e-6), name


@pytest.fixture(scope="module")
def ideal_friction_lowpass(truth, tmp_path_factory):
    return identify(tmp_path_factory.mktemp("mj"), "ideal", ["sine", "spiral", "braking"], compensate_delays=False,
                    conditioning="friction_lowpass = true\nmin_speed = 0.02")


def test_friction_columns_through_the_loads_low_pass_give_the_suspensions_within_one_percent(
        truth, ideal_all, ideal_friction_lowpass):
    """[conditioning] friction_lowpass = true: the dampers' dry-friction columns through the loads' low-pass (W and Y
    through the same filters). With min_speed 0.02 m/s every spring, damper and bar is within issue 24's 1 % on
    ideal/ and the dry friction within 5 % (measured: ks <= 0.51 %, h <= 0.68 %, fs <= 0.93 %, bars <= 0.47 %;
    the defaults miss by up to 2.7 %), and every suspension group's residual falls below half the defaults'
    (measured 0.06 / 0.06 / 0.04 / 0.05 % against 0.24 / 0.25 / 0.15 / 0.14 %)."""
    res, _ = ideal_friction_lowpass
    values = {p["label"]: p["value"] for p in res["parameters"]}
    true = {p["label"]: p["value"] for p in truth["true_parameters"]}
    for corner in (9, 18, 27, 36):
        for kind in ("ks", "h"):
            assert values[f"{kind}{corner}"] == pytest.approx(true[f"{kind}{corner}"], rel=0.01), (kind, corner)
        assert values[f"fs{corner}"] == pytest.approx(true[f"fs{corner}"], rel=0.05)
        group = f"susp{corner}"
        assert res["validation"]["direct"][group] < 0.5 * ideal_all[0]["validation"]["direct"][group]
    for bar in ("karf", "karr"):
        assert values[bar] == pytest.approx(true[bar], rel=0.01)


@pytest.fixture(scope="module")
def noise_all(truth, tmp_path_factory):
    return identify(tmp_path_factory.mktemp("mj"), "noise", ["sine", "spiral", "braking"], compensate_delays=True)


def test_the_sensor_chain_s_files_with_the_defaults(truth, noise_all, ideal_all):
    """noise/ (the same runs through the paper's Table-1 sensor chain, seed 406) with every default: the Table-1
    dynamics undone, σ total from the suite's zero offsets. Mass, CoG, pitch and yaw inertia, springs, dampers, dry
    friction and bars to the bounds of issue 24; every chassis and suspension estimate within 3 σ total of the
    truth; each tire's kt within 5 % of the line the ideal channels give over the same three runs (the contact is
    nonlinear: the line depends on the load range, so it is the same runs' line, not truth.json's sine-only one).
    The roll inertia at the CoG is -5.8 % here, outside issue 24's 5 % (its σ total is 7 %, from the inclinometers'
    and lasers' offsets on these three tests): ZZ6, which carries it, is held within 3 σ total as every chassis
    estimate is. Measured: mass -0.07 %, CoG 0.0 and
    1.2 mm, pitch +0.4 %, yaw +1.7 % (+2.4 % before the band limits were undone in phase), springs <= 1.4 %,
    dampers <= 1.8 %, dry friction <= 3.8 %, bars <= 1.6 %, kt within 4.8 % of the line."""
    res, eng = noise_all
    ideal = {p["label"]: p["value"] for p in ideal_all[0]["parameters"]}
    values = {p["label"]: p for p in res["parameters"]}
    true = {p["label"]: p["value"] for p in truth["true_parameters"]}
    v = truth["vehicle"]
    assert eng["mass_total"] == pytest.approx(v["total_mass"]["value"], rel=0.005)
    x_g, _, z_g = v["chassis_com_frame6"]["value"]
    assert eng["cgs_ahead_rear"] == pytest.approx(z_g, abs=2.5e-3)
    assert eng["cgs_height"] == pytest.approx(x_g + v["geometry"]["wheel_radius"], abs=2.5e-3)
    assert eng["Iyy"] == pytest.approx(1900.0, rel=0.02)
    assert eng["Izz"] == pytest.approx(2100.0, rel=0.02)
    for corner in (9, 18, 27, 36):
        assert values[f"ks{corner}"]["value"] == pytest.approx(true[f"ks{corner}"], rel=0.03)
        assert values[f"h{corner}"]["value"] == pytest.approx(true[f"h{corner}"], rel=0.05)
        assert values[f"fs{corner}"]["value"] == pytest.approx(true[f"fs{corner}"], rel=0.10)
    for bar in ("karf", "karr"):
        assert values[bar]["value"] == pytest.approx(true[bar], rel=0.05)
    for tire in (15, 24, 33, 42):
        assert values[f"kt{tire}"]["value"] == pytest.approx(ideal[f"kt{tire}"], rel=0.05)
    for p in res["parameters"]:
        if p["truth"] is None or p["flag"] == "known" or p["name"] in TIRE_PARAMETERS:
            continue
        assert abs(p["value"] - p["truth"]) <= 3.0 * p["std_total"], p
