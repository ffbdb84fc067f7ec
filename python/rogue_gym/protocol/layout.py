"""How a gymnasium space is laid out as flat bytes in shared memory, leaf by leaf.

A space is a tree: ``Dict`` and ``Tuple`` nodes, and leaves. A *fixed* leaf (``Box``,
``Discrete``, ``MultiDiscrete``, ``MultiBinary``) is one numpy array of a fixed dtype and shape
(a ``Discrete`` is an ``int64`` scalar), placed at an offset aligned to its item size. One value
of the fixed leaves is ``nbytes`` bytes; a batch of ``n`` values is an ``(n, stride)`` uint8
array (the stride is ``nbytes`` rounded up to 8, so every row is 8-byte aligned), and each leaf
of the batch is a zero-copy strided view of it. Nothing is pickled for them.

A *dynamic* leaf (``Text``, ``Graph``, ``Sequence``, ``OneOf``, or any custom space) has no
fixed size: its values travel apart, pickled per env (:meth:`SpaceLayout.dynamic_values`), and
a batch holds them as gymnasium's vector envs do, one tuple of ``n`` values per leaf
(:meth:`SpaceLayout.fill`).
"""

from __future__ import annotations

import ctypes
import functools
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Sequence, Union

import numpy as np
from gymnasium import spaces

__all__ = [
    "Leaf",
    "SpaceLayout",
    "UnsupportedSpaceError",
    "at_path",
    "is_fixed",
    "map_leaves",
    "space_leaves",
]

#: Alignment of a batch row (so leaves of every dtype stay aligned in every row).
ROW_ALIGN = 8
#: Writers and row views a layout keeps, by destination address (the pool lends the same few
#: dozen destinations over and over); beyond this many the cache starts again.
MAX_DESTINATIONS = 1024

Path = tuple[Union[str, int], ...]


class UnsupportedSpaceError(TypeError):
    """A space the pool cannot carry where only fixed-size leaves may be (a vector env per
    worker, or ``shared_memory=True``)."""


#: The leaf spaces of a fixed size.
FIXED_SPACES = (spaces.Box, spaces.Discrete, spaces.MultiDiscrete, spaces.MultiBinary)


def is_fixed(space: spaces.Space) -> bool:
    """Whether ``space`` is a fixed-size leaf."""
    return isinstance(space, FIXED_SPACES)


@dataclass(frozen=True)
class Leaf:
    """One array of a space: where it sits in a value's bytes and what it holds."""

    path: Path
    dtype: np.dtype
    shape: tuple[int, ...]
    offset: int
    #: The leaf's own space (for bounds checks and messages).
    space: spaces.Space

    @functools.cached_property
    def count(self) -> int:
        """Elements of the leaf's array."""
        return int(np.prod(self.shape, dtype=np.int64))

    @functools.cached_property
    def nbytes(self) -> int:
        """Bytes of the leaf's array."""
        return self.count * self.dtype.itemsize


def space_leaves(space: spaces.Space, path: Path = ()) -> Iterator[tuple[Path, spaces.Space]]:
    """The leaves of ``space`` with their paths, in walk order (a ``Dict`` in its key order, a
    ``Tuple`` in index order): every walk of a space in this module goes this way."""
    if isinstance(space, spaces.Dict):
        for key, sub in space.spaces.items():
            yield from space_leaves(sub, (*path, key))
    elif isinstance(space, spaces.Tuple):
        for i, sub in enumerate(space.spaces):
            yield from space_leaves(sub, (*path, i))
    else:
        yield path, space


def map_leaves(space: spaces.Space, node: Any, fn: Callable[[spaces.Space, Any], Any]) -> Any:
    """A tree of ``space``'s structure (dicts and tuples) whose leaves are ``fn(leaf space,
    node's value there)``, walking ``node`` alongside (``None``: no tree, ``fn`` gets
    ``None``), in the walk order of :func:`space_leaves`."""
    if isinstance(space, spaces.Dict):
        return {
            k: map_leaves(s, None if node is None else node[k], fn) for k, s in space.spaces.items()
        }
    if isinstance(space, spaces.Tuple):
        return tuple(
            map_leaves(s, None if node is None else node[i], fn) for i, s in enumerate(space.spaces)
        )
    return fn(space, node)


def at_path(value: Any, path: Path) -> Any:
    """The part of ``value`` (a value or a batch) at a leaf's ``path``."""
    for key in path:
        value = value[key]
    return value


def _leaf_array(space: spaces.Space) -> tuple[np.dtype, tuple[int, ...]]:
    if isinstance(space, spaces.Box):
        return np.dtype(space.dtype), tuple(space.shape)
    if isinstance(space, spaces.Discrete):
        return np.dtype(space.dtype), ()
    if isinstance(space, spaces.MultiDiscrete):
        return np.dtype(space.dtype), tuple(space.shape)
    assert isinstance(space, spaces.MultiBinary)  # is_fixed(space)
    return np.dtype(space.dtype), tuple(space.shape)


class SpaceLayout:
    """The flat byte layout of one space (see the module docs)."""

    def __init__(self, space: spaces.Space) -> None:
        self.space = space
        #: The fixed leaves, in shared memory.
        self.leaves: list[Leaf] = []
        #: The dynamic leaves (path and space), pickled per env.
        self.dynamic: list[tuple[Path, spaces.Space]] = []
        #: Whether each leaf, in the order of a walk of the space, is dynamic.
        self._order: list[bool] = []
        offset = 0
        for path, s in space_leaves(space):
            self._order.append(not is_fixed(s))
            if not is_fixed(s):
                self.dynamic.append((path, s))
                continue
            dtype, shape = _leaf_array(s)
            offset = -(-offset // dtype.itemsize) * dtype.itemsize
            leaf = Leaf(path, dtype, shape, offset, s)
            self.leaves.append(leaf)
            offset += leaf.nbytes
        #: Bytes of one value (unpadded).
        self.nbytes = offset
        #: Bytes of one row of a batch (``nbytes`` rounded up to 8, at least 8).
        self.stride = max(ROW_ALIGN, -(-offset // ROW_ALIGN) * ROW_ALIGN)
        #: The space is one array (no Dict or Tuple around it).
        self.single = len(self.leaves) == 1 and self.leaves[0].path == ()
        #: :meth:`writer` by destination address (see :meth:`writer_at`).
        self._writers: dict[int, Callable[[Any], None]] = {}
        self._rows: dict[tuple[int, int], np.ndarray] = {}

    @functools.cached_property
    def signature(self) -> tuple[Any, ...]:
        """What two spaces must share to be carried alike: the fixed leaves' paths, dtypes
        and shapes, and the dynamic leaves' paths."""
        fixed = tuple((leaf.path, leaf.dtype.str, leaf.shape) for leaf in self.leaves)
        return fixed, tuple(path for path, _ in self.dynamic)

    # -- one value <-> memory (worker side) ---------------------------------------------

    def writer(self, address: int) -> Callable[[Any], None]:
        """A function that writes one value into the ``nbytes`` bytes at ``address`` (memory
        lent by the caller for the duration of each call), casting each leaf to its dtype and
        checking its size (not its shape: a value of the right size is reshaped), with one
        copy."""
        raw = np.ctypeslib.as_array((ctypes.c_uint8 * max(self.nbytes, 1)).from_address(address))
        views = [
            (
                leaf,
                raw[leaf.offset : leaf.offset + leaf.nbytes].view(leaf.dtype).reshape(leaf.shape),
            )
            for leaf in self.leaves
        ]

        def put(leaf: Leaf, dst: np.ndarray, value: Any) -> None:
            if type(value) is np.ndarray and value.shape == leaf.shape:
                np.copyto(dst, value, casting="unsafe")
                return
            arr = np.asarray(value, dtype=leaf.dtype)
            if arr.size != dst.size:
                raise ValueError(
                    f"value of shape {np.shape(value)} does not fit the space {leaf.space}"
                )
            dst[...] = arr.reshape(leaf.shape)

        if self.single:
            leaf, dst = views[0]
            shape = leaf.shape

            def write_single(value: Any) -> None:
                if type(value) is np.ndarray and value.shape == shape:
                    dst[...] = value  # one copy, casting to the leaf dtype
                else:
                    put(leaf, dst, value)

            return write_single

        def write_tree(value: Any) -> None:
            for leaf, dst in views:
                put(leaf, dst, at_path(value, leaf.path))

        return write_tree

    def writer_at(self, address: int) -> Callable[[Any], None]:
        """:meth:`writer` for ``address``, made once per destination and kept in
        a cache of up to :data:`MAX_DESTINATIONS`."""
        writer = self._writers.get(address)
        if writer is None:
            if len(self._writers) >= MAX_DESTINATIONS:
                self._writers.clear()
            writer = self._writers[address] = self.writer(address)
        return writer

    def rows_at(self, address: int, n: int) -> np.ndarray:
        """The ``(n, stride)`` bytes at ``address`` (a batch of destinations lent by the
        caller, for :meth:`write_batch`), as a numpy view made once per destination."""
        rows = self._rows.get((address, n))
        if rows is None:
            if len(self._rows) >= MAX_DESTINATIONS:
                self._rows.clear()
            raw = (ctypes.c_uint8 * (n * self.stride)).from_address(address)
            rows = self._rows[(address, n)] = np.ctypeslib.as_array(raw).reshape(n, self.stride)
        return rows

    def decoder(self) -> Callable[[bytes], Any]:
        """:meth:`decode`, made short for a space of one array (the common Box action): it
        runs every env step."""
        if not self.single or self.leaves[0].shape == ():
            return self.decode
        leaf = self.leaves[0]
        dtype, count, shape = leaf.dtype, leaf.count, leaf.shape
        frombuffer = np.frombuffer

        if len(shape) == 1:
            return lambda data: frombuffer(bytearray(data), dtype, count)
        return lambda data: frombuffer(bytearray(data), dtype, count).reshape(shape)

    def decode(self, data: bytes, dynamic: Sequence[Any] = ()) -> Any:
        """One value from its bytes (writable arrays, a ``Discrete`` leaf as a numpy int) and
        the values of its dynamic leaves."""
        buf = bytearray(data)
        if self.single:
            return self._leaf_value(buf, self.leaves[0])
        leaves = self._merged([self._leaf_value(buf, leaf) for leaf in self.leaves], dynamic)
        return map_leaves(self.space, None, lambda _s, _n: next(leaves))

    def _merged(self, fixed: Sequence[Any], dynamic: Sequence[Any]) -> Iterator[Any]:
        """The leaves in walk order: fixed ones from ``fixed``, dynamic ones from ``dynamic``
        (``None`` where it runs short)."""
        f, d = iter(fixed), iter(dynamic)
        return (next(d, None) if is_dyn else next(f) for is_dyn in self._order)

    def dynamic_values(self, value: Any) -> list[Any]:
        """The values of the dynamic leaves of one value (or, of a batch, their batches)."""
        return [at_path(value, path) for path, _ in self.dynamic]

    def fill(self, tree: Any, dynamic: Sequence[Any]) -> Any:
        """``tree`` (a value, or a batch, as :meth:`decode` or :meth:`batch_views` build it)
        with its dynamic leaves replaced by ``dynamic``, in order: a new tree, the fixed leaves
        shared."""
        return self._rebuild(tree, dynamic, ints=False)

    def env_value(self, row: Any, dynamic: Sequence[Any]) -> Any:
        """One env's value as envs return it, from its row of a batch (:meth:`batch_views`
        then one row) and its dynamic leaves: a ``Discrete`` leaf as a Python ``int``."""
        return self._rebuild(row, dynamic, ints=True)

    def _rebuild(self, tree: Any, dynamic: Sequence[Any], ints: bool) -> Any:
        values = iter(dynamic)

        def leaf(space: spaces.Space, node: Any) -> Any:
            if not is_fixed(space):
                return next(values, None)
            return int(node) if ints and isinstance(space, spaces.Discrete) else node

        return map_leaves(self.space, tree, leaf)

    @staticmethod
    def _leaf_value(buf: bytearray, leaf: Leaf) -> Any:
        arr = np.frombuffer(buf, leaf.dtype, leaf.count, leaf.offset).reshape(leaf.shape)
        return arr[()] if leaf.shape == () else arr

    # -- batches (front end) ---------------------------------------------------------------

    def batch_views(self, rows: np.ndarray) -> Any:
        """Zero-copy views of a batch: ``rows`` is an ``(n, >= nbytes)`` uint8 array; the
        result has the structure of the space with one ``(n, *shape)`` array per fixed leaf
        (and ``None`` for each dynamic one, until :meth:`fill`)."""
        n = rows.shape[0]
        if self.single and not self.dynamic:  # one array leaf: one view, no tree to build
            leaf = self.leaves[0]
            return (
                rows[:, leaf.offset : leaf.offset + leaf.nbytes]
                .view(leaf.dtype)
                .reshape((n, *leaf.shape))
            )
        views = [
            rows[:, leaf.offset : leaf.offset + leaf.nbytes]
            .view(leaf.dtype)
            .reshape((n, *leaf.shape))
            for leaf in self.leaves
        ]
        leaves = self._merged(views, ())
        return map_leaves(self.space, None, lambda _s, _n: next(leaves))

    def write_batch(self, values: Any, rows: np.ndarray) -> None:
        """Write a batch (the structure of the space, one ``(n, *shape)`` array per leaf) into
        ``rows``, casting to each leaf's dtype; raises ``ValueError`` on a shape mismatch."""
        n = rows.shape[0]
        for leaf in self.leaves:
            arr = np.asarray(at_path(values, leaf.path))
            if arr.shape != (n, *leaf.shape):
                where = "".join(f"[{k!r}]" for k in leaf.path) or "actions"
                raise ValueError(
                    f"{where} has shape {arr.shape}; expected {(n, *leaf.shape)} for {n} envs of {leaf.space}"
                )
            dest = rows[:, leaf.offset : leaf.offset + leaf.nbytes].view(leaf.dtype)
            dest.reshape((n, *leaf.shape))[...] = arr

    def flat_batch(self, values: Any, rows: np.ndarray) -> np.ndarray:
        """A batch's bytes, flat and checked (:meth:`check_batch`): the values' own memory
        when the space is one array and ``values`` a C-contiguous ndarray of its dtype and
        shape (the usual Box batch, no copy), else :meth:`write_batch` into ``rows``."""
        n = rows.shape[0]
        leaf = self.leaves[0] if self.single else None
        own = (
            leaf is not None
            and self.nbytes > 0
            and type(values) is np.ndarray
            and values.dtype == leaf.dtype
            and values.shape == (n, *leaf.shape)
            and values.flags.c_contiguous
        )
        if own:
            rows = values.reshape(n, -1).view(np.uint8)
        else:
            self.write_batch(values, rows)
        self.check_batch(rows)
        return rows.reshape(-1)

    def check_batch(self, rows: np.ndarray) -> None:
        """Raise ``ValueError`` naming the first env whose value lies outside the space's
        bounds (Discrete, MultiDiscrete, MultiBinary and integer or finite-bounded Box)."""
        n = rows.shape[0]
        for leaf in self.leaves:
            v = (
                rows[:, leaf.offset : leaf.offset + leaf.nbytes]
                .view(leaf.dtype)
                .reshape((n, *leaf.shape))
            )
            s = leaf.space
            if isinstance(s, spaces.Discrete):
                lo, hi = s.start, s.start + s.n - 1
            elif isinstance(s, spaces.MultiDiscrete):
                lo, hi = s.start, s.start + s.nvec - 1
            elif isinstance(s, spaces.MultiBinary):
                lo, hi = 0, 1
            else:
                continue  # Box: envs clip or reject out-of-bounds values themselves
            bad = np.any((v < lo) | (v > hi), axis=tuple(range(1, v.ndim)))
            if np.any(bad):
                i = int(np.argmax(bad))
                where = "".join(f"[{k!r}]" for k in leaf.path)
                raise ValueError(f"env {i}: action{where} {v[i].tolist()} is outside {s}")
