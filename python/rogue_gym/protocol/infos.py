"""Info dicts across the pool, and gymnasium's vector infos built from them.

Worker side (:class:`InfoEncoder`): an env's info dict becomes bytes. An info whose values are
numbers (``int``, ``float``, ``bool``, numpy scalars) and numpy arrays of numbers, in nested
dicts of string keys, is a *typed row*: a header naming its structure, the structure itself
(a small pickle, so that the caller can decode any row on first sight), then the values' raw
bytes. The structure is laid out once per distinct set of keys, types, dtypes and shapes, and
again whenever it changes. Anything else (strings, lists, objects) is pickled, as a list of
``("reset" | "step", info)`` entries.

Caller side (:func:`vector_infos`): the rows of one call are grouped by structure, and each
group becomes numpy columns in one ``np.frombuffer`` over its rows, so an info costs no
per-env Python work. The result is what gymnasium's ``VectorEnv._add_info`` builds env by
env: the same keys, dtypes, ``_key`` masks and nesting.
"""

from __future__ import annotations

import hashlib
import pickle
import struct
from collections.abc import Iterable, Sequence
from typing import Any, Callable, NamedTuple, Optional

import numpy as np

from .. import _native

__all__ = [
    "RESET_OBS",
    "STEP_OBS",
    "FlatPlan",
    "InfoDecoder",
    "InfoEncoder",
    "add_row_info",
    "split_joined",
    "split_vector_info",
    "vector_infos",
]

#: Marks a typed row (a pickle starts with 0x80).
MAGIC = b"RGi1"
#: ``magic, tag (0 reset, 1 step), structure hash, structure length``; 24 bytes.
_HEADER = struct.Struct("<4sB3xQI4x")
HEADER_BYTES = _HEADER.size
#: The bytes that tell a row's tag and structure (magic, tag, padding, hash): the pool
#: groups extra infos that share them (``rogue_gym._native.EXTRA_HEAD``, written once there).
HEAD: int = _native.EXTRA_HEAD
assert HEAD <= HEADER_BYTES, "the head lies inside a row's header"
#: Where a row's structure hash lies: after its magic, tag and padding, to the head's end.
_HASH = slice(struct.calcsize("<4sB3x"), HEAD)
TAGS = ("reset", "step")
#: The entries that carry the values of an observation's dynamic leaves (a list, in the order
#: of ``SpaceLayout.dynamic``): of the step's observation, and of the reset's. Always pickled.
STEP_OBS, RESET_OBS = "step_obs", "reset_obs"
#: At most this many structures are remembered per env (an env whose shapes never repeat
#: falls back to pickles rather than growing without bound).
MAX_STRUCTURES = 64

#: struct format characters of numpy scalar kinds and sizes.
_STRUCT_CHARS = {
    ("i", 1): "b",
    ("i", 2): "h",
    ("i", 4): "i",
    ("i", 8): "q",
    ("u", 1): "B",
    ("u", 2): "H",
    ("u", 4): "I",
    ("u", 8): "Q",
    ("f", 2): "e",
    ("f", 4): "f",
    ("f", 8): "d",
    ("b", 1): "?",
}
#: Array dtypes that travel as raw bytes.
_ARRAY_KINDS = "biufc"

# A structure is a tuple of ``(key, node)``; a node is a nested structure (a dict), or a leaf
# ``("s", type name or dtype string)`` (a scalar) or ``("a", dtype string, shape)`` (an array).
Structure = tuple[tuple[str, Any], ...]
#: Python scalar types of typed rows: their name in a structure and their struct code.
_PY_SCALARS: dict[type, tuple[str, str]] = {
    int: ("int", "q"),
    float: ("float", "d"),
    bool: ("bool", "?"),
}
_PY_SCALAR_OF_NAME = {name: t for t, (name, _) in _PY_SCALARS.items()}


#: A flat layout as the worker's Rust step packs it: the keys in order, each value's exact type,
#: the row's prefix (header and structure, for a step) and each value's struct code.
FlatPlan = tuple[tuple[str, ...], tuple[type, ...], bytes, str]

#: Value types whose signature needs more than the type (see :func:`_signature`).
_DEEP_TYPES = frozenset((np.ndarray, dict))


def _signature(info: dict[str, Any]) -> tuple[Any, ...]:
    """What must match for two infos to share a layout (keys in order, value types, array
    dtypes and shapes). A flat info of scalars (the common per-step info) takes a shortcut:
    its keys and its value types."""
    types = tuple(map(type, info.values()))
    if _DEEP_TYPES.isdisjoint(types):
        return (tuple(info), types)
    out: list[Any] = []
    for key, value in info.items():
        t = type(value)
        if t is np.ndarray:
            out.append((key, value.dtype, value.shape))
        elif t is dict:
            out.append((key, _signature(value)))
        else:
            out.append((key, t))
    return tuple(out)


class _Layout:
    """The typed-row layout of one structure (worker side)."""

    def __init__(self, info: dict[str, Any]) -> None:
        scalars: list[str] = []
        arrays = 0

        def describe(d: dict[str, Any]) -> Structure:
            nonlocal arrays
            nodes: list[tuple[str, Any]] = []
            for key, value in d.items():
                if type(key) is not str:
                    raise TypeError("non-string key")
                t = type(value)
                if t is dict:
                    nodes.append((key, describe(value)))
                elif t in _PY_SCALARS:
                    name, char = _PY_SCALARS[t]
                    nodes.append((key, ("s", name)))
                    scalars.append(char)
                elif isinstance(value, np.generic) and issubclass(t, np.number):
                    dt = np.dtype(t)
                    code = _STRUCT_CHARS.get((dt.kind, dt.itemsize))
                    if code is None:
                        raise TypeError(f"no struct code for {dt}")
                    nodes.append((key, ("s", dt.str)))
                    scalars.append(code)
                elif t is np.ndarray and value.dtype.kind in _ARRAY_KINDS:
                    nodes.append((key, ("a", value.dtype.str, value.shape)))
                    arrays += 1
                else:
                    raise TypeError(f"{t.__name__} is not typed")
            return tuple(nodes)

        self.structure = describe(info)
        self.has_arrays = arrays > 0
        #: Scalars only, no nested dicts: the values pack as they come.
        self.flat = not self.has_arrays and all(type(v) is not dict for v in info.values())
        self.pack = struct.Struct("<" + "".join(scalars)).pack
        desc = pickle.dumps(self.structure, protocol=4)
        digest = int.from_bytes(hashlib.blake2b(desc, digest_size=8).digest(), "little")
        pad = b"\0" * (-len(desc) % 8)
        self.prefixes = [_HEADER.pack(MAGIC, k, digest, len(desc)) + desc + pad for k in (0, 1)]
        #: A flat layout's step rows as the worker packs them (see :data:`FlatPlan`).
        self.plan: Optional[FlatPlan] = (
            (tuple(info), tuple(map(type, info.values())), self.prefixes[1], "".join(scalars))
            if self.flat
            else None
        )

    def encode(self, info: dict[str, Any], tag: int) -> bytes:
        if self.flat:
            return self.prefixes[tag] + self.pack(*info.values())
        if not self.has_arrays:
            return self.prefixes[tag] + self.pack(*_flat_scalars(info))
        scalars: list[Any] = []
        arrays: list[bytes] = []
        _split(info, scalars, arrays)
        return b"".join([self.prefixes[tag], self.pack(*scalars), *arrays])


def _flat_scalars(info: dict[str, Any]) -> Iterable[Any]:
    for value in info.values():
        if type(value) is dict:
            yield from _flat_scalars(value)
        else:
            yield value


def _split(info: dict[str, Any], scalars: list[Any], arrays: list[bytes]) -> None:
    for value in info.values():
        t = type(value)
        if t is dict:
            _split(value, scalars, arrays)
        elif t is np.ndarray:
            arrays.append(value.tobytes())
        else:
            scalars.append(value)


class InfoEncoder:
    """One env's info dicts as bytes (see the module docs); remembers its layouts."""

    def __init__(self) -> None:
        self._layouts: dict[tuple[Any, ...], Optional[_Layout]] = {}
        #: The last flat layout used: most envs give the same info on every step, which is
        #: then matched by its plan's keys and value types without hashing a signature.
        self._flat: Optional[_Layout] = None

    def encode(self, entries: list[tuple[str, Any]]) -> bytes:
        """The bytes of one call's entries: a typed row for a single typed info, else the
        pickled entries."""
        if len(entries) == 1 and entries[0][0] in TAGS:
            tag, info = entries[0]
            data, _ = self._typed(info, TAGS.index(tag))
            if data is not None:
                return data
        return pickle.dumps(entries, protocol=pickle.HIGHEST_PROTOCOL)

    def encode_step(self, info: dict[str, Any]) -> tuple[bytes, Optional[FlatPlan]]:
        """The bytes of a step's info, and its layout's :data:`FlatPlan` if it has one."""
        data, layout = self._typed(info, 1)
        if data is None:
            return pickle.dumps([("step", info)], protocol=pickle.HIGHEST_PROTOCOL), None
        return data, None if layout is None else layout.plan

    def _typed(self, info: dict[str, Any], tag: int) -> tuple[Optional[bytes], Optional[_Layout]]:
        """``info`` as a typed row of ``tag``, and its layout; ``(None, None)`` if it is not
        typed."""
        try:
            plan = None if self._flat is None else self._flat.plan
            if (
                plan is not None
                and tuple(map(type, info.values())) == plan[1]
                and tuple(info) == plan[0]
            ):
                layout: Optional[_Layout] = self._flat
            else:
                layout = self._layout_of(info)
            if layout is not None:
                return layout.encode(info, tag), layout
        except (struct.error, OverflowError, TypeError):
            pass  # e.g. an int beyond int64: pickled as it is
        return None, None

    def _layout_of(self, info: dict[str, Any]) -> Optional[_Layout]:
        """The typed layout of ``info`` (made on first sight), or ``None`` if it has none."""
        sig = _signature(info)
        layout = self._layouts.get(sig, ...)
        if layout is ...:
            try:
                layout = _Layout(info)
            except TypeError:
                layout = None
            if len(self._layouts) >= MAX_STRUCTURES:
                self._layouts.clear()
            self._layouts[sig] = layout
        if layout is not None and layout.flat:
            self._flat = layout
        return layout


class _Step(NamedTuple):
    """One key of a typed row's structure, as :meth:`_Decoded.put` adds it: a nested dict
    (``sub``, its steps) or a column (``name``: its record field; ``dtype``, ``shape``), and its
    ``_key`` mask."""

    key: str
    mask_key: str
    sub: Optional[list[_Step]]
    name: str
    dtype: Any
    shape: tuple[int, ...]


class _Decoded:
    """A typed row's layout on the caller's side: one numpy record per row."""

    def __init__(self, structure: Structure, offset: int) -> None:
        self.structure = structure
        scalars: list[tuple[tuple[str, ...], np.dtype, Callable[[Any], Any]]] = []
        arrays: list[tuple[tuple[str, ...], np.dtype, tuple[int, ...]]] = []

        def visit(nodes: Structure, path: tuple[str, ...]) -> None:
            for key, node in nodes:
                if node and node[0] == "s" and isinstance(node[1], str):
                    name = node[1]
                    t: Any = _PY_SCALAR_OF_NAME.get(name)
                    if t is not None:
                        scalars.append(((*path, key), np.dtype(t), t))
                    else:
                        dt = np.dtype(name)
                        scalars.append(((*path, key), dt, dt.type))
                elif node and node[0] == "a" and isinstance(node[1], str):
                    arrays.append(((*path, key), np.dtype(node[1]), tuple(node[2])))
                else:
                    visit(node, (*path, key))

        visit(structure, ())
        names: list[str] = []
        formats: list[Any] = []
        offsets: list[int] = []
        #: path -> (field name, vector dtype, shape, make a single value)
        self.leaves: dict[tuple[str, ...], tuple[str, np.dtype, tuple[int, ...], Any]] = {}
        for path, dt, make in scalars:
            name = f"f{len(names)}"
            names.append(name)
            formats.append(dt.newbyteorder("<"))
            offsets.append(offset)
            offset += dt.itemsize
            self.leaves[path] = (name, dt, (), make)
        for path, dt, shape in arrays:
            name = f"f{len(names)}"
            names.append(name)
            formats.append((dt, shape) if shape else dt)
            offsets.append(offset)
            offset += dt.itemsize * int(np.prod(shape, dtype=np.int64))
            self.leaves[path] = (name, dt, shape, None)
        self.dtype = np.dtype(
            {"names": names, "formats": formats, "offsets": offsets, "itemsize": max(offset, 1)}
        )

        def plan(nodes: Structure, path: tuple[str, ...]) -> list[_Step]:
            steps = []
            for key, node in nodes:
                leaf = self.leaves.get((*path, key))
                sub = plan(node, (*path, key)) if leaf is None else None
                name, dt, shape, _ = leaf if leaf is not None else ("", None, (), None)
                steps.append(_Step(key, f"_{key}", sub, name, dt, shape))
            return steps

        #: What :meth:`put` does, key by key in the structure's order.
        self.plan = plan(structure, ())

    def put(
        self, infos: dict[str, Any], records: np.ndarray, rows: Optional[np.ndarray], n: int
    ) -> None:
        """Add the records of ``rows`` (of a batch of ``n``; ``None``: all ``n``, in order) to
        vector infos."""
        every = slice(None) if rows is None else rows

        def run(target: dict[str, Any], steps: list[_Step]) -> None:
            for key, mask_key, sub, name, dt, shape in steps:
                if sub is not None:
                    inner = target.get(key)
                    if not isinstance(inner, dict):
                        inner = target[key] = {}
                    run(inner, sub)
                else:
                    array = target.get(key)
                    if array is not None:
                        array[every] = records[name]
                    elif rows is None:  # a new column of every row: one converting copy
                        target[key] = records[name].astype(dt)
                    else:
                        array = target[key] = np.zeros((n, *shape), dt)
                        array[rows] = records[name]
                _mark(target, mask_key, every, n)

        run(infos, self.plan)

    def one(self, data: bytes) -> dict[str, Any]:
        """One row as the env's own info dict (same value types)."""
        record = np.frombuffer(data, self.dtype, 1)[0]

        def build(nodes: Structure, path: tuple[str, ...]) -> dict[str, Any]:
            out: dict[str, Any] = {}
            for key, node in nodes:
                leaf = self.leaves.get((*path, key))
                if leaf is None:
                    out[key] = build(node, (*path, key))
                else:
                    name, _, _, make = leaf
                    value = record[name]
                    out[key] = make(value) if make is not None else np.array(value)
            return out

        return build(self.structure, ())


class InfoDecoder:
    """Decodes the info bytes of many envs (caller side); remembers the layouts it saw."""

    def __init__(self) -> None:
        self._layouts: dict[bytes, _Decoded] = {}
        #: Rows decoded so far, typed and pickled (``stats()``).
        self.typed_rows = 0
        self.pickled_rows = 0

    def counts(self) -> tuple[int, int]:
        """Rows decoded so far: typed, and pickled."""
        return self.typed_rows, self.pickled_rows

    def _layout(self, data: bytes) -> _Decoded:
        head = data[:HEADER_BYTES]
        layout = self._layouts.get(head[_HASH])
        if layout is None:
            _, _, _, length = _HEADER.unpack(head)
            structure = pickle.loads(data[HEADER_BYTES : HEADER_BYTES + length])
            layout = _Decoded(structure, HEADER_BYTES + length + (-length % 8))
            self._layouts[head[_HASH]] = layout
        return layout

    def entries(self, data: bytes) -> list[tuple[str, Any]]:
        """One env's entries: ``("reset" | "step", info)``, and :data:`STEP_OBS` or
        :data:`RESET_OBS` with an observation's dynamic values."""
        if data[:4] != MAGIC:
            self.pickled_rows += 1
            return pickle.loads(data)
        self.typed_rows += 1
        return [(TAGS[data[4]], self._layout(data).one(data))]

    def put_uniform(
        self,
        infos: dict[str, Any],
        data: Any,
        rows: Optional[Sequence[int]],
        n: int,
    ) -> bool:
        """Add rows that share one tag and structure (so one size), joined in ``data``, to
        vector infos of ``n`` rows: those of ``rows``, or all ``n`` in order for ``None``, in
        one go; ``False`` (nothing added) if they are not typed. ``data`` may also be a slot's
        extra-info room (one row per env, each starting with its info), read in place."""
        room = isinstance(data, np.ndarray)
        head = data[0, :HEADER_BYTES].tobytes() if room else data[:HEADER_BYTES]
        if head[:4] != MAGIC:
            return False
        layout = self._layout(data[0].tobytes() if room else data)
        at = None if rows is None else np.array(rows, np.intp)
        if room:
            records = np.ndarray(
                (len(data),), layout.dtype, buffer=data, strides=(data.strides[0],)
            )
        else:
            records = np.frombuffer(data, layout.dtype)
        layout.put(infos, records, at, n)
        self.typed_rows += len(records)
        return True

    def put_typed(self, infos: dict[str, Any], rows: list[tuple[int, bytes]], n: int) -> bool:
        """Add typed rows to vector infos, a group of rows of the same structure at a time;
        ``False`` (nothing added) if any row is not typed."""
        if not rows:
            return True
        ids, datas = zip(*rows)
        if len({d[:HEAD] for d in datas}) == 1:  # the usual call: one tag and structure
            every = len(ids) == n and ids == tuple(range(n))
            if self.put_uniform(infos, b"".join(datas), None if every else ids, n):
                return True
        groups: dict[bytes, list[tuple[int, bytes]]] = {}
        for row, data in rows:
            if data[:4] != MAGIC:
                return False
            groups.setdefault(data[_HASH], []).append((row, data))
        # The group holding the lowest row of a key decides its dtype, as env order does in
        # gymnasium: groups are taken by their lowest row.
        for group in sorted(groups.values(), key=lambda g: g[0][0]):
            layout = self._layout(group[0][1])
            records = np.frombuffer(b"".join(d for _, d in group), layout.dtype)
            at = np.fromiter((r for r, _ in group), np.intp, len(group))
            layout.put(infos, records, at, n)
            self.typed_rows += len(group)
        return True


def split_joined(
    rows: Optional[Sequence[int]], data: Any, size: int, ends: Sequence[int], n: int
) -> list[tuple[int, bytes]]:
    """The ``(row, bytes)`` of joined extras (a result's ``extras``): ``rows`` (``None``:
    all ``n`` in order), each ``size`` bytes of ``data``, or ending at ``ends``; ``data`` may
    also be a slot's extra-info room (``n x room`` bytes, each row's first ``size`` its own)."""
    if isinstance(data, np.ndarray):
        return [(row, data[row, :size].tobytes()) for row in range(n)]
    if size:
        ends = range(size, len(data) + 1, size)
    starts = [0, *ends[:-1]]
    ids = range(n) if rows is None else rows
    return [(row, data[a:b]) for row, a, b in zip(ids, starts, ends)]


def add_row_info(infos: dict[str, Any], info: dict[str, Any], row: int, n: int) -> dict[str, Any]:
    """Add one row's info to vector infos of ``n`` rows, as gymnasium's ``_add_info`` does
    (``final_obs`` and other objects in object arrays, nested dicts recursively, a ``_key``
    mask per key)."""
    for key, value in info.items():
        if isinstance(value, dict) and key != "final_obs":
            array: Any = add_row_info(infos.get(key, {}), value, row, n)
        else:
            array = infos.get(key)
            if array is None:
                if key != "final_obs" and (
                    type(value) in (int, float, bool) or isinstance(value, np.number)
                ):
                    array = np.zeros(n, dtype=type(value))
                elif key != "final_obs" and isinstance(value, np.ndarray):
                    array = np.zeros((n, *value.shape), dtype=value.dtype)
                else:
                    array = np.full(n, None, dtype=object)
            array[row] = value
        infos[key] = array
        _mark(infos, f"_{key}", row, n)
    return infos


def _mark(infos: dict[str, Any], mask_key: str, rows: Any, n: int) -> None:
    """Set the mask ``mask_key`` (``_key``) of vector infos of ``n`` rows at ``rows`` (a row,
    an index array, or ``slice(None)`` for every row)."""
    mask = infos.get(mask_key)
    if mask is not None:
        mask[rows] = True
    elif isinstance(rows, slice):  # every row
        infos[mask_key] = np.ones(n, np.bool_)
    else:
        mask = infos[mask_key] = np.zeros(n, np.bool_)
        mask[rows] = True


def vector_infos(
    infos: dict[str, Any],
    decoder: InfoDecoder,
    extras: list[tuple[int, bytes]],
    n: int,
    env_info: Callable[[int, list[tuple[str, Any]]], dict[str, Any]],
    special: Iterable[int] = (),
) -> dict[str, Any]:
    """gymnasium's vector infos of one call: ``extras`` are ``(row, info bytes)`` of a batch
    of ``n`` rows. Typed rows go in as columns; when some row is pickled, or is ``special``
    (its info needs ``env_info``'s per-env treatment, e.g. a SAME_STEP final observation),
    every row goes in one by one, in row order, through ``env_info(row, entries)``."""
    special = set(special)
    if not special and decoder.put_typed(infos, extras, n):
        return infos
    by_row = dict(extras)
    for row in sorted(set(by_row) | special):
        data = by_row.get(row)
        info = env_info(row, decoder.entries(data) if data is not None else [])
        if info:
            infos = add_row_info(infos, info, row, n)
    return infos


def split_vector_info(info: dict[str, Any], n: int) -> list[dict[str, Any]]:
    """The per-env infos in a vector env's info dict of ``n`` envs (the inverse of
    gymnasium's ``_add_info``): env ``i`` has key ``k`` where the mask ``_k`` is set (everywhere
    when there is none), with row ``i`` of its array (a nested dict is split the same way, a
    ``numpy.bool_`` becomes a ``bool``); a value that is not ``n`` rows goes to every env."""
    rows: list[dict[str, Any]] = [{} for _ in range(n)]
    for key, value in info.items():
        if key.startswith("_") and key[1:] in info:
            continue
        parts: Any
        if isinstance(value, dict):
            parts = split_vector_info(value, n)
        elif isinstance(value, np.ndarray) and value.ndim >= 1 and value.shape[0] == n:
            parts = value.tolist() if value.dtype == np.bool_ and value.ndim == 1 else list(value)
        elif isinstance(value, (list, tuple)) and len(value) == n:
            parts = value
        else:
            parts = [value] * n
        mask = info.get(f"_{key}")
        for i in range(n) if mask is None else np.flatnonzero(mask):
            rows[i][key] = parts[i]
    return rows
