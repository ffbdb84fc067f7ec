"""The pool under every vector env class, whatever env kind it hosts.

:class:`Core` owns the native pool (supervisor and worker processes) and what the caller side
keeps of it: the shared-memory batch slots the workers write observations into, one record
array and one column buffer per slot (the per-env rewards, flags and counters of the call that
wrote the slot), the SAME_STEP final-observation buffer, and the lending of slots
(:mod:`rogue_gym.front.leases`). It knows nothing of gymnasium's or SB3's API: the facades in
:mod:`rogue_gym.front` build those over it, and the env kind (:mod:`rogue_gym.kinds`, bound as
:class:`Kind`) turns slot bytes into observations and records into infos.
"""

from __future__ import annotations

import errno
import json
import weakref
from typing import Any, Callable, NoReturn, Optional, Protocol, Sequence

import numpy as np
from gymnasium import spaces

from .. import _native
from .._records import FLAG_FINAL_OBS, FLAG_RESTARTED, FLAG_TERMINATED, FLAG_TRUNCATED, RECORD_DTYPE
from ..errors import CLOSED_MESSAGE, EnvFailedError, PoolClosedError
from ..protocol.exceptions import decode_exception
from . import leases, sigterm
from .stats import PoolStats, WorkerStats

__all__ = [
    "SUMMARY_FINAL",
    "SUMMARY_RESTARTED",
    "Core",
    "Kind",
    "copy_tree",
    "flags",
    "mark_restarted",
    "raised_in_worker",
    "reraise",
    "row_of",
    "scalar_actions",
]

#: Bit of a step's summary: some env's worker was restarted during the call.
SUMMARY_RESTARTED: int = _native.SUMMARY_RESTARTED
#: Bit of a step's summary: some env has a final observation (SAME_STEP).
SUMMARY_FINAL: int = _native.SUMMARY_FINAL


class Kind(Protocol):
    """An env kind: its data, and the calls that differ from one kind to another.

    The step path calls :meth:`actions` and :meth:`step_infos` once per step, never anything
    per env.
    """

    @property
    def num_envs(self) -> int:
        """Envs in the pool."""
        ...

    @property
    def obs_bytes(self) -> int:
        """Bytes of one env's observation in a batch slot."""
        ...

    @property
    def single_observation_space(self) -> spaces.Space:
        """One env's observation space."""
        ...

    @property
    def single_action_space(self) -> spaces.Space:
        """One env's action space."""
        ...

    @property
    def metadata(self) -> dict[str, Any]:
        """The envs' ``metadata`` (render modes)."""
        ...

    @property
    def render_mode(self) -> Optional[str]:
        """The envs' render mode."""
        ...

    @property
    def spec(self) -> Any:
        """The envs' ``EnvSpec``, if any."""
        ...

    @property
    def who(self) -> str:
        """Who serves the env operations (a key of :data:`rogue_gym.protocol.ops.SERVED_BY`)."""
        ...

    @property
    def ops(self) -> frozenset[str]:
        """The env operations the kind serves."""
        ...

    @property
    def worker_command(self) -> Sequence[str]:
        """Program and leading args of a worker process."""
        ...

    def pool_settings(self) -> dict[str, Any]:
        """The native pool's settings (JSON object) but the autoreset mode and slot count."""
        ...

    def bind(self, core: Core) -> None:
        """Called once the pool runs (per-slot templates, the pool's info names)."""
        ...

    def batch_views(self, rows: np.ndarray) -> Any:
        """Observations of ``rows`` (``(k, obs_bytes)`` uint8) as a batch of the observation
        space, without a copy."""
        ...

    def obs_filler(self) -> Optional[Callable[[Any, Optional[np.ndarray]], Any]]:
        """``None`` when the slot's observations are whole; else the function that makes a
        batch of them (of every env, or of ``env_ids``) whole, after the call's infos were
        read: the values of leaves of no fixed size, which travel apart. Bound once, at
        construction: a kind without such leaves costs the hot path nothing."""
        ...

    def actions(self, actions: Any, env_ids: Optional[Sequence[int]]) -> np.ndarray:
        """A batch of actions (for every env, or ``env_ids``) checked, as the pool takes them:
        int64 indices or uint8 bytes."""
        ...

    def seed_schedule(self, seed: Any, core: Core) -> Optional[dict[str, Any]]:
        """The episode-seed schedule for ``reset(seed=seed)``; ``None`` keeps the current one.
        ``ValueError``/``TypeError`` for a seed the kind cannot take."""
        ...

    def seed_partial(self, seed: Any, mask: np.ndarray, core: Core) -> None:
        """Seed the next reset of the envs of ``mask`` (a partial reset with ``seed``: an int
        ``s`` seeds env ``i`` with ``s + i``, a list gives each env's); a ``ValueError`` for a
        kind whose seeds cannot be set per env."""
        ...

    def reset_infos(self, core: Core, slot: int, only: Optional[np.ndarray]) -> dict[str, Any]:
        """The infos of a reset of every env, or of the envs of ``only`` (a partial reset)."""
        ...

    def step_infos(self, core: Core, slot: int, summary: int, same_step: bool) -> dict[str, Any]:
        """The infos of a step (``final_obs``/``final_info`` in SAME_STEP, ``worker_restarted``)."""
        ...

    def recv_infos(
        self,
        core: Core,
        recs: np.ndarray,
        env_extras: list[tuple[int, bytes]],
        env_id: np.ndarray,
    ) -> dict[str, Any]:
        """The infos of an async ``recv`` batch (rows in ``env_id`` order; ``env_extras``:
        the ``(env id, bytes)`` of envs that wrote extra info)."""
        ...

    def call(
        self,
        core: Core,
        op: str,
        name: str,
        arguments: Sequence[tuple[tuple[Any, ...], dict[str, Any]]],
        indices: Sequence[int],
    ) -> list[Any]:
        """Run call operation ``op`` (:data:`rogue_gym.protocol.ops.ENV_OPS`) on the envs
        ``indices`` with ``arguments[j]`` for the ``j``-th; one result each."""
        ...

    def info_counts(self) -> tuple[int, int]:
        """Env info rows received so far as typed rows and as pickles (``stats()``)."""
        ...

    def render(self, core: Core) -> Optional[tuple[Any, ...]]:
        """Every env's frame in the render mode."""
        ...


class Core:
    """The native pool of one vector env, its batch slots, records and column buffers.

    Args:
        kind: the env kind (spaces, settings, observation views).
        same_step: SAME_STEP autoreset (the workers keep each ended episode's last
            observation, read with :meth:`final_obs`).
        copy: the facade hands out observations that are the caller's to keep; large batches
            are then lent (the slot is not written again while a returned array lives) rather
            than copied.
    """

    def __init__(self, kind: Kind, *, same_step: bool, copy: bool) -> None:
        self.kind = kind
        self.num_envs = n = kind.num_envs
        self.obs_bytes = kind.obs_bytes
        self.copy = bool(copy)
        #: SAME_STEP autoreset (else NEXT_STEP).
        self.same_step = bool(same_step)
        lend = self.copy and n * self.obs_bytes >= leases.LEND_MIN_BYTES
        settings = kind.pool_settings()
        settings["autoreset"] = "same_step" if same_step else "next_step"
        sigterm.install()
        try:
            try:
                self.pool: Any = _native.Pool(json.dumps(settings), list(kind.worker_command))
            except OSError as err:
                if not (settings.get("batch_slots") and err.errno == errno.ENOSPC):
                    raise
                # /dev/shm has no room for the slots asked for: the default two (lending every
                # other batch of a loop); still too big: the error.
                settings["batch_slots"] = None
                self.pool = _native.Pool(json.dumps(settings), list(kind.worker_command))
        except EnvFailedError as err:
            reraise(err)
        self._finalizer = weakref.finalize(self, _native.Pool.close, self.pool)
        self.closed = False
        #: The pool's name: the prefix of its shared-memory files.
        self.name: str = self.pool.name()
        self.num_workers: int = int(self.pool.num_workers)
        self.slots = [np.asarray(v).reshape(n, self.obs_bytes) for v in self.pool.shared_views()]
        self.views = [kind.batch_views(s) for s in self.slots]
        self.lender = leases.SlotLender(self.slots, kind.batch_views) if lend else None
        self.final = np.zeros((n, self.obs_bytes), np.uint8) if same_step else None
        # One record array per slot (the call that wrote the slot), and one to write next.
        self.recs = [np.zeros(n, RECORD_DTYPE) for _ in self.slots]
        self._next_recs = np.zeros(n, RECORD_DTYPE)
        self.cols = self._bind_columns()
        #: The slot written by the last call.
        self.slot = 0
        #: No reset or step since the pool started.
        self.fresh = True
        #: Observation batches handed out: lent, copied, or as views (``stats()``).
        self.lent = self.copied = self.viewed = 0
        kind.bind(self)

    def _bind_columns(self) -> list[dict[str, np.ndarray]]:
        """One column buffer per slot, bound in the native pool (see ``step_columns``):
        per-env rewards, flags, counters and info rows, decoded from the slot's records."""
        n = self.num_envs
        layout, total = self.pool.column_layout()
        buffers, out = [], []
        for _ in self.slots:
            buf = np.zeros(total, np.uint8)
            cols: dict[str, np.ndarray] = {}
            for name, dt, off, rows in layout:
                col = buf[off : off + rows * n * np.dtype(dt).itemsize].view(dt)
                cols[name] = col.reshape(rows, n) if name.startswith("info_") else col
            # Seeds cross as int64 (torch has no uint64): seeds >= 2**63 read as seed - 2**64.
            cols["seed"] = cols["seed"].view(np.int64)
            buffers.append(buf)
            out.append(cols)
        self.pool.bind_columns(buffers)
        return out

    # -- calls -----------------------------------------------------------------------------

    def check_open(self) -> None:
        """``PoolClosedError`` once closed."""
        if self.closed:
            raise PoolClosedError(CLOSED_MESSAGE)

    def call(self, fn: Callable[..., Any], *args: Any) -> Any:
        """Run a native call; an env's own exception is re-raised as itself."""
        try:
            return fn(*args)
        except EnvFailedError as err:
            reraise(err)

    def _steer(self) -> None:
        """Make the next slot-writing call write a slot no lent array still uses."""
        if self.lender is not None:
            free = self.lender.steer()
            if free is not None:
                self.call(self.pool.select_slot, free)

    def _took(self, slot: int) -> int:
        """Book the slot a call wrote: its records are the ones just written."""
        self.recs[slot], self._next_recs = self._next_recs, self.recs[slot]
        self.slot = slot
        self.fresh = False
        return slot

    def step(self, actions: np.ndarray) -> int:
        """A whole sync step: the slot written ``|`` the ``SUMMARY_*`` bits; the slot's columns
        hold the decoded records."""
        self._steer()
        r = self.call(self.pool.step_columns, actions, self._next_recs, self.final)
        self._took(r & 0xFF)
        return int(r)

    def send_step(self, actions: np.ndarray) -> None:
        """The first half of :meth:`step`: the workers step while the caller goes on."""
        self._steer()
        self.call(self.pool.step_shared_send, actions)

    def wait_step(self, timeout: Optional[float]) -> Optional[int]:
        """The second half of :meth:`send_step`: what :meth:`step` returns, or ``None`` when
        ``timeout`` seconds passed first (the step stays pending)."""
        r = self.call(self.pool.wait_columns, timeout, self._next_recs, self.final)
        if r is None:
            return None
        self._took(r & 0xFF)
        return int(r)

    def send_reset(self) -> None:
        """The first half of a full reset."""
        self._steer()
        self.call(self.pool.reset_shared_send)

    def wait_reset(self, timeout: Optional[float]) -> Optional[int]:
        """The second half of :meth:`send_reset`: the slot, or ``None`` on ``timeout``."""
        slot = self.call(self.pool.wait_shared, timeout, self._next_recs, None)
        return None if slot is None else self._took(int(slot))

    def reset_envs(self, mask: np.ndarray) -> int:
        """A partial reset (the envs of ``mask``; the others' observations written again)."""
        self._steer()
        return self._took(int(self.call(self.pool.reset_envs_shared, mask, self._next_recs)))

    def set_seeds(self, schedule: dict[str, Any]) -> None:
        """Replace the episode-seed schedule (applies from the next reset)."""
        self.call(self.pool.set_seeds, json.dumps(schedule))

    def observations(self, slot: int) -> Any:
        """The observations of ``slot`` as the facade returns them: lent, copied
        (``copy=True``), or views of shared memory."""
        if self.lender is not None:
            lent = self.lender.lend(slot)
            if lent is None:
                self.copied += 1
                return copy_tree(self.views[slot])
            self.lent += 1
            return lent
        if self.copy:
            self.copied += 1
            return copy_tree(self.views[slot])
        self.viewed += 1
        return self.views[slot]

    def final_obs(self, env: int) -> Any:
        """(SAME_STEP) env ``env``'s final observation of the last call, a fresh copy."""
        assert self.final is not None
        return copy_tree(row_of(self.kind.batch_views(self.final[env : env + 1]), 0))

    # -- async (EnvPool-style) -------------------------------------------------------------

    def async_reset(self) -> None:
        """Start resetting every env; collect with :meth:`recv`."""
        self.call(self.pool.async_reset)

    def send(self, actions: np.ndarray, env_ids: Sequence[int]) -> None:
        """Send actions to any envs (each at most once until received)."""
        self.call(self.pool.send, actions, list(env_ids))

    def recv(
        self,
        min_batch: Optional[int] = None,
        max_batch: Optional[int] = None,
        timeout: Optional[float] = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[tuple[int, bytes]]]:
        """The first envs ready: ``(obs rows, records, env ids, extras)``, the rows a fresh
        copy; ``extras`` are the ``(env id, bytes)`` of envs that wrote extra info."""
        ids, raw, recs, extras = self.call(self.pool.recv, min_batch, max_batch, timeout)
        rows = raw.reshape(-1, self.obs_bytes)
        return rows, np.frombuffer(recs, RECORD_DTYPE), ids, extras

    def mark_recycled(self, infos: dict[str, Any]) -> None:
        """Flag the restarted envs whose worker was replaced by plan during the last call
        (``worker_recycled`` and its mask); asked of the pool only when some env restarted."""
        if "worker_restarted" not in infos:
            return
        ids = self.pool.recycled_envs()
        if ids:
            mask = np.isin(self._env_ids(infos), ids)
            infos["worker_recycled"] = mask
            infos["_worker_recycled"] = mask.copy()

    @staticmethod
    def _env_ids(infos: dict[str, Any]) -> np.ndarray:
        """The env of each row of a call's infos: ``env_id`` (recv), else every env."""
        return np.asarray(infos.get("env_id", np.arange(len(infos["worker_restarted"]))))

    # -- the pool --------------------------------------------------------------------------

    def stats(self) -> PoolStats:
        """The counters since the pool started (see :mod:`rogue_gym.front.stats`)."""
        workers, between_ns, inside_ns, calls = self.pool.stats()
        typed, pickled = self.kind.info_counts()
        return PoolStats(
            seconds=(between_ns + inside_ns) / 1e9,
            caller_s=between_ns / 1e9,
            waiting_s=inside_ns / 1e9,
            calls=int(calls),
            workers=tuple(WorkerStats.from_native(w) for w in workers),
            info_rows_typed=typed,
            info_rows_pickled=pickled,
            batches_lent=self.lent,
            batches_copied=self.copied,
            batches_viewed=self.viewed,
            shm_bytes=int(self.pool.shm_bytes()),
        )

    @property
    def worker_pids(self) -> list[int]:
        """Process ids of the workers (in worker order); empty once closed."""
        return [] if self.closed else list(self.pool.worker_pids())

    @property
    def restarts(self) -> int:
        """Worker restarts so far."""
        return int(self.pool.restarts())

    def envs_of_worker(self, worker: int) -> range:
        """Indices of the envs hosted by ``worker``."""
        self.check_open()
        return range(*self.pool.worker_envs(worker))

    def close(self) -> None:
        """Stop the workers and remove the pool's files (idempotent)."""
        self.closed = True
        self._finalizer()


def flags(recs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(terminated, truncated, restarted, has_final_obs)`` bool arrays of a record batch."""
    f = recs["flags"]
    return (
        (f & FLAG_TERMINATED) != 0,
        (f & FLAG_TRUNCATED) != 0,
        (f & FLAG_RESTARTED) != 0,
        (f & FLAG_FINAL_OBS) != 0,
    )


def scalar_actions(n: int) -> str:
    """The message of a ``TypeError`` for one action given to a vector env of ``n`` envs (as
    gymnasium's vector envs refuse it)."""
    return (
        f"expected a batch of actions, one per env ({n}), got a scalar: a vector env takes "
        "an array of shape (num_envs, ...)"
    )


def mark_restarted(infos: dict[str, Any], restarted: Optional[np.ndarray]) -> None:
    """Flag the envs whose worker was restarted during the call (``worker_restarted`` and its
    mask), if any: every kind and call reports them so."""
    if restarted is not None and restarted.any():
        infos["worker_restarted"] = restarted.copy()
        infos["_worker_restarted"] = restarted.copy()


def copy_tree(value: Any) -> Any:
    """A copy of a batch (an array, or a dict / tuple of them; anything else is kept)."""
    if isinstance(value, dict):
        return {k: copy_tree(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return tuple(copy_tree(v) for v in value)
    return value.copy() if isinstance(value, np.ndarray) else value


def row_of(tree: Any, i: int) -> Any:
    """Row ``i`` of a batch tree (a dict / tuple of arrays; anything else is kept)."""
    if isinstance(tree, dict):
        return {k: row_of(v, i) for k, v in tree.items()}
    if isinstance(tree, tuple):
        return tuple(row_of(v, i) for v in tree)
    return tree[i] if isinstance(tree, np.ndarray) else tree


def raised_in_worker(detail: str, where: str) -> Optional[BaseException]:
    """The env's exception encoded in ``detail`` (by the worker's adapter), with a note (Python
    3.11+) saying ``where`` it was raised and the worker-side traceback; ``None`` if ``detail``
    is no such encoding."""
    decoded = decode_exception(detail)
    if decoded is None:
        return None
    exc, tb = decoded
    if hasattr(exc, "add_note"):
        exc.add_note(f"raised by {where}. Worker-side traceback:\n{tb}")
    return exc


def env_exception(err: BaseException) -> BaseException:
    """The env's own exception carried by an ``EnvFailedError`` (with the worker-side traceback
    as a note on Python 3.11+), or ``err`` itself if it carries none."""
    if not isinstance(err, EnvFailedError):
        return err
    where = (
        f"env {err.env} during {err.context} in worker {err.worker} (pid {err.pid}); call "
        "reset() to continue"
    )
    return raised_in_worker(err.detail, where) or err


def reraise(err: EnvFailedError) -> NoReturn:
    """Raise the env's own exception carried by ``err``. When several envs or workers failed
    in the same call, the first is raised and the others (decoded too) are in its ``others``
    attribute, one note each on Python 3.11+; one ``reset()`` clears them all."""
    exc = env_exception(err)
    others = [env_exception(o) for o in getattr(err, "others", [])]
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
