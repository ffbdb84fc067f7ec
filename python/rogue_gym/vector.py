"""``RogueVectorEnv``: the pool as a ``gymnasium.vector.VectorEnv``, and :func:`make_vec`."""

from __future__ import annotations

import functools
from typing import Any, Callable, Optional, Sequence, Union

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ._config import ConfigLike
from ._core import SUMMARY_FINAL, SUMMARY_RESTARTED, ActionHistory, PoolCore, PoolFacade
from ._records import RECORD_DTYPE
from .async_calls import already_pending, no_async_call, timed_out, warn_close_pending
from .envs.rogue_env import ACTIONS
from .registration import ENV_ID
from .reset_mask import partial_mask, refuse_finished
from .settings import PoolSettings, parse_autoreset_mode

__all__ = ["RogueVectorEnv", "make_vec"]


class RogueVectorEnv(gym.vector.VectorEnv, PoolFacade):
    """``num_envs`` Rogue-Gym games stepped by worker processes over shared memory.

    Semantics follow gymnasium's own vector envs:

    * ``reset(seed=s)`` restarts every env's episode schedule from base seed ``s`` (env ``i``'s
      ``e``-th episode plays ``schedule(s, i, e)``, the same for any ``num_workers``);
      ``options={"reset_mask": mask}`` resets only the masked envs.
    * ``step(actions)`` takes one int action per env (an array of shape ``(num_envs,)``, or a
      string with one key per env) and returns ``(obs, rewards, terminations, truncations,
      infos)``; rewards are float64, flags ``bool``; infos is a dict of arrays with ``_key``
      masks (``seed``, ``episode_index``, ``episode_return``, ``episode_length``, ``floor``,
      ``max_floor``, ``gold``, ``hp``, ``max_hp``, ``died``, ``won``; ``worker_restarted`` where a
      worker was restarted).
    * ``autoreset_mode``: ``NEXT_STEP`` (default; the step after an episode end ignores the
      env's action and returns the reset observation with reward 0) or ``SAME_STEP`` (the ending
      step returns the reset observation; ``infos["final_obs"]`` / ``infos["final_info"]`` hold
      the last one). Deviation: on that step the other info values of the ended envs still
      describe the ended episode (as ``final_info`` does); the new episode's show from the next
      step on.
    * A crashed worker is restarted (``on_worker_failure="restart"``: its envs report
      ``truncated=True`` and ``infos["worker_restarted"]``) or raises
      :class:`rogue_gym.WorkerCrashedError` (``"raise"``).

    Args:
        num_envs, config: the number of games and their config (see
            :class:`rogue_gym.settings.PoolSettings`).
        autoreset_mode: ``NEXT_STEP`` (default), ``SAME_STEP`` or ``DISABLED`` (finished envs
            wait for ``reset(options={"reset_mask": ...})``; stepping them is a ``ValueError``).
        copy: return a fresh observation array each call instead of the shared-memory view.
        render_mode: ``None``, ``"ansi"`` or ``"human"`` (records actions to replay screens).
        **options: any other field of :class:`rogue_gym.settings.PoolSettings` (``num_workers``,
            ``seed``, ``seeds``, ``obs``, ``dtype``, ``max_steps``, ``stair_reward``,
            ``on_worker_failure``, ``step_timeout``, ...), each with its default there.

    **Array lifetimes.** The observation array returned by ``reset``/``step`` is a view of one
    of the pool's two shared-memory batch slots, which the workers write directly (zero-copy)
    and alternately: it stays unchanged until the second following ``reset``/``step`` call (so
    the previous observation is still intact while you hold the new one), and readable even
    after ``close()``. Pass ``copy=True`` to get a fresh array each call. Rewards and flags
    are fresh arrays. The value arrays of ``step()``'s ``infos`` (``seed``, ``episode_index``,
    ..., not the dicts) are preallocated and reused with the same lifetime as the observation
    (unchanged until the second following ``step``): copy the ones you keep longer, or pass
    ``copy=True``, which copies them too. ``reset()``'s infos and ``infos["final_obs"]``
    entries are fresh.
    """

    metadata: dict[str, Any] = {  # noqa: RUF012
        "render_modes": ["ansi", "human"],
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs: int = PoolSettings.num_envs,
        config: ConfigLike = PoolSettings.config,
        *,
        autoreset_mode: Union[str, AutoresetMode] = AutoresetMode.NEXT_STEP,
        copy: bool = False,
        render_mode: Optional[str] = None,
        **options: Any,
    ) -> None:
        mode = parse_autoreset_mode(autoreset_mode)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}"
            )
        settings = PoolSettings.from_kwargs({"num_envs": num_envs, "config": config, **options})
        self._core = PoolCore(settings, same_step=mode == AutoresetMode.SAME_STEP)
        self.metadata = {**type(self).metadata, "autoreset_mode": mode}
        self.autoreset_mode = mode
        self.num_envs = self._core.num_envs
        #: DISABLED: which envs finished their episode and wait for a reset_mask.
        self._done: Optional[np.ndarray] = (
            np.zeros(self.num_envs, bool) if mode == AutoresetMode.DISABLED else None
        )
        self.single_observation_space = self._core.single_observation_space
        self.single_action_space = spaces.Discrete(len(ACTIONS))
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.render_mode = render_mode
        self.copy = bool(copy)
        self._last_recs: Optional[np.ndarray] = None
        self._history = ActionHistory(self._core) if render_mode is not None else None
        #: The split call in flight (``step_async``/``reset_async``) and what its wait needs.
        self._pending: Optional[tuple[str, Any]] = None

    # ------------------------------------------------------------------------------------
    @property
    def config(self) -> dict[str, Any]:
        """The game config of every env."""
        return dict(self._core.config)

    def _out(self, obs: np.ndarray) -> np.ndarray:
        return obs.copy() if self.copy else obs

    def reset(
        self,
        *,
        seed: Optional[Union[int, Sequence[int]]] = None,
        options: Optional[dict[str, Any]] = None,
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset all envs (or those in ``options["reset_mask"]``); returns ``(obs, infos)``.

        ``reset_mask`` (a ``np.bool_`` array of shape ``(num_envs,)``, at least one ``True``;
        anything else raises ``ValueError``) resets only the masked envs, as gymnasium does:
        they start their next scheduled episode, the others keep their state and their
        current observation is returned unchanged (an unmasked env whose episode ended is
        still autoreset by the next step). ``infos`` describe the reset envs only (the ``_key``
        masks are the reset mask; other entries are 0). A partial reset cannot take ``seed``.
        """
        self.reset_async(seed=seed, options=options)
        return self.reset_wait()

    def reset_async(
        self,
        seed: Optional[Union[int, Sequence[int]]] = None,
        options: Optional[dict[str, Any]] = None,
    ) -> None:
        """The first half of :meth:`reset` (gymnasium's ``AsyncVectorEnv.reset_async``): a full
        reset is sent and the workers reset while you do something else; :meth:`reset_wait`
        collects it. A partial reset (``reset_mask``) runs here, whole."""
        self._not_pending("reset_async")
        if seed is not None and not isinstance(seed, (int, np.integer)):
            raise TypeError(
                f"seed must be an int (the base of every env's episode-seed schedule), got {type(seed).__name__}; "
                "use make_vec(seeds=[...]) to choose the dungeons"
            )
        raw_mask = None if not options else options.get("reset_mask")
        mask = partial_mask(raw_mask, self.num_envs, started=self._last_recs is not None)
        if mask is not None and seed is not None:
            raise ValueError(
                "reset(seed=...) restarts every env's seed schedule and cannot be combined with a "
                "partial reset_mask; reset with the seed first, then use the mask"
            )
        super().reset(seed=None if seed is None else int(seed))
        carry = None
        if mask is not None and self._history is not None:
            carry = self._prev_done() & ~mask  # unmasked envs still to be autoreset
        if mask is not None:
            self._pending = ("reset", (mask, carry, self._core.reset(None, mask)))
        else:
            self._core.send_reset(None if seed is None else int(seed))
            self._pending = ("reset", (None, carry, None))

    def reset_wait(self, timeout: Optional[float] = None) -> tuple[np.ndarray, dict[str, Any]]:
        """The second half of :meth:`reset_async`: wait at most ``timeout`` seconds (``None``:
        the pool's own bound) and return ``(obs, infos)``. On a timeout
        (``multiprocessing.TimeoutError``) the reset stays pending: call it again."""
        mask, carry, done = self._take_pending("reset", timeout)
        if done is None:
            done = self._core.wait_reset(timeout)
            if done is None:
                self._pending = ("reset", (mask, carry, None))
                raise timed_out("reset", timeout)
        obs, recs = done
        self._last_recs = recs
        if self._done is not None:  # the reset envs may step again
            self._done = np.zeros_like(self._done) if mask is None else self._done & ~mask
        _, _, restarted, _ = PoolCore.flags(recs)
        if mask is None:
            reset_envs = np.ones(self.num_envs, bool)
            infos = self._infos(recs, restarted)
        else:
            # A worker restarted during the call reset all its envs: report them too.
            reset_envs = mask | restarted
            infos = self._infos(recs, restarted, reset_envs)
        if self._history is not None:
            self._history.on_reset(recs, reset_envs)
            self._carry_done = carry
        return self._out(obs), infos

    def _infos(
        self, recs: np.ndarray, restarted: np.ndarray, only: Optional[np.ndarray] = None
    ) -> dict[str, Any]:
        """Infos of a reset: every env, or (partial reset) the envs of ``only``."""
        infos: dict[str, Any] = {}
        mask = np.ones(self.num_envs, bool) if only is None else only
        for key, arr in self._core.info_arrays(recs).items():
            if only is not None:
                arr[~only] = 0
            infos[key] = arr
            infos[f"_{key}"] = mask
        if restarted.any():
            infos["worker_restarted"] = restarted.copy()
            infos["_worker_restarted"] = restarted.copy()
        return infos

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every env; returns ``(obs, rewards, terminations, truncations, infos)``.

        One native call checks the actions, steps and decodes the records into preallocated
        arrays; rewards, terminations and truncations are fresh copies (as gymnasium's), the
        info value arrays are reused (see the class docs for their lifetime).
        """
        prev_done = self._before_step("step")
        return self._after_step(prev_done, self._core.step_columns(actions))

    def step_async(self, actions: Any) -> None:
        """The first half of :meth:`step` (gymnasium's ``AsyncVectorEnv.step_async``): send
        ``actions`` and return at once; the workers step while you do something else."""
        prev_done = self._before_step("step_async")
        self._core.send_step(actions)
        self._pending = ("step", prev_done)

    def step_wait(
        self, timeout: Optional[float] = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """The second half of :meth:`step_async`: wait at most ``timeout`` seconds (``None``:
        the pool's own bound) and return what :meth:`step` returns. On a timeout
        (``multiprocessing.TimeoutError``) the step stays pending: call it again."""
        prev_done = self._take_pending("step", timeout)
        got = self._core.wait_columns(timeout)
        if got is None:
            self._pending = ("step", prev_done)
            raise timed_out("step", timeout)
        return self._after_step(prev_done, got)

    def _not_pending(self, caller: str) -> None:
        if self._pending is not None:
            raise already_pending(caller, self._pending[0])

    def _take_pending(self, what: str, timeout: Optional[float]) -> Any:
        """The state kept by ``{what}_async``; ``NoAsyncCallError`` if there is none."""
        if self._pending is None or self._pending[0] != what:
            raise no_async_call(what)
        state, self._pending = self._pending[1], None
        return state

    def _before_step(self, caller: str) -> Optional[np.ndarray]:
        """Checks before a step; the envs whose episode had ended (for the render history)."""
        self._not_pending(caller)
        if self._last_recs is None:
            raise RuntimeError("call reset() before step()")
        if self._done is not None:  # DISABLED
            refuse_finished(self._done)
        return self._prev_done() if self._history is not None else None

    def _after_step(
        self,
        prev_done: Optional[np.ndarray],
        stepped: tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], dict[str, Any], int],
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """What a step returns, from the core's columns."""
        history = self._history
        core = self._core
        obs, recs, cols, template, summary = stepped
        self._last_recs = recs
        infos = template.copy()
        infos.update(dict.fromkeys(core.mask_keys, np.ones(self.num_envs, bool)))
        if self.copy:
            for key in core.info_keys:
                infos[key] = infos[key].copy()
        if summary & SUMMARY_RESTARTED:
            restarted = cols["restarted"]
            infos["worker_restarted"] = restarted.copy()
            infos["_worker_restarted"] = restarted.copy()
        if history is not None and prev_done is not None:
            restarted = cols["restarted"]
            history.on_step(core.last_actions, ~prev_done & ~restarted, recs)
            history.on_reset(recs, prev_done | restarted)
        if summary & SUMMARY_FINAL and self.autoreset_mode == AutoresetMode.SAME_STEP:
            has_final = cols["has_final_obs"]
            final = core.final_obs
            assert final is not None
            final_obs = np.full(self.num_envs, None, dtype=object)
            for i in np.flatnonzero(has_final):
                final_obs[i] = final[i].copy()
            infos["final_obs"] = final_obs
            infos["_final_obs"] = has_final.copy()
            infos["final_info"] = {k: v for k, v in infos.items() if not k.startswith("final")}
            infos["_final_info"] = has_final.copy()
            if history is not None:
                history.on_reset(recs, has_final, seed_known=False)
        terminated, truncated = cols["terminated"].copy(), cols["truncated"].copy()
        if self._done is not None:
            self._done = terminated | truncated
        return self._out(obs), cols["reward"].copy(), terminated, truncated, infos

    def _prev_done(self) -> np.ndarray:
        if self._last_recs is None or self.autoreset_mode == AutoresetMode.SAME_STEP:
            return np.zeros(self.num_envs, bool)
        f = self._last_recs["flags"]
        done = (f & 3) != 0
        carry = getattr(self, "_carry_done", None)
        if carry is not None:  # ended before a partial reset that kept them
            done |= carry
            self._carry_done = None
        return done

    # ------------------------------------------------------------------------------------
    # EnvPool-style async API
    def async_reset(self) -> None:
        """Start resetting every env; collect the first observations with :meth:`recv`."""
        self._core.native.async_reset()
        self._async_ids: Optional[np.ndarray] = None
        self._last_recs = None

    def send(self, actions: Any, env_id: Optional[Any] = None) -> None:
        """Send ``actions[r]`` to env ``env_id[r]`` (default: the envs of the last :meth:`recv`).

        ``env_id`` must consist of whole worker blocks (as returned by ``recv``).
        """
        ids = getattr(self, "_async_ids", None) if env_id is None else np.asarray(env_id, np.int64)
        if ids is None:
            raise RuntimeError("send() needs env_id, or a previous recv() whose envs it answers")
        a = np.asarray(actions)
        if a.shape != ids.shape:
            raise ValueError(
                f"expected {ids.shape[0]} actions (one per env id), got shape {a.shape}"
            )
        if a.dtype.kind not in "iu":
            raise TypeError(f"expected integer actions in [0, {len(ACTIONS)}), got dtype {a.dtype}")
        self._core.native.send(np.ascontiguousarray(a, np.int64), [int(i) for i in ids])

    def recv(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Wait for the next ``batch_size`` envs; returns ``(obs, rewards, terminations,
        truncations, infos)`` with ``infos["env_id"]`` naming the envs of the rows.

        **Zero-copy**: when the batch is one worker block (``batch_size`` = envs per worker),
        ``obs`` is a read-only view of the worker's shared-memory sample; its ``base`` owns the
        sample, which stays valid and unchanged for as long as the array (or any view of it)
        lives, even after the env is closed. Keep at most a few (``max_borrowed - 1`` = 3) such
        arrays per worker alive, or ``recv`` fails. Larger batches are gathered into a new array.
        """
        core = self._core
        blocks = core.native.recv()
        obs_parts, recs_parts, ids = [], [], []
        for start, raw, rec_bytes, _extras in blocks:
            recs = np.frombuffer(rec_bytes, RECORD_DTYPE)
            n = recs.shape[0]
            obs_parts.append(raw.view(core.obs_dtype).reshape((n, *core.obs_shape)))
            recs_parts.append(recs)
            ids.append(np.arange(start, start + n))
        obs = obs_parts[0] if len(obs_parts) == 1 else np.concatenate(obs_parts)
        recs = recs_parts[0] if len(recs_parts) == 1 else np.concatenate(recs_parts)
        env_id = np.concatenate(ids)
        self._async_ids = env_id
        terminated, truncated, restarted, _ = PoolCore.flags(recs)
        infos = self._infos_rows(recs, restarted)
        infos["env_id"] = env_id
        return obs, recs["reward"].astype(np.float64), terminated, truncated, infos

    def _infos_rows(self, recs: np.ndarray, restarted: np.ndarray) -> dict[str, Any]:
        infos: dict[str, Any] = dict(self._core.info_arrays(recs))
        if restarted.any():
            infos["worker_restarted"] = restarted.copy()
        return infos

    # ------------------------------------------------------------------------------------
    def render(self) -> Optional[tuple[str, ...]]:
        """Render every env's screen: ``ansi`` returns a tuple of strings, ``human`` prints them.

        Workers do not ship screens: the frames are rebuilt by replaying each env's current
        episode (seed + recorded actions) on an in-process engine, so this is meant for
        occasional inspection, not every step.
        """
        if self.render_mode is None:
            gym.logger.warn(
                "render() called without a render_mode; pass render_mode='ansi' or 'human'"
            )
            return None
        frames = tuple(self.render_env(i) for i in range(self.num_envs))
        if self.render_mode == "human":
            for i, frame in enumerate(frames):
                print(f"--- env {i}\n{frame}", flush=True)
            return None
        return frames

    def render_env(self, i: int) -> str:
        """The current screen of env ``i`` (map rows and status line), rebuilt by replay."""
        if self._history is None:
            raise RuntimeError(
                "render needs render_mode='ansi' or 'human' (actions are only recorded then)"
            )
        if self._last_recs is None:
            raise RuntimeError("call reset() before render()")
        return self._history.screen(i)

    # ------------------------------------------------------------------------------------
    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Call ``name`` on every env; supports ``render`` and attribute reads (workers host Rust games)."""
        if name == "render":
            return tuple(self.render_env(i) for i in range(self.num_envs))
        value = self.get_attr(name)
        if callable(value[0]):
            return tuple(v(*args, **kwargs) for v in value)
        return value

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """Read an attribute of every env (``render_mode``, ``config``, ``max_steps``,
        ``stair_reward``, ``observation_space``, ``action_space``, ``episode_seed``, ``spec``)."""
        n = self.num_envs
        core = self._core
        if name == "episode_seed":
            if self._last_recs is None:
                return (None,) * n
            return tuple(int(s) for s in self._last_recs["seed"])
        simple = {
            "render_mode": self.render_mode,
            "config": core.config,
            "max_steps": core.max_steps,
            "stair_reward": core.stair_reward,
            "observation_space": self.single_observation_space,
            "action_space": self.single_action_space,
            "spec": None,
            "metadata": self.metadata,
        }
        if name not in simple:
            raise AttributeError(
                f"the envs have no attribute {name!r} readable from Python (they run in workers)"
            )
        return (simple[name],) * n

    def set_attr(self, name: str, values: Any) -> None:
        """Setting attributes of envs running in workers is not supported."""
        raise AttributeError(
            f"cannot set {name!r}: the envs run in worker processes (configure them at construction)"
        )

    # ------------------------------------------------------------------------------------
    def close_extras(self, **kwargs: Any) -> None:
        """Stop all workers and remove the pool's shared-memory files. A pending
        ``step_async`` or ``reset_async`` is abandoned with a warning."""
        pending = getattr(self, "_pending", None)
        if pending is not None and not self._core.closed:
            warn_close_pending(pending[0])
        self._pending = None
        self._core.close()

    def __del__(self) -> None:
        core = getattr(self, "_core", None)
        if core is not None:
            core.close()

    def __repr__(self) -> str:
        return f"RogueVectorEnv(num_envs={self.num_envs}, num_workers={self.num_workers})"


def make_vec(
    env: Union[int, str, Callable[[], gym.Env]] = PoolSettings.num_envs,
    num_envs: Optional[int] = None,
    config: ConfigLike = PoolSettings.config,
    **kwargs: Any,
) -> VectorEnv:
    """A vector env in the pool's worker processes.

    * ``make_vec(64, config="paper", **pool_options)`` (or ``make_vec("RogueGym-v0", 64,
      ...)``): the native game, :class:`RogueVectorEnv`.
    * ``make_vec("CartPole-v1", 64, env_kwargs={...}, **options)``: any registered gymnasium
      id, hosted as Python envs (:class:`rogue_gym.hosted.PoolVectorEnv`; ``options`` are its
      keywords).
    * ``make_vec(env_fn, 64, **options)``: ``env_fn()`` builds each env.

    Example::

        envs = rogue_gym.make_vec(64, config="paper", num_workers=2, seed=0)
        obs, infos = envs.reset()
        obs, rewards, terminated, truncated, infos = envs.step(envs.action_space.sample())
        envs.close()
    """
    if isinstance(env, (int, np.integer)):
        if num_envs is not None:
            raise TypeError("make_vec(num_envs, ...) got num_envs twice")
        return RogueVectorEnv(int(env), config, **kwargs)
    if num_envs is None:
        raise TypeError(f"make_vec({env!r}, num_envs, ...) needs num_envs")
    if env == ENV_ID:
        return RogueVectorEnv(num_envs, config, **kwargs)
    if config is not PoolSettings.config:
        raise TypeError(
            "config= is an option of the native game only (make_vec(num_envs, config=...))"
        )
    from .hosted import PoolVectorEnv

    env_kwargs = dict(kwargs.pop("env_kwargs", None) or {})
    if isinstance(env, str):
        env_fn: Callable[[], gym.Env] = functools.partial(gym.make, env, **env_kwargs)
    elif callable(env):
        if env_kwargs:
            raise TypeError("env_kwargs is for gymnasium ids; bind arguments into the callable")
        env_fn = env
    else:
        raise TypeError(f"make_vec needs a num_envs, a gymnasium id or a callable, got {env!r}")
    return PoolVectorEnv([env_fn] * int(num_envs), **kwargs)
