"""What the engines derive from a tree is kept beside it (kinematics.per_tree.PerTree, dynamics.compiled.Workspace),
never written into the frozen Tree, never keeping it alive, and never handed to a later tree at the same address.

Oracles: a content-equal twin of the tree, alive for the whole test (so no address of it is ever reused), evaluated
by the same engine; and the tree's own fields (all that may be in its __dict__: its derived properties are kept
beside it too, model.workspace)."""

from __future__ import annotations

import dataclasses
import gc
import weakref

import numpy as np
import pytest

from dynid.dynamics import Model, compiled
from dynid.kinematics.forward import frame_plan
from dynid.kinematics.per_tree import PerTree
from dynid.model import example_path, load_tree
from dynid.model.tree import Tree


@pytest.fixture(scope="module")
def puma() -> Tree:
    return load_tree(example_path("puma560"))


def _moved(tree: Tree, d: float) -> Tree:
    """The tree with frame 3's d changed (another geometry, same structure and parameter names)."""
    frames = tuple(dataclasses.replace(f, d=d) if f.j == 3 else f for f in tree.frames)
    return dataclasses.replace(tree, frames=frames)


def _samples(n: int, N: int = 7) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(25)
    return tuple(rng.uniform(-1.5, 1.5, (N, n)) for _ in range(3))


def _evaluate(tree: Tree) -> tuple[np.ndarray, ...]:
    """Every engine path that derives something from the tree: frame plans, compiled geometry, X arrays, plans."""
    m = Model(tree)
    q, qd, qdd = _samples(tree.n)
    return (m.transforms(q), m.inverse_dynamics(q, qd, qdd), m.inverse_dynamics(q, qd, qdd, backend="numpy"),
            m.regressor(q, qd, qdd), m.regressor(q, qd, qdd, rows=[2, 3], cols=["ZZ2", "MX3", "M3"]),
            m.inertia_matrix(q))


def _reborn(victim: list[Tree], like: Tree, tries: int = 1000) -> Tree:
    """A tree equal to `like` at the address of victim[0], which is dropped here. The instance is allocated
    right after the victim is freed and before anything else (CPython hands the freed block of that size out
    again), with the collector off so that nothing else runs in between; then it is initialised."""
    kwargs = {f.name: getattr(like, f.name) for f in dataclasses.fields(Tree)}
    address, ref, held = id(victim[0]), weakref.ref(victim[0]), []
    gc.disable()
    try:
        victim.clear()  # the last reference: freed now, not by the collector
        assert ref() is None
        for _ in range(tries):
            t = Tree.__new__(Tree)
            if id(t) == address:
                break
            held.append(t)
        else:
            pytest.skip("the allocator did not reuse the freed tree's address")
    finally:
        gc.enable()
    t.__init__(**kwargs)
    return t


def test_a_tree_at_a_reused_address_gets_its_own_results(puma):
    twin = _moved(puma, 0.30)  # alive throughout: the oracle
    expected = _evaluate(twin)
    first = _moved(puma, 0.55)
    stale = _evaluate(first)
    assert not np.allclose(stale[1], expected[1])  # the two geometries differ where it is checked
    victim = [first]
    del first
    second = _reborn(victim, twin)
    for got, want in zip(_evaluate(second), expected, strict=True):
        np.testing.assert_array_equal(got, want)  # same content, same code: bit for bit


def test_derived_values_stay_out_of_the_tree_and_do_not_keep_it_alive(puma):
    tree = _moved(puma, 0.40)
    fields = {f.name for f in dataclasses.fields(Tree)}
    _evaluate(tree)
    frame_plan(tree)
    compiled.regressor_plan(tree, [1, 2], [0, 1])
    assert set(vars(tree)) == fields, sorted(set(vars(tree)) ^ fields)
    with pytest.raises(dataclasses.FrozenInstanceError):
        tree.name = "other"  # type: ignore[misc]
    ref = weakref.ref(tree)
    del tree
    gc.collect()
    assert ref() is None


def test_per_tree_entry_goes_with_its_tree(puma):
    calls = []
    derived = PerTree(lambda t: calls.append(t.name) or len(calls))
    a = [_moved(puma, 0.1)]
    assert derived(a[0]) == 1 and derived(a[0]) == 1 and len(derived) == 1
    b = _reborn(a, puma)
    assert len(derived) == 0
    assert derived(b) == 2 and calls == [puma.name, puma.name]


def test_a_workspace_does_not_outlive_its_tree_silently(puma):
    tree = _moved(puma, 0.2)
    ws = compiled.Workspace(tree)
    del tree
    gc.collect()
    with pytest.raises(ReferenceError, match="garbage collected"):
        ws.regressor_plan((1,), (0,))


def test_car_derived_values_do_not_keep_the_car_alive():
    pytest.importorskip("scipy")
    from dynid.vehicle.car_model import car_template
    from dynid.vehicle.equations import _radius, car_base_parameters

    tree = car_template()
    r = _radius(tree)
    assert 0.2 < r < 0.4
    car_base_parameters(tree)
    assert set(vars(tree)) == {f.name for f in dataclasses.fields(Tree)}
    ref = weakref.ref(tree)
    del tree
    gc.collect()
    assert ref() is None
