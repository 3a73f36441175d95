"""Kinematic tables, aerodynamics and the template's text. Oracles: cubic polynomials (which
cubic splines reproduce exactly), finite differences for the chain rule, the drag formula
½ρSV²Cx, and the paper's numbers in the printed text."""

import numpy as np
import pytest

from dynid import Model
from dynid.cli.vehicle_cmds import show_template
from dynid.model import ModelError
from dynid.vehicle.aero import AeroError, aero_wrench
from dynid.vehicle.car_model import car_template
from dynid.vehicle.tables import KinematicTable, KinematicTableError, default_tables, load_table_csv, load_tables
from dynid.vehicle.template import DAMPERS

U = np.linspace(-0.1, 0.1, 9)
H = np.linspace(-2.0, 2.0, 7)


def cubic(u, h):
    return 0.1 * u - 3.0 * u**2 + 20.0 * u**3 + 0.05 * h - 0.01 * h**3 + 0.5 * u * h


def test_bicubic_table_reproduces_a_cubic_and_its_derivatives():
    t = KinematicTable("camber", "front left", U, cubic(*np.meshgrid(U, H, indexing="ij")), H)
    u, h = np.array([-0.073, 0.0, 0.051]), np.array([1.3, -0.4, 0.0])
    f, fu, fh, fuu, fuh, fhh = t.derivatives(u, h)
    np.testing.assert_allclose(f, cubic(u, h), atol=1e-12)
    np.testing.assert_allclose(fu, 0.1 - 6.0 * u + 60.0 * u**2 + 0.5 * h, atol=1e-10)
    np.testing.assert_allclose(fh, 0.05 - 0.03 * h**2 + 0.5 * u, atol=1e-10)
    np.testing.assert_allclose(fuu, -6.0 + 120.0 * u, atol=1e-8)
    np.testing.assert_allclose(fuh, 0.5, atol=1e-9)
    np.testing.assert_allclose(fhh, -0.06 * h, atol=1e-9)


def test_joint_velocities_and_accelerations_match_finite_differences():
    t = np.linspace(0.0, 1.0, 2001)
    dt = t[1] - t[0]
    q, qd, qdd = (np.zeros((t.size, 42)) for _ in range(3))
    w = 2 * np.pi * 1.3
    for k, d in enumerate(DAMPERS):
        q[:, d - 1], qd[:, d - 1], qdd[:, d - 1] = 0.05 * np.sin(w * t + k), 0.05 * w * np.cos(w * t + k), \
            -0.05 * w * w * np.sin(w * t + k)
    h = (2.0 * np.sin(3 * t), 6.0 * np.cos(3 * t), -18.0 * np.sin(3 * t))
    q, qd, qdd = default_tables().joints(q, qd, qdd, h)
    for j in (10, 11, 12, 28, 29, 30, 37, 38):
        np.testing.assert_allclose(np.gradient(q[:, j - 1], dt)[5:-5], qd[5:-5, j - 1], atol=1e-5)
        np.testing.assert_allclose(np.gradient(qd[:, j - 1], dt)[5:-5], qdd[5:-5, j - 1], atol=1e-4)
    assert np.ptp(q[:, 27]) > 0.1  # the front left wheel steers with the steering wheel


def test_out_of_range_names_the_table_the_input_and_the_range():
    q = np.zeros((3, 42))
    q[2, 8] = 0.2  # rear left damper clearance beyond the 0.12 m of the tables
    with pytest.raises(KinematicTableError, match=r"'steering' of the rear left corner: damper clearance = 0.2 m at "
                                                  r"sample 2 is outside the table's range \[-0.12, 0.12\] m"):
        default_tables().joints(q, q, q)
    with pytest.raises(KinematicTableError, match="steering-wheel angle = 12 rad at sample 0"):
        default_tables().joints(np.zeros((1, 42)), np.zeros((1, 42)), np.zeros((1, 42)), 12.0)


def test_csv_and_toml_tables(tmp_path):
    grid = tmp_path / "camber.csv"
    lines = ["travel\\steering," + ",".join(repr(float(x)) for x in H)]
    lines += [repr(float(u)) + "," + ",".join(repr(float(cubic(u, x))) for x in H) for u in U]
    grid.write_text("\n".join(lines) + "\n")
    t = load_table_csv(grid, "camber", "front left")
    np.testing.assert_allclose(t(np.array([0.03]), 0.7), cubic(0.03, 0.7), atol=1e-12)
    two = tmp_path / "caster.csv"
    two.write_text("travel,caster_deg\n" + "\n".join(f"{u:g},{10 * u + 1:g}" for u in U) + "\n")
    np.testing.assert_allclose(load_table_csv(two, "caster", "rear left", units="deg")(0.05), np.radians(1.5))
    toml = tmp_path / "tables.toml"
    toml.write_text('[rear_right.camber]\nunits = "deg"\ntravel = [-0.1, -0.05, 0.0, 0.05, 0.1]\n'
                    "values = [1.0, 0.5, 0.0, -0.5, -1.0]\n")
    tabs = load_tables(toml)
    np.testing.assert_allclose(tabs.table(1, "camber")(0.02), np.radians(-0.2), atol=1e-12)
    bad = tmp_path / "bad.toml"
    bad.write_text("[middle.camber]\ntravel = [0, 1]\nvalues = [0, 1]\n")
    with pytest.raises(KinematicTableError, match=r"\[middle\] is not a corner"):
        load_tables(bad)
    short = tmp_path / "short.csv"
    short.write_text("travel,value\n0,1\n0.1,x\n0.2,1\n0.3,1\n")
    with pytest.raises(KinematicTableError, match=r"short\.csv, line 3: expected numbers"):
        load_table_csv(short, "camber", "rear left")


def test_drag_at_speed_and_reversing_is_refused():
    model = Model(car_template())
    q, qd = np.zeros((1, 42)), np.zeros((1, 42))
    qd[0, 1] = 30.0  # forward along y0 at zero yaw
    w = aero_wrench(model, q, qd)
    qbar = 0.5 * 1.225 * 30.0**2 * 2.0
    np.testing.assert_allclose(w.values[0, :3], [qbar * 0.12, 0.0, -qbar * 0.31], atol=1e-9)  # up, right, forward
    qd[0, 1] = -30.0
    with pytest.raises(AeroError, match="outside the tables"):
        aero_wrench(model, q, qd)


def test_show_template_text():
    text = show_template("peugeot406")
    for needle in ("42 frames", "(0.319, 0.003, 1.405)", "paper estimates: NOT realisable", "YY6", "triangle",
                   "a priori: realisable", "truth: realisable", "48 of 48", "44 of 48",
                   "XX6 = XX6 + YY14 + YY23 + YY32 + YY41", "ks9", "kt42", "karf", "off36"):
        assert needle in text, needle
    with pytest.raises(ModelError, match="no car template 'beetle'"):
        show_template("beetle")


@pytest.mark.parametrize("measured", [(), ("steering", "camber")])
def test_compiled_tables_equal_scipys_splines(monkeypatch, measured):
    """The compiled evaluation (piecewise polynomials, cells found by walking) against scipy's own splines
    (FITPACK bicubic B-splines, CubicSpline), on a smooth record and on samples in random order, with a
    user table on an uneven steering grid."""
    import dynid.vehicle.tables as tables_module

    assert tables_module.table_joints is not None, "numba is a runtime dependency"
    uneven = np.array([-3.0, -1.7, -0.4, 0.0, 0.9, 2.2, 3.0])
    tabs = default_tables().replace(2, "caster", KinematicTable(
        "caster", "front left", U, cubic(*np.meshgrid(U, uneven, indexing="ij")) + np.sin(5 * U)[:, None], uneven))
    rng = np.random.default_rng(7)
    t = np.linspace(0.0, 20.0, 5001)
    q, qd, qdd = (np.zeros((t.size, 42)) for _ in range(3))
    for k, d in enumerate(DAMPERS):
        w = 2 * np.pi * (0.7 + 0.3 * k)
        q[:, d - 1], qd[:, d - 1], qdd[:, d - 1] = 0.09 * np.sin(w * t), 0.09 * w * np.cos(w * t), \
            -0.09 * w * w * np.sin(w * t)
    h = (2.9 * np.sin(0.9 * t), 2.61 * np.cos(0.9 * t), -2.349 * np.sin(0.9 * t))
    shuffled = rng.permutation(t.size)
    for order in (slice(None), shuffled):
        args = [a[order] for a in (q, qd, qdd)], tuple(x[order] for x in h)
        compiled = tabs.joints(*args[0], args[1], measured=measured)
        monkeypatch.setattr(tables_module, "table_joints", None)
        reference = tabs.joints(*args[0], args[1], measured=measured)
        monkeypatch.undo()
        tol = [32 * np.finfo(float).eps * e for e in _chain_rule_error_scale(tabs, measured, *args[0], *args[1])]
        for a, b, e in zip(compiled, reference, tol, strict=True):
            assert np.all(np.abs(a - b) <= e)


def _chain_rule_error_scale(tabs, measured, q, qd, qdd, h, hd, hdd):
    """Per sample and column, the size of the rounding errors by which the compiled (q, qd, qdd) and
    scipy's may differ, in units of eps. test_simulator.test_tables_match_scipy: table derivative (m, k)
    is scipy's to a few eps x size / (wx^m wy^k), size = sum of the |coefficients| of the sample's cell
    but the constant's (plus the constant |c_00| for the value); the chain rule multiplies them by
    |u'|, |h'|, u'^2, ... and adds at most 5 terms: q ~ |c_00| + size, qd ~ size (|u'| / wx + |h'| / wy),
    qdd ~ size ((|u'| / wx + |h'| / wy)^2 + |u''| / wx + |h''| / wy). Other columns are copies (0).
    Measured: <= 4.3 eps x this. (A fixed rtol = 1e-9, atol = 1e-11 max|b| left the former packing's qdd
    at 0.8 of it.)"""
    from dynid.vehicle.table_poly import pack
    from dynid.vehicle.tables import TABLE_NAMES
    from dynid.vehicle.template import base

    scale = [np.zeros_like(q) for _ in range(3)]
    for corner in range(4):
        for i, name in enumerate(TABLE_NAMES):
            if name in measured:
                continue
            tab = tabs.table(corner, name)
            XB, YB, NX, NY, C = pack([tab])
            c = np.abs(C[0])
            size = c.sum(axis=(2, 3)) - c[:, :, 0, 0]
            du, u = base(corner) + 1, q[:, base(corner) + 1]
            a = np.clip(np.searchsorted(XB[0], u, "right") - 1, 0, NX[0] - 1)
            gx = 1.0 / (XB[0, a + 1] - XB[0, a])
            g1, g2 = np.abs(qd[:, du]) * gx, np.abs(qdd[:, du]) * gx
            b = np.zeros_like(a)
            if tab.steering is not None:
                b = np.clip(np.searchsorted(YB[0], h, "right") - 1, 0, NY[0] - 1)
                gy = 1.0 / (YB[0, b + 1] - YB[0, b])
                g1, g2 = g1 + np.abs(hd) * gy, g2 + np.abs(hdd) * gy
            j = base(corner) + 2 + i  # column of the table's joint
            scale[0][:, j] = c[a, b, 0, 0] + size[a, b]
            scale[1][:, j] = size[a, b] * g1
            scale[2][:, j] = size[a, b] * (g1 * g1 + g2)
    return scale
