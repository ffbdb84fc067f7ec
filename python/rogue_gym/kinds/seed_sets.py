"""The native game's seed sets: which dungeons a pool's episodes are drawn from."""

from __future__ import annotations

from typing import Any, Mapping, Optional

import numpy as np

from ..settings import SeedsLike

__all__ = ["seed_set"]


def seed_set(seeds: SeedsLike, config: Mapping[str, Any]) -> Optional[dict[str, Any]]:
    """The pool's seed set (JSON) from ``seeds`` (or the config's ``seed_range`` / ``seed``);
    ``None``: unrestricted."""
    if seeds is None:
        if config.get("seed_range") is not None:
            lo, hi = (int(x) for x in config["seed_range"])
            seeds = range(lo, hi)
        elif config.get("seed") is not None:
            seeds = [int(config["seed"])]
        else:
            return None
    if isinstance(seeds, range):
        if seeds.step != 1:
            return {"list": [int(s) for s in seeds]}
        if len(seeds) == 0:
            raise ValueError("the seed range is empty")
        return {"range": {"start": int(seeds.start), "end": int(seeds.stop)}}
    if (
        isinstance(seeds, tuple)
        and len(seeds) == 2
        and all(isinstance(x, (int, np.integer)) for x in seeds)
    ):
        lo, hi = int(seeds[0]), int(seeds[1])
        if hi <= lo:
            raise ValueError(f"seeds=(lo, hi) needs lo < hi, got {seeds}")
        return {"range": {"start": lo, "end": hi}}
    values = [int(s) for s in seeds]
    if not values:
        raise ValueError("seeds must not be empty")
    if any(s < 0 or s >= 2**64 for s in values):
        raise ValueError("seeds must lie in [0, 2**64)")
    return {"list": values}
