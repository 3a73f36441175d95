"""Physically consistent WLS (method "wls-pc") and the robot's physical-consistency verdict.

Oracles: an independent formulation of the same semidefinite program (the whole weighted data rather than
the WLS covariance, a PSD matrix variable per body tied to the parameters entry by entry, scaled variables);
closed forms on synthetic data (an estimate already consistent is returned unchanged; a mass pushed negative
lands on its bound with the other parameters at the least-squares solution given that bound, and the KKT
sign condition holds), and SCS, a first-order solver, on that small case.

Tolerances. Every comparison is in the WLS's own metric: for a quadratic objective f on a convex set with
minimiser b*, f(b) - f(b*) >= ||L (b - b*)||² (C_w⁻¹ = LᵀL), and |Δb_k| <= σ_k ||L Δb||, so a solve whose
objective is within δ of the optimum is within sqrt(δ) standard deviations on every parameter. Clarabel's
relative gap tolerance 1e-8 on the TX40's weighted residual (||P r||² ≈ 2400 at s_w ≈ 1.08) gives δ <= 3e-5,
i.e. 6e-3 σ per solve: two solves agree within 1e-2 σ.
"""

from __future__ import annotations

import dataclasses
import json
import types
from pathlib import Path

import numpy as np
import pytest

cp = pytest.importorskip("cvxpy", reason="the pc extra (pip install cvxpy clarabel) is not installed")

from dynid import load_model  # noqa: E402
from dynid.estimation import IdentificationError, Method, wls  # noqa: E402
from dynid.estimation.physical import MARGIN, pseudo_inertia, require_cvxpy, wls_pc  # noqa: E402
from dynid.model import check_physical  # noqa: E402
from dynid.model.consistency import check_joint_terms  # noqa: E402
from dynid.model.tree import Frame, Tree  # noqa: E402
from dynid.pipeline.config import load_config  # noqa: E402
from dynid.pipeline.run import consistency_structure, identify, robot_consistency, write_outputs  # noqa: E402

CONFIG = Path(__file__).resolve().parents[2] / "examples" / "tx40" / "identify.toml"
AGREE_SIGMA = 1e-2  # see the module doc


# ------------------------------------------------------------------------------------------ the TX40, real data
@pytest.fixture(scope="module")
def tx40(tx40_data):
    cfg = load_config(CONFIG)
    return identify(dataclasses.replace(cfg, method="wls-pc")), identify(cfg)


@pytest.mark.slow
def test_tx40_every_body_is_realisable_and_the_fit_barely_worsens(tx40, tmp_path):
    pc, plain = tx40
    fit = pc.consistency["wls_pc"]
    std = fit["standard_parameters"]
    bodies = sorted(consistency_structure(pc.model.tree, pc.base).bodies)
    assert bodies == [1, 2, 3, 4, 5, 6]
    assert check_physical(std, frames=bodies) == []
    couplings = {c.name: c.kind for c in pc.model.tree.couplings}
    assert check_joint_terms(std, couplings) == []
    # the reported set is the second solve's (closest to the model file's values), which meets the margin to
    # Clarabel's tolerance: 1e-8 relative on pseudo-inertias of ~1 (measured 0.995 MARGIN at worst)
    assert min(fit["pseudo_inertia_min_eigenvalue"].values()) >= 0.99 * MARGIN
    assert pc.consistency["realisable"] is True
    # the WLS estimate of these data is not realisable (largest margin about -7e-3, body 3's triangle inequality)
    assert plain.consistency["realisable"] is False and plain.consistency["violations"]
    # measured: 5.139 % against 5.136 % (+0.07 %): within 1 %
    assert fit["relative_residual_wls"] == pytest.approx(plain.result.residual.relative_residual, rel=1e-12)
    assert 0.0 <= fit["fit_worsening_percent"] < 1.0
    # the base estimate is K s*, and the report and results.json carry the verdict
    sv = np.array([std[n] for n in pc.model.tree.parameter_names])
    # the reported standard set moves from the first solve's along a computed basis N of K's null space (SVD:
    # K N = O(eps cond(K)) per unit step), so K s is the estimate to that times the step, |step| <= |s|:
    # measured 7e-10 for a 600 kg.m step (M2, which no base parameter contains), i.e. 1.1e-12 per unit
    assert np.max(np.abs(pc.base.values(sv) - pc.result.values)) <= 1e-10 * np.abs(sv).max()
    write_outputs(pc, tmp_path, "TX40 wls-pc")
    data = json.loads((tmp_path / "results.json").read_text())
    assert data["method"] == "WLS-PC" and data["consistency"]["realisable"] is True
    assert data["consistency"]["wls_pc"]["active_constraints"]
    assert "Physical consistency" in (tmp_path / "report.html").read_text()
    assert "physically realisable" in pc.summary() and "fit +" in pc.summary()


def _independent(W, Y, groups, names, structure, sigmas, margin, known=None, solver="CLARABEL", **opts):
    """The same program written another way: min ||P (Y - W K s)||² over the whole weighted data, a PSD
    variable per body equal to its pseudo-inertia entry by entry, variables scaled by the columns' norms."""
    row = np.array([1.0 / sigmas[g] for g in groups])
    A, y = W * row[:, None], Y * row
    AK = A @ structure.base_map
    norm = np.linalg.norm(AK, axis=0)
    d = np.where(norm > 0, 1.0 / np.where(norm > 0, norm, 1.0), 1.0)
    u = cp.Variable(AK.shape[1])
    s = cp.multiply(d, u)
    cons = []
    for idx in structure.bodies.values():
        XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M = (s[i] for i in idx)
        P = cp.Variable((4, 4), PSD=True)
        cons += [P[0, 0] == (YY + ZZ - XX) / 2 - margin, P[1, 1] == (XX + ZZ - YY) / 2 - margin,
                 P[2, 2] == (XX + YY - ZZ) / 2 - margin, P[0, 1] == -XY, P[0, 2] == -XZ, P[1, 2] == -YZ,
                 P[0, 3] == MX, P[1, 3] == MY, P[2, 3] == MZ, P[3, 3] == M - margin]
    cons.append(u[list(structure.nonnegative)] >= 0)
    for n, v in (known or {}).items():
        cons.append(structure.base_map[list(names).index(n)] @ s == v)
    cp.Problem(cp.Minimize(cp.sum_squares((AK * d) @ u - y)), cons).solve(solver=solver, **opts)
    return structure.base_map @ (d * u.value)


@pytest.mark.slow
def test_tx40_agrees_with_an_independent_formulation(tx40):
    pc, _ = tx40
    structure = consistency_structure(pc.model.tree, pc.base)
    sys = pc.identify
    b = _independent(sys.W, sys.Y, sys.groups, pc.base.names, structure, pc.result.weights, MARGIN)
    # measured: within 1.1e-4 σ of wls-pc on every base parameter
    assert np.max(np.abs(b - pc.result.values) / pc.result.std) < AGREE_SIGMA


# ------------------------------------------------------------------------------------------ synthetic closed forms
def _simulated(tree: Tree, X: np.ndarray, noise: float, seed: int = 1, samples: int = 400):
    """Base regressor rows at random states, per joint group, and Y = W X_base + noise (relative to Y's rms)."""
    from dynid.dynamics import Model
    from dynid.dynamics.base import random_states

    model = Model(tree)
    base = model.base_parameters()
    q, qd, qdd = random_states(tree, samples, seed)
    qd = qd + 0.5  # mostly moving forward: Coulomb friction's column is then not orthogonal to gravity's
    W = np.asarray(model.regressor(q, qd, qdd, cols=list(base.columns)))  # (N, n, q)
    xb = base.values(X)
    n = tree.n
    Wr = W.transpose(1, 0, 2).reshape(-1, base.rank)
    rng = np.random.default_rng(seed)
    Y = Wr @ xb
    Y = Y + noise * np.sqrt(np.mean(Y**2)) * rng.normal(size=Y.size)
    groups = np.repeat([f"joint{j}" for j in range(1, n + 1)], samples)
    return model, base, Wr, Y, groups


def test_a_consistent_wls_estimate_is_returned_unchanged():
    model = load_model("tx40")
    tree = model.tree.with_values({"M1": 5.0, "XX1": 0.3, "YY1": 0.3})  # a real first body (its mass has no effect)
    # the truth's largest pseudo-inertia margin is 2e-4 (the wrist's small inertias): noise 1e-6 of Y's rms keeps
    # the WLS estimate (σ of the wrist's inertias ~1e-7) well inside the consistent set
    model, base, W, Y, groups = _simulated(tree, tree.parameters, noise=1e-6)
    structure = consistency_structure(tree, base)
    fit = wls_pc(W, Y, groups, base.names, structure)
    w = fit.wls
    assert fit.active == ()
    # Clarabel's gap (1e-8 relative) bounds the chi-square increase over WLS, hence the distance in σ
    assert fit.chi2_increase < 1e-5
    assert np.max(np.abs(fit.result.values - w.values) / w.std) < AGREE_SIGMA
    assert robot_consistency(w, structure, tree)["realisable"] is True


def test_what_the_data_cannot_see_stays_near_the_model_files_values():
    """The base values fix only part of the standard set. Of the consistent sets giving the estimate, the one
    reported (and exported to a URDF) is the closest to the model file's, in distances relative to each value:
    the first body's mass and inertias about x and y, which no base parameter contains (a realisable 5 kg body
    in the prior), stay within 10 % of their a priori values (they share the body's pseudo-inertia with ZZ1,
    which the data move) where the first solve alone leaves whatever it met; the base values are the
    estimate's to round-off (the second solve moves only along K's null space)."""
    model = load_model("tx40")
    tree = model.tree.with_values({"M1": 5.0, "XX1": 0.3, "YY1": 0.3})
    model, base, W, Y, groups = _simulated(tree, tree.parameters, noise=1e-3)
    structure = consistency_structure(tree, base)
    names = structure.standard_names
    prior = dict(zip(tree.parameter_names, tree.parameters, strict=True))
    first = wls_pc(W, Y, groups, base.names, structure)
    fit = wls_pc(W, Y, groups, base.names, structure, standard_prior=prior)
    for key in ("M1", "XX1", "YY1"):
        assert abs(fit.standard[key] - prior[key]) <= 0.1 * prior[key], (key, fit.standard[key])
    s0 = np.array([prior[n] for n in names])
    scale = np.maximum(np.abs(s0), 1e-3)

    def distance(std):
        return float(np.linalg.norm((np.array([std[n] for n in names]) - s0) / scale))

    assert distance(fit.standard) < distance(first.standard)
    np.testing.assert_allclose(fit.result.values, first.result.values, rtol=0, atol=0)  # the estimate itself
    assert fit.active == first.active  # the constraints' prices are the estimate's, not the chosen set's
    b = structure.base_values(np.array([fit.standard[n] for n in names]))
    b1 = structure.base_values(np.array([first.standard[n] for n in names]))
    # round-off of first + N z: |z| up to the standard values' size (~1e2 here) x 1e-16 x sqrt(p)
    assert np.allclose(b, b1, rtol=1e-9, atol=1e-11 * max(1.0, float(np.abs(s0).max())))
    assert check_physical(fit.standard, frames=sorted(structure.bodies)) == []


def _prismatic() -> Tree:
    """One vertical prismatic joint: only its mass M1, viscous FV1 and Coulomb FS1 friction act."""
    return Tree("lift", (Frame(1, 0, 1),), joint_terms={1: ("FV", "FS")},
                values={"M1": 2.0, "FV1": 3.0, "FS1": 1.0, "XX1": 0.1, "YY1": 0.1, "ZZ1": 0.1})


@pytest.mark.parametrize("solver", ["CLARABEL", "SCS"])
def test_a_mass_pushed_negative_lands_on_its_bound(solver):
    tree = _prismatic()
    X = tree.with_values({"M1": -0.3}).parameters  # data that want a negative mass
    _, base, W, Y, groups = _simulated(tree, X, noise=1e-3)
    assert tuple(base.names) == ("M1", "FV1", "FS1")
    structure = consistency_structure(tree, base)
    assert structure.bodies == {1: tuple(range(10))}
    w = wls(W, Y, groups, base.names)
    assert w.value("M1") < -0.2
    opts = {"eps_abs": 1e-10, "eps_rel": 1e-10, "max_iters": 200000} if solver == "SCS" else {}
    fit = wls_pc(W, Y, groups, base.names, structure, solver=solver, solver_options=opts)
    # the body's other parameters are free, so J ⪰ margin·I4 is exactly M1 >= margin: M1 on the bound ...
    assert fit.result.value("M1") == pytest.approx(MARGIN, abs=1e-9)
    assert fit.active == ("body 1 pseudo-inertia",)
    # ... and FV1, FS1 the weighted least squares with M1 fixed there (closed form)
    fixed = wls(W, Y, groups, base.names, known={"M1": MARGIN}, group_sigmas=w.weights)
    for n in ("FV1", "FS1"):
        assert abs(fit.result.value(n) - fixed.value(n)) < AGREE_SIGMA * w.std[w.index(n)], n
    # KKT: the gradient of the chi-square along M1 at the solution is > 0 (the data pull M1 down: the bound holds
    # it) and zero along the free parameters
    L = np.linalg.cholesky(np.linalg.inv(w.covariance)).T
    grad = 2 * L.T @ L @ (fit.result.values - w.values)
    assert grad[0] > 0
    assert np.all(np.abs(grad[1:] * w.std[1:]) < 1e-4 * grad[0] * w.std[0] + 1e-6)


# ------------------------------------------------------------------------------------------ the verdict
def test_the_verdict_names_the_inequality_of_an_inconsistent_estimate():
    model = load_model("tx40")
    tree = model.tree.with_values({"M1": 5.0, "XX1": 0.3, "YY1": 0.3})
    model, base, W, Y, groups = _simulated(tree, tree.parameters, noise=1e-6)
    structure = consistency_structure(tree, base)
    w = wls(W, Y, groups, base.names)
    good = robot_consistency(w, structure, tree)
    assert good["realisable"] is True and good["violations"] == []
    bad_values = w.values.copy()
    bad_values[w.index("ZZ6")] = -0.01  # ZZ6 is a base parameter on its own: a moment that cannot be < 0
    bad_values[w.index("FV2")] = -1.0
    bad = robot_consistency(dataclasses.replace(w, values=bad_values), structure, tree)
    assert bad["realisable"] is False
    text = bad["text"]
    assert "NOT physically realisable" in text and "ZZ6 = -0.01" in text and "viscous friction FV2 = -1" in text
    # the same on a standard set (the wls-pc path): the body's own inequality is named
    std = dict(zip(tree.parameter_names, tree.parameters, strict=True))
    fit = types.SimpleNamespace(standard=std, to_dict=lambda: {})
    assert robot_consistency(w, structure, tree, fit)["realisable"] is True
    std_bad = {**std, "ZZ6": -0.001, "FV3": -0.5}
    fit_bad = types.SimpleNamespace(standard=std_bad, to_dict=lambda: {})
    v = robot_consistency(w, structure, tree, fit_bad)
    assert v["realisable"] is False
    conditions = {(x["body"], x["condition"]) for x in v["violations"]}
    assert (6, "positive definite") in conditions and (3, "viscous friction") in conditions


def test_without_the_extra_the_error_is_one_line(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "cvxpy", None)
    with pytest.raises(IdentificationError) as exc:
        require_cvxpy()
    assert str(exc.value).count("\n") == 0 and "pip install cvxpy clarabel" in str(exc.value)
    # and the verdict of a WLS estimate then says what it could not check (its check needs Clarabel alone)
    monkeypatch.setitem(sys.modules, "clarabel", None)
    model = load_model("tx40")
    model, base, W, Y, groups = _simulated(model.tree, model.tree.parameters, noise=1e-4)
    structure = consistency_structure(model.tree, base)
    v = robot_consistency(wls(W, Y, groups, base.names), structure, model.tree)
    assert v["realisable"] is None and v["unchecked"] and "pip install cvxpy clarabel" in v["text"]



@pytest.mark.parametrize("robot", ["tx40", "puma560"])
def test_the_check_given_to_clarabel_directly_equals_cvxpys_program(robot):
    """The physical-consistency check's conic program, written out for Clarabel (no cvxpy import: 56 MB of a robot
    run), against the same program canonicalised by cvxpy and solved by Clarabel: the largest margin t to the
    solvers' tolerance (1e-7 relative: their duality gaps), the verdict, the status and the bodies at the margin,
    on base values from realisable to far from it (the truth's inertial parameters moved by up to 30 % of their
    scale) and infeasible (a friction term's base value negative)."""
    from dynid.dynamics import Model
    from dynid.estimation import physical

    tree = load_model(robot).tree
    base = Model(tree).base_parameters()
    structure = consistency_structure(tree, base)
    X = np.asarray(tree.parameters, dtype=float)
    assert tree.parameter_names == structure.standard_names
    inertial = np.array([not n.startswith(("IA", "FV", "FS")) for n in structure.standard_names])
    rng = np.random.default_rng(5)
    verdicts = set()
    for spread in (0.0, 0.01, 0.1, 0.3, -1.0):
        Xs = X.copy()
        if spread > 0:  # inertial terms moved: a margin that shrinks, then a non-realisable set
            Xs[inertial] += spread * np.abs(X[inertial]).max() * rng.normal(size=inertial.sum())
        elif spread < 0:  # a viscous friction negative: no standard set (infeasible)
            Xs[structure.standard_names.index("FV1")] = -1.0
        b = base.values(Xs)
        direct = physical._feasible_clarabel(structure, b, MARGIN)
        oracle = physical._feasible_cvxpy(structure, b, MARGIN, "CLARABEL")
        verdicts.add((direct.status, direct.realisable))
        assert direct.status == oracle.status and direct.realisable == oracle.realisable
        assert direct.t == pytest.approx(oracle.t, rel=1e-7, abs=1e-9)
        assert set(direct.tightest) == set(oracle.tightest)
        if not direct.standard:  # infeasible: no witness
            continue
        # the witness standard set reproduces the base values (K s = b) and keeps its margin in every body
        s = np.array([direct.standard[n] for n in structure.standard_names])
        np.testing.assert_allclose(structure.base_map @ s, b, rtol=1e-7, atol=1e-9 * np.abs(b).max())
        assert min(physical._min_eigs(structure, s).values()) >= direct.t - 1e-7 * max(1.0, abs(direct.t))
    assert {("optimal", True), ("optimal", False), ("infeasible", False)} <= verdicts

def test_pseudo_inertia_of_a_point_mass():
    # a point mass m at c: J = m [c; 1][c; 1]ᵀ (rank one, positive semidefinite)
    m, c = 2.0, np.array([0.1, -0.2, 0.3])
    J = m * (c @ c * np.eye(3) - np.outer(c, c))
    p = [J[0, 0], J[0, 1], J[0, 2], J[1, 1], J[1, 2], J[2, 2], *(m * c), m]
    v = np.append(c, 1.0)
    assert np.allclose(pseudo_inertia(p), m * np.outer(v, v))


def test_the_config_takes_wls_pc_for_a_robot_only(tmp_path, tx40_data):  # its config names the TX40 files
    from dynid.pipeline.config import ConfigError

    text = CONFIG.read_text().replace('method = "wls"', 'method = "wls-pc"')
    text = text.replace("../../../shared", str(CONFIG.parents[3] / "shared"))
    (tmp_path / "robot.toml").write_text(text)
    assert load_config(tmp_path / "robot.toml").method is Method.WLS_PC
    (tmp_path / "sine.csv").write_text("time\n0\n")
    (tmp_path / "car.toml").write_text('[model]\ntemplate = "peugeot406"\n[[tests]]\nfile = "sine.csv"\n'
                                       '[identification]\nmethod = "wls-pc"\n')
    with pytest.raises(ConfigError) as exc:
        load_config(tmp_path / "car.toml")
    assert "wls-pc" in str(exc.value) and "robot" in str(exc.value) and "\n" not in str(exc.value)
