"""The car in a chassis engineer's words (issue 27 items 1-3): each parameter's corner, quantity and unit; the
chassis entered from a data sheet (CoG and ISO 8855 inertia at it); the ride-and-handling sheet with σ.

Oracles: the template's design poses (where a parameter's frame sits on the car; the damper axes), a cloud of
point masses summed directly in both frames, a two-degree-of-freedom bounce-pitch model solved numerically
(eigenvalues, a linear solve), closed forms by hand for a symmetric car, and a Monte-Carlo of the covariance.
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

from dynid.cli.main import main
from dynid.vehicle.description import VehicleError, load_vehicle, vehicle_path
from dynid.vehicle.engineering import (
    QUANTITIES,
    car_quantities,
    chassis_data_sheet,
    chassis_from_data_sheet,
    engineering_figures,
)
from dynid.vehicle.geometry import AxleGeometry, CarGeometry, demo_geometry
from dynid.vehicle.template import (
    CORNERS,
    DAMPERS,
    TIRES,
    WHEELS,
    design_poses,
    meaning,
    paper_parameter_names,
)

SHIPPED = vehicle_path("peugeot406").read_text(encoding="utf-8")
CHASSIS = ("XX6", "XY6", "XZ6", "YY6", "YZ6", "ZZ6", "MX6", "MY6", "MZ6", "M6")


# ------------------------------------------------------------------ 1. names


def test_every_corner_parameter_names_the_corner_its_frame_sits_at():
    """The corner a parameter names is where its frame is on the car (design pose in frame 6: y6 right, z6
    forward, the rear axle at z6 = 0), not a table of names."""
    g = demo_geometry()
    poses = design_poses(g)
    for n in paper_parameter_names():
        m = meaning(n)
        assert m is not None and m.unit and m.quantity, n
        frame = int(re.sub(r"^\D+", "", n)) if n not in ("karf", "karr") else None
        if frame is None or frame == 6:
            continue
        y, z = poses[frame][1, 3], poses[frame][2, 3]
        side = "right" if y > 0 else "left"
        axle = "front" if z > g.wheelbase / 2 else "rear"
        assert m.corner == f"{axle} {side}", (n, m)
    assert meaning("ks9").text() == "spring, rear left" and meaning("K9") == meaning("ks9")
    assert meaning("kt42").text() == "tire vertical stiffness, front right" and meaning("kt42").unit == "N/m"
    assert meaning("h27").unit == "N·s/m" and meaning("karf").corner == "front axle"
    assert meaning("XX6").quantity.startswith("yaw inertia") and meaning("M6").unit == "kg"
    assert meaning("ZZ1") is None and meaning("Iam6") is None  # a robot's: nothing to say


# ------------------------------------------------------------------ 2. data-sheet entry

def _cloud(rng: np.random.Generator, n: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """Point masses (kg) and their positions (ahead of the rear axle, left of the centreline, above the ground)."""
    m = rng.uniform(0.5, 6.0, n)
    p = np.column_stack([rng.uniform(-0.8, 3.6, n), rng.uniform(-0.85, 0.8, n), rng.uniform(0.2, 1.4, n)])
    return m, p


def test_a_data_sheet_is_the_frame6_parameters_of_the_same_body():
    """A body of point masses: its CoG and inertia at the CoG summed in ISO 8855 axes, its XX6..M6 summed in frame
    6 about O6; the conversion takes one to the other and back to round-off."""
    g = dataclasses.replace(demo_geometry(), wheel_radius=0.31, wheel_centre_height=0.04)
    m, p = _cloud(np.random.default_rng(5))
    M = m.sum()
    G = m @ p / M
    r = p - G  # ISO x forward, y left, z up, about the CoG
    J_iso = sum(mi * (ri @ ri * np.eye(3) - np.outer(ri, ri)) for mi, ri in zip(m, r, strict=True))
    ground = g.wheel_centre_height - g.wheel_radius
    s = np.column_stack([p[:, 2] + ground, -p[:, 1], p[:, 0]])  # frame 6: x6 up, y6 right, z6 forward, about O6
    J6 = sum(mi * (si @ si * np.eye(3) - np.outer(si, si)) for mi, si in zip(m, s, strict=True))
    want = {"XX6": J6[0, 0], "XY6": J6[0, 1], "XZ6": J6[0, 2], "YY6": J6[1, 1], "YZ6": J6[1, 2], "ZZ6": J6[2, 2],
            "MX6": m @ s[:, 0], "MY6": m @ s[:, 1], "MZ6": m @ s[:, 2], "M6": M}
    got = chassis_from_data_sheet(M, G[0], G[2], G[1], J_iso, g)
    for k in CHASSIS:
        assert got[k] == pytest.approx(want[k], rel=1e-12, abs=1e-9 * M), k
    back = chassis_data_sheet(want, g)
    assert (back["cgs_ahead_rear"], back["cgs_lateral"], back["cgs_height"]) == pytest.approx(tuple(G), rel=1e-12)
    assert [back[k] for k in ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")] == pytest.approx(
        [J_iso[0, 0], J_iso[1, 1], J_iso[2, 2], J_iso[0, 1], J_iso[0, 2], J_iso[1, 2]], rel=1e-10, abs=1e-9)


SHEET = {"mass_kg": 1512.5, "cog_ahead_of_rear_axle_m": 1.2875, "cog_above_ground_m": 0.5625, "cog_left_m": 0.0125,
         "Ixx_kg_m2": 512.25, "Iyy_kg_m2": 2431.75, "Izz_kg_m2": 2687.5, "Ixz_kg_m2": -87.5, "Ixy_kg_m2": 3.25,
         "Iyz_kg_m2": -1.5}


def _with_sheet(sheet: dict[str, float], section: str = "a_priori") -> str:
    """The shipped 406 with its [section] chassis given as a data sheet instead of XX6..M6."""
    lines = SHIPPED.splitlines()
    start = lines.index(next(line for line in lines if line.startswith(f"[{section}]")))
    end = next((i for i in range(start + 1, len(lines)) if lines[i].startswith("[")), len(lines))
    body = [line for line in lines[start:end] if line.split(" = ")[0] not in CHASSIS]
    table = [f"[{section}.chassis]", *(f"{k} = {v!r}" for k, v in sheet.items()), ""]
    return "\n".join(lines[:start] + body + table + lines[end:]) + "\n"


def test_a_vehicle_file_with_a_data_sheet_round_trips_through_vehicle_show(tmp_path, capsys):
    path = tmp_path / "car.toml"
    path.write_text(_with_sheet(SHEET), encoding="utf-8")
    v = load_vehicle(path)
    assert v.a_priori["M6"] == SHEET["mass_kg"]
    assert v.a_priori["MZ6"] == pytest.approx(SHEET["mass_kg"] * SHEET["cog_ahead_of_rear_axle_m"], rel=1e-15)
    assert main(["vehicle", "show", str(path)]) == 0
    out = capsys.readouterr().out
    shown = {}
    for line in out.splitlines():
        words = line.split()
        if len(words) >= 2 and (words[0] in SHEET or words[0] == "cog_above_wheel_centres_m"):
            shown[words[0]] = float(words[1])  # the a priori column
    for k, x in SHEET.items():
        assert shown[k] == pytest.approx(x, rel=1e-12, abs=1e-12), k
    assert shown["cog_above_wheel_centres_m"] == pytest.approx(SHEET["cog_above_ground_m"] - v.geometry.wheel_radius,
                                                               rel=1e-12)
    # the height may be given above the wheel centres instead: the same car
    other = dict(SHEET)
    other["cog_above_wheel_centres_m"] = other.pop("cog_above_ground_m") - v.geometry.wheel_radius
    path.write_text(_with_sheet(other), encoding="utf-8")
    w = load_vehicle(path)
    for k in CHASSIS:
        assert w.a_priori[k] == pytest.approx(v.a_priori[k], rel=1e-12, abs=1e-9), k


@pytest.mark.parametrize(("section", "key", "value", "words"), [
    ("a_priori", "ks9", 22.0, ["ks9 = 22", "1000..1e+06 N/m"]),
    ("a_priori", "M6", 1685000.0, ["M6 = 1.685e+06", "300..4000 kg"]),
    ("truth", "kt15", 216.5, ["kt15 = 216.5", "10000..5e+06 N/m"]),
])
def test_a_number_in_the_wrong_unit_is_refused_with_key_value_and_range(tmp_path, section, key, value, words):
    text = re.sub(rf"(?m)^(\[{section}\][^\[]*?^){key} = [^\n]*", rf"\g<1>{key} = {value}", SHIPPED, count=1)
    assert text != SHIPPED
    path = tmp_path / "car.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(VehicleError) as e:
        load_vehicle(path)
    msg = str(e.value)
    assert "\n" not in msg and str(path) in msg and f"[{section}]" in msg, msg
    for w in words:
        assert w in msg, msg


@pytest.mark.parametrize(("key", "value", "words"), [
    ("mass_kg", 1512500.0, ["mass_kg = 1.5125e+06", "300..4000 kg"]),
    ("Izz_kg_m2", 2687500.0, ["Izz_kg_m2 = 2.6875e+06", "200..50000 kg·m²"]),
    ("cog_ahead_of_rear_axle_m", 1287.5, ["cog_ahead_of_rear_axle_m = 1287.5", "0..2.7 m"]),
    ("cog_above_ground_m", 562.5, ["cog_above_ground_m = 562.5", "0.15..1.5 m"]),
])
def test_a_data_sheet_number_out_of_range_is_refused(tmp_path, key, value, words):
    path = tmp_path / "car.toml"
    path.write_text(_with_sheet({**SHEET, key: value}), encoding="utf-8")
    with pytest.raises(VehicleError) as e:
        load_vehicle(path)
    msg = str(e.value)
    assert "\n" not in msg and str(path) in msg and "[a_priori.chassis]" in msg, msg
    for w in words:
        assert w in msg, msg


def test_a_data_sheet_and_frame6_values_together_or_half_a_sheet_are_refused(tmp_path):
    path = tmp_path / "car.toml"
    path.write_text(_with_sheet(SHEET).replace("[a_priori.chassis]", "M6 = 1500.0\n\n[a_priori.chassis]"),
                    encoding="utf-8")
    with pytest.raises(VehicleError, match=r"gives M6 and \[a_priori.chassis\]"):
        load_vehicle(path)
    half = {k: x for k, x in SHEET.items() if k != "Iyy_kg_m2"}
    path.write_text(_with_sheet(half), encoding="utf-8")
    with pytest.raises(VehicleError, match="missing Iyy_kg_m2"):
        load_vehicle(path)
    path.write_text(_with_sheet({**SHEET, "cog_above_wheel_centres_m": 0.25}), encoding="utf-8")
    with pytest.raises(VehicleError, match="only one"):
        load_vehicle(path)
    path.write_text(_with_sheet({**SHEET, "Izz": 2000.0}), encoding="utf-8")
    with pytest.raises(VehicleError, match="Izz_kg_m2"):
        load_vehicle(path)


# ------------------------------------------------------------------ 3. the ride-and-handling sheet

# a symmetric car built by hand
L, A_REAR, H, TF, TR, R = 2.6, 1.2, 0.55, 0.76, 0.74, 0.30
MS, MW = 1400.0, 40.0
KSF, KSR, HF, HR, KT, KARF, KARR = 25000.0, 21000.0, 3000.0, 2800.0, 220000.0, 15000.0, 8000.0
TILT_F, TILT_FL, TILT_R = math.radians(10.0), math.radians(4.0), math.radians(6.0)
IXX, IZZ = 500.0, 2500.0
IYY = MS * (L - A_REAR) * A_REAR  # dynamic index 1: front and rear bounce decouple


def _car() -> tuple[CarGeometry, dict[str, float]]:
    g = CarGeometry(front=AxleGeometry(TF, L, TILT_F, TILT_FL), rear=AxleGeometry(TR, 0.0, TILT_R, 0.0),
                    wheel_radius=R, wheel_centre_height=0.0)
    x6, z6 = H - R, A_REAR  # the CoG in frame 6 (wheel centres at x6 = 0, the ground at -R)
    v = {"M6": MS, "MX6": MS * x6, "MY6": 0.0, "MZ6": MS * z6,  # parallel axis by hand, frame-6 axes
         "XX6": IZZ + MS * z6**2, "YY6": IYY + MS * (x6**2 + z6**2), "ZZ6": IXX + MS * x6**2,
         "XZ6": -MS * x6 * z6, "XY6": 0.0, "YZ6": 0.0, "karf": KARF, "karr": KARR}
    for k, d in enumerate(DAMPERS):
        front = CORNERS[k].startswith("front")
        v.update({f"K{d}": KSF if front else KSR, f"FV{d}": HF if front else HR, f"K{TIRES[k]}": KT})
    for w in WHEELS:
        v.update({f"M{w}": MW, f"XX{w}": 0.8, f"YY{w}": 0.8, f"ZZ{w}": 1.2})
    return g, v


def _vertical(g: CarGeometry, corner: int) -> float:
    """The damper axis' vertical component, from the template's design pose of the damper frame (its z axis)."""
    return float(design_poses(g)[DAMPERS[corner]][0, 2])


def test_the_symmetric_car_gives_its_figures_by_hand():
    g, v = _car()
    q = car_quantities(v, g)
    cf, cr = _vertical(g, CORNERS.index("front left")), _vertical(g, CORNERS.index("rear left"))
    # wheel rates: a vertical travel z moves the damper z/c along its axis: ks/c², the bar in roll 2 k_ar/c²
    assert q["wheel_rate_front_left"] == pytest.approx(KSF / cf**2, rel=1e-12)
    assert q["wheel_rate_rear_right"] == pytest.approx(KSR / cr**2, rel=1e-12)
    assert q["wheel_rate_bar_front"] == pytest.approx(2 * KARF / cf**2, rel=1e-12)
    # corner weights and axle loads by the lever rule, the wheels on their corners
    a, b = L - A_REAR, A_REAR  # CoG to the front and to the rear axle
    assert q["corner_front_left"] == pytest.approx(MS * b / L / 2 + MW, rel=1e-12)
    assert q["corner_front_right"] == pytest.approx(q["corner_front_left"], rel=1e-12)
    assert q["corner_rear_right"] == pytest.approx(MS * a / L / 2 + MW, rel=1e-12)
    assert q["front_load"] == pytest.approx(9.81 * 2 * q["corner_front_left"], rel=1e-12)
    # bounce and pitch of the sprung body on its two axles' ride rates (springs in series with the tires) and the
    # dampers at the wheels: the eigenvalues of the two-degree-of-freedom model, with Iyy = m a b they decouple
    kf = 2 * (KSF / cf**2) * KT / (KSF / cf**2 + KT)
    kr = 2 * (KSR / cr**2) * KT / (KSR / cr**2 + KT)
    df, dr = 2 * HF / cf**2, 2 * HR / cr**2
    M = np.diag([MS, IYY])
    K = np.array([[kf + kr, kf * a - kr * b], [kf * a - kr * b, kf * a**2 + kr * b**2]])
    C = np.array([[df + dr, df * a - dr * b], [df * a - dr * b, df * a**2 + dr * b**2]])
    state = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
    lam = np.linalg.eigvals(state)
    lam = lam[lam.imag > 0]
    wn = np.abs(lam)
    zeta = -lam.real / wn
    fn = np.sqrt(np.linalg.eigvals(np.linalg.solve(M, K)).real) / (2 * np.pi)
    assert sorted(fn) == pytest.approx(sorted([q["ride_frequency_front"], q["ride_frequency_rear"]]), rel=1e-9)
    # the damped modes are the axles' too (Iyy = m a b, and proportional damping is not needed: M is diagonal in
    # front/rear coordinates), so each ζ is one of the eigenvalues'
    assert sorted(zeta) == pytest.approx(sorted([q["damping_ratio_front"], q["damping_ratio_rear"]]), rel=1e-9)
    # roll stiffness (N·m/deg): springs and bars at the wheel, the wheels t either side
    kphi_f = (2 * KSF / cf**2 + 4 * KARF / cf**2) * TF**2
    kphi_r = (2 * KSR / cr**2 + 4 * KARR / cr**2) * TR**2
    assert q["roll_front"] == pytest.approx(kphi_f * math.pi / 180, rel=1e-12)
    assert q["roll_front_share"] == pytest.approx(100 * kphi_f / (kphi_f + kphi_r), rel=1e-12)
    # roll centre: where the lines through the two contact points perpendicular to the damper axes meet
    poses = design_poses(g)
    heights = {}
    for axle in ("front", "rear"):
        pts, dirs = [], []
        for side in ("left", "right"):
            k = CORNERS.index(f"{axle} {side}")
            u = poses[DAMPERS[k]][:3, 2]
            contact = poses[TIRES[k]][:3, 3]
            pts.append(contact[:2])  # (x6 up, y6 right) in the front view
            dirs.append(np.array([u[1], -u[0]]))  # perpendicular to the axis' front-view projection
        s = np.linalg.solve(np.column_stack([dirs[0], -dirs[1]]), pts[1] - pts[0])
        heights[axle] = float((pts[0] + s[0] * dirs[0])[0] + R)  # above the ground
    assert q["roll_centre_front"] == pytest.approx(heights["front"], rel=1e-9)
    assert q["roll_centre_rear"] == pytest.approx(heights["rear"], rel=1e-9)
    # roll gradient: the sprung weight's arm above the roll axis, the tires in series, the body's weight term
    arm = H - (heights["rear"] + (heights["front"] - heights["rear"]) * b / L)
    keff = sum(ks * kt / (ks + kt) for ks, kt in ((kphi_f, 2 * KT * TF**2), (kphi_r, 2 * KT * TR**2)))
    phi = MS * 9.81 * arm / (keff - MS * 9.81 * arm)
    assert q["roll_gradient"] == pytest.approx(math.degrees(phi), rel=1e-9)
    # pitch gradient: 1 g of braking is a moment m g h about the ground line, the body free to heave: solve the
    # statics of the same two-degree-of-freedom model with the weight's moment as it pitches
    Kg = K - np.array([[0.0, 0.0], [0.0, MS * 9.81 * H]])
    theta = np.linalg.solve(Kg, [0.0, MS * 9.81 * H])[1]
    assert q["pitch_gradient"] == pytest.approx(math.degrees(theta), rel=1e-9)


def test_a_progressive_tire_rates_at_its_static_load():
    """The tire law kt q + ktq q² + off = Fz: the sheet's tire rate is dFz/dq where the tire carries its corner's
    static load (oracle: the deflection found by a root finder, the slope by central differences); the ride
    frequency puts it in series with the wheel rate; a line (ktq 0) rates kt."""
    from scipy.optimize import brentq

    g, v = _car()
    assert car_quantities(v, g)["tire_rate_front_left"] == KT
    ktq, off = 4.0e6, 2500.0
    for t in TIRES:
        v.update({f"KQ{t}": ktq, f"OFF{t}": off})
    q = car_quantities(v, g)
    law = lambda x: KT * x + ktq * x * x + off  # noqa: E731
    a, b = L - A_REAR, A_REAR
    for corner, load in (("front_left", (MS * b / L / 2 + MW) * 9.81), ("rear_right", (MS * a / L / 2 + MW) * 9.81)):
        x = brentq(lambda x, f: law(x) - f, 0.0, 0.1, args=(load,), xtol=1e-15)
        slope = (law(x + 1e-6) - law(x - 1e-6)) / 2e-6  # exact for a quadratic up to rounding (1e-9 relative)
        assert q[f"tire_rate_{corner}"] == pytest.approx(slope, rel=1e-8)
        assert q[f"tire_rate_{corner}"] > KT
    cf = _vertical(g, CORNERS.index("front left"))
    kf = 2 * _in_series(KSF / cf**2, q["tire_rate_front_left"])
    # the axle's ride on its share of the sprung mass (Iyy = m a b: the axles decouple, see the test above)
    assert q["ride_frequency_front"] == pytest.approx(math.sqrt(kf / (MS * b / L)) / (2 * math.pi), rel=1e-9)


def _in_series(a: float, b: float) -> float:
    return a * b / (a + b)


def test_a_lateral_offset_loads_the_left_wheels_as_the_roll_stiffness_shares_it():
    g, v = _car()
    y = 0.02  # 2 cm to the left: MY6 = -m y (y6 to the right)
    v["MY6"] = -MS * y
    q = car_quantities(v, g)
    kphi_f = (2 * KSF + 4 * KARF) * TF**2 / _vertical(g, 2) ** 2
    kphi_r = (2 * KSR + 4 * KARR) * TR**2 / _vertical(g, 0) ** 2
    ef = kphi_f * 2 * KT * TF**2 / (kphi_f + 2 * KT * TF**2)
    er = kphi_r * 2 * KT * TR**2 / (kphi_r + 2 * KT * TR**2)
    front = ef / (ef + er)
    # each axle's left-right difference times its half track is its share of the moment m y (moments about the
    # centreline: W_l t - W_r t)
    assert (q["corner_front_left"] - q["corner_front_right"]) * TF == pytest.approx(MS * y * front, rel=1e-9)
    assert (q["corner_rear_left"] - q["corner_rear_right"]) * TR == pytest.approx(MS * y * (1 - front), rel=1e-9)
    assert sum(q[k] for k in q if k.startswith("corner_")) == pytest.approx(MS + 4 * MW, rel=1e-12)


def test_the_sheets_sigma_is_the_monte_carlo_spread_of_the_covariance():
    """First-order σ (the linearised map) against 4000 draws of a correlated covariance, within 10 %."""
    g, v = _car()
    v["MY6"] = -MS * 0.01
    names = ["M6", "MX6", "MY6", "MZ6", "YY6", "XX6", "ZZ6", "XZ6", *(f"K{d}" for d in DAMPERS),
             *(f"FV{d}" for d in DAMPERS), *(f"K{t}" for t in TIRES), "karf", "karr"]
    x = np.array([v[n] for n in names])
    rng = np.random.default_rng(11)
    A = rng.normal(size=(len(names), len(names)))
    corr = np.corrcoef(A @ A.T + 2 * len(names) * np.eye(len(names)))
    sd = 0.02 * np.abs(x) + 1.0
    C = corr * np.outer(sd, sd)
    got = {q.key: q.std for q in engineering_figures(v, g, names, C)}
    draws = rng.multivariate_normal(x, C, size=4000)
    sampled = [car_quantities({**v, **dict(zip(names, d, strict=True))}, g) for d in draws]
    keys = [k for k in QUANTITIES if k.startswith(("corner_", "wheel_rate_", "ride_", "damping_", "roll_", "pitch_"))
            and not k.startswith("roll_centre")]  # the roll centres are geometry: σ 0
    assert len(keys) > 15
    for k in keys:
        mc = float(np.std([s[k] for s in sampled]))
        assert got[k] == pytest.approx(mc, rel=0.10), k
    assert got["roll_centre_front"] == 0.0


def test_the_terminal_block_names_units_and_sigma():
    from dynid.report.tables import engineering_block

    g, v = _car()
    names = ["M6", "MZ6", "K27", "K36"]
    C = np.diag([4.0, 9.0, 250.0**2, 250.0**2])
    text = engineering_block(engineering_figures(v, g, names, C), "total")
    lines = text.splitlines()
    assert "σ total" in lines[0]
    ride = next(line for line in lines if line.strip().startswith("ride frequency"))
    assert " Hz " in ride and "front" in ride and "rear" in ride and "±" in ride
    assert any(line.strip().startswith("roll stiffness ") and "N·m/deg" in line for line in lines)
    assert any(line.strip().startswith("corner weights") and " kg " in line and "FL" in line for line in lines)
    assert any(line.strip().startswith("roll gradient") and "deg/g" in line for line in lines)
    assert len(lines) <= 16  # compact


def test_the_shipped_406_sheet_is_a_passenger_car():
    """Not an oracle, a sanity range: the 406's truth reads as a saloon's data sheet."""
    v = load_vehicle("peugeot406")
    q = car_quantities({**v.truth.values, **v.known}, v.geometry)
    assert 0.9 < q["ride_frequency_front"] < 1.6 and 0.9 < q["ride_frequency_rear"] < 1.8
    assert 0.2 < q["damping_ratio_front"] < 1.0 and 1 < q["roll_gradient"] < 8 and 0.5 < q["pitch_gradient"] < 5
    assert 400 < q["roll_front"] < 3000  # N·m/deg


def test_a_new_vehicle_file_offers_the_data_sheet_and_it_reads_as_the_same_car(tmp_path, capsys):
    """`dynid vehicle new` ends with the 406's chassis as a commented [a_priori.chassis]: uncommented in place of
    XX6..M6 it is the same chassis to the 4 digits it is written with."""
    path = tmp_path / "mine.toml"
    assert main(["vehicle", "new", "Mine", "--out", str(path)]) == 0
    text = path.read_text(encoding="utf-8")
    assert "# [a_priori.chassis]" in text
    lines, section = [], ""
    for line in text.splitlines():
        section = line.split("]")[0] + "]" if line.startswith("[") else section
        if section == "[a_priori]" and line.split(" = ")[0] in CHASSIS:
            continue
        lines.append(re.sub(r"^# (\[a_priori\.chassis\]|mass_kg|cog_|I[xyz][xyz]_)", r"\1", line))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    mine, shipped = load_vehicle(path), load_vehicle("peugeot406")
    for k in CHASSIS:
        assert mine.a_priori[k] == pytest.approx(shipped.a_priori[k], rel=2e-3, abs=0.5), k


def test_the_simulated_406_rolls_and_pitches_as_its_sheet_says():
    """The sheet's gradients are those of dynid's car model, not of a textbook car: the simulator (the nonlinear
    multibody with Magic Formula tires, kinematic tables, aero, the unsprung masses) driven by the truth set, in
    step steers at 2 and 4 m/s² and brakings at 3 and 6 m/s², rolls and pitches by the sheet's deg/g. The difference
    of two levels cancels the dampers' dry-friction band; the deceleration is the speed's slope (the accelerometer
    also reads g sin(pitch)). Seen: roll 5.52 against 5.80 deg/g (left out by the sheet: the unsprung masses'
    transfer, the tires' forces turned by camber and steer); with the roll centres at the ground rather than the
    slides' (t tan α below it) the sheet would say 4.6. Pitch 3.31 against 3.15 deg/g: the sheet counts no anti- or
    pro-dive, and the front slides' 3° rearward tilt turns part of the front brake forces (70 % of the braking here)
    into front spring compression; how much depends on the brake balance, which a vehicle file does not give."""
    from dynid.vehicle.sim import CarSimulator

    sim = CarSimulator()
    q = car_quantities(sim.parameters.values, sim.geometry)
    roll, ay = [], []
    for a in (2.0, 4.0):
        ch = sim.run("step", speed=80.0, lateral_acceleration=a, duration=6.0).ideal_channels()
        tail = slice(-300, None)
        roll.append(np.mean(ch["imu_roll"][tail]))
        ay.append(np.mean(np.radians(ch["imu_yaw_rate"][tail]) * ch["correvit_vx"][tail] / 3.6) / 9.81)
    assert abs(np.diff(roll)[0] / np.diff(ay)[0]) == pytest.approx(q["roll_gradient"], rel=0.06)
    pitch, ax = [], []
    for d in (3.0, 6.0):
        ch = sim.run("braking", speed=100.0, deceleration=d, duration=4.0).ideal_channels()
        window = slice(-400, None)  # the last 0.64 s: braking steadily, the car still rolling
        t = 0.0016 * np.arange(400)
        pitch.append(np.mean(ch["imu_pitch"][window]))
        ax.append(np.polyfit(t, ch["correvit_vx"][window] / 3.6, 1)[0] / 9.81)
    assert abs(np.diff(pitch)[0] / np.diff(ax)[0]) == pytest.approx(q["pitch_gradient"], rel=0.08)
