"""What a vector env class needs from an env kind (:class:`Kind`)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Optional, Protocol, Sequence

import numpy as np
from gymnasium import spaces

if TYPE_CHECKING:
    from ..front.core import Core

__all__ = ["Kind"]


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

    def actions(self, actions: Any, env_ids: Optional[Sequence[int]]) -> np.ndarray:
        """A batch of actions (for every env, or ``env_ids``) checked, as the pool takes them:
        int64 indices or uint8 bytes."""
        ...

    def seed_schedule(self, seed: Any, core: Core) -> Optional[dict[str, Any]]:
        """The episode-seed schedule for ``reset(seed=seed)``; ``None`` keeps the current one.
        ``ValueError``/``TypeError`` for a seed the kind cannot take."""
        ...

    def reset_infos(self, core: Core, slot: int, only: Optional[np.ndarray]) -> dict[str, Any]:
        """The infos of a reset of every env, or of the envs of ``only`` (a partial reset)."""
        ...

    def step_infos(self, core: Core, slot: int, summary: int, same_step: bool) -> dict[str, Any]:
        """The infos of a step (``final_obs``/``final_info`` in SAME_STEP, ``worker_restarted``)."""
        ...

    def recv_infos(
        self, core: Core, recs: np.ndarray, blocks: list[Any], env_id: np.ndarray
    ) -> dict[str, Any]:
        """The infos of an async ``recv`` batch (rows in ``env_id`` order)."""
        ...

    def call(
        self,
        core: Core,
        op: str,
        name: str,
        arguments: Sequence[tuple[tuple[Any, ...], dict[str, Any]]],
        indices: Sequence[int],
    ) -> list[Any]:
        """Run call operation ``op`` (:data:`rogue_gym.hosted.adapter.CALL_OPS`) on the envs
        ``indices`` with ``arguments[j]`` for the ``j``-th; one result each."""
        ...

    def info_counts(self) -> tuple[int, int]:
        """Env info rows received so far as typed rows and as pickles (``stats()``)."""
        ...

    def render(self, core: Core) -> Optional[tuple[Any, ...]]:
        """Every env's frame in the render mode."""
        ...
