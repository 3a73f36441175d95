"""Values derived from a tree, kept beside it rather than inside it (`model.workspace.PerObject`, for trees).

A `Tree` is a frozen description; what the engines derive from it (flat geometry arrays, per-frame constants,
regressor plans) is a pure function of it, so it is computed once per tree and kept in a `PerTree` map owned by the
module that derives it, weak in the tree (see model.workspace).
"""

from __future__ import annotations

from typing import TypeVar

from ..model.tree import Tree
from ..model.workspace import PerObject

T = TypeVar("T")


class PerTree(PerObject[Tree, T]):
    """`make(tree)` computed once per live tree; the value must not refer to the tree (`PerObject`)."""


__all__ = ["PerTree"]
