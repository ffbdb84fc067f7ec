"""The public gymnasium vector env classes, thin names over
:class:`rogue_gym.front.vector_env.FrontVectorEnv` with the constructor of their env kind, and
:func:`make_vec`.

* :class:`RogueVectorEnv`: Rogue-Gym's own game (:class:`rogue_gym.kinds.native.NativeKind`).
* :class:`PoolVectorEnv`: any gymnasium env hosted in the workers (a drop-in for
  ``AsyncVectorEnv``; :class:`rogue_gym.kinds.hosted.HostedKind`).
"""

from __future__ import annotations

import functools
from typing import Any, Callable, Optional, Sequence, Union

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv

from ._config import ConfigLike
from .front.vector_env import FrontVectorEnv
from .kinds.hosted import DEFAULT_INFO_BYTES, HostedKind, VectorEnvFn
from .kinds.native import NativeKind
from .registration import ENV_ID
from .settings import PoolOptions, PoolSettings, parse_autoreset_mode

__all__ = ["PoolVectorEnv", "RogueVectorEnv", "make_vec"]

EnvFn = Callable[[], gym.Env]


class RogueVectorEnv(FrontVectorEnv):
    """``num_envs`` Rogue-Gym games stepped by worker processes over shared memory.

    Semantics are gymnasium's (see :class:`rogue_gym.front.vector_env.FrontVectorEnv`); what
    comes from the game:

    * ``reset(seed=s)`` restarts every env's episode schedule from base seed ``s`` (env ``i``'s
      ``e``-th episode plays ``schedule(s, i, e)``, the same for any ``num_workers``).
    * ``step(actions)`` takes one int action per env (an array of shape ``(num_envs,)``, or a
      string with one key per env); infos hold ``seed`` (int64: a seed >= 2**63 reads as
      ``seed - 2**64``), ``episode_index``, ``episode_return``, ``episode_length``, ``floor``,
      ``max_floor``, ``gold``, ``hp``, ``max_hp``, ``died``, ``won`` (and ``worker_restarted``
      where a worker was restarted), each with its ``_key`` mask.
    * SAME_STEP: on an ending step the ended envs' other info values still describe the ended
      episode (as ``final_info`` does); the new episode's show from the next step on.
    * ``render()``: frames rebuilt by replaying each env's episode (``ansi``: text, ``human``:
      printed, ``rgb_array``: one pixel per cell).

    Args:
        num_envs, config: the number of games and their config (see
            :class:`rogue_gym.settings.PoolSettings`).
        autoreset_mode: ``NEXT_STEP`` (default), ``SAME_STEP`` or ``DISABLED``.
        copy: return observations that are yours to keep (lent or copied) instead of views of
            shared memory.
        render_mode: ``None``, ``"ansi"``, ``"human"`` or ``"rgb_array"`` (records actions to
            replay screens).
        **options: any other field of :class:`rogue_gym.settings.PoolSettings`.

    **Array lifetimes.** With ``copy=False`` (the default) the observation array returned by
    ``reset``/``step`` is a view of one of the pool's shared-memory batch slots, which the
    workers write directly (zero-copy) and in turn: it stays unchanged until the second
    following ``reset``/``step`` call, and readable even after ``close()``. The value arrays
    of ``step()``'s infos are reused with the same lifetime (``copy=True`` copies them too).
    Rewards and flags are fresh arrays.
    """

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
        settings = PoolSettings.from_kwargs({"num_envs": num_envs, "config": config, **options})
        super().__init__(NativeKind(settings, render_mode), autoreset_mode=mode, copy=copy)

    @property
    def config(self) -> dict[str, Any]:
        """The game config of every env."""
        return dict(self._kind.config)  # type: ignore[attr-defined]

    def render_env(self, i: int) -> str:
        """The current screen of env ``i`` (map rows and status line), rebuilt by replay."""
        return self._kind.screen(i)  # type: ignore[attr-defined]


def _is_space_pair(mode: Any) -> bool:
    """Whether ``mode`` is a ``(batch, single)`` pair of spaces (an ``observation_mode``)."""
    return (
        isinstance(mode, tuple)
        and len(mode) == 2
        and all(isinstance(m, spaces.Space) for m in mode)
    )


class PoolVectorEnv(FrontVectorEnv):
    """``num_envs = len(env_fns)`` gymnasium envs, stepped by worker processes over shared
    memory (a drop-in for ``AsyncVectorEnv``).

    Example::

        envs = rogue_gym.PoolVectorEnv([lambda: gym.make("CartPole-v1")] * 64, num_workers=2)
        obs, infos = envs.reset(seed=0)
        obs, rewards, terminations, truncations, infos = envs.step(envs.action_space.sample())
        envs.close()

    Args:
        env_fns: one callable per env, each returning a gymnasium env; all envs must have the
            same spaces. They are cloudpickled, so closures and lambdas work.
        num_workers: worker processes (default: as many as CPUs, at most ``num_envs``); each
            hosts a contiguous block of envs, the blocks differing by at most one env.
        copy: return observations that are yours to keep (default, like ``AsyncVectorEnv``):
            views of a shared-memory slot that the workers do not write again while any of
            them lives (:mod:`rogue_gym.front.leases`), or copies when no other slot is free
            (``batch_slots``) or the batch is small; with ``False`` they are views of shared
            memory, valid until the second following ``step``/``reset``.
        autoreset_mode: ``NEXT_STEP`` (default), ``SAME_STEP`` or ``DISABLED``.
        on_worker_failure, step_timeout, start_timeout, max_restarts, batch_size,
            worker_command, poll_us, runtime_dir, recycle_after_steps, recycle_above_rss,
            batch_slots, cpu_affinity, streaming_stores, env_concurrency: the pool's options
            (see :class:`rogue_gym.settings.PoolSettings`: ``recycle_*`` replace a worker by
            plan, for envs that leak; ``batch_slots`` trades memory for lent instead of copied
            batches; ``cpu_affinity`` pins the workers to cores; ``streaming_stores`` writes
            large batches past the cache; ``env_concurrency="threads"`` steps each env on a
            thread of its own, for envs that wait).
        worker_poll_us: how long the workers poll before they block, in µs (default
            :data:`rogue_gym.kinds.hosted.HOSTED_WORKER_POLL_US`; in the async API on a
            machine with no core to spare, workers block at once whatever it says).
        info_bytes: room per env and step for the env's info in shared memory (typed rows of
            numbers and arrays, or pickles); a longer info travels beside it, more slowly.
        shared_memory: the pool always carries fixed-size leaves (Box, Discrete,
            MultiDiscrete, MultiBinary) in shared memory, and leaves of no fixed size (Text,
            Graph, Sequence, OneOf, custom spaces) pickled per env; ``True`` refuses the latter
            with ``AsyncVectorEnv``'s errors (a ``TypeError``, or a ``ValueError`` for a custom
            space).
        context, daemon: accepted for ``AsyncVectorEnv`` compatibility; the workers are always
            fresh (spawned) processes that die with this one.
        observation_mode: ``"same"`` (default: every env has env 0's observation space),
            ``"different"`` (spaces of one layout, leaf dtypes and shapes, that differ
            otherwise, e.g. in their bounds; every env is built here once for its space, as
            ``AsyncVectorEnv`` does) or a ``(batch_space, single_space)`` pair, as gymnasium
            takes them. The workers check each env's space (a ``RuntimeError``, as gymnasium).

    ``reset(seed=s)`` seeds env ``i`` with ``s + i`` (a list seeds each env); ``None`` keeps
    each env's generator. An exception raised by an env (constructor, ``reset`` or ``step``)
    is re-raised here with its type and message, and the worker-side traceback as a note; the
    pool works again after ``reset()``.
    """

    def __init__(
        self,
        env_fns: Sequence[EnvFn],
        *,
        num_workers: Optional[int] = None,
        copy: bool = True,
        autoreset_mode: Union[str, AutoresetMode] = AutoresetMode.NEXT_STEP,
        on_worker_failure: str = PoolOptions.on_worker_failure,
        step_timeout: Optional[float] = PoolOptions.step_timeout,
        start_timeout: float = PoolOptions.start_timeout,
        max_restarts: Optional[int] = PoolOptions.max_restarts,
        info_bytes: int = DEFAULT_INFO_BYTES,
        worker_command: Optional[Sequence[str]] = None,
        batch_size: Optional[int] = None,
        poll_us: Optional[int] = None,
        worker_poll_us: Optional[int] = None,
        runtime_dir: Optional[str] = None,
        shared_memory: Optional[bool] = None,
        context: Optional[str] = None,
        daemon: bool = True,
        observation_mode: Any = "same",
        recycle_after_steps: Optional[int] = None,
        recycle_above_rss: Optional[int] = None,
        batch_slots: Optional[int] = None,
        cpu_affinity: Union[int, str, None] = None,
        streaming_stores: Optional[bool] = None,
        env_concurrency: Union[str, int] = PoolOptions.env_concurrency,
    ) -> None:
        del context, daemon  # always spawned workers
        if not (observation_mode in ("same", "different") or _is_space_pair(observation_mode)):
            raise ValueError(  # gymnasium's message
                "Invalid `observation_mode`, expected: 'same' or 'different' or tuple of single "
                f"and batch observation space, actual got {observation_mode}"
            )
        mode = parse_autoreset_mode(autoreset_mode)
        options = PoolOptions(
            num_workers=num_workers,
            on_worker_failure=on_worker_failure,
            step_timeout=step_timeout,
            start_timeout=start_timeout,
            max_restarts=max_restarts,
            worker_command=worker_command,
            batch_size=batch_size,
            runtime_dir=runtime_dir,
            poll_us=poll_us,
            worker_poll_us=worker_poll_us,
            recycle_after_steps=recycle_after_steps,
            recycle_above_rss=recycle_above_rss,
            batch_slots=batch_slots,
            cpu_affinity=cpu_affinity,
            streaming_stores=streaming_stores,
            env_concurrency=env_concurrency,
        )
        kind = HostedKind(
            env_fns,
            options,
            mode,
            info_bytes,
            static_only=shared_memory is True,
            observation_mode=observation_mode,
        )
        super().__init__(kind, autoreset_mode=mode, copy=copy)
        if kind.batch_observation_space is not None:
            self.observation_space = kind.batch_observation_space

    @property
    def np_random_seed(self) -> tuple[int, ...]:  # type: ignore[override]
        """Each env's ``np_random_seed``, as ``AsyncVectorEnv`` gives it."""
        return self.get_attr("np_random_seed")

    @property  # type: ignore[misc]  # read-only, as AsyncVectorEnv's
    def np_random(self) -> tuple[np.random.Generator, ...]:  # type: ignore[override]
        """Each env's ``np_random`` (copies from the workers), as ``AsyncVectorEnv`` gives it."""
        return self.get_attr("np_random")

    @classmethod
    def from_vector_env(
        cls, vector_env_fn: Callable[[int], VectorEnv], num_envs: int, **options: Any
    ) -> PoolVectorEnv:
        """``num_envs`` envs hosted as one vector env per worker: worker ``k`` builds
        ``vector_env_fn(n_k)`` for its block of ``n_k`` envs and steps the whole block with one
        call, which lets a vector env that runs its envs in C++ (ale-py's ``AtariVectorEnv``,
        with ``num_threads=1``) run at its own speed in every worker. Example::

            from ale_py.vector_env import AtariVectorEnv

            envs = rogue_gym.PoolVectorEnv.from_vector_env(
                lambda n: AtariVectorEnv("pong", num_envs=n, num_threads=1), 64, num_workers=2
            )

        The vector env must autoreset as the pool does (its ``metadata["autoreset_mode"]``, in
        ``SAME_STEP`` with ``final_obs``, and ``final_info`` if any, in its infos, as
        gymnasium's vector envs give them); ``vector_env_fn(1)`` is called here once, to learn
        the spaces. Seeds: ``reset(seed=s)`` resets the block of envs ``i .. j`` with
        ``seed=s + i`` (consecutive seeds, as every vector env takes them), so trajectories do
        not depend on the worker count when the vector env seeds its env ``k`` with
        ``seed + k``, as gymnasium's and ale-py's do. Infos are split per env (by the ``_key``
        masks) and merged again as gymnasium does (with a ``_key`` mask per key); an ``env_id``
        info is the pool's env index. ``call``/``get_attr`` go through the vector env's own.
        ``options`` are those of :class:`PoolVectorEnv`."""
        return cls(VectorEnvFn(vector_env_fn, int(num_envs)), **options)  # type: ignore[arg-type]

    @classmethod
    def from_pettingzoo(
        cls, env_fn: Callable[[], Any], num_envs: int, **options: Any
    ) -> PoolVectorEnv:
        """``num_envs`` PettingZoo envs (``env_fn()`` builds a ``ParallelEnv``, or an
        ``AECEnv`` taken through ``aec_to_parallel``) as one vector env with one row per
        (env, agent): row ``e * A + j`` is env ``e``'s agent ``possible_agents[j]``, ``A``
        agents per env, every agent with the same spaces. Each worker hosts whole envs
        (:class:`rogue_gym.multi_agent.AgentRows` of its block); ``infos["active"]`` marks
        the rows whose agent is there (absent ones: action ignored, observation zeros, reward
        0). An env autoresets when all its agents are done. ``num_workers`` is at most
        ``num_envs``; ``options`` are those of :class:`PoolVectorEnv`. See
        docs/multi-agent.md."""
        from .multi_agent import hosted_rows

        mode = parse_autoreset_mode(options.get("autoreset_mode", AutoresetMode.NEXT_STEP))
        rows, options = hosted_rows(env_fn, num_envs, mode, options)
        return cls(rows, **options)


def make_vec(
    env: Union[int, str, Callable[[], gym.Env], None] = None,
    num_envs: Optional[int] = None,
    config: ConfigLike = PoolSettings.config,
    **kwargs: Any,
) -> VectorEnv:
    """A vector env in the pool's worker processes.

    * ``make_vec(64, config="paper", **pool_options)`` (or ``make_vec(num_envs=64, ...)``,
      ``make_vec("RogueGym-v0", 64, ...)``): the native game, :class:`RogueVectorEnv`.
    * ``make_vec("CartPole-v1", 64, env_kwargs={...}, **options)``: any registered gymnasium
      id, hosted as Python envs (:class:`PoolVectorEnv`; ``options`` are its keywords).
    * ``make_vec(env_fn, 64, **options)``: ``env_fn()`` builds each env.

    Example::

        envs = rogue_gym.make_vec(64, config="paper", num_workers=2, seed=0)
        obs, infos = envs.reset()
        obs, rewards, terminated, truncated, infos = envs.step(envs.action_space.sample())
        envs.close()
    """
    if env is None:  # the native game: make_vec(num_envs=64, ...) or make_vec()
        return RogueVectorEnv(
            PoolSettings.num_envs if num_envs is None else int(num_envs), config, **kwargs
        )
    if isinstance(env, (int, np.integer)):
        if num_envs is not None:
            raise TypeError(
                f"make_vec({env}, num_envs={num_envs}): the number of envs is given twice; "
                "give it once, as make_vec(64, ...) or make_vec(num_envs=64, ...)"
            )
        return RogueVectorEnv(int(env), config, **kwargs)
    if num_envs is None:
        raise TypeError(f"make_vec({env!r}, num_envs, ...) needs num_envs")
    if env == ENV_ID:
        return RogueVectorEnv(num_envs, config, **kwargs)
    if config is not PoolSettings.config:
        raise TypeError(
            "config= is an option of the native game only (make_vec(num_envs, config=...))"
        )
    env_kwargs = dict(kwargs.pop("env_kwargs", None) or {})
    if isinstance(env, str):
        env_fn: EnvFn = functools.partial(gym.make, env, **env_kwargs)
    elif callable(env):
        if env_kwargs:
            raise TypeError("env_kwargs is for gymnasium ids; bind arguments into the callable")
        env_fn = env
    else:
        raise TypeError(f"make_vec needs a num_envs, a gymnasium id or a callable, got {env!r}")
    return PoolVectorEnv([env_fn] * int(num_envs), **kwargs)
