"""Vehicle files (`vehicle.description`): the shipped 406, another car's geometry against hand formulas and
Pinocchio, and bad files refused with one line naming the file, the key and the fix.

Oracles: the paper's 406 values as the template had them in code (the refactor must change nothing),
hand formulas for wheel centres and contact points, Pinocchio's inverse dynamics of the same tree.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from dynid.cli.main import main
from dynid.dynamics import Model
from dynid.model.tree import INERTIAL
from dynid.vehicle import parameters as sets
from dynid.vehicle.car_model import car_template
from dynid.vehicle.description import VehicleError, load_vehicle, shipped_vehicles, vehicle_path
from dynid.vehicle.geometry import AxleGeometry, CarGeometry
from dynid.vehicle.template import DAMPERS, TIRES, WHEELS, tabulated

SHIPPED = vehicle_path("peugeot406").read_text(encoding="utf-8")

# another car: a compact SUV's proportions, vertical rear dampers, no kingpin inclination at the rear
SUV = (SHIPPED.replace("wheelbase_m = 2.7", "wheelbase_m = 2.64")
       .replace("half_track_m = 0.755", "half_track_m = 0.79")
       .replace("half_track_m = 0.75", "half_track_m = 0.80")
       .replace("damper_lateral_tilt_deg = 8.0", "damper_lateral_tilt_deg = 0.0")
       .replace("kingpin_inclination_deg = 5.0", "kingpin_inclination_deg = 0.0")
       .replace("kingpin_offset_m = 0.03", "kingpin_offset_m = 0.0")
       .replace("radius_m = 0.317", "radius_m = 0.35")
       .replace("centre_height_m = 0.0", "centre_height_m = 0.05"))


def write(tmp_path: Path, text: str, name: str = "car.toml") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


# the 406 as the code had it before its file was the one place of its numbers (geometry.py, parameters.py)
OLD_GEOMETRY = CarGeometry(
    front=AxleGeometry(half_track=0.755, position=2.70, damper_lateral_tilt=math.radians(11.0),
                       damper_longitudinal_tilt=math.radians(3.0), kingpin_inclination=math.radians(12.0),
                       caster=math.radians(3.5), kingpin_offset=0.06),
    rear=AxleGeometry(half_track=0.750, position=0.0, damper_lateral_tilt=math.radians(8.0),
                      damper_longitudinal_tilt=0.0, kingpin_inclination=math.radians(5.0), caster=0.0,
                      kingpin_offset=0.03),
    wheel_radius=0.317)
OLD_WHEEL = {"XX": 0.65, "YY": 0.65, "ZZ": 1.05, "M": 35.0}
OLD_A_PRIORI = {"XX6": 6810.44, "XZ6": -445.9, "YY6": 6567.0, "ZZ6": 668.56, "MX6": 537.24, "MY6": 5.81,
                "MZ6": 2368.21, "M6": 1685.0, "karf": 19780.0, "karr": 19185.0,
                **{f"{p}{d}": x for d, ks, h in ((9, 22000.0, 4200.0), (18, 22000.0, 4200.0), (27, 20000.0, 3200.0),
                                                 (36, 20000.0, 3200.0)) for p, x in (("K", ks), ("FV", h))},
                **{f"K{t}": 200000.0 for t in TIRES}}
OLD_OFFSETS = {9: 3573.279614416879, 18: 3592.840192065781, 27: 4381.654313343572, 36: 4336.018513060617}


def test_the_shipped_406_is_the_paper_car_as_it_was():
    """The 406 file gives the template's geometry, the paper's a priori set and the simulation's truth exactly as
    the code had them (the values are written with all their digits; the offsets are solved from the statics)."""
    assert "peugeot406" in shipped_vehicles()
    v = load_vehicle("peugeot406")
    assert v.geometry == OLD_GEOMETRY
    a = v.a_priori.values
    assert {n: a[n] for n in OLD_A_PRIORI} == OLD_A_PRIORI
    assert a["XY6"] == -a["MX6"] * a["MY6"] / a["M6"] and a["YZ6"] == -a["MY6"] * a["MZ6"] / a["M6"]
    assert all(a[f"{p}{d}"] == 0.0 for d in DAMPERS for p in ("FS", "OFF"))  # the paper gives none
    assert v.known == {f"{p}{w}": OLD_WHEEL[p] for w in WHEELS for p in ("XX", "YY", "ZZ", "M")}
    assert {n: x for n, x in a.items() if n in v.known} == v.known
    est, t = sets.paper_estimates().values, v.truth.values
    yy_g = a["YY6"] - (a["MX6"] ** 2 + a["MZ6"] ** 2) / a["M6"]  # the a priori pitch inertia at the CoG, to O6
    assert t["YY6"] == yy_g + (t["MX6"] ** 2 + t["MZ6"] ** 2) / t["M6"]
    assert {n: t[n] for n in est if n != "YY6" and not n.startswith("OFF")} == {
        n: x for n, x in est.items() if n != "YY6" and not n.startswith("OFF")}
    for d, off in OLD_OFFSETS.items():  # Newton's root to 1e-13 of the loads: the same to round-off
        assert t[f"OFF{d}"] == pytest.approx(off, rel=1e-9)
    assert sets.a_priori().values == a and sets.truth().values == t  # the code's sets are the file's


def test_the_default_geometry_is_the_demo_vehicle_files():
    """A function given no geometry takes the demo vehicle's, read from its shipped file (geometry.demo_geometry,
    which does not load the vehicle: the description builds on it); it is the vehicle's, and every shipped file's
    geometry is the one its tables give."""
    import tomllib

    from dynid.shipped import DEMO_VEHICLE
    from dynid.vehicle.geometry import demo_geometry, file_geometry

    assert demo_geometry() == load_vehicle(DEMO_VEHICLE).geometry
    for name in shipped_vehicles():
        data = tomllib.loads(vehicle_path(name).read_text(encoding="utf-8"))
        assert file_geometry(data) == load_vehicle(name).geometry


def test_geometry_of_another_car_by_hand(tmp_path):
    """Wheel centres at design and at +-50 mm of clearance (tabulated joints held at 0) move along the damper
    axis the file's tilts give, u = (1, -side tan(lateral), -tan(longitudinal)) / norm in frame 6; the contact
    point is the unloaded radius minus the tire deflection straight below the upright wheel."""
    v = load_vehicle(write(tmp_path, SUV))
    g = v.geometry
    assert g.wheelbase == pytest.approx(2.64) and g.front.half_track == 0.79 and g.rear.damper_lateral_tilt == 0.0
    model = Model(car_template(g, v.a_priori.values))
    for corner in range(4):
        side = 1 if corner % 2 else -1
        ax = g.front if corner >= 2 else g.rear
        half = 0.79 if corner >= 2 else 0.80
        centre = np.array([0.05, side * half, 2.64 if corner >= 2 else 0.0])
        u = np.array([1.0, -side * math.tan(ax.damper_lateral_tilt), -math.tan(ax.damper_longitudinal_tilt)])
        u /= np.linalg.norm(u)
        for clearance in (-0.05, 0.0, 0.05):
            q = np.zeros(42)
            q[DAMPERS[corner] - 1] = clearance
            q[TIRES[corner] - 1] = 0.012
            assert not any(q[j - 1] for j in tabulated(corner))
            T = model.transforms(q)
            T6 = np.linalg.inv(T[6])
            wheel = (T6 @ T[WHEELS[corner]])[:3, 3]
            contact = (T6 @ T[TIRES[corner]])[:3, 3]
            np.testing.assert_allclose(wheel, centre + clearance * u, atol=1e-12)
            np.testing.assert_allclose(contact, wheel - (0.35 - 0.012) * np.array([1.0, 0.0, 0.0]), atol=1e-12)


def test_inverse_dynamics_of_a_vehicle_file_matches_pinocchio(tmp_path):
    """The rigid-body inverse dynamics of the tree built from a vehicle file against Pinocchio's rnea on the same
    MDH frames (the oracle's own conversion), random states."""
    pin = pytest.importorskip("pinocchio")  # noqa: F841 - the oracle needs it
    from oracles import PinModel, random_states

    v = load_vehicle(write(tmp_path, SUV))
    tree = car_template(v.geometry, v.truth.values)
    values = {k: x for k, x in tree.values.items() if k.rstrip("0123456789") in INERTIAL}
    tree = dataclasses.replace(tree, couplings=(), joint_terms={}, values=values)
    q, qd, qdd = random_states(tree, 10, seed=3)
    tau = Model(tree).inverse_dynamics(q, qd, qdd)
    ref = PinModel(tree).rnea(q, qd, qdd)
    assert np.abs(tau - ref).max() / np.abs(ref).max() < 1e-10


def test_no_anti_roll_bar_means_known_zero(tmp_path):
    v = load_vehicle(write(tmp_path, SHIPPED.replace("anti_roll_bar = true", "anti_roll_bar = false", 1)))
    assert v.known["karf"] == 0.0 and "karr" not in v.known and v.a_priori.values["karf"] == 0.0


def test_labels_and_names_are_both_accepted_and_offsets_come_from_statics(tmp_path):
    text = SHIPPED.replace("ks9 = 24425.0", "K9 = 24425.0")
    v = load_vehicle(write(tmp_path, text))
    assert v.truth.values["K9"] == 24425.0
    assert v.truth.values["OFF9"] == pytest.approx(sets.truth().values["OFF9"], rel=1e-12)


def test_describing_a_car_solves_no_statics(monkeypatch):
    """Reading a vehicle file, its template and its default tables are a description: the rest state is solved
    where it is needed (the truth's damper preloads, the simulator), once per vehicle, and not before."""
    from dynid.vehicle import statics

    def solve(*args, **kwargs):
        raise AssertionError("the statics were solved while describing the car")

    solved = statics._solve_rest
    monkeypatch.setattr(statics, "_SOLVED", type(statics._SOLVED)())  # no rest state kept from an earlier test
    monkeypatch.setattr(statics, "_solve_rest", solve)
    for name in shipped_vehicles():
        v = load_vehicle(name)
        v.template()
        car_template(v.geometry, v.a_priori.values)
        assert all(f"OFF{d}" not in v.truth_given.values for d in DAMPERS)  # the file leaves the offsets out
    calls = []
    monkeypatch.setattr(statics, "_solve_rest", lambda *a, **k: calls.append(1) or solved(*a, **k))
    first = v.truth
    assert v.truth is first and calls == [1]  # solved at the first use, kept beside the vehicle
    assert "truth" not in vars(v)  # not in the frozen description


def test_a_truth_whose_wheel_floats_is_refused_where_it_is_solved(tmp_path):
    """The truth's chassis moved 1.7 m forward (its inertia about its centre of mass kept: parallel axes), 0.5 m
    ahead of the front axle: the description reads, its preloads' rest state refuses it."""
    truth = load_vehicle("peugeot406").truth_given.values
    m, c = truth["M6"], np.array([truth[f"M{a}6"] for a in "XYZ"]) / truth["M6"]
    moved = c + np.array([0.0, 0.0, 1.7])
    J = np.array([[truth[f"{a}{b}6"] if f"{a}{b}6" in truth else truth[f"{b}{a}6"] for b in "XYZ"] for a in "XYZ"])
    J += m * ((moved @ moved) * np.eye(3) - np.outer(moved, moved) - (c @ c) * np.eye(3) + np.outer(c, c))
    head, rest = SHIPPED.split("[truth]", 1)
    body, tail = rest.split("[known]", 1)
    lines = [line for line in body.splitlines() if not line.startswith(("XX6", "XY6", "XZ6", "YY6", "YZ6", "ZZ6",
                                                                        "MZ6"))]
    at = {f"{a}{b}6": float(J["XYZ".index(a), "XYZ".index(b)]) for a, b in ("XX", "XY", "XZ", "YY", "YZ", "ZZ")}
    lines += [f"{n} = {x!r}" for n, x in at.items()]
    lines.append(f"MZ6 = {float(m * moved[2])!r}")
    v = load_vehicle(write(tmp_path, head + "[truth]" + "\n".join(lines) + "\n[known]" + tail))  # it reads
    with pytest.raises(VehicleError, match=r"car\.toml: \[truth\]: .*wheel \(frame \d+\) would float"):
        _ = v.truth


def _a_priori_without(name: str) -> str:
    head, rest = SHIPPED.split("[a_priori]", 1)
    body, tail = rest.split("[truth]", 1)
    body = "\n".join(line for line in body.splitlines() if not line.startswith(f"{name} ="))
    return head + "[a_priori]" + body + "\n[truth]" + tail


BAD = [  # (change, words in the one-line error)
    (lambda s: s.replace("[axles.rear]", "[axles.middle]"), ["[axles]", "'middle'", "valid keys: front, rear"]),
    (lambda s: s.split("[axles.rear]")[0] + "[wheels]" + s.split("[wheels]")[1], ["missing the table [axles.rear]"]),
    (lambda s: s.replace("half_track_m = 0.755", "half_track_m = -0.755"), ["[axles.front]", "half_track_m", "0.4"]),
    (lambda s: s.replace("half_track_m = 0.755", "half_track_m = 755"), ["half_track_m", "unit"]),
    (lambda s: s.replace("wheelbase_m = 2.7", "wheelbase_m = 2700"), ["wheelbase_m", "unit"]),
    (lambda s: s.replace("radius_m = 0.317", 'radius_m = "0.317 m"'), ["radius_m", "finite number"]),
    (lambda s: s.replace("damper_lateral_tilt_deg = 11.0", "damper_lateral_tilt_deg = 85.0"),
     ["damper_lateral_tilt_deg", "parallel to the ground"]),
    (lambda s: s.replace("caster_deg = 3.5", "caster_deg = 0.061"), None),  # a small angle is accepted
    (lambda s: s.replace("wheelbase_m = 2.7", "wheelbase_m = -2.7"), ["wheelbase_m", "1.5..4.5"]),
    (lambda s: s.replace("kingpin_offset_m = 0.06", "kingpin_ofset_m = 0.06"), ["kingpin_ofset_m",
                                                                                "did you mean 'kingpin_offset_m'"]),
    (lambda s: s.replace("[wheels]", "[wheel]"), ["'wheel'", "did you mean 'wheels'"]),
    (lambda s: s + "\n[radars]\nfront = true\n", ["'radars'"]),
    (lambda s: s.replace("anti_roll_bar = true", 'anti_roll_bar = "yes"', 1), ["anti_roll_bar", "true or false"]),
    (lambda s: s.replace("[known]", "[known]\nM99 = 3.0"), ["[known]", "'M99'"]),
    (lambda s: s.replace("[known]", "[known]\nkarff = 3.0"), ["did you mean 'karf'"]),
    (lambda s: s.replace("M14 = 35.0\nXX23", "M14 = -35.0\nXX23"), ["[known]", "M14", ">= 0"]),
    (lambda s: _a_priori_without("kt15"), ["[a_priori]", "lacks", "K15"]),
    (lambda s: s.replace("axes = [[0.0, 0.0, 1.0]", "axes = [[0.0, 0.0, 2.0]"), ["imu_axes", "rotation"]),
    (lambda s: s.replace("position_m = [0.0, 0.0, 0.0]", "position_m = [0.0, 0.0]"), ["[imu] position_m", "3"]),
    (lambda s: s.replace('name = "Peugeot 406 saloon"', ""), ["missing 'name'"]),
    (lambda s: s.replace("ZZ6 = 714.26", "ZZ6 = 90000.0"), ["[truth]", "realisable"]),
    (lambda s: s.replace("# [tables]", '[tables]\nfront_left.camber = { csv = "nope.csv", units = "deg" }\n#'),
     ["[tables]", "nope.csv", "cannot read"]),
    (lambda s: s.replace("# [tables]", '[tables]\nfront_left.toe = { csv = "t.csv" }\n#'),
     ["[tables.front_left]", "'toe'"]),
    (lambda s: s.replace("# [tables]", '[tables]\nfront_left.camber = { csv = "bad.csv", units = "deg" }\n#'),
     ["bad.csv"]),
    (lambda s: s.replace("[aero]", "").replace("# [tables]", "[aero]\narea_m2 = 0.0\n#"), ["area_m2", "0.5"]),
    (lambda s: s.replace("wheelbase_m = 2.7", "wheelbase_m = 2.7\nwheelbase_m = 2.8"), ["not valid TOML"]),
    (lambda s: s.replace("[imu]", "[sensors]\nlasers = false\n[imu]"), ["lasers = false", "K15", "[known]",
                                                                       "tire bench"]),
    (lambda s: s.replace("[imu]", "[sensors]\nradar = true\n[imu]"),
     ["[sensors]", "'radar'", "cameras, correvit, correvit_position_m, dynamics, gnss_position_m, laser_positions_m"]),
    (lambda s: s.replace("[imu]", "[sensors]\ncameras = 0\n[imu]"), ["[sensors] cameras", "true or false"]),
    (lambda s: s.replace("[imu]", "[sensors]\nlaser_positions_m = [[-0.5, -0.4, 0.0], [0.0, 0.4, 0.0], "
                                  "[0.0, -0.4, 2.7], [0.0, 0.4, 2.7]]\n[imu]"),
     ["laser_positions_m[0]", "not on the car"]),
    (lambda s: s.replace("[imu]", "[sensors]\ncorrevit_position_m = [0.1, 1.0]\n[imu]"),
     ["correvit_position_m", "3 finite numbers"]),
    (lambda s: s.replace("# [tables]", '[aero]\nfile = "aero_bad.csv"\n# [tables]'), ["aero_bad.csv", "line 1", "cm"]),
    (lambda s: s.replace("# [tables]", '[aero]\nfile = "aero_text.csv"\n# [tables]'), ["aero_text.csv", "line 3"]),
    (lambda s: s.replace("[imu]", "[sensors]\ngnss_position_m = [1.0, 0.0, 1.3]\n[imu]"),
     ["gnss_position_m", "correvit = false"]),
    # the logger's dynamics (vehicle.dynamics)
    (lambda s: _dynamics(s, 'imu_yaw_rat = "none"'), ["[sensors.dynamics]", "'imu_yaw_rat'",
                                                     "did you mean 'imu_yaw_rate'", "pattern"]),
    (lambda s: _dynamics(s, 'default = "ideal"'), ["[sensors.dynamics] default = 'ideal'", '"none"', '"table1"']),
    (lambda s: _dynamics(s, 'imu = "aligned"'), ["[sensors.dynamics] imu = 'aligned'", '"none"', "bandwidth_hz"]),
    (lambda s: _dynamics(s, "imu = { bandwith_hz = 10 }"), ["[sensors.dynamics] imu", "'bandwith_hz'",
                                                           "did you mean 'bandwidth_hz'"]),
    (lambda s: _dynamics(s, "imu = { delay_ms = -3 }"), ["[sensors.dynamics] imu", "delay_ms = -3", "0..500",
                                                        "milliseconds"]),
    (lambda s: _dynamics(s, "imu = { delay_ms = 25000 }"), ["delay_ms = 25000", "0..500"]),
    (lambda s: _dynamics(s, "imu = { bandwidth_hz = 0 }"), ["bandwidth_hz = 0", "(Hz)"]),
    (lambda s: _dynamics(s, "imu = { order = 2 }"), ["order without bandwidth_hz"]),
    (lambda s: _dynamics(s, "imu = { bandwidth_hz = 10, order = 2.5 }"), ["order = 2.5", "whole number"]),
    (lambda s: _dynamics(s, "imu = { rate_hz = true }"), ["rate_hz = True", "number"]),
    (lambda s: _dynamics(s, "imu = {}"), ["imu = {}", "declares nothing"]),
    (lambda s: _dynamics(s, '"gnss_*" = "none"'), ["'gnss_*' matches no channel"]),
    (lambda s: _dynamics(s, 'gnss = "none"'), ["gnss", "carries no GNSS/INS velocity", "remove the entry"]),
    (lambda s: _dynamics(s, '"wft_*" = "none"\n"wft_rl_*" = { delay_ms = 2 }'),
     ["'wft_*'", "'wft_rl_*'", "both match wft_rl_Fx", "its own entry"]),
    (lambda s: s.replace("[imu]", '[sensors]\ndynamics = "none"\n[imu]'), ["[sensors.dynamics] must be a table"]),
    (lambda s: _dynamics(s, '"wft_*" = "none"\nwft_rl_Fx = { delay_ms = 2 }'), None),  # a channel beats a pattern
    (lambda s: s.replace("[wheels]", '[wheels]\ntire_law = "quadratic"'), ["[wheels] tire_law = 'quadratic'",
                                                                          "paper, progressive"]),
    (lambda s: s.replace("[wheels]", '[wheels]\ntire_law = "progressive"'), None),
    (lambda s: s.replace("[wheels]", '[wheels]\ntire_lateral_force = true'),
     ["[wheels] tire_lateral_force = true is an option of the progressive tire law", 'tire_law = "progressive"']),
    (lambda s: s.replace("[wheels]", '[wheels]\ntire_law = "progressive"\ntire_lateral_force = 1'),
     ["[wheels] tire_lateral_force must be true or false"]),
    (lambda s: s.replace("[wheels]", '[wheels]\ntire_law = "progressive"\ntire_lateral_force = true'), None),
    (lambda s: s.replace("[axles.front]", '[axles.front]\ndamper_friction = "tanh"'),
     ["[axles.front] damper_friction = 'tanh'", "vs_m_s"]),
    (lambda s: s.replace("[axles.rear]", '[axles.rear]\ndamper_friction = { shape = "tanh", vs_m_s = 2.0 }'),
     ["[axles.rear] damper_friction vs_m_s = 2.0", "(0, 0.5]"]),
    (lambda s: s.replace("[axles.rear]", '[axles.rear]\ndamper_friction = { shape = "sigmoid", vs_m_s = 0.002 }'),
     None),
]


def _dynamics(text: str, entries: str) -> str:
    """The file with a [sensors.dynamics] table of these entries."""
    return text.replace("[imu]", f"[sensors.dynamics]\n{entries}\n\n[imu]")


@pytest.mark.parametrize("change, words", BAD)
def test_bad_vehicle_files_give_one_line(tmp_path, change, words):
    (tmp_path / "bad.csv").write_text("travel,camber\n0.0,1.0\n-0.1,0.5\n0.1,2.0\n0.2,3.0\n")  # travel not increasing
    (tmp_path / "aero_bad.csv").write_text("beta_deg,cx,cy,cz,cl,cn\n0,0.3,0,0.1,0,0\n")
    (tmp_path / "aero_text.csv").write_text("beta_deg,cx,cy,cz,cl,cm,cn\n-10,0.3,0,0.1,0,0,0\n0,0.3,x,0.1,0,0,0\n")
    path = write(tmp_path, change(SHIPPED))
    if words is None:
        load_vehicle(path)
        return
    with pytest.raises(VehicleError) as exc:
        load_vehicle(path)
    msg = str(exc.value)
    assert str(path) in msg and "\n" not in msg, msg
    for w in words:
        assert w in msg, (w, msg)


def test_cli_vehicle_commands(tmp_path, capsys):
    assert main(["vehicle", "list"]) == 0
    assert "peugeot406" in capsys.readouterr().out
    out = tmp_path / "mine.toml"
    assert main(["vehicle", "new", "Estate 2.0", "--out", str(out)]) == 0
    v = load_vehicle(out)
    assert v.name == "Estate 2.0" and v.geometry == load_vehicle().geometry
    assert main(["vehicle", "new", "again", "--out", str(out)]) == 2  # never replaces a file
    assert load_vehicle(out).name == "Estate 2.0"
    assert main(["vehicle", "show", str(out)]) == 0
    text = capsys.readouterr().out
    # a new car's unloaded tire radius is not known to 0.1 mm: the paper's 32 and the four tire offsets off15..off42
    assert "Estate 2.0" in text and "physically realisable" in text and "36 identified of 36" in text
    assert "height lasers, cameras" in text
    assert main(["vehicle", "show", "compact_suv"]) == 0  # its tire stiffness known: no lasers to identify it
    text = capsys.readouterr().out
    assert "no height lasers" in text and "28 identified of 28 not known" in text
    bad = write(tmp_path, SHIPPED.replace("[wheels]", "[wheel]"), "bad.toml")
    assert main(["demo", "--vehicle", str(bad), "--out", str(tmp_path / "demo")]) == 2
    assert "did you mean 'wheels'" in capsys.readouterr().err
    assert not (tmp_path / "demo").exists()  # nothing written


def test_aero_tables_from_a_csv(tmp_path):
    """The file's coefficient tables replace the default ones, sideslip in degrees; the reference point is the
    car's (mid-wheelbase, centreline, ground)."""
    from dynid.vehicle.aero import COEFFICIENTS, Aerodynamics, reference_point

    d = Aerodynamics()
    rows = ["beta_deg," + ",".join(COEFFICIENTS)]
    rows += [",".join(repr(float(x)) for x in (math.degrees(b), *(1.5 * getattr(d, n)[i] for n in COEFFICIENTS)))
             for i, b in enumerate(d.beta)]
    (tmp_path / "aero.csv").write_text("\n".join(rows) + "\n")
    v = load_vehicle(write(tmp_path, SUV.replace("# [tables]", '[aero]\nfile = "aero.csv"\n# [tables]')))
    np.testing.assert_allclose(v.aero.beta, d.beta, rtol=1e-15)
    for n in COEFFICIENTS:
        np.testing.assert_allclose(getattr(v.aero, n), 1.5 * getattr(d, n), rtol=1e-15)
    np.testing.assert_allclose(v.aero.point, reference_point(v.geometry))


def test_the_tables_a_file_does_not_give_are_named_as_dynid_s_defaults(tmp_path):
    """A file without [tables] gets dynid's 406-class tables for all 16 (corner, table) pairs, and the results' note
    says the caster ones were used (no sensor measures the caster; the default turns the hubs with the damper travel);
    a file giving some keeps the defaults for the rest and the note lists those the estimator uses; the MuJoCo
    example, which gives all, has none and no note. Oracle: the files' own [tables]."""
    from dynid.vehicle.notes import sensors_note

    bare = load_vehicle(write(tmp_path, SHIPPED))
    assert len(bare.defaulted_tables) == 16 and "every caster table" in sensors_note(bare)
    (tmp_path / "c.csv").write_text("travel,value\n-0.1,0\n-0.05,0\n0.05,0\n0.1,0\n")
    rear = "\n".join(f"{c}.caster = {{ csv = \"c.csv\" }}" for c in ("rear_left", "rear_right"))
    some = load_vehicle(write(tmp_path, SHIPPED.replace("# [tables]", f"[tables]\n{rear}\n#"), "some.toml"))
    assert "rear_left.caster" not in some.defaulted_tables and len(some.defaulted_tables) == 14
    note = sensors_note(some)
    assert "front_left.caster, front_right.caster" in note and "rear_left" not in note
    example = Path(__file__).resolve().parents[2] / "examples" / "mujoco_car" / "vehicle.toml"
    mujoco = load_vehicle(example)
    assert mujoco.defaulted_tables == () and "Kinematic tables" not in sensors_note(mujoco)


def test_a_folder_named_like_a_shipped_vehicle_does_not_hide_it(tmp_path, monkeypatch):
    """`dynid demo --out peugeot406` leaves a folder of that name: a config saying vehicle = "peugeot406" run from
    beside it still gets the shipped vehicle (it read the folder: "cannot read the vehicle file (Is a directory)").
    A folder given where a vehicle file is wanted says so."""
    from dynid.vehicle.description import VehicleError, load_vehicle, vehicle_path

    monkeypatch.chdir(tmp_path)
    (tmp_path / "peugeot406").mkdir()
    assert vehicle_path("peugeot406").is_file() and load_vehicle("peugeot406").name == load_vehicle().name
    (tmp_path / "mycar").mkdir()
    with pytest.raises(VehicleError, match="mycar: a folder, not a vehicle file"):
        load_vehicle("mycar")
    (tmp_path / "car.toml").mkdir()
    with pytest.raises(VehicleError, match=r"car\.toml: a folder, not a vehicle file"):
        load_vehicle("car.toml")
