"""Damper curves (issue 31, item 1): a piecewise-linear viscous law, four slopes about two knees, linear in the
slopes (model.tree's FVPL FVPH FVNL FVNH), in the engines, the vehicle file, the simulator and the identification.

Oracles: the curve written out by hand (its value at velocities on each piece, from the slopes alone); the closed
form of a mass on a vertical slide (m (qdd + g) + K q + FS sign(qd) + curve); the simulator's truth through the
files a user would feed (noise-free logger files, `dynid identify`'s pipeline), which the estimator never sees.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from dynid.dynamics import Model
from dynid.dynamics.newton_euler import joint_term_column
from dynid.model import Frame, Tree
from dynid.model.tree import ModelError
from dynid.vehicle.car_model import car_template
from dynid.vehicle.description import VehicleError, load_vehicle, vehicle_path
from dynid.vehicle.template import DAMPERS

SLOPES = {"FVPL": 2000.0, "FVPH": 900.0, "FVNL": 4100.0, "FVNH": 1700.0}
KNEES = (-0.15, 0.1)  # rebound knee at -0.15 m/s, bump knee at +0.1 m/s


def by_hand(v: float) -> float:
    """The curve from its slopes: continuous, zero at rest, slope FVPL up to the bump knee then FVPH, FVNL down to
    the rebound knee then FVNH."""
    lo, hi = KNEES
    if v >= 0:
        return SLOPES["FVPL"] * min(v, hi) + SLOPES["FVPH"] * max(v - hi, 0.0)
    return SLOPES["FVNL"] * max(v, lo) + SLOPES["FVNH"] * min(v - lo, 0.0)


VELOCITIES = np.array([-0.6, -0.15, -0.1, -1e-3, 0.0, 1e-3, 0.05, 0.1, 0.25, 1.2])


def test_columns_sum_to_the_curve_written_by_hand():
    """sum of slope x column = the curve at velocities on every piece and on the knees (the engine's columns)."""
    zero = np.zeros_like(VELOCITIES)
    total = sum(x * joint_term_column(t, zero, VELOCITIES, zero, knees=KNEES) for t, x in SLOPES.items())
    expected = np.array([by_hand(v) for v in VELOCITIES])
    assert np.allclose(total, expected, rtol=1e-14, atol=1e-12)
    # the slopes are the curve's: a finite difference on each piece
    for t, (a, b) in {"FVPL": (0.01, 0.05), "FVPH": (0.2, 0.4), "FVNL": (-0.1, -0.02), "FVNH": (-0.5, -0.3)}.items():
        assert (by_hand(b) - by_hand(a)) / (b - a) == pytest.approx(SLOPES[t], rel=1e-12)


def slide(knees=KNEES) -> Tree:
    """A 5 kg mass on a vertical prismatic joint with a spring, dry friction and the curve (one damper corner)."""
    terms = ("FS", "K", "FVPL", "FVPH", "FVNL", "FVNH")
    values = {"M1": 5.0, "K1": 20000.0, "FS1": 30.0, **{f"{t}1": x for t, x in SLOPES.items()}}
    return Tree("slide", (Frame(1, 0, 1),), {1: terms}, values=values, knees={1: knees})


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_inverse_dynamics_and_regressor_of_a_damped_slide(backend):
    """IDM = m (qdd + g) + K q + FS sign(qd) + curve(qd) and W X = IDM, in both engines."""
    tree = slide()
    m = Model(tree)
    N = VELOCITIES.size
    rng = np.random.default_rng(4)
    q, qdd = rng.normal(scale=0.05, size=(N, 1)), rng.normal(size=(N, 1))
    qd = VELOCITIES[:, None]
    tau = m.inverse_dynamics(q, qd, qdd, backend=backend)[:, 0]
    expected = (5.0 * (qdd[:, 0] + 9.81) + 20000.0 * q[:, 0] + 30.0 * np.sign(qd[:, 0])
                + np.array([by_hand(v) for v in VELOCITIES]))
    assert np.allclose(tau, expected, rtol=1e-13, atol=1e-10)
    W = m.regressor(q, qd, qdd, backend=backend)
    assert np.allclose(W[:, 0, :] @ tree.parameters, expected, rtol=1e-13, atol=1e-10)


def test_bad_knees_are_refused():
    with pytest.raises(ModelError, match="v- < 0 < v\\+"):
        slide((0.1, 0.2))
    with pytest.raises(ModelError, match="FVPH needs a finite knee v\\+"):
        slide((-0.1, math.inf))
    with pytest.raises(ModelError, match="two numbers"):
        slide((-0.1,))


# ----- the vehicle file ---------------------------------------------------------------------------------------------

TRUTH_SLOPES = {9: (2100, 1050, 4200, 2100), 18: (2200, 1100, 4400, 2200), 27: (1600, 800, 3200, 1600),
                36: (1900, 950, 3800, 1900)}
"""Bilinear dampers: rebound twice as stiff as bump, the slopes halve past the knees (a digressive valve); the
406's a priori h (4200 rear, 3200 front) sits between the low-speed bump and rebound slopes."""


def curve_vehicle(tmp_path, law: str = "curve", knees: str = "knee_bump_m_s = 0.1\nknee_rebound_m_s = 0.1",
                  truth: bool = True, extra_a_priori: str = "") -> str:
    """The shipped 406 with [dampers] and a bilinear curve per damper in [truth]."""
    text = vehicle_path("peugeot406").read_text()
    text = text.replace("[a_priori]", f'[dampers]\nlaw = "{law}"\n{knees}\n\n[a_priori]\n{extra_a_priori}', 1)
    if truth:
        rows = "\n".join(f"hbl{d} = {a}.0\nhbh{d} = {b}.0\nhrl{d} = {c}.0\nhrh{d} = {e}.0"
                         for d, (a, b, c, e) in TRUTH_SLOPES.items())
        text = text.replace("[known]", rows + "\n\n[known]", 1)
    path = tmp_path / "curve406.toml"
    path.write_text(text)
    return str(path)


def test_vehicle_file_curves(tmp_path):
    """The a priori curve starts from h (each slope = h), the truth's is its own, the knees are the file's."""
    v = load_vehicle(curve_vehicle(tmp_path))
    assert v.damper_law == "curve" and v.damper_knees == dict.fromkeys(DAMPERS, (-0.1, 0.1))
    tree = v.template()
    assert tree.knees == v.damper_knees and "FV9" not in tree.index
    assert [tree.values[f"{t}9"] for t in SLOPES] == [4200.0] * 4
    assert [tree.label(f"{t}27") for t in SLOPES] == ["hbl27", "hbh27", "hrl27", "hrh27"]
    assert [v.truth.values[f"{t}36"] for t in SLOPES] == [1900.0, 950.0, 3800.0, 1900.0]
    assert "FV36" not in v.truth.values
    # the linear law identifies h, the simulator still drives the truth's curves
    lin = load_vehicle(curve_vehicle(tmp_path, law="linear"))
    assert "FV9" in lin.template().index and lin.truth.values["FVPL9"] == 2100.0
    # an axle's own knees; no knee on one side: one slope there
    v = load_vehicle(curve_vehicle(tmp_path, knees='knee_bump_m_s = 0.1\nknee_rebound_m_s = "inf"\n'
                                   '[dampers.front]\nknee_bump_m_s = 0.2', truth=False))
    assert v.damper_knees[9] == (-math.inf, 0.1) and v.damper_knees[27] == (-math.inf, 0.2)
    assert "FVNH9" not in v.template().index and "FVPH9" in v.template().index


@pytest.mark.parametrize("law, knees, extra, message", [
    ("valved", "", "", "law = 'valved'; give one of linear, curve"),
    ("curve", "knee_bump_m_s = 0.1", "", "rear dampers have knee_bump_m_s but no knee_rebound_m_s"),
    ("curve", "knee_bump_m_s = 100\nknee_rebound_m_s = 0.1", "", "knee_bump_m_s = 100 m/s is outside"),
    ("curve", "knee_bump_m_s = -0.1\nknee_rebound_m_s = 0.1", "", "a number > 0"),
    ("linear", "", "hbl9 = 3000.0", "hbl9 is a damper curve's slope, but \\[dampers\\] law"),
    ("curve", "knee_bump_m_s = 0.1\nknee_rebound_m_s = 0.1", "hbl9 = -3.0", "hbl9 = -3.0 is outside|>= 0"),
])
def test_bad_damper_sections_are_refused(tmp_path, law, knees, extra, message):
    with pytest.raises(VehicleError, match=message):
        load_vehicle(curve_vehicle(tmp_path, law=law, knees=knees, truth=False, extra_a_priori=extra))


def test_truth_curve_needs_knees(tmp_path):
    with pytest.raises(VehicleError, match="hbl9 is a damper curve's slope: give its knees"):
        load_vehicle(curve_vehicle(tmp_path, law="linear", knees=""))


def test_constant_dampers_stay_the_default():
    """Without [dampers] the tree is today's: h on every damper, no knees, the same parameter names."""
    v = load_vehicle("peugeot406")
    assert v.damper_law == "linear" and v.damper_knees == {}
    tree = v.template()
    assert not tree.knees and all(f"FV{d}" in tree.index and f"FVPL{d}" not in tree.index for d in DAMPERS)
    assert tree.parameter_names == car_template(tire_offsets=False).parameter_names


# ----- the simulated car through its files ---------------------------------------------------------------------------

@pytest.mark.slow
@pytest.mark.e2e
def test_bilinear_dampers_from_noise_free_files(tmp_path):
    """The simulator drives bilinear dampers (knees at 0.1 m/s, rebound slopes twice the bump ones); the demo's
    tests as noise-free logger files through the identification: every slope within 2 % (measured: 0.5 %), the
    knees the file's, the other parameters within 1 % (dry friction 5 %). The conditioning's cutoff is 8 Hz, not
    the demo's 4: a low-pass at 4 Hz rounds the clearance rate's peaks past the knees, which biased the high-speed
    slopes by up to 6 % (docs/vehicle.md, 'Damper curves')."""
    from test_car_truth import judged

    from dynid.pipeline.config import load_config
    from dynid.pipeline.demo import simulate_tests, write_demo
    from dynid.pipeline.run import identify

    vehicle = curve_vehicle(tmp_path)
    config = write_demo(tmp_path, simulate_tests(vehicle=vehicle), noise=False, vehicle=vehicle)
    text = config.read_text()
    assert "cutoff = 4.0" in text
    config.write_text(text.replace("cutoff = 4.0", "cutoff = 8.0"))
    sidecar = json.loads((tmp_path / "data" / "sine.json").read_text())
    assert sidecar["damper_knees"] == {str(d): [-0.1, 0.1] for d in DAMPERS}
    run = identify(load_config(config))
    errors = {n: e for n, (e, *_rest) in judged(run.result).items()}
    slopes = [f"{t}{d}" for d in DAMPERS for t in SLOPES]
    assert set(slopes) <= set(errors)
    bad = {n: f"{100 * errors[n]:+.2f} %" for n in slopes if abs(errors[n]) > 0.02}
    assert not bad, bad
    others = {n: f"{100 * e:+.2f} %" for n, e in errors.items()
              if n not in slopes and abs(e) > (0.05 if n.startswith("FS") else 0.01)}
    assert not others, others
    # σ per slope: the slopes are parameters of the result, with their standard deviations
    std = dict(zip(run.result.names, run.result.std, strict=True))
    assert all(0 < std[n] < 0.02 * run.result.truth[n] for n in slopes)
    # the report's section: per damper its four slopes with the truth, and the figure
    from dynid.report.build import damper_section

    section, png = damper_section(run)
    assert [len(t.rows) for t in section.tables] == [4] * 4 and png[:8] == b"\x89PNG\r\n\x1a\n"
    assert section.tables[0].rows[1][0].text == "hbh9 (bump, high speed)"


class _Result:
    """A result's names, values and covariance (what vehicle.dampers reads)."""

    def __init__(self, values: dict[str, float], cov: np.ndarray) -> None:
        self.names = tuple(values)
        self.values = np.array(list(values.values()))
        self.full_covariance = cov


def test_curve_band_against_its_closed_form():
    """Force = the curve by hand; σ at a velocity past the bump knee = sqrt(vb² σ_bl² + (v - vb)² σ_bh²
    + 2 vb (v - vb) cov(bl, bh)), on one piece |v| σ; the slopes with their σ and ranges."""
    from dynid.vehicle.dampers import damper_curve, damper_slopes

    values = {"K9": 2e4, **{f"{t}9": x for t, x in SLOPES.items()}}
    sd = np.array([100.0, 20.0, 30.0, 40.0, 50.0])
    corr = np.eye(5)
    corr[1, 2] = corr[2, 1] = -0.6
    result = _Result(values, corr * np.outer(sd, sd))
    force, sigma = damper_curve(result, 9, VELOCITIES, KNEES)
    assert np.allclose(force, [by_hand(v) for v in VELOCITIES], rtol=1e-14, atol=1e-12)
    vb, v = KNEES[1], VELOCITIES[-1]
    expected = math.sqrt(vb**2 * 20.0**2 + (v - vb) ** 2 * 30.0**2 + 2 * vb * (v - vb) * (-0.6 * 20.0 * 30.0))
    assert sigma[-1] == pytest.approx(expected, rel=1e-12)
    assert sigma[6] == pytest.approx(0.05 * 20.0, rel=1e-12) and sigma[4] == 0.0
    slopes = damper_slopes(result, 9, KNEES)
    assert [(s.label, s.value, s.std) for s in slopes] == [
        ("hbl9", 2000.0, 20.0), ("hbh9", 900.0, 30.0), ("hrl9", 4100.0, 40.0), ("hrh9", 1700.0, 50.0)]
    assert slopes[1].range == (0.1, math.inf) and slopes[1].meaning == "bump, high speed"
    with pytest.raises(KeyError, match="no viscous term of damper 18"):
        damper_curve(result, 18, VELOCITIES)


def test_instruments_simulate_the_curve(tmp_path):
    """IDIM-IV's suspensions (vehicle.instruments) driven by the loads of a simulated car with bilinear dampers, with
    the true parameters, give its clearances and rates back (as test_vehicle_instruments does for h), on a 1 Hz
    sine steer whose rates pass the knees (0.1 m/s) in a quarter of the samples; with h in place of the curve they
    do not (the oracle discriminates)."""
    from dynid.vehicle.instruments import suspension_loads, suspension_response
    from dynid.vehicle.sim import CarSimulator

    v = load_vehicle(curve_vehicle(tmp_path))
    run = CarSimulator(v.truth, v.geometry, v.tables, v.aero, damper_knees=v.damper_knees).run(
        "sine", duration=5.0, frequency=1.0, lateral_acceleration=5.0)
    cols = np.array(DAMPERS) - 1
    assert np.mean(np.abs(run.qd[:, cols]) > 0.1) > 0.1
    eq = run.identification(spin=False)
    values = dict(run.tree.values)
    load = suspension_loads(run.tree, eq, values, run.qdd)
    q, qd, _ = suspension_response(run.tree, values, run.time, load, run.time, run.q[0, cols], run.qd[0, cols])
    np.testing.assert_allclose(q, run.q[:, cols], atol=1e-6)
    np.testing.assert_allclose(qd, run.qd[:, cols], atol=2e-4)  # 0.2 mm/s against 180 mm/s
    linear = car_template(v.geometry, {n: x for n, x in values.items() if not n.startswith(("FVP", "FVN"))
                                       and not n.startswith(tuple(f"FV{t}" for t in (15, 24, 33, 42)))})
    h = {**{n: x for n, x in values.items() if n in linear.index}, **{f"FV{d}": 3000.0 for d in DAMPERS}}
    q_h, _, _ = suspension_response(linear, h, run.time, load, run.time, run.q[0, cols], run.qd[0, cols])
    assert np.abs(q_h - run.q[:, cols]).max() > 1e-4


def test_sheet_damping_ratio_of_a_curve(tmp_path):
    """The engineer's sheet: a damper curve's ride damping ratio is that of h = (hbl + hrl) / 2 (its small-amplitude
    linear equivalent), the same car with that h giving the same figure."""
    from dynid.vehicle.engineering import car_quantities

    v = load_vehicle(curve_vehicle(tmp_path))
    curve = dict(v.truth.values)
    linear = {n: x for n, x in curve.items() if not n.startswith(("FVP", "FVN"))}
    linear.update({f"FV{d}": 0.5 * (a + c) for d, (a, _, c, _) in TRUTH_SLOPES.items()})
    for key in ("damping_ratio_front", "damping_ratio_rear"):
        assert car_quantities(curve, v.geometry)[key] == pytest.approx(car_quantities(linear, v.geometry)[key],
                                                                       rel=1e-12)
        assert car_quantities(curve, v.geometry)[key] > 0.1


# ----- knees from the data (issue 31: "knee velocities chosen by the user or from the data's velocity range") -------

def test_knee_search_finds_the_knees_of_a_synthetic_damper():
    """KneeSearch on rows written by hand: Y = K q + off + the curve of knees (-0.135, 0.087) + fs sign(q') + noise,
    the linear law's columns (q, q', sign, 1) as W; the knees come back within 1 % (the grid is 4 % apart and
    neither knee is within 1 % of a grid point: the parabola's refinement brings them there), the rows added in
    three chunks merged."""
    from dynid.vehicle.dampers import KNEE_GRID, KneeSearch

    rng = np.random.default_rng(7)
    N = 6000
    lo, hi = -0.135, 0.087
    assert all(np.min(np.abs(np.log(KNEE_GRID / k))) > 0.01 for k in (hi, -lo))
    qd = 0.12 * rng.standard_normal(N)
    q = 0.02 * rng.standard_normal(N)
    curve = np.array([2000 * min(v, hi) + 900 * max(v - hi, 0) if v >= 0 else 4100 * max(v, lo) + 1700 * min(v - lo, 0)
                      for v in qd])
    Y = 22000 * q + 300.0 + curve + 40 * np.sign(qd) + rng.normal(scale=5.0, size=N)
    W = np.column_stack([q, qd, np.sign(qd), np.ones(N)])
    parts = []
    for rows in np.array_split(np.arange(N), 3):
        s = KneeSearch()
        s.add(9, W[rows], Y[rows], s.hinges(qd[rows]), qd[rows])
        parts.append(s)
    found = parts[0].merge(parts[1]).merge(parts[2]).knees()[9]
    assert found[0] == pytest.approx(lo, rel=0.01) and found[1] == pytest.approx(hi, rel=0.01), found


def test_vehicle_without_knees_takes_them_from_the_data(tmp_path):
    """law = "curve" without knees: those dampers are the search's (knees_from_data), with h until then; with_knees
    gives the curve the knees and the a priori slopes h (an "inf" side: no high-speed slope)."""
    v = load_vehicle(curve_vehicle(tmp_path, knees="", truth=False))
    assert v.knees_from_data == DAMPERS and v.damper_knees == {}
    tree = v.template()
    assert "FV9" in tree.index and "FVPL9" not in tree.index and not tree.knees
    chosen = v.with_knees({d: (-0.12, 0.09) for d in DAMPERS[:3]} | {36: (-math.inf, 0.2)})
    assert chosen.knees_from_data == () and chosen.damper_knees[36] == (-math.inf, 0.2)
    tree = chosen.template()
    assert tree.knees[9] == (-0.12, 0.09)
    assert [tree.values[f"{t}9"] for t in SLOPES] == [4200.0] * 4
    assert "FVNH36" not in tree.index and tree.values["FVPH36"] == 3200.0
    # the front axle's knees given, the rear's from the data
    v = load_vehicle(curve_vehicle(tmp_path, knees="[dampers.front]\nknee_bump_m_s = 0.1\nknee_rebound_m_s = 0.2",
                                   truth=False))
    assert v.knees_from_data == (9, 18) and v.damper_knees[27] == (-0.2, 0.1)
    with pytest.raises(VehicleError, match="damper 27's knees are the file's"):
        v.with_knees({27: (-0.1, 0.1)})


@pytest.mark.slow
@pytest.mark.e2e
def test_knees_from_noise_free_files(tmp_path):
    """The simulator's bilinear dampers (knees at 0.1 m/s); the demo's tests and a 1 Hz sine steer (which moves the
    dampers past the knees in a quarter of its samples: the demo's tests alone put 2-9 rows of a side past them)
    as noise-free logger files, identified with a vehicle file that gives no knee: every chosen knee within 1 % of
    0.1 m/s (measured 0.02-0.5 %), every slope within 2 % of the truth (measured 1.6 %), the results' note and
    results.json name the knees. Cutoff 10 Hz."""
    from test_car_truth import judged

    from dynid.pipeline.config import load_config
    from dynid.pipeline.demo import simulate_tests, simulated_car, write_demo
    from dynid.pipeline.run import identify
    from dynid.vehicle.sim.recording import write_test

    vehicle = curve_vehicle(tmp_path)
    results = simulate_tests(vehicle=vehicle)
    sine = simulated_car(vehicle).run("sine", duration=20.0, frequency=1.0, lateral_acceleration=5.0)
    config = write_demo(tmp_path, results, noise=False, vehicle=vehicle)
    write_test(sine, tmp_path / "data" / "sine1hz.csv", noise=False, suite=load_vehicle(vehicle).suite)
    (tmp_path / "auto").mkdir()
    auto = curve_vehicle(tmp_path / "auto", knees="", truth=False)  # the truth's curves come from the sidecar
    text = config.read_text().replace("cutoff = 4.0", "cutoff = 10.0").replace(
        json.dumps(str(Path(vehicle).resolve().as_posix())), json.dumps(str(Path(auto).resolve().as_posix())))
    assert auto in text
    config.write_text(text + '\n[[tests]]\nname = "sine 1 Hz"\nrole = "identify"\nfile = "data/sine1hz.csv"\n')
    run = identify(load_config(config))
    knees = {d: (lo, hi) for d, lo, hi in run.config.car.knees}
    assert set(knees) == set(DAMPERS) and run.model.tree.knees == knees
    off = {d: k for d, k in knees.items() if not (abs(k[0] + 0.1) < 1e-3 and abs(k[1] - 0.1) < 1e-3)}
    assert not off, off
    errors = {n: e for n, (e, *_rest) in judged(run.result).items()}
    slopes = [f"{t}{d}" for d in DAMPERS for t in SLOPES]
    bad = {n: f"{100 * errors[n]:+.2f} %" for n in slopes if abs(errors[n]) > 0.02}
    assert not bad, bad
    assert "Damper knees chosen from the data" in run.notes
    from dynid.pipeline.run import write_outputs

    write_outputs(run, tmp_path / "out", "knees from the data")
    data = json.loads((tmp_path / "out" / "results.json").read_text())
    assert data["damper_knees_from_data"] == list(DAMPERS)
    assert data["damper_knees"] == {str(d): list(k) for d, k in knees.items()}


# ----- the sensor suite, ten seeds -----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def curve_seeds(tmp_path_factory):
    """The bilinear dampers' car through the demo's tests and a 1 Hz sine steer (its own seed: 100 + seed), the
    sensor suite's noise and zero offsets, cutoff 6 Hz (docs/vehicle.md's advice for curves with WLS), WLS:
    {seed: {slope: (error / truth, σ total / truth)}}."""
    from test_car_truth import SEEDS, judged

    from dynid.pipeline.config import load_config
    from dynid.pipeline.demo import simulate_tests, simulated_car, write_demo
    from dynid.pipeline.run import identify
    from dynid.vehicle.sim.recording import write_test

    root = tmp_path_factory.mktemp("curves")
    vehicle = curve_vehicle(root)
    results = simulate_tests(vehicle=vehicle)
    sine = simulated_car(vehicle).run("sine", duration=20.0, frequency=1.0, lateral_acceleration=5.0)
    suite = load_vehicle(vehicle).suite
    out = {}
    for seed in SEEDS:
        folder = root / f"seed{seed}"
        config = write_demo(folder, results, seed=seed, fmt="parquet", vehicle=vehicle)
        write_test(sine, folder / "data" / "sine1hz.parquet", seed=seed + 100, noise=True, suite=suite)
        text = config.read_text().replace("cutoff = 4.0", "cutoff = 6.0")
        config.write_text(text + '\n[[tests]]\nname = "sine 1 Hz"\nrole = "identify"\nfile = "data/sine1hz.parquet"\n')
        judged_ = judged(identify(load_config(config)).result)
        out[seed] = {n: judged_[n][:2] for n in judged_ if n.startswith(tuple(SLOPES))}
    return out


@pytest.mark.slow
@pytest.mark.e2e
def test_ten_seeds_slopes_and_their_sigma(curve_seeds):
    """With the sensor suite (noise and per-test zero offsets), ten seeds: every slope, low and high speed, within
    10 % of the truth in at least 9 of 10 (issue 31; measured 10 of 10, the largest error 6.5 %, FVPH36) and the
    low-speed ones without the rate noise's bias: their mean error over the seeds within 3 % (measured 1.7 % at
    most; three standard errors of a mean of ten with the largest spread, 2.8 %; at 10 Hz the noise biased them up
    to 4.3 %); every slope's σ total honest: the RMS of (estimate - truth) / σ total over the seeds within 0.5-2
    (measured 0.53-1.49). The high-speed slopes missed 10 % in up to 7 of 10 seeds before the wheel forces' zero
    offsets (10 N, drawn anew at each test's zeroing) were estimated (estimation/offsets.py, the default)."""
    seeds = list(curve_seeds)
    names = list(curve_seeds[seeds[0]])
    assert len(names) == 16
    low = [n for n in names if n.startswith(("FVPL", "FVNL"))]
    misses = {n: [s for s in seeds if abs(curve_seeds[s][n][0]) > 0.10] for n in names}
    assert all(len(m) <= 1 for m in misses.values()), misses
    mean = {n: float(np.mean([curve_seeds[s][n][0] for s in seeds])) for n in low}
    biased = {n: f"{100 * m:+.1f} %" for n, m in mean.items() if abs(m) > 0.03}
    assert not biased, biased
    rms = {n: float(np.sqrt(np.mean([(curve_seeds[s][n][0] / curve_seeds[s][n][1]) ** 2 for s in seeds])))
           for n in names}
    off = {n: round(r, 2) for n, r in rms.items() if not 0.5 <= r <= 2.0}
    assert not off, off
