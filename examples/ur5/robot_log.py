"""Stand-in for the robot: drive traj.csv through the UR5 (its URDF's inertias, and joint friction the URDF does
not give), add torque noise, and log time, q and tau at 500 Hz as a controller would."""
import tomllib
from pathlib import Path

import numpy as np

import dynid
from dynid.io import read_recording
from dynid.model.files import tree_from_dict

# the arm: ur5.toml's geometry and inertias (the URDF's), with the joints' friction that a URDF does not give
description = tomllib.loads(Path("ur5.toml").read_text())
description["friction"] = {"all": ["FV", "FS"], "shape": "tanh", "vs": 0.05}
friction = {f"FV{j}": fv for j, fv in enumerate([6.0, 6.0, 4.0, 1.5, 1.5, 1.0], start=1)}
friction |= {f"FS{j}": fs for j, fs in enumerate([5.0, 5.0, 3.5, 1.2, 1.2, 0.8], start=1)}
robot = dynid.Model(tree_from_dict(description, source="ur5.toml")).with_values(friction)
rec = read_recording("traj.csv")
t = rec.channel("q1").time
q, qd, qdd = (np.stack([rec.channel(f"{x}{j}").values for j in range(1, 7)], axis=1) for x in ("q", "qd", "qdd"))
noise = np.array([0.5, 0.5, 0.5, 0.1, 0.1, 0.1])  # N.m: about 0.3 % of each joint's rated torque
tau = robot.inverse_dynamics(q, qd, qdd) + noise * np.random.default_rng(1).normal(size=q.shape)
head = ",".join(["time [s]", *(f"q{j} [rad]" for j in range(1, 7)), *(f"tau{j} [N.m]" for j in range(1, 7))])
np.savetxt("ur5_log.csv", np.column_stack([t, q, tau]), delimiter=",", header=head, comments="", fmt="%.9g")
print(f"wrote ur5_log.csv: {t.size} samples, {t[-1]:.1f} s")
