"""``RayVectorEnv``: a gymnasium vector env in the driver whose envs live in Ray actors.

Each actor (:class:`rogue_gym.ray.actor.PoolActor`) owns one pool on its node and a contiguous
block of the global envs. ``step`` fans the actions out to the actors and gathers their batches
in env order; ``send``/``recv`` do the same without waiting for the slowest actor. A lost actor
(killed, or its node gone) is recreated with the same envs: they report ``truncated=True`` and
``infos["actor_restarted"]`` and start new episodes. Worker failures inside a node are the
pool's own business (``on_worker_failure``), as on one machine.
"""

from __future__ import annotations

import contextlib
import time
import weakref
from typing import Any, Optional, Sequence

import numpy as np
import ray
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from ray.exceptions import GetTimeoutError, RayActorError

from .. import _native
from ..registration import ENV_ID
from ..settings import parse_autoreset_mode
from .actor import EnvLike, PoolActor, is_native

__all__ = ["RayVectorEnv"]

#: Seconds ``close`` waits for an actor to close its pool before it kills the actor.
CLOSE_TIMEOUT_S = 10.0

_RemoteActor = ray.remote(PoolActor)


def merge_infos(parts: Sequence[dict[str, Any]], sizes: Sequence[int]) -> dict[str, Any]:
    """Join per-actor vector infos (dicts of arrays with ``_key`` masks) into one, in order."""
    if len(parts) == 1:
        return parts[0]
    total = int(sum(sizes))
    starts = np.cumsum([0, *sizes])
    out: dict[str, Any] = {}
    keys = [k for k in dict.fromkeys(k for p in parts for k in p) if not k.startswith("_")]
    for key in keys:
        values = [p.get(key) for p in parts]
        mask = np.zeros(total, bool)
        for p, v, a, b in zip(parts, values, starts[:-1], starts[1:]):
            if v is not None:
                mask[a:b] = p.get("_" + key, True)
        if all(v is None or isinstance(v, dict) for v in values):
            out[key] = merge_infos([v or {} for v in values], sizes)
        else:
            arrays = [np.asarray(v) for v in values if v is not None]
            joined = np.zeros(total, np.result_type(*arrays))
            for v, a, b in zip(values, starts[:-1], starts[1:]):
                if v is not None:
                    joined[a:b] = v
            out[key] = joined
        out["_" + key] = mask
    return out


def _close_actors(actors: list[Any]) -> None:
    """Ask each actor to close its pool (bounded wait), then end it. Nothing to do once Ray is
    shut down: that ends the actors, and their pools with them."""
    if not ray.is_initialized():
        return
    pending = []
    for a in actors:
        with contextlib.suppress(Exception):  # an actor already gone
            pending.append(a.close.remote())
    with contextlib.suppress(Exception):
        ray.wait(pending, num_returns=len(pending), timeout=CLOSE_TIMEOUT_S)
    for a in actors:
        with contextlib.suppress(Exception):
            ray.kill(a, no_restart=True)


class RayVectorEnv(VectorEnv):
    """``num_envs`` envs in ``num_actors`` Ray actors, one pool per actor, as one vector env.

    Example::

        ray.init()
        envs = RayVectorEnv("RogueGym-v0", 64, num_actors=4, seed=0, num_workers=8)
        obs, infos = envs.reset(seed=0)
        obs, rewards, terminations, truncations, infos = envs.step(envs.action_space.sample())
        envs.close()

    Args:
        env: ``"RogueGym-v0"`` (the native game) or a gymnasium id or env callable (hosted
            Python envs), as for :func:`rogue_gym.make_vec`.
        num_envs: envs in all; actor ``k`` holds a contiguous block (the blocks differ by at
            most one env).
        num_actors: Ray actors (pools).
        seed: base seed; ``reset(seed=s)`` overrides it. Env ``g``'s episodes are those env
            ``g`` of one local pool of ``num_envs`` envs plays with the same seed.
        step_timeout: seconds to wait for an actor's batch before it counts as lost.
        max_actor_restarts: recreated actors allowed over the env's life; past it, the loss
            is raised.
        actor_options: Ray options of each actor (``num_cpus``, ``resources``,
            ``scheduling_strategy``, ...); ``num_cpus`` defaults to the pool's ``num_workers``
            (1 if unset).
        **pool_options: options of each actor's pool (``num_workers``, ``obs``, ``config``,
            ...). Autoreset is NEXT_STEP.

    Arrays: observations cross the node boundary through Ray's object store. With one actor,
    ``obs`` is the object store's read-only array; with more, a fresh array.
    """

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.NEXT_STEP}  # noqa: RUF012

    def __init__(
        self,
        env: EnvLike = ENV_ID,
        num_envs: int = 8,
        *,
        num_actors: int = 2,
        seed: Optional[int] = None,
        step_timeout: Optional[float] = 120.0,
        max_actor_restarts: int = 100,
        actor_options: Optional[dict[str, Any]] = None,
        **pool_options: Any,
    ) -> None:
        if not 1 <= int(num_actors) <= int(num_envs):
            raise ValueError(f"num_actors must be in [1, num_envs={num_envs}], got {num_actors}")
        if not ray.is_initialized():
            raise RuntimeError("RayVectorEnv needs a Ray cluster: call ray.init() first")
        mode = pool_options.get("autoreset_mode", AutoresetMode.NEXT_STEP)
        parse_autoreset_mode(mode, (AutoresetMode.NEXT_STEP,))  # the actors' mode
        self.env = env
        self.num_envs = int(num_envs)
        if seed is None:
            seed = int(np.random.SeedSequence().generate_state(1, np.uint64)[0] >> 2)
        self.seed = int(seed)
        self.step_timeout = step_timeout
        self.max_actor_restarts = int(max_actor_restarts)
        self.actor_restarts = 0
        self._options = dict(pool_options)
        if is_native(env):
            self._options["seed"] = self.seed
        opts = dict(actor_options or {})
        opts.setdefault("num_cpus", int(self._options.get("num_workers") or 1))
        self._actor_options = opts
        self.blocks = [
            _native.block_range(self.num_envs, int(num_actors), k) for k in range(int(num_actors))
        ]
        self._closed = True  # until the actors are up
        self._actors: list[Any] = [self._spawn(k) for k in range(len(self.blocks))]
        self._finalizer = weakref.finalize(self, _close_actors, list(self._actors))
        try:
            self._get([a.pid.remote() for a in self._actors])  # every actor up
            single_obs, single_act = self._get(self._actors[0].spaces.remote())
        except GetTimeoutError:
            self._finalizer()
            raise RuntimeError(
                f"the {len(self.blocks)} pool actors did not start within step_timeout="
                f"{self.step_timeout} s; each asks for {self._actor_options} and the cluster "
                f"has {ray.available_resources()} free: lower num_workers or actor_options, or "
                "add nodes"
            ) from None
        except BaseException:
            self._finalizer()
            raise
        self.single_observation_space = single_obs
        self.single_action_space = single_act
        self.observation_space = batch_space(single_obs, self.num_envs)
        self.action_space = batch_space(single_act, self.num_envs)
        self.autoreset_mode = AutoresetMode.NEXT_STEP
        self._last_obs: list[Optional[np.ndarray]] = [None] * len(self.blocks)
        self._pending: dict[int, Any] = {}
        self._async_ids: Optional[np.ndarray] = None
        self._closed = False

    # ------------------------------------------------------------------------------------
    @property
    def num_actors(self) -> int:
        """The number of actors (pools)."""
        return len(self.blocks)

    @property
    def in_flight(self) -> int:
        """Envs sent actions by :meth:`send` whose results :meth:`recv` has not returned."""
        return sum(self.blocks[k][1] - self.blocks[k][0] for k in self._pending)

    def _spawn(self, k: int) -> Any:
        a, b = self.blocks[k]
        return _RemoteActor.options(**self._actor_options).remote(
            self.env, a, b - a, self.num_envs, self._options
        )

    def _get(self, ref: Any) -> Any:
        return ray.get(ref, timeout=self.step_timeout)

    def _restart(self, k: int, cause: BaseException) -> tuple[np.ndarray, dict[str, Any]]:
        """Replace lost actor ``k`` and reset its envs (from a seed of its own); the infos
        carry ``actor_restarted`` for each of them."""
        if self.actor_restarts >= self.max_actor_restarts:
            raise RuntimeError(
                f"actor {k} (envs {self.blocks[k][0]}..{self.blocks[k][1] - 1}) was lost and "
                f"the restart budget max_actor_restarts={self.max_actor_restarts} is spent: "
                f"{cause}"
            ) from cause
        self.actor_restarts += 1
        with contextlib.suppress(Exception):  # it is gone already
            ray.kill(self._actors[k], no_restart=True)
        self._actors[k] = self._spawn(k)
        self._finalizer.detach()
        self._finalizer = weakref.finalize(self, _close_actors, list(self._actors))
        seed = int(np.random.SeedSequence([self.seed, k, self.actor_restarts]).generate_state(1)[0])
        obs, infos = self._get(self._actors[k].reset.remote(seed, None))
        flag = np.ones(len(obs), bool)
        return obs, {**infos, "actor_restarted": flag, "_actor_restarted": flag.copy()}

    def _gather(self, refs: dict[int, Any]) -> dict[int, tuple]:
        """Each actor's result; a lost actor's envs come back reset and truncated."""
        out: dict[int, tuple] = {}
        deadline = None if self.step_timeout is None else time.monotonic() + self.step_timeout
        for k, ref in refs.items():
            try:
                left = None if deadline is None else max(0.0, deadline - time.monotonic())
                out[k] = ray.get(ref, timeout=left)
            except (RayActorError, GetTimeoutError) as e:
                obs, infos = self._restart(k, e)
                n = len(obs)
                out[k] = (obs, np.zeros(n), np.zeros(n, bool), np.ones(n, bool), infos)
        return out

    def _split(self, actions: Any) -> list[Any]:
        acts = np.asarray(actions)
        if acts.shape[:1] != (self.num_envs,):
            raise ValueError(
                f"expected one action per env ({self.num_envs}), got an array of shape {acts.shape}"
            )
        return [acts[a:b] for a, b in self.blocks]

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("the RayVectorEnv is closed")

    # ------------------------------------------------------------------------------------
    def reset(
        self, *, seed: Optional[int] = None, options: Optional[dict[str, Any]] = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every env (``seed``: the global base seed), or ``options["reset_mask"]``'s."""
        self._check_open()
        self._pending.clear()
        self._async_ids = None
        if seed is not None:
            self.seed = int(seed)
        mask = (options or {}).get("reset_mask")
        refs = {}
        for k, (a, b) in enumerate(self.blocks):
            opts = options
            if mask is not None:
                part = np.asarray(mask, bool)[a:b]
                if not part.any():
                    continue
                opts = {**options, "reset_mask": part} if options else None
            refs[k] = self._actors[k].reset.remote(seed, opts)
        got = {}
        for k, ref in refs.items():
            try:
                got[k] = self._get(ref)
            except (RayActorError, GetTimeoutError) as e:
                got[k] = self._restart(k, e)
        parts_obs, parts_info, sizes = [], [], []
        for k, (a, b) in enumerate(self.blocks):
            if k in got:
                obs, infos = got[k]
                self._last_obs[k] = obs
            else:
                last = self._last_obs[k]
                if last is None:
                    raise RuntimeError("reset with a reset_mask needs a full reset() before it")
                obs, infos = last, {}
            parts_obs.append(obs)
            parts_info.append(infos)
            sizes.append(b - a)
        return self._concat(parts_obs), merge_infos(parts_info, sizes)

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every env: the actions fan out to the actors, the batches come back in order."""
        self._check_open()
        if self._pending:
            raise RuntimeError("step() while send() results are pending: recv() them first")
        refs = {k: self._actors[k].step.remote(part) for k, part in enumerate(self._split(actions))}
        return self._join(self._gather(refs))

    def _join(
        self, out: dict[int, tuple]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        ks = sorted(out)
        for k in ks:
            self._last_obs[k] = out[k][0]
        sizes = [self.blocks[k][1] - self.blocks[k][0] for k in ks]
        return (
            self._concat([out[k][0] for k in ks]),
            np.concatenate([np.asarray(out[k][1], np.float64) for k in ks]),
            np.concatenate([out[k][2] for k in ks]),
            np.concatenate([out[k][3] for k in ks]),
            merge_infos([out[k][4] for k in ks], sizes),
        )

    @staticmethod
    def _concat(parts: list[Any]) -> np.ndarray:
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    # ------------------------------------------------------------------------------------
    # Async: whole actor blocks
    def send(self, actions: Any, env_id: Optional[Any] = None) -> None:
        """Send ``actions[r]`` to env ``env_id[r]``; ``env_id`` must consist of whole actor
        blocks. Default: the envs of the last :meth:`recv`, or every env before the first."""
        self._check_open()
        last = self._async_ids
        if env_id is not None:
            ids = np.asarray(env_id, np.int64)
        else:
            ids = last if last is not None else np.arange(self.num_envs)
        acts = np.asarray(actions)
        if acts.shape[:1] != ids.shape:
            raise ValueError(f"expected {ids.shape[0]} actions (one per env id), got {acts.shape}")
        starts = {a: k for k, (a, _) in enumerate(self.blocks)}
        sends, row = {}, 0
        while row < len(ids):
            k = starts.get(int(ids[row]), -1)
            a, b = self.blocks[k] if k >= 0 else (0, 0)
            if (
                k < 0
                or k in self._pending
                or k in sends
                or not np.array_equal(ids[row : row + b - a], np.arange(a, b))
            ):
                raise ValueError(
                    f"env_id must be whole actor blocks {self.blocks}, none pending; got {ids}"
                )
            sends[k] = acts[row : row + b - a]
            row += b - a
        for k, part in sends.items():
            self._pending[k] = self._actors[k].step.remote(part)
        self._async_ids = None

    def recv(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """The batches of every actor done so far (at least one), in env order, with
        ``infos["env_id"]`` naming the rows."""
        self._check_open()
        if not self._pending:
            raise RuntimeError("recv() with nothing sent: send() actions first")
        refs = list(self._pending.values())
        ready, _ = ray.wait(refs, num_returns=1, timeout=self.step_timeout)
        ready_set = set(ready) if ready else set(refs)  # none ready in time: let _gather judge
        done = {k: r for k, r in self._pending.items() if r in ready_set}
        for k in done:
            del self._pending[k]
        out = self._join(self._gather(done))
        ids = np.concatenate([np.arange(*self.blocks[k]) for k in sorted(done)])
        self._async_ids = ids
        out[4]["env_id"] = ids
        return out

    # ------------------------------------------------------------------------------------
    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """``call`` on every env, in env order."""
        self._check_open()
        parts = self._get([a.call.remote(name, args, kwargs) for a in self._actors])
        return tuple(x for part in parts for x in part)

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """An attribute of every env, in env order."""
        return self.call(name)

    def actor_pids(self) -> list[int]:
        """The process id of each actor."""
        return list(self._get([a.pid.remote() for a in self._actors]))

    def close(self, **kwargs: Any) -> None:
        """Close every actor's pool and end the actors (idempotent)."""
        if getattr(self, "_closed", True):
            return
        self._closed = True
        self._finalizer.detach()
        _close_actors(self._actors)
