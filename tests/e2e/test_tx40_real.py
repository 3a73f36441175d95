"""Real data: the Staubli TX40's base parameters from its measured positions and torques.

Runs the shipped example config (examples/tx40/identify.toml) through `dynid identify`'s
pipeline. Oracle: the published OLS/WLS identification of the same files (figaroh-plus,
TX40_bp_5.csv); our estimates come from our own model, filter, regressor, decimation and
least squares, and only the published values are read for comparison.
"""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from dynid.pipeline.config import load_config
from dynid.pipeline.run import identify, write_outputs

# The real TX40 files through the whole pipeline (about 10 s).
pytestmark = [pytest.mark.slow, pytest.mark.e2e]

CONFIG = Path(__file__).resolve().parents[2] / "examples" / "tx40" / "identify.toml"


@pytest.fixture(scope="module")
def runs(tx40_data):
    cfg = load_config(CONFIG)
    return identify(cfg), identify(dataclasses.replace(cfg, method="ols"))


def test_every_published_parameter_is_matched(runs):
    assert len(runs[0].reference) == 60


def test_well_identified_parameters_agree_with_the_publication(runs):
    """Published WLS %σ <= 2 %: our WLS estimate within max(3 σ_published, 10 %) of the published value."""
    run = runs[0]
    names, values = list(run.result.names), run.result.values
    checked = 0
    for m in run.reference:
        if m.row.wls_rel_std > 2.0:
            continue
        pub, ours = m.row.wls, m.value(names, values)
        assert abs(ours - pub) <= max(3 * abs(pub) * m.row.wls_rel_std / 100, 0.10 * abs(pub)), (m.label, ours, pub)
        checked += 1
    assert checked >= 10


def test_uncertainties_are_of_the_published_order(runs):
    """Our %σ for the well-identified parameters is within a factor 2 of the published one (same data, method)."""
    for run, pick in ((runs[0], lambda r: r.wls_rel_std), (runs[1], lambda r: r.ols_rel_std)):
        names = list(run.result.names)
        for m in run.reference:
            if m.row.wls_rel_std > 2.0 or m.weights != {m.label: 1.0}:
                continue
            ours = run.result.rel_std_percent[names.index(m.label)]
            assert 0.5 < ours / pick(m.row) < 2.0, (run.result.method, m.label)


def test_outputs_are_written(runs, tmp_path):
    files = write_outputs(runs[0], tmp_path, "TX40")
    assert {f.name for f in files} >= {"results.json", "report.html"}
    data = json.loads((tmp_path / "results.json").read_text())
    assert len(data["parameters"]) == 60 and data["validation"]["direct"]["overall"] < 0.1
    assert "Comparison with the published identification" in (tmp_path / "report.html").read_text()
    assert not list(tmp_path.glob(".*.tmp"))


def test_nrmse_beside_the_relative_error(runs):
    """Per joint, the NRMSE is the RMS of the residual over the measured torque's spread, from the run's own rows
    (an independent numpy computation); it exceeds the relative error where a static load (gravity on joint 2:
    measured 5.2 % against 4.5 %) fills ||Y|| without being dynamics, and stays below 1 (better than predicting
    the mean)."""
    run = runs[0]
    sys, X = run.identify, run.result.values
    for g, e in run.errors["direct NRMSE"].items():
        if g == "overall":
            continue
        rows = sys.groups == g
        y, r = sys.Y[rows], sys.Y[rows] - sys.W[rows] @ X
        assert e == pytest.approx(np.sqrt(np.mean(r**2)) / np.std(y), rel=1e-9)
        assert 0 < e < 1
    assert run.errors["direct NRMSE"]["joint2"] > 1.1 * run.errors["direct"]["joint2"]


def test_flag_judges_products_and_first_moments_against_the_link(runs):
    """The "uncertain" flag on the real data: a product of inertia or a first moment is judged against its link's
    size from the model file's a priori set (sqrt(XX YY) for XY, mass x link size for MX, computed here from the
    model file's numbers), not against its estimate, which is near zero for most of them. Measured: 47 of 60
    flagged against the values, 35 against the scales; of the 23 products and first moments flagged before, those
    still flagged have a σ above 2.5 % of their link's size (the wrist, whose data are poor: 8 to 99 %)."""
    run = runs[0]
    r, tree = run.result, run.model.tree
    by_value = int(np.sum(~(100 * r.std_total / np.abs(r.values) <= r.flag_percent)))
    assert by_value >= 45 and len(r.uncertain) <= 36, (by_value, len(r.uncertain))
    for i, name in enumerate(r.names):
        kind, j = name.rstrip("0123456789"), name[len(name.rstrip("0123456789")):]
        if kind not in ("XY", "XZ", "YZ", "MX", "MY", "MZ") or run.base.expressions[i] != name:
            continue
        v = {k: abs(tree.values.get(f"{k}{j}", 0.0)) for k in ("XX", "YY", "ZZ", "M")}
        if kind[0] != "M":
            scale = np.sqrt(v[kind[0] * 2] * v[kind[1] * 2])
            assert r.scale[i] == pytest.approx(max(scale, abs(r.values[i])), rel=1e-12), name
        else:  # mass x size, the size at least the joint-to-joint distance of the README's table (0.225 m)
            assert r.scale[i] >= v["M"] * (0.225 if j in ("2", "3") else 0.0), name
        assert (name in r.uncertain) == (100 * r.std_total[i] / r.scale[i] > r.flag_percent), name


def test_physically_consistent_wls_is_compared_with_the_published_wls(tx40_data, tmp_path):
    """method = "wls-pc" is a weighted estimate: the reference table, the report and results.json set it beside the
    published WLS column, not the OLS one (they used to, as its result's method "WLS-PC" is not "WLS")."""
    pytest.importorskip("cvxpy")
    run = identify(dataclasses.replace(load_config(CONFIG), method="wls-pc"))
    write_outputs(run, tmp_path, "TX40")
    published = [r["published_value"] for r in json.loads((tmp_path / "results.json").read_text())["reference"]]
    assert published == [m.row.wls for m in run.reference]
    assert any(m.row.wls != m.row.ols for m in run.reference)
    table = [float(line.split()[3]) for line in run.reference_table().splitlines()[1:]]  # printed to 6 digits
    assert table == pytest.approx([m.row.wls for m in run.reference], rel=1e-5, abs=1e-12)
