"""Kernels that evaluate samples side by side (issue 16): the Numba block kernels (dynid.symbolic.blocks),
GeneratedRegressor on them, and the generated C `_block` functions, against the numeric engine and Pinocchio.

Tolerance, 1e-12 relative to the largest entry (at least 1): every output is a sum of at most a few
hundred products of the inputs, evaluated in a different order by each implementation; the forward
error of such a sum is below n * eps * sum|terms| ~ 300 * 1.1e-16 * (a few times the largest entry),
about 1e-13 of the largest entry; sine and cosine are within an ulp or two of libm (fdlibm's
polynomials) and enter linearly. The kernels use no fast-math (no FMA contraction), so the same
bound holds under NUMBA_CPU_NAME=generic. 1e-12 leaves a factor 10 over that bound; measured ~1e-15.
"""

from __future__ import annotations

import ctypes
import dataclasses
from pathlib import Path

import numpy as np
import pytest
from oracles import PinModel, compile_generated_c, random_states, random_tree, trig_edge_angles

import dynid
from dynid import Model, Wrench
from dynid.model import INERTIAL
from dynid.symbolic import WrenchSite, build
from dynid.symbolic.blocks import LANES, aligned_zeros, block_model
from dynid.symbolic.generated import GeneratedRegressor
from dynid.vehicle import car_template
from dynid.vehicle.equations import identified
from dynid.vehicle.template import EQUATION_ROWS, paper_parameter_names

pytest.importorskip("numba")

RTOL = 1e-12
SIZES = [1, LANES - 1, LANES, 2 * LANES + 5]  # one sample, a lone tail, one full block, blocks and a tail


@pytest.fixture(autouse=True)
def _cache(tmp_path_factory, monkeypatch):
    # one cache for the whole file: each kernel is compiled once (seconds), then loaded
    monkeypatch.setenv("DYNID_CACHE", str(tmp_path_factory.getbasetemp() / "dynid-cache"))


def close(a: np.ndarray, b: np.ndarray, rtol: float = RTOL) -> None:
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape
    scale = max(1.0, float(np.abs(b).max(initial=0.0)))
    err = float(np.abs(a - b).max(initial=0.0))
    assert err <= rtol * scale, err / scale


def as_samples(buf: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """(size, N) kernel output -> (N, *shape)."""
    return np.moveaxis(buf.reshape(*shape, buf.shape[1]), -1, 0)


def pinocchio_regressor(pm: PinModel, tree, q, qd, qdd) -> np.ndarray:
    """Pinocchio's regressor of every sample in dynid's column order (moving frames' inertial columns)."""
    return np.stack([pm.regressor(q[s], qd[s], qdd[s]) for s in range(q.shape[0])])


def moving_columns(pm: PinModel, tree) -> list[int]:
    names = tree.parameter_names
    return [names.index(f"XX{j}") + i for j in pm.moving for i in range(10)]


@pytest.mark.parametrize("seed, n", [(1, 6), (2, 11)])
@pytest.mark.parametrize("N", SIZES)
def test_block_regressor_matches_engine_and_pinocchio(seed, n, N):
    tree = random_tree(seed, n, fixed=False, serial=n == 6)
    q, qd, qdd = random_states(tree, N, seed=N)
    kernel = block_model(tree, "regressor")
    W = as_samples(kernel(q, qd, qdd)["out"], kernel.shape)
    close(W, Model(tree).regressor(q, qd, qdd))
    pm = PinModel(tree)
    close(W[:, pm.cols][:, :, moving_columns(pm, tree)], pinocchio_regressor(pm, tree, q, qd, qdd))


@pytest.mark.parametrize("N", SIZES)
def test_block_idm_of_the_car_matches_engine_and_pinocchio(N):
    """The 42-frame car with its springs, dampers and anti-roll bars against the engine; without them
    (Pinocchio has no joint terms nor couplings) against Pinocchio too."""
    car = car_template()
    rigid = dataclasses.replace(car, couplings=(), joint_terms={}, values={
        k: v for k, v in car.values.items() if k.rstrip("0123456789") in INERTIAL})
    q, qd, qdd = (a[::2] for a in random_states(car, 2 * N, seed=N + 1))  # every other sample: strided
    qd = np.asfortranarray(qd)
    for tree in (car, rigid):
        tau = block_model(tree, "idm", parameters="numeric")(q, qd, qdd)["out"].T
        close(tau, Model(tree).inverse_dynamics(q, qd, qdd))
    close(tau, PinModel(rigid).rnea(q, qd, qdd))


def test_block_idm_with_parameters_and_wrench_matches_engine():
    """Symbolic parameters (X read once, broadcast to the lanes) and a tool wrench (N, 1, 6)."""
    tree = dynid.load_model("puma560").tree
    N = 2 * LANES + 3
    q, qd, qdd = random_states(tree, N, seed=4)
    site = WrenchSite(6, (0.0, 0.0, 0.1), 0)
    vals = np.random.default_rng(5).normal(size=(N, 1, 6))
    X = tree.parameters * np.random.default_rng(6).uniform(0.5, 1.5, tree.p)
    kernel = block_model(tree, "idm", wrenches=[site])
    tau = kernel(q, qd, qdd, X=X, wrench=vals)["out"].T
    W, Q = Model(tree).regressor(q, qd, qdd, [Wrench(6, vals[:, 0], (0.0, 0.0, 0.1), 0)])
    close(tau, np.einsum("nij,j->ni", W, X) - Q)


@pytest.mark.parametrize("law", ["paper", "progressive", "curve"])
@pytest.mark.parametrize("N", SIZES)
def test_car_identification_model_through_generated_regressor(N, law):
    """The pipeline's call: the 14 equations, the paper's 48 columns (and the tires' offsets and second-order terms
    KQ q² of the progressive law; the dampers' curve slopes in place of h), wheel wrenches; W and Q."""
    # curve: knees inside the random clearance rates (N(0, 1)), one damper without its rebound knee
    knees = {9: (-0.1, 0.1), 18: (-0.3, 0.2), 27: (-0.5, 0.05), 36: (-np.inf, 0.4)} if law == "curve" else None
    tree = car_template(tire_offsets=law == "progressive", tire_law="progressive" if law == "progressive" else "paper",
                        damper_knees=knees)
    m = Model(tree)
    q, qd, qdd = random_states(tree, N, seed=N + 2)
    rng = np.random.default_rng(N)
    wrenches = [Wrench(t, rng.normal(size=(N, 6)), (0.0, 0.1, -0.2), frame=t) for t in (15, 24, 33, 42)]
    extra = [f"{p}{t}" for p in ("OFF", "KQ") for t in (15, 24, 33, 42)] if law == "progressive" else []
    rows, cols = list(EQUATION_ROWS), [*identified(tree), *extra]
    W, Q = GeneratedRegressor(tree)(q, qd, qdd, wrenches, rows, cols)
    We, Qe = m.regressor(q, qd, qdd, wrenches, rows=rows, cols=cols)
    close(W, We)
    close(Q, Qe)


def test_inputs_of_any_layout_and_unaligned_outputs():
    """Sliced and Fortran-ordered inputs, a broadcast wrench, an output buffer not on a cache line."""
    tree = dynid.load_model("puma560").tree
    N = 3 * LANES + 1
    q, qd, qdd = random_states(tree, 2 * N, seed=8)
    ref = Model(tree).regressor(q[::2], qd[::2], qdd[::2])
    kernel = block_model(tree, "regressor")
    sliced = kernel(q[::2], qd[::2], qdd[::2])["out"]
    fortran = kernel(*(np.asfortranarray(a[::2]) for a in (q, qd, qdd)))["out"]
    raw = np.zeros((kernel.outputs["out"], N + 1))
    unaligned = kernel(q[::2], qd[::2], qdd[::2], out={"out": raw[:, 1:]})["out"]
    for out in (sliced, fortran, unaligned):
        close(as_samples(out, kernel.shape), ref)
    site = WrenchSite(6, (0.1, 0.0, 0.0), None)
    w = np.random.default_rng(9).normal(size=6)
    idm = block_model(tree, "idm", parameters="numeric", wrenches=[site])
    tau = idm(q[:N], qd[:N], qdd[:N], wrench=w)["out"].T  # one wrench for every sample
    close(tau, Model(tree).inverse_dynamics(q[:N], qd[:N], qdd[:N], [Wrench(6, w, (0.1, 0.0, 0.0), None)]))


def test_angles_beyond_the_polynomials_and_nan():
    """A lane with |q| >= 1e5 takes libm's sin and cos; a NaN stays in its own sample."""
    tree = dynid.load_model("puma560").tree
    N = 2 * LANES
    q, qd, qdd = random_states(tree, N, seed=10)
    q[3, 1] = 2.5e5
    q[9, 2] = -1e7
    kernel = block_model(tree, "regressor")
    close(as_samples(kernel(q, qd, qdd)["out"], kernel.shape), Model(tree).regressor(q, qd, qdd))
    q[5, 1] = np.nan  # (q1 does not enter the regressor of an arm on a vertical first axis)
    W = as_samples(kernel(q, qd, qdd)["out"], kernel.shape)
    assert np.isnan(W[5]).any()
    keep = np.arange(N) != 5
    close(W[keep], Model(tree).regressor(q[keep], qd[keep], qdd[keep]))


def test_zero_samples_and_bad_shapes():
    tree = dynid.load_model("puma560").tree
    kernel = block_model(tree, "regressor")
    assert kernel(np.zeros((0, 6)), np.zeros((0, 6)), np.zeros((0, 6)))["out"].shape == (kernel.outputs["out"], 0)
    with pytest.raises(ValueError, match="qd has shape"):
        kernel(np.zeros((3, 6)), np.zeros((2, 6)), np.zeros((3, 6)))
    with pytest.raises(ValueError, match="buffer"):
        kernel(np.zeros((3, 6)), np.zeros((3, 6)), np.zeros((3, 6)), out={"out": np.zeros((3, kernel.outputs["out"]))})


def _wheel_wrenches(N: int) -> list[Wrench]:
    """The paper case's rows, columns and wheel wrench sites (test_car_identification_model_through_generated_
    regressor[paper]): the buffer tests below use its kernel, compiled once per session (4 s a kernel), since what
    they prove (buffers, threads) does not depend on which kernel fills the buffers."""
    return [Wrench(t, np.ones((N, 6)), (0.0, 0.1, -0.2), frame=t) for t in (15, 24, 33, 42)]


def test_generated_regressor_results_are_read_only_and_never_reused_while_alive():
    tree = car_template()
    g = GeneratedRegressor(tree)
    rows, cols = list(EQUATION_ROWS), identified(tree)
    N = 3 * LANES
    states = [random_states(tree, N, seed=s) for s in (20, 21)]
    wrench = _wheel_wrenches(N)
    W1, _ = g(*states[0], wrench, rows, cols)
    keep = W1.copy()
    with pytest.raises(ValueError):
        W1[0, 0, 0] = 1.0
    W2, _ = g(*states[1], wrench, rows, cols)  # W1 alive: another buffer
    assert np.array_equal(W1, keep)
    del W2
    W3, _ = g(*states[0], wrench, rows, cols)  # W2's buffer again, its zero rows still zero
    assert np.array_equal(W3, keep)
    with pytest.raises(ValueError):  # nor can a result be made writeable through its base
        W1.base.flags.writeable = True
    part = np.asarray(W1)[:, 2:]  # a view of a result holds its buffer as the result did
    del W1, W3
    W4, _ = g(*states[1], wrench, rows, cols)
    assert not np.shares_memory(W4, part) and np.array_equal(part, keep[:, 2:])


def test_aligned_zeros():
    a = aligned_zeros(5, 13)
    assert a.shape == (5, 13) and a.ctypes.data % 64 == 0 and a.strides[0] % 64 == 0 and not a.any()


# ----- C ---------------------------------------------------------------------------------------------------
def _compile(tmp_path: Path, prog, stem: str):
    return compile_generated_c(tmp_path, prog, stem, block=True)


def _call(fn, N, *arrays, out_shapes):
    P = ctypes.POINTER(ctypes.c_double)
    arrays = [np.ascontiguousarray(a, dtype=float) for a in arrays]
    outs = [np.full((N, *s), np.nan) for s in out_shapes]
    fn(ctypes.c_long(N), *[a.ctypes.data_as(P) for a in arrays], *[o.ctypes.data_as(P) for o in outs])
    return outs


@pytest.fixture(scope="module")
def rnd6_c(tmp_path_factory):
    """The random 6-joint tree's C block regressor, built and compiled once for every N (2.4 s of build and cc)."""
    tree = random_tree(1, 6, fixed=False, serial=True)
    prog = build(tree, "regressor")
    return tree, prog, _compile(tmp_path_factory.mktemp("rnd6"), prog, "rnd6")


@pytest.mark.parametrize("N", [*SIZES, 0])
def test_c_block_regressor_matches_engine_and_pinocchio(N, rnd6_c):
    tree, prog, lib = rnd6_c
    q, qd, qdd = random_states(tree, N, seed=N + 30)
    (W,) = _call(lib.rnd6_regressor_block, N, q, qd, qdd, out_shapes=[prog.shape])
    close(W, Model(tree).regressor(q, qd, qdd))
    if N:
        pm = PinModel(tree)
        close(W[:, pm.cols][:, :, moving_columns(pm, tree)], pinocchio_regressor(pm, tree, q, qd, qdd))


def test_c_sine_and_cosine_are_trigs_to_the_bit(tmp_path):
    """The generated C's _block sine and cosine (a revolute joint's dgm: T1 holds cos q1 and sin q1, lanes side by
    side) are dynamics.trig's run by Python, to the bit, as every other target's (issue 25: one sine and cosine):
    on the quadrants' edges (multiples of pi/4 and their neighbours), small, large and out-of-range angles (|x| >=
    trig.LIMIT, inf, NaN: libm's). The per-sample function (_batch) calls libm (faster in scalar code): within an
    ulp of them, and told apart by these angles."""
    from dynid.dynamics import trig
    from dynid.model import Frame, Tree

    x, want = trig_edge_angles(8)
    finite = np.isfinite(x)
    want = want[finite]
    prog = build(Tree("one revolute joint", (Frame(1, 0, 0),)), "dgm")
    lib = _compile(tmp_path, prog, "one")
    got = {}
    for name in ("batch", "block"):
        (T,) = _call(getattr(lib, f"one_dgm_{name}"), len(x), x[:, None], out_shapes=[prog.shape])
        got[name] = np.column_stack([T[:, 1, 1, 0], T[:, 1, 0, 0]])  # T1[1, 0] = sin q1, T1[0, 0] = cos q1
        assert np.isnan(got[name][~finite]).all()
    libm = np.column_stack([np.sin(x[finite]), np.cos(x[finite])])
    # a block of LANES samples with an angle out of range goes to the per-sample code whole (libm's values)
    far = ~(np.abs(x) < trig.LIMIT)
    far_block = np.repeat(np.add.reduceat(far, np.arange(0, len(x), LANES)) > 0, LANES)[:len(x)][finite]
    block, batch = got["block"][finite], got["batch"][finite]
    assert far_block.sum() < 40 and far_block.sum() >= 8  # the test's few far angles, two or three blocks
    assert np.array_equal(block[~far_block].view(np.int64), want[~far_block].view(np.int64)), (
        x[finite][~far_block][np.any(block[~far_block] != want[~far_block], axis=1)][:5])
    assert np.array_equal(block[far_block].view(np.int64), libm[far_block].view(np.int64))
    assert np.array_equal(batch, libm)
    # within an ulp of max(|y|, 1/2) (trig's accuracy against libm), and apart on some of these angles
    assert np.all(np.abs(batch - want) <= np.spacing(np.maximum(np.abs(want), 0.5)))
    assert not np.array_equal(batch, want)


@pytest.mark.slow
def test_c_block_of_the_puma_and_the_car(tmp_path):
    """The benchmark's two identification models, with joint terms (sign()) and far angles (libm lanes)."""
    for stem, tree, opts in (("puma", dynid.load_model("puma560").tree, {}),
                             ("car", car_template(), {"rows": list(EQUATION_ROWS), "cols": paper_parameter_names()})):
        N = 2 * LANES + 3
        q, qd, qdd = random_states(tree, N, seed=31)
        q[4, 2] = 3e5
        prog = build(tree, "regressor", **opts)
        lib = _compile(tmp_path, prog, stem)
        (W,) = _call(getattr(lib, f"{stem}_regressor_block"), N, q, qd, qdd, out_shapes=[prog.shape])
        (Wb,) = _call(getattr(lib, f"{stem}_regressor_batch"), N, q, qd, qdd, out_shapes=[prog.shape])
        close(W, Wb)  # the far angle's block by the per-sample code: the same libm call on the same argument
        # the engine: the same but for the far sample, whose angle's last bit (6e-11 at 3e5) is rounded
        # differently by the engine (MDH offsets added apart): cos(3e5 + 6e-11) moves by 6e-11
        near = np.arange(N) != 4
        ref = Model(tree).regressor(q, qd, qdd, rows=opts.get("rows"), cols=opts.get("cols"))
        close(W[near], ref[near])
        close(W[4], ref[4], rtol=1e-9)


def test_c_block_idm_with_parameters_and_wrench(tmp_path):
    tree = dynid.load_model("puma560").tree
    N = LANES + 1
    q, qd, qdd = random_states(tree, N, seed=32)
    vals = np.random.default_rng(33).normal(size=(N, 1, 6))
    lib = _compile(tmp_path, build(tree, "idm", wrenches=[WrenchSite(6, (0.0, 0.0, 0.1), 0)]), "pumaw")
    (tau,) = _call(lib.pumaw_idm_block, N, q, qd, qdd, tree.parameters, vals, out_shapes=[(6,)])
    close(tau, Model(tree).inverse_dynamics(q, qd, qdd, [Wrench(6, vals[:, 0], (0.0, 0.0, 0.1), 0)]))


def test_smooth_friction_laws_lane_by_lane():
    """tanh and sigmoid friction (tanh from libm, lane by lane) through GeneratedRegressor's kernel."""
    from test_friction_shapes import states as friction_states
    from test_friction_shapes import tx40_shaped

    tree = tx40_shaped()
    q, qd, qdd = friction_states(tree.n, 2 * LANES + 1)
    kernel = block_model(tree, "regressor")
    assert kernel.available
    close(as_samples(kernel(q, qd, qdd)["out"], kernel.shape), Model(tree).regressor(q, qd, qdd))


def test_source_outside_the_block_language_is_refused():
    from dynid.symbolic.blocks import block_ir
    from dynid.symbolic.llvm_code import UnsupportedSourceError

    with pytest.raises(UnsupportedSourceError, match="exp"):
        block_ir("def f(q, out):\n    out[0] = math.exp(q[0])\n    return 0\n", "f")


def test_generated_regressor_from_two_threads():
    """The car pipeline's two threads: each call gets its own buffers (none handed out twice)."""
    from concurrent.futures import ThreadPoolExecutor

    tree = car_template()
    g = GeneratedRegressor(tree)
    rows, cols = list(EQUATION_ROWS), identified(tree)
    N = 4 * LANES + 3
    wrench = _wheel_wrenches(N)
    states = [random_states(tree, N, seed=40 + i) for i in range(8)]
    expected = [Model(tree).regressor(*s, wrench, rows=rows, cols=cols)[0] for s in states]

    def run(i):
        W, _ = g(*states[i], wrench, rows, cols)
        return W.copy()

    with ThreadPoolExecutor(2) as pool:
        for _ in range(3):
            for W, ref in zip(pool.map(run, range(len(states))), expected, strict=True):
                close(W, ref)


def test_cli_codegen_block(tmp_path):
    from dynid.cli.main import main

    assert main(["model", "codegen", "puma560", "--lang", "c", "--model", "regressor", "--block", "--out",
                 str(tmp_path)]) == 0
    assert "puma_560_regressor_block(long N" in (tmp_path / "puma_560_regressor.h").read_text()


def test_generated_regressor_without_numba_uses_the_numpy_code(monkeypatch):
    import dynid.symbolic.generated as generated

    monkeypatch.setattr(generated, "have_numba", lambda: False)
    tree = car_template()
    N = LANES + 2
    q, qd, qdd = random_states(tree, N, seed=50)
    wrench = [Wrench(33, np.ones((N, 6)), (0.0, 0.0, 0.0), frame=33)]
    rows, cols = list(EQUATION_ROWS), paper_parameter_names()
    W, Q = generated.GeneratedRegressor(tree)(q, qd, qdd, wrench, rows, cols)
    We, Qe = Model(tree).regressor(q, qd, qdd, wrench, rows=rows, cols=cols)
    close(W, We)
    close(Q, Qe)
