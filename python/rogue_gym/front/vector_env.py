"""``FrontVectorEnv``: the pool as a ``gymnasium.vector.VectorEnv``, for every env kind."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Optional, Sequence, Union

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from ..errors import CorruptInfoError
from ..kinds.result import Result, copy_tree
from ..protocol.ops import refuse_op
from ..settings import parse_autoreset_mode
from .core import Core, mark_restarted
from .pending import Split, already_pending, no_async_call, timed_out, warn_close_pending
from .reset_mask import partial_mask, refuse_finished
from .stats import PoolStats

if TYPE_CHECKING:
    from ..kinds.spec import Kind

__all__ = ["FrontVectorEnv"]

Seed = Union[int, Sequence[Optional[int]], None]
StepResult = tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]


@dataclass(frozen=True)
class Pending:
    """The split call in flight, as gymnasium's ``AsyncState``: ``what`` it is; ``done`` is
    what a call that already ran left for its wait (a partial reset's ``(obs, infos)``, a
    call's ``("ok", results)`` or ``("err", exception)``), or ``None`` while the workers are at
    it."""

    what: Split
    done: Any = None


class FrontVectorEnv(gym.vector.VectorEnv):
    """``num_envs`` envs stepped by worker processes over shared memory (see the public
    classes, :class:`rogue_gym.RogueVectorEnv` and :class:`rogue_gym.PoolVectorEnv`, for what
    each kind takes and does).

    Semantics follow gymnasium's own vector envs:

    * ``reset(seed=..., options=...)``: the seed as the kind takes it (the native game: the
      base of every env's episode schedule; hosted envs: ``seed + i`` or one per env);
      ``options["reset_mask"]`` resets only the masked envs (with their seeds, where the kind
      seeds envs one by one); other options go to every env's next reset.
    * ``step(actions)``: ``(obs, rewards, terminations, truncations, infos)``; rewards float64,
      flags bool, infos a dict of arrays with ``_key`` masks.
    * ``autoreset_mode``: ``NEXT_STEP`` (default), ``SAME_STEP`` (``final_obs`` and
      ``final_info`` in the infos) or ``DISABLED`` (reset ended envs with ``reset_mask``;
      stepping them is a ``ValueError``).
    * ``step_async``/``step_wait``, ``reset_async``/``reset_wait`` (with timeouts) and
      ``call_async``/``call_wait``, and gymnasium's errors for calls out of order.
    * A lost worker is restarted (its envs report ``truncated=True`` and
      ``infos["worker_restarted"]``) or raises :class:`rogue_gym.WorkerCrashedError`; every call
      returns or raises within ``step_timeout + start_timeout``.
    """

    def __init__(
        self,
        kind: Kind,
        *,
        autoreset_mode: Union[str, AutoresetMode] = AutoresetMode.NEXT_STEP,
        copy: bool = False,
    ) -> None:
        self.autoreset_mode = parse_autoreset_mode(autoreset_mode)
        #: Whether the env was closed (gymnasium's ``close()`` sets it).
        self.closed = False
        facts = kind.facts
        self._same_step = self.autoreset_mode == AutoresetMode.SAME_STEP
        # The pool first: one that cannot fit /dev/shm fails at once, before the batched
        # spaces (num_envs times the bounds of one observation) are built.
        self._core = Core(kind, same_step=self._same_step, copy=bool(copy))
        self.num_envs = facts.num_envs
        self.single_observation_space = facts.single_observation_space
        self.single_action_space = facts.single_action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.metadata = {**facts.metadata, "autoreset_mode": self.autoreset_mode}
        self.render_mode = facts.render_mode
        self.spec = facts.env_spec
        self.copy = bool(copy)
        self._kind = kind
        self._fill = facts.obs_filler
        self._disabled = self.autoreset_mode == AutoresetMode.DISABLED
        #: The split call in flight.
        self._pending: Optional[Pending] = None
        #: The call lifecycle (shared with the kind's view, and rogue_gym.envpool).
        self.call_state = self._core.state
        #: The actions each env took last (kept for the episode log).
        self._taken = np.zeros(facts.num_envs, np.int64)
        self._stats_base: Optional[PoolStats] = None

    # -- the pool --------------------------------------------------------------------------

    @property
    def num_workers(self) -> int:
        """Number of worker processes."""
        return self._core.num_workers

    @property
    def batch_size(self) -> int:
        """Envs an async :meth:`recv` returns by default (``num_envs`` unless set)."""
        return int(self._core.pool.batch_size)

    @property
    def worker_pids(self) -> list[int]:
        """Process ids of the workers (worker ``k`` hosts envs ``envs_of_worker(k)``)."""
        return self._core.worker_pids

    @property
    def restarts(self) -> int:
        """Worker restarts so far (``on_worker_failure="restart"``; ``max_restarts`` bounds
        them)."""
        return self._core.restarts

    @property
    def pool_name(self) -> str:
        """The pool's name: the prefix of its shared-memory files."""
        return self._core.name

    def envs_of_worker(self, worker: int) -> range:
        """Indices of the envs hosted by ``worker``."""
        return self._core.envs_of_worker(worker)

    def stats(self, reset: bool = False) -> PoolStats:
        """Where the time went since the pool started (or since ``stats(reset=True)``): per
        worker, env steps and the time in the envs, waiting for actions and publishing,
        restarts and timeouts; for the caller, the time between and inside the pool's calls;
        how infos travelled and observations were handed out. The workers keep their counters
        in shared memory: reading them sends no message. ``str()`` of it is a one-line health
        summary. ``reset=True`` starts a new span after this reading."""
        now = self._core.stats()
        out = now if self._stats_base is None else now - self._stats_base
        if reset:
            self._stats_base = now
        return out

    # -- reset -----------------------------------------------------------------------------

    def reset(
        self, *, seed: Seed = None, options: Optional[dict[str, Any]] = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset every env (or those of ``options["reset_mask"]``); ``(obs, infos)``.

        ``reset_mask`` (a ``np.bool_`` array of shape ``(num_envs,)`` with at least one
        ``True``, as gymnasium checks it) resets only the masked envs: the others keep their
        state and their current observation is returned again; infos describe the reset envs.
        With a ``seed``, the masked envs are seeded as a full reset would seed them (hosted
        envs; the native game's seeds are a schedule, so it refuses). Other ``options`` go to
        every env's reset.
        """
        self.reset_async(seed=seed, options=options)
        return self.reset_wait()

    def reset_async(self, seed: Seed = None, options: Optional[dict[str, Any]] = None) -> None:
        """The first half of :meth:`reset` (gymnasium's ``AsyncVectorEnv.reset_async``): a full
        reset is sent and the workers reset while you do something else; :meth:`reset_wait`
        collects it. A partial reset (``reset_mask``) runs here, whole."""
        core = self._core
        core.check_open()
        self._not_pending("reset_async")
        options = dict(options or {})
        state = core.state
        mask = partial_mask(options.pop("reset_mask", None), self.num_envs, state.started)
        if mask is not None and seed is not None:
            self._kind.seeds(seed, mask)
        if options:  # for each env's next reset, as AsyncVectorEnv passes them
            self._call_all("set_reset_options", "", (options,))
        if mask is not None:
            core.send_reset(mask)
            res = core.wait(None)
            assert res is not None  # no timeout: a result or an error
            restarted = res.restarted
            reset = mask if restarted is None else mask | restarted
            state.ended &= ~reset
            if state.log is not None:
                state.log.record(res, None, self._same_step, rows=reset)
            infos = self._infos(res, mask)
            self._pending = Pending(Split.RESET, (self._observations(res), infos))
            return
        schedule = self._kind.seeds(seed, None)
        if isinstance(seed, (int, np.integer)):
            super().reset(seed=int(seed))  # the vector env's own np_random
        if schedule is not None:
            core.set_seeds(schedule)
        core.send_reset()
        self._pending = Pending(Split.RESET)

    def reset_wait(self, timeout: Optional[float] = None) -> tuple[Any, dict[str, Any]]:
        """The second half of :meth:`reset_async`: wait at most ``timeout`` seconds (``None``:
        the pool's own bound) and return ``(obs, infos)``. On a timeout
        (``multiprocessing.TimeoutError``) the reset stays pending: call it again."""
        core = self._core
        core.check_open()
        partial = self._take_pending(Split.RESET)
        if partial is not None:
            return partial
        res = core.wait(timeout)
        if res is None:
            self._pending = Pending(Split.RESET)
            raise timed_out(Split.RESET, timeout)
        state = core.state
        state.restart()
        if state.log is not None:
            state.log.record(res, None, self._same_step)
        infos = copy_tree(self._infos(res))  # a reset's infos are the caller's to keep
        return self._observations(res), infos

    # -- step ------------------------------------------------------------------------------

    def step(self, actions: Any) -> StepResult:
        """Step every env with ``actions`` (a batch of the action space); returns ``(obs,
        rewards, terminations, truncations, infos)``. Rewards and flags are fresh arrays."""
        acts = self._step_actions(actions, "step")
        return self._stepped(self._core.step(acts), acts)

    def step_async(self, actions: Any) -> None:
        """The first half of :meth:`step` (gymnasium's ``AsyncVectorEnv.step_async``): send
        ``actions`` and return at once; the workers step while you do something else."""
        acts = self._step_actions(actions, "step_async")
        self._core.send_step(acts)
        self._pending = Pending(Split.STEP, acts)

    def step_wait(self, timeout: Optional[float] = None) -> StepResult:
        """The second half of :meth:`step_async`: wait at most ``timeout`` seconds (``None``:
        the pool's own bound) and return what :meth:`step` returns. On a timeout
        (``multiprocessing.TimeoutError``) the step stays pending: call it again."""
        self._core.check_open()
        acts = self._take_pending(Split.STEP)
        res = self._core.wait(timeout)
        if res is None:
            self._pending = Pending(Split.STEP, acts)
            raise timed_out(Split.STEP, timeout)
        return self._stepped(res, acts)

    def _step_actions(self, actions: Any, caller: str) -> np.ndarray:
        """Checks before a step; the actions as the pool takes them."""
        core = self._core
        core.check_open()
        if self._pending is not None:
            raise already_pending(caller, self._pending.what)
        if not core.state.started:
            raise RuntimeError("call reset() before step()")
        if self._disabled:
            refuse_finished(core.state.ended)
        return self._kind.actions(actions, None)

    def _stepped(self, res: Result, actions: np.ndarray) -> StepResult:
        """What a step returns, from the slot the workers wrote and its columns."""
        cols = res.cols
        state = self._core.state
        if state.log is not None:
            state.log.record(res, actions, self._same_step)
        infos = self._infos(res)
        terminated, truncated = cols["terminated"].copy(), cols["truncated"].copy()
        state.ended = terminated | truncated
        return self._observations(res), cols["reward"].copy(), terminated, truncated, infos

    def _infos(self, res: Result, only: Optional[np.ndarray] = None) -> dict[str, Any]:
        """A call's infos (``only``: a partial reset's mask): the kind's (SAME_STEP's final
        observations included), then what every kind reports (restarted and recycled workers,
        ``env_id`` for ``recv``). Read before the observations: a kind may complete those from
        its infos."""
        core = self._core
        try:
            infos = self._kind.infos(res, only)
        except CorruptInfoError as err:
            err.name_worker(*core.worker_of(err.env))
            raise
        if res.env_ids is not None:
            infos["env_id"] = res.env_ids
        restarted = res.restarted
        if restarted is not None:
            mark_restarted(infos, restarted)
            core.mark_recycled(infos, res.env_ids)
        return infos

    def _observations(self, res: Result) -> Any:
        """The observations of a call's rows, made whole where the kind needs it."""
        if res.slot is not None:
            obs = self._core.observations(res.slot)
            return obs if self._fill is None else self._fill(obs, None)
        assert res.obs is not None
        obs = self._kind.batch_views(res.obs)
        return obs if self._fill is None else self._fill(obs, res.env_ids)

    def _not_pending(self, caller: str) -> None:
        if self._pending is not None:
            raise already_pending(caller, self._pending.what)

    def _take_pending(self, what: Split) -> Any:
        """End the pending ``{what}_async`` (``NoAsyncCallError`` if there is none); what it
        left for its wait."""
        if self._pending is None or self._pending.what != what:
            raise no_async_call(what)
        left, self._pending = self._pending.done, None
        return left

    def episode_counters(self) -> tuple[np.ndarray, np.ndarray]:
        """``(episode_return, episode_length)`` of every env after the last call: in SAME_STEP,
        an env whose episode ended on that step shows the ended episode's."""
        slot = self._core.state.slot
        if slot is None:
            raise RuntimeError("call reset() first")
        cols = self._core.cols[slot]
        return cols["episode_return"].copy(), cols["episode_length"].copy()

    # -- EnvPool-style async API -----------------------------------------------------------

    def async_reset(self, seed: Seed = None) -> None:
        """Start resetting every env (seeded as by :meth:`reset`); collect the first
        observations with :meth:`recv`. Needs ``NEXT_STEP`` or ``SAME_STEP`` autoreset (in
        SAME_STEP, ``recv`` does not return the ended episodes' last observations)."""
        core = self._core
        core.check_open()
        self._not_pending("async_reset")
        if self._disabled:
            raise ValueError(
                "the async API (async_reset/send/recv) needs autoreset_mode NEXT_STEP or SAME_STEP"
            )
        schedule = self._kind.seeds(seed, None)
        if schedule is not None:
            core.set_seeds(schedule)
        core.async_reset()
        core.state.restart()

    def send(self, actions: Any, env_id: Optional[Any] = None) -> None:
        """Send ``actions`` (one row per env id) to the envs ``env_id`` (default: those of the
        last :meth:`recv`): any envs, each at most once until it is received. An env whose
        worker is busy with others of its envs goes with the worker's next command."""
        self._core.check_open()
        ids = self.call_state.last_ids if env_id is None else np.asarray(env_id)
        if ids is None:
            raise RuntimeError("send() needs env_id, or a previous recv() whose envs it answers")
        env_ids = np.atleast_1d(ids)
        if env_ids.dtype != np.int64:
            if env_ids.dtype.kind not in "iu" and env_ids.size:
                raise TypeError(f"env_id must be integers, got dtype {env_ids.dtype}")
            env_ids = env_ids.astype(np.int64)
        acts = self._kind.actions(actions, env_ids)
        self._core.send(acts, env_ids)
        if self.call_state.log is not None:
            self._taken[env_ids] = acts

    def recv(
        self,
        min_batch: Optional[int] = None,
        max_batch: Optional[int] = None,
        timeout: Optional[float] = None,
    ) -> StepResult:
        """The first envs ready, first ready first: ``(obs, rewards, terminations,
        truncations, infos)`` with ``infos["env_id"]`` naming the envs of the rows.

        By default exactly ``batch_size`` envs. ``max_batch``: return as soon as that many
        are ready (default ``batch_size``); ``timeout`` (seconds from the call): return then
        with every env ready (up to ``max_batch``) if at least ``min_batch`` are (default
        ``max_batch``; 1 or more), else raise ``TimeoutError`` with nothing lost. With no
        ``timeout`` it waits for ``min_batch`` and returns every env ready then (up to
        ``max_batch``). These are TorchRL ``AsyncEnvPool``'s ``min_get``, ``max_get`` and
        ``timeout``. The observations are a fresh copy.
        """
        core = self._core
        core.check_open()
        res = core.recv(min_batch, max_batch, timeout)
        assert res.env_ids is not None
        state = core.state
        state.last_ids = res.env_ids
        cols = res.cols
        terminated, truncated = cols["terminated"].copy(), cols["truncated"].copy()
        state.ended[res.env_ids] = terminated | truncated
        if state.log is not None:
            state.log.record(res, self._taken, self._same_step)
        infos = self._infos(res)
        return self._observations(res), cols["reward"].copy(), terminated, truncated, infos

    # -- calls -----------------------------------------------------------------------------

    def call_envs(
        self,
        op: str,
        name: str,
        arguments: Sequence[tuple[tuple[Any, ...], dict[str, Any]]],
        indices: Optional[Sequence[int]] = None,
    ) -> list[Any]:
        """Run call operation ``op`` (see :data:`rogue_gym.protocol.ops.ENV_OPS`) on the
        envs ``indices`` (default all), with ``arguments[j]`` = ``(args, kwargs)`` for the
        ``j``-th of them; their results in that order. An env's exception is re-raised here."""
        self._core.check_open()
        self._not_pending("call")
        envs = list(range(self.num_envs)) if indices is None else [int(i) for i in indices]
        if len(arguments) != len(envs):
            raise ValueError(f"{len(arguments)} argument sets for {len(envs)} envs")
        facts = self._kind.facts
        if op not in facts.ops:
            raise refuse_op(facts.who, op)
        return self._kind.run_ops(op, name, arguments, envs)

    def call_async(self, name: str, *args: Any, **kwargs: Any) -> None:
        """The first half of :meth:`call` (gymnasium's ``AsyncVectorEnv.call_async``). Env
        calls are off the hot path: the call runs here, whole, within the pool's bound, and
        :meth:`call_wait` returns its results (or raises its error)."""
        self._core.check_open()
        self._not_pending("call_async")
        try:
            done: tuple[str, Any] = ("ok", self.call(name, *args, **kwargs))
        except Exception as exc:  # raised by call_wait, as AsyncVectorEnv raises it there
            done = ("err", exc)
        self._pending = Pending(Split.CALL, done)

    def call_wait(self, timeout: Optional[float] = None) -> tuple[Any, ...]:
        """The second half of :meth:`call_async`: one result per env (``timeout`` is accepted
        for gymnasium's signature: the call has already run)."""
        self._core.check_open()
        status, value = self._take_pending(Split.CALL)
        if status == "err":
            raise value
        return value

    def _call_all(self, op: str, name: str, args: tuple[Any, ...] = (), **kwargs: Any) -> list[Any]:
        return self.call_envs(op, name, [(args, kwargs)] * self.num_envs)

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """``getattr(env, name)(*args, **kwargs)`` in every env (or the attribute itself if it
        is not callable); one result per env."""
        return tuple(self._call_all("call", name, args, **kwargs))

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

    def render(self) -> Optional[tuple[Any, ...]]:
        """Every env's frame in the render mode (see the kind: the native game rebuilds its
        screens by replay; hosted envs render in their workers)."""
        self._core.check_open()
        return self._kind.render()

    # -- close -----------------------------------------------------------------------------

    def close_extras(self, **kwargs: Any) -> None:
        """Stop the workers and remove the pool's shared-memory files (idempotent). A pending
        ``step_async`` or ``reset_async`` is abandoned with a warning."""
        core = getattr(self, "_core", None)
        if core is None:
            return
        if self._pending is not None and not core.closed:
            warn_close_pending(self._pending.what)
        self._pending = None
        core.close()

    def __del__(self) -> None:
        core = getattr(self, "_core", None)
        if core is not None:
            core.close()

    def __repr__(self) -> str:
        return f"{type(self).__name__}(num_envs={self.num_envs}, num_workers={self.num_workers})"
