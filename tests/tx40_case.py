"""The robot case the bad-input tests break one thing of: a TX40 log on six sines and its identify config."""

import io

import numpy as np

JOINTS = 6
QS = ", ".join(f'"q{j + 1}"' for j in range(JOINTS))
TAUS = ", ".join(f'"tau{j + 1}"' for j in range(JOINTS))


def tx40_log(n: int, fs: float) -> str:
    """CSV text: a TX40 on six sines (n samples at fs Hz), torques from its own inverse dynamics (so the baseline
    identifies them)."""
    from dynid import load_model

    model = load_model("tx40")
    t = np.arange(n) / fs
    q = np.stack([0.5 * np.sin(2 * np.pi * (0.3 + 0.1 * j) * t + j) for j in range(JOINTS)], axis=1)
    qd = np.gradient(q, 1 / fs, axis=0)
    qdd = np.gradient(qd, 1 / fs, axis=0)
    tau = model.inverse_dynamics(q, qd, qdd)
    head = ",".join(["time [s]"] + [f"q{j + 1} [rad]" for j in range(JOINTS)]
                    + [f"tau{j + 1} [N.m]" for j in range(JOINTS)])
    buf = io.StringIO()
    np.savetxt(buf, np.column_stack([t, q, tau]), delimiter=",", header=head, comments="", fmt="%.10g")
    return buf.getvalue()


def tx40_config(decimate: int) -> str:
    """identify.toml of log.csv: an identification test and a validation test on it, WLS."""
    return f"""[model]
example = "tx40"

[[tests]]
name = "a"
role = "identify"
files = {{ q = "log.csv", tau = "log.csv" }}

[[tests]]
name = "b"
role = "validate"
files = {{ q = "log.csv", tau = "log.csv" }}

[channels]
q = {{ channels = [{QS}] }}
tau = {{ channels = [{TAUS}] }}

[conditioning]
cutoff = 20.0
order = 4
decimate = [{decimate}]

[identification]
method = "wls"
"""
