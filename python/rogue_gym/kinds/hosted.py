"""Gymnasium envs hosted in the workers as an env kind (``env_fns``, or one vector env per
worker).

The callables are cloudpickled once, here; each worker process (``python -m
rogue_gym.worker``, never a fork) builds its block of envs from them and runs the pool's Rust
loop, which calls the envs through :mod:`rogue_gym.worker.env_adapter`. Observations and actions
cross in shared memory, laid out leaf by leaf (:mod:`rogue_gym.protocol.layout`); infos cross
only when an env returns a non-empty one (:mod:`rogue_gym.protocol.infos`). The leaves of no
fixed size (Text, Graph, Sequence, OneOf, custom spaces) travel pickled per env: an
observation's with the env's info, an action's by a call before the step.
"""

from __future__ import annotations

import base64
import pickle
import sys
from dataclasses import dataclass
from typing import Any, Callable, Optional, Sequence

import cloudpickle
import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import CustomSpaceError
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_differing_spaces

from ..errors import CorruptInfoError, out_of_range, scalar_actions
from ..protocol import NO_SEED, registry
from ..protocol.infos import RESET_OBS, STEP_OBS, InfoDecoder, split_joined, vector_infos
from ..protocol.layout import FIXED_SPACES, SpaceLayout, UnsupportedSpaceError, space_leaves
from ..protocol.ops import SERVED_BY, Interpreter
from ..protocol.vector_contract import check_vector_env
from ..settings import PoolOptions
from .final_obs import add_final_obs
from .result import Result
from .spec import EnvIds, KindFacts
from .view import PoolView

__all__ = ["DEFAULT_INFO_BYTES", "HOSTED_WORKER_POLL_US", "HostedKind", "VectorEnvFn"]

#: Room per env and step for an env's info in the worker's block, in bytes (``info_bytes``);
#: a longer info travels beside the block, in a private file.
DEFAULT_INFO_BYTES = 4096
#: How long a worker of hosted envs polls for the next command before it blocks, in µs
#: (``worker_poll_us``). Between two steps the caller runs Python (decoding, the policy), and a
#: worker that has gone to sleep costs a wake-up on every step, which a poll of a few
#: milliseconds saves (``benchmarks/results/real_envs/README.md``, "Polling", has the figures).
HOSTED_WORKER_POLL_US = 2000

EnvFn = Callable[[], gym.Env]


@dataclass(frozen=True)
class VectorEnvFn:
    """One vector env per worker: ``fn(n)`` builds a vector env of ``n`` envs, one per worker
    block (see :meth:`rogue_gym.PoolVectorEnv.from_vector_env`)."""

    fn: Callable[[int], VectorEnv]
    num_envs: int
    #: Envs that stay together on one worker: every block is a multiple of it (the agents of
    #: one multi-agent env, :meth:`rogue_gym.PoolVectorEnv.from_pettingzoo`).
    unit: int = 1

    def __post_init__(self) -> None:
        if not callable(self.fn):
            raise TypeError("vector_env_fn must be a callable building a vector env of n envs")
        if int(self.num_envs) < 1:
            raise ValueError(f"num_envs must be at least 1, got {self.num_envs}")


def _check_dynamic(obs: SpaceLayout, act: SpaceLayout, vector_env: bool, static_only: bool) -> None:
    """Refuse leaves of no fixed size where they cannot go: in a hosted vector env, and with
    ``static_only`` those ``AsyncVectorEnv(..., shared_memory=True)`` refuses, with its errors
    (a ``TypeError`` for ``Graph`` and ``Sequence``, a ``ValueError`` for a custom space; it
    takes ``Text`` and ``OneOf``, which the pool carries pickled all the same)."""
    dynamic = [space for _, space in obs.dynamic + act.dynamic]
    if dynamic and vector_env:
        raise UnsupportedSpaceError(
            f"a vector env per worker needs spaces of fixed-size leaves; {dynamic[0]} has "
            "none: host single envs instead (PoolVectorEnv(env_fns))"
        )
    for space in dynamic if static_only else []:
        _refuse_unshared(space)


def _refuse_unshared(space: spaces.Space) -> None:
    """Raise ``AsyncVectorEnv(shared_memory=True)``'s error if it cannot hold ``space``."""
    for _, leaf in space_leaves(space):
        if isinstance(leaf, spaces.OneOf):
            for sub in leaf.spaces:
                _refuse_unshared(sub)
        elif isinstance(leaf, (spaces.Graph, spaces.Sequence)):
            raise TypeError(
                f"As {leaf} has a dynamic shape so its not possible to make a static shared "
                "memory. Leave shared_memory out (or False) to carry it pickled per env."
            )
        elif not isinstance(leaf, (spaces.Text, *FIXED_SPACES)):
            raise ValueError(  # from a CustomSpaceError, as AsyncVectorEnv raises it
                f"shared_memory=True needs spaces it can lay out, and {leaf} is a custom space; "
                "leave shared_memory out (or False) to carry it pickled per env"
            ) from CustomSpaceError(f"{type(leaf).__name__} has no shared-memory layout")


def _space_of(fn: EnvFn) -> spaces.Space:
    """The observation space of the env ``fn`` builds (built here, then closed)."""
    env = fn()
    try:
        return env.observation_space
    finally:
        env.close()


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


class HostedKind:
    """Envs built by ``env_fns`` (one per env) or by a :class:`VectorEnvFn`, in the workers.

    Args:
        env_fns: one callable per env (all envs must have the same spaces), or a
            :class:`VectorEnvFn`.
        options: the pool's options (checked here).
        autoreset_mode: the facade's (a hosted vector env must autoreset so).
        info_bytes: room per env and step for the env's info in shared memory.
        static_only: refuse spaces with leaves of no fixed size, as ``AsyncVectorEnv(...,
            shared_memory=True)`` does (gymnasium's errors).
        observation_mode: ``"same"`` (every env has env 0's observation space), ``"different"``
            (spaces of one layout that differ otherwise, e.g. in their bounds: every env is
            built here once for its space, as ``AsyncVectorEnv`` does) or a ``(batch,
            single)`` pair of spaces; the workers check each env's space against it.
    """

    def __init__(
        self,
        env_fns: Any,
        options: PoolOptions,
        autoreset_mode: AutoresetMode,
        info_bytes: int = DEFAULT_INFO_BYTES,
        static_only: bool = False,
        observation_mode: Any = "same",
    ) -> None:
        hosted = env_fns if isinstance(env_fns, VectorEnvFn) else None
        self._block_unit = 1 if hosted is None else int(hosted.unit)
        fns: list[EnvFn] = [] if hosted is not None else list(env_fns)
        if hosted is None and not fns:
            raise ValueError("env_fns is empty: give one callable per env")
        self.num_envs = len(fns) if hosted is None else int(hosted.num_envs)
        checked = options.checked_pool(self.num_envs)
        self.options = PoolOptions(**{**vars(options), **checked})
        if hosted is not None and self.options.env_threads():
            raise ValueError(
                "env_concurrency: a vector env per worker steps its envs itself; threads are for "
                "envs of one callable each (PoolVectorEnv(env_fns, env_concurrency=...))"
            )
        # Probe one env here for the spaces and metadata, as AsyncVectorEnv does.
        probe: Any
        if hosted is None:
            probe = fns[0]()
            if not isinstance(probe, gym.Env):
                raise TypeError(
                    f"env_fns[0]() returned {type(probe).__name__!r}, not a gymnasium.Env: each "
                    "env function must build and return an env (e.g. lambda: "
                    "gym.make('CartPole-v1'))"
                )
        else:
            probe = hosted.fn(hosted.unit)
        try:
            if hosted is None:
                self.single_observation_space = probe.observation_space
                self.single_action_space = probe.action_space
            else:
                check_vector_env(probe, hosted.unit, autoreset_mode)
                self.single_observation_space = probe.single_observation_space
                self.single_action_space = probe.single_action_space
            metadata: dict[str, Any] = dict(probe.metadata)
            render_mode, env_spec = probe.render_mode, getattr(probe, "spec", None)
        finally:
            probe.close()
        #: The batch observation space when the envs' spaces differ (``None``: batched as one).
        self.batch_observation_space: Optional[spaces.Space] = None
        if observation_mode == "different":
            if hosted is not None:
                raise ValueError("observation_mode='different' needs env_fns, one per env")
            per_env = [_space_of(fn) for fn in fns]
            self.single_observation_space = per_env[0]
            self.batch_observation_space = batch_differing_spaces(per_env)
        elif observation_mode != "same":
            self.batch_observation_space, self.single_observation_space = observation_mode
        self._obs_layout = SpaceLayout(self.single_observation_space)
        self.obs_bytes = self._obs_layout.stride
        act = self.single_action_space
        self._discrete = act if isinstance(act, spaces.Discrete) else None
        self._discrete_range = (0, 0) if self._discrete is None else (int(act.start), int(act.n))
        self._act_layout = SpaceLayout(act)
        _check_dynamic(self._obs_layout, self._act_layout, hosted is not None, static_only)
        #: Each env's dynamic observation leaves, as its last info brought them.
        self._dynamic_obs: list[list[Any]] = [
            [None] * len(self._obs_layout.dynamic)
        ] * self.num_envs
        #: Bytes of one action on the wire (at least 1: a space of dynamic leaves only).
        self._act_bytes = max(self._act_layout.nbytes, 1)
        self._act_rows = np.zeros((self.num_envs, self._act_bytes), np.uint8)
        self._view: Optional[PoolView] = None
        spec = {
            "obs_shape": [self.obs_bytes],
            "dtype": "u8",
            "num_actions": 0 if self._discrete is None else int(self._discrete.n),
            "info_names": [],
            "action_bytes": 0 if self._discrete is not None else self._act_bytes,
            "extra_bytes": int(info_bytes),
        }
        adapter: dict[str, Any] = {
            "sys_path": [p for p in sys.path if p],
            # Ids registered here exist in the workers too (never forked).
            "registry": registry.capture(),
            "spaces": _b64(cloudpickle.dumps((self.single_observation_space, act))),
            "discrete_start": None if self._discrete is None else int(self._discrete.start),
            # Each env's observation space must equal env 0's, or only have its layout.
            "same_obs_space": observation_mode == "same",
        }
        if hosted is None:
            pickled = [cloudpickle.dumps(fn) for fn in fns]
            unique = list(dict.fromkeys(pickled))
            adapter["env_fns"] = [_b64(p) for p in unique]
            adapter["fn_of_env"] = [unique.index(p) for p in pickled]
        else:
            adapter["vector_env_fn"] = _b64(cloudpickle.dumps(hosted.fn))
            adapter["autoreset_mode"] = autoreset_mode.value
        self._env = {
            "kind": "python" if hosted is None else "python-vector",
            "spec": spec,
            "adapter": adapter,
        }
        self._pool_spec = spec
        self._decoder = InfoDecoder()
        #: (SAME_STEP) each ended env's final dynamic leaves and last step info, until read.
        self._finals: dict[int, tuple[list[Any], dict[str, Any]]] = {}
        filler = self._fill_dynamic if self._obs_layout.dynamic else None
        who = Interpreter.HOSTED if hosted is None else Interpreter.HOSTED_VECTOR
        self.facts = KindFacts(
            num_envs=self.num_envs,
            single_observation_space=self.single_observation_space,
            single_action_space=self.single_action_space,
            metadata=metadata,
            render_mode=render_mode,
            env_spec=env_spec,
            worker_command=checked["worker_command"],
            who=who,
            ops=SERVED_BY[who],
            obs_filler=filler,
            info_counts=self._decoder.counts,
        )

    # -- the pool --------------------------------------------------------------------------

    def pool_settings(self) -> dict[str, Any]:
        """The native pool's settings: the envs' pickles and spaces, no seeds yet."""
        return {
            **self.options.pool_json(self.num_envs, HOSTED_WORKER_POLL_US),
            "env": self._env,
            "spec": self._pool_spec,
            "seeds": self._seeds(None),
            "block_unit": self._block_unit,
        }

    def bind(self, view: PoolView) -> None:
        """Keep the view: env operations, dynamic actions and final observations go through
        it; infos are decoded as they come."""
        self._view = view

    def _bound(self) -> PoolView:
        """The view of the running pool."""
        if self._view is None:
            raise RuntimeError("the hosted kind is not bound to a running pool yet")
        return self._view

    def batch_views(self, rows: np.ndarray) -> Any:
        """Slot rows as a batch of the observation space, leaf by leaf (views)."""
        return self._obs_layout.batch_views(rows)

    def _fill_dynamic(self, obs: Any, env_ids: Optional[np.ndarray]) -> Any:
        """``obs`` with its dynamic leaves (one tuple of values per leaf, as gymnasium batches
        them) from the envs' last infos."""
        ids = range(self.num_envs) if env_ids is None else [int(e) for e in env_ids]
        values = [self._dynamic_obs[e] for e in ids]
        columns = [tuple(v[j] for v in values) for j in range(len(self._obs_layout.dynamic))]
        return self._obs_layout.fill(obs, columns)

    # -- actions and seeds -----------------------------------------------------------------

    def actions(self, actions: Any, env_ids: Optional[EnvIds]) -> np.ndarray:
        """Discrete actions as indices from 0 (checked in the space's terms, ``start``
        included); others as their raw bytes, leaf by leaf."""
        n = self.num_envs if env_ids is None else len(env_ids)
        if not isinstance(actions, (dict, tuple, list)) and np.ndim(actions) == 0:
            raise TypeError(scalar_actions(n))
        if self._discrete is not None:
            return self._discrete_indices(actions, env_ids, n)
        rows = self._act_rows if env_ids is None else np.zeros((n, self._act_bytes), np.uint8)
        flat = self._act_layout.flat_batch(actions, rows)
        if self._act_layout.dynamic:
            self._stage_dynamic_actions(actions, env_ids, n)
        return flat

    def _stage_dynamic_actions(self, actions: Any, env_ids: Optional[EnvIds], n: int) -> None:
        """Stage each env's values of its action's dynamic leaves (pickled) with the pool:
        the step command to its worker carries them."""
        columns = self._act_layout.dynamic_values(actions)
        for (path, space), column in zip(self._act_layout.dynamic, columns):
            where = "".join(f"[{k!r}]" for k in path) or "actions"
            if not isinstance(column, (tuple, list, np.ndarray)):
                raise TypeError(f"{where} must be a tuple of one value of {space} per env")
            if len(column) != n:
                raise ValueError(f"{where} has {len(column)} values of {space}; expected {n}")
        ids = range(n) if env_ids is None else env_ids
        extras = [
            (int(env), pickle.dumps(list(row), protocol=pickle.HIGHEST_PROTOCOL))
            for env, row in zip(ids, zip(*columns))
        ]
        self._bound().stage_action_extras(extras)

    def _discrete_indices(self, actions: Any, env_ids: Optional[EnvIds], n: int) -> np.ndarray:
        a = np.asarray(actions)
        if a.shape != (n,) or a.dtype.kind not in "iu":
            raise ValueError(f"expected integer actions of shape ({n},), got {a.dtype} {a.shape}")
        space = self._discrete
        assert space is not None
        start, size = self._discrete_range
        wide = a.astype(object) if a.dtype.kind == "u" and a.dtype.itemsize >= 8 else a
        if n and (wide.min() < start or wide.max() >= start + size):
            j = int(np.flatnonzero((wide < start) | (wide >= start + size))[0])
            env = j if env_ids is None else env_ids[j]
            raise ValueError(out_of_range(env, a[j], start, start + size - 1, space))
        out = a.astype(np.int64)
        if start:
            out -= start
        return out

    def _unit_seeds(self, seed: int) -> list[int]:
        """Rows in units of ``block_unit`` (one PettingZoo env's agents): every row of unit
        ``u`` gets ``seed + u``, so that env ``u`` is seeded with ``seed + u`` as SuperSuit's
        ``concat_vec_envs`` seeds it."""
        if seed < 0 or seed + self.num_envs > 2**63:
            raise ValueError(f"seed must be in [0, 2**63 - num_envs), got {seed}")
        return [seed + r // self._block_unit for r in range(self.num_envs)]

    def _seeds(self, seed: Any) -> dict[str, Any]:
        """The schedule for ``reset(seed=...)``: env ``i``'s next episode gets ``seed + i`` (or
        ``seed[i]``), or no seed at all for ``None``; later episodes are not reseeded."""
        if seed is None:
            return {"base": 0, "set": {"list": [NO_SEED]}, "policy": "sequential"}
        if isinstance(seed, (int, np.integer)) and self._block_unit > 1:
            seed = self._unit_seeds(int(seed))
        if isinstance(seed, (int, np.integer)):
            start = int(seed)
            if start < 0 or start + self.num_envs > 2**63:
                raise ValueError(f"seed must be in [0, 2**63 - num_envs), got {seed}")
            return {
                "base": start,
                "set": {"range": {"start": start, "end": start + self.num_envs}},
                "policy": "sequential",
            }
        seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise ValueError(
                f"seed list has {len(seeds)} entries; expected one per env ({self.num_envs})"
            )
        if any(s is None for s in seeds):
            raise ValueError(
                "a seed list cannot mix None and seeds; pass seed=None to seed from entropy"
            )
        values = [int(s) for s in seeds]
        if any(s < 0 or s >= 2**63 for s in values):
            raise ValueError("seeds must be in [0, 2**63)")
        return {"base": 0, "set": {"list": values}, "policy": "sequential"}

    def seeds(self, seed: Any, mask: Optional[np.ndarray]) -> Optional[dict[str, Any]]:
        """A full reset: an int seeds env ``i`` with ``seed + i``, a list seeds each env;
        ``None`` keeps each env's generator (a first reset without a seed reseeds nothing, as
        gymnasium's). A partial reset: see :meth:`_seed_partial`."""
        if mask is not None:
            self._seed_partial(seed, mask)
            return None
        if seed is None and self._bound().state.started:
            return None
        return self._seeds(seed)

    def _seed_partial(self, seed: Any, mask: np.ndarray) -> None:
        """The masked envs' next reset gets ``seed + i`` (an int) or ``seed[i]`` (a list; a
        ``None`` entry: no reseeding), as gymnasium's vector envs seed a partial reset."""
        if isinstance(seed, (int, np.integer)) and self._block_unit > 1:
            seeds: list[Optional[int]] = list(self._unit_seeds(int(seed)))
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(
                    f"seed list has {len(seeds)} entries; expected one per env ({self.num_envs})"
                )
        chosen = {int(i): s for i in np.flatnonzero(mask) if (s := seeds[i]) is not None}
        if any(not 0 <= int(s) < 2**63 for s in chosen.values()):
            raise ValueError("seeds must be in [0, 2**63)")
        if chosen:
            args: list[tuple[tuple[Any, ...], dict[str, Any]]] = [
                ((int(s),), {}) for s in chosen.values()
            ]
            self.run_ops("set_reset_seed", "", args, list(chosen))

    # -- infos -----------------------------------------------------------------------------

    def infos(self, result: Result, only: Optional[np.ndarray]) -> dict[str, Any]:
        """The infos the envs returned, merged as gymnasium's vector envs merge them, and
        SAME_STEP's final observations (dynamic leaves included) with their last step's info."""
        view = self._bound()
        if not (view.same_step and result.has_final):
            return self._env_infos(result, set())
        final = {int(i) for i in np.flatnonzero(result.cols["has_final_obs"])}
        infos = self._env_infos(result, final)
        return add_final_obs(infos, view, result, self.batch_views, self._final)

    def _env_infos(self, result: Result, final: set[int]) -> dict[str, Any]:
        """The envs' own infos (those of ``final``: their reset's; their last step's info and
        final dynamic leaves are kept for :meth:`_final`). Bytes that do not decode raise
        :class:`~rogue_gym.errors.CorruptInfoError` naming the env, the error as its cause."""
        try:
            return self._decoded_infos(result, final)
        except Exception as err:
            raise CorruptInfoError(self._culprit(result), f"{type(err).__name__}: {err}") from err

    def _culprit(self, result: Result) -> int:
        """The env of the first row whose info bytes do not decode on their own (the first
        row that has some when each does)."""
        if result.extras is None:
            return int(result.ids()[0])
        joined, data, size, ends = result.extras
        rows = split_joined(joined, data, size, ends, result.rows)
        for row, data in rows:
            try:
                InfoDecoder().entries(bytes(data))
            except Exception:
                return int(result.ids()[row])
        return int(result.ids()[rows[0][0] if rows else 0])

    def _decoded_infos(self, result: Result, final: set[int]) -> dict[str, Any]:
        """:meth:`_env_infos`, trusting the bytes."""
        rows = result.rows
        infos: dict[str, Any] = {}
        extras: list[tuple[int, bytes]] = []
        if result.extras is not None:
            joined, data, size, ends = result.extras
            if size and not final and self._decoder.put_uniform(infos, data, joined, rows):
                return infos  # the usual step: one typed info layout, decoded in one go
            extras = split_joined(joined, data, size, ends, rows)
        elif not final:
            return infos
        env_of = result.ids()
        return vector_infos(
            infos,
            self._decoder,
            extras,
            rows,
            lambda row, entries: self._env_info(int(env_of[row]), entries, row in final),
            final,
        )

    def _env_info(self, env: int, entries: list[tuple[str, Any]], final: bool) -> dict[str, Any]:
        """One env's info for this call: the reset's (or step's). When the episode ended in
        SAME_STEP mode, the last step's info and the final observation's dynamic leaves are
        kept for :meth:`_final`."""
        info: dict[str, Any] = {}
        final_info: dict[str, Any] = {}
        final_dynamic: list[Any] = []
        for tag, entry in entries:
            if tag == STEP_OBS and final:
                final_dynamic = entry
            elif tag in (STEP_OBS, RESET_OBS):
                self._dynamic_obs[env] = entry
            elif tag == "step" and final:
                final_info = entry
            else:
                info.update(entry)
        if final:
            self._finals[env] = (final_dynamic, final_info)
        return info

    def _final(self, env: int, obs: Any) -> tuple[Any, dict[str, Any]]:
        """(SAME_STEP) env ``env``'s final observation ``obs`` with its dynamic leaves, and the
        info of its last step."""
        dynamic, info = self._finals.pop(env, ([], {}))
        return self._obs_layout.env_value(obs, dynamic), info

    # -- calls and render ------------------------------------------------------------------

    def run_ops(
        self,
        op: str,
        name: str,
        arguments: Sequence[tuple[tuple[Any, ...], dict[str, Any]]],
        indices: Sequence[int],
    ) -> list[Any]:
        """Run ``op`` in the envs' workers; an env's exception is re-raised here."""
        return self._bound().call_envs(op, name, list(zip(indices, arguments)))

    def render(self) -> Optional[tuple[Any, ...]]:
        """Every env's ``render()``."""
        n = self.num_envs
        return tuple(self.run_ops("render", "", [((), {})] * n, range(n)))
