"""``PoolVectorEnv``: any gymnasium env in the pool's worker processes, as a gymnasium
``VectorEnv`` (a drop-in for ``AsyncVectorEnv``).

The callables are cloudpickled once, in this process; each worker process
(``python -m rogue_gym.worker``, never a fork) builds its block of envs from them and runs the
pool's Rust loop, which calls the envs through :mod:`rogue_gym.hosted.adapter`. Observations and
actions cross in shared memory, laid out leaf by leaf (:mod:`rogue_gym.hosted.layout`); infos
cross only when an env returns a non-empty one.
"""

from __future__ import annotations

import base64
import json
import os
import pickle
import sys
import weakref
from dataclasses import dataclass
from typing import Any, Callable, NoReturn, Optional, Sequence, Union

import cloudpickle
import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .. import _native, _sigterm
from .._records import FLAG_RESTARTED, FLAG_TERMINATED, FLAG_TRUNCATED, RECORD_DTYPE
from ..async_calls import already_pending, no_async_call, timed_out, warn_close_pending
from ..errors import CLOSED_MESSAGE, EnvFailedError, PoolClosedError
from ..reset_mask import partial_mask, refuse_finished
from ..settings import FAILURE_POLICIES, PoolSettings, check_start_timeout, parse_autoreset_mode
from . import leases
from .adapter import NO_SEED, decode_exception
from .infos import HEAD, InfoDecoder, split_joined, vector_infos
from .layout import SpaceLayout
from .vector_adapter import check_vector_env

__all__ = ["PoolVectorEnv"]

#: Room per env and step for an env's info in the worker's block, in bytes (``info_bytes``);
#: a longer info travels beside the block, in a private file.
DEFAULT_INFO_BYTES = 4096
#: How long a worker of hosted envs polls for the next command before it blocks, in µs
#: (``worker_poll_us``). Between two steps the caller runs Python (decoding, the policy), and a
#: worker that has gone to sleep costs a wake-up on every step: on the 2-core VM, CartPole x 64
#: with 2 workers ran at 46k steps/s with the pool's 50 µs and at 65-72k with 1-3 ms; blocking
#: sooner when waits are long was slower for HalfCheetah and Pong too, even with 4 workers on 2
#: cores (``benchmarks/results/real_envs/README.md``, "Polling").
HOSTED_WORKER_POLL_US = 2000

EnvFn = Callable[[], gym.Env]


@dataclass(frozen=True)
class _VectorEnvFn:
    """What :meth:`PoolVectorEnv.from_vector_env` hosts: ``fn(n)`` builds a vector env of
    ``n`` envs, one per worker block."""

    fn: Callable[[int], VectorEnv]
    num_envs: int

    def __post_init__(self) -> None:
        if not callable(self.fn):
            raise TypeError("vector_env_fn must be a callable building a vector env of n envs")
        if int(self.num_envs) < 1:
            raise ValueError(f"num_envs must be at least 1, got {self.num_envs}")


def _is_space_pair(mode: Any) -> bool:
    """Whether ``mode`` is a ``(single, batch)`` pair of spaces (an ``observation_mode``)."""
    return (
        isinstance(mode, tuple)
        and len(mode) == 2
        and all(isinstance(m, spaces.Space) for m in mode)
    )


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def _copy_tree(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _copy_tree(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return tuple(_copy_tree(v) for v in value)
    return value.copy()


class PoolVectorEnv(VectorEnv):
    """``num_envs = len(env_fns)`` gymnasium envs, stepped by worker processes over shared
    memory.

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
            them lives (:mod:`rogue_gym.hosted.leases`), or copies when you keep more than a
            few batches or the batch is small; with ``False`` they are views of shared
            memory, valid until the second following ``step``/``reset``.
        autoreset_mode: ``NEXT_STEP`` (default), ``SAME_STEP`` (``final_obs`` and
            ``final_info`` in the infos) or ``DISABLED`` (reset finished envs yourself with
            ``reset(options={"reset_mask": ...})``).
        on_worker_failure: ``"restart"`` (a dead or hung worker's envs are rebuilt and report
            ``truncated`` plus ``info["worker_restarted"]``) or ``"raise"``
            (:class:`rogue_gym.WorkerCrashedError`).
        step_timeout: seconds after which a worker that has not answered is treated as hung.
        start_timeout: seconds a lost worker has to come back (backoff, start-up and the reset
            of its envs). Every call returns or raises within ``step_timeout + start_timeout``.
        max_restarts: worker restarts allowed over the pool's life.
        info_bytes: room per env and step for the env's info in shared memory (typed rows of
            numbers and arrays, or pickles); a longer info travels beside it, more slowly.
        batch_size: envs per async :meth:`recv` (default all; otherwise a multiple of the envs
            per worker, which needs ``num_workers`` to divide ``num_envs``).
        worker_command: program and leading args of a worker (default:
            ``[sys.executable, "-m", "rogue_gym.worker"]``).
        poll_us, worker_poll_us: how long this process and the workers poll (yielding the
            CPU) before they block when waiting for each other, in µs (default: the pool's
            50 µs here, :data:`HOSTED_WORKER_POLL_US` in the workers).
        runtime_dir: the private directory of the pool's files (see
            :class:`rogue_gym.settings.PoolSettings`; default the user's runtime directory).
        shared_memory, context, daemon: accepted for ``AsyncVectorEnv`` compatibility; the
            pool always uses shared memory and fresh (spawned) worker processes that die with
            this one.
        observation_mode: only ``"same"`` is supported.

    An exception raised by an env (constructor, ``reset`` or ``step``) is re-raised here with
    its type and message, and the worker-side traceback as a note; the pool works again after
    ``reset()``.
    """

    def __init__(
        self,
        env_fns: Sequence[EnvFn],
        *,
        num_workers: Optional[int] = None,
        copy: bool = True,
        autoreset_mode: Union[str, AutoresetMode] = AutoresetMode.NEXT_STEP,
        on_worker_failure: str = PoolSettings.on_worker_failure,
        step_timeout: Optional[float] = PoolSettings.step_timeout,
        start_timeout: float = PoolSettings.start_timeout,
        max_restarts: Optional[int] = PoolSettings.max_restarts,
        info_bytes: int = DEFAULT_INFO_BYTES,
        worker_command: Optional[Sequence[str]] = None,
        batch_size: Optional[int] = None,
        poll_us: Optional[int] = None,
        worker_poll_us: Optional[int] = HOSTED_WORKER_POLL_US,
        runtime_dir: Optional[str] = None,
        shared_memory: bool = True,
        context: Optional[str] = None,
        daemon: bool = True,
        observation_mode: str = "same",
    ) -> None:
        del shared_memory, context, daemon  # always shared memory and spawned workers
        hosted = env_fns if isinstance(env_fns, _VectorEnvFn) else None
        env_fns = [] if hosted is not None else list(env_fns)
        if hosted is None and not env_fns:
            raise ValueError("env_fns is empty: give one callable per env")
        if not (observation_mode in ("same", "different") or _is_space_pair(observation_mode)):
            raise ValueError(  # gymnasium's message
                "Invalid `observation_mode`, expected: 'same' or 'different' or tuple of single "
                f"and batch observation space, actual got {observation_mode}"
            )
        if observation_mode != "same":
            raise ValueError(
                f"observation_mode={observation_mode!r} (per-env observation spaces) is not "
                "supported yet: every env must have the same observation space"
            )
        if on_worker_failure not in FAILURE_POLICIES:
            raise ValueError(
                f"on_worker_failure must be one of {FAILURE_POLICIES}, got {on_worker_failure!r}"
            )
        self.autoreset_mode = parse_autoreset_mode(autoreset_mode)
        self.num_envs = len(env_fns) if hosted is None else hosted.num_envs
        self.copy = bool(copy)
        workers = (
            min(self.num_envs, os.cpu_count() or 1) if num_workers is None else int(num_workers)
        )

        # Probe one env here for the spaces and metadata, as AsyncVectorEnv does.
        if not 1 <= workers <= self.num_envs:
            raise ValueError(
                f"num_workers must be between 1 and the number of envs ({self.num_envs}), got {workers}"
            )
        probe: Any
        if hosted is None:
            probe = env_fns[0]()
            if not isinstance(probe, gym.Env):
                raise TypeError(
                    f"env_fns[0]() returned {type(probe).__name__!r}, not a gymnasium.Env: each "
                    "env function must build and return an env (e.g. lambda: "
                    "gym.make('CartPole-v1'))"
                )
        else:
            probe = hosted.fn(1)
        try:
            if hosted is None:
                self.single_observation_space = probe.observation_space
                self.single_action_space = probe.action_space
            else:
                check_vector_env(probe, 1, self.autoreset_mode)
                self.single_observation_space = probe.single_observation_space
                self.single_action_space = probe.single_action_space
            self.metadata = dict(probe.metadata)
            self.render_mode = probe.render_mode
            self.spec = getattr(probe, "spec", None)
        finally:
            probe.close()
        self.metadata["autoreset_mode"] = self.autoreset_mode
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._obs_layout = SpaceLayout(self.single_observation_space)
        act = self.single_action_space
        num_actions = int(act.n) if isinstance(act, spaces.Discrete) else 0
        self._discrete_start: Optional[int] = (
            int(act.start) if isinstance(act, spaces.Discrete) else None
        )
        self._act_layout = SpaceLayout(act)

        spec = {
            "obs_shape": [self._obs_layout.stride],
            "dtype": "u8",
            "num_actions": num_actions,
            "info_names": [],
            "action_bytes": 0 if self._discrete_start is not None else self._act_layout.nbytes,
            "extra_bytes": int(info_bytes),
        }
        adapter: dict[str, Any] = {
            "sys_path": [p for p in sys.path if p],
            "spaces": _b64(cloudpickle.dumps((self.single_observation_space, act))),
            "discrete_start": self._discrete_start,
        }
        if hosted is None:
            pickled = [cloudpickle.dumps(fn) for fn in env_fns]
            unique = list(dict.fromkeys(pickled))
            adapter["env_fns"] = [_b64(p) for p in unique]
            adapter["fn_of_env"] = [unique.index(p) for p in pickled]
        else:
            adapter["vector_env_fn"] = _b64(cloudpickle.dumps(hosted.fn))
            adapter["autoreset_mode"] = self.autoreset_mode.value
        kind = "python" if hosted is None else "python-vector"
        lend = self.copy and self.num_envs * self._obs_layout.stride >= leases.LEND_MIN_BYTES
        self._settings: dict[str, Any] = {
            "env": {"kind": kind, "spec": spec, "adapter": adapter},
            "spec": spec,
            "num_envs": self.num_envs,
            "num_workers": workers,
            "seeds": self._seeds(None),
            "autoreset": "same_step"
            if self.autoreset_mode == AutoresetMode.SAME_STEP
            else "next_step",
            "on_worker_failure": on_worker_failure,
            "step_timeout": step_timeout,
            "start_timeout": check_start_timeout(start_timeout),
            "max_restarts": max_restarts,
            "batch_size": batch_size,
            "batch_slots": leases.LENDING_SLOTS if lend else None,
            "poll_us": poll_us,
            "worker_poll_us": worker_poll_us,
            "runtime_dir": None if runtime_dir is None else os.fspath(runtime_dir),
        }
        command = list(worker_command or [sys.executable, "-m", "rogue_gym.worker"])
        _sigterm.install()
        try:
            self._pool: Any = _native.Pool(json.dumps(self._settings), command)
        except EnvFailedError as err:
            _reraise(err)
        self._finalizer = weakref.finalize(self, _native.Pool.close, self._pool)
        #: The pool's name: the prefix of its shared-memory files.
        self.pool_name: str = self._pool.name()
        self.num_workers = workers
        n, stride = self.num_envs, self._obs_layout.stride
        self._slots = [np.asarray(v).reshape(n, stride) for v in self._pool.shared_views()]
        self._slot_views = [self._obs_layout.batch_views(s) for s in self._slots]
        self._lender = (
            leases.SlotLender(self._slots, self._obs_layout.batch_views) if lend else None
        )
        self._final = (
            np.zeros((n, stride), np.uint8) if self._settings["autoreset"] == "same_step" else None
        )
        self._act_rows = np.zeros((n, self._act_layout.nbytes), np.uint8)
        self._done = np.zeros(n, bool)
        self._info_decoder = InfoDecoder()
        self._started = False
        #: The split call in flight (gymnasium's ``step_async``/``reset_async``), if any.
        self._pending: Optional[str] = None
        #: A partial reset's result, done in ``reset_async`` and returned by ``reset_wait``.
        self._partial: Optional[tuple[Any, dict[str, Any]]] = None
        self.closed = False

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
        gymnasium's vector envs give them); ``vector_env_fn(1)`` is called here once, to learn the spaces. Seeds:
        ``reset(seed=s)`` resets the block of envs ``i .. j`` with ``seed=s + i`` (consecutive
        seeds, as every vector env takes them), so trajectories do not depend on the worker
        count when the vector env seeds its env ``k`` with ``seed + k``, as gymnasium's and
        ale-py's do. Infos are split per env (by the ``_key`` masks) and merged again as
        gymnasium does (with a ``_key`` mask per key); an ``env_id`` info is the pool's env
        index. ``call``/``get_attr`` go through the vector env's own.
        ``options`` are those of :class:`PoolVectorEnv`."""
        return cls(_VectorEnvFn(vector_env_fn, int(num_envs)), **options)  # type: ignore[arg-type]

    # -- seeds ---------------------------------------------------------------------------

    def _seeds(self, seed: Union[int, Sequence[Optional[int]], None]) -> dict[str, Any]:
        """The pool's seed schedule for ``reset(seed=...)``: env ``i``'s first episode gets
        ``seed + i`` (or ``seed[i]``), or no seed at all for ``None``; later episodes are not
        reseeded."""
        if seed is None:
            return {"base": 0, "set": {"list": [NO_SEED]}, "policy": "sequential"}
        if isinstance(seed, (int, np.integer)):
            start = int(seed)
            if start < 0 or start + self.num_envs > 2**63:
                raise ValueError(f"seed must be in [0, 2**63 - num_envs), got {seed}")
            return {
                "base": start,
                "set": {"range": {"start": start, "end": start + self.num_envs}},
                "policy": "sequential",
            }
        seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise ValueError(
                f"seed list has {len(seeds)} entries; expected one per env ({self.num_envs})"
            )
        if any(s is None for s in seeds):
            raise ValueError(
                "a seed list cannot mix None and seeds; pass seed=None to seed from entropy"
            )
        values = [int(s) for s in seeds if s is not None]
        if any(s < 0 or s >= 2**63 for s in values):
            raise ValueError("seeds must be in [0, 2**63)")
        return {"base": 0, "set": {"list": values}, "policy": "sequential"}

    # -- the VectorEnv API -----------------------------------------------------------------

    def reset(
        self,
        *,
        seed: Union[int, Sequence[Optional[int]], None] = None,
        options: Optional[dict[str, Any]] = None,
    ) -> tuple[Any, dict[str, Any]]:
        """Reset every env (or those of ``options["reset_mask"]``). ``seed``: an int seeds env
        ``i`` with ``seed + i``, a list seeds each env; ``None`` keeps each env's generator
        (and a first reset without a seed reseeds nothing, as gymnasium's vector envs).
        Other ``options`` go to every env's next reset."""
        self.reset_async(seed=seed, options=options)
        return self.reset_wait()

    def reset_async(
        self,
        seed: Union[int, Sequence[Optional[int]], None] = None,
        options: Optional[dict[str, Any]] = None,
    ) -> None:
        """The first half of :meth:`reset` (gymnasium's ``AsyncVectorEnv.reset_async``): a full
        reset is sent and the workers reset while you do something else; :meth:`reset_wait`
        collects it. A partial reset (``reset_mask``) runs here, whole."""
        self._check_open()
        self._not_pending("reset_async")
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        if options:  # for each env's next reset, as AsyncVectorEnv passes them
            self.call_envs("set_reset_options", "", [((options,), {})] * self.num_envs)
        mask = partial_mask(mask, self.num_envs, self._started)
        if mask is not None:
            if seed is not None:
                raise ValueError("reset(seed=...) cannot be combined with a reset_mask")
            obs = self._shared(lambda: self._pool.reset_envs_shared(mask))
            self._done &= ~mask
            _, _, _, restarted, final = self._pool.outcome()
            self._pending, self._partial = "reset", (obs, self._infos(restarted, final))
            return
        if seed is not None or not self._started:
            self._pool.set_seeds(json.dumps(self._seeds(seed)))
        self._steer()
        self._call(self._pool.reset_shared_send)
        self._pending, self._partial = "reset", None

    def reset_wait(self, timeout: Optional[float] = None) -> tuple[Any, dict[str, Any]]:
        """The second half of :meth:`reset_async`: wait at most ``timeout`` seconds (``None``:
        the pool's own bound) and return ``(obs, infos)``. On a timeout (``TimeoutError``) the
        reset stays pending: call ``reset_wait`` again."""
        self._check_open()
        if self._pending != "reset":
            raise no_async_call("reset")
        if self._partial is not None:
            self._pending, (obs, infos), self._partial = None, self._partial, None
            return obs, infos
        obs = self._collect("reset", timeout)
        self._done[:] = False
        self._started = True
        _, _, _, restarted, final = self._pool.outcome()
        return obs, self._infos(restarted, final)

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every env with ``actions`` (a batch of the action space)."""
        acts = self._step_actions(actions, "step")
        obs = self._shared(lambda: self._pool.step_shared(acts, None, self._final))
        return self._step_result(obs)

    def step_async(self, actions: Any) -> None:
        """The first half of :meth:`step` (gymnasium's ``AsyncVectorEnv.step_async``): send
        ``actions`` and return at once; the workers step while you do something else."""
        acts = self._step_actions(actions, "step_async")
        self._steer()
        self._call(lambda: self._pool.step_shared_send(acts))
        self._pending = "step"

    def step_wait(
        self, timeout: Optional[float] = None
    ) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """The second half of :meth:`step_async`: wait at most ``timeout`` seconds (``None``:
        the pool's own bound) and return what :meth:`step` returns. On a timeout
        (``TimeoutError``) the step stays pending: call ``step_wait`` again."""
        self._check_open()
        if self._pending != "step":
            raise no_async_call("step")
        return self._step_result(self._collect("step", timeout))

    def _step_actions(self, actions: Any, caller: str) -> Any:
        """Checks before a step; the actions as the pool takes them."""
        self._check_open()
        self._not_pending(caller)
        if not self._started:
            raise RuntimeError("call reset() before step()")
        if self.autoreset_mode == AutoresetMode.DISABLED:
            refuse_finished(self._done)
        if self._discrete_start is not None:
            return self._discrete_indices(actions, range(self.num_envs))
        return self._act_layout.flat_batch(actions, self._act_rows)

    def _step_result(
        self, obs: Any
    ) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        rewards, terminated, truncated, restarted, final = self._pool.outcome()
        self._done = terminated | truncated
        return obs, rewards, terminated, truncated, self._infos(restarted, final)

    def _not_pending(self, caller: str) -> None:
        if self._pending is not None:
            raise already_pending(caller, self._pending)

    def _collect(self, what: str, timeout: Optional[float]) -> Any:
        """Wait for the pending ``what`` (step or reset); its observations. A timeout keeps it
        pending; an error ends it."""
        try:
            slot = self._call(lambda: self._pool.wait_shared(timeout, None, self._final))
        except BaseException:
            self._pending = None
            raise
        if slot is None:
            raise timed_out(what, timeout)
        self._pending = None
        return self._lend(int(slot))

    def close_extras(self, **kwargs: Any) -> None:
        """Stop the workers and remove the pool's shared-memory files (idempotent; nothing to
        do if the constructor failed before the pool existed). A pending ``step_async`` or
        ``reset_async`` is abandoned with a warning."""
        pending = getattr(self, "_pending", None)
        if pending is not None and not self.closed:
            warn_close_pending(pending)
            self._pending = None
        finalizer = getattr(self, "_finalizer", None)
        if finalizer is not None:
            finalizer()

    # -- EnvPool-style async API -------------------------------------------------------------

    def async_reset(self, seed: Union[int, Sequence[Optional[int]], None] = None) -> None:
        """Start resetting every env (seeded as by :meth:`reset`); collect the first
        observations with :meth:`recv`. The async API needs ``NEXT_STEP`` autoreset."""
        self._check_open()
        if self.autoreset_mode != AutoresetMode.NEXT_STEP:
            raise ValueError("the async API (async_reset/send/recv) needs autoreset_mode NEXT_STEP")
        if seed is not None or not self._started:
            self._pool.set_seeds(json.dumps(self._seeds(seed)))
        self._pool.async_reset()
        self._started = True
        self._async_ids: Optional[np.ndarray] = None

    def send(self, actions: Any, env_id: Optional[Any] = None) -> None:
        """Send ``actions`` (a batch of the action space, one row per env id) to the envs
        ``env_id`` (default: those of the last :meth:`recv`); they must form whole worker
        blocks, as :meth:`recv` returns them."""
        self._check_open()
        ids = getattr(self, "_async_ids", None) if env_id is None else np.asarray(env_id, np.int64)
        if ids is None:
            raise RuntimeError("send() needs env_id, or a previous recv() whose envs it answers")
        env_ids = [int(i) for i in ids]
        if self._discrete_start is not None:
            acts = self._discrete_indices(actions, env_ids)
            self._call(lambda: self._pool.send(acts, env_ids))
        else:
            rows = np.zeros((len(env_ids), self._act_layout.nbytes), np.uint8)
            flat = self._act_layout.flat_batch(actions, rows)
            self._call(lambda: self._pool.send(flat, env_ids))

    def recv(self) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Wait for the next ``batch_size`` envs: ``(obs, rewards, terminations, truncations,
        infos)`` with ``infos["env_id"]`` naming the envs of the rows. Observations are copies
        (``copy=True``) or, for a batch of one worker block, read-only views of the worker's
        shared-memory sample that stay valid for as long as they live."""
        self._check_open()
        blocks = self._call(self._pool.recv)
        stride = self._obs_layout.stride
        rows = [np.asarray(raw).reshape(-1, stride) for _, raw, _, _ in blocks]
        recs = np.concatenate([np.frombuffer(r, RECORD_DTYPE) for _, _, r, _ in blocks])
        env_id = np.concatenate(
            [np.arange(start, start + len(r)) for (start, *_), r in zip(blocks, rows)]
        )
        obs_rows = rows[0] if len(rows) == 1 else np.concatenate(rows)
        obs = self._obs_layout.batch_views(obs_rows)
        if self.copy:
            obs = _copy_tree(obs)
        self._async_ids = env_id
        flags = recs["flags"]
        terminated = (flags & FLAG_TERMINATED) != 0
        truncated = (flags & FLAG_TRUNCATED) != 0
        restarted = (flags & FLAG_RESTARTED) != 0
        infos: dict[str, Any] = {}
        if restarted.any():
            infos["worker_restarted"] = restarted.copy()
            infos["_worker_restarted"] = restarted.copy()
        row_of = {int(e): r for r, e in enumerate(env_id)}
        extras = [(row_of[env], data) for *_, block_extras in blocks for env, data in block_extras]
        infos = vector_infos(
            infos,
            self._info_decoder,
            extras,
            len(env_id),
            lambda row, entries: self._env_info(int(env_id[row]), entries, False),
        )
        infos["env_id"] = env_id
        return obs, recs["reward"].astype(np.float64), terminated, truncated, infos

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """``getattr(env, name)(*args, **kwargs)`` in every env (or the attribute itself if it
        is not callable), through the wrappers; one result per env."""
        return tuple(self.call_envs("call", name, [(args, kwargs)] * self.num_envs))

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """The attribute ``name`` of every env (called if callable, as ``AsyncVectorEnv``)."""
        return self.call(name)

    def set_attr(self, name: str, values: Any) -> None:
        """Set ``name`` in every env: ``values`` is one value per env (list or tuple) or one
        value for all."""
        if not isinstance(values, (list, tuple)):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(
                f"set_attr needs one value per env ({self.num_envs}), got {len(values)}"
            )
        self.call_envs("set_wrapper_attr", name, [((v,), {}) for v in values])

    def render(self) -> tuple[Any, ...]:
        """Every env's ``render()``."""
        return tuple(self.call_envs("render", "", [((), {})] * self.num_envs))

    def call_envs(
        self,
        op: str,
        name: str,
        arguments: Sequence[tuple[tuple[Any, ...], dict[str, Any]]],
        indices: Optional[Sequence[int]] = None,
    ) -> list[Any]:
        """Run call operation ``op`` (see :data:`rogue_gym.hosted.adapter.CALL_OPS`) on the
        envs ``indices`` (default all), with ``arguments[j]`` = ``(args, kwargs)`` for the
        ``j``-th of them; returns their results in that order. An env's exception is re-raised
        here."""
        self._check_open()
        envs = list(range(self.num_envs)) if indices is None else [int(i) for i in indices]
        if len(arguments) != len(envs):
            raise ValueError(f"{len(arguments)} argument sets for {len(envs)} envs")
        requests = [
            (env, pickle.dumps((op, name, args, kwargs), protocol=pickle.HIGHEST_PROTOCOL))
            for env, (args, kwargs) in zip(envs, arguments)
        ]
        try:
            replies = self._pool.call_envs(requests)
        except EnvFailedError as err:
            _reraise(err)
        results = []
        for env, data in replies:
            status, value = pickle.loads(data)
            if status == "err":
                decoded = decode_exception(value)
                if decoded is None:
                    raise RuntimeError(f"env {env}: {value}")
                exc, tb = decoded
                if hasattr(exc, "add_note"):
                    exc.add_note(
                        f"raised by env {env} during {op}({name!r}); worker-side traceback:\n{tb}"
                    )
                raise exc
            results.append(value)
        return results

    @property
    def worker_pids(self) -> list[int]:
        """Process ids of the workers (in worker order)."""
        return [] if self.closed else list(self._pool.worker_pids())

    @property
    def restarts(self) -> int:
        """Worker restarts so far (``on_worker_failure="restart"``; ``max_restarts`` bounds
        them)."""
        return int(self._pool.restarts())

    # -- helpers ---------------------------------------------------------------------------

    def _check_open(self) -> None:
        if self.closed:
            raise PoolClosedError(CLOSED_MESSAGE)

    def _call(self, fn: Callable[[], Any]) -> Any:
        """Run a native call; an env's own exception is re-raised as itself."""
        try:
            return fn()
        except EnvFailedError as err:
            _reraise(err)

    def _discrete_indices(self, actions: Any, env_ids: Sequence[int]) -> np.ndarray:
        """Discrete actions (one per env of ``env_ids``) as indices from 0, checked against
        the space in the caller's terms (``start`` included)."""
        a = np.asarray(actions)
        if a.shape != (len(env_ids),) or a.dtype.kind not in "iu":
            raise ValueError(
                f"expected integer actions of shape ({len(env_ids)},), got {a.dtype} {a.shape}"
            )
        space = self.single_action_space
        start, n = int(space.start), int(space.n)  # type: ignore[attr-defined]
        wide = a.astype(object) if a.dtype.kind == "u" and a.dtype.itemsize >= 8 else a
        bad = (wide < start) | (wide >= start + n)
        if bad.any():
            j = int(np.flatnonzero(bad)[0])
            raise ValueError(
                f"env {env_ids[j]}: action {a[j]} is out of range of {space}; valid actions are "
                f"{start} to {start + n - 1}"
            )
        return a.astype(np.int64) - start

    def _shared(self, call: Callable[[], int]) -> Any:
        """Run a ``*_shared`` call of the pool into a slot no returned array still uses;
        returns the observations it wrote (lent, copied, or views with ``copy=False``)."""
        self._steer()
        return self._lend(int(self._call(call)))

    def _steer(self) -> None:
        """Make the next ``*_shared`` call write a slot no lent array still uses."""
        if self._lender is not None:
            free = self._lender.steer()
            if free is not None:
                self._call(lambda: self._pool.select_slot(free))

    def _lend(self, slot: int) -> Any:
        """The observations of ``slot`` as returned: lent, copied, or views (``copy=False``)."""
        if self._lender is None:
            views = self._slot_views[slot]
            return _copy_tree(views) if self.copy else views
        lent = self._lender.lend(slot)
        return _copy_tree(self._slot_views[slot]) if lent is None else lent

    def _infos(self, restarted: Optional[np.ndarray], final_envs: list[int]) -> dict[str, Any]:
        """The vector infos of the last call: ``restarted`` (envs whose worker was restarted,
        or ``None``) and ``final_envs`` (SAME_STEP: envs whose episode ended) as
        :meth:`_native.Pool.outcome` gives them."""
        infos: dict[str, Any] = {}
        if restarted is not None:
            infos["worker_restarted"] = restarted
            infos["_worker_restarted"] = restarted.copy()
        final = set(final_envs) if self._final is not None else set()
        rows, data, size, ends = self._pool.take_extras(HEAD)
        if size and not final and self._info_decoder.put_uniform(infos, data, rows, self.num_envs):
            return infos  # the usual step: one typed info layout, decoded in one go
        return vector_infos(
            infos,
            self._info_decoder,
            split_joined(rows, data, size, ends, self.num_envs),
            self.num_envs,
            lambda env, entries: self._env_info(env, entries, env in final),
            final,
        )

    def _env_info(
        self, env: int, entries: list[tuple[str, dict[str, Any]]], final: bool
    ) -> dict[str, Any]:
        """One env's info for this call, as gymnasium's vector envs build it: the reset's (or
        step's) info and, when the episode ended in SAME_STEP mode, ``final_obs`` and the last
        step's info as ``final_info``."""
        info: dict[str, Any] = {}
        final_info: dict[str, Any] = {}
        for kind, entry in entries:
            if kind == "step" and final:
                final_info = entry
            else:
                info.update(entry)
        if final and self._final is not None:
            row = self._final[env : env + 1]
            info["final_obs"] = _copy_tree(_first(self._obs_layout.batch_views(row)))
            info["final_info"] = final_info
        return info


def _env_exception(err: BaseException) -> BaseException:
    """The env's own exception carried by an ``EnvFailedError`` (with the worker-side traceback
    as a note on Python 3.11+), or ``err`` itself if it carries none."""
    if not isinstance(err, EnvFailedError):
        return err
    decoded = decode_exception(err.detail)
    if decoded is None:
        return err
    exc, tb = decoded
    if hasattr(exc, "add_note"):  # Python 3.11+
        exc.add_note(
            f"raised by env {err.env} during {err.context} in worker {err.worker} (pid {err.pid}); "
            f"call reset() to continue. Worker-side traceback:\n{tb}"
        )
    return exc


def _reraise(err: EnvFailedError) -> NoReturn:
    """Raise the env's own exception carried by ``err``. When several envs or workers failed
    in the same call, the first is raised and the others (decoded too) are in its ``others``
    attribute, one note each on Python 3.11+; one ``reset()`` clears them all."""
    exc = _env_exception(err)
    others = [_env_exception(o) for o in getattr(err, "others", [])]
    if others:
        if exc is not err:
            exc.__notes__ = [
                n for n in getattr(exc, "__notes__", []) if not n.startswith("also failed")
            ]
        exc.others = others  # type: ignore[attr-defined]
        for o in others:
            if hasattr(exc, "add_note"):
                exc.add_note(f"also failed in the same call: {type(o).__name__}: {o}")
    raise exc from None


def _first(tree: Any) -> Any:
    """Row 0 of a batch tree."""
    if isinstance(tree, dict):
        return {k: _first(v) for k, v in tree.items()}
    if isinstance(tree, tuple):
        return tuple(_first(v) for v in tree)
    return tree[0]
