"""The native game as an env kind: Rogue-Gym's own dungeons, run by the workers in Rust.

Its spaces come from the engine, its seeds from the pool's episode schedule (env ``i``'s
``e``-th episode plays the same dungeon whatever the worker count), its infos from the
columns every call is decoded into (no per-env Python), and its frames are rebuilt by
replaying each env's episode, as the front logs it (:mod:`rogue_gym.kinds.episode_log`), on an
in-process engine.
"""

from __future__ import annotations

from typing import Any, Optional, Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .. import _native
from .._config import resolve_config, to_json
from ..envs.image import ObsSpec, observation_space
from ..envs.palette import screen_to_rgb
from ..envs.rogue_env import ACTIONS
from ..errors import out_of_range, scalar_actions
from ..protocol.ops import Interpreter, op_table, run_op
from ..settings import PoolSettings
from .final_obs import add_final_obs
from .result import SUMMARY_FINAL, Result
from .seed_sets import seed_set
from .spec import EnvIds, KindFacts
from .view import PoolView

__all__ = ["RENDER_MODES", "WHO", "NativeKind"]

#: This kind in :data:`rogue_gym.protocol.ops.SERVED_BY`.
WHO = Interpreter.NATIVE

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
        if st.env_threads():
            raise ValueError(
                'env_concurrency: the native game computes (it never waits): it runs "serial"; '
                "add workers instead"
            )
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
        self.base_seed = int(st.seed or 0)
        self._schedule: dict[str, Any] = {
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
        self._view: Optional[PoolView] = None
        self._copy = self._same_step = False
        self._ops = op_table(self, WHO)
        self.facts = KindFacts(
            num_envs=self.num_envs,
            single_observation_space=self.single_observation_space,
            single_action_space=self.single_action_space,
            metadata={"render_modes": list(RENDER_MODES)},
            render_mode=render_mode,
            env_spec=None,
            worker_command=list(st.worker_command or []),
            who=WHO,
            ops=frozenset(self._ops),
            # Frames are rebuilt by replay: the front logs episodes of up to max_steps.
            log_steps=self.max_steps + 2 if render_mode is not None else None,
        )

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
            "seeds": dict(self._schedule),
        }

    def bind(self, view: PoolView) -> None:
        """Check the pool's observation and build one info template per slot over its
        columns (the step path copies a template, nothing per env)."""
        self._view = view
        # Read on every step: kept as plain attributes.
        self._copy, self._same_step = view.copy, view.same_step
        layout = view.layout
        if layout.obs_shape != self.obs_shape or np.dtype(layout.obs_dtype) != self.obs_dtype:
            raise RuntimeError(
                f"pool observation {layout.obs_dtype}{layout.obs_shape} differs from the "
                f"engine's {self.obs_dtype}{self.obs_shape}"
            )
        self.info_names = list(layout.info_names)
        self._templates = [self._info_values(view.columns(s)) for s in range(layout.slots)]
        self._info_keys = list(self._templates[0])
        ones = np.ones(self.num_envs, bool)
        self._masks = {f"_{k}": ones for k in self._info_keys}

    def _info_values(self, cols: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The infos as views of a result's columns: the episode counters, then one row of
        the info columns per info value."""
        values: dict[str, np.ndarray] = {
            "seed": cols["seed"],
            "episode_index": cols["episode_index"],
            "episode_return": cols["episode_return"],
            "episode_length": cols["episode_length"],
        }
        for k, name in enumerate(self.info_names):
            values[name] = cols["info_bool" if name in _BOOL_INFO else "info_int"][k]
        return values

    def batch_views(self, rows: np.ndarray) -> np.ndarray:
        """Slot rows as observations of the engine's dtype and shape (a view)."""
        return rows.view(self.obs_dtype).reshape((rows.shape[0], *self.obs_shape))

    # -- actions and seeds -----------------------------------------------------------------

    def actions(self, actions: Any, env_ids: Optional[EnvIds]) -> np.ndarray:
        """Integer actions, one per env (an array, or a string with one key per env); the
        range is checked by the pool, which names the env and the value."""
        n = self.num_envs if env_ids is None else len(env_ids)
        a = actions
        if type(a) is np.ndarray and a.dtype == np.int64 and a.shape == (n,):
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
                env = i if env_ids is None else env_ids[i]
                raise ValueError(out_of_range(env, a[i], 0, len(ACTIONS) - 1))
        out = self._actions if env_ids is None else np.empty(n, np.int64)
        np.copyto(out, a, casting="unsafe")
        return out

    def seeds(self, seed: Any, mask: Optional[np.ndarray]) -> Optional[dict[str, Any]]:
        """``reset(seed=s)`` restarts every env's episode schedule from base seed ``s``; with
        a partial reset's mask it is refused (a seed restarts the whole schedule)."""
        if seed is None:
            return None
        if mask is not None:
            raise ValueError(
                "reset(seed=...) restarts the game's episode-seed schedule and cannot be "
                "combined with a partial reset_mask; reset with the seed first, then use the mask"
            )
        if not isinstance(seed, (int, np.integer)):
            raise TypeError(
                f"seed must be an int (the base of every env's episode-seed schedule), got "
                f"{type(seed).__name__}; use make_vec(seeds=[...]) to choose the dungeons"
            )
        seed = int(seed)
        if not 0 <= seed < 2**64:
            raise ValueError(f"seed must be in [0, 2**64), got {seed}")
        if not self._bound().state.started and seed == self.base_seed:
            return None  # the pool just started from this schedule
        self.base_seed = seed
        self._schedule["base"] = seed
        return dict(self._schedule)

    # -- infos -----------------------------------------------------------------------------

    def infos(self, result: Result, only: Optional[np.ndarray]) -> dict[str, Any]:
        """A whole-batch call: the slot's info template (arrays reused, like the slot, unless
        the env hands out copies), and SAME_STEP's final observations. A partial reset
        (``only``) or a ``recv``: fresh arrays, the rows not reset zero and unmasked."""
        if only is None and result.slot is not None:
            template = self._templates[result.slot]
            infos = template.copy()
            infos.update(self._masks)
            if self._copy:
                for key in self._info_keys:
                    infos[key] = infos[key].copy()
            if self._same_step and result.summary & SUMMARY_FINAL:
                # The step's row of an ended episode describes it: its info is the last step's.
                keys = self._info_keys
                add_final_obs(
                    infos,
                    self._bound(),
                    result,
                    self.batch_views,
                    lambda env, obs: (obs, {key: template[key][env] for key in keys}),
                )
            return infos
        # A recv's rows: in the recv buffer, or (written in place) in a slot.
        slot = result.slot
        template = self._info_values(result.cols) if slot is None else self._templates[slot]
        rows = result.rows
        shown = np.ones(rows, bool)
        if only is not None:
            restarted = result.restarted
            shown = only if restarted is None else only | restarted
        infos = {}
        for key in self._info_keys:
            arr = template[key][:rows].copy()
            if only is not None:
                arr[~shown] = 0
            infos[key] = arr
            infos[f"_{key}"] = shown
        return infos

    def _bound(self) -> PoolView:
        """The view of the running pool."""
        if self._view is None:
            raise RuntimeError("the native kind is not bound to a running pool yet")
        return self._view

    # -- calls and render ------------------------------------------------------------------

    def _attributes(self) -> dict[str, Any]:
        return {
            "render_mode": self.facts.render_mode,
            "render_modes": list(RENDER_MODES),
            "config": self.config,
            "max_steps": self.max_steps,
            "stair_reward": self.stair_reward,
            "observation_space": self.single_observation_space,
            "action_space": self.single_action_space,
            "spec": None,
            "metadata": self.facts.metadata,
        }

    def _attribute(self, name: str, env: int) -> Any:
        if name == "episode_seed":
            view = self._bound()
            slot = view.state.slot
            if slot is None:
                return None
            return int(view.columns(slot)["seed"].view(np.uint64)[env])
        table = self._attributes()
        if name not in table:
            raise AttributeError(
                f"the native game has no attribute {name!r} readable from Python (its envs run "
                f"in Rust); readable: {', '.join(sorted([*table, 'episode_seed']))}"
            )
        return table[name]

    def run_ops(
        self,
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
        return screen_to_rgb(screen) if self.facts.render_mode == "rgb_array" else screen

    def screen(self, env: int) -> str:
        """The current screen of env ``env`` (map rows and status line), rebuilt by replaying
        its episode as the front logged it."""
        state = self._bound().state
        if state.log is None:
            raise RuntimeError(
                "rendering needs render_mode='ansi', 'human' or 'rgb_array' (actions are only "
                "recorded then)"
            )
        if not state.started:
            raise RuntimeError("call reset() before render()")
        seed, actions = state.log.episode(env)
        game = _native.Game(to_json(self.config), self.max_steps, self.stair_reward)
        game.reset(seed)
        for a in actions:
            game.step(int(a))
        return "\n".join([*game.screen(), game.status_line()])

    def render(self) -> Optional[tuple[Any, ...]]:
        """Every env's frame; ``human`` prints the screens and returns ``None``."""
        if self.facts.render_mode is None:
            gym.logger.warn(
                "render() called without a render_mode; pass render_mode='ansi', 'human' or "
                "'rgb_array'"
            )
            return None
        frames = tuple(self.frame(i) for i in range(self.num_envs))
        if self.facts.render_mode == "human":
            for i, frame in enumerate(frames):
                print(f"--- env {i}\n{frame}", flush=True)
            return None
        return frames
