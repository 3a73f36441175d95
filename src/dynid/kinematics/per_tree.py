"""Values derived from a tree, kept beside it rather than inside it.

A `Tree` is a frozen description; what the engines derive from it (flat geometry arrays,
per-frame constants, regressor plans) is a pure function of it, so it is computed once per
tree and kept in a `PerTree` map owned by the module that derives it. The map is weak in the
tree: an entry goes when its tree is garbage collected, so the tree is never kept alive by
it, and a later tree that happens to reuse the freed address starts empty. (A
WeakKeyDictionary would do the same but needs a hashable key, and a Tree holds dicts.)
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from typing import Generic, TypeVar

from ..model.tree import Tree

T = TypeVar("T")


class PerTree(Generic[T]):
    """`make(tree)` computed once per live tree; the value must not refer to the tree (it would keep it alive).

    Thread-safe without a lock (each dict operation is atomic): two threads asking for the same new tree at once
    may both compute it (the computation is pure) and keep either value. The weakref callback runs while the old
    tree is deallocated, before its address can be reused, so it never sees a newer tree's entry at that key.
    """

    def __init__(self, make: Callable[[Tree], T]) -> None:
        self._make = make
        self._items: dict[int, tuple[weakref.ref, T]] = {}

    def __call__(self, tree: Tree) -> T:
        key = id(tree)
        hit = self._items.get(key)
        if hit is not None and hit[0]() is tree:
            return hit[1]
        value = self._make(tree)
        self._items[key] = (weakref.ref(tree, self._drop_callback(key)), value)
        return value

    def _drop_callback(self, key: int) -> Callable[[weakref.ref], None]:
        items = self._items  # not self: the callback must not keep the map alive

        def drop(ref: weakref.ref) -> None:
            hit = items.get(key)
            if hit is not None and hit[0] is ref:  # this tree's entry, not one that replaced it
                del items[key]

        return drop

    def __len__(self) -> int:
        return len(self._items)


__all__ = ["PerTree"]
