"""``RogueEnv``: a gymnasium ``Env`` over one in-process Rogue-Gym engine."""

from __future__ import annotations

import json
import os
import sys
import time
from typing import Any, Mapping, Optional, Sequence, SupportsFloat, Union

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .. import _native
from .._config import load_config, to_json
from .image import ImageSetting, ObsSpec, observation_space

__all__ = ["ACTIONS", "ACTION_MEANINGS", "RogueEnv"]

#: The 11 action keys, in index order (vi keys: ``j`` moves down, ``k`` up).
ACTIONS: str = _native.ACTION_KEYS
#: What each action key does.
ACTION_MEANINGS: dict[str, str] = {
    ".": "NO_OPERATION",
    "h": "MOVE_LEFT",
    "j": "MOVE_DOWN",
    "k": "MOVE_UP",
    "l": "MOVE_RIGHT",
    "n": "MOVE_RIGHTDOWN",
    "b": "MOVE_LEFTDOWN",
    "u": "MOVE_RIGHTUP",
    "y": "MOVE_LEFTUP",
    ">": "DOWNSTAIR",
    "s": "SEARCH",
}

_SEED_MAX = 2**63
#: Run keys (repeat a move until something interesting happens); each repetition is a step.
_RUN_KEYS = "HJKLYUBN"


def _action_index(action: Any) -> int:
    """Convert an int-like action to an index, raising a clear error otherwise."""
    if isinstance(action, (bool, np.bool_)):
        raise TypeError(f"action must be an int in [0, {len(ACTIONS)}) or a key string, got bool")
    if isinstance(action, np.ndarray):
        if action.ndim != 0 or action.dtype.kind not in "iu":
            raise TypeError(
                f"action must be an int in [0, {len(ACTIONS)}) or a key string, "
                f"got an array of shape {action.shape} and dtype {action.dtype}"
            )
        action = action.item()
    if not isinstance(action, (int, np.integer)):
        raise TypeError(
            f"action must be an int in [0, {len(ACTIONS)}) or a key string, got {type(action).__name__}"
        )
    index = int(action)
    if not 0 <= index < len(ACTIONS):
        raise ValueError(f"Invalid action: {index} (expected an int in [0, {len(ACTIONS)}))")
    return index


class RogueEnv(gym.Env):
    """Rogue-Gym as a gymnasium environment (one game in this process).

    Compatible with the original constructor: ``RogueEnv(config_path=None, config_dict=None,
    max_steps=1000, image_setting=ImageSetting(), **kwargs)``, where extra keywords are game-config
    keys (``RogueEnv(width=32, height=16, seed_range=[0, 40])``). The engine rejects unknown config
    keys with a ``ValueError`` that names the key.

    Reward is the gold gained plus ``stair_reward`` for each new deepest floor. The default
    ``stair_reward=0`` keeps the original's gold-only reward; :class:`StairRewardEnv` adds the
    original's wrapper bonus on top (do not set both unless you want both). The pool
    (:func:`rogue_gym.make_vec`) uses the design's default of 50.

    Observations: by default the original image (``image_setting``, float32 ``(C, H, W)``). Pass
    ``obs="symbol_onehot" | "symbol_index" | "gray" | "ascii" | "status_vector"`` (and
    ``dtype="uint8" | "float32"``, ``status=StatusFlag...``, ``history=True``) to use the
    engine's encodings instead. Every observation is a new array that the caller owns.

    Actions: an int in ``[0, 11)`` (index into :data:`ACTIONS`) or a string of keys. Each key of a
    multi-key string is one game step; rewards are summed and the string stops at episode end.

    Seeding: ``reset(seed=s)`` plays dungeon ``s``; later ``reset()`` calls draw the next episode
    seed from the env's RNG, uniformly from ``seed_range`` if the config has one, else the config's
    fixed ``seed`` if any, else from ``[0, 2**63)``. ``seed(s)`` (the original API) pins every
    following episode to ``s``.
    """

    metadata: dict[str, Any] = {"render_modes": ["human", "ansi"], "render_fps": 10}  # noqa: RUF012
    ACTIONS = ACTIONS
    ACTION_MEANINGS = ACTION_MEANINGS
    ACTION_LEN = len(ACTIONS)

    def __init__(
        self,
        config_path: Optional[Union[str, os.PathLike]] = None,
        config_dict: Optional[Mapping[str, Any]] = None,
        max_steps: int = 1000,
        image_setting: ImageSetting = ImageSetting(),  # noqa: B008 (immutable NamedTuple)
        *,
        obs: Optional[str] = None,
        dtype: Optional[str] = None,
        status: Optional[Any] = None,
        normalize_status: bool = False,
        history: Optional[bool] = None,
        stair_reward: float = 0.0,
        render_mode: Optional[str] = None,
        **kwargs: Any,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}"
            )
        if int(max_steps) <= 0:
            raise ValueError(f"max_steps must be positive, got {max_steps}")
        self.config: dict[str, Any] = load_config(config_path, config_dict, kwargs)
        self.max_steps = int(max_steps)
        self.stair_reward = float(stair_reward)
        self.render_mode = render_mode
        self.image_setting = image_setting
        if obs is None:
            spec = image_setting.to_spec(dtype or "float32", normalize_status)
            if status is not None:
                spec = spec._replace(status=status)
            if history is not None:
                spec = spec._replace(history=history)
        else:
            spec = ObsSpec(obs, dtype or "uint8", status or 0, normalize_status, bool(history))
        self.obs_spec: ObsSpec = spec.validated()
        self.game = _native.Game(to_json(self.config), self.max_steps, self.stair_reward)
        shape = tuple(self.game.obs_shape(self.obs_spec))
        self.observation_space = observation_space(self.obs_spec, shape, self.game.symbols)
        self.action_space = spaces.Discrete(len(ACTIONS))
        self._sticky_seed: Optional[int] = None
        self._actions: list[str] = []
        self._episode_seed: Optional[int] = None
        self._needs_reset = True

    # ----------------------------------------------------------------------------------------
    # gymnasium API
    def reset(
        self, *, seed: Optional[int] = None, options: Optional[dict[str, Any]] = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start a new episode and return ``(obs, info)``.

        ``seed`` selects the dungeon directly (and seeds the env's RNG for later resets);
        ``options={"episode_seed": s}`` plays dungeon ``s`` without reseeding the RNG.
        """
        super().reset(seed=seed)
        if options and "episode_seed" in options:
            episode_seed = int(options["episode_seed"])
        elif seed is not None:
            episode_seed = int(seed)
        else:
            episode_seed = self._draw_seed()
        if not 0 <= episode_seed < 2**64:
            raise ValueError(f"seed must be in [0, 2**64), got {episode_seed}")
        self._episode_seed = episode_seed
        self.game.reset(episode_seed)
        self._actions = []
        self._needs_reset = False
        return self._obs(), self.game.info()

    def step(
        self, action: Union[int, str, np.integer]
    ) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        """Play one action (or each key of a string) and return the gymnasium 5-tuple."""
        if self._needs_reset:
            raise RuntimeError("call reset() before step()")
        if isinstance(action, str):
            if not action:
                raise ValueError("an action string must hold at least one key")
            bad = [k for k in action if k not in ACTIONS and k not in _RUN_KEYS]
            if bad:
                raise ValueError(
                    f"Invalid input key: {bad[0]!r} (expected one of {ACTIONS!r}, or HJKLYUBN to run)"
                )
            keys = list(action)
        else:
            keys = [ACTIONS[_action_index(action)]]
        total = 0.0
        terminated = truncated = False
        for key in keys:
            reward, terminated, truncated = self.game.step_key(key)
            self._actions.append(key)
            total += reward
            if terminated or truncated:
                self._needs_reset = True
                break
        return self._obs(), total, bool(terminated), bool(truncated), self.game.info()

    def render(self) -> Optional[str]:
        """``ansi``: return the screen (map rows and status line) as text; ``human``: print it."""
        if self.render_mode is None:
            gym.logger.warn(
                "render() called without a render_mode; pass render_mode='ansi' or 'human'"
            )
            return None
        text = self.screen_text()
        if self.render_mode == "ansi":
            return text
        print(text, flush=True)
        return None

    def close(self) -> None:
        """Nothing to release (the engine lives in this process)."""

    # ----------------------------------------------------------------------------------------
    # original API
    def seed(self, seed: Optional[int] = None) -> None:
        """Pin every following episode to dungeon ``seed`` (original, sticky); ``None`` unpins."""
        self._sticky_seed = None if seed is None else int(seed)

    def screen_size(self) -> tuple[int, int]:
        """``(height, width)`` of the screen."""
        return self.game.height, self.game.width

    def get_dungeon(self) -> list[str]:
        """The map rows as strings (what the player currently sees)."""
        return list(self.game.screen())

    def get_config(self) -> dict[str, Any]:
        """The game config as a dict."""
        return dict(self.config)

    def save_config(self, path: Union[str, os.PathLike]) -> None:
        """Write the game config as JSON."""
        with open(path, "w", encoding="utf-8") as f:
            json.dump(self.config, f)

    def screen_text(self) -> str:
        """The screen: map rows followed by the status line."""
        return "\n".join([*self.game.screen(), self.game.status_line()])

    def __repr__(self) -> str:
        if self._episode_seed is None:
            return f"RogueEnv(config={self.config!r}, max_steps={self.max_steps})"
        return self.screen_text()

    @property
    def episode_seed(self) -> Optional[int]:
        """The dungeon seed of the current episode."""
        return self._episode_seed

    @property
    def status(self) -> dict[str, int]:
        """The player's status (dungeon level, gold, hp, ...)."""
        return self.game.status()

    def state_to_image(self, setting: Optional[ImageSetting] = None) -> np.ndarray:
        """The current state as an original-style float32 image for ``setting``."""
        spec = (setting or self.image_setting).to_spec().validated()
        return self.game.obs(spec)

    def save_actions(self, path: Union[str, os.PathLike]) -> None:
        """Write the current episode's seed, config and action keys as JSON (see :meth:`replay`)."""
        record = {
            "seed": self._episode_seed,
            "config": self.config,
            "max_steps": self.max_steps,
            "actions": "".join(self._actions),
        }
        with open(path, "w", encoding="utf-8") as f:
            json.dump(record, f)

    @property
    def action_history(self) -> str:
        """The keys played in the current episode."""
        return "".join(self._actions)

    def replay(
        self,
        interval_ms: int = 100,
        *,
        path: Optional[Union[str, os.PathLike]] = None,
        out: Any = None,
    ) -> list[str]:
        """Replay the current episode (or one saved by :meth:`save_actions`) frame by frame.

        Prints each frame to ``out`` (default: stdout; pass ``out=False`` to print nothing)
        waiting ``interval_ms`` between frames, and returns the frames.
        """
        if path is not None:
            with open(path, encoding="utf-8") as f:
                record = json.load(f)
            config, seed, keys = record["config"], record["seed"], record["actions"]
            max_steps = int(record.get("max_steps", self.max_steps))
        else:
            config, seed, keys, max_steps = (
                self.config,
                self._episode_seed,
                self.action_history,
                self.max_steps,
            )
        if seed is None:
            raise RuntimeError("nothing to replay: no episode was played")
        game = _native.Game(to_json(config), max_steps, self.stair_reward)
        game.reset(int(seed))
        frames = ["\n".join([*game.screen(), game.status_line()])]
        for key in keys:
            game.step_key(key)
            frames.append("\n".join([*game.screen(), game.status_line()]))
        if out is not False:
            stream = sys.stdout if out is None else out
            for frame in frames:
                stream.write("\x1b[2J\x1b[H" + frame + "\n")
                stream.flush()
                if interval_ms > 0:
                    time.sleep(interval_ms / 1000)
        return frames

    # ----------------------------------------------------------------------------------------
    def _obs(self) -> np.ndarray:
        return self.game.obs(self.obs_spec)

    def _draw_seed(self) -> int:
        if self._sticky_seed is not None:
            return self._sticky_seed
        seed_range: Optional[Sequence[int]] = self.config.get("seed_range")
        if seed_range is not None:
            lo, hi = int(seed_range[0]), int(seed_range[1])
            if hi <= lo:
                raise ValueError(f"seed_range must satisfy lo < hi, got {list(seed_range)}")
            return int(self.np_random.integers(lo, hi))
        if self.config.get("seed") is not None:
            return int(self.config["seed"])
        return int(self.np_random.integers(0, _SEED_MAX))
