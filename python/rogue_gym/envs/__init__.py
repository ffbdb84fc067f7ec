"""Single-process environments with the original Rogue-Gym API (gymnasium 1.x)."""

from .image import DungeonType, ImageSetting, ObsSpec, StatusFlag
from .rogue_env import ACTION_MEANINGS, ACTIONS, RogueEnv
from .wrappers import FirstFloorEnv, StairRewardEnv

__all__ = [
    "ACTIONS",
    "ACTION_MEANINGS",
    "DungeonType",
    "FirstFloorEnv",
    "ImageSetting",
    "ObsSpec",
    "RogueEnv",
    "StairRewardEnv",
    "StatusFlag",
]
