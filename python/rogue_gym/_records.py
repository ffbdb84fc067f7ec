"""The per-env step record written by pool workers, as a numpy structured dtype."""

from __future__ import annotations

import numpy as np

__all__ = [
    "FLAG_FINAL_OBS",
    "FLAG_RESTARTED",
    "FLAG_TERMINATED",
    "FLAG_TRUNCATED",
    "MAX_INFO",
    "RECORD_DTYPE",
]

#: Most env-defined info values per env.
MAX_INFO = 8
#: The episode ended by the game's rules (death, amulet).
FLAG_TERMINATED = 1
#: The episode was cut (step limit or worker restart).
FLAG_TRUNCATED = 2
#: The env's worker was restarted; its episode was cut and a new one started.
FLAG_RESTARTED = 4
#: (SAME_STEP) the final observation of the ended episode is available.
FLAG_FINAL_OBS = 8

#: Mirrors the pool's ``#[repr(C)] EnvRecord`` (104 bytes); checked against the native size.
RECORD_DTYPE = np.dtype(
    [
        ("reward", "<f4"),
        ("flags", "<u4"),
        ("episode_return", "<f8"),
        ("episode", "<u8"),
        ("seed", "<u8"),
        ("episode_length", "<u4"),
        ("reserved", "<u4"),
        ("info", "<f8", (MAX_INFO,)),
    ],
    align=True,
)
