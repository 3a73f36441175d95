"""`dynid plan` (pipeline/plan.py, issue 29) and the manoeuvres it added to the simulator.

Oracles: a Monte-Carlo spread of weighted least squares (NumPy's lstsq, true weights) for the predicted σ total of
a combination of tests; closed forms for a repeated test's offsets; the simulator's requested values and an
existing manoeuvre (the step steer's steady angle) for the new manoeuvres; the identification itself, through the
files, over seeds (slow)."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from dynid.estimation import StreamingLS
from dynid.pipeline import plan as planner
from dynid.pipeline.config import ConfigError
from dynid.vehicle.sim import CarSimulator, ManoeuvreError


# ----------------------------------------------------------------------------------------- σ total of a combination
def _piece(rng: np.random.Generator, W: np.ndarray, groups: np.ndarray, x0: np.ndarray, noise: dict[str, float],
           offsets: dict[str, np.ndarray], test: str, reps: int = 1, drawn: float = 0.0) -> planner.Piece:
    """A test's Piece as `reduce_candidates` makes it: noise-free rows with the offsets' sums and their columns for
    the estimate, and one noisy draw (its rows `reps` times, each with its own noise: σ_g to 1 / sqrt(2 reps n_g));
    drawn: each offset of the noisy draw, in its σ (their residual inflates the weights, as a real test's do), and
    then a draw of the noise alone (`Piece.quiet`, the same reps)."""
    from dynid.estimation.offsets import OffsetFactors

    names = [f"x{i}" for i in range(W.shape[1])]
    Y = W @ x0
    ls = StreamingLS(names)
    ls.add(W, Y, groups)
    bias = ls.bias_accumulator()
    for source, dY in offsets.items():
        bias.add(f"{test}: {source}", W, Y, np.zeros_like(W), dY, groups)
    zeros = OffsetFactors(np.arange(W.shape[1]), np.zeros(0, dtype=int), np.zeros(0), x0)
    zeros.add(test, list(offsets), W, Y, [None] * len(offsets), list(offsets.values()), groups)
    noisy, quiet = StreamingLS(names), StreamingLS(names)
    for _ in range(reps):
        e = np.array([noise[g] for g in groups]) * rng.standard_normal(len(groups))
        noisy.add(W, Y + e + drawn * sum(offsets.values()), groups)
        quiet.add(W, Y + np.array([noise[g] for g in groups]) * rng.standard_normal(len(groups)), groups)
    return planner.Piece(ls, bias, (noisy,), zeros, quiet if drawn else None)


def _problem(rng: np.random.Generator, n: int = 600):
    W = np.column_stack([np.ones(n), rng.standard_normal(n), np.sin(np.linspace(0, 20, n))])
    groups = np.where(np.arange(n) % 3 == 0, "a", "b")
    noise = {"a": 0.5, "b": 2.0}
    # two sensors' offsets: one a constant on group a's rows, one proportional to the second column on b's
    offsets = {"zero": 0.3 * (groups == "a"), "gain": 0.2 * W[:, 1] * (groups == "b")}
    return W, groups, noise, offsets


def test_predicted_sigma_total_matches_the_spread_of_weighted_least_squares():
    """Two tests (the second run twice: a new zeroing and a new noise draw each time): the predicted σ total
    against the spread of 4000 weighted least-squares estimates (true weights, NumPy's lstsq) with fresh noise and
    fresh offsets per test. Tolerance: the spread's own error over 4000 draws (1.1 %) and the predicted σ's from
    one noisy draw per test (σ_g from ~200 rows: 5 %), with margin: 10 %."""
    rng = np.random.default_rng(29)
    x0 = np.array([1.0, -2.0, 0.5])
    tests = [_problem(rng), _problem(rng)]
    pieces = [_piece(rng, t[0], t[1], x0, t[2], t[3], f"t{i}") for i, t in enumerate(tests)]
    pred = planner.predict([pieces[0], pieces[1], pieces[1]], estimate=False)
    runs = [tests[0], tests[1], tests[1]]
    W = np.vstack([t[0] for t in runs])
    groups = np.concatenate([t[1] for t in runs])
    w = 1.0 / np.array([runs[0][2][g] for g in groups])
    draws = 4000
    Y = np.concatenate([(t[0] @ x0)[:, None] + np.array([t[2][g] for g in t[1]])[:, None]
                        * rng.standard_normal((len(t[1]), draws))
                        + sum(np.outer(dY, rng.standard_normal(draws)) for dY in t[3].values()) for t in runs])
    est = np.linalg.lstsq(W * w[:, None], Y * w[:, None], rcond=None)[0].T
    spread = np.std(est, axis=0, ddof=1)
    assert np.allclose(pred.x, x0, rtol=1e-9)
    assert np.all(np.abs(pred.std_total / spread - 1) < 0.10), (pred.std_total, spread)
    # both regimes: the offsets dominate the intercept, the noise the third parameter
    assert pred.std_sys[0] > 2 * pred.std_stat[0] and pred.std_stat[2] > 2 * pred.std_sys[2]


def test_predicted_sigma_total_with_the_offsets_estimated_matches_the_spread_of_their_estimate():
    """The identification's default: each test's offsets estimated with the parameters, their declared σ as the
    prior. Oracle: 4000 estimates by NumPy's lstsq of the stacked system [W C; 0 I] [x; u] = [Y; 0] (Theil and
    Goldberger's estimate written out: every test's, a repeat's own offset columns; true weights), with fresh noise
    and offsets per run; the noise's part (offsets held at zero) and the offsets' part (noise-free) apart, then
    together. The offsets' part hangs on the groups' relative weights (what group b's rows read of group a's
    offset): an 8 % error of σ_b moved it by 16 %, so the weights come from 25 noisy draws of each row (σ_g to 1 %,
    about 2 % on the offsets' part). Tolerance 10 %: that, and the spread over 4000 draws (1.1 %), with margin."""
    rng = np.random.default_rng(290)
    x0 = np.array([1.0, -2.0, 0.5])
    tests = [_problem(rng), _problem(rng)]
    pieces = [_piece(rng, t[0], t[1], x0, t[2], t[3], f"t{i}", reps=25) for i, t in enumerate(tests)]
    pred = planner.predict([pieces[0], pieces[1], pieces[1]])
    runs = [tests[0], tests[1], tests[1]]
    W = np.vstack([t[0] for t in runs])
    groups = np.concatenate([t[1] for t in runs])
    w = 1.0 / np.array([runs[0][2][g] for g in groups])
    C = np.zeros((len(W), 2 * len(runs)))  # each run's two offsets, one σ each
    first = 0
    for i, t in enumerate(runs):
        C[first:first + len(t[1]), 2 * i:2 * i + 2] = np.column_stack(list(t[3].values()))
        first += len(t[1])
    m = C.shape[1]
    A = np.block([[W * w[:, None], C * w[:, None]], [np.zeros((m, 3)), np.eye(m)]])
    draws = 4000
    noise = np.array([runs[0][2][g] for g in groups])[:, None] * rng.standard_normal((len(W), draws))
    u = rng.standard_normal((m, draws))
    spread = {}
    for part, Y in (("stat", noise), ("sys", C @ u), ("total", noise + C @ u)):
        Y = (W @ x0)[:, None] + Y
        est = np.linalg.lstsq(A, np.vstack([Y * w[:, None], np.zeros((m, draws))]), rcond=None)[0][:3].T
        spread[part] = np.std(est, axis=0, ddof=1)
    assert np.allclose(pred.x, x0, rtol=1e-9)
    assert np.all(np.abs(pred.std_stat / spread["stat"] - 1) < 0.10), (pred.std_stat, spread["stat"])
    assert np.all(np.abs(pred.std_sys / spread["sys"] - 1) < 0.10), (pred.std_sys, spread["sys"])
    assert np.all(np.abs(pred.std_total / spread["total"] - 1) < 0.10), (pred.std_total, spread["total"])
    # what the data pin of the offsets is no longer uncertainty: the intercept's offsets' part well below the
    # propagated one (the rows read the constant offset on group a)
    propagated = planner.predict([pieces[0], pieces[1], pieces[1]], estimate=False)
    assert pred.std_sys[0] < 0.8 * propagated.std_sys[0], (pred.std_sys, propagated.std_sys)


def test_the_spread_with_weights_the_offsets_inflate_is_the_estimators_sandwich():
    """A real test's weights (eq. (8)) come from residuals its offsets inflate; the identification keeps them, so the
    σ total it reports (s² A_r⁻¹) overstates what its estimates spread. Oracle: 4000 estimates by NumPy's lstsq of
    [W C; 0 I] [x; u] = [Y; 0] weighted with the prediction's own σ_g (the noisy draws' eq. (8), offsets of 5 σ in
    them), fresh noise (its true σ) and offsets per run: their spread against the predicted σ total (the sandwich,
    with the noise's σ from `Piece.quiet`). Tolerance: 1.1 % of the spread over 4000 draws, the noise's σ from 25
    draws of each row (1 %), with margin: 5 %; and the reported σ total is not the spread (21 to 23 % above it
    here, far beyond those errors)."""
    rng = np.random.default_rng(2929)
    x0 = np.array([1.0, -2.0, 0.5])
    tests = [_problem(rng), _problem(rng)]
    pieces = [_piece(rng, t[0], t[1], x0, t[2], t[3], f"t{i}", reps=25, drawn=5.0) for i, t in enumerate(tests)]
    pred = planner.predict([pieces[0], pieces[1]])
    sigmas = pieces[0].noisy[0].merge(pieces[1].noisy[0]).group_sigmas()
    W = np.vstack([t[0] for t in tests])
    groups = np.concatenate([t[1] for t in tests])
    w = 1.0 / np.array([sigmas[g] for g in groups])
    C = np.zeros((len(W), 4))
    C[:600, :2] = np.column_stack(list(tests[0][3].values()))
    C[600:, 2:] = np.column_stack(list(tests[1][3].values()))
    A = np.block([[W * w[:, None], C * w[:, None]], [np.zeros((4, 3)), np.eye(4)]])
    draws = 4000
    noise = np.array([tests[0][2][g] for g in groups])[:, None] * rng.standard_normal((len(W), draws))
    Y = (W @ x0)[:, None] + noise + C @ rng.standard_normal((4, draws))
    est = np.linalg.lstsq(A, np.vstack([Y * w[:, None], np.zeros((4, draws))]), rcond=None)[0][:3].T
    spread = np.std(est, axis=0, ddof=1)
    assert np.all(np.abs(pred.std_total / spread - 1) < 0.05), (pred.std_total, spread)
    reported = np.sqrt(np.diag(pred.reported))
    assert np.all(reported > 1.15 * spread), (reported, spread)


# estimate=True: 11 s of CPU (400 oracle draws through solve_with_offsets), so slow; the quick run keeps
# estimate=False (the same reported_draws against the same 400-draw oracle) and
# test_predicted_sigma_total_with_the_offsets_estimated_matches_the_spread_of_their_estimate (the offsets estimated)
@pytest.mark.parametrize("estimate", [pytest.param(True, marks=pytest.mark.slow), False])
def test_the_reported_sigma_over_draws_of_the_offsets_is_the_identifications(estimate):
    """What an identification reports moves with each seed's offsets (its weights, eq. (8), come from residuals they
    inflate). Oracle: 400 explicit draws of two tests' rows (fresh noise, fresh offsets of one σ each, 3 σ of them
    in the noisy draws the pieces keep), each weighted by the identification's own eq. (8) (`group_sigmas`), s²
    from NumPy's lstsq of the weighted rows, and its covariance by `solve_with_offsets` (estimate) or `propagate`
    (not): the 10 %, 50 % and 90 % quantiles of each σ against `reported_draws`' 400 draws. Tolerance: a quantile
    of 400 draws of a σ whose scatter is 3 to 13 % holds to about 1 % (its sd); two such apart, 1.4 %: 5 % is 3.5
    of them, and the scatter itself (CV above 8 % for the two parameters the offsets reach) is far larger."""
    from dynid.estimation.offsets import solve_with_offsets
    from dynid.estimation.systematic import propagate

    rng = np.random.default_rng(2930)
    x0 = np.array([1.0, -2.0, 0.5])
    tests = [_problem(rng), _problem(rng)]
    pieces = [_piece(rng, t[0], t[1], x0, t[2], t[3], f"t{i}", reps=25, drawn=3.0) for i, t in enumerate(tests)]
    names = ("x0", "x1", "x2")
    rep = planner.reported_draws(pieces, planner.Scorer(names, (), (), np.zeros((0, 3))), 400, estimate=estimate)
    acc, bias = pieces[0].zeros.merge(pieces[1].zeros), pieces[0].bias.merge(pieces[1].bias)
    got = []
    for _ in range(400):
        ls, rows = StreamingLS(list(names)), []
        for W, groups, noise, offsets in tests:
            Y = W @ x0 + np.array([noise[g] for g in groups]) * rng.standard_normal(len(groups)) + sum(
                rng.standard_normal() * dY for dY in offsets.values())
            ls.add(W, Y, groups)
            rows.append((W, Y, groups))
        sigmas = ls.group_sigmas()
        w = 1 / np.array([sigmas[g] for r in rows for g in r[2]])
        W, Y = np.vstack([r[0] for r in rows]) * w[:, None], np.concatenate([r[1] for r in rows]) * w
        e = Y - W @ np.linalg.lstsq(W, Y, rcond=None)[0]
        s2 = e @ e / (len(Y) - 3)
        if estimate:
            est = solve_with_offsets(acc, names, sigmas, sigma2=s2)
            cov = est.solution.covariance + est.systematic.covariance
        else:
            cov = s2 * np.linalg.inv(W.T @ W) + np.diag(propagate(W.T @ W, bias, x0, names, sigmas).std ** 2)
        got.append(np.sqrt(np.diag(cov)))
    got = np.array(got)
    for level in (0.1, 0.5, 0.9):
        ratio = np.quantile(rep.std, level, axis=0) / np.quantile(got, level, axis=0)
        assert np.all(np.abs(ratio - 1) < 0.05), (level, ratio)
    assert np.all((got.std(axis=0) / got.mean(axis=0))[1:] > 0.08)


def test_a_repeated_test_halves_the_variance_of_its_offsets():
    """Closed form: the same rows twice double A and each zeroing's shift halves; two independent shifts of half
    the size: variance 2 (1/2)² = 1/2 of one run's."""
    rng = np.random.default_rng(7)
    W, groups, noise, offsets = _problem(rng)
    piece = _piece(rng, W, groups, np.ones(3), noise, offsets, "t")
    once, twice = planner.predict([piece], estimate=False), planner.predict([piece, piece], estimate=False)
    # the weights σ_g of eq. (8) on the rows twice: 2 rss / (2 n - p) against rss / (n - p), a change of order p / n
    assert np.allclose(twice.std_sys, once.std_sys / math.sqrt(2), rtol=3 / 600)
    assert np.allclose(twice.std_stat, once.std_stat / math.sqrt(2), rtol=0.01)  # s² of the same rows: 1 + O(1/n)


def test_a_combination_that_cannot_identify_every_parameter_says_so():
    rng = np.random.default_rng(1)
    W, groups, noise, offsets = _problem(rng)
    W[:, 2] = 2 * W[:, 1]
    for estimate in (False, True):
        p = planner.predict([_piece(rng, W, groups, np.ones(3), noise, offsets, "t")], estimate=estimate)
        assert p.rank == 2 and np.all(np.isinf(p.std_total))


def test_search_finds_the_shortest_plan_and_drops_what_is_not_needed():
    """Three synthetic tests: the long one alone meets the target, the two short ones together too, in less time;
    a fourth test only adds time. Oracle: every plan of up to three tests, enumerated."""
    rng = np.random.default_rng(3)
    x0 = np.array([1.0, -2.0, 0.5])
    pieces, durations = {}, {}
    for key, n, dur in (("long", 2400, 30.0), ("short1", 900, 8.0), ("short2", 900, 8.0), ("idle", 50, 5.0)):
        W, groups, noise, offsets = _problem(rng, n)
        pieces[key], durations[key] = _piece(rng, W, groups, x0, noise, offsets, key), dur
    names = ("x0", "x1", "x2")
    score = planner.Scorer(names, (planner.Target("parameter", "x1", 1.0, ""),), (), np.zeros((0, 3)))

    def reported(plan, draws=planner.SEARCH_DRAWS):  # the search's draws
        return planner.reported_draws([pieces[k] for k in sorted(plan)], score, draws)  # the search's order

    limit = 1.02 * float(score.reported(reported(["short1", "short2"]))[0])
    score = planner.Scorer(names, (planner.Target("parameter", "x1", limit, ""),), (), np.zeros((0, 3)))
    plan, _ = planner.search(pieces, durations, score, repeats=1)
    import itertools

    feasible = [c for r in (1, 2, 3) for c in itertools.combinations(pieces, r)
                if score.shortfall(reported(c)) < planner.NEAR
                and score.shortfall(reported(c, planner.OFFSET_DRAWS)) == 0]
    assert feasible
    best = min(sum(durations[k] for k in c) for c in feasible)
    assert sum(durations[k] for k in plan) == best, (plan, feasible)
    # [limits] time: no plan of 10 s meets the target; the one returned keeps within it
    short, _ = planner.search(pieces, durations, score, repeats=1, max_seconds=10.0)
    assert sum(durations[k] for k in short) <= 10.0 and score.shortfall(reported(short)) > 0


def test_the_offsets_of_a_combination_as_the_identification_propagates_them():
    """Oracle: `estimation.systematic.propagate` (the identification's, one source at a time) on the tests' offset
    sums merged, a repeat's sources renamed (its own zeroing): the same covariance to round-off."""
    from dynid.estimation.systematic import propagate

    rng = np.random.default_rng(11)
    x0 = np.array([1.0, -2.0, 0.5])
    pieces = [_piece(rng, *_problem(rng)[:2], x0, *_problem(rng)[2:], f"t{i}") for i in range(2)]
    plan = [pieces[0], pieces[1], pieces[1]]
    pred = planner.predict(plan, estimate=False)
    sigmas = pieces[0].noisy[0].merge(pieces[1].noisy[0]).merge(pieces[1].noisy[0]).group_sigmas()
    merged = pieces[0].bias.merge(pieces[1].bias).merge(
        type(pieces[1].bias)(pieces[1].bias.columns, pieces[1].bias.known_columns, pieces[1].bias.known_values,
                             {f"{s} again": v for s, v in pieces[1].bias.terms.items()}))
    ls = pieces[0].ls.merge(pieces[1].ls).merge(pieces[1].ls)
    A = sum(ls.group_factor(g)[:3, :3].T @ ls.group_factor(g)[:3, :3] / sigmas[g] ** 2 for g in sigmas)
    ref = propagate(A, merged, pred.x, pred.names, sigmas)
    assert len(ref.shifts) == 6
    assert np.allclose(pred.std_sys, ref.std, rtol=1e-9)


# ----------------------------------------------------------------------------------------------------- targets
def test_targets_file(tmp_path):
    f = tmp_path / "t.toml"
    f.write_text("[targets]\nmoments = 1.5\ntires = false\n[targets.parameters]\nks27 = 2.0\n"
                 "[targets.quantities]\nIxx = 3.0\n[limits]\nspeed = 100\n", encoding="utf-8")
    spec = planner.load_targets(f)
    assert spec.categories["moments"] == 1.5 and spec.categories["tires"] is None
    assert spec.limits.speed == 100.0 and spec.limits.lateral_acceleration == planner.Limits().lateral_acceleration
    names = ["K27", "FS27", "K15", "XX6"]
    values = {"K27": 20000.0, "FS27": 30.0, "K15": 2e5, "XX6": 7000.0}
    quantities = {"Ixx": 600.0, "Iyy": 3000.0, "Izz": 3200.0}
    got = {t.key: t.limit for t in planner.targets_for(spec, names, values, quantities, {"K27": "ks27"})}
    assert got["K27"] == pytest.approx(400.0) and got["FS27"] == pytest.approx(3.0)
    assert "K15" not in got and "XX6" not in got  # tires off; the chassis is judged by its engineering figures
    assert got["Ixx"] == pytest.approx(18.0) and got["Iyy"] == pytest.approx(45.0)
    assert got["Ixz"] == pytest.approx(0.02 * 600.0) and got["cg_height"] == pytest.approx(0.0025)


@pytest.mark.parametrize("text, match", [
    ("[targets]\ncog = -1\n", "positive number"),
    ("[targets]\nroll = 2\n", "not a target"),
    ("[targets.quantities]\nIxxx = 2\n", "not an engineering quantity"),
    ("[limits]\nspeeed = 2\n", "unknown"),
    ("[target]\n", "unknown table"),
    ("[targets\n", "not valid TOML"),
])
def test_bad_targets_file(tmp_path, text, match):
    f = tmp_path / "t.toml"
    f.write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError, match=match):
        planner.load_targets(f)


def test_cli_refuses_a_bad_targets_file_before_simulating(tmp_path, capsys):
    from dynid.cli.main import main

    f = tmp_path / "t.toml"
    f.write_text("[targets]\ncog = 0\n", encoding="utf-8")
    assert main(["plan", "--targets", str(f), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cog = 0" in err and not (tmp_path / "out").exists(), err


# ----------------------------------------------------------------------------------------- the new manoeuvres
@pytest.fixture(scope="module")
def sim() -> CarSimulator:
    return CarSimulator()


def test_acceleration_reaches_its_rate_and_final_speed(sim):
    """Oracle: the requested values. The driver's PI follows a ramp with the force fed forward: the peak (2 Hz)
    within 10 % of the rate, the speed at the end within 1 km/h of the final speed."""
    r = sim.run("accel", duration=12.0)
    env = planner.envelope(r)
    assert env.longitudinal == pytest.approx(3.0, rel=0.10)
    assert 3.6 * np.hypot(*r.qd[-1, :2]) == pytest.approx(100.0, abs=1.0)
    with pytest.raises(ManoeuvreError, match="front tires' adhesion"):
        sim.run("accel", acceleration=6.5)
    with pytest.raises(ManoeuvreError, match="final_speed"):
        sim.run("accel", speed=80.0, final_speed=60.0)


def test_fishhook_and_random_steer_against_the_step_steers_angle(sim):
    """Oracle: the step steer's steady steering-wheel angle for the same lateral acceleration (an existing,
    tested manoeuvre): the fishhook holds +A then -A (the steering robot settles within 1 %); the random steer's
    RMS after its fade-in is A (Schroeder's multisine: RMS A by construction, over whole periods of its lowest
    line) and its power lies below its highest line."""
    A = sim.run("step", duration=8.0, lateral_acceleration=3.0).steering_wheel[-1, 0]
    fish = sim.run("fishhook", duration=8.0, lateral_acceleration=3.0).steering_wheel[:, 0]
    t = np.arange(fish.size) * sim.settings.dt
    up = t0 = 2.0
    t1 = A / math.radians(720.0)
    assert fish[np.searchsorted(t, up + t1 + 0.2)] == pytest.approx(A, rel=0.01)
    down = t0 + t1 + 0.25 + 2 * t1
    assert fish[np.searchsorted(t, down + 2.5)] == pytest.approx(-A, rel=0.01)
    rnd = sim.run("random", duration=23.0, lateral_acceleration=3.0, frequency=2.0, components=20).steering_wheel
    h = rnd[int(3.0 / sim.settings.dt):, 0][: int(10.0 / sim.settings.dt)]
    assert np.sqrt(np.mean(h**2)) == pytest.approx(A, rel=0.03)  # the robot's 8 Hz lag: below 1 % at 2 Hz
    spectrum = np.abs(np.fft.rfft(h)) ** 2
    f = np.fft.rfftfreq(h.size, sim.settings.dt)
    assert spectrum[f > 2.2].sum() < 1e-3 * spectrum.sum()


def test_a_table_replays_the_step_steer_and_brakes_at_its_demand(sim):
    """Oracle: the step steer (an existing manoeuvre) driven from its own steering-wheel target sampled every
    10 ms: the robot follows the same reference to the linear interpolation's error (h'' dt² / 8, about 1e-4 of
    the angle), so the lateral acceleration matches the step's to 1 % of its peak; and a demand of -4 m/s² from
    1.5 s: the speed target's slope, the brakes taking what the resistances do not (the 2 Hz peak within 5 %, the
    speed at the end within 1 km/h of the target)."""
    from dynid.vehicle.sim.kernel import smoothstep
    from dynid.vehicle.sim.manoeuvres import manoeuvre, pack, table_manoeuvre

    step = sim.run("step", duration=6.0)
    A, rise = pack(manoeuvre("step"), sim.car_constants())[3:5]
    t = np.arange(0.0, 6.0 + 1e-9, 0.01)
    h = np.array([A * smoothstep((x - 2.0) / rise) if x > 2.0 else 0.0 for x in t])
    table = sim.run(table_manoeuvre(0.01, h, np.zeros_like(h), 80.0))
    ay_step, ay_table = (planner.road_signals(r)[0] for r in (step, table))
    assert np.max(np.abs(ay_table - ay_step)) < 0.01 * np.max(np.abs(ay_step))
    a = np.where(t > 1.5, -4.0, 0.0)
    braking = sim.run(table_manoeuvre(0.01, np.zeros_like(t), a, 100.0))
    env = planner.envelope(braking)
    assert env.longitudinal == pytest.approx(4.0, rel=0.05) and env.lateral < 0.1
    assert 3.6 * np.hypot(*braking.qd[-1, :2]) == pytest.approx(100.0 - 3.6 * 4.0 * 4.5, abs=1.0)
    with pytest.raises(ManoeuvreError, match=r"10\.\.180 km/h"):
        table_manoeuvre(0.01, np.zeros_like(t), np.full(t.size, -6.0), 100.0)


def test_envelope_of_a_braking_is_its_deceleration(sim):
    """Oracle: the requested 6 m/s² plus the rolling resistance and drag at 100 km/h (about 0.4 m/s²)."""
    env = planner.envelope(sim.run("braking", duration=6.0))
    assert env.longitudinal == pytest.approx(6.4, rel=0.05)
    assert env.lateral < 0.1 and env.speed == pytest.approx(100.0, abs=0.5)


# ----------------------------------------------------------------------------------- the prediction, over seeds
SEEDS = 10
# the sample standard deviation of ten seeds scatters about the true one: s / σ ~ sqrt(χ²(9) / 9), 1 σ of about
# 24 %; its 99.9 % band (χ²(9) quantiles 1.97 and 29.67) bounds each parameter, and the 25 % bounds the
# RMS over the parameters (32 parameters: about 8 % of sampling error if they were independent)
BAND = (math.sqrt(1.97 / 9), math.sqrt(29.67 / 9))


VEHICLES = ("peugeot406", "compact_suv")  # the shipped vehicles (issue 29: both)


@pytest.fixture(scope="module")
def planned():
    """`plan_tests` once per vehicle for the whole module (the 406's plan serves both its fixtures)."""
    return functools.cache(planner.plan_tests)


@pytest.fixture(scope="module")
def plan406(planned):
    return planned("peugeot406")


@pytest.fixture(scope="module", params=VEHICLES)
def vehicle_plan(request, planned):
    """Each shipped vehicle's recommended plan (`dynid plan --vehicle NAME`, the default targets)."""
    return planned(request.param)


@pytest.fixture(scope="module")
def vehicle_seeds(vehicle_plan, tmp_path_factory):
    """The recommended plan driven ten times with the vehicle's sensor suite (each test its own draw of noise and
    zero offsets), each through `identify` as `dynid demo` does."""
    return planner.check_seeds(vehicle_plan, range(SEEDS), tmp_path_factory.mktemp("seeds"))


@pytest.mark.slow
def test_the_plan_predicts_the_spread_of_ten_seeds(vehicle_plan, vehicle_seeds):
    """Issue 29's honesty test, both shipped vehicles: the spread of the ten seeds' estimates against the predicted
    σ total, over the parameters (the RMS of their ratio; each parameter's band is the next test). Measured 27 Nov
    with the noise's part from four draws of it as it is (`NoiseScores`): the 406's 92 s plan median 0.97, RMS 0.98;
    the SUV's 24 s plan (sine 0.5 Hz at 120 km/h, braking from 80 km/h) median 0.90, RMS 1.00 (white per group
    before: RMS 1.14 and 1.23, most of the SUV's M6, MZ6, XY6, XX6; one draw: 0.95 and 1.04)."""
    ratio = vehicle_seeds.spread / vehicle_seeds.predicted
    print(vehicle_seeds.text(vehicle_plan.labels))
    assert abs(np.sqrt(np.mean(ratio**2)) - 1) < 0.25, vehicle_seeds.text(vehicle_plan.labels)


@pytest.mark.slow
def test_every_parameter_of_the_plan_within_the_spreads_band(vehicle_plan, vehicle_seeds):
    """Each parameter's spread over its predicted σ total inside the 99.9 % band of ten seeds' sample deviation
    (0.47 to 1.82). Measured 27 Nov: the 406's 92 s plan 0.55 (kt24) to 1.35 (ks18), ZZ6 0.61, MX6 0.66, M6 1.01;
    the SUV's 24 s plan 0.51 (off9; off36 0.52, MY6 0.53: the offsets' part, as before) to 1.54 (ks36), karf 1.48,
    M6 1.47, off27 1.47, MZ6 1.38, XY6 1.25.

    The noise's part of the prediction is the estimator's sandwich of the noise as it is (`NoiseScores`: four draws
    of the suite's noise without offsets, their rows less the noise-free rows, scored by the noise-free rows with each
    test's offsets profiled out, summed per time stamp over the groups, one row of lag: the rows at 12.5 /s
    oversample the 4 Hz conditioning band 1.56 x). White per group (σ_g per group, rows independent) it left the
    SUV's M6 at 2.32, MZ6 1.99, XY6 1.89, outside the band (the 406: 0.62 to 1.61). The cause (found by experiment,
    27 Nov: one sensor's noise at a time, offsets 0 but estimated, the rows' true noise through the estimator's
    linear map at fixed weights, 40 draws): no slow noise; every group's row noise is flat below 3 Hz and gone above
    5 Hz, so rows 0.08 s apart carry the low frequencies M6 is read at with 1.7 x the density of a white noise of
    the rows' variance, and one accelerometer axis is in several groups at once (ay: the x, yaw and roll rows,
    correlated ±1; ax: y and pitch): M6's noise part spreads 1.59 x the white per-group σ (MZ6 1.19, XY6 1.35,
    XX6 1.86), the group-summed sandwich of one draw 0.96 of it (10-90 %: 0.80-1.16). The ten seeds this test draws
    (1000 s + i) are the unlucky ten of those forty for the SUV (M6 2.26 x white; the other tens 1.55, 1.06, 1.20).
    One draw's prediction scatters (six other draws of the noise, 27 Nov, the 406's plan: 5 % median over the
    parameters, YY6 39 %, ZZ6 2.04-2.32 against the first draw's 2.95), hence the mean of four (ZZ6 2.62)."""
    ratio = vehicle_seeds.spread / vehicle_seeds.predicted
    assert np.all((ratio > BAND[0]) & (ratio < BAND[1])), vehicle_seeds.text(vehicle_plan.labels)


@pytest.mark.slow
def test_the_plan_predicts_the_sigma_total_the_identification_reports(vehicle_plan, vehicle_seeds):
    """Issue 29 item 1: the σ total the plan predicts the identification reports (the RMS over its 400 draws of the
    offsets) against the RMS over ten seeds of what each seed's identification reported. The seeds' side carries the
    seed-to-seed scatter of the reported σ (about 20 %: the weights come from residuals the offsets dominate) over 10
    seeds: about 7 % per parameter; over 32 parameters the RMS of the ratio within 25 % of 1, as the spread's test
    (measured 27 Nov: the 406's 92 s plan median 1.00, RMS 1.01, 0.94 to 1.10; the SUV's 24 s plan median 1.02, RMS
    1.02, 0.94 to 1.14)."""
    r = vehicle_seeds.reported_ratio
    assert abs(np.sqrt(np.mean(r**2)) - 1) < 0.25, vehicle_seeds.text(vehicle_plan.labels)


@pytest.mark.slow
def test_the_plan_meets_its_targets_in_nine_seeds_of_ten(vehicle_plan, vehicle_seeds):
    """Issue 29: the targets met (σ total the identification reports) in at least 9 of 10 seeds. The plan promises
    it (every target at once in a share LEVEL of its draws of the offsets: nine of ten or more in 95 % of campaigns);
    measured 27 Nov: the 406's 92 s plan (sine 0.5 Hz twice, 1 Hz twice, 0.3 Hz, braking from 80 km/h) met them in 10
    of 10, fs9 at most 0.88 x its bound, Iyy 0.91 x (the 40 s plan the 4 noisy files chose: 5 of 10, as its draws of
    the offsets say, 53 %); the SUV's 24 s plan in 10 of 10, Iyz at most 0.89 x, fs9 0.82 x."""
    assert vehicle_plan.met, vehicle_plan.text()
    assert int(vehicle_seeds.met.sum()) >= 9, vehicle_seeds.text(vehicle_plan.labels)


@pytest.mark.slow
def test_roll_inertia_as_the_binding_target_on_ten_seeds(tmp_path_factory, tmp_path):
    """Issue 29: a plan whose binding target is the roll inertia at the CoG (the other targets off) gives it within
    2 % of the simulator's truth on ten seeds (oracle: the truth set's Ixx, engineering.car_quantities). The target,
    0.6 %, puts 2 % at 3.3 σ: all ten seeds inside with 99 % probability."""
    from dynid.vehicle.description import load_vehicle
    from dynid.vehicle.engineering import car_quantities

    f = tmp_path / "roll.toml"
    f.write_text("[targets]\ncog = false\nmoments = false\nproducts = false\nsprings = false\ndampers = false\n"
                 "dry_friction = false\ntires = false\n[targets.quantities]\nIxx = 0.6\n", encoding="utf-8")
    plan = planner.plan_tests("peugeot406", planner.load_targets(f))
    assert plan.met
    check = planner.check_seeds(plan, range(SEEDS), tmp_path_factory.mktemp("roll"))
    v = load_vehicle("peugeot406")
    truth = car_quantities({**v.template().values, **v.truth.values}, v.geometry)["Ixx"]
    bench = v.template().with_values(v.known).values
    for x in check.estimates:
        values = {**bench, **dict(zip(check.names, x, strict=True))}
        assert abs(car_quantities(values, v.geometry)["Ixx"] / truth - 1) < 0.02


@pytest.mark.slow
def test_which_test_identifies_what_in_the_report_is_the_identification_without_it(tmp_path):
    """The report's table (run.without_test) against the identification re-run without that test (oracle: the
    whole pipeline again on fewer files): the same σ total, to the round-off of a different fold order."""
    import dataclasses

    from dynid.pipeline.config import load_config
    from dynid.pipeline.delays import DELAY_SOURCE
    from dynid.pipeline.demo import simulate_tests, write_demo
    from dynid.pipeline.run import identify

    cfg = load_config(write_demo(tmp_path, simulate_tests(quick=True)))
    run = identify(cfg)
    dropped = next(t for t in cfg.tests if t.role == "identify" and t.name.startswith("straight"))
    again = identify(dataclasses.replace(cfg, tests=tuple(t for t in cfg.tests if t is not dropped)))
    # the re-run's σ total without the channel delays' mismatch shift it may add (the table is noise and offsets)
    r = again.result
    offsets = [d for s, d in r.systematic.shifts.items() if not s.startswith(DELAY_SOURCE)]
    sys_std = dict(zip(r.systematic.names, np.sqrt(np.sum(np.square(offsets), axis=0)), strict=True))
    want = {n: math.hypot(s, sys_std[n]) for n, s in zip(r.names, r.std, strict=True)}
    got = run.without_test[dropped.name]
    assert set(run.without_test) == {t.name for t in cfg.tests if t.role == "identify"}
    for n, v in want.items():
        assert got[n] == pytest.approx(v, rel=1e-6), n


def test_campaign_level():
    """Oracle: scipy.stats' binomial: at the level, a campaign of 10 seeds meets the targets in 9 or more with
    probability 95 % (the bisection's 60 halvings: to 1e-15)."""
    from scipy.stats import binom

    p = planner.campaign_level(10, 9, 0.95)
    assert binom.sf(8, 10, p) == pytest.approx(0.95, abs=1e-12)
    assert p == pytest.approx(planner.LEVEL)


# ------------------------------------------------------------------------------------------ the optimised input
@pytest.fixture(scope="module")
def design406(plan406):
    from dynid.pipeline.plan_input import optimise_input

    return optimise_input(plan406, duration=20.0, designs=4)


@pytest.mark.slow
def test_the_optimised_input_respects_the_limits_on_a_grid_ten_times_denser(plan406, design406, tmp_path):
    """Issue 29: the steering-robot file read back and driven by dynid's simulator (the oracle: the car's truth,
    not the design's fit), its accelerations (2 Hz, as the limits read them) and speed checked every step / 10 s,
    its length over the run; the design held its peaks to 0.9 of the limits on its own grid only."""
    from dynid.pipeline.demo import simulated_car
    from dynid.pipeline.plan_input import plot_input, write_robot_file
    from dynid.vehicle.sim import table_manoeuvre

    path = write_robot_file(design406, tmp_path / "input.csv")
    t, h, a = np.loadtxt(path, delimiter=",", comments="#", skiprows=2).T
    step = float(t[1] - t[0])
    assert step == pytest.approx(design406.manoeuvre.params["step"])
    run = simulated_car("peugeot406").run(table_manoeuvre(step, np.radians(h), a,
                                                          design406.manoeuvre.params["speed"]))
    ay, ax, v, fs = planner.road_signals(run)
    dense = np.arange(0.0, t[-1] + 1e-9, step / 10)
    lim = plan406.spec.limits
    for what, x, bound in (("lateral", ay, lim.lateral_acceleration), ("longitudinal", ax,
                                                                      lim.longitudinal_acceleration),
                           ("speed", 3.6 * v, lim.speed)):
        on_grid = np.interp(dense, run.time, np.abs(x))
        assert on_grid.max() <= bound, (what, on_grid.max(), bound)
    assert np.sum(v) / fs <= lim.length
    # it excites both: the steering and the pedal reach most of their limits
    assert np.abs(ay).max() > 0.5 * lim.lateral_acceleration and np.abs(ax).max() > 0.5 * lim.longitudinal_acceleration
    assert plot_input(design406, lim, tmp_path / "input.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_the_optimised_input_lowers_the_binding_targets_sigma(plan406, design406):
    """Issue 29: with the plan's tests, the optimised input gives the binding target (the least margin) a smaller
    predicted σ total than any standard candidate of the same duration would."""
    from dynid.pipeline.plan_input import binding_target, sigma_with

    k = binding_target(plan406)
    same = [c.key for c in plan406.candidates.values() if c.duration == 20.0 and c.key in plan406.pieces]
    standard = {key: sigma_with(plan406, [plan406.pieces[key]], k) for key in same}
    assert len(same) >= 3 and design406.sigma < min(standard.values()), (plan406.score.targets[k].key,
                                                                          design406.sigma, standard)


def test_the_optimised_input_is_scored_with_the_tests_that_fit_beside_it():
    """Issue 29 item 4: under [limits] time, an input is scored with the plan's tests that fit beside it, taken in
    the plan's order while they fit; all of them without a limit (oracle: the sums by hand)."""
    from types import SimpleNamespace

    from dynid.pipeline.plan_input import fitting

    cands = {"a": SimpleNamespace(duration=20.0), "b": SimpleNamespace(duration=12.0),
             "c": SimpleNamespace(duration=4.0)}
    plan = SimpleNamespace(plan=["a", "b", "c"], candidates=cands,
                           spec=SimpleNamespace(limits=planner.Limits(time=45.0)))
    assert fitting(plan, 20.0) == ["a", "c"]  # 25 s left: a (20), not b (12 > 5), c (4)
    assert fitting(plan, 40.0) == ["c"]
    plan.spec = SimpleNamespace(limits=planner.Limits())
    assert fitting(plan, 20.0) == ["a", "b", "c"]
