"""The candidate layouts tune times for one env, and how an env given to tune is read."""

from __future__ import annotations

import functools
import importlib
from dataclasses import dataclass, field
from typing import Any, Callable, Optional, Sequence, Union

import gymnasium as gym

from ..registration import ENV_ID

__all__ = [
    "HARVEST",
    "MAX_ONE_PER_ENV",
    "NATIVE_NAMES",
    "THREADS",
    "Candidate",
    "EnvLike",
    "candidates",
    "resolve",
]

NATIVE_NAMES = (ENV_ID, "native", "rogue")

EnvLike = Union[str, Callable[[], gym.Env], Sequence[Callable[[], gym.Env]]]


@dataclass(frozen=True)
class Candidate:
    """One layout: the keyword arguments of the vector env, and how it is stepped."""

    #: ``"pool"`` (``step``), ``"async"`` (``send``/``recv`` of ``batch_size`` envs),
    #: ``"harvest"`` (``recv`` with a deadline, :data:`HARVEST`), ``"vector"`` (one vector env
    #: per worker) or ``"sync"`` (gymnasium's ``SyncVectorEnv`` in this process).
    mode: str
    kwargs: dict[str, Any] = field(default_factory=dict)

    @property
    def label(self) -> str:
        """A short name for the table."""
        if self.mode == "sync":
            return "SyncVectorEnv"
        args = ", ".join(f"{k}={v}" for k, v in self.kwargs.items())
        return f"{self.mode}: {args}"

    @classmethod
    def from_label(cls, label: str) -> Candidate:
        """The candidate a :attr:`label` names (its keyword values are ints, bools or words)."""
        if label == "SyncVectorEnv":
            return cls("sync")
        mode, _, args = label.partition(": ")
        kwargs: dict[str, Any] = {}
        for arg in args.split(", "):
            key, _, value = arg.partition("=")
            if value in ("True", "False"):
                kwargs[key] = value == "True"
            else:
                kwargs[key] = int(value) if value.isdigit() else value
        return cls(mode, kwargs)


#: Most envs for which tune tries one worker per env.
MAX_ONE_PER_ENV = 64
#: The ``env_concurrency`` of the threaded candidates (every other one is serial).
THREADS = "threads"
#: The deadline harvest's ``recv`` arguments besides ``max_batch`` (TorchRL's, pytorch/rl PR
#: #4182).
HARVEST = {"min_batch": 1, "timeout": 1e-3}


def _builds_pettingzoo(env_fn: Callable[[], Any]) -> bool:
    """Whether ``env_fn()`` is a PettingZoo env (tuned as rows, one per agent); it is built
    here once to see."""
    env = env_fn()
    try:
        return type(env).__module__.startswith("pettingzoo") or any(
            c.__module__.startswith("pettingzoo") for c in type(env).__mro__
        )
    finally:
        env.close()


def resolve(env: EnvLike) -> tuple[str, Any, Optional[str]]:
    """``(kind, env_fn or env_fns, gym_id)`` of what tune was given."""
    if isinstance(env, (list, tuple)):
        if not env or not all(callable(f) for f in env):
            raise TypeError("env_fns must be a non-empty list of callables building envs")
        return "hosted", list(env), None
    if isinstance(env, str) and env in NATIVE_NAMES:
        return "native", None, None
    if isinstance(env, str) and ":" in env and env not in gym.registry:
        module, _, name = env.partition(":")
        return "hosted", getattr(importlib.import_module(module), name), None
    if isinstance(env, str):
        if env not in gym.registry:
            raise ValueError(
                f"{env!r} is not a registered gymnasium id, 'module:callable' or {ENV_ID}"
            )
        return "hosted", functools.partial(gym.make, env), env
    if callable(env):
        return ("pettingzoo" if _builds_pettingzoo(env) else "hosted"), env, None
    raise TypeError(f"tune needs a gymnasium id, an env factory or {ENV_ID!r}, got {env!r}")


def candidates(
    kind: str, num_envs: int, gym_id: Optional[str], cpus: int, lends: bool = False
) -> list[Candidate]:
    """Every layout tune times for ``num_envs`` envs on ``cpus`` CPUs; ``lends``: the batch is
    large enough to be lent (``copy=True``), so three batch slots (every batch lent, one more
    batch of ``/dev/shm``) are a candidate too."""
    out: list[Candidate] = []
    workers = [w for w in range(1, 2 * cpus + 1) if w <= num_envs]
    if kind == "pettingzoo":  # whole envs per worker; the plain loop in this process
        return [
            *(
                Candidate("pool", {"num_workers": w, "copy": c})
                for w in workers
                for c in (True, False)
            ),
            Candidate("sync"),
        ]
    for w in workers:
        for copy in (True, False):
            out.append(Candidate("pool", {"num_workers": w, "copy": copy}))
        if lends:
            out.append(Candidate("pool", {"num_workers": w, "copy": True, "batch_slots": 3}))
        if w > 1:
            for b in sorted({num_envs // w, num_envs // 2} - {0}):
                out.append(Candidate("async", {"num_workers": w, "batch_size": b}))
    # One worker per env: envs that sleep (slow resets, I/O) cost no CPU while they wait, and
    # no env waits behind another.
    spread = [num_envs] if workers[-1] < num_envs <= MAX_ONE_PER_ENV else []
    for w in spread:
        out.append(Candidate("async", {"num_workers": w, "batch_size": max(1, num_envs // 2)}))
    for w in sorted({min(cpus, num_envs), *spread}):
        out.append(Candidate("harvest", {"num_workers": w, "batch_size": 1}))
    # Envs that wait: each env on a thread of its worker, so that a waiting env holds none of
    # its mates (hosted envs of one callable each), in lockstep and received as they are ready.
    if kind == "hosted":
        for w in sorted({1, min(cpus, num_envs)}):
            out.append(Candidate("pool", {"num_workers": w, "env_concurrency": THREADS}))
            out.append(
                Candidate(
                    "harvest", {"num_workers": w, "batch_size": 1, "env_concurrency": THREADS}
                )
            )
    if kind == "hosted" and gym_id is not None and gym.spec(gym_id).vector_entry_point:
        for w in workers:
            out.append(Candidate("vector", {"num_workers": w}))
    if kind == "hosted":
        out.append(Candidate("sync"))
    return out
