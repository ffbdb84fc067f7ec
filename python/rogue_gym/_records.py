"""The per-env step record written by pool workers, as a numpy structured dtype."""

from __future__ import annotations

import numpy as np

from . import _native

__all__ = [
    "FLAG_FINAL_OBS",
    "FLAG_RESTARTED",
    "FLAG_TERMINATED",
    "FLAG_TRUNCATED",
    "MAX_INFO",
    "RECORD_DTYPE",
]

# The record layout's constants come from the native module (the pool crate defines them).
#: Most env-defined info values per env.
MAX_INFO: int = _native.MAX_INFO
#: The episode ended by the game's rules (death, amulet).
FLAG_TERMINATED: int = _native.FLAG_TERMINATED
#: The episode was cut (step limit or worker restart).
FLAG_TRUNCATED: int = _native.FLAG_TRUNCATED
#: The env's worker was restarted; its episode was cut and a new one started.
FLAG_RESTARTED: int = _native.FLAG_RESTARTED
#: (SAME_STEP) the final observation of the ended episode is available.
FLAG_FINAL_OBS: int = _native.FLAG_FINAL_OBS

#: Mirrors the pool's ``#[repr(C)] EnvRecord`` (112 bytes); checked against the native size.
RECORD_DTYPE = np.dtype(
    [
        ("reward", "<f8"),
        ("flags", "<u4"),
        ("episode_length", "<u4"),
        ("episode_return", "<f8"),
        ("episode", "<u8"),
        ("seed", "<u8"),
        ("extra_len", "<u4"),
        ("reserved", "<u4"),
        ("info", "<f8", (MAX_INFO,)),
    ],
    align=True,
)

if RECORD_DTYPE.itemsize != _native.RECORD_BYTES:  # pragma: no cover - a build mismatch
    raise ImportError(
        f"rogue_gym._native records are {_native.RECORD_BYTES} bytes but RECORD_DTYPE has "
        f"{RECORD_DTYPE.itemsize}: the extension and the Python package are from different builds"
    )
