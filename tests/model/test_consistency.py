"""Physical consistency of inertial parameters. Oracles: bodies built from point masses (always
realisable), hand constructions of non-positive-definite inertia, and the paper's numbers as
worked out by hand in DESIGN.md §5 (YY_G ≈ 12980 > XX_G + ZZ_G ≈ 3870)."""

import numpy as np
import pytest

from dynid.model.consistency import check_body, check_physical
from dynid.vehicle import parameters as params
from dynid.vehicle.car_model import car_template


def body_from_points(masses, points):
    """The 10 parameters (about the origin) of point masses: sums, no formula under test."""
    J = np.zeros((3, 3))
    for m, p in zip(masses, points, strict=True):
        J += m * (p @ p * np.eye(3) - np.outer(p, p))
    ms = (masses[:, None] * points).sum(axis=0)
    return [J[0, 0], J[0, 1], J[0, 2], J[1, 1], J[1, 2], J[2, 2], *ms, masses.sum()]


@pytest.mark.parametrize("seed", range(5))
def test_bodies_made_of_point_masses_pass(seed):
    rng = np.random.default_rng(seed)
    masses = rng.uniform(0.1, 5.0, size=8)
    points = rng.normal(size=(8, 3)) + rng.normal(size=3) * 3
    assert check_body(body_from_points(masses, points), body=3) == []


def test_a_flat_plate_on_the_boundary_passes():
    # points in a plane: I_z = I_x + I_y exactly (triangle equality), must not be reported
    rng = np.random.default_rng(1)
    pts = np.column_stack([rng.normal(size=(6, 2)), np.zeros(6)])
    assert check_body(body_from_points(np.ones(6), pts), body=1) == []


def test_random_non_positive_definite_inertia_fails():
    rng = np.random.default_rng(2)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    JG = Q @ np.diag([-0.5, 2.0, 3.0]) @ Q.T
    M, c = 4.0, rng.normal(size=3)
    JO = JG + M * (c @ c * np.eye(3) - np.outer(c, c))  # moved to the origin by the parallel-axis rule
    values = {"XX7": JO[0, 0], "XY7": JO[0, 1], "XZ7": JO[0, 2], "YY7": JO[1, 1], "YZ7": JO[1, 2],
              "ZZ7": JO[2, 2], "MX7": M * c[0], "MY7": M * c[1], "MZ7": M * c[2], "M7": M}
    bad = check_physical(values)
    assert bad[0].condition == "positive definite"
    assert bad[0].body == 7 and "body 7" in bad[0].message and "-0.5" in bad[0].message


def test_non_positive_mass_fails_naming_the_body():
    bad = check_physical({"M4": -2.0, "XX4": 1.0, "YY4": 1.0, "ZZ4": 1.0})
    assert len(bad) == 1 and bad[0].condition == "mass" and "M4 = -2 kg" in bad[0].message


def test_paper_estimated_chassis_breaks_the_triangle_inequality_about_y6():
    bad = check_physical(params.paper_estimates().values)
    assert [(v.body, v.condition) for v in bad] == [(6, "triangle")]
    msg = bad[0].message
    assert "YY6" in msg and "triangle" in msg and "body 6" in msg
    assert abs(bad[0].numbers["principal_moment"] - 12980) < 5
    assert abs(bad[0].numbers["sum_of_others"] - 3870) < 10


def test_a_priori_and_truth_sets_are_realisable():
    assert check_physical(params.a_priori().values) == []
    assert check_physical(params.truth().values) == []


def test_tree_input_checks_the_bodies_with_mass_only():
    tree = car_template(None, params.paper_estimates().values)
    bad = check_physical(tree)
    assert [v.body for v in bad] == [6]
    assert check_physical(tree, frames=[14, 23, 32, 41]) == []
