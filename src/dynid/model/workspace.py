"""Values derived from a frozen object, kept beside it rather than inside it (the Model/Data split of Pinocchio).

A `Tree`, a car's kinematic tables, a car's stacked equations are frozen values; what is derived from one of them
(a tree's parameter names and constant rotations, the engines' flat arrays and regressor plans, the packed tables,
the stacked regressor) is a pure function of it, so it is computed once per object and kept in a `PerObject` map
owned by the module that derives it, never written into the object (`vars(obj)` holds its fields only). The map is
weak in the object: an entry goes when its object is garbage collected, so the object is never kept alive by it,
and a later object that happens to reuse the freed address starts empty. (A WeakKeyDictionary would do the same
but needs a hashable key, and a Tree holds dicts.)

`derived` is `functools.cached_property` with its value kept that way: for the properties of a frozen class.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from typing import Any, Generic, TypeVar, overload

K = TypeVar("K")
T = TypeVar("T")


class PerObject(Generic[K, T]):
    """`make(obj)` computed once per live object; the value must not refer to the object (it would keep it alive).

    Thread-safe without a lock (each dict operation is atomic): two threads asking for the same new object at once
    may both compute it (the computation is pure) and keep either value. The weakref callback runs while the old
    object is deallocated, before its address can be reused, so it never sees a newer object's entry at that key.
    """

    def __init__(self, make: Callable[[K], T]) -> None:
        self._make = make
        self._items: dict[int, tuple[weakref.ref, T]] = {}

    def __call__(self, obj: K) -> T:
        key = id(obj)
        hit = self._items.get(key)
        if hit is not None and hit[0]() is obj:
            return hit[1]
        value = self._make(obj)
        self._items[key] = (weakref.ref(obj, self._drop_callback(key)), value)
        return value

    def _drop_callback(self, key: int) -> Callable[[weakref.ref], None]:
        items = self._items  # not self: the callback must not keep the map alive

        def drop(ref: weakref.ref) -> None:
            hit = items.get(key)
            if hit is not None and hit[0] is ref:  # this object's entry, not one that replaced it
                del items[key]

        return drop

    def __len__(self) -> int:
        return len(self._items)


# per object, the values of its `derived` properties by name
_DERIVED: PerObject[Any, dict[str, Any]] = PerObject(lambda obj: {})
_DERIVED_ITEMS = _DERIVED._items
_MISSING = object()


class derived(Generic[T]):  # noqa: N801 (a decorator, named as functools.cached_property)
    """A property of a frozen class computed on first use and kept beside the instance (`PerObject`), not in it.

    The function must not return something that refers to the instance. Two threads asking at once may both
    compute it (it is pure); every caller gets the value kept first.
    """

    def __init__(self, func: Callable[[Any], T]) -> None:
        self.func = func
        self.name = func.__name__
        self.__doc__ = func.__doc__

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    @overload
    def __get__(self, obj: None, owner: type | None = None) -> derived[T]: ...
    @overload
    def __get__(self, obj: object, owner: type | None = None) -> T: ...

    def __get__(self, obj, owner=None):
        if obj is None:
            return self
        hit = _DERIVED_ITEMS.get(id(obj))  # _DERIVED(obj) inlined: this is read in the NumPy engine's loops
        values = hit[1] if hit is not None and hit[0]() is obj else _DERIVED(obj)
        value = values.get(self.name, _MISSING)
        return values.setdefault(self.name, self.func(obj)) if value is _MISSING else value


def derived_values(obj: object) -> dict[str, Any]:
    """The `derived` values computed so far for obj, by name (a copy: for tests and diagnostics)."""
    return dict(_DERIVED(obj))


__all__ = ["PerObject", "derived", "derived_values"]
