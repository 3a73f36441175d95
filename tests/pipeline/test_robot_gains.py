"""Motor currents and drive gains (issue 26, item 4).

Oracle: the Puma 560 (a shipped model) driven along Fourier trajectories, its joint torques from its own inverse
dynamics, written through a gearbox (joint torque = Nt motor torque, with a coupled wrist) as motor currents
i = tau_m / g_true, while the config's data-sheet gains are off by +-8 %. A second test carries a known payload on
the last link, simulated by adding to that link's standard parameters the payload's, computed here from the point
masses that make it up (sums of m r and m (|r|^2 1 - r r^T), independent of the config's parallel-axis
conversion). The gains must come back within 1 % of g_true and the inertial parameters as the torque files of the
same samples give them (the torque route, with the same payload test); with the right gains known, a current log
must identify to the torque log's estimate to round-off.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import dynid
from dynid.cli.main import main
from dynid.pipeline.config import load_config
from dynid.pipeline.run import identify

FS = 1000.0
DURATION = 20.0
G_TRUE = np.array([0.26, 0.22, 0.24, 0.075, 0.070, 0.065])  # N.m/A, motor side
SHEET = G_TRUE * np.array([1.08, 0.92, 1.08, 0.92, 1.08, 0.92])  # the data sheet's, off by +-8 %
# joint torque = NT @ motor torque: gear ratios, the wrist's motor 5 also driving joint 6 (a Puma-like coupling)
NT = np.diag([62.6, 107.8, 53.7, 76.0, 71.9, 76.7])
NT[5, 4] = 13.7
# the payload: point masses (kg) at points of the last link's frame (m); its mass, centre of mass and inertia
# about the centre of mass (the config's) and its standard parameters about the frame's origin (the simulation's)
# are both sums over these points
POINTS = np.array([[0.04, 0.00, 0.03], [-0.04, 0.01, 0.03], [0.00, 0.05, 0.07], [0.01, -0.05, 0.07],
                   [0.00, 0.00, 0.12], [0.02, 0.01, 0.01]])
MASSES = np.array([0.4, 0.4, 0.3, 0.3, 0.5, 0.3])

CONFIG = """
[model]
example = "puma560"

[[tests]]
name = "bare"
files = {{ q = "{bare}", {effort} = "{bare}" }}
{payload_test}
[channels]
q = {{ channels = ["q1", "q2", "q3", "q4", "q5", "q6"], unit = "rad" }}
{effort} = {{ channels = {names}, unit = "{unit}" }}

[transmission]
tau = {nt}

[conditioning]
cutoff = 10.0
order = 4
decimate = [10, 5]
border = 1.0

[identification]
method = "{method}"
{drive}"""


def payload_about_com() -> tuple[float, np.ndarray, list[float]]:
    m = MASSES.sum()
    c = MASSES @ POINTS / m
    r = POINTS - c
    inertia = sum(mi * (ri @ ri * np.eye(3) - np.outer(ri, ri)) for mi, ri in zip(MASSES, r, strict=True))
    return float(m), c, [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]


def payload_about_origin() -> dict[str, float]:
    """The last link's added standard parameters: sums over the points about frame 6's origin."""
    inertia = sum(mi * (ri @ ri * np.eye(3) - np.outer(ri, ri)) for mi, ri in zip(MASSES, POINTS, strict=True))
    first = MASSES @ POINTS
    return {"XX6": inertia[0, 0], "XY6": inertia[0, 1], "XZ6": inertia[0, 2], "YY6": inertia[1, 1],
            "YZ6": inertia[1, 2], "ZZ6": inertia[2, 2], "MX6": first[0], "MY6": first[1], "MZ6": first[2],
            "M6": float(MASSES.sum())}


def trajectory(t: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q, qd, qdd (N, 6), exact: 5 harmonics of 0.1 Hz per joint."""
    rng = np.random.default_rng(seed)
    w = 2 * np.pi * 0.1 * np.arange(1, 6)
    a, b = rng.normal(0, 1.0, (2, 6, 5)) / np.arange(1, 6) ** 1.5
    amp = np.array([1.5, 1.0, 1.0, 2.0, 1.5, 2.5])
    s, c = np.sin(np.multiply.outer(t, w)), np.cos(np.multiply.outer(t, w))
    q = s @ a.T + c @ b.T
    k = amp / np.abs(q).max(axis=0)
    return q * k, (c * w) @ a.T * k - (s * w) @ b.T * k, -(s * w**2) @ a.T * k - (c * w**2) @ b.T * k


def write(folder: Path, noise: float, seed: int = 3) -> dict[str, Path]:
    """The two tests' logs, motor torques (N.m) and currents (A), of the same samples; noise: the currents' white
    noise, a fraction of each channel's RMS in the test without payload; the torque logs carry the same noise
    through the true gains."""
    model = dynid.load_model("puma560")
    loaded = dynid.Model(model.tree.with_values({k: model.tree.values.get(k, 0.0) + v
                                                 for k, v in payload_about_origin().items()}))
    t = np.arange(int(DURATION * FS)) / FS
    rng = np.random.default_rng(seed)
    out = {}
    sigma = None
    for name, m, s in (("bare", model, 1), ("payload", loaded, 2)):
        q, qd, qdd = trajectory(t, s)
        tau_m = np.linalg.solve(NT, m.inverse_dynamics(q, qd, qdd).T).T
        sigma = noise * np.sqrt(np.mean((tau_m / G_TRUE) ** 2, axis=0)) if sigma is None else sigma
        i = tau_m / G_TRUE + sigma * rng.standard_normal(q.shape)
        tau = i * G_TRUE  # the motor torques, through the same [transmission] as the currents
        for kind, e, unit in (("tau", tau, "N.m"), ("current", i, "A")):
            path = folder / f"{name}_{kind}.csv"
            head = ",".join(["time [s]", *(f"q{j} [rad]" for j in range(1, 7)),
                             *(f"{kind[0]}{j} [{unit}]" for j in range(1, 7))])
            np.savetxt(path, np.column_stack([t, q, e]), delimiter=",", header=head, comments="", fmt="%.17g")
            out[f"{name}_{kind}"] = path
    return out


def config(folder: Path, logs: dict[str, Path], effort: str, name: str, drive: str = "", payload: bool = True,
           method: str = "wls") -> Path:
    m, c, inertia = payload_about_com()
    test = (f'\n[[tests]]\nname = "payload"\nfiles = {{ q = "{logs[f"payload_{effort}"]}", {effort} = '
            f'"{logs[f"payload_{effort}"]}" }}\npayload = {{ mass_kg = {m!r}, com_m = {[float(x) for x in c]}, '
            f'inertia_kg_m2 = {[float(x) for x in inertia]} }}\n' if payload else "")
    names = [f"{effort[0]}{j}" for j in range(1, 7)]
    text = CONFIG.format(bare=logs[f"bare_{effort}"], effort=effort, payload_test=test, names=json.dumps(names),
                         unit="A" if effort == "current" else "N.m",
                         nt=json.dumps(NT.tolist()), method=method, drive=drive)
    path = folder / f"{name}.toml"
    path.write_text(text)
    return path


def gains_drive(gains: np.ndarray, identify_gains: str = "true") -> str:
    return f"\n[drive]\ngains = {json.dumps(gains.tolist())}\nidentify_gains = {identify_gains}\n"


def base_of(run) -> tuple[np.ndarray, np.ndarray]:
    names = list(run.base.names)
    r = run.result
    return np.array([r.value(n) for n in names]), np.array([r.std[r.index(n)] for n in names])


# The logs are written once per module (about 2.5 s a pair of tests) and only read: every test that needs the
# noise-free or the noisy files of these seeds shares them and writes its own config beside its own tmp_path.
@pytest.fixture(scope="module")
def exact_logs(tmp_path_factory) -> dict[str, Path]:
    return write(tmp_path_factory.mktemp("gains_exact"), 0.0)


@pytest.fixture(scope="module")
def noisy_logs(tmp_path_factory) -> dict[str, Path]:
    return write(tmp_path_factory.mktemp("gains_noisy"), 0.02)  # 2 % of each current's RMS, white at 1 kHz


@pytest.fixture(scope="module")
def noise_free(tmp_path_factory, exact_logs):
    d = tmp_path_factory.mktemp("gains_exact_runs")
    torque = identify(load_config(config(d, exact_logs, "tau", "torque")))
    current = identify(load_config(config(d, exact_logs, "current", "current", gains_drive(SHEET))))
    return torque, current


@pytest.fixture(scope="module")
def noisy(tmp_path_factory, noisy_logs):
    d = tmp_path_factory.mktemp("gains_noisy_runs")
    torque = identify(load_config(config(d, noisy_logs, "tau", "torque")))
    current = identify(load_config(config(d, noisy_logs, "current", "current", gains_drive(SHEET))))
    return torque, current


def test_noise_free_gains_and_inertial_parameters(noise_free):
    """Noise-free files: the gains to 1e-6 of the truth, the base estimate the torque route's to 1e-6. Their
    conditioning (filter, differences, 1 s borders) leaves a 1.5e-7 relative residual, which the gains' freedom
    turns into 3e-7 (measured, both)."""
    torque, current = noise_free
    r = current.result
    g = np.array([r.value(f"G{k}") for k in range(1, 7)])
    np.testing.assert_allclose(g, G_TRUE, rtol=1e-6)
    x_t, _ = base_of(torque)
    x_c, _ = base_of(current)
    assert np.linalg.norm(x_c - x_t) <= 1e-6 * np.linalg.norm(x_t), np.max(np.abs(x_c - x_t))


def test_noisy_gains_within_one_percent(noisy):
    """White current noise: every gain within 1 % of the truth and within 4 of its σ; the base estimate the torque
    route's to within the spread the noise explains (4 σ of the current route's estimate, whose σ holds the gains'
    uncertainty that the torque route does not have)."""
    torque, current = noisy
    r = current.result
    g = np.array([r.value(f"G{k}") for k in range(1, 7)])
    sg = np.array([r.std[r.index(f"G{k}")] for k in range(1, 7)])
    assert np.all(np.abs(g / G_TRUE - 1) < 0.01), g / G_TRUE - 1
    assert np.all(np.abs(g - G_TRUE) < 4 * sg), (g - G_TRUE) / sg
    assert np.all(sg / G_TRUE < 0.005), sg / G_TRUE
    x_t, _ = base_of(torque)
    x_c, s_c = base_of(current)
    assert np.all(np.abs(x_c - x_t) <= 4 * s_c), np.max(np.abs(x_c - x_t) / s_c)


def test_known_gains_are_a_scaling(tmp_path, noisy_logs, noisy):
    """The right gains known: the current log identifies to the torque log's estimate (round-off). The torque
    route's run is the noisy fixture's: the same files (noise 0.02, seed 3) and the same config."""
    torque, _ = noisy
    current = identify(load_config(config(tmp_path, noisy_logs, "current", "known", gains_drive(G_TRUE, "false"))))
    assert list(current.result.names) == list(torque.result.names)
    np.testing.assert_allclose(current.result.values, torque.result.values, rtol=1e-10, atol=0)
    np.testing.assert_allclose(current.result.std, torque.result.std, rtol=1e-8)


def test_one_known_gain_fixes_the_scale(tmp_path, exact_logs):
    """Without a payload, one gain known (joint 1's, the true value) fixes the scale of the others: through the
    links' shares of joint 1's torque, small for the wrist (its gains come back to 6e-5 on noise-free files whose
    conditioning leaves a 1.5e-7 relative residual; 1e-7 for the arm's), so 2e-4."""
    logs = exact_logs
    drive = gains_drive(np.r_[G_TRUE[0], SHEET[1:]], json.dumps([f"c{j}" for j in range(2, 7)]))
    run = identify(load_config(config(tmp_path, logs, "current", "one", drive, payload=False)))
    r = run.result
    assert r.flags[r.index("G1")] == "known"
    g = np.array([r.value(f"G{k}") for k in range(1, 7)])
    np.testing.assert_allclose(g, G_TRUE, rtol=2e-4)


def test_gains_are_reported_with_their_unit(noise_free, tmp_path):
    from dynid.pipeline.run import write_outputs

    _, current = noise_free
    write_outputs(current, tmp_path, "gains")
    data = json.loads((tmp_path / "results.json").read_text())
    rows = {p["name"]: p for p in data["parameters"]}
    assert rows["G1"]["unit"] == "N·m/A" and rows["G1"]["std"] > 0
    csv = (tmp_path / "parameters.csv").read_text()
    assert any(line.startswith("G3,") and "N·m/A" in line for line in csv.splitlines())
    assert "drive gains (N·m/A, motor side)" in current.summary()
    assert "G6" in (tmp_path / "report.html").read_text()


def _cli_error(tmp_path: Path, text: str, capsys) -> str:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    rc = main(["identify", str(path), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert rc != 0 and len(err.splitlines()) == 1, err
    assert not (tmp_path / "out").exists()
    return err


def _text(tmp_path: Path, logs, drive: str = "", payload: bool = True, method: str = "wls") -> str:
    return config(tmp_path, logs, "current", "bad", drive, payload, method).read_text()


@pytest.fixture
def logs(exact_logs):
    return exact_logs


def test_a_current_channel_without_a_gain(tmp_path, logs, capsys):
    err = _cli_error(tmp_path, _text(tmp_path, logs), capsys)
    assert "'c1' has no drive gain" in err and "[drive] gains" in err
    err = _cli_error(tmp_path, _text(tmp_path, logs, f"\n[drive]\ngains = {SHEET[:4].tolist()}\n"), capsys)
    assert "'c5' has no gain" in err


def test_every_gain_identified_needs_a_payload_or_a_known_gain(tmp_path, logs, capsys):
    err = _cli_error(tmp_path, _text(tmp_path, logs, gains_drive(SHEET), payload=False), capsys)
    assert "identify_gains" in err and "payload" in err and "known" in err


def test_a_payload_that_is_no_body_is_refused(tmp_path, logs, capsys):
    text = _text(tmp_path, logs, gains_drive(SHEET))
    inertia = payload_about_com()[2]
    bad = [inertia[0], inertia[1], -inertia[2], *inertia[3:]]
    text = text.replace(repr([float(x) for x in inertia]), repr([float(x) for x in bad]))
    err = _cli_error(tmp_path, text, capsys)
    assert "payload" in err and "inertia_kg_m2" in err and "not positive definite" in err


def test_wls_pc_refuses_identified_gains(tmp_path, logs, capsys):
    err = _cli_error(tmp_path, _text(tmp_path, logs, gains_drive(SHEET), method="wls-pc"), capsys)
    assert "wls-pc" in err and "identify_gains = false" in err


@pytest.mark.parametrize(("old", "new", "words"), [
    ("current = { channels", 'tau = { channels = ["c1"] }\ncurrent = { channels',
     ["[channels]", "both tau and current"]),
    ("identify_gains = true", 'identify_gains = ["c1", "c9"]', ["identify_gains", "'c9'", "not a current channel"]),
    ("mass_kg = 2.2", "mass_kg = 0.0", ["payload", "mass_kg = 0.0", "> 0"]),
    ("payload = { mass_kg", "payload = { frame = 9, mass_kg", ["payload frame = 9", "frames 1 to 6"]),
])
def test_drive_and_payload_mistakes_are_one_line(tmp_path, logs, capsys, old, new, words):
    text = _text(tmp_path, logs, gains_drive(SHEET))
    assert old in text
    err = _cli_error(tmp_path, text.replace(old, new, 1), capsys)
    assert all(w in err for w in words), err


def test_drive_gains_need_current_channels(tmp_path, logs, capsys):
    text = config(tmp_path, logs, "tau", "bad", gains_drive(SHEET)).read_text()
    err = _cli_error(tmp_path, text, capsys)
    assert "[drive]" in err and "[channels] has tau" in err
