"""EnvPool's Python API over any gymnasium env, in the pool's worker processes.

Scripts written for EnvPool (CleanRL's ``ppo_atari_envpool.py``, its async Sebulba/Cleanba
variants) run with one change::

    import rogue_gym.envpool as envpool

    envs = envpool.make("CartPole-v1", env_type="gymnasium", num_envs=8, seed=1)
    obs, info = envs.reset()
    obs, reward, terminated, truncated, info = envs.step(actions)     # info["env_id"], ...

    envs = envpool.make("Pong-v5", env_type="gymnasium", num_envs=16, batch_size=8)
    envs.async_reset()
    obs, reward, terminated, truncated, info = envs.recv()            # 8 envs ready
    envs.send(actions, info["env_id"])

* ``make(task_id, ...)`` takes EnvPool's arguments. ``task_id`` is any id ``gymnasium.make``
  knows (the caller's registrations included). EnvPool's Atari ids (``"Pong-v5"``,
  ``"Breakout-v5"``) run ale-py's C++ vector env in each worker, with EnvPool's preprocessing
  arguments (``stack_num``, ``frame_skip``, ``gray_scale``, ``episodic_life``,
  ``reward_clip``, ...), when ale-py is installed.
* The object has EnvPool's surface: single-env ``observation_space``/``action_space``,
  ``reset(env_id=None)``, ``step(action, env_id=None)``, ``async_reset``, ``send``, ``recv``,
  ``spec.config``, ``config``, ``all_env_ids``, ``is_async``, and the infos ``env_id``,
  ``players`` (``{"env_id": ...}``) and ``elapsed_step``, int32 as EnvPool's; rewards are
  float32, flags bool.
* ``env_type="gym"`` is the API EnvPool's gym envs had before gym 0.26, which CleanRL's EnvPool
  scripts are written against: ``reset()`` returns the observations, ``step()``
  ``(obs, reward, done, info)`` with ``done = terminated | truncated``. ``env_type="dm"`` is
  not offered.

``docs/hosting.md`` lists every difference from EnvPool. Autoreset is EnvPool's: the step after
an episode ends returns the next episode's first observation (``elapsed_step`` 0, reward 0).
"""

from __future__ import annotations

import contextlib
import functools
import math
from collections import namedtuple
from dataclasses import dataclass, field
from typing import Any, Optional

import gymnasium as gym
import numpy as np

from . import _native
from . import xla as _xla
from .front.vector_env import FrontVectorEnv
from .kinds.native import NativeKind
from .registration import ENV_ID
from .settings import PoolSettings
from .vector import PoolVectorEnv, RogueVectorEnv

__all__ = [
    "EnvPoolEnv",
    "EnvSpec",
    "list_all_envs",
    "make",
    "make_gym",
    "make_gymnasium",
    "make_spec",
]

#: EnvPool's Atari options and their defaults (EnvPool's own).
ATARI_DEFAULTS: dict[str, Any] = {
    "max_episode_steps": 27000,
    "stack_num": 4,
    "frame_skip": 4,
    "noop_max": 30,
    "episodic_life": False,
    "reward_clip": False,
    "use_fire_reset": True,
    "img_height": 84,
    "img_width": 84,
    "full_action_space": False,
    "repeat_action_probability": 0.0,
    "gray_scale": True,
}
#: EnvPool options that only tune its C++ thread pool: accepted, and without effect here.
THREAD_OPTIONS = ("thread_affinity_offset",)
#: Info keys of the pool's own that an EnvPool script does not expect.
_POOL_INFO_KEYS = ("worker_restarted",)
#: The native game's info values that are flags.
_BOOL_INFOS = frozenset(_native.BOOL_INFO_NAMES)


@dataclass(frozen=True)
class EnvSpec:
    """What ``make_spec`` returns and ``envs.spec`` is: the task's ``config`` (a namedtuple,
    as EnvPool's ``spec.config``) and its single-env spaces."""

    config: Any
    observation_space: gym.Space
    action_space: gym.Space
    #: The gymnasium id (EnvPool's task id maps to it for Atari).
    gym_id: str = ""
    reward_threshold: Optional[float] = None
    kwargs: dict[str, Any] = field(default_factory=dict)

    @property
    def gymnasium_observation_space(self) -> gym.Space:
        """The single-env observation space (EnvPool's name)."""
        return self.observation_space

    @property
    def gymnasium_action_space(self) -> gym.Space:
        """The single-env action space (EnvPool's name)."""
        return self.action_space


def list_all_envs() -> list[str]:
    """Every id this process can make: gymnasium's registry (the Atari ids with ale-py)."""
    return list(gym.registry.keys())


def _atari_game(task_id: str) -> Optional[str]:
    """The ale-py ROM name of an EnvPool Atari id (``"Pong-v5"`` -> ``"pong"``), or ``None``
    when ``task_id`` is not one or ale-py is not installed."""
    if not task_id.endswith("-v5") or "/" in task_id:
        return None
    try:
        import ale_py  # noqa: F401  # registers the ALE/ ids
    except ImportError:
        return None
    name = task_id[: -len("-v5")]
    if f"ALE/{name}-v5" not in gym.registry:
        return None
    return "".join("_" + c.lower() if c.isupper() and i else c.lower() for i, c in enumerate(name))


def _atari_vector_env(n: int, game: str, options: dict[str, Any]) -> gym.vector.VectorEnv:
    """ale-py's C++ vector env of ``n`` envs with EnvPool's preprocessing options (rewards
    unclipped: the facade clips them and keeps the raw ones in ``info["reward"]``)."""
    from ale_py.vector_env import AtariVectorEnv

    return AtariVectorEnv(
        game,
        num_envs=n,
        num_threads=1,
        max_num_frames_per_episode=options["max_episode_steps"] * options["frame_skip"],
        repeat_action_probability=options["repeat_action_probability"],
        full_action_space=options["full_action_space"],
        img_height=options["img_height"],
        img_width=options["img_width"],
        grayscale=options["gray_scale"],
        stack_num=options["stack_num"],
        frameskip=options["frame_skip"],
        noop_max=options["noop_max"],
        episodic_life=options["episodic_life"],
        reward_clipping=False,
        use_fire_reset=options["use_fire_reset"],
    )


def _layout(num_envs: int, batch_size: int, num_threads: int, whole_blocks: bool) -> int:
    """Workers for ``num_envs`` envs served in batches of ``batch_size``: ``num_threads`` (at
    most one per env). A vector env per worker (``whole_blocks``, Atari) is sent whole, so there
    the blocks are of equal size and divide the batch, as many workers as ``num_threads`` asks
    where the sizes allow, else the closest number above it."""
    if not whole_blocks:
        return max(1, min(num_threads, num_envs))
    common = math.gcd(num_envs, batch_size)
    fits = [b for b in range(common, 0, -1) if common % b == 0 and num_envs // b >= num_threads]
    return num_envs // (fits[0] if fits else 1)


def make_spec(task_id: str, **kwargs: Any) -> EnvSpec:
    """The spec of ``make(task_id, **kwargs)`` (its ``config`` and spaces), built without a
    pool: one env is made here for its spaces."""
    return _resolve(task_id, kwargs)[0]


def _resolve(task_id: str, kwargs: dict[str, Any]) -> tuple[EnvSpec, Any, int, int]:
    """The spec, the pool's env source (env_fns or a vector-env fn), workers and batch size."""
    opts = dict(kwargs)
    opts.pop("env_type", None)
    num_envs = int(opts.pop("num_envs", 1))
    batch_size = int(opts.pop("batch_size", 0) or num_envs)
    num_threads = int(opts.pop("num_threads", 0) or min(num_envs, _native.usable_cores()))
    seed = int(opts.pop("seed", 42))
    for name in THREAD_OPTIONS:
        opts.pop(name, None)
    if num_envs < 1 or not 1 <= batch_size <= num_envs:
        raise ValueError(
            f"num_envs ({num_envs}) must be at least 1 and batch_size ({batch_size}) between 1 "
            "and num_envs"
        )
    game = _atari_game(task_id)
    config: dict[str, Any] = {
        "num_envs": num_envs,
        "batch_size": batch_size,
        "num_threads": num_threads,
        "max_num_players": 1,
        "seed": seed,
        "gym_reset_return_info": True,
    }
    if game is not None:
        unknown = sorted(set(opts) - set(ATARI_DEFAULTS))
        if unknown:
            raise TypeError(
                f"make({task_id!r}): unknown Atari option(s) {unknown}; the options are "
                f"{sorted(ATARI_DEFAULTS)}"
            )
        atari = {**ATARI_DEFAULTS, **opts}
        config.update(atari, task=game)
        probe = _atari_vector_env(1, game, atari)
        obs_space, act_space = probe.single_observation_space, probe.single_action_space
        probe.close()
        source: Any = functools.partial(_atari_vector_env, game=game, options=atari)
        gym_id, threshold = f"ALE/{task_id}", None
    else:
        max_steps = opts.pop("max_episode_steps", None)
        make_kwargs = dict(opts)
        if max_steps is not None:
            make_kwargs["max_episode_steps"] = int(max_steps)
        gspec = gym.spec(task_id)
        if task_id == ENV_ID:  # the game's own spaces, as its native pool makes them
            settings = PoolSettings.from_kwargs({"num_envs": num_envs, **make_kwargs})
            facts = NativeKind(settings, None).facts
            obs_space, act_space = facts.single_observation_space, facts.single_action_space
        else:
            probe_env = gym.make(task_id, **make_kwargs)
            obs_space, act_space = probe_env.observation_space, probe_env.action_space
            probe_env.close()
        config["max_episode_steps"] = (
            max_steps if max_steps is not None else gspec.max_episode_steps
        )
        config["reward_threshold"] = gspec.reward_threshold
        config.update(opts)
        if task_id == ENV_ID:  # the game itself: the pool's native kind, no Python env
            source = functools.partial(RogueVectorEnv, num_envs, **make_kwargs)
        else:
            source = [functools.partial(gym.make, task_id, **make_kwargs)] * num_envs
        gym_id, threshold = task_id, gspec.reward_threshold
    Config = namedtuple("Config", list(config))  # type: ignore[misc]  # EnvPool's spec.config
    spec = EnvSpec(Config(**config), obs_space, act_space, gym_id, threshold, dict(kwargs))
    whole_blocks = game is not None
    workers = _layout(num_envs, batch_size, num_threads, whole_blocks=whole_blocks)
    return spec, source, workers, batch_size


class EnvPoolEnv(gym.Env):
    """EnvPool's env object over a :class:`rogue_gym.PoolVectorEnv` (see the module doc).

    A ``gymnasium.Env`` (so ``gymnasium.Wrapper`` subclasses such as CleanRL's
    ``RecordEpisodeStatistics`` wrap it) whose spaces are one env's, as EnvPool's are. Its
    attributes (``num_envs``, ``single_observation_space``, ...) may be set, as CleanRL does.
    Arrays returned are the caller's (copies); ``close()`` stops the workers.
    """

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012  # gymnasium.Env's

    def __init__(self, task_id: str, env_type: str = "gymnasium", **kwargs: Any) -> None:
        if env_type not in ("gymnasium", "gym"):
            raise ValueError(
                f"env_type must be 'gymnasium' (five-tuple steps) or 'gym' (four-tuple steps, "
                f"as CleanRL's EnvPool scripts use), got {env_type!r}: the dm_env API is not "
                "offered"
            )
        spec, source, workers, batch_size = _resolve(task_id, kwargs)
        self.spec = spec  # type: ignore[assignment]
        self.env_type = env_type
        self.num_envs = spec.config.num_envs
        self.observation_space = self.single_observation_space = spec.observation_space
        self.action_space = self.single_action_space = spec.action_space
        self._atari = "task" in spec.config._fields
        self._clip = bool(self._atari and spec.config.reward_clip)
        self._pool: FrontVectorEnv
        if self._atari:
            self._pool = PoolVectorEnv.from_vector_env(
                source, self.num_envs, num_workers=workers, batch_size=batch_size
            )
        elif isinstance(source, functools.partial):  # the native game
            self._pool = source(num_workers=workers, batch_size=batch_size, copy=True)
        else:
            self._pool = PoolVectorEnv(source, num_workers=workers, batch_size=batch_size)
        #: The pool's call lifecycle (started, ended episodes, the last recv's envs).
        self._state = self._pool.call_state
        self._seeded = False
        self._actions: Optional[np.ndarray] = None
        self._xla_used = False

    # -- EnvPool's properties --------------------------------------------------------------

    @property
    def config(self) -> dict[str, Any]:
        """The config as a dict (EnvPool's ``envs.config``)."""
        return dict(self.spec.config._asdict())  # type: ignore[union-attr]

    @property
    def all_env_ids(self) -> np.ndarray:
        """Every env id, int32."""
        return np.arange(self.num_envs, dtype=np.int32)

    @property
    def is_async(self) -> bool:
        """Whether batches are smaller than ``num_envs`` (EnvPool's async mode)."""
        return bool(self.spec.config.batch_size != self.num_envs)  # type: ignore[union-attr]

    def __len__(self) -> int:
        return int(self.num_envs)

    @property
    def pool(self) -> FrontVectorEnv:
        """The pool underneath (``stats()``, ``worker_pids``, ...): a
        :class:`rogue_gym.PoolVectorEnv`, or for ``RogueGym-v0`` the game's native
        :class:`rogue_gym.RogueVectorEnv`."""
        return self._pool

    # -- the calls -------------------------------------------------------------------------

    def _seed(self) -> Optional[int]:
        """EnvPool seeds once, at its first reset: env ``i`` with ``seed + i``."""
        if self._seeded:
            return None
        self._seeded = True
        return int(self.spec.config.seed)  # type: ignore[union-attr]

    def reset(
        self,
        env_id: Optional[Any] = None,
        *,
        seed: Optional[int] = None,
        options: Optional[dict[str, Any]] = None,
    ) -> Any:
        """Reset the envs ``env_id`` (default: all) and return their ``(obs, info)`` (``gym``
        type: ``obs``). Seeds come from ``make(seed=...)``; a ``seed`` here is ignored, as
        EnvPool ignores it. In async mode this starts every env and returns the first batch,
        as EnvPool does."""
        obs, info = self._reset(env_id, options)
        return obs if self.env_type == "gym" else (obs, info)

    def _reset(self, env_id: Optional[Any], options: Optional[dict[str, Any]]) -> tuple[Any, Any]:
        mask = None if options is None else options.get("reset_mask")
        if env_id is None and mask is not None:
            env_id = np.flatnonzero(np.asarray(mask, bool))
        if self.is_async:
            self.async_reset()
            first = self._recv()
            return first[0], first[4]
        ids = self.all_env_ids if env_id is None else np.atleast_1d(np.asarray(env_id, np.int32))
        if env_id is None or not self._state.started:
            obs, infos = self._pool.reset(seed=self._seed())
        else:
            full = np.zeros(self.num_envs, bool)
            full[ids] = True
            obs, infos = self._pool.reset(options={"reset_mask": full})
        rows = self.all_env_ids
        info = self._info(infos, rows, np.zeros(self.num_envs, np.float64))
        if env_id is None:
            return obs, info
        return obs[ids], {k: _take(v, ids) for k, v in info.items()}

    def step(self, action: Any, env_id: Optional[Any] = None) -> tuple[Any, ...]:
        """Step the envs ``env_id`` (default: all, or in async mode those of the last
        ``recv``) with ``action`` and return the next batch, as :meth:`recv` does."""
        self.send(action, env_id)
        return self.recv()

    def async_reset(self) -> None:
        """Start resetting every env; collect the first batches with :meth:`recv`."""
        self._pool.async_reset(seed=self._seed())

    def send(self, action: Any, env_id: Optional[Any] = None) -> None:
        """Send ``action`` (one row per env of ``env_id``) to the envs ``env_id``."""
        actions = np.asarray(action)
        if not self.is_async:
            if env_id is not None and len(np.atleast_1d(env_id)) != self.num_envs:
                raise ValueError(
                    f"this pool steps all its {self.num_envs} envs at once (batch_size = "
                    "num_envs): send one action per env, or make it with a smaller batch_size "
                    "to step some envs at a time"
                )
            if not self._state.started:
                raise RuntimeError("call reset() (or async_reset()) before step()")
            order = None if env_id is None else np.argsort(np.asarray(env_id))
            self._actions = actions if order is None else actions[order]
            return
        ids = (
            self._state.last_ids if env_id is None else np.atleast_1d(np.asarray(env_id, np.int64))
        )
        if ids is None:
            raise RuntimeError("send() needs env_id, or a recv() before it whose envs it answers")
        self._pool.send(actions, ids)

    def recv(self, reset: bool = False, return_info: bool = True) -> tuple[Any, ...]:
        """The next batch: ``(obs, reward, terminated, truncated, info)`` (``gym`` type:
        ``(obs, reward, done, info)``; ``reset=True``: ``(obs, info)``), with
        ``info["env_id"]`` naming the rows."""
        obs, reward, terminated, truncated, info = self._recv()
        if reset:
            return (obs, info) if return_info else (obs,)
        if self.env_type == "gym":
            info["TimeLimit.truncated"] = truncated  # the old gym API's
            return obs, reward, terminated | truncated, info
        return obs, reward, terminated, truncated, info

    def _recv(self) -> tuple[Any, ...]:
        if not self.is_async:
            if self._actions is None:
                raise RuntimeError("recv() in sync mode follows a send()")
            actions, self._actions = self._actions, None
            obs, rewards, terminated, truncated, infos = self._pool.step(actions)
            ids = self.all_env_ids
        else:
            obs, rewards, terminated, truncated, infos = self._pool.recv()
            ids = np.asarray(infos["env_id"], np.int32)
        info = self._info(infos, ids, rewards)
        reward = np.asarray(rewards, np.float32)
        if self._clip:
            reward = np.sign(reward).astype(np.float32)
        return obs, reward, np.asarray(terminated, bool), np.asarray(truncated, bool), info

    def _info(self, infos: dict[str, Any], ids: np.ndarray, rewards: Any) -> dict[str, Any]:
        """EnvPool's info: the env's own numeric infos, then ``env_id``, ``players``,
        ``elapsed_step`` (and for Atari the raw ``reward`` and ``terminated``)."""
        info: dict[str, Any] = {}
        for key, value in infos.items():
            if key.startswith("_") or key in _POOL_INFO_KEYS or key == "env_id":
                continue
            info[key] = value
        if self._atari:
            lives = np.asarray(info.get("lives", np.zeros(len(ids))), np.int32)
            info["lives"] = lives
            info["reward"] = np.asarray(rewards, np.float32)
            info["terminated"] = self._state.ended[ids].astype(np.int32) & (lives == 0)
        env_id = np.asarray(ids, np.int32)
        info["env_id"] = env_id
        info["players"] = {"env_id": env_id.copy()}
        info["elapsed_step"] = self._elapsed_steps(len(ids))
        return info

    def _elapsed_steps(self, rows: int) -> np.ndarray:
        """``elapsed_step`` of the last call's rows: the steps of each env's episode so far,
        as the workers count them (0 at a reset and at an autoreset step), int32. The same
        count the ``xla()`` functions return, so that Python and jitted calls may be mixed."""
        last = self._pool._core.last
        assert last is not None  # after a call
        return np.asarray(last.cols["episode_length"][:rows], np.int32)

    def xla(self) -> _xla.XlaFunctions:
        """EnvPool's ``handle, recv, send, step = envs.xla()``: functions usable inside
        ``jax.jit``, ``lax.scan`` and ``lax.fori_loop`` that step this pool through native XLA
        FFI handlers (see :mod:`rogue_gym.xla`); ``recv`` returns what :meth:`recv` does, as
        jax arrays. Needs jax (``pip install 'rogue_gym[jax]'``)."""
        core = self._pool._core
        core.check_open()
        # A jitted step may write any batch slot: hand out copies, never lent slots.
        if core.lender is not None:
            core.lender = None
            core.pool.async_views(True)
        self._xla_used = True
        space = self.spec.observation_space  # type: ignore[union-attr]
        if not isinstance(space, gym.spaces.Box):
            raise TypeError(f"xla() takes envs whose observation space is a Box, not {space}")
        if int(np.prod(space.shape)) * space.dtype.itemsize > core.obs_bytes:
            raise TypeError(f"xla(): the observations of {space} do not match the pool's rows")
        act = self.spec.action_space  # type: ignore[union-attr]
        return _xla.build(core.pool, tuple(space.shape), space.dtype, act, self._xla_outputs)

    def _xla_outputs(self, raw: _xla.Raw) -> tuple[Any, ...]:
        """``recv``'s outputs in this facade's form, from the handler's arrays (traced once)."""
        import jax.numpy as jnp

        info: dict[str, Any] = {}
        if raw.info is not None:
            for j, name in enumerate(self._pool._core.layout.info_names):
                value = raw.info[:, j]
                info[name] = value.astype(bool) if name in _BOOL_INFOS else value.astype(jnp.int32)
        reward = raw.reward
        if self._atari:
            info["reward"] = raw.reward
            info["terminated"] = raw.terminated.astype(jnp.int32)
            if self._clip:
                reward = jnp.sign(raw.reward)
        info["env_id"] = raw.env_id
        info["players"] = {"env_id": raw.env_id}
        info["elapsed_step"] = raw.elapsed_step
        if self.env_type == "gym":
            info["TimeLimit.truncated"] = raw.truncated
            return raw.obs, reward, raw.terminated | raw.truncated, info
        return raw.obs, reward, raw.terminated, raw.truncated, info

    def close(self, **kwargs: Any) -> None:
        """Stop the workers (idempotent), once every jitted call already dispatched on them
        (``xla()``) has run: jax dispatches asynchronously."""
        del kwargs
        if self._xla_used:
            import jax

            # A failed call raises where its result is read; close anyway.
            with contextlib.suppress(Exception):
                jax.effects_barrier()
        self._pool.close()

    def __repr__(self) -> str:
        fields = ", ".join(f"{k}={v!r}" for k, v in self.config.items())
        return f"EnvPoolEnv({fields})"


def _take(value: Any, ids: np.ndarray) -> Any:
    if isinstance(value, dict):
        return {k: _take(v, ids) for k, v in value.items()}
    return np.asarray(value)[ids]


def make(task_id: str, env_type: str = "gymnasium", **kwargs: Any) -> EnvPoolEnv:
    """EnvPool's ``envpool.make``: ``num_envs`` envs of ``task_id`` in the pool's workers.

    Args:
        task_id: a gymnasium id, or an EnvPool Atari id (``"Pong-v5"``; needs ale-py).
        env_type: ``"gymnasium"`` (five-tuple steps) or ``"gym"`` (EnvPool's gym API before
            gym 0.26: ``reset()`` gives ``obs``, ``step()`` ``(obs, reward, done, info)``).
        num_envs: envs (default 1); batch_size: envs per ``recv`` (default ``num_envs``: sync).
        num_threads: worker processes (default: the CPUs); for Atari the pool may take a few
            more so that worker blocks (one ``AtariVectorEnv`` each) divide ``batch_size``.
        seed: env ``i`` is seeded with ``seed + i`` at the first reset (default 42, EnvPool's).
        max_episode_steps: the episode limit. Other keywords go to ``gymnasium.make``, or for
            Atari are EnvPool's preprocessing options (:data:`ATARI_DEFAULTS`).
    """
    return EnvPoolEnv(task_id, env_type=env_type, **kwargs)


def make_gymnasium(task_id: str, **kwargs: Any) -> EnvPoolEnv:
    """``make(task_id, env_type="gymnasium", ...)``."""
    return make(task_id, env_type="gymnasium", **kwargs)


def make_gym(task_id: str, **kwargs: Any) -> EnvPoolEnv:
    """``make(task_id, env_type="gym", ...)``: four-tuple steps."""
    return make(task_id, env_type="gym", **kwargs)
