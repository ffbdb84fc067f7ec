"""Observation settings of the original API: ``StatusFlag``, ``DungeonType``, ``ImageSetting``.

They describe the original ``(C, H, W)`` float32 image (dungeon channels, then one constant
plane per selected status value, then an optional visited-history plane) and map it to the
engine's observation spec.
"""

from __future__ import annotations

import enum
from typing import Any, NamedTuple

import numpy as np
from gymnasium import spaces

from .. import _native

__all__ = ["DungeonType", "ImageSetting", "ObsSpec", "StatusFlag"]


class StatusFlag(enum.Flag):
    """Which status values become constant planes after the dungeon channels.

    The bit order is the original's and fixes the plane order.
    """

    EMPTY = 0
    DUNGEON_LEVEL = 1 << 0
    HP_CURRENT = 1 << 1
    HP_MAX = 1 << 2
    STR_CURRENT = 1 << 3
    STR_MAX = 1 << 4
    DEFENSE = 1 << 5
    PLAYER_LEVEL = 1 << 6
    EXP = 1 << 7
    HUNGER = 1 << 8
    FULL = 0b1_1111_1111

    def count_one(self) -> int:
        """Number of selected status values (planes)."""
        return bin(self.value).count("1")


class DungeonType(enum.Enum):
    """How the dungeon itself is encoded: one gray channel or one-hot symbol channels."""

    GRAY = 1
    SYMBOL = 2


class ObsSpec(NamedTuple):
    """An observation spec in the engine's terms (``engine/src/obs/mod.rs`` documents the layouts).

    Attributes:
        encoding: one of ``symbol_onehot``, ``symbol_index``, ``gray``, ``ascii``,
            ``status`` (alias ``status_vector``).
        dtype: ``uint8`` or ``float32``.
        status: bitmask of :class:`StatusFlag` values appended as planes.
        normalize_status: scale status planes to ``[0, 1]`` instead of raw values.
        history: append the visited-cells plane.
    """

    encoding: str = "symbol_onehot"
    dtype: str = "float32"
    status: int = 0
    normalize_status: bool = False
    history: bool = False

    def validated(self) -> ObsSpec:
        """Return the spec with names normalised by the engine's parser (the one parser of an
        observation spec), raising ``ValueError`` on unknown values."""
        status = self.status.value if isinstance(self.status, StatusFlag) else self.status
        try:
            dtype = np.dtype(self.dtype).name
        except TypeError:
            dtype = str(self.dtype)
        spec = {
            "encoding": str(self.encoding).lower(),
            "dtype": dtype,
            "status": int(status),
            "normalize_status": bool(self.normalize_status),
            "history": bool(self.history),
        }
        return ObsSpec(**_native.normalize_obs_spec(spec))

    def to_dict(self) -> dict[str, Any]:
        """The spec as a plain dict (what the native layer takes)."""
        return self._asdict()


class ImageSetting(NamedTuple):
    """The original observation setting.

    The default (symbol channels + all nine status planes, no history) gives
    ``(symbols + 9, H, W)`` float32 observations, as in the original.
    """

    dungeon: DungeonType = DungeonType.SYMBOL
    status: StatusFlag = StatusFlag.FULL
    includes_hist: bool = False

    def dim(self, symbols: int) -> int:
        """Number of channels for a game with ``symbols`` symbol channels."""
        channels = symbols if self.dungeon == DungeonType.SYMBOL else 1
        return channels + self.status.count_one() + int(self.includes_hist)

    def to_spec(self, dtype: str = "float32", normalize_status: bool = False) -> ObsSpec:
        """The equivalent engine observation spec."""
        enc = "symbol_onehot" if self.dungeon == DungeonType.SYMBOL else "gray"
        return ObsSpec(enc, dtype, self.status.value, normalize_status, self.includes_hist)

    def detect_space(self, h: int, w: int, symbols: int) -> spaces.Box:
        """The observation space for an ``h`` x ``w`` screen (float32, as in the original)."""
        return observation_space(self.to_spec(), (self.dim(symbols), h, w), symbols)


def observation_space(spec: ObsSpec, shape: tuple[int, ...], symbols: int) -> spaces.Box:
    """The ``Box`` for observations of ``spec`` with the given shape (exact per-channel bounds).

    Map channels: one-hot and history planes lie in ``[0, 1]``, symbol indices in
    ``[0, symbols)``, ascii in ``[0, 255]``, gray in ``[0, 1]`` (f32) or ``[0, 255]`` (u8).
    Status planes are ``[0, 1]`` when normalised (``[0, 255]`` as u8), else raw values: u8
    saturates to ``[0, 255]``, f32 holds any game integer (hp can go negative on death).
    """
    dtype = np.dtype(spec.dtype)
    u8 = dtype.kind == "u"
    # Raw f32 status values are game integers (i32/u32): finite bounds that hold any of them.
    raw_lo, raw_hi = (0.0, 255.0) if u8 else (-float(2**31), float(2**32))
    norm_hi = 255.0 if u8 else 1.0
    status_lo, status_hi = (0.0, norm_hi) if spec.normalize_status else (raw_lo, raw_hi)
    if spec.encoding == "status":
        return spaces.Box(status_lo, status_hi, shape, dtype)
    map_hi = {
        "symbol_onehot": 1.0,
        "symbol_index": float(symbols - 1),
        "ascii": 255.0,
        "gray": 255.0 if u8 else 1.0,
    }[spec.encoding]
    if len(shape) == 2:
        return spaces.Box(0, map_hi, shape, dtype)
    low = np.zeros(shape, dtype=np.float64)
    high = np.full(shape, map_hi, dtype=np.float64)
    n_status = bin(spec.status).count("1")
    n_hist = int(spec.history)
    first = shape[0] - n_status - n_hist
    low[first : first + n_status] = status_lo
    high[first : first + n_status] = status_hi
    if n_hist:
        high[-1] = 1.0
    return spaces.Box(low.astype(dtype), high.astype(dtype), shape, dtype)
