"""Symbolic models and generated code.

Oracle: the numeric engine (dynid.Model: transforms, inverse_dynamics, regressor,
inertia_matrix, base_parameters), itself checked against Pinocchio in
test_pinocchio_oracle.py; Khalil's published regrouping formulas for the PUMA 560; the
C compiler for the generated C. No test compares the generator with itself.
"""

from __future__ import annotations

import ctypes
import dataclasses
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from oracles import compile_generated_c

import dynid
from dynid.dynamics import Model, trig
from dynid.model import Frame, Tree
from dynid.symbolic import (
    SymbolicError,
    WrenchSite,
    build,
    dgm,
    idm,
    inertia,
    numpy_module,
    regressor,
    to_numpy,
    to_text,
)
from dynid.symbolic.regroup import base_parameters
from dynid.vehicle import car_template
from dynid.vehicle.template import EQUATION_ROWS as CAR_ROWS
from dynid.vehicle.template import paper_parameter_names

CAR_COLS = tuple(paper_parameter_names())

RTOL = 1e-10


@pytest.fixture(autouse=True)
def _cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DYNID_CACHE", str(tmp_path / "cache"))


def random42() -> Tree:
    sys.path.insert(0, str(Path(__file__).parent))
    from oracles import random_tree

    return random_tree(7, 42)


def trees() -> dict[str, Tree]:
    out = {name: dynid.load_model(name).tree for name in ("puma560", "tx40", "floating_tree")}
    return out


def states(tree: Tree, N: int = 6, seed: int = 3):
    rng = np.random.default_rng(seed)
    return rng.uniform(-np.pi, np.pi, (N, tree.n)), rng.normal(size=(N, tree.n)), rng.normal(size=(N, tree.n))


def close(a: np.ndarray, b: np.ndarray, rtol: float = RTOL) -> None:
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape
    scale = max(1.0, float(np.abs(b).max()))
    assert np.abs(a - b).max() <= rtol * scale, np.abs(a - b).max() / scale


def evaluate(prog, tree):
    ns: dict = {}
    exec(compile(to_numpy(prog, tree), "<generated>", "exec"), ns)
    return ns["evaluate"]


CASES = ["puma560", "tx40", "floating_tree", "random42", "tx40_curves"]


def with_curves(tree: Tree) -> Tree:
    """Every moving joint with a viscous curve besides its other terms (four slopes about knees inside the states'
    N(0, 1) velocities, one joint without a rebound knee), random slopes."""
    rng = np.random.default_rng(11)
    moving = [f.j for f in tree.frames if f.sigma != 2]
    knees = {j: (-float(rng.uniform(0.1, 0.8)), float(rng.uniform(0.1, 0.8))) for j in moving}
    knees[moving[0]] = (-math.inf, knees[moving[0]][1])
    curve = {j: ("FVPL", "FVPH", "FVNL", *(("FVNH",) if j != moving[0] else ())) for j in moving}
    terms = {j: (*tree.joint_terms.get(j, ()), *curve[j]) for j in moving}
    t = dataclasses.replace(tree, joint_terms=terms, knees=knees)
    return t.with_values({f"{c}{j}": float(rng.uniform(0.5, 2.0)) for j in moving for c in curve[j]})


def get_tree(name: str) -> Tree:
    if name == "tx40_curves":
        return with_curves(dynid.load_model("tx40").tree)
    return random42() if name == "random42" else dynid.load_model(name).tree


@pytest.mark.parametrize("name", CASES)
def test_generated_numpy_agrees_with_engine(name):
    tree = get_tree(name)
    m = Model(tree)
    q, qd, qdd = states(tree)
    close(evaluate(dgm(tree), tree)(q), m.transforms(q))
    close(evaluate(idm(tree), tree)(q, qd, qdd), m.inverse_dynamics(q, qd, qdd))
    X = np.random.default_rng(1).normal(size=tree.p)
    close(evaluate(idm(tree), tree)(q, qd, qdd, X), m.inverse_dynamics(q, qd, qdd, X=X))
    close(evaluate(regressor(tree), tree)(q, qd, qdd), m.regressor(q, qd, qdd))
    close(evaluate(inertia(tree), tree)(q), m.inertia_matrix(q))
    close(evaluate(inertia(tree, parameters="numeric"), tree)(q), m.inertia_matrix(q))
    # one sample in, one sample out
    close(evaluate(idm(tree), tree)(q[0], qd[0], qdd[0]), m.inverse_dynamics(q, qd, qdd)[0])


@pytest.mark.parametrize("name", ["puma560", "floating_tree"])
def test_symbolic_geometry_agrees_with_engine(name):
    tree = get_tree(name)
    m = Model(tree)
    q, qd, qdd = states(tree)
    prog = regressor(tree, geometry="symbolic")
    assert prog.constants  # D3, RL4 ... stay symbols
    close(evaluate(prog, tree)(q, qd, qdd), m.regressor(q, qd, qdd))
    close(evaluate(idm(tree, geometry="symbolic"), tree)(q, qd, qdd), m.inverse_dynamics(q, qd, qdd))


def test_restricted_identification_model_of_the_car():
    tree = car_template()
    m = Model(tree)
    q, qd, qdd = states(tree, 5)
    prog = regressor(tree, rows=CAR_ROWS, cols=CAR_COLS)
    assert prog.shape == (14, 48)
    close(evaluate(prog, tree)(q, qd, qdd), m.regressor(q, qd, qdd, rows=CAR_ROWS, cols=CAR_COLS))


def test_external_wrenches_in_idm_and_regressor():
    tree = get_tree("floating_tree")
    m = Model(tree)
    q, qd, qdd = states(tree)
    N = q.shape[0]
    rng = np.random.default_rng(5)
    sites = [WrenchSite(10, (0.1, -0.2, 0.05), None), WrenchSite(8, (0.0, 0.0, 0.3), 0), WrenchSite(6, (0, 0, 0), 9)]
    vals = rng.normal(size=(N, len(sites), 6))
    wrenches = [dynid.Wrench(s.link, vals[:, i], s.point, s.frame) for i, s in enumerate(sites)]
    tau = m.inverse_dynamics(q, qd, qdd, wrenches)
    close(evaluate(idm(tree, wrenches=sites), tree)(q, qd, qdd, None, vals), tau)
    W, Q = evaluate(regressor(tree, wrenches=sites), tree)(q, qd, qdd, vals)
    We, Qe = m.regressor(q, qd, qdd, wrenches)
    close(W, We)
    close(Q, Qe)
    close(np.einsum("nij,j->ni", W, tree.parameters) - Q, tau)


def _namespace(prog, tree, **settings) -> dict:
    """The generated module's namespace, with module settings (CHUNK, POOL_MIN) overridden."""
    ns: dict = {}
    exec(compile(to_numpy(prog, tree), "<generated>", "exec"), ns)
    ns.update(settings)
    return ns


@pytest.mark.parametrize("N, chunk", [(1, 4), (3, 4), (4, 4), (5, 4), (11, 4), (9, 1), (0, 4)])
def test_generated_numpy_over_chunk_boundaries(N, chunk):
    tree = get_tree("puma560")
    m = Model(tree)
    q, qd, qdd = states(tree, max(N, 1), seed=N)
    q, qd, qdd = q[:N], qd[:N], qdd[:N]
    ns = _namespace(regressor(tree), tree, CHUNK=chunk)
    W = ns["evaluate"](q, qd, qdd)
    assert W.shape == (N, 6, tree.p)
    if N:
        close(W, m.regressor(q, qd, qdd))
    tau = _namespace(idm(tree), tree, CHUNK=chunk)["evaluate"](q, qd, qdd)
    assert tau.shape == (N, 6)
    if N:
        close(tau, m.inverse_dynamics(q, qd, qdd))


def test_generated_numpy_output_layout_and_single_sample():
    tree = get_tree("tx40")
    m = Model(tree)
    q, qd, qdd = states(tree, 7)
    f = evaluate(regressor(tree), tree)
    W = f(q, qd, qdd)
    # a view (N, rows, cols) of a C-ordered (rows * cols, N) buffer: one contiguous row per entry
    assert W.shape == (7, 6, tree.p) and W.base is not None and W.base.shape == (6 * tree.p, 7)
    assert W.transpose(1, 2, 0).flags.c_contiguous and not W.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        W[0, 0, 0] = 1.0
    w1 = f(q[2], qd[2], qdd[2])
    assert w1.shape == (6, tree.p)
    close(w1, m.regressor(q, qd, qdd)[2])
    # inputs in any layout
    close(f(np.asfortranarray(q), qd[:, :].copy(order="F"), qdd), m.regressor(q, qd, qdd))


@pytest.mark.parametrize("readonly", [True, False])
def test_generated_numpy_reuses_only_dropped_buffers(readonly):
    tree = get_tree("puma560")
    m = Model(tree)
    q, qd, qdd = states(tree, 9)
    ref = m.regressor(q, qd, qdd)
    ns = _namespace(regressor(tree), tree, POOL_MIN=0, CHUNK=4, READONLY=readonly)
    f = ns["evaluate"]
    a = f(q, qd, qdd)
    a_copy = a.copy()
    b = f(q[::-1], qd[::-1], qdd[::-1])  # a is held: b gets another buffer
    assert not np.shares_memory(a, b)
    np.testing.assert_array_equal(a, a_copy)
    address = a.base.__array_interface__["data"][0]
    if readonly:
        with pytest.raises(ValueError, match="read-only"):
            a[...] = 7.0
        with pytest.raises(ValueError):  # nor can it be made writeable: the buffer's zero rows stay zero
            a.base.flags.writeable = True
    else:
        a[...] = 7.0  # the caller writes into a result, then drops it: the buffer is cleared before reuse
    view = a[1:]  # a view of a result holds the buffer too
    del a
    c = f(q, qd, qdd)
    assert not np.shares_memory(c, view)
    del view, c
    c = f(q, qd, qdd)
    assert c.base.__array_interface__["data"][0] == address  # reused...
    close(c, ref)  # ...with its structural zeros zero again
    close(b, ref[::-1])
    del c
    d = f(q, qd, qdd)  # reused without clearing (read-only) or cleared: still right
    close(d, ref)
    ns["release"]()
    assert not ns["_POOL"]


def test_generated_numpy_from_two_threads():
    from concurrent.futures import ThreadPoolExecutor

    tree = get_tree("puma560")
    m = Model(tree)
    ns = _namespace(regressor(tree), tree, POOL_MIN=0, CHUNK=16)
    runs = [states(tree, 40 + k, seed=k) for k in range(8)]
    with ThreadPoolExecutor(2) as pool:
        results = list(pool.map(lambda s: ns["evaluate"](*s), runs))
    for (q, qd, qdd), W in zip(runs, results, strict=True):
        close(W, m.regressor(q, qd, qdd))


def test_generated_sincos_against_libm():
    ns = _namespace(regressor(get_tree("puma560")), get_tree("puma560"))
    rng = np.random.default_rng(0)
    xs = [np.linspace(-20.0, 20.0, 4001), rng.uniform(-9.9e4, 9.9e4, 4000), np.arange(-64, 64) * np.pi / 4,
          np.array([0.0, 1e-300, -3.0, 1e5 + 1.0, -1e7]), np.array([np.nan, 1.0, np.inf])]
    rows = trig.numpy_rows()
    for x in xs:
        s, c, w, k = np.empty_like(x), np.empty_like(x), np.empty((rows, x.size)), np.empty(x.size, np.int64)
        with np.errstate(invalid="ignore"):
            ns["_sincos"](x, s, c, k, *w)
            es, ec = np.sin(x), np.cos(x)
        np.testing.assert_allclose(s, es, rtol=0, atol=3e-16)
        np.testing.assert_allclose(c, ec, rtol=0, atol=3e-16)


@pytest.mark.parametrize("name", ["floating_tree", "car"])
def test_both_projections_of_the_regressor_agree_with_engine(name):
    """W and Q through the joints' unit twists or through wrenches moved back (models._regressor)."""
    from dynid.symbolic.models import _regressor

    tree = car_template() if name == "car" else get_tree(name)
    m = Model(tree)
    q, qd, qdd = states(tree, 5)
    N = q.shape[0]
    if name == "car":
        rows, cols = list(CAR_ROWS), list(CAR_COLS)
        sites = [WrenchSite(k, (0.0, 0.0, 0.0), k) for k in (15, 24, 33, 42)] + [WrenchSite(6, (0.5, 0.0, 0.2))]
    else:
        rows, cols = None, None
        sites = [WrenchSite(10, (0.1, -0.2, 0.05), None), WrenchSite(8, (0.0, 0.0, 0.3), 0), WrenchSite(6)]
    vals = np.random.default_rng(5).normal(size=(N, len(sites), 6))
    wrenches = [dynid.Wrench(s.link, vals[:, i], s.point, s.frame) for i, s in enumerate(sites)]
    We, Qe = m.regressor(q, qd, qdd, wrenches, rows=rows, cols=cols)
    counts = set()
    for back_w in (False, True):
        for back_q in (False, True):
            prog = _regressor(tree, rows, cols, "numeric", sites, back_w, back_q)
            W, Q = evaluate(prog, tree)(q, qd, qdd, vals)
            close(W, We)
            close(Q, Qe)
            counts.add((prog.ops().mult, prog.ops().add))
    best = regressor(tree, rows=rows, cols=cols, wrenches=sites).ops()
    assert all(best.mult <= a or best.add <= b for a, b in counts)
    if name == "car":  # long corners, few parameters: moving the wrenches back pays
        assert (best.mult, best.add) == min(counts)


@pytest.mark.slow
def test_generated_text_does_not_depend_on_the_hash_seed():
    code = (
        "import hashlib, dynid\n"
        "from dynid.symbolic import build, to_c, to_numpy, to_text\n"
        "from dynid.vehicle import car_template\n"
        "from dynid.vehicle.template import EQUATION_ROWS, paper_parameter_names\n"
        "car, puma = car_template(), dynid.load_model('puma560').tree\n"
        "progs = [(build(car, 'regressor', rows=EQUATION_ROWS, cols=paper_parameter_names()), car),\n"
        "         (build(car, 'idm'), car), (build(puma, 'regressor'), puma), (build(puma, 'inertia'), puma)]\n"
        "text = ''.join(to_numpy(p, t) + ''.join(to_c(p)) + to_text(p) for p, t in progs)\n"
        "print(hashlib.sha256(text.encode()).hexdigest())\n"
    )
    digests = set()
    for seed in ("0", "1", "12345"):
        path = os.pathsep.join([str(Path(dynid.__file__).parents[1]), os.environ.get("PYTHONPATH", "")])
        env = {**os.environ, "PYTHONHASHSEED": seed, "PYTHONPATH": path}
        res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
        digests.add(res.stdout.strip())
    assert len(digests) == 1


def test_generated_numpy_rejects_clashing_names():
    from dynid.model import Coupling

    tree = Tree("clash", (Frame(1, 0, 0), Frame(2, 1, 0, alpha=0.3)), couplings=(Coupling("_t0", "FV", {2: 1.0}),),
                values={"M2": 1.0, "MX2": 0.1})
    with pytest.raises(SymbolicError, match="clashes"):
        to_numpy(idm(tree), tree)


def _compile(tmp_path: Path, prog, stem: str):
    lib = compile_generated_c(tmp_path, prog, stem)
    return getattr(lib, f"{stem}_{prog.model}_batch")


def _call(fn, N, *arrays, out_shapes):
    P = ctypes.POINTER(ctypes.c_double)
    arrays = [np.ascontiguousarray(a, dtype=float) for a in arrays]
    outs = [np.full((N, *s), np.nan) for s in out_shapes]
    fn(ctypes.c_long(N), *[a.ctypes.data_as(P) for a in arrays], *[o.ctypes.data_as(P) for o in outs])
    return outs


# The 42-frame random tree's C takes the compiler about a minute.
@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n == "random42" else n for n in CASES])
def test_generated_c_agrees_with_engine(name, tmp_path):
    tree = get_tree(name)
    m = Model(tree)
    q, qd, qdd = states(tree)
    N = q.shape[0]
    X = tree.parameters
    progs = {"idm": idm(tree), "regressor": regressor(tree), "inertia": inertia(tree), "dgm": dgm(tree)}
    if name not in ("puma560", "random42"):
        progs = {k: v for k, v in progs.items() if k in ("idm", "regressor")}
    args = {"idm": (q, qd, qdd, X), "regressor": (q, qd, qdd), "inertia": (q, X), "dgm": (q,)}
    ref = {"idm": lambda: m.inverse_dynamics(q, qd, qdd), "regressor": lambda: m.regressor(q, qd, qdd),
           "inertia": lambda: m.inertia_matrix(q), "dgm": lambda: m.transforms(q)}
    for model, prog in progs.items():
        fn = _compile(tmp_path, prog, name)
        (out,) = _call(fn, N, *args[model], out_shapes=[prog.shape])
        close(out, ref[model]())


def test_generated_c_with_wrench(tmp_path):
    tree = get_tree("puma560")
    m = Model(tree)
    q, qd, qdd = states(tree)
    N = q.shape[0]
    sites = [WrenchSite(6, (0.0, 0.0, 0.1), 0)]
    vals = np.random.default_rng(2).normal(size=(N, 1, 6))
    fn = _compile(tmp_path, idm(tree, wrenches=sites), "pumaw")
    (out,) = _call(fn, N, q, qd, qdd, tree.parameters, vals, out_shapes=[(6,)])
    close(out, m.inverse_dynamics(q, qd, qdd, [dynid.Wrench(6, vals[:, 0], (0.0, 0.0, 0.1), 0)]))


@pytest.mark.parametrize("name", ["puma560", "tx40"])
def test_symbolic_regrouping_equals_numeric_base_parameters(name):
    tree = get_tree(name)
    sym_ = base_parameters(tree)
    num = Model(tree).base_parameters()
    assert sym_.rank == num.rank
    assert sym_.names == num.names
    Bn = np.zeros((num.rank, tree.p))
    Bn[np.arange(num.rank), list(num.columns)] = 1.0
    Bn[:, list(num.regrouped_columns)] += num.beta
    # same combinations, row by row, up to a scaling of each row
    Bs = sym_.matrix()
    for r in range(num.rank):
        k = np.argmax(np.abs(Bn[r]))
        np.testing.assert_allclose(Bs[r] * (Bn[r, k] / Bs[r, k]), Bn[r], atol=1e-8)
    # symbolic geometry gives the same numbers
    np.testing.assert_allclose(base_parameters(tree, geometry="symbolic").matrix(), Bs, atol=1e-12)


def test_puma_regrouping_follows_khalils_formulas():
    tree = get_tree("puma560")
    bp = base_parameters(tree, geometry="symbolic")
    # Khalil & Dombre, PUMA 560 (joint 3 parallel to joint 2, at distance D3 along x2)
    assert bp.expression("XX2") == "XX2 - YY2 - D3**2*M3 - D3**2*M4 - D3**2*M5 - D3**2*M6"
    assert bp.expression("MX2") == "MX2 + D3*M3 + D3*M4 + D3*M5 + D3*M6"
    assert bp.expression("MY3").startswith("MY3 + MZ4 + RL4*M4")
    assert bp.expression("XX6") == "XX6 - YY6"
    assert "XX2" not in bp.numeric and "MY3" not in bp.numeric


def test_idm_operation_count_of_a_6r_arm_with_tool_wrench():
    """OpenSYMORO's customised RX90 model: 389 mult, 340 add (all standard parameters, IA, FV, FS, wrench)."""
    h = math.pi / 2
    frames = (Frame(1, 0, 0), Frame(2, 1, 0, alpha=h), Frame(3, 2, 0, d=0.45), Frame(4, 3, 0, alpha=-h, r=0.45),
              Frame(5, 4, 0, alpha=h), Frame(6, 5, 0, alpha=-h))
    tree = Tree("RX90", frames, joint_terms={j: ("IA", "FV", "FS") for j in range(1, 7)})
    ops = idm(tree, wrenches=[WrenchSite(6)]).ops()
    assert ops.mult <= 389 and ops.add <= 340, ops
    for name in ("puma560", "tx40"):
        ops = idm(get_tree(name), wrenches=[WrenchSite(6)]).ops()
        assert ops.mult <= 389 and ops.add <= 340, (name, ops)


def test_readable_equations():
    tree = get_tree("puma560")
    text = to_text(dgm(tree))
    assert "C23 = cos(q2 + q3)" in text and "S23 = sin(q2 + q3)" in text
    text = to_text(idm(tree))
    names = ("WI12", "WP33", "DV115", "U115", "VP13", "F16", "No16", "FDI16", "E15", "NDI36", "GAM1")
    for name in names:
        assert f"  {name} = " in text, name
    # no zero or unit term is ever written out
    import re

    eqs = text.split("Outputs")[0]
    assert not re.search(r"(?<![0-9.])(0\.0|1\.0)\*|\*(0\.0|1\.0)(?![0-9])|[+-] 0\.0(?![0-9])", eqs)


def test_to_sympy_agrees_with_numpy():
    import sympy

    tree = get_tree("puma560")
    prog = dgm(tree)
    eqs, outs = prog.to_sympy()
    q = states(tree, 1)[0][0]
    env = {sympy.Symbol(f"q{j}", real=True): q[j - 1] for j in range(1, 7)}
    for s, e in eqs:
        env[s] = float(e.subs(env))
    ref = Model(tree).transforms(q[None])[0]
    for idx, e in outs:
        assert abs(float(e.subs(env)) - ref[idx]) < 1e-12


def test_numpy_module_is_cached_on_disk(tmp_path):
    tree = get_tree("tx40")
    mod = numpy_module(tree, "regressor", rows=[1, 2], cols=["ZZ1", "M2", "fvm6"])
    path = Path(mod.__file__)
    assert path.parent.parent == tmp_path / "cache" and path.exists()
    q, qd, qdd = states(tree)
    close(mod.evaluate(q, qd, qdd), Model(tree).regressor(q, qd, qdd, rows=[1, 2], cols=["ZZ1", "M2", "fvm6"]))
    from dynid.symbolic import cache

    cache._LOADED.clear()
    path.write_text("this is not python")  # a damaged cache file is regenerated, not trusted
    mod2 = numpy_module(tree, "regressor", rows=[1, 2], cols=["ZZ1", "M2", "fvm6"])
    close(mod2.evaluate(q, qd, qdd), mod.evaluate(q, qd, qdd))
    other = numpy_module(tree.with_values({"M2": 9.0}), "idm")
    assert other.HASH != mod.HASH


def test_one_loader_for_generated_modules(tmp_path, monkeypatch):
    """cache.load_module: generated once, then from memory and from disk (the source is not asked again); a file
    of another key or a damaged one is generated again; a read-only cache gives a module in memory whose
    functions inspect can read (llvm_code translates their source). Oracle: the files and calls counted."""
    import inspect

    from dynid.symbolic import cache

    calls = []

    def source(value: int):
        def text() -> str:
            calls.append(value)
            return f"def f(x):\n    return x + {value}\n"
        return text

    mod = cache.load_module("test", "dynid_test_loader_a", "k1", source(1))
    path = cache.module_path("test", "dynid_test_loader_a")
    assert Path(mod.__file__) == path and mod.f(1) == 2 and mod.KEY == "k1" and calls == [1]
    assert cache.load_module("test", "dynid_test_loader_a", "k1", source(2)) is mod and calls == [1]  # memory
    cache._LOADED.clear()
    assert cache.load_module("test", "dynid_test_loader_a", "k1", None).f(1) == 2 and calls == [1]  # disk
    cache._LOADED.clear()
    assert cache.load_module("test", "dynid_test_loader_a", "k2", source(3)).f(1) == 4  # another key: again
    assert calls == [1, 3] and "k2" in path.read_text()
    cache._LOADED.clear()
    path.write_text("def f(x):\n    return (\n")  # damaged: generated again
    assert cache.load_module("test", "dynid_test_loader_a", "k2", source(4)).f(1) == 5 and calls == [1, 3, 4]
    cache._LOADED.clear()
    assert cache.load_module("test", "dynid_test_loader_b", "k1", None) is None  # cache only: not there
    readonly = tmp_path / "readonly"
    readonly.mkdir()
    monkeypatch.setenv("DYNID_CACHE", str(readonly))
    monkeypatch.setattr(cache, "write_atomic", lambda path, text: (_ for _ in ()).throw(PermissionError(path)))
    mem = cache.load_module("test", "dynid_test_loader_c", "k1", source(5))
    assert getattr(mem, "__file__", None) is None and mem.f(1) == 6 and "return x + 5" in inspect.getsource(mem.f)
    assert not list(readonly.rglob("*.py"))


def test_bad_input_gives_a_clear_error():
    tree = get_tree("puma560")
    with pytest.raises(SymbolicError, match="unknown model"):
        build(tree, "forward")
    with pytest.raises(SymbolicError, match="takes no option"):
        build(tree, "dgm", rows=[1])
    with pytest.raises(SymbolicError, match="row 9"):
        regressor(tree, rows=[9])
    with pytest.raises(SymbolicError, match="no parameter"):
        regressor(tree, cols=["XX9"])
    with pytest.raises(SymbolicError, match="link 7"):
        idm(tree, wrenches=[WrenchSite(7)])
    with pytest.raises(SymbolicError, match="geometry"):
        idm(tree, geometry="exact")
    with pytest.raises(SymbolicError, match="Tree"):
        idm("puma560")
    # a coupling whose name clashes with an intermediate variable
    from dynid.model import Coupling

    clash = Tree("clash", (Frame(1, 0, 0), Frame(2, 1, 0, alpha=0.3)), couplings=(Coupling("C2", "FV", {2: 1.0}),),
                 values={"M2": 1.0, "MX2": 0.1})
    with pytest.raises(SymbolicError, match="rename"):
        idm(clash)


Q_FLOAT = np.array([0.3, -0.2, 0.5, 0.4, -0.7, 1.1, 0.25, 0.05, -0.6, 0.0])


def _eval_text_dgm(text: str, q: np.ndarray) -> np.ndarray:
    """The transforms a written text DGM gives at q: its equations run as Python (cos, sin and names), its
    outputs "Tj[r, c] = expr" (1-based) read into (n+1, 4, 4)."""
    equations, outputs = text.split("\nOutputs")
    env = {"cos": math.cos, "sin": math.sin} | {f"q{j + 1}": float(v) for j, v in enumerate(q)}
    for line in equations.splitlines():
        if " = " in line and line.startswith("  "):
            name, expr = line.strip().split(" = ")
            env[name] = eval(expr, {"__builtins__": {}}, env)
    rows = [line.strip() for line in outputs.splitlines()[1:] if line.startswith("  T")]
    T = np.zeros((q.size + 1, 4, 4))
    for line in rows:
        target, expr = line.split(" = ")
        j, rc = target[1:].split("[")
        r, c = (int(x) for x in rc.rstrip("]").split(","))
        T[int(j), r - 1, c - 1] = eval(expr, {"__builtins__": {}}, env)
    return T


def test_cli_ops_and_codegen(tmp_path, capsys):
    from dynid.cli.main import main

    assert main(["model", "ops", "puma560"]) == 0
    out = capsys.readouterr().out
    assert "regressor" in out and "mult" in out
    assert main(["model", "codegen", "tx40", "--lang", "c", "--model", "idm", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "staubli_tx40_idm.h").exists() and (tmp_path / "staubli_tx40_idm.c").exists()
    assert main(["model", "codegen", "puma560", "--lang", "numpy", "--model", "regressor", "--rows", "1,2",
                 "--cols", "ZZ1,XX2", "--out", str(tmp_path)]) == 0
    assert main(["model", "codegen", "floating_tree", "--lang", "text", "--model", "dgm", "--out", str(tmp_path)]) == 0
    T = _eval_text_dgm((tmp_path / "floating_tree_dgm.txt").read_text(), Q_FLOAT)
    np.testing.assert_allclose(T, dynid.load_model("floating_tree").transforms(Q_FLOAT), rtol=0, atol=1e-12)
    assert main(["model", "codegen", "puma560", "--lang", "text", "--model", "regressor", "--cols", "XX9",
                 "--out", str(tmp_path)]) == 2
    assert "no parameter" in capsys.readouterr().err
