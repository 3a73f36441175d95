"""One sine and cosine (dynid.dynamics.trig) in every target: the Numba engine's `_sincos`, the generated NumPy
module, the generated C `_block` function and the LLVM block kernel, on the same 1e5 angles.

Oracles: the generated targets each other, to the bit (the same IEEE operations in the same order, no
contraction into FMA: on any CPU); the engine's, contracted into FMA like the engine's kernels (15 % of a PUMA's
inverse dynamics uncontracted), within 1 ulp of them; and libm through np.sin / np.cos, within 1 ulp of
max(|y|, 1/2) for every target (a contraction only rounds less). Why that bound holds: against the exact
value, these steps err by under 1.05 ulp of max(|y|, 1/2) (fdlibm's kernels, under an ulp, and the two-part
pi/2, |k| 2^-87 absolute; measured 1.04 against long double), a libm by under 0.55 (glibc; fdlibm-based ones
under 1, with the same kernels); for |y| >= 1/2 two doubles of one binade differ by a whole number of ulps, so
by at most 1; below 1/2 both errors are at most ~1 ulp of 1/4, which sum below 1 ulp of 1/2.
"""

from __future__ import annotations

import ctypes
from fractions import Fraction

import numpy as np
import pytest
from oracles import compile_generated_c

from dynid.dynamics import compiled, trig
from dynid.model import Frame, Tree
from dynid.symbolic import build
from dynid.symbolic.cache import numpy_module

numba = pytest.importorskip("numba")

ONE_JOINT = Tree("one revolute joint", (Frame(1, 0, 0),))  # its dgm's T1 holds cos q1 and sin q1


def angles() -> np.ndarray:
    """1e5 angles: the edges of the quadrants (k pi/4 and its neighbours), small and large ones, zeros, tiny."""
    k = np.arange(-3000, 3000) * np.pi / 4
    edges = np.concatenate([k, np.nextafter(k, np.inf), np.nextafter(k, -np.inf),
                            np.array([1.0, -1.0, 0.5, -0.5]) * (trig.LIMIT - 1e-6)])
    rng = np.random.default_rng(25)
    tiny = np.array([0.0, -0.0, 5e-324, -5e-324, 1e-300, -1e-300, 1e-9, -1e-9])
    rest = 100_000 - edges.size - tiny.size
    return np.concatenate([edges, tiny, rng.uniform(-4.0, 4.0, rest // 2),
                           rng.uniform(-trig.LIMIT, trig.LIMIT, rest - rest // 2)])


@numba.njit
def _engine_loop(x, s, c):
    for i in range(x.size):
        s[i], c[i] = compiled._sincos(x[i])


def every_target(x: np.ndarray, tmp_path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(sin x, cos x) of each target."""
    from dynid.symbolic.blocks import block_model

    out = {}
    s, c = np.empty_like(x), np.empty_like(x)
    _engine_loop(x, s, c)
    out["numba engine"] = (s, c)
    q = x[:, None]
    T = numpy_module(ONE_JOINT, "dgm").evaluate(q)  # (N, 2, 4, 4): T1[0, 0] = cos, T1[1, 0] = sin
    out["numpy"] = (T[:, 1, 1, 0].copy(), T[:, 1, 0, 0].copy())
    kernel = block_model(ONE_JOINT, "dgm")
    o = kernel(q)["out"]  # (32, N), entry-major
    out["llvm vector"] = (o[16 + 4].copy(), o[16].copy())
    prog = build(ONE_JOINT, "dgm")
    prog.meta["n"] = ONE_JOINT.n
    lib = compile_generated_c(tmp_path, prog, "trig", block=True)
    T = np.full((x.size, 2 * 16), np.nan)
    P = ctypes.POINTER(ctypes.c_double)
    lib.trig_dgm_block(ctypes.c_long(x.size), np.ascontiguousarray(q).ctypes.data_as(P), T.ctypes.data_as(P))
    out["c block"] = (T[:, 16 + 4].copy(), T[:, 16].copy())
    return out


def ulps(y: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """|y - ref| in ulps of max(|ref|, 1/2)."""
    return np.abs(y - ref) / np.spacing(np.maximum(np.abs(ref), 0.5))


def test_every_target_is_the_same_sine_and_cosine(tmp_path, monkeypatch):
    monkeypatch.setenv("DYNID_CACHE", str(tmp_path / "cache"))
    x = angles()
    assert x.size == 100_000
    res = every_target(x, tmp_path)
    engine = res.pop("numba engine")
    bits = {name: (s.view(np.int64), c.view(np.int64)) for name, (s, c) in res.items()}
    first, *others = bits
    for name in others:
        for f, a, b in (("sin", bits[first][0], bits[name][0]), ("cos", bits[first][1], bits[name][1])):
            diff = np.flatnonzero(a != b)
            assert diff.size == 0, f"{f}: {name} differs from {first} at {diff.size} angles, e.g. x = {x[diff[0]]!r}"
    for name, (s, c) in [*res.items(), ("numba engine", engine)]:
        assert ulps(s, np.sin(x)).max() <= 1.0, name
        assert ulps(c, np.cos(x)).max() <= 1.0, name
    s, c = res[first]
    assert ulps(engine[0], s).max() <= 1.0 and ulps(engine[1], c).max() <= 1.0


def test_angles_out_of_range_take_libm_in_every_target(tmp_path, monkeypatch):
    """|x| >= LIMIT (k * PIO2_1 no longer exact) and NaN: libm's values, the neighbours unaffected."""
    monkeypatch.setenv("DYNID_CACHE", str(tmp_path / "cache"))
    x = np.array([trig.LIMIT, -trig.LIMIT, 3.0e5, -1e9, 1e300, np.nan, 0.5, -2.0, np.inf])
    with np.errstate(invalid="ignore"):
        res = every_target(x, tmp_path)
        es, ec = np.sin(x), np.cos(x)
    near = np.abs(x) < trig.LIMIT
    for name, (s, c) in res.items():
        assert np.array_equal(np.isnan(s), np.isnan(es)) and np.array_equal(np.isnan(c), np.isnan(ec)), name
        ok = ~np.isnan(es)
        assert ulps(s[ok], es[ok]).max() <= 1.0 and ulps(c[ok], ec[ok]).max() <= 1.0, name
        assert np.array_equal(s[near], res["numpy"][0][near]) or name == "numba engine", name


def test_the_steps_are_fdlibms_sine_and_cosine_kernels():
    """The step list evaluated in exact rational arithmetic is __kernel_sin/__kernel_cos's polynomials
    (an independent transcription of k_sin.c and k_cos.c), so that no step was dropped or reordered."""
    r = Fraction(3, 10)
    val = {"x": Fraction(0)} | {k: Fraction(v) for k, v in trig.CONSTANTS.items()}
    val["r"] = r  # the reduction is checked by the tests above; here the kernels alone
    for name, op, a, b in trig.STEPS:
        if name in ("k", "kx", "kr", "kp1", "kp2", "r1", "r"):
            continue
        x, y = val[a], val[b]
        val[name] = x + y if op == "add" else x - y if op == "sub" else x * y
    z = r * r
    S, C = [Fraction(v) for v in trig.SIN], [Fraction(v) for v in trig.COS]
    sin_r = r + z * r * (S[0] + z * (S[1] + z * (S[2] + z * (S[3] + z * (S[4] + z * S[5])))))
    cos_r = 1 - z / 2 + z * z * (C[0] + z * (C[1] + z * (C[2] + z * (C[3] + z * (C[4] + z * C[5])))))
    assert val["sn"] == sin_r and val["cs"] == cos_r
