"""The native game as an env kind: Rogue-Gym's own dungeons, run by the workers in Rust.

Its spaces come from the engine, its seeds from the pool's episode schedule (env ``i``'s
``e``-th episode plays the same dungeon whatever the worker count), its infos from the
records the workers write (decoded into preallocated columns, no per-env Python), and its
frames are rebuilt by replaying each env's episode here (:mod:`rogue_gym.kinds.replay`).
"""

from __future__ import annotations

import weakref
from typing import TYPE_CHECKING, Any, Optional, Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .. import _native
from .._config import resolve_config, to_json
from ..envs.image import ObsSpec, observation_space
from ..envs.palette import screen_to_rgb
from ..envs.rogue_env import ACTIONS
from ..front.core import SUMMARY_FINAL, SUMMARY_RESTARTED, flags, mark_restarted, scalar_actions
from ..protocol.ops import op_table, run_op
from ..settings import PoolSettings
from .replay import ActionHistory
from .seed_sets import seed_set

if TYPE_CHECKING:
    from ..front.core import Core

__all__ = ["RENDER_MODES", "WHO", "NativeKind"]

#: This kind's name in :data:`rogue_gym.protocol.ops.SERVED_BY`.
WHO = "the native game"

#: How the native game's frames can be rendered: text (``ansi``), printed (``human``), or one
#: pixel per cell (``rgb_array``).
RENDER_MODES = ("ansi", "human", "rgb_array")
#: Info values of the game that are flags (the rest are integers).
_BOOL_INFO = frozenset(_native.BOOL_INFO_NAMES)


class NativeKind:
    """Rogue-Gym's own game (see :class:`rogue_gym.settings.PoolSettings` for the options)."""

    def __init__(self, settings: PoolSettings, render_mode: Optional[str] = None) -> None:
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(
                f"render_mode must be one of {list(RENDER_MODES)} or None, got {render_mode!r}"
            )
        st = settings.checked()
        self.settings = st
        self.config = resolve_config(st.config)
        self.obs_spec = ObsSpec(
            st.obs, st.dtype, st.status, st.normalize_status, st.history
        ).validated()
        self.num_envs = st.num_envs
        self.max_steps, self.stair_reward = st.max_steps, st.stair_reward
        # A local game validates the config (ValueError naming the key) and gives the spaces.
        probe = _native.Game(to_json(self.config), self.max_steps, self.stair_reward)
        self.obs_shape = tuple(probe.obs_shape(self.obs_spec))
        self.obs_dtype = np.dtype(self.obs_spec.dtype)
        self.obs_bytes = int(np.prod(self.obs_shape)) * self.obs_dtype.itemsize
        self.single_observation_space = observation_space(
            self.obs_spec, self.obs_shape, int(probe.symbols)
        )
        self.single_action_space: spaces.Discrete = spaces.Discrete(len(ACTIONS))
        self.metadata: dict[str, Any] = {"render_modes": list(RENDER_MODES)}
        self.render_mode = render_mode
        self.spec = None
        self.worker_command = list(st.worker_command or [])
        self.base_seed = int(st.seed or 0)
        self.seeds: dict[str, Any] = {
            "base": self.base_seed,
            "set": seed_set(st.seeds, self.config),
            "policy": st.seed_policy,
            "shard": None
            if st.shard is None
            else {"first_env": st.shard[0], "total_envs": st.shard[1]},
        }
        self.info_names: list[str] = []
        self._templates: list[dict[str, Any]] = []
        self._info_keys: list[str] = []
        self._masks: dict[str, np.ndarray] = {}
        self._actions = np.zeros(self.num_envs, np.int64)
        #: The actions of the last step (int64, one per env).
        self.last_actions = self._actions
        self._history = (
            ActionHistory(self.config, self.max_steps, self.stair_reward, self.num_envs)
            if render_mode is not None
            else None
        )
        # Render bookkeeping (NEXT_STEP): envs whose episode ended at the last call, whose next
        # step starts a new episode; and those a partial reset left to be autoreset.
        self._ended = np.zeros(self.num_envs, bool)
        self._started = False
        #: The action last sent to each env through the async API (for the replay history).
        self._sent = np.zeros(self.num_envs, np.int64)
        self._ops = op_table(self, WHO)
        #: Who serves this kind's env operations (:data:`rogue_gym.protocol.ops.SERVED_BY`).
        self.who = WHO
        #: The env operations this kind serves.
        self.ops = frozenset(self._ops)

    # -- the pool --------------------------------------------------------------------------

    def pool_settings(self) -> dict[str, Any]:
        """The native pool's settings: the game, its observation and the seed schedule."""
        return {
            **self.settings.pool_json(self.num_envs),
            "env": {
                "kind": "rogue",
                "config": self.config,
                "max_steps": self.max_steps,
                "stair_reward": self.stair_reward,
                "obs": self.obs_spec.to_dict(),
            },
            "seeds": dict(self.seeds),
        }

    def bind(self, core: Core) -> None:
        """Check the pool's observation and build one info template per slot over its
        columns (the step path copies a template, nothing per env)."""
        self._core = weakref.ref(core)
        pool = core.pool
        if tuple(pool.obs_shape) != self.obs_shape or np.dtype(pool.obs_dtype) != self.obs_dtype:
            raise RuntimeError(
                f"pool observation {pool.obs_dtype}{tuple(pool.obs_shape)} differs from the "
                f"engine's {self.obs_dtype}{self.obs_shape}"
            )
        self.info_names = list(pool.info_names)
        self._templates = []
        for cols in core.cols:
            values: dict[str, np.ndarray] = {
                "seed": cols["seed"],
                "episode_index": cols["episode_index"],
                "episode_return": cols["episode_return"],
                "episode_length": cols["episode_length"],
            }
            for k, name in enumerate(self.info_names):
                values[name] = cols["info_bool" if name in _BOOL_INFO else "info_int"][k]
            self._templates.append(values)
        self._info_keys = list(values)
        ones = np.ones(self.num_envs, bool)
        self._masks = {f"_{k}": ones for k in self._info_keys}

    def batch_views(self, rows: np.ndarray) -> np.ndarray:
        """Slot rows as observations of the engine's dtype and shape (a view)."""
        return rows.view(self.obs_dtype).reshape((rows.shape[0], *self.obs_shape))

    def obs_filler(self) -> None:
        """The game's observations are whole as they come."""
        return None

    # -- actions and seeds -----------------------------------------------------------------

    def actions(self, actions: Any, env_ids: Optional[Sequence[int]]) -> np.ndarray:
        """Integer actions, one per env (an array, or a string with one key per env); the
        range is checked by the pool, which names the env and the value."""
        n = self.num_envs if env_ids is None else len(env_ids)
        a = actions
        if type(a) is np.ndarray and a.dtype == np.int64 and a.shape == (n,):
            if env_ids is None:
                self.last_actions = a
            elif self._history is not None:
                self._sent[np.asarray(env_ids, np.int64)] = a
            return a
        if isinstance(a, str):
            if len(a) != n:
                raise ValueError(
                    f"an action string needs one key per env: expected {n} keys, got {len(a)}"
                )
            a = [ACTIONS.index(k) if k in ACTIONS else _native.action_from_key(k) for k in a]
        a = np.asarray(a)
        if a.ndim == 0:
            raise TypeError(scalar_actions(n))
        if a.shape != (n,):
            if a.size == n and a.ndim == 2 and 1 in a.shape:
                a = a.reshape(n)
            else:
                raise ValueError(
                    f"expected actions of shape ({n},) (one per env), got shape {a.shape}"
                )
        if a.dtype.kind not in "iu":
            if a.dtype.kind == "f" and np.all(np.mod(a, 1) == 0):
                a = a.astype(np.int64)
            else:
                raise TypeError(
                    f"expected integer actions in [0, {len(ACTIONS)}), got dtype {a.dtype}"
                )
        if a.dtype.kind == "u" and a.dtype.itemsize >= 8:  # would wrap when cast to int64
            bad = a >= len(ACTIONS)
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise ValueError(
                    f"env {i}: action {a[i]} is out of range; valid actions are 0 to "
                    f"{len(ACTIONS) - 1} (range({len(ACTIONS)}))"
                )
        out = self._actions if env_ids is None else np.empty(n, np.int64)
        np.copyto(out, a, casting="unsafe")
        if env_ids is None:
            self.last_actions = out
        elif self._history is not None:
            self._sent[np.asarray(env_ids, np.int64)] = out
        return out

    def seed_schedule(self, seed: Any, core: Core) -> Optional[dict[str, Any]]:
        """``reset(seed=s)`` restarts every env's episode schedule from base seed ``s``."""
        if seed is None:
            return None
        if not isinstance(seed, (int, np.integer)):
            raise TypeError(
                f"seed must be an int (the base of every env's episode-seed schedule), got "
                f"{type(seed).__name__}; use make_vec(seeds=[...]) to choose the dungeons"
            )
        seed = int(seed)
        if not 0 <= seed < 2**64:
            raise ValueError(f"seed must be in [0, 2**64), got {seed}")
        if core.fresh and seed == self.base_seed:
            return None  # the pool just started from this schedule
        self.base_seed = seed
        self.seeds["base"] = seed
        return dict(self.seeds)

    def seed_partial(self, seed: Any, mask: np.ndarray, core: Core) -> None:
        """Refused: a seed restarts the whole episode-seed schedule."""
        raise ValueError(
            "reset(seed=...) restarts the game's episode-seed schedule and cannot be combined "
            "with a partial reset_mask; reset with the seed first, then use the mask"
        )

    # -- infos -----------------------------------------------------------------------------

    def info_arrays(self, recs: np.ndarray) -> dict[str, np.ndarray]:
        """The info values and episode counters of a record batch as fresh arrays."""
        out: dict[str, np.ndarray] = {
            "seed": recs["seed"].view(np.int64).copy(),
            "episode_index": recs["episode"].astype(np.int64),
            "episode_return": recs["episode_return"].copy(),
            "episode_length": recs["episode_length"].astype(np.int64),
        }
        n = len(self.info_names)
        if n:
            values = recs["info"][:, :n].T
            ints = np.ascontiguousarray(values, dtype=np.int64)
            for k, name in enumerate(self.info_names):
                out[name] = values[k] != 0 if name in _BOOL_INFO else ints[k]
        return out

    def reset_infos(self, core: Core, slot: int, only: Optional[np.ndarray]) -> dict[str, Any]:
        """Every env's info values (or, for a partial reset, the reset envs', others 0)."""
        recs = core.recs[slot]
        restarted = flags(recs)[2]
        reset = np.ones(self.num_envs, bool) if only is None else only | restarted
        infos: dict[str, Any] = {}
        for key, arr in self.info_arrays(recs).items():
            if only is not None:
                arr[~reset] = 0
            infos[key] = arr
            infos[f"_{key}"] = reset
        mark_restarted(infos, restarted)
        if self._history is not None:
            if only is not None:
                self._ended &= ~reset  # the others are still to be autoreset
            else:
                self._ended[:] = False
            self._history.on_reset(recs, reset)
        self._started = True
        return infos

    def step_infos(self, core: Core, slot: int, summary: int, same_step: bool) -> dict[str, Any]:
        """The slot's info template (arrays reused, like the slot), the masks, and in
        SAME_STEP the ended envs' ``final_obs``/``final_info``."""
        cols = core.cols[slot]
        infos = self._templates[slot].copy()
        infos.update(self._masks)
        if core.copy:
            for key in self._info_keys:
                infos[key] = infos[key].copy()
        if summary & SUMMARY_RESTARTED:
            mark_restarted(infos, cols["restarted"])
        history = self._history
        if history is not None:
            recs = core.recs[slot]
            restarted = cols["restarted"]
            history.on_step(self.last_actions, ~self._ended & ~restarted, recs)
            history.on_reset(recs, self._ended | restarted)
            if not same_step:
                self._ended = cols["terminated"] | cols["truncated"]
        if summary & SUMMARY_FINAL and same_step:
            ended = cols["has_final_obs"].copy()
            final_obs = np.full(self.num_envs, None, dtype=object)
            for i in np.flatnonzero(ended):
                final_obs[i] = core.final_obs(int(i))
            infos["final_info"] = infos.copy()
            infos["_final_info"] = ended
            infos["final_obs"] = final_obs
            infos["_final_obs"] = ended
            if history is not None:
                history.on_reset(core.recs[slot], ended, seed_known=False)
        return infos

    def recv_infos(
        self,
        core: Core,
        recs: np.ndarray,
        env_extras: list[tuple[int, bytes]],
        env_id: np.ndarray,
    ) -> dict[str, Any]:
        """The info values of the batch's envs (one row each, all set); the replay history
        follows the rows, so that ``render()`` shows the envs as they are now."""
        if self._history is not None:
            ids = np.asarray(env_id, np.int64)
            same_step = core.same_step
            self._history.on_rows(ids, recs, self._sent, same_step)
            if not same_step:
                self._ended[ids] = (recs["flags"] & 3) != 0
            self._started = True
        infos: dict[str, Any] = {}
        ones = np.ones(len(recs), bool)
        for key, arr in self.info_arrays(recs).items():
            infos[key] = arr
            infos[f"_{key}"] = ones
        return infos

    def info_counts(self) -> tuple[int, int]:
        """None: the game's infos are fixed fields of its records, not rows."""
        return 0, 0

    # -- calls and render ------------------------------------------------------------------

    def _attributes(self) -> dict[str, Any]:
        return {
            "render_mode": self.render_mode,
            "render_modes": list(RENDER_MODES),
            "config": self.config,
            "max_steps": self.max_steps,
            "stair_reward": self.stair_reward,
            "observation_space": self.single_observation_space,
            "action_space": self.single_action_space,
            "spec": None,
            "metadata": self.metadata,
        }

    def _attribute(self, name: str, env: int) -> Any:
        if name == "episode_seed":
            core = self._core()
            assert core is not None  # bound while the pool lives
            return int(core.recs[core.slot]["seed"][env]) if self._started else None
        table = self._attributes()
        if name not in table:
            raise AttributeError(
                f"the native game has no attribute {name!r} readable from Python (its envs run "
                f"in Rust); readable: {', '.join(sorted([*table, 'episode_seed']))}"
            )
        return table[name]

    def call(
        self,
        core: Core,
        op: str,
        name: str,
        arguments: Sequence[tuple[tuple[Any, ...], dict[str, Any]]],
        indices: Sequence[int],
    ) -> list[Any]:
        """The env operations of :data:`rogue_gym.protocol.ops.SERVED_BY` over the game's
        readable attributes and its screens (the game has no attributes to set and no reset
        options)."""
        return [
            run_op(self._ops, WHO, op, name, env, *args, **kwargs)
            for env, (args, kwargs) in zip(indices, arguments)
        ]

    # The env operations (protocol.ops) for env ``env``.
    def _op_call(self, name: str, env: int, *args: Any, **kwargs: Any) -> Any:
        if name == "render":
            return self.frame(env)
        value = self._attribute(name, env)
        return value(*args, **kwargs) if callable(value) else value

    def _op_env_method(self, name: str, env: int, *args: Any, **kwargs: Any) -> Any:
        if name == "get_wrapper_attr":
            return self._attribute(args[0], env)
        if name == "render":
            return self.frame(env)
        raise AttributeError(
            f"the native game has no method {name!r} callable from Python (its envs run in Rust)"
        )

    def _op_get_attr(self, name: str, env: int) -> Any:
        return self._attribute(name, env)

    def _op_has_attr(self, name: str, env: int) -> bool:
        return name == "episode_seed" or name in self._attributes()

    def _op_is_wrapped(self, name: str, env: int, wrapper_class: Any = None) -> bool:
        return False

    def _op_render(self, name: str, env: int) -> Any:
        return self.frame(env)

    def _op_set_reset_options(self, name: str, env: int, options: Any) -> None:
        if options:
            raise ValueError(
                f"the native game takes no reset options, got {sorted(options)}: pass only "
                "reset_mask (game options are set at construction)"
            )

    def frame(self, env: int) -> Any:
        """Env ``env``'s current frame: its screen (text) or, in ``rgb_array`` mode, an image."""
        screen = self.screen(env)
        return screen_to_rgb(screen) if self.render_mode == "rgb_array" else screen

    def screen(self, env: int) -> str:
        """The current screen of env ``env`` (map rows and status line), rebuilt by replay."""
        if self._history is None:
            raise RuntimeError(
                "rendering needs render_mode='ansi', 'human' or 'rgb_array' (actions are only "
                "recorded then)"
            )
        if not self._started:
            raise RuntimeError("call reset() before render()")
        return self._history.screen(env)

    def render(self, core: Core) -> Optional[tuple[Any, ...]]:
        """Every env's frame; ``human`` prints the screens and returns ``None``."""
        if self.render_mode is None:
            gym.logger.warn(
                "render() called without a render_mode; pass render_mode='ansi', 'human' or "
                "'rgb_array'"
            )
            return None
        frames = tuple(self.frame(i) for i in range(self.num_envs))
        if self.render_mode == "human":
            for i, frame in enumerate(frames):
                print(f"--- env {i}\n{frame}", flush=True)
            return None
        return frames
