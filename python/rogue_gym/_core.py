"""The pool core shared by the gymnasium and SB3 facades.

It owns the native pool (supervisor + worker processes), validates actions, and holds the
zero-copy views of the pool's two shared-memory batch slots that the sync ``step()`` returns
alternately (double buffering: the workers write the slot not returned last time).
"""

from __future__ import annotations

import json
import os
import weakref
from typing import Any, Mapping, Optional

import numpy as np

from . import _native, _sigterm
from ._config import resolve_config, to_json
from ._records import (
    FLAG_FINAL_OBS,
    FLAG_RESTARTED,
    FLAG_TERMINATED,
    FLAG_TRUNCATED,
    RECORD_DTYPE,
)
from .envs.image import ObsSpec, observation_space
from .envs.rogue_env import ACTIONS
from .errors import CLOSED_MESSAGE, PoolClosedError
from .settings import PoolSettings, SeedsLike

__all__ = ["ActionHistory", "PoolCore", "PoolFacade", "SeedsLike", "screen_to_rgb"]

#: Info values of the rogue env kind that are flags (the rest are integers).
_BOOL_INFO = frozenset(_native.BOOL_INFO_NAMES)

#: :meth:`PoolCore.step_columns` summary bit: some env's worker was restarted.
SUMMARY_RESTARTED: int = _native.SUMMARY_RESTARTED
#: :meth:`PoolCore.step_columns` summary bit: some env has a final observation (SAME_STEP).
SUMMARY_FINAL: int = _native.SUMMARY_FINAL


def _seed_set(seeds: SeedsLike, config: Mapping[str, Any]) -> Optional[dict[str, Any]]:
    """The pool's seed set from ``seeds`` (or the config's ``seed_range`` / ``seed``)."""
    if seeds is None:
        if config.get("seed_range") is not None:
            lo, hi = (int(x) for x in config["seed_range"])
            seeds = range(lo, hi)
        elif config.get("seed") is not None:
            seeds = [int(config["seed"])]
        else:
            return None
    if isinstance(seeds, range):
        if seeds.step != 1:
            return {"list": [int(s) for s in seeds]}
        if len(seeds) == 0:
            raise ValueError("the seed range is empty")
        return {"range": {"start": int(seeds.start), "end": int(seeds.stop)}}
    if (
        isinstance(seeds, tuple)
        and len(seeds) == 2
        and all(isinstance(x, (int, np.integer)) for x in seeds)
    ):
        lo, hi = int(seeds[0]), int(seeds[1])
        if hi <= lo:
            raise ValueError(f"seeds=(lo, hi) needs lo < hi, got {seeds}")
        return {"range": {"start": lo, "end": hi}}
    values = [int(s) for s in seeds]
    if not values:
        raise ValueError("seeds must not be empty")
    if any(s < 0 or s >= 2**64 for s in values):
        raise ValueError("seeds must lie in [0, 2**64)")
    return {"list": values}


class PoolCore:
    """Native pool + batch buffers + record decoding. Internal: use the facades."""

    def __init__(self, settings: PoolSettings, *, same_step: bool = False) -> None:
        st = settings.checked()
        self.settings = st
        self.config = resolve_config(st.config)
        self.spec = ObsSpec(
            st.obs, st.dtype, st.status, st.normalize_status, st.history
        ).validated()
        self.num_envs = st.num_envs
        self.num_workers = int(st.num_workers or 1)
        self.max_steps = st.max_steps
        self.stair_reward = st.stair_reward
        self.same_step = bool(same_step)
        self.base_seed = int(st.seed or 0)
        # A local game validates the config (ValueError naming the key) and gives the spaces.
        probe = _native.Game(to_json(self.config), self.max_steps, self.stair_reward)
        self.obs_shape = tuple(probe.obs_shape(self.spec))
        self.obs_dtype = np.dtype(self.spec.dtype)
        self.symbols = int(probe.symbols)
        self.single_observation_space = observation_space(self.spec, self.obs_shape, self.symbols)
        self._settings: dict[str, Any] = {
            "num_envs": self.num_envs,
            "num_workers": self.num_workers,
            "batch_size": st.batch_size,
            "env": {
                "kind": "rogue",
                "config": self.config,
                "max_steps": self.max_steps,
                "stair_reward": self.stair_reward,
                "obs": self.spec.to_dict(),
            },
            "seeds": {
                "base": self.base_seed,
                "set": _seed_set(st.seeds, self.config),
                "policy": st.seed_policy,
                "shard": None
                if st.shard is None
                else {"first_env": st.shard[0], "total_envs": st.shard[1]},
            },
            "autoreset": "same_step" if self.same_step else "next_step",
            "on_worker_failure": st.on_worker_failure,
            "step_timeout": st.step_timeout,
            "start_timeout": st.start_timeout,
            "max_restarts": st.max_restarts,
            "runtime_dir": None if st.runtime_dir is None else os.fspath(st.runtime_dir),
        }
        self._cmd = list(st.worker_command or [])
        self._pool: Any = None
        self._fresh = False  # the pool has not been reset since it started
        self._closed = False
        self._finalizer: Optional[weakref.finalize] = None
        batch_shape = (self.num_envs, *self.obs_shape)
        # Double buffer: the workers write each step's observations straight into one of two
        # shared-memory batch slots, alternately, so the batch returned by the previous call
        # stays intact while the next one is written. (Set by start().)
        self._bufs: list[np.ndarray] = []
        self._final = np.zeros(batch_shape, self.obs_dtype) if self.same_step else None
        self._recs = [np.zeros(self.num_envs, RECORD_DTYPE) for _ in range(2)]
        self._slot = 0
        self._actions = np.zeros(self.num_envs, np.int64)
        self.last_actions = self._actions
        self._cols: list[dict[str, np.ndarray]] = []
        self._info_templates: list[dict[str, Any]] = []
        self.info_keys: list[str] = []
        self.mask_keys: list[str] = []
        self.info_names: list[str] = []
        #: The pool's name: the prefix of its /dev/shm files.
        self.name: str = ""
        self.start()

    def start(self, seed: Optional[int] = None) -> None:
        """(Re)start the workers, with base seed ``seed`` if given (episode counters restart)."""
        if self._closed:
            raise PoolClosedError(CLOSED_MESSAGE)
        if seed is not None:
            self.base_seed = int(seed)
            self._settings["seeds"]["base"] = self.base_seed
        self._stop()
        _sigterm.install()
        pool = _native.Pool(json.dumps(self._settings), self._cmd)
        self._pool = pool
        self._finalizer = weakref.finalize(self, _native.Pool.close, pool)
        self._fresh = True
        if tuple(pool.obs_shape) != self.obs_shape or np.dtype(pool.obs_dtype) != self.obs_dtype:
            raise RuntimeError(
                f"pool observation {pool.obs_dtype}{tuple(pool.obs_shape)} differs from the engine's {self.obs_dtype}{self.obs_shape}"
            )
        self.info_names = list(pool.info_names)
        shape = (self.num_envs, *self.obs_shape)
        self._bufs = [v.view(self.obs_dtype).reshape(shape) for v in pool.shared_views()]
        self._bind_columns(pool)
        self.name = pool.name()

    def _bind_columns(self, pool: Any) -> None:
        """Preallocate one column buffer per shared batch slot for :meth:`step_columns`."""
        n = self.num_envs
        layout, total = pool.column_layout()
        buffers, self._cols, self._info_templates = [], [], []
        for _ in self._bufs:
            buf = np.zeros(total, np.uint8)
            cols: dict[str, np.ndarray] = {}
            for name, dt, off, rows in layout:
                size = rows * n * np.dtype(dt).itemsize
                col = buf[off : off + size].view(dt)
                cols[name] = col.reshape(rows, n) if name.startswith("info_") else col
            values: dict[str, np.ndarray] = {
                "seed": cols["seed"],
                "episode_index": cols["episode_index"],
                "episode_return": cols["episode_return"],
                "episode_length": cols["episode_length"],
            }
            for k, name in enumerate(self.info_names):
                values[name] = cols["info_bool" if name in _BOOL_INFO else "info_int"][k]
            template: dict[str, Any] = {}
            for key, arr in values.items():
                template[key] = arr
                template[f"_{key}"] = None  # the step's mask, set per step
            buffers.append(buf)
            self._cols.append(cols)
            self._info_templates.append(template)
        self.info_keys = list(values)
        self.mask_keys = [f"_{k}" for k in values]
        pool.bind_columns(buffers)

    def step_columns(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], dict[str, Any], int]:
        """The fast sync step: ``(obs, records, columns, info template, summary)``.

        One native call validates the actions, steps, and decodes every env's record into the
        column arrays of the returned slot (``reward`` float64, ``terminated`` / ``truncated``
        / ``restarted`` / ``has_final_obs`` bool, ``seed``, ``episode_index``,
        ``episode_return``, ``episode_length``, ``info_int`` / ``info_bool`` rows). The columns
        and the template's arrays are reused: like the observation slot, they stay unchanged
        until the second following step. ``summary``: :data:`SUMMARY_RESTARTED` /
        :data:`SUMMARY_FINAL` bits. The actions actually sent are kept in ``last_actions``.
        """
        a = self._int_actions(actions)
        recs = self._recs[1 - self._slot]
        return self._columns_result(self._pool.step_columns(a, recs, self._final), recs)

    def send_step(self, actions: Any) -> None:
        """The first half of :meth:`step_columns` (gymnasium's ``step_async``): check and send
        the actions; the workers step while the caller goes on."""
        self._pool.step_shared_send(self._int_actions(actions))

    def wait_columns(
        self, timeout: Optional[float]
    ) -> Optional[tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], dict[str, Any], int]]:
        """The second half of :meth:`send_step`: what :meth:`step_columns` returns, or ``None``
        when ``timeout`` seconds passed first (the step stays pending)."""
        self._check_open()
        recs = self._recs[1 - self._slot]
        r = self._pool.wait_columns(timeout, recs, self._final)
        return None if r is None else self._columns_result(r, recs)

    def _int_actions(self, actions: Any) -> np.ndarray:
        """The actions as int64, one per env (kept in ``last_actions``)."""
        self._check_open()
        a = actions
        if not (type(a) is np.ndarray and a.dtype == np.int64 and a.shape == (self.num_envs,)):
            a = self.validate_actions(a, check_range=False)
        self.last_actions = a
        return a

    def _columns_result(
        self, r: int, recs: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], dict[str, Any], int]:
        slot = self._slot = r & 0xFF
        if self._recs[slot] is not recs:
            self._recs.reverse()
        self._fresh = False
        return self._bufs[slot], recs, self._cols[slot], self._info_templates[slot], r

    def _stop(self) -> None:
        if self._finalizer is not None:
            self._finalizer()
        self._pool = None

    # ------------------------------------------------------------------------------------
    @property
    def closed(self) -> bool:
        """Whether the pool was closed."""
        return self._closed

    def close(self) -> None:
        """Stop all workers and remove the pool's files (idempotent)."""
        self._closed = True
        self._stop()

    @property
    def worker_pids(self) -> list[int]:
        """Process ids of the live workers, one per worker (in worker order)."""
        return [] if self._pool is None else list(self._pool.worker_pids())

    @property
    def restarts(self) -> int:
        """Worker restarts so far."""
        return 0 if self._pool is None else int(self._pool.restarts())

    @property
    def native(self) -> Any:
        """The native pool (``rogue_gym._native.Pool``)."""
        self._check_open()
        return self._pool

    def envs_of_worker(self, worker: int) -> range:
        """Indices of the envs hosted by ``worker``."""
        self._check_open()
        return range(*self._pool.worker_envs(worker))

    def _check_open(self) -> None:
        if self._closed or self._pool is None:
            raise PoolClosedError(CLOSED_MESSAGE)

    def validate_actions(self, actions: Any, check_range: bool = True) -> np.ndarray:
        """Check a batch of actions; returns them as ``int64`` (one per env).

        With ``check_range=False`` the range is left to the native pool, which raises the same
        ``ValueError`` (naming the env and the value) before anything is sent to the workers.
        """
        n = self.num_envs
        if isinstance(actions, str):
            if len(actions) != n:
                raise ValueError(
                    f"an action string needs one key per env: expected {n} keys, got {len(actions)}"
                )
            actions = [
                ACTIONS.index(k) if k in ACTIONS else _native.action_from_key(k) for k in actions
            ]
        a = np.asarray(actions)
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
        if check_range or (a.dtype.kind == "u" and a.dtype.itemsize >= 8):
            # (Checked here for uint64 too, which would wrap when cast to int64.)
            bad = (a < 0) | (a >= len(ACTIONS))
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise ValueError(
                    f"env {i}: action {a[i]} is out of range; valid actions are 0 to "
                    f"{len(ACTIONS) - 1} (range({len(ACTIONS)}))"
                )
        np.copyto(self._actions, a, casting="unsafe")
        return self._actions

    def reset(
        self, seed: Optional[int] = None, mask: Optional[np.ndarray] = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Reset every env (or the envs of ``mask``); returns (obs batch, records) written into
        the next slot.

        With ``seed``, the episode schedule restarts from base seed ``seed`` (env ``i``'s episode
        ``e`` plays the same dungeon whatever the worker count), as in a fresh pool. With a
        partial ``mask`` (checked by :func:`rogue_gym.reset_mask.partial_mask`, never with a
        ``seed``), the masked envs start their next scheduled episode and the others keep their
        state; their current observation and records are returned again (reward 0, no flags).
        """
        self._check_open()
        if mask is not None:
            recs = self._recs[1 - self._slot]
            slot = self._slot = self._pool.reset_envs_shared(mask, recs)
            if self._recs[slot] is not recs:
                self._recs.reverse()
            return self._bufs[slot], recs
        self.send_reset(seed)
        got = self.wait_reset(None)
        assert got is not None  # no timeout
        return got

    def send_reset(self, seed: Optional[int] = None) -> None:
        """The first half of a full :meth:`reset` (gymnasium's ``reset_async``): the workers
        reset while the caller goes on; :meth:`wait_reset` collects it."""
        self._check_open()
        if seed is not None:
            seed = int(seed)
            if not 0 <= seed < 2**64:
                raise ValueError(f"seed must be in [0, 2**64), got {seed}")
            if not (self._fresh and seed == self.base_seed):
                self.base_seed = seed
                self._settings["seeds"]["base"] = seed
                self._pool.set_seeds(json.dumps(self._settings["seeds"]))
        self._pool.reset_shared_send()

    def wait_reset(self, timeout: Optional[float]) -> Optional[tuple[np.ndarray, np.ndarray]]:
        """The second half of :meth:`send_reset`: (obs batch, records), or ``None`` when
        ``timeout`` seconds passed first (the reset stays pending)."""
        self._check_open()
        recs = self._recs[1 - self._slot]
        slot = self._pool.wait_shared(timeout, recs, None)
        if slot is None:
            return None
        self._slot = slot
        if self._recs[slot] is not recs:
            self._recs.reverse()
        self._fresh = False
        return self._bufs[slot], recs

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray]:
        """Step every env; returns (obs batch, records) written into the next slot."""
        self._check_open()
        acts = self.validate_actions(actions, check_range=False)
        recs = self._recs[1 - self._slot]
        slot = self._slot = self._pool.step_shared(acts, recs, self._final)
        if self._recs[slot] is not recs:
            self._recs.reverse()
        self._fresh = False
        return self._bufs[slot], recs

    @property
    def final_obs(self) -> Optional[np.ndarray]:
        """(SAME_STEP) final observations of the last step, valid where the record says so."""
        return self._final

    # ------------------------------------------------------------------------------------
    @staticmethod
    def flags(recs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(terminated, truncated, restarted, has_final_obs) bool arrays of a record batch."""
        # One unpack for all four flags (bit k of the low byte -> row k), rows viewed as bool.
        bits = np.unpackbits(recs["flags"].astype(np.uint8)[None, :], axis=0, bitorder="little")
        b = bits.view(np.bool_)
        return (
            b[FLAG_TERMINATED.bit_length() - 1],
            b[FLAG_TRUNCATED.bit_length() - 1],
            b[FLAG_RESTARTED.bit_length() - 1],
            b[FLAG_FINAL_OBS.bit_length() - 1],
        )

    def info_arrays(self, recs: np.ndarray) -> dict[str, np.ndarray]:
        """The env-defined info values and episode counters as arrays (one entry per env)."""
        out: dict[str, np.ndarray] = {
            "seed": recs["seed"].copy(),
            "episode_index": recs["episode"].astype(np.int64),
            "episode_return": recs["episode_return"].copy(),
            "episode_length": recs["episode_length"].astype(np.int64),
        }
        n = len(self.info_names)
        if n:
            # One conversion for all columns; rows of the transposed copy are contiguous.
            values = recs["info"][:, :n].T
            ints = np.ascontiguousarray(values, dtype=np.int64)
            for k, name in enumerate(self.info_names):
                out[name] = values[k] != 0 if name in _BOOL_INFO else ints[k]
        return out

    def info_dict(self, recs: np.ndarray, i: int) -> dict[str, Any]:
        """The info values of env ``i`` as a plain dict."""
        r = recs[i]
        d: dict[str, Any] = {
            "seed": int(r["seed"]),
            "episode_index": int(r["episode"]),
            "episode_return": float(r["episode_return"]),
            "episode_length": int(r["episode_length"]),
        }
        for k, name in enumerate(self.info_names):
            v = r["info"][k]
            d[name] = bool(v) if name in _BOOL_INFO else int(v)
        return d


class ActionHistory:
    """Per-env action keys since each env's episode start, to rebuild screens by replay.

    Workers do not ship screens; a frame is rebuilt by replaying an env's current episode (its
    seed and recorded actions) on an in-process engine. Cheap to record (a few vector ops per
    step), O(episode length) to render.
    """

    def __init__(self, core: PoolCore) -> None:
        self.core = core
        self.actions = np.zeros((core.max_steps + 2, core.num_envs), np.uint8)
        self.length = np.zeros(core.num_envs, np.int64)
        self.seeds = np.zeros(core.num_envs, np.uint64)
        self.stale = np.zeros(core.num_envs, bool)

    def on_reset(self, recs: np.ndarray, envs: np.ndarray, seed_known: bool = True) -> None:
        """``envs`` (bool mask) started new episodes, described by ``recs`` if ``seed_known``
        (SAME_STEP ending steps describe the old episode: the seed is taken from the next step)."""
        self.length[envs] = 0
        if seed_known:
            self.seeds[envs] = recs["seed"][envs]
            self.stale[envs] = False
        else:
            self.stale |= envs

    def on_step(self, actions: np.ndarray, stepped: np.ndarray, recs: np.ndarray) -> None:
        """Record ``actions`` of the envs in the ``stepped`` mask (``recs``: this step's records)."""
        if self.stale.any():
            fix = self.stale & ((recs["flags"] & 3) == 0)
            self.seeds[fix] = recs["seed"][fix]
            self.stale &= ~fix
        idx = np.flatnonzero(stepped)
        pos = np.minimum(self.length[idx], self.actions.shape[0] - 1)
        self.actions[pos, idx] = actions[idx]
        self.length[idx] += 1

    def screen(self, i: int) -> str:
        """The current screen of env ``i``: map rows and status line."""
        core = self.core
        game = _native.Game(to_json(core.config), core.max_steps, core.stair_reward)
        game.reset(int(self.seeds[i]))
        for a in self.actions[: int(self.length[i]), i]:
            game.step(int(a))
        return "\n".join([*game.screen(), game.status_line()])


def screen_to_rgb(screen: str) -> np.ndarray:
    """A ``(rows, cols, 3)`` uint8 image of a text screen, one pixel per cell, colour by glyph."""
    rows = screen.split("\n")
    width = max(len(r) for r in rows)
    codes = np.zeros((len(rows), width), np.uint8)
    for y, row in enumerate(rows):
        codes[y, : len(row)] = np.frombuffer(row.encode("ascii", "replace"), np.uint8)
    palette = np.zeros((256, 3), np.uint8)
    for ch, rgb in {
        "@": (255, 255, 0),
        "#": (120, 120, 120),
        ".": (60, 60, 60),
        "-": (200, 200, 200),
        "|": (200, 200, 200),
        "%": (0, 255, 0),
        "+": (180, 120, 40),
        "*": (255, 200, 0),
        ":": (200, 80, 80),
    }.items():
        palette[ord(ch)] = rgb
    for c in range(ord("A"), ord("Z") + 1):
        palette[c] = (255, 0, 0)
    for c in range(ord("!"), ord("~") + 1):
        if not palette[c].any():
            palette[c] = (150, 150, 255)
    return palette[codes]


class PoolFacade:
    """What both facades (gymnasium and SB3) expose of their pool (:attr:`_core`)."""

    _core: PoolCore

    @property
    def num_workers(self) -> int:
        """Number of worker processes."""
        return self._core.num_workers

    @property
    def worker_pids(self) -> list[int]:
        """Process ids of the workers (worker ``k`` hosts envs ``envs_of_worker(k)``)."""
        return self._core.worker_pids

    @property
    def restarts(self) -> int:
        """Worker restarts so far (``on_worker_failure="restart"``; ``max_restarts`` bounds
        them)."""
        return self._core.restarts

    def envs_of_worker(self, worker: int) -> range:
        """Indices of the envs hosted by ``worker``."""
        return self._core.envs_of_worker(worker)
