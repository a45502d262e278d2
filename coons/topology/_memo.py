"""Memos keyed weakly by immutable geometry objects, for what sewing, checking and mass properties
compute from one curve, p-curve, surface or face spec alone.

Geometry in coons is a value (frozen dataclasses over read-only arrays), so anything computed from
such an object alone never goes stale: a B-rep built from the faces of an earlier one (the faces a
Boolean passes through unchanged keep their curve, p-curve and surface objects) finds it again.
:class:`IdentityMemo` holds one entry per object, dropped when the object dies; only values
(:func:`is_value`) may be keys.  A result that also depends on other inputs (a parameter range, a
second object) is stored under a key of those inside the entry, by the caller.  Results never
depend on what is remembered, only the time does; :func:`clear_all` forgets everything.

:func:`pool_positions` carries tables between B-reps as arrays instead: the positions of one
B-rep's geometry objects in another's pools (a Boolean's result in its operand's), by which rows
built per object are gathered in one take; :func:`pool_values` says which pool objects are values.
A B-rep assembled from arrays comes with its pools' ids sorted already (:func:`seed_pool_ids`: the
builder sorts them to find the distinct objects), so a sequential cut's result is not walked again
for them.
"""

from __future__ import annotations

import weakref
from typing import Any, Callable, Iterable, Sequence

import numpy as np

__all__ = ["IdentityMemo", "clear_all", "is_value", "pool_positions", "pool_values", "read_only"]

_VALUE_TYPES: dict[type, bool] = {}
#: Every memo made, so that :func:`clear_all` (benchmarks, tests comparing warm and cold runs)
#: reaches them all.
_ALL: "weakref.WeakSet[IdentityMemo]" = weakref.WeakSet()


def clear_all() -> None:
    """Forget every :class:`IdentityMemo` (results never depend on them, only the time does)."""
    for memo in list(_ALL):
        memo.clear()


def read_only(a: np.ndarray) -> np.ndarray:
    """``a`` made read-only in place and returned: the arrays kept in memos are shared, never written."""
    a.setflags(write=False)
    return a


def is_value(obj: Any) -> bool:
    """Whether ``obj`` is an immutable value: an instance of a frozen dataclass (every curve, p-curve,
    surface and face spec of coons), so that what is computed from it alone may be remembered."""
    return _value_type(type(obj))


def all_values(objs) -> bool:
    """Whether every object of ``objs`` is a value (:func:`is_value`), tested once per type (a value is
    one by its type alone): a Boolean's result brings a thousand new p-curves of two or three types."""
    return all(map(_value_type, set(map(type, objs))))


def _value_type(kind: type) -> bool:
    """Whether instances of ``kind`` are values (:func:`is_value`)."""
    got = _VALUE_TYPES.get(kind)
    if got is None:
        params = getattr(kind, "__dataclass_params__", None)
        got = _VALUE_TYPES[kind] = params is not None and bool(params.frozen)
    return got


class _Ref(weakref.ref):
    """A weak reference that knows its entry's key (one shared callback removes dead entries)."""

    __slots__ = ("key",)


class IdentityMemo:
    """``object -> value`` by identity, weakly: an entry dies with its object.

    A dict on ``id`` holding a weak reference to each key object (checked on every lookup, so a
    recycled id never finds another object's entry; the reference's callback removes the entry).
    Lookups cost one dict access, unlike :class:`weakref.WeakKeyDictionary`, which makes a new
    weak reference for each: the checker looks up every coedge of a model.  A value must not
    refer to its key (directly or through what it holds), or the entry keeps the key alive for
    good.
    """

    def __init__(self) -> None:
        self._data: dict[int, tuple[_Ref, Any]] = {}
        data = self._data

        def forget(ref: _Ref) -> None:
            got = data.get(ref.key)
            if got is not None and got[0] is ref:
                del data[ref.key]

        self._forget = forget
        _ALL.add(self)

    def get(self, obj: Any, default: Any = None) -> Any:
        got = self._data.get(id(obj))
        if got is None or got[0]() is not obj:
            return default
        return got[1]

    def get_many(self, objs: Iterable[Any]) -> list:
        """:meth:`get` of each object (None where absent), in one call."""
        data = self._data
        out = []
        for obj in objs:
            got = data.get(id(obj))
            out.append(None if got is None or got[0]() is not obj else got[1])
        return out

    def set(self, obj: Any, value: Any) -> None:
        """Remember ``value`` for ``obj``, which must be a value (:func:`is_value`)."""
        if not is_value(obj):
            raise TypeError(f"IdentityMemo keys must be immutable values (frozen dataclasses), got {type(obj).__name__}")
        ref = _Ref(obj, self._forget)
        ref.key = id(obj)
        self._data[ref.key] = (ref, value)

    def set_many(self, objs: Sequence[Any], values: Iterable[Any]) -> None:
        """:meth:`set` of each object to its value (in turn: a repeated object keeps its last), in one
        call: the value check once per type, not per object (a Boolean's pieces bring a thousand new
        edge uses, each given samples, a box and a row)."""
        for kind in set(map(type, objs)):
            if not _value_type(kind):
                raise TypeError(f"IdentityMemo keys must be immutable values (frozen dataclasses), got {kind.__name__}")
        data, forget = self._data, self._forget
        for obj, value in zip(objs, values, strict=True):
            ref = _Ref(obj, forget)
            key = ref.key = id(obj)
            data[key] = (ref, value)

    def setdefault(self, obj: Any, factory: Callable[[], Any]) -> Any:
        """The value for ``obj``, made by ``factory()`` and remembered when absent."""
        got = self.get(obj, _MISSING)
        if got is _MISSING:
            got = factory()
            self.set(obj, got)
        return got

    def clear(self) -> None:
        self._data.clear()

    def __len__(self) -> int:
        return len(self._data)


_MISSING = object()


class LastRecord(IdentityMemo):
    """One record, of the last object given to :meth:`keep` (held weakly): what a sewing, a clean
    check or a shell-volume sum leaves for the next one, which reads it back by :meth:`last` (a
    Boolean's result carries most of its operand's faces).  Cleared with the other memos
    (:func:`clear_all`)."""

    def __init__(self) -> None:
        super().__init__()
        self._last: weakref.ref | None = None

    def keep(self, obj: Any, record: Any) -> None:
        """Make ``record`` the one record, of ``obj`` (a value: :func:`is_value`)."""
        super().clear()
        self.set(obj, record)
        self._last = weakref.ref(obj)

    def last(self) -> Any:
        """The record kept, None when there is none or its object has died."""
        obj = self._last() if self._last is not None else None
        return self.get(obj) if obj is not None else None

    def clear(self) -> None:
        super().clear()
        self._last = None


#: B-rep -> ``{pool name: (ids in pool order, sorted ids of the value objects, their positions)}`` of
#: its geometry pools (``surfaces``, ``curves``, ``pcurves``), built on demand (:func:`pool_positions`)
#: or from ``(ids, order)`` seeded by the builder (:func:`seed_pool_ids`).
_POOL_IDS = IdentityMemo()
#: B-rep -> ``{pool name: (ids, order)}`` given by :func:`seed_pool_ids`, taken by the first read.
_POOL_SEEDS = IdentityMemo()
#: B-rep -> ``{(pool name, id(donor)): (weak reference to the donor, positions)}``: what
#: :func:`pool_positions` found, shared by the checker and the mass tables of one B-rep.
_POSITIONS = IdentityMemo()


def _pool_ids(b: Any, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ids ``(n,)`` of the pool ``name`` of ``b`` in pool order, and the sorted ids of its value
    objects (:func:`is_value`) with their positions."""
    got = _POOL_IDS.get(b)
    if got is None:
        got = {}
        _POOL_IDS.set(b, got)
    hit = got.get(name)
    if hit is None:
        pool = getattr(b, name)
        seeds = _POOL_SEEDS.get(b)
        seed = seeds.pop(name, None) if seeds is not None else None
        if seed is None:
            ids = np.fromiter(map(id, pool), dtype=np.uint64, count=len(pool))  # (CPython ids are addresses, >= 0)
            o = np.argsort(ids, kind="stable")
        else:
            ids, o = seed  # (seed_pool_ids: the builder sorted them)
        if not all(map(_value_type, set(map(type, pool)))):
            # (a stable order filtered is the stable order of the filtered ids)
            o = o[np.fromiter(map(is_value, pool), dtype=bool, count=len(pool))[o]]
        hit = got[name] = (read_only(ids), read_only(ids[o]), read_only(o))
    return hit


def seed_pool_ids(b: Any, name: str, ids: np.ndarray, order: np.ndarray) -> None:
    """Give :func:`_pool_ids` the ids of the pool ``name`` of the new B-rep ``b`` that its builder
    had at hand: ``ids (n,)`` uint64 in pool order and ``order (n,)`` the stable order that sorts
    them (the builder finds a pool's distinct objects by sorting their ids).  The value filter
    is left to the first read; a B-rep never read as a donor or against one costs nothing more."""
    got = _POOL_SEEDS.get(b)
    if got is None:
        got = {}
        _POOL_SEEDS.set(b, got)
    got[name] = (ids, order)


def id_index(objs: Any) -> tuple[np.ndarray, np.ndarray]:
    """The record side of :func:`found_by_id`: the ids of ``objs`` (a sequence) sorted, and their
    positions in it (stable)."""
    ids = np.fromiter(map(id, objs), dtype=np.int64, count=len(objs))
    order = np.argsort(ids, kind="stable")
    return ids[order], order


def found_by_id(objs: Any, ids: np.ndarray, order: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where each of ``objs`` (a sequence of n objects) sits in a record of objects, found by identity
    in one pass: ``(positions (n,), found (n,) bool)`` (positions are meaningless where not found).

    ``ids`` are the record's object ids sorted (non-empty), ``order`` their positions in the record.
    The record must hold its objects (so that an equal id is the same object).
    """
    want = np.fromiter(map(id, objs), dtype=np.int64, count=len(objs))
    j = np.minimum(np.searchsorted(ids, want), ids.size - 1)
    return order[j], ids[j] == want


def pool_values(b: Any, name: str) -> np.ndarray:
    """``(n,)`` bool: which objects of the pool ``name`` of B-rep ``b`` are values (:func:`is_value`)."""
    _, _, order = _pool_ids(b, name)
    out = np.zeros(len(getattr(b, name)), dtype=bool)
    out[order] = True
    return out


def pool_positions(b: Any, donor: Any, name: str) -> np.ndarray:
    """Position ``(n,)`` int64 of each object of the pool ``name`` of B-rep ``b`` in the same pool of
    ``donor`` (the very object), -1 where absent or not a value (:func:`is_value`).

    Tables built per pool object (the checker's same-parameter rows, the mass tables' surface and
    p-curve rows) are functions of the object alone: those of a B-rep that shares most of its
    geometry with an earlier one (a Boolean's result and its operand) are gathered from the
    earlier table with these positions in one take.  Objects are matched by ``id``: both B-reps
    are alive and hold their pools, so equal ids are the same object.  Both B-reps are immutable:
    the result is remembered per ``b`` and donor.
    """
    got = _POSITIONS.get(b)
    if got is None:
        got = {}
        _POSITIONS.set(b, got)
    hit = got.get((name, id(donor)))
    if hit is not None and hit[0]() is donor:
        return hit[1]
    ids = _pool_ids(b, name)[0]
    _, sorted_ids, order = _pool_ids(donor, name)
    pos = np.full(ids.size, -1, dtype=np.int64)
    if sorted_ids.size and ids.size:
        j = np.minimum(np.searchsorted(sorted_ids, ids), sorted_ids.size - 1)
        same = sorted_ids[j] == ids
        pos[same] = order[j[same]]
    got[(name, id(donor))] = (weakref.ref(donor), read_only(pos))
    return pos
