"""The worker's side of PettingZoo envs in the pool (see :mod:`rogue_gym.multi_agent`):
:class:`AgentRows`, the vector env a worker hosts for its block of whole PettingZoo envs, one
row per (env, agent), and the block function the pool's workers call to build it.
"""

from __future__ import annotations

from typing import Any, Callable, Optional, Sequence, Union

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..protocol.infos import add_row_info

__all__ = ["AgentRows", "block_rows", "parallel"]

#: The spaces a row can have: fixed-size arrays.
_ARRAY_SPACES = (spaces.Box, spaces.Discrete, spaces.MultiDiscrete, spaces.MultiBinary)


def parallel(env: Any) -> Any:
    """``env`` as a PettingZoo ``ParallelEnv`` (an AEC env through ``aec_to_parallel``)."""
    from pettingzoo.utils.conversions import aec_to_parallel
    from pettingzoo.utils.env import AECEnv, ParallelEnv

    if isinstance(env, ParallelEnv):
        return env
    if isinstance(env, AECEnv):
        return aec_to_parallel(env)
    raise TypeError(
        f"env_fn() returned {type(env).__name__!r}, not a PettingZoo ParallelEnv or AECEnv"
    )


def block_rows(env_fn: Callable[[], Any], agents: int, mode: str, rows: int) -> AgentRows:
    """A worker block's vector env: :class:`AgentRows` of ``rows // agents`` envs of
    ``env_fn``."""
    # The worker copies each batch into shared memory before the next call: no copy here.
    return AgentRows([env_fn] * (rows // agents), autoreset_mode=AutoresetMode(mode), copy=False)


class AgentRows(VectorEnv):
    """``len(env_fns)`` PettingZoo envs as one vector env, one row per (env, agent) (see the
    module doc for the row order, absent agents and autoreset).

    Args:
        env_fns: one callable per env, each building a PettingZoo ``ParallelEnv`` or
            ``AECEnv`` with the same ``possible_agents``.
        autoreset_mode: ``NEXT_STEP`` (default) or ``SAME_STEP``, for each env as a whole.
        copy: return a fresh observation batch from each call (``False``: the same array,
            rewritten by the next call, as the pool's worker reads it before it steps again).
    """

    def __init__(
        self,
        env_fns: Sequence[Callable[[], Any]],
        autoreset_mode: Union[str, AutoresetMode] = AutoresetMode.NEXT_STEP,
        copy: bool = True,
    ) -> None:
        if not env_fns:
            raise ValueError("env_fns is empty: give one callable per env")
        mode = AutoresetMode(autoreset_mode)
        if mode == AutoresetMode.DISABLED:
            raise ValueError("AgentRows autoresets NEXT_STEP or SAME_STEP")
        self.envs = [parallel(fn()) for fn in env_fns]
        first = self.envs[0]
        self.agents: list[Any] = list(first.possible_agents)
        self._index = {a: j for j, a in enumerate(self.agents)}
        obs_space, act_space = (
            first.observation_space(self.agents[0]),
            first.action_space(self.agents[0]),
        )
        for env in self.envs:
            if list(env.possible_agents) != self.agents:
                raise ValueError(
                    f"every env must have the same possible_agents; got {env.possible_agents} "
                    f"and {self.agents}"
                )
            for a in self.agents:
                for what, got, want in (
                    ("observation", env.observation_space(a), obs_space),
                    ("action", env.action_space(a), act_space),
                ):
                    if got != want:
                        raise ValueError(
                            f"agent {a!r} has the {what} space {got}, agent "
                            f"{self.agents[0]!r} {want}: the rows share one space; pad the "
                            f"spaces to one first (e.g. SuperSuit's pad_observations_v0 and "
                            f"pad_action_space_v0)"
                        )
        for space in (obs_space, act_space):
            if not isinstance(space, _ARRAY_SPACES):
                raise ValueError(
                    f"AgentRows needs spaces of fixed-size arrays (Box, Discrete, "
                    f"MultiDiscrete, MultiBinary), got {space}"
                )
        self.num_agents = len(self.agents)
        self.num_envs = len(self.envs) * self.num_agents
        self.single_observation_space = obs_space
        self.single_action_space = act_space
        self.observation_space = batch_space(obs_space, self.num_envs)
        self.action_space = batch_space(act_space, self.num_envs)
        self.autoreset_mode = mode
        self.copy = bool(copy)
        self.metadata = {
            "autoreset_mode": mode,
            "render_modes": list(first.metadata.get("render_modes", [])),
        }
        self.render_mode = getattr(first, "render_mode", None)
        shape = (self.num_envs, *(obs_space.shape or ()))
        self._obs: np.ndarray = np.zeros(shape, obs_space.dtype)
        #: Envs whose episode ended at the last step (NEXT_STEP: they reset at the next).
        self._ended = np.zeros(len(self.envs), bool)
        self._active = np.zeros(self.num_envs, bool)

    # -- rows ------------------------------------------------------------------------------

    def _put(self, e: int, obs: dict[Any, Any], infos: dict[Any, Any], out: dict[str, Any]) -> None:
        """Write env ``e``'s observations (zeros for absent agents) and infos into its rows."""
        base = e * self.num_agents
        self._obs[base : base + self.num_agents] = 0
        for a, o in obs.items():
            self._obs[base + self._index[a]] = o
        for a, info in infos.items():
            if info:
                add_row_info(out, info, base + self._index[a], self.num_envs)

    def _reset_env(self, e: int, seed: Optional[int], options: Any, out: dict[str, Any]) -> None:
        env = self.envs[e]
        obs, infos = env.reset(seed=seed, options=options)
        self._put(e, obs, infos, out)
        base = e * self.num_agents
        self._active[base : base + self.num_agents] = False
        for a in env.agents:
            self._active[base + self._index[a]] = True
        self._ended[e] = False

    def _batch(self) -> np.ndarray:
        return self._obs.copy() if self.copy else self._obs

    def _infos(self, out: dict[str, Any]) -> dict[str, Any]:
        out["active"] = self._active.copy()
        out["_active"] = np.ones(self.num_envs, bool)
        return out

    # -- the vector env --------------------------------------------------------------------

    def reset(
        self, *, seed: Any = None, options: Optional[dict[str, Any]] = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every env (or those with a row in ``options["reset_mask"]``); env ``e`` is
        seeded with ``s + e`` for an int ``s`` (SuperSuit's ``concat_vec_envs`` rule), with
        its first row's entry (``e * A``) for a list."""
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        n, agents = self.num_envs, self.num_agents
        if seed is None or isinstance(seed, (int, np.integer)):
            row_seeds: list[Optional[int]] = [
                None if seed is None else int(seed) + r // agents for r in range(n)
            ]
        else:
            row_seeds = [None if s is None else int(s) for s in seed]
            if len(row_seeds) != n:
                raise ValueError(f"seed list has {len(row_seeds)} entries; expected {n}")
        which = (
            np.ones(len(self.envs), bool)
            if mask is None
            else np.asarray(mask, bool).reshape(len(self.envs), agents).any(axis=1)
        )
        out: dict[str, Any] = {}
        for e in np.flatnonzero(which).tolist():
            self._reset_env(e, row_seeds[e * agents], options or None, out)
        return self._batch(), self._infos(out)

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every env with its live agents' rows of ``actions``."""
        n, agents = self.num_envs, self.num_agents
        actions = np.asarray(actions)
        rewards = np.zeros(n, np.float64)
        terminated = np.zeros(n, bool)
        truncated = np.zeros(n, bool)
        out: dict[str, Any] = {}
        finals: dict[int, tuple[Any, dict[str, Any]]] = {}
        same_step = self.autoreset_mode == AutoresetMode.SAME_STEP
        discrete = isinstance(self.single_action_space, spaces.Discrete)
        for e, env in enumerate(self.envs):
            base = e * agents
            if self._ended[e]:  # NEXT_STEP: this step is the env's reset
                self._reset_env(e, None, None, out)
                continue
            alive = list(env.agents)
            acts = {
                a: int(actions[base + self._index[a]])
                if discrete
                else actions[base + self._index[a]]
                for a in alive
            }
            obs, rew, term, trunc, infos = env.step(acts)
            self._active[base : base + agents] = False
            for a in alive:
                row = base + self._index[a]
                self._active[row] = True
                rewards[row] = rew.get(a, 0.0)
                terminated[row] = bool(term.get(a, False))
                truncated[row] = bool(trunc.get(a, False))
            if same_step:
                for a in alive:
                    row = base + self._index[a]
                    if terminated[row] or truncated[row]:
                        finals[row] = (np.array(obs.get(a, 0), self._obs.dtype), infos.get(a, {}))
                obs = {a: o for a, o in obs.items() if base + self._index[a] not in finals}
                infos = {a: i for a, i in infos.items() if base + self._index[a] not in finals}
            self._put(e, obs, infos, out)
            if not env.agents:
                self._ended[e] = True
                if same_step:  # the env's next episode starts now, its rows' first
                    self._reset_env(e, None, None, out)
        for row, (final_obs, final_info) in sorted(finals.items()):
            add_row_info(out, {"final_obs": final_obs, "final_info": final_info}, row, n)
        return self._batch(), rewards, terminated, truncated, self._infos(out)

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """``getattr(env, name)`` of each row's env (called with the arguments if callable)."""
        results = []
        for env in self.envs:
            attr = getattr(env, name)
            value = attr(*args, **kwargs) if callable(attr) else attr
            results.extend([value] * self.num_agents)
        return tuple(results)

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """The attribute ``name`` of each row's env."""
        return tuple(getattr(env, name) for env in self.envs for _ in range(self.num_agents))

    def close_extras(self, **kwargs: Any) -> None:
        """Close every env."""
        for env in self.envs:
            env.close()
