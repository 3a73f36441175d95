"""Generated straight-line code compiled from LLVM IR (dynid.symbolic.llvm_code): the same numbers, to the
bit, as Numba's compile of the same source and as the source run by Python; what it cannot translate
is compiled by Numba from Python, with a warning."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from oracles import trig_edge_angles

from dynid.symbolic import numba_backend as nb
from dynid.symbolic.llvm_code import UnsupportedSourceError, function_ir

pytest.importorskip("numba")

BODY = '''
def {name}(q, wrench, out, extra):
    """A model in the generated language: reads, constants, + - *, unary -, sin, cos, _sign, writes."""
    c1 = 0.1
    a = q[0]
    b = q[1]
    w = wrench[1, 4]
    s = _sin(a)
    c = _cos(b)
    e = -(a * s - b * c) * c1 + 3 * w
    out[0] = e * e - a
    out[2] = _sign(a) + _sign(b) * 2.0 + _sign(w - w)
    out[3] = -e
    extra[:] = 0.0
    extra[5] = wrench[0, 0] * q[2] + 1.0000000000000002
    return 0
'''


def _python(name: str, body: str):
    ns: dict = {}
    exec(compile(nb.HEADER + body, "<test>", "exec"), ns)
    return ns[name]


def test_straight_line_code_is_numbas_to_the_bit(tmp_path, monkeypatch):
    monkeypatch.setenv("DYNID_CACHE", str(tmp_path))
    body = BODY.format(name="f") + BODY.format(name="g")
    mod = nb.compile_source(body, ["f", "g"], nb.source_key("test straight line", body), prefix="dynid_test",
                            straight=["f"])
    text = nb.cached_module_path(mod.KEY, "dynid_test").read_text()
    assert "_ir_f = straight_line(f," in text and "straight_line(g," not in text  # f from IR, g by numba
    plain = _python("f", BODY.format(name="f"))
    rng = np.random.default_rng(3)
    for k in range(20):
        q = rng.normal(size=3) * 10.0 ** rng.integers(-3, 4)
        if k == 0:
            q[:] = [0.0, -0.0, 1.0]  # _sign of zeros
        wrench = rng.normal(size=(2, 6))
        outs = []
        for fn in (mod.f, mod.g, plain):
            out, extra = np.full(4, 7.0), np.full(6, 7.0)
            assert fn(q, wrench, out, extra) == 0
            outs.append(np.concatenate([out, extra]))
        assert np.array_equal(outs[0], outs[1]) and np.array_equal(outs[0], outs[2]), k
        assert outs[0][1] == 7.0 and not np.any(outs[0][4:9])  # unwritten entry kept; extra[:] cleared


@pytest.mark.parametrize("line", ["out[0] = q[0] / q[1]", "out[0] = q[0] ** 2", "out[int(q[0])] = 1.0",
                                  "out[:] = 1.0", "x = np.sin(q[0])", "out[0] = y"])
def test_what_it_cannot_translate_is_refused(line):
    src = f"def f(q, out):\n    {line}\n    return 0\n"
    with pytest.raises(UnsupportedSourceError):
        function_ir(src, "f")


def test_unsupported_source_falls_back_to_numba(tmp_path, monkeypatch):
    monkeypatch.setenv("DYNID_CACHE", str(tmp_path))
    body = "def h(q, out):\n    out[0] = q[0] / q[1]\n    return 0\n"
    with pytest.warns(RuntimeWarning, match="compiled by numba from Python"):
        mod = nb.compile_source(body, ["h"], nb.source_key("test fallback", body), prefix="dynid_test",
                                straight=["h"])
    out = np.zeros(1)
    mod.h(np.array([1.0, 4.0]), out)
    assert out[0] == 0.25


def test_simulator_models_are_their_python_source_to_the_bit():
    """car_kin, car_idm and car_inertia (from LLVM IR into native code, called by address) equal their generated
    Python run by Python."""
    from dynid.vehicle.sim import CarSimulator, kernel
    from dynid.vehicle.sim.car import _models_source

    sim = CarSimulator()
    body = "\n".join(_models_source(sim.tree, sim.aero_point).values())
    ns: dict = {}
    exec(compile(nb.HEADER + body, "<simulator models>", "exec"), ns)
    rng = np.random.default_rng(5)
    rest = sim.initial_state(20.0)
    for _ in range(3):
        q = np.zeros(42)
        q[np.array(kernel.FREE) - 1] = rest[:kernel.NF] + 0.01 * rng.normal(size=kernel.NF)
        qd, qdd = rng.normal(size=42), rng.normal(size=42)
        wrench = rng.normal(size=(5, 6)) * 1e3
        for name, args, size in (("car_kin", (q, qd), kernel.NKIN), ("car_idm", (q, qd, qdd, wrench), 42),
                                 ("car_inertia", (q,), kernel.NF * kernel.NF_ROW)):
            a, b = np.full(size, np.nan), np.full(size, np.nan)
            sim.models.python[name](*args, a)
            ns[name](*args, b)
            assert np.array_equal(a, b), name


def test_native_functions_are_the_python_source_to_the_bit_and_load_from_disk(tmp_path, monkeypatch):
    """native_functions: machine code from the IR equals the source run by Python, to the bit; a second load
    (a new process's: the in-memory registry cleared) comes from the object code on disk and gives the same; a
    file made for another CPU is built again, never loaded."""
    import pickle

    from dynid.symbolic import cache

    monkeypatch.setenv("DYNID_CACHE", str(tmp_path))
    body = BODY.format(name="f")
    key = nb.source_key("test native", body)
    rng = np.random.default_rng(11)
    q, wrench = rng.normal(size=3), rng.normal(size=(2, 6))
    want = (np.full(4, 7.0), np.full(6, 7.0))
    _python("f", body)(q, wrench, *want)
    built = []

    def sources():
        built.append(1)
        return {"f": body}

    for round_ in range(3):
        cache._LOADED.clear()
        fns = nb.native_functions(key, sources, prefix="dynid_test")
        out, extra = np.full(4, 7.0), np.full(6, 7.0)
        fns.python["f"](q, wrench, out, extra)
        assert np.array_equal(out, want[0]) and np.array_equal(extra, want[1]), round_
        if round_ == 1:
            assert len(built) == 1  # loaded, not built
            path = next(tmp_path.rglob("dynid_test_*.lib"))
            stored = pickle.loads(path.read_bytes())
            stored["state"] = (("another", "cpu", ""), stored["state"][1])
            path.write_bytes(pickle.dumps(stored))
    assert len(built) == 2  # the foreign file was built again


def test_internal_functions_compile_without_entry_points(tmp_path, monkeypatch):
    """compile_source(internal=...): a helper only jitted code calls, of the body or imported, is compiled without
    Python and C entry points (the simulator's kernel: issue 28), the caller's numbers unchanged; the imported
    dispatcher itself keeps its entry point for Python."""
    from dynid.vehicle.table_poly import _cell

    monkeypatch.setenv("DYNID_CACHE", str(tmp_path))
    body = ("from dynid.vehicle.table_poly import _cell\n\n\ndef twice(a, i):\n    return 2.0 * a[i]\n\n\n"
            "def entry(b, x):\n    return twice(b, _cell(b, b.size - 1, x))\n")
    mod = nb.compile_source(body, ["twice", "entry"], nb.source_key("test internal", body), prefix="dynid_test",
                            internal=["twice", "_cell"])
    b = np.array([0.0, 1.0, 2.0, 3.0])
    assert mod.entry(b, 1.5) == 2.0 and mod.entry(b, 2.5) == 4.0
    for f in (mod.twice, mod._cell):
        assert f.targetoptions["no_cpython_wrapper"] and f.targetoptions["no_cfunc_wrapper"]
    assert mod._cell is not _cell and _cell(b, 3, 2.5) == 2  # the original, unchanged, from Python


def test_internal_functions_are_linked_into_their_callers_not_emitted(tmp_path, monkeypatch):
    """compile_source(internal=...): a helper only jitted code calls is kept as LLVM IR (link_only: no module
    optimisation, no machine code, not cached) and linked into its caller's library, which alone is emitted and
    cached; the caller's numbers are those of the same body compiled with the helpers emitted as usual (the oracle,
    to the bit: a loop, a division, libm's atan and tanh)."""
    from numba.core.caching import NullCache
    from numba.core.codegen import JITCodeLibrary

    from dynid.symbolic.link_only import LinkOnlyLibrary

    monkeypatch.setenv("DYNID_CACHE", str(tmp_path))
    body = ("import math\n\n\ndef helper(a, x):\n    s = 0.0\n    for v in a:\n        s += math.atan(v / x)\n"
            "    return s\n\n\ndef entry(a, x):\n    return math.tanh(helper(a, x)) / 3.0 + helper(a, 2.0 * x)\n")
    key = nb.source_key("test link only", body)
    linked = nb.compile_source(body, ["helper", "entry"], key, prefix="dynid_test_link", internal=["helper"])
    usual = nb.compile_source(body, ["helper", "entry"], key, prefix="dynid_test_usual")
    a = np.linspace(-3.0, 7.0, 101)
    for x in (0.1, 0.7, 1.0 / 3.0, 5.0):
        assert linked.entry(a, x) == usual.entry(a, x), x
    (sig,) = linked.helper.signatures
    lib = linked.helper.overloads[sig].library
    assert isinstance(lib, LinkOnlyLibrary) and lib.get_pointer_to_function("anything") == 0
    assert type(linked.entry.overloads[linked.entry.signatures[0]].library) is JITCodeLibrary
    assert isinstance(linked.helper._cache, NullCache)  # not cached: its code is, in entry's
    assert os.path.exists(linked.entry._cache._cache_file._index_path)


def test_a_numba_without_what_link_only_uses_compiles_the_usual_way(tmp_path, monkeypatch):
    """Where Numba's private code library lacks what LinkOnlyLibrary uses (another version), a helper compiles the
    usual way, with the same numbers, instead of failing: simulated by asking for an attribute no version has."""
    from dynid.symbolic import link_only

    monkeypatch.setenv("DYNID_CACHE", str(tmp_path))
    monkeypatch.setattr(link_only, "_USED", (*link_only._USED, "_no_such_attribute"))
    monkeypatch.setattr(link_only, "_FITS", [])
    body = "def helper(x):\n    return x / 3.0\n\n\ndef entry(x):\n    return helper(x) + 1.0\n"
    mod = nb.compile_source(body, ["helper", "entry"], nb.source_key("test link only off", body),
                            prefix="dynid_test_link_off", internal=["helper"])
    assert mod.entry(2.0) == 2.0 / 3.0 + 1.0
    (sig,) = mod.helper.signatures
    assert not isinstance(mod.helper.overloads[sig].library, link_only.LinkOnlyLibrary)
    assert link_only._FITS == [False]


def test_generated_sine_and_cosine_are_trigs_to_the_bit(tmp_path, monkeypatch):
    """A generated model's sine and cosine (a revolute joint's dgm: T1 holds cos q1 and sin q1) are
    dynamics.trig's, run by Python, to the bit: compiled from LLVM IR (native_functions: the simulator's models;
    straight_line) and by Numba from the Python source, on the edges of the quadrants (multiples of pi/4 and their
    neighbours), small, large and out-of-range angles (|x| >= trig.LIMIT, inf, NaN: libm's), no contraction into
    FMA on any CPU. libm's (the scalar IR's sine before) differs from them by an ulp on some of these angles."""
    from dynid.model import Frame, Tree
    from dynid.symbolic import build

    monkeypatch.setenv("DYNID_CACHE", str(tmp_path))
    x, want = trig_edge_angles(7)
    prog = build(Tree("one revolute joint", (Frame(1, 0, 0),)), "dgm")
    src = nb.scalar_source(prog, "dgm")
    assert "_sin(" in src and "math.sin" not in src
    key = nb.source_key("test trig", src)
    native = nb.native_functions(key, lambda: {"dgm": src}, prefix="dynid_test").python["dgm"]
    straight = nb.compile_source(src, ["dgm"], key, prefix="dynid_test_ir", straight=["dgm"]).dgm
    numba = nb.compile_source(src, ["dgm"], key, prefix="dynid_test_nb").dgm
    for label, fn in (("native", native), ("straight_line", straight), ("numba", numba)):
        got = np.empty_like(want)
        out = np.empty(32)
        for i, v in enumerate(x):
            fn(np.array([v]), out)
            got[i] = out[20], out[16]  # T1[1, 0] = sin q1, T1[0, 0] = cos q1
        finite = np.isfinite(x)
        assert np.array_equal(got[finite].view(np.int64), want[finite].view(np.int64)), (
            label, x[np.any(got != want, axis=1) & finite][:5])
        assert np.isnan(got[~finite]).all(), label
    assert not np.array_equal(np.sin(x[finite]), want[finite, 0])  # libm's: this test tells them apart


def _native_entry(tmp_path, monkeypatch, body: str, label: str):
    """(the library's cache file, a loader counting its builds, the numbers the source gives run by Python)."""
    from dynid.symbolic import cache

    monkeypatch.setenv("DYNID_CACHE", str(tmp_path))
    key = nb.source_key(label, body)
    rng = np.random.default_rng(12)
    q, wrench = rng.normal(size=3), rng.normal(size=(2, 6))
    want = np.full(4, 7.0), np.full(6, 7.0)
    _python("f", body)(q, wrench, *want)
    built = []

    def load():
        cache._LOADED.clear()  # a new process's loader
        fns = nb.native_functions(key, lambda: built.append(1) or {"f": body}, prefix="dynid_test")
        out, extra = np.full(4, 7.0), np.full(6, 7.0)
        fns.python["f"](q, wrench, out, extra)
        return np.concatenate([out, extra])

    return cache.module_path("numba", f"dynid_test_{key}").with_suffix(".lib"), load, built, np.concatenate(want)


@pytest.mark.parametrize("damage", ["truncated", "garbage", "empty"])
def test_a_damaged_library_entry_is_built_again(tmp_path, monkeypatch, damage):
    """cache.load_entry through native_functions: a truncated, overwritten or empty .lib is built again (never
    trusted) and written whole; the numbers are the source's, to the bit."""
    path, load, built, want = _native_entry(tmp_path, monkeypatch, BODY.format(name="f"), "test damaged")
    assert np.array_equal(load(), want) and len(built) == 1 and path.exists()
    whole = path.read_bytes()
    path.write_bytes({"truncated": whole[:len(whole) // 2], "garbage": b"\x80\x05not a pickle" * 50,
                      "empty": b""}[damage])
    assert np.array_equal(load(), want) and len(built) == 2
    assert path.read_bytes() != b"" and np.array_equal(load(), want) and len(built) == 2  # rewritten whole: loaded


def test_a_changed_source_gives_a_new_entry(tmp_path, monkeypatch):
    """A changed source (another constant) has another key (source_key), so another entry, built and giving the
    new numbers; the first entry stays; and a change to any file of the generator (here one digit of
    dynamics.trig's constants, in a copy) changes the generator's fingerprint that every key holds."""
    import shutil

    from dynid.dynamics import trig
    from dynid.symbolic import cache

    body = BODY.format(name="f")
    path1, load1, built1, want1 = _native_entry(tmp_path, monkeypatch, body, "test changed")
    changed = body.replace("c1 = 0.1", "c1 = 0.2")
    path2, load2, built2, want2 = _native_entry(tmp_path, monkeypatch, changed, "test changed")
    assert path1 != path2 and not np.array_equal(want1, want2)
    assert np.array_equal(load1(), want1) and np.array_equal(load2(), want2) and (built1, built2) == ([1], [1])
    assert path1.exists() and path2.exists()
    files = [*sorted(Path(cache.__file__).parent.glob("*.py")), Path(trig.__file__)]
    copies = []
    for f in files:
        shutil.copy(f, tmp_path / f.name)
        copies.append(tmp_path / f.name)
    assert cache.fingerprint(copies) == cache.fingerprint(files)
    text = copies[-1].read_text()
    copies[-1].write_text(text.replace("1.57079632673412561417e+00", "1.57079632673412561418e+00", 1))
    assert copies[-1].read_text() != text and cache.fingerprint(copies) != cache.fingerprint(files)


_WRITER = """
import sys, time
import numpy as np
from dynid.symbolic import numba_backend as nb
body, key, start = sys.argv[1], sys.argv[2], float(sys.argv[3])
while time.time() < start:  # both processes build and write at the same moment
    time.sleep(0.001)
fns = nb.native_functions(key, lambda: {"f": body}, prefix="dynid_test")
mod = nb.compile_source(body, ["f"], key, prefix="dynid_test_mod")
print("ok")
"""


def test_two_processes_writing_one_entry_leave_a_valid_one(tmp_path, monkeypatch):
    """Two processes building the same library and module at once into an empty cache: each writes its file
    atomically (cache.write_atomic: whole or not at all), so the entries that stay load without a build and give
    the source's numbers, and no partial file is left."""
    import subprocess
    import sys
    import time

    from dynid.symbolic import cache

    body = BODY.format(name="f")
    path, load, built, want = _native_entry(tmp_path, monkeypatch, body, "test concurrent")
    key = path.stem.removeprefix("dynid_test_")
    start = str(time.time() + 3.0)
    procs = [subprocess.Popen([sys.executable, "-c", _WRITER, body, key, start], stdout=subprocess.PIPE, text=True)
             for _ in range(2)]
    assert [p.communicate(timeout=600)[0].strip() for p in procs] == ["ok", "ok"]
    assert np.array_equal(load(), want) and built == []  # from the disk, not built
    cache._LOADED.clear()
    mod = cache.load_module("numba", f"dynid_test_mod_{key}", key, None)
    assert mod is not None and key == mod.KEY
    out, extra = np.full(4, 7.0), np.full(6, 7.0)
    rng = np.random.default_rng(12)
    mod.f(rng.normal(size=3), rng.normal(size=(2, 6)), out, extra)
    assert np.array_equal(np.concatenate([out, extra]), want)
    assert sorted(p.name for p in path.parent.iterdir() if not p.is_dir()) == sorted(
        [path.name, f"dynid_test_mod_{key}.py"])


def test_native_functions_without_numba_are_a_cached_module(tmp_path, monkeypatch):
    """Without numba, native_functions' functions are the source run by Python (the same numbers), kept as a
    generated module by the same loader (cache.load_entry): built once, then loaded from the disk."""
    path, load, built, want = _native_entry(tmp_path, monkeypatch, BODY.format(name="f"), "test no numba")
    monkeypatch.setattr(nb, "have_numba", lambda: False)
    monkeypatch.setattr(nb, "_WARNED", [False])
    with pytest.warns(nb.NumbaMissingWarning):
        assert np.array_equal(load(), want)
    assert np.array_equal(load(), want) and built == [1] and path.with_suffix(".py").exists() and not path.exists()
