"""Game-config helpers shared by the single env and the pool."""

from __future__ import annotations

import copy
import json
import os
from typing import Any, Mapping, Optional, Union

__all__ = ["PAPER_CONFIG", "load_config"]

#: The CoG'19 paper's training config (32x16, 2x2 rooms, no enemies, training seeds [0, 40)).
PAPER_CONFIG: dict[str, Any] = {
    "width": 32,
    "height": 16,
    "seed_range": [0, 40],
    "hide_dungeon": True,
    "dungeon": {"style": "rogue", "room_num_x": 2, "room_num_y": 2},
    "enemies": {"enemies": []},
}

ConfigLike = Union[None, str, "os.PathLike[str]", Mapping[str, Any]]


def load_config(
    config_path: Optional[Union[str, os.PathLike]] = None,
    config_dict: Optional[Mapping[str, Any]] = None,
    extra: Optional[Mapping[str, Any]] = None,
) -> dict[str, Any]:
    """Build a game-config dict from a JSON file, a dict and extra keys.

    ``extra`` keys override the file/dict (as the original's ``**kwargs``). Nothing passed in is
    mutated (the original's shared mutable default is gone).
    """
    if config_path is not None:
        with open(config_path, encoding="utf-8") as f:
            text = f.read()
        try:
            base = json.loads(text)
        except json.JSONDecodeError as e:
            raise ValueError(f"invalid JSON in config file {os.fspath(config_path)!r}: {e}") from e
        if not isinstance(base, dict):
            raise ValueError(f"config file {os.fspath(config_path)!r} must hold a JSON object")
    elif config_dict is not None:
        if not isinstance(config_dict, Mapping):
            raise TypeError(f"config_dict must be a mapping, got {type(config_dict).__name__}")
        base = copy.deepcopy(dict(config_dict))
    else:
        base = {}
    if extra:
        base.update(copy.deepcopy(dict(extra)))
    return base


def resolve_config(config: ConfigLike) -> dict[str, Any]:
    """Accept ``None`` (default game), ``"paper"``, a JSON string, a path or a dict."""
    if config is None:
        return {}
    if isinstance(config, Mapping):
        return copy.deepcopy(dict(config))
    if isinstance(config, str) and config == "paper":
        return copy.deepcopy(PAPER_CONFIG)
    if isinstance(config, str) and config.lstrip().startswith("{"):
        try:
            value = json.loads(config)
        except json.JSONDecodeError as e:
            raise ValueError(f"invalid JSON config: {e}") from e
        if not isinstance(value, dict):
            raise ValueError("a JSON config must be an object")
        return value
    if isinstance(config, (str, os.PathLike)):
        return load_config(config_path=config)
    raise TypeError(
        f"config must be a dict, a JSON string, a path or 'paper'; got {type(config).__name__}"
    )


def to_json(config: Mapping[str, Any]) -> str:
    """Serialise a config dict for the engine."""
    return json.dumps(config, separators=(",", ":"))
