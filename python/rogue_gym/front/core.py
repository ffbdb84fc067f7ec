"""The pool under every vector env class, whatever env kind it hosts.

:class:`Core` owns the native pool (supervisor and worker processes) and what the caller side
keeps of it: views of the shared-memory batch slots, where the workers write every per-env
output of a whole-batch call in place (observations, the columns of rewards, flags, counters
and info values, SAME_STEP final observations, extra info), the column buffer of ``recv``,
the lending of slots
(:mod:`rogue_gym.front.leases`), and the call lifecycle every kind shares
(:attr:`Core.state`, a :class:`rogue_gym.kinds.view.CallState`). Every call returns one
:class:`rogue_gym.kinds.result.Result`. It knows nothing of gymnasium's or SB3's API: the
facades in :mod:`rogue_gym.front` build those over it, and the env kind
(:mod:`rogue_gym.kinds`), reading the pool through its view
(:class:`rogue_gym.front.pool_view.CoreView`), turns slot bytes into observations and columns
into infos.
"""

from __future__ import annotations

import errno
import json
import weakref
from typing import TYPE_CHECKING, Any, Optional

import numpy as np

from .. import _native
from ..errors import CLOSED_MESSAGE, EnvFailedError, PoolClosedError
from ..kinds.episode_log import EpisodeLog
from ..kinds.result import Extras, Result, copy_tree
from ..kinds.view import CallState, PoolLayout
from . import leases, sigterm
from .pool_view import CoreView
from .stats import PoolStats, WorkerStats
from .worker_errors import native_call, reraise

if TYPE_CHECKING:
    from ..kinds.spec import Kind

__all__ = ["Core", "mark_restarted"]


class Core:
    """The native pool of one vector env, its batch slots, column buffers and call lifecycle.

    Args:
        kind: the env kind (spaces, settings, observation views).
        same_step: SAME_STEP autoreset (the workers keep each ended episode's last
            observation, read with :meth:`final_obs`).
        copy: the facade hands out observations that are the caller's to keep; large batches
            are then lent (the slot is not written again while a returned array lives) rather
            than copied.
    The kind's ``facts.log_steps`` (not ``None``: it renders by replay) has each env's actions
    since its episode began kept in the call state's ``log``, for episodes of up to that many
    steps.
    """

    def __init__(self, kind: Kind, *, same_step: bool, copy: bool) -> None:
        self.kind = kind
        facts = kind.facts
        self.num_envs = n = facts.num_envs
        self.copy = bool(copy)
        #: SAME_STEP autoreset (else NEXT_STEP).
        self.same_step = bool(same_step)
        settings = kind.pool_settings()
        settings["autoreset"] = "same_step" if same_step else "next_step"
        sigterm.install()
        try:
            try:
                self.pool: Any = _native.Pool(json.dumps(settings), list(facts.worker_command))
            except OSError as err:
                if not (settings.get("batch_slots") and err.errno == errno.ENOMEM):
                    raise
                # No memory for the slots asked for: the default two (lending every other
                # batch of a loop); still too big: the error.
                settings["batch_slots"] = None
                self.pool = _native.Pool(json.dumps(settings), list(facts.worker_command))
        except EnvFailedError as err:
            reraise(err)
        self._finalizer = weakref.finalize(self, _native.Pool.close, self.pool)
        self.closed = False
        #: The pool's name: the prefix of its shared-memory files.
        self.name: str = self.pool.name()
        self.num_workers: int = int(self.pool.num_workers)
        #: Bytes of one env's observation in a batch slot.
        self.obs_bytes: int = int(self.pool.obs_bytes)
        lend = self.copy and n * self.obs_bytes >= leases.LEND_MIN_BYTES
        areas = self.pool.slot_views()
        #: Each batch slot's observations as the workers write them (``num_envs x obs_bytes``).
        self.slots = [np.asarray(a[0]).reshape(n, self.obs_bytes) for a in areas]
        self.views = [kind.batch_views(s) for s in self.slots]
        self.lender = leases.SlotLender(self.slots, kind.batch_views) if lend else None
        #: (SAME_STEP) each slot's final observations, written in place by the workers.
        self.finals = [
            None if a[2] is None else np.asarray(a[2]).reshape(n, self.obs_bytes) for a in areas
        ]
        #: Each slot's extra-info room (``num_envs x extra_bytes``), or ``None``.
        self.extra_rooms = [
            None if a[3] is None else np.asarray(a[3]).reshape(n, -1) for a in areas
        ]
        #: One env's observation as the workers write it, info value names, batch slots.
        self.layout = PoolLayout(
            tuple(self.pool.obs_shape),
            str(self.pool.obs_dtype),
            tuple(self.pool.info_names),
            len(areas),
        )
        columns, total = self.pool.column_layout()
        #: Each slot's columns (the per-env values the workers wrote in place), then ``recv``'s.
        self.cols = [self._columns(np.asarray(a[1]), columns) for a in areas]
        recv = np.zeros(total, np.uint8)
        self.pool.bind_recv_columns(recv)
        self.cols.append(self._columns(recv, columns))
        # ``recv`` hands rows that are one run of envs in one slot out as views, unless slots
        # are lent out: the lender's caller keeps copies, and each async call tells the pool
        # which slots are lent (no answer is written in a lent slot).
        self.pool.async_views(self.lender is None)
        #: The last call's result (``None`` before the first).
        self.last: Optional[Result] = None
        self._views: dict[tuple[int, int, int], tuple[dict[str, np.ndarray], Any]] = {}
        #: The call lifecycle: written by the facades, read by the kind through its view.
        self.state = CallState(n)
        if facts.log_steps is not None:
            self.state.log = EpisodeLog(n, facts.log_steps)
        #: Observation batches handed out: lent, copied, or as views (``stats()``).
        self.lent = self.copied = self.viewed = 0
        #: The pool as the kind reads it (no reference back to this object).
        self.view = CoreView(
            self.pool,
            copy=self.copy,
            same_step=self.same_step,
            layout=self.layout,
            state=self.state,
            cols=self.cols,
            finals=self.finals,
        )
        kind.bind(self.view)

    def _columns(
        self, area: np.ndarray, layout: list[tuple[str, str, int, int, int]]
    ) -> dict[str, Any]:
        """Views of the columns in ``area`` (a slot's columns area, or the ``recv`` buffer):
        per-env rewards, flags, counters and info rows of the call that wrote them."""
        n = self.num_envs
        cols: dict[str, np.ndarray] = {}
        for name, dt, off, rows, stride in layout:
            dtype = np.dtype(dt)
            if name.startswith("info_"):  # one row per info value, rows apart in memory
                cols[name] = np.ndarray(
                    (rows, n), dtype, buffer=area, offset=off, strides=(stride, dtype.itemsize)
                )
            else:
                cols[name] = area[off : off + n * dtype.itemsize].view(dtype)
        # Seeds cross as int64 (torch has no uint64): seeds >= 2**63 read as seed - 2**64.
        cols["seed"] = cols["seed"].view(np.int64)
        return cols

    # -- calls -----------------------------------------------------------------------------

    def check_open(self) -> None:
        """``PoolClosedError`` once closed."""
        if self.closed:
            raise PoolClosedError(CLOSED_MESSAGE)

    def _steer(self) -> None:
        """Make the next slot-writing call write a slot no lent array still uses."""
        if self.lender is not None:
            free = self.lender.steer()
            if free is not None:
                native_call(self.pool.select_slot, free)

    def _took(self, r: tuple[int, int, Extras]) -> Result:
        """The result of a whole-batch call, from the native ``(slot, summary, extras)``
        (extras of one layout are read in place, in the slot's extra-info room)."""
        slot, summary, extras = r
        self.state.slot = slot
        if extras is not None and extras[1] is None:
            room = self.extra_rooms[slot]
            assert room is not None
            extras = (None, room, extras[2], [])
        self.last = Result(self.cols[slot], summary, extras, slot)
        return self.last

    def step(self, actions: np.ndarray) -> Result:
        """A whole sync step."""
        self._steer()
        return self._took(native_call(self.pool.step, actions))

    def send_step(self, actions: np.ndarray) -> None:
        """The first half of :meth:`step`: the workers step while the caller goes on."""
        self._steer()
        native_call(self.pool.send_step, actions)

    def send_reset(self, mask: Optional[np.ndarray] = None) -> None:
        """The first half of a reset: of every env, or with ``mask`` of the masked envs (the
        others' observations written again)."""
        self._steer()
        native_call(self.pool.send_reset, mask)

    def wait(self, timeout: Optional[float]) -> Optional[Result]:
        """The second half of :meth:`send_step` or :meth:`send_reset`, or ``None`` when
        ``timeout`` seconds passed first (the call stays pending)."""
        r = native_call(self.pool.wait, timeout)
        return None if r is None else self._took(r)

    def set_seeds(self, schedule: dict[str, Any]) -> None:
        """Replace the episode-seed schedule (applies from the next reset)."""
        native_call(self.pool.set_seeds, json.dumps(schedule))

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

    # -- async (EnvPool-style) -------------------------------------------------------------

    def _lent(self) -> int:
        """The slots arrays handed out still use (bits), which an async call tells the pool:
        no answer is written there."""
        return 0 if self.lender is None else self.lender.lent_mask()

    def async_reset(self) -> None:
        """Start resetting every env; collect with :meth:`recv`."""
        native_call(self.pool.async_reset, self._lent())

    def send(self, actions: np.ndarray, env_ids: Any) -> None:
        """Send actions to any envs (``env_ids``: an int64 array or a sequence of ints, each
        env at most once until received)."""
        native_call(self.pool.send, actions, env_ids, self._lent())

    def recv(
        self,
        min_batch: Optional[int] = None,
        max_batch: Optional[int] = None,
        timeout: Optional[float] = None,
    ) -> Result:
        """The first envs ready. Rows that are one run of envs in one slot (see
        :meth:`__init__`) are views of their batch slot, columns and observations (the
        observations copied with ``copy``), unchanged until those envs' next answer but one;
        other rows are gathered: columns in the ``recv`` buffer (valid until the next
        ``recv``), observations a fresh copy."""
        got = native_call(self.pool.recv, min_batch, max_batch, timeout)
        rows, summary, extras, ids, raw, view = got
        if view is not None:
            # Written in place as one run of envs: views of the slot (a copy with ``copy``).
            cols, obs = self._view(view[0], view[1], rows)
            if extras is not None and extras[1] is None:
                room = self.extra_rooms[view[0]]
                assert room is not None
                extras = (None, room[view[1] : view[1] + rows], extras[2], [])
            self.last = Result(cols, summary, extras, None, ids, obs.copy() if self.copy else obs)
        else:
            cols = {k: v[..., :rows] for k, v in self.cols[-1].items()}
            obs = raw.reshape(-1, self.obs_bytes)
            self.last = Result(cols, summary, extras, None, ids, obs)
        return self.last

    def _view(self, slot: int, first: int, rows: int) -> tuple[dict[str, np.ndarray], Any]:
        """The columns and observation rows of envs ``first..first + rows`` of ``slot`` (views,
        made once per run: a loop of halves asks for the same few again and again)."""
        key = (slot, first, rows)
        got = self._views.get(key)
        if got is None:
            span = slice(first, first + rows)
            got = ({k: v[..., span] for k, v in self.cols[slot].items()}, self.slots[slot][span])
            if len(self._views) >= 64:
                self._views.clear()
            self._views[key] = got
        return got

    def mark_recycled(self, infos: dict[str, Any], env_ids: Optional[np.ndarray]) -> None:
        """Flag the restarted envs whose worker was replaced by plan during the last call
        (``worker_recycled`` and its mask); asked of the pool only when some env restarted."""
        if "worker_restarted" not in infos:
            return
        ids = self.pool.recycled_envs()
        if ids:
            rows = np.arange(self.num_envs) if env_ids is None else env_ids
            mask = np.isin(rows, ids)
            infos["worker_recycled"] = mask
            infos["_worker_recycled"] = mask.copy()

    # -- the pool --------------------------------------------------------------------------

    def stats(self) -> PoolStats:
        """The counters since the pool started (see :mod:`rogue_gym.front.stats`)."""
        workers, between_ns, inside_ns, calls = self.pool.stats()
        counts = self.kind.facts.info_counts
        typed, pickled = (0, 0) if counts is None else counts()
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
            buffer_bytes=int(self.pool.buffer_bytes()),
            machine=dict(self.pool.machine()),
        )

    @property
    def worker_pids(self) -> list[int]:
        """Process ids of the workers (in worker order); empty once closed."""
        return [] if self.closed else list(self.pool.worker_pids())

    @property
    def restarts(self) -> int:
        """Worker restarts so far."""
        return int(self.pool.restarts())

    def worker_of(self, env: int) -> tuple[int, Optional[int]]:
        """The worker that hosts ``env``, and its process id (``None`` once closed)."""
        for k in range(self.num_workers):
            if env in self.envs_of_worker(k):
                pids = self.worker_pids
                return k, pids[k] if k < len(pids) else None
        raise ValueError(f"env {env} is not one of the pool's {self.num_envs} envs")

    def envs_of_worker(self, worker: int) -> range:
        """Indices of the envs hosted by ``worker``."""
        self.check_open()
        return range(*self.pool.worker_envs(worker))

    def close(self) -> None:
        """Stop the workers and remove the pool's files (idempotent)."""
        self.closed = True
        self._finalizer()


def mark_restarted(infos: dict[str, Any], restarted: Optional[np.ndarray]) -> None:
    """Flag the envs whose worker was restarted during the call (``worker_restarted`` and its
    mask), if any: every kind and call reports them so."""
    if restarted is not None and restarted.any():
        infos["worker_restarted"] = restarted.copy()
        infos["_worker_restarted"] = restarted.copy()
