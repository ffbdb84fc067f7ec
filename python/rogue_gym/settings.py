"""The pool's settings: one typed definition, with every default written once.

:class:`PoolSettings` is what :func:`rogue_gym.make_vec`,
:class:`rogue_gym.vector.RogueVectorEnv`, :class:`rogue_gym.sb3.RogueVecEnv` and the native
kind (:class:`rogue_gym.kinds.native.NativeKind`) take; the facades pass their keyword arguments through :meth:`PoolSettings.from_kwargs`, so a
misspelt option is a ``TypeError`` that lists the valid ones. Its base :class:`PoolOptions` holds
the options of the pool itself, which hosted envs take too. The env kinds
(:mod:`rogue_gym.kinds`) turn the checked settings into the JSON object the native pool
receives (keys as named here; the Rust side adds no defaults).
"""

from __future__ import annotations

import dataclasses
import os
import sys
from typing import Any, Mapping, Optional, Sequence, Union

from gymnasium.vector import AutoresetMode

from . import _native
from ._config import ConfigLike

__all__ = ["FAILURE_POLICIES", "SEED_POLICIES", "PoolOptions", "PoolSettings", "SeedsLike"]

#: ``seeds=``: a list, a ``range`` or ``(lo, hi)``.
SeedsLike = Union[None, Sequence[int], range, tuple]

#: What a crashed or hung worker does to the caller.
FAILURE_POLICIES = ("restart", "raise")
#: How episode seeds are drawn from the seed set.
SEED_POLICIES = ("sample", "sequential")


def _optional_int(value: Any) -> Optional[int]:
    return None if value is None else int(value)


@dataclasses.dataclass
class PoolOptions:
    """The options of the pool itself, whatever env kind it hosts (see :class:`PoolSettings`
    for each one's meaning); :class:`PoolSettings` adds the native game's."""

    num_workers: Optional[int] = None
    on_worker_failure: str = "restart"
    step_timeout: Optional[float] = 60.0
    start_timeout: float = 30.0
    max_restarts: Optional[int] = 100
    worker_command: Optional[Sequence[str]] = None
    batch_size: Optional[int] = None
    runtime_dir: Optional[str] = None
    poll_us: Optional[int] = None
    worker_poll_us: Optional[int] = None
    recycle_after_steps: Optional[int] = None
    recycle_above_rss: Optional[int] = None
    batch_slots: Optional[int] = None
    cpu_affinity: Union[int, str, None] = None
    streaming_stores: Optional[bool] = None
    env_concurrency: Union[str, int] = "serial"

    @classmethod
    def from_kwargs(cls, options: Mapping[str, Any]) -> Any:
        """Options from keyword arguments; an unknown name is a ``TypeError`` listing the
        valid ones."""
        names = [f.name for f in dataclasses.fields(cls)]
        unknown = sorted(set(options) - set(names))
        if unknown:
            raise TypeError(
                f"unknown pool option(s) {', '.join(map(repr, unknown))}; valid options: "
                + ", ".join(names)
            )
        return cls(**options)

    def checked_pool(self, num_envs: int) -> dict[str, Any]:
        """The pool-level options for ``num_envs`` envs, checked (``ValueError`` names the
        option) and with their defaults resolved, as keyword values."""
        num_workers = self.num_workers
        if num_workers is None:
            num_workers = min(num_envs, _native.usable_cores())
        if not 1 <= int(num_workers) <= num_envs:
            raise ValueError(
                f"num_workers must be between 1 and num_envs ({num_envs}), got {num_workers}"
            )
        if self.on_worker_failure not in FAILURE_POLICIES:
            raise ValueError(
                f"on_worker_failure must be one of {FAILURE_POLICIES}, got {self.on_worker_failure!r}"
            )
        if self.step_timeout is not None and not float(self.step_timeout) > 0:
            raise ValueError(f"step_timeout must be positive or None, got {self.step_timeout}")
        for name in ("poll_us", "worker_poll_us"):
            value = getattr(self, name)
            if value is not None and int(value) < 0:
                raise ValueError(f"{name} must be a number of microseconds >= 0, got {value}")
        affinity = self.cpu_affinity
        if (
            affinity is not None
            and affinity != "disjoint"
            and (isinstance(affinity, (bool, str)) or int(affinity) < 0)
        ):
            raise ValueError(
                f'cpu_affinity must be a core offset >= 0, "disjoint" or None (no pinning), '
                f"got {affinity!r}"
            )
        if self.streaming_stores not in (None, True, False):
            raise ValueError(
                "streaming_stores must be True, False or None (by the batch's size), got "
                f"{self.streaming_stores!r}"
            )
        concurrency = self.env_concurrency
        if concurrency == "serial":
            env_threads = 0
        elif concurrency == "threads":
            env_threads = -(-num_envs // int(num_workers))  # one per env of the largest block
        elif isinstance(concurrency, int) and not isinstance(concurrency, bool) and concurrency > 0:
            env_threads = int(concurrency)
        else:
            raise ValueError(
                'env_concurrency must be "serial", "threads" or a number of threads >= 1, got '
                f"{concurrency!r}"
            )
        for name in ("recycle_after_steps", "recycle_above_rss"):
            value = getattr(self, name)
            if value is not None and int(value) < 1:
                raise ValueError(f"{name} must be a positive number (or None: never), got {value}")
        command = self.worker_command
        if command is None:
            command = [sys.executable, "-m", "rogue_gym.worker"]
        return {
            "num_workers": int(num_workers),
            "step_timeout": None if self.step_timeout is None else float(self.step_timeout),
            "start_timeout": check_start_timeout(self.start_timeout),
            "max_restarts": None if self.max_restarts is None else int(self.max_restarts),
            "worker_command": list(command),
            "poll_us": None if self.poll_us is None else int(self.poll_us),
            "worker_poll_us": None if self.worker_poll_us is None else int(self.worker_poll_us),
            "recycle_after_steps": _optional_int(self.recycle_after_steps),
            "recycle_above_rss": _optional_int(self.recycle_above_rss),
            "batch_slots": _optional_int(self.batch_slots),
            "cpu_affinity": affinity if affinity in (None, "disjoint") else int(affinity),
            "streaming_stores": self.streaming_stores,
            "env_concurrency": env_threads,
        }

    def pool_json(self, num_envs: int, worker_poll_us: Optional[int] = None) -> dict[str, Any]:
        """The pool-level part of the native pool's settings JSON (checked options);
        ``worker_poll_us`` is the kind's default for the option (None: the pool's)."""
        return {
            "num_envs": int(num_envs),
            "num_workers": int(self.num_workers or 1),
            "batch_size": self.batch_size,
            "on_worker_failure": self.on_worker_failure,
            "step_timeout": self.step_timeout,
            "start_timeout": self.start_timeout,
            "max_restarts": self.max_restarts,
            "poll_us": self.poll_us,
            "worker_poll_us": (
                self.worker_poll_us if self.worker_poll_us is not None else worker_poll_us
            ),
            "recycle_after_steps": self.recycle_after_steps,
            "recycle_above_rss": self.recycle_above_rss,
            "batch_slots": self.batch_slots,
            "cpu_affinity": self.cpu_affinity,
            "streaming_stores": self.streaming_stores,
            "env_threads": self.env_threads(),
            "runtime_dir": None if self.runtime_dir is None else os.fspath(self.runtime_dir),
        }

    def env_threads(self) -> int:
        """Threads per worker that step its envs, from the checked ``env_concurrency``: 0 for
        ``"serial"``."""
        c = self.env_concurrency
        return 0 if c == "serial" else int(c) if not isinstance(c, str) else 0


@dataclasses.dataclass
class PoolSettings(PoolOptions):
    """Every option of a pool of the native game, with its default.

    Attributes:
        num_envs: number of games.
        config: game config: ``"paper"`` (32x16, 2x2 rooms, no monsters, seeds [0, 40)), a
            dict, a JSON string or a path; ``{}`` is the original default game.
        num_workers: worker processes, at most ``num_envs`` (default: the cores this process
            may use, its affinity mask and its cgroup's CPU quota rounded up, at most
            ``num_envs``); each hosts a contiguous block of envs, the blocks differing by at
            most one env.
        seed: base of the episode-seed schedule (default: random).
        seeds: the dungeons episodes are drawn from: a list, a ``range`` or ``(lo, hi)``
            (default: the config's ``seed_range`` / ``seed``, else unrestricted).
        seed_policy: ``"sample"`` (independent draws, training) or ``"sequential"`` (cover the
            set evenly, evaluation).
        obs, dtype, status, normalize_status, history: the observation encoding
            (``symbol_onehot`` / ``symbol_index`` / ``gray`` / ``ascii`` / ``status``), its dtype
            (``uint8`` / ``float32``), status planes (a ``StatusFlag`` mask) and the
            visited-history plane.
        max_steps: episode step limit (truncation); 500 as in the paper.
        stair_reward: reward per new deepest floor, added to the gold gained; 50 as in the
            paper.
        on_worker_failure: ``"restart"`` or ``"raise"``.
        step_timeout: seconds after which a silent worker counts as hung (``None``: never).
        start_timeout: seconds a lost worker has to come back (its restart backoff, start-up
            and the reset of its envs); a worker not ready within it is killed. Every call
            returns or raises within ``step_timeout + start_timeout``.
        max_restarts: worker restarts allowed over the pool's life.
        worker_command: program and leading args of a worker (default:
            ``[sys.executable, "-m", "rogue_gym.worker"]``).
        shard: ``(first_env, total_envs)``: this pool's envs are envs ``first_env ..
            first_env + num_envs - 1`` of a larger set of ``total_envs`` (one pool per machine,
            as :mod:`rogue_gym.ray` runs them), and their episode seeds are those envs' seeds in
            one pool of ``total_envs``. Default: the pool is the whole set.
        batch_size: envs per async ``recv`` by default (1 to ``num_envs``; default all).
        runtime_dir: the directory that holds the pool's files; it must be a directory of
            yours that no one else can enter (created 0700 if missing; refused otherwise).
            Default: ``$ROGUE_GYM_RUNTIME_DIR``, else ``$XDG_RUNTIME_DIR/rogue-gym``, else
            ``/tmp/rogue-gym-<uid>`` (see docs/security.md).
        poll_us, worker_poll_us: how long the caller and the workers poll (yielding the CPU)
            before they block when waiting for each other, in µs (default: the pool's).
        batch_slots: slots of the shared batch buffer the workers write observations into,
            2 to 16 (default 2: the pool's footprint in ``/dev/shm`` is twice the batch). With
            ``copy=True`` and large batches the pool lends its slots instead of copying: 2 lend
            every other batch of a loop that holds the previous one, 3 every batch; each slot
            costs one batch of ``/dev/shm`` (docs/performance.md, "Batch slots").
        recycle_after_steps, recycle_above_rss: replace a worker by plan once it has served
            this many env steps, or once its resident memory is above this many bytes (envs
            that leak; default ``None``: never). The replacement builds its envs while the
            worker serves on, then takes over between two calls; the worker's envs start new
            episodes there (``truncated``, info ``worker_recycled``). Counted in ``stats()``
            as ``recycles``, apart from crash restarts and outside the restart budget.
        cpu_affinity: pin the workers to cores (opt-in): an offset ``o`` runs worker ``k`` on
            the ``(o + k)``-th core this process may use, wrapping around (EnvPool's
            ``thread_affinity_offset``); ``"disjoint"`` gives each worker a core that no other
            pool of yours on the machine holds, wherever the pools start (the pools' ledger
            hands them out; too few free cores is an error naming the pools that hold them).
            ``None`` (the default): the kernel places them. On a machine of several NUMA nodes
            run one pool per node (docs/performance.md).
        env_concurrency: how a worker steps its envs (hosted envs of one callable each):
            ``"serial"`` (the default: one after the other, right for envs that compute: add
            workers instead), ``"threads"`` (each env on a thread of its own) or a number of
            threads per worker. For envs that wait (a socket, a remote simulator, a subprocess,
            a sleep): a waiting env holds only its thread, and in the async API each env's
            result is handed out as soon as it is ready. ``python -m rogue_gym.tuning`` tries
            both (docs/performance.md, "Envs that wait").
        streaming_stores: write the observation rows with streaming (non-temporal) stores,
            which bypass the cache: ``True`` always, ``False`` never, ``None`` (the default)
            when the observations of all the ``batch_slots`` take more than a third of the
            last-level cache (the native game's from 643 envs on a 32 MB cache with two
            slots; docs/performance.md, "Memory traffic"). Only the speed changes.
    """

    num_envs: int = 8
    config: ConfigLike = "paper"
    seed: Optional[int] = None
    seeds: SeedsLike = None
    seed_policy: str = "sample"
    obs: str = "symbol_onehot"
    dtype: str = "uint8"
    status: int = 0
    normalize_status: bool = False
    history: bool = False
    max_steps: int = 500
    stair_reward: float = 50.0
    shard: Optional[tuple[int, int]] = None

    def checked(self) -> PoolSettings:
        """A copy with the defaults resolved (``num_workers``, ``seed``, ``worker_command``) and
        every value checked; ``ValueError`` names the option."""
        num_envs = int(self.num_envs)
        if num_envs <= 0:
            raise ValueError(f"num_envs must be positive, got {self.num_envs}")
        pool = self.checked_pool(num_envs)
        if self.seed_policy not in SEED_POLICIES:
            raise ValueError(
                f"seed_policy must be one of {SEED_POLICIES}, got {self.seed_policy!r}"
            )
        if int(self.max_steps) <= 0:
            raise ValueError(f"max_steps must be positive, got {self.max_steps}")
        shard = self.shard
        if shard is not None:
            first, total = (int(x) for x in shard)
            if first < 0 or first + num_envs > total:
                raise ValueError(
                    f"shard=(first_env, total_envs) must hold the pool's {num_envs} envs: "
                    f"0 <= first_env and first_env + num_envs <= total_envs, got {tuple(shard)}"
                )
            shard = (first, total)
        seed = self.seed
        if seed is None:
            seed = int.from_bytes(os.urandom(8), "little") >> 1
        elif not 0 <= int(seed) < 2**64:
            raise ValueError(f"seed must be an integer in [0, 2**64), got {seed}")
        return dataclasses.replace(
            self,
            **pool,
            num_envs=num_envs,
            shard=shard,
            seed=int(seed),
            max_steps=int(self.max_steps),
            stair_reward=float(self.stair_reward),
        )


def check_start_timeout(start_timeout: Any) -> float:
    """``start_timeout`` as seconds; ``ValueError`` unless it is a positive number."""
    try:
        value = float(start_timeout)
    except (TypeError, ValueError):
        value = float("nan")
    if not value > 0 or value == float("inf"):
        raise ValueError(
            f"start_timeout must be a positive number of seconds, got {start_timeout!r}"
        )
    return value


def parse_autoreset_mode(
    mode: Union[str, AutoresetMode], allowed: Sequence[AutoresetMode] = tuple(AutoresetMode)
) -> AutoresetMode:
    """An ``AutoresetMode`` from itself, its value (``"NextStep"``) or its name in any case
    (``"NEXT_STEP"``, ``"next-step"``); ``ValueError`` names the ``allowed`` ones."""
    key = str(getattr(mode, "value", mode)).replace("_", "").replace("-", "").lower()
    found = next((m for m in AutoresetMode if m.value.lower() == key), None)
    if found is None or found not in allowed:
        names = ", ".join(m.name for m in allowed)
        raise ValueError(f"autoreset_mode must be one of {names}, got {mode!r}")
    return found
