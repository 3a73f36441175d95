"""Independent oracles for the tests: Pinocchio models built from a dynid tree, random trees.

The Pinocchio model is built only from the geometric table (each MDH row becomes a
joint placement SE3 built with Pinocchio's own algebra), never from dynid's kinematics.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dynid.model import INERTIAL, Frame, Tree

pin = pytest.importorskip("pinocchio")


def rigid(tree: Tree) -> Tree:
    """The tree without joint terms and couplings (Pinocchio models neither)."""
    values = {k: v for k, v in tree.values.items() if k.rstrip("0123456789") in INERTIAL}
    return dataclasses.replace(tree, couplings=(), joint_terms={}, values=values)


def mdh_placement(f: Frame) -> pin.SE3:
    """Rot(z,gamma) Trans(z,b) Rot(x,alpha) Trans(x,d) Rot(z,theta0) Trans(z,r0) with Pinocchio's SE3."""

    def rz(t: float) -> pin.SE3:
        return pin.SE3(pin.utils.rotate("z", t), np.zeros(3))

    def rx(t: float) -> pin.SE3:
        return pin.SE3(pin.utils.rotate("x", t), np.zeros(3))

    def tz(x: float) -> pin.SE3:
        return pin.SE3(np.eye(3), np.array([0.0, 0.0, x]))

    def tx(x: float) -> pin.SE3:
        return pin.SE3(np.eye(3), np.array([x, 0.0, 0.0]))

    return rz(f.gamma) * tz(f.b) * rx(f.alpha) * tx(f.d) * rz(f.theta) * tz(f.r)


def pin_inertia(p: np.ndarray) -> pin.Inertia:
    """Pinocchio inertia from dynid's (XX XY XZ YY YZ ZZ MX MY MZ M) about the frame origin."""
    m = p[9]
    J_O = np.array([[p[0], p[1], p[2]], [p[1], p[3], p[4]], [p[2], p[4], p[5]]])
    if m == 0.0:  # a pure rotor-like inertia (first moments must then be zero)
        assert not p[6:9].any()
        return pin.Inertia(0.0, np.zeros(3), J_O)
    c = p[6:9] / m
    J_G = J_O - m * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
    return pin.Inertia(m, c, J_G)


class PinModel:
    """A Pinocchio model of a dynid tree; fixed frames become bodies appended to their parent joint."""

    def __init__(self, tree: Tree, X: np.ndarray | None = None, only_link: int | None = None) -> None:
        X = tree.parameters if X is None else X
        block = tree.inertial_block(X)
        self.tree = tree
        self.model = pin.Model()
        self.model.gravity = pin.Motion(np.array(tree.gravity), np.zeros(3))
        # frame j -> (pinocchio joint id, placement of frame j in that joint's frame)
        self.where: dict[int, tuple[int, pin.SE3]] = {0: (0, pin.SE3.Identity())}
        self.moving: list[int] = []
        for f in tree.frames:
            jid, M = self.where[f.ant]
            M = M * mdh_placement(f)
            if f.sigma == 2:
                self.where[f.j] = (jid, M)
            else:
                jm = pin.JointModelRZ() if f.sigma == 0 else pin.JointModelPZ()
                self.where[f.j] = (self.model.addJoint(jid, jm, M, f"j{f.j}"), pin.SE3.Identity())
                self.moving.append(f.j)
            p = block[f.j]
            if p.any() and (only_link is None or only_link == f.j):
                jid, M = self.where[f.j]
                self.model.appendBodyToJoint(jid, pin_inertia(p), M)
        self.data = self.model.createData()
        self.cols = np.array(self.moving) - 1

    def rnea(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        tau = np.zeros((q.shape[0], self.tree.n))
        c = self.cols
        for s in range(q.shape[0]):
            tau[s, c] = pin.rnea(self.model, self.data, q[s, c], qd[s, c], qdd[s, c])
        return tau

    def placements(self, q: np.ndarray) -> np.ndarray:
        """0T_j of every frame j, (n+1, 4, 4), for one sample."""
        pin.forwardKinematics(self.model, self.data, q[self.cols])
        out = np.zeros((self.tree.n + 1, 4, 4))
        for j in range(self.tree.n + 1):
            jid, M = self.where[j]
            out[j] = (self.data.oMi[jid] * M).homogeneous
        return out

    def regressor(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """Pinocchio's joint-torque regressor, columns permuted to dynid's per-joint order, (nv, 10*nv)."""
        c = self.cols
        Y = pin.computeJointTorqueRegressor(self.model, self.data, q[c], qd[c], qdd[c])
        perm = [4, 5, 7, 6, 8, 9, 1, 2, 3, 0]  # pin: m mx my mz Ixx Ixy Iyy Ixz Iyz Izz
        return np.concatenate([Y[:, 10 * i : 10 * i + 10][:, perm] for i in range(len(c))], axis=1)


def random_inertia(rng: np.random.Generator, scale: float = 1.0) -> np.ndarray:
    """A physically consistent random inertial parameter set about the frame origin (10,)."""
    m = rng.uniform(0.5, 5.0) * scale
    c = rng.normal(scale=0.3, size=3)
    A = rng.normal(size=(3, 3))
    J_G = A @ A.T * 0.1 * scale + 0.01 * np.eye(3)
    J_O = J_G + m * (c @ c * np.eye(3) - np.outer(c, c))
    return np.array([J_O[0, 0], J_O[0, 1], J_O[0, 2], J_O[1, 1], J_O[1, 2], J_O[2, 2], *(m * c), m])


def random_tree(
    seed: int, n: int, *, floating: bool = False, fixed: bool = True, serial: bool = False
) -> Tree:
    """A random branched tree with revolute, prismatic and fixed frames, non-zero gamma and b."""
    rng = np.random.default_rng(seed)
    frames = []
    values: dict[str, float] = {}
    start = 1
    if floating:  # virtual 3P + 3R chain: translations along x0, y0, z0 then three rotations
        for j in range(1, 4):
            frames.append(Frame(j, j - 1, 1, gamma=np.pi / 2, alpha=np.pi / 2))
        frames += [Frame(4, 3, 0), Frame(5, 4, 0, alpha=np.pi / 2), Frame(6, 5, 0, alpha=np.pi / 2)]
        start = 7
        values.update(dict(zip([f"{p}6" for p in ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M")],
                               random_inertia(rng, 10.0), strict=True)))
    for j in range(start, n + 1):
        ant = j - 1 if serial or j == 1 else int(rng.integers(max(0, start - 1), j))
        sigma = int(rng.choice([0, 1, 2], p=[0.55, 0.3, 0.15] if fixed else [0.6, 0.4, 0.0]))
        frames.append(Frame(j, ant, sigma, *rng.uniform(-1.5, 1.5, size=6)))
        if rng.random() < 0.85:
            names = [f"{p}{j}" for p in ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M")]
            values.update(dict(zip(names, random_inertia(rng), strict=True)))
    return Tree(name=f"random{seed}", frames=tuple(frames), values=values, gravity=tuple(rng.normal(size=3) * 5))


def random_states(tree: Tree, N: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.uniform(-np.pi, np.pi, (N, tree.n)), rng.normal(size=(N, tree.n)), rng.normal(size=(N, tree.n))


def trig_edge_angles(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(x, want): angles on the quadrants' edges (multiples of pi/4 and their neighbours), small, large and out of
    dynamics.trig's range (|x| >= trig.LIMIT, inf, NaN), and random ones; want (N, 2) their sine and cosine by
    trig.python_function run by Python (NaN where x is not finite: Python's math.sin raises at inf, compiled code
    gives NaN). The oracle of every generated target's sine and cosine."""
    from dynid.dynamics import trig

    k = np.arange(-400, 400) * (np.pi / 4)
    rng = np.random.default_rng(seed)
    x = np.concatenate([k, np.nextafter(k, np.inf), np.nextafter(k, -np.inf), [1e-300, -0.0, 0.0, 5e-324],
                        np.array([1.0, -1.0]) * np.nextafter(trig.LIMIT, 0.0), [trig.LIMIT, -trig.LIMIT, 3e5, 1e300],
                        [np.inf, -np.inf, np.nan], rng.uniform(-trig.LIMIT, trig.LIMIT, 2000),
                        rng.uniform(-4.0, 4.0, 2000)])
    ref = trig.python_function()
    return x, np.array([ref(float(v)) if np.isfinite(v) else (np.nan, np.nan) for v in x])


def compile_generated_c(tmp_path, prog, stem: str, block: bool = False):
    """The generated C of `prog` (`to_c`, with the block functions when `block`) compiled with -O2 -Wall -Werror into
    a shared library and loaded with ctypes; the test is skipped on a machine without a C compiler."""
    import ctypes
    import shutil
    import subprocess

    import pytest

    from dynid.symbolic import to_c

    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        pytest.skip("no C compiler on this machine")
    h, c = to_c(prog, prefix=stem, block=block)
    name = f"{stem}_{prog.model}"
    (tmp_path / f"{name}.h").write_text(h)
    (tmp_path / f"{name}.c").write_text(c)
    lib = tmp_path / f"{name}.so"
    res = subprocess.run([cc, "-O2", "-std=c99", "-Wall", "-Werror", "-shared", "-fPIC", "-o", str(lib),
                          str(tmp_path / f"{name}.c"), "-lm"], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    return ctypes.CDLL(str(lib))
