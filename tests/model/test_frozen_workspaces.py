"""Frozen objects are not changed by use: what is derived from a Tree, a car's KinematicTables or its CarEquations is
kept beside it (model.workspace: `derived`, `PerObject`), never written into it, and is what the direct computation
gives.

Oracles: the object's own attributes (`vars(obj)`, key by key and object by object) before and after every derived
property and the kernels that read them; each derived property's own function called again on the object (the
direct computation: bit for bit); and, for the packed tables, a fresh KinematicTables of the same tables."""

from __future__ import annotations

import ast
import dataclasses
import functools
import gc
import threading
import weakref
from pathlib import Path

import numpy as np
import pytest

import dynid
from dynid.dynamics import Model
from dynid.model import example_path, load_tree
from dynid.model.tree import Mimic, Tree
from dynid.model.workspace import derived, derived_values


def _derived_names(cls: type) -> list[str]:
    return [k for k, v in vars(cls).items() if isinstance(v, derived)]


def _property_names(cls: type) -> list[str]:
    """Every property of the class, however made (a functools.cached_property would write into the instance)."""
    return [k for k, v in vars(cls).items() if isinstance(v, property | functools.cached_property | derived)]


def _snapshot(obj: object) -> dict[str, tuple]:
    """The object's own attributes, by identity and shallow content: any attribute added, removed or rebound
    shows, and so does a container among them that gained entries (a cache declared as a field)."""
    def content(v: object) -> object:
        if isinstance(v, dict):
            return tuple((k, id(x)) for k, x in v.items())
        if isinstance(v, list | tuple):
            return tuple(map(id, v))
        return v.tobytes() if isinstance(v, np.ndarray) else None

    return {k: (id(v), content(v)) for k, v in vars(obj).items()}


def _same(a: object, b: object) -> bool:
    if isinstance(a, np.ndarray):
        return isinstance(b, np.ndarray) and a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    return type(a) is type(b) and a == b


@pytest.fixture(scope="module")
def puma() -> Tree:
    return load_tree(example_path("puma560"))


def _fresh(tree: Tree, **changes: object) -> Tree:
    """A new tree equal to `tree` but for `changes` (nothing derived from it yet but what validation reads)."""
    return dataclasses.replace(tree, **changes)


def _trees(puma: Tree) -> list[Tree]:
    from dynid.vehicle.car_model import car_template

    return [_fresh(puma), _fresh(puma, mimic={3: Mimic(2, 0.5, 0.1)}), car_template()]


def test_a_tree_is_not_changed_by_its_derived_properties_nor_by_the_engines(puma):
    pytest.importorskip("scipy")
    names = _derived_names(Tree)
    assert {"ant", "sigma", "ancestors", "index", "constant_rotation", "parameters", "known_mask"} <= set(names)
    for tree in _trees(puma):
        fields = {f.name for f in dataclasses.fields(Tree)}
        before = _snapshot(tree)
        assert set(before) == fields  # nothing but its fields, from construction on
        values = {k: getattr(tree, k) for k in _property_names(Tree)}
        assert tree.unconstrained is tree.unconstrained  # made once for a tree with mimics, the tree itself else
        m = Model(tree)
        rng = np.random.default_rng(7)
        q, qd, qdd = (rng.uniform(-1.0, 1.0, (5, tree.n)) for _ in range(3))
        m.inverse_dynamics(q, qd, qdd)
        m.inverse_dynamics(q, qd, qdd, backend="numpy")
        m.regressor(q, qd, qdd)
        m.transforms(q)
        tree.inertial_block()
        tree.with_values({})
        assert _snapshot(tree) == before, sorted(set(vars(tree)) ^ set(before))
        for k in names:
            assert getattr(tree, k) is values[k], k  # kept: the same object at every use
            assert _same(values[k], vars(Tree)[k].func(tree)), k  # what the direct computation gives
        assert set(derived_values(tree)) >= set(names) - {"_without_mimic"}


def test_threads_asking_at_once_get_one_value(puma):
    names = _derived_names(Tree)
    for _ in range(5):
        tree = _fresh(puma, mimic={3: Mimic(2, -1.0)})
        start, got = threading.Barrier(2), [None, None]

        def ask(i: int, tree: Tree, start: threading.Barrier, got: list) -> None:
            start.wait()
            got[i] = [getattr(tree, k) for k in names]

        threads = [threading.Thread(target=ask, args=(i, tree, start, got)) for i in range(2)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert all(a is b for a, b in zip(*got, strict=True))


def test_derived_values_go_with_their_object(puma):
    tree = _fresh(puma, mimic={3: Mimic(2, 0.5)})
    for k in _derived_names(Tree):
        getattr(tree, k)
    kept = weakref.ref(tree.unconstrained)  # the tree without its mimics, a value kept beside this one
    ref = weakref.ref(tree)
    del tree
    gc.collect()
    assert ref() is None and kept() is None
    plain = _fresh(puma)
    assert plain.unconstrained is plain  # not kept beside itself (that would keep it alive)
    ref = weakref.ref(plain)
    del plain
    gc.collect()
    assert ref() is None


def test_kinematic_tables_are_not_changed_by_filling_joints():
    pytest.importorskip("scipy")
    from dynid.vehicle.tables import TABLE_NAMES, KinematicTables, default_tables
    from dynid.vehicle.template import DAMPERS

    tables = default_tables()
    before = _snapshot(tables)
    assert set(before) == {f.name for f in dataclasses.fields(KinematicTables)}
    rng = np.random.default_rng(3)
    q, qd, qdd = (np.zeros((40, 42)) for _ in range(3))
    for d in DAMPERS:
        q[:, d - 1], qd[:, d - 1], qdd[:, d - 1] = rng.uniform(-0.08, 0.08, (3, 40))
    h = tuple(rng.uniform(-1.0, 1.0, (3, 40)))
    outs = [tables.joints(q, qd, qdd, h, measured=m) for m in ((), ("camber",), ())]
    assert _snapshot(tables) == before
    twin = KinematicTables(tables.tables)  # the same tables, nothing packed yet
    for m, out in zip(((), ("camber",)), outs, strict=False):
        for a, b in zip(out, twin.joints(q, qd, qdd, h, measured=m), strict=True):
            assert _same(a, b)
    todo = tuple((k, n) for k in range(4) for n in TABLE_NAMES)
    packed = tables._packed(todo)
    assert tables._packed(todo) is packed  # kept
    assert all(_same(a, b) for a, b in zip(packed, twin._packed(todo), strict=True))
    assert _snapshot(tables) == before


def test_car_equations_are_not_changed_by_stacking_w():
    pytest.importorskip("scipy")
    from dynid.vehicle.car_model import car_template
    from dynid.vehicle.equations import CarEquations, car_identification

    tree = car_template()
    rng = np.random.default_rng(5)
    N = 6
    q, qd, qdd = (np.zeros((N, 42)) for _ in range(3))
    for a in (q, qd, qdd):
        a[:, :6] = rng.uniform(-0.1, 0.1, (N, 6))
    eq = car_identification(tree, q, qd, qdd, rng.normal(0.0, 100.0, (N, 4, 6)))
    before = _snapshot(eq)
    assert set(before) == {f.name for f in dataclasses.fields(CarEquations)}
    for k in _property_names(CarEquations):
        getattr(eq, k)
    W, Y, groups = eq
    assert eq.W is W and Y is eq.Y and groups is eq.groups  # W kept
    eq.residual(tree.parameters)
    assert _snapshot(eq) == before
    direct = np.ascontiguousarray(eq.per_sample.transpose(1, 0, 2)).reshape(-1, eq.per_sample.shape[2])
    assert _same(W, direct) and W.flags.c_contiguous
    for i in range(len(eq.rows)):  # group by group: row i's samples, in order
        assert _same(W[i * N:(i + 1) * N], eq.per_sample[:, i, :].copy())


def _frozen_dataclass(node: ast.ClassDef) -> bool:
    return any(isinstance(d, ast.Call) and getattr(d.func, "id", getattr(d.func, "attr", None)) == "dataclass"
               and any(k.arg == "frozen" and getattr(k.value, "value", False) is True for k in d.keywords)
               for d in node.decorator_list)


def test_no_frozen_class_of_dynid_has_a_cached_property():
    """A functools.cached_property writes into the instance: in a frozen class, use `derived` (model.workspace).
    Oracle: the source files' own class definitions, parsed with `ast`."""
    package = Path(dynid.__file__).parent
    found = []
    for path in sorted(package.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef) and _frozen_dataclass(node):
                found += [f"{path.relative_to(package)}: {node.name}.{f.name}" for f in node.body
                          if isinstance(f, ast.FunctionDef)
                          and any(getattr(d, "attr", getattr(d, "id", None)) == "cached_property"
                                  for d in f.decorator_list)]
    assert not found, found
