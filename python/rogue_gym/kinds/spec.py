"""What an env kind is: the :class:`Kind` spec the front binds once per vector env.

A kind says what differs between the envs a pool can host, and nothing more: its spaces and
facts, the native pool's settings, its seeds, how actions and observations are coded in
shared memory, how a call's columns and extra info become infos, which env operations it
serves, and how it renders. The front (:mod:`rogue_gym.front`) owns every call and its
lifecycle (started, ended episodes, restarted workers, the episode log) for every kind.

A new kind is one module of this package implementing :class:`Kind`;
``tests/python/test_kind_spec.py`` builds a small one (the pool's built-in test env) to show
the least one needs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable, Optional, Protocol, Sequence

import numpy as np
from gymnasium import spaces

if TYPE_CHECKING:
    from ..front.core import Core, Result

__all__ = ["Kind"]


class Kind(Protocol):
    """An env kind, as data and a few callables. The step path calls :meth:`actions` and
    :meth:`infos` once per step, never anything per env."""

    @property
    def num_envs(self) -> int:
        """Envs in the pool."""
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

    @property
    def log_steps(self) -> Optional[int]:
        """Longest episode the front logs for a replay (:attr:`Core.log`), or ``None``
        for a kind that does not render by replay."""
        ...

    @property
    def obs_bytes(self) -> int:
        """Bytes of one env's observation in a batch slot."""
        ...

    def pool_settings(self) -> dict[str, Any]:
        """The native pool's settings (JSON object) but the autoreset mode and slot count."""
        ...

    def bind(self, core: Core) -> None:
        """Called once the pool runs (per-buffer templates, the pool's info names)."""
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

    def infos(self, core: Core, result: Result, only: Optional[np.ndarray]) -> dict[str, Any]:
        """The infos of a call's rows (``only``: a partial reset's mask; the other rows' info
        is empty), as gymnasium's vector envs return them. The front adds what every kind
        reports (``final_obs``/``final_info`` in SAME_STEP, ``worker_restarted``, ``env_id``)."""
        ...

    def final(self, core: Core, env: int) -> tuple[Any, dict[str, Any]]:
        """(SAME_STEP, after :meth:`infos` of a step where env ``env``'s episode ended) its
        final observation and the info of its last step; the front adds them to the infos as
        gymnasium does (``final_obs``, ``final_info``)."""
        ...

    def call(
        self,
        core: Core,
        op: str,
        name: str,
        arguments: Sequence[tuple[tuple[Any, ...], dict[str, Any]]],
        indices: Sequence[int],
    ) -> list[Any]:
        """Run env operation ``op`` (one of :attr:`ops`) on the envs ``indices`` with
        ``arguments[j]`` for the ``j``-th; one result each."""
        ...

    def info_counts(self) -> tuple[int, int]:
        """Env info rows received so far as typed rows and as pickles (``stats()``)."""
        ...

    def render(self, core: Core) -> Optional[tuple[Any, ...]]:
        """Every env's frame in the render mode."""
        ...
