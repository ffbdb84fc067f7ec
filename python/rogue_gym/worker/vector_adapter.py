"""The worker side of a hosted *vector* env: one gymnasium ``VectorEnv`` (for instance ale-py's
C++ ``AtariVectorEnv``) for a worker's whole block of envs, built from the caller's cloudpickled
``vector_env_fn(num_envs)``.

The pool's Rust worker loop (``python/src/hosted.rs``) calls :class:`HostedVectorEnv` once per
command for the whole block: it keeps each env's episode bookkeeping itself, and this adapter
resets or steps the vector env, writes the batch of observations straight into the worker's
rows of shared memory and returns rewards and flags as raw arrays and each env's info as bytes
(:mod:`rogue_gym.protocol.infos`). The vector env must autoreset as the pool does; in
``SAME_STEP`` mode the final observations of the envs whose episode ended go to their rows of
the worker's final-observation area, and their last step's info travels as the env's step
entry, before its reset's.
"""

from __future__ import annotations

import base64
import contextlib
import json
import pickle
from typing import Any, Optional

import cloudpickle
import numpy as np
from gymnasium.vector import AsyncVectorEnv, AutoresetMode, SyncVectorEnv

from ..protocol import NO_SEED
from ..protocol.exceptions import EncodedEnvError, encode_exception
from ..protocol.infos import InfoEncoder, split_vector_info
from ..protocol.layout import SpaceLayout
from ..protocol.ops import op_table, run_op
from ..protocol.vector_contract import check_vector_env
from .env_adapter import explained, prepare

__all__ = ["WHO", "HostedVectorEnv"]

#: This interpreter's name in :data:`rogue_gym.protocol.ops.SERVED_BY`.
WHO = "a hosted vector env"


def _seed_arg(seeds: list[Optional[int]], envs: Any) -> Any:
    """The ``seed`` argument of ``envs.reset`` for one seed (or ``None``) per env of the block
    (``None`` too for an env not being reset): ``None`` for none, an ``int`` for consecutive
    seeds of every env (what every vector env takes), else the list for gymnasium's own
    vector envs and an ``int64`` array with -1 for "no seed" for others (ale-py's
    convention)."""
    if all(s is None for s in seeds):
        return None
    first = seeds[0]
    if first is not None and all(s == first + i for i, s in enumerate(seeds)):
        return first
    if isinstance(envs, (SyncVectorEnv, AsyncVectorEnv)):
        return seeds
    return np.array([-1 if s is None else s for s in seeds], np.int64)


class HostedVectorEnv:
    """One worker's vector env (built by :meth:`build`) and the byte codecs of its spaces."""

    def __init__(
        self, envs: Any, first: int, obs_space: Any, action_space: Any, discrete_start: Any
    ) -> None:
        self.envs = envs
        self.n = int(envs.num_envs)
        #: The pool's index of the block's first env.
        self.first = first
        self._obs = SpaceLayout(obs_space)
        self._act = SpaceLayout(action_space)
        self._discrete_start: Optional[int] = discrete_start
        #: Whether each env has not been reset yet (its first reset is seeded in any episode).
        self._fresh = np.ones(self.n, bool)
        self._options: Optional[dict[str, Any]] = None
        #: Seeds of the next reset of some envs (a seeded partial reset sets them by a call).
        self._seeds: dict[int, int] = {}
        self._encoder = InfoEncoder()
        self._ops = op_table(self, WHO)
        #: The last batch of observations (what envs not being reset show again).
        self._last: Any = None

    @classmethod
    def build(cls, config_json: str, first: int, count: int) -> HostedVectorEnv:
        """Build the vector env of the pool's envs ``first .. first + count`` from the front
        end's adapter config (the caller's ``sys_path``, the pickled ``vector_env_fn``, the
        spaces and autoreset mode every env must have)."""
        try:
            cfg = json.loads(config_json)
            prepare(cfg)
            fn = cloudpickle.loads(base64.b64decode(cfg["vector_env_fn"]))
            obs_space, action_space = cloudpickle.loads(base64.b64decode(cfg["spaces"]))
            with explained():
                envs = fn(count)
            try:
                check_vector_env(envs, count, AutoresetMode(cfg["autoreset_mode"]))
                for what, got, want in (
                    ("observation", envs.single_observation_space, obs_space),
                    ("action", envs.single_action_space, action_space),
                ):
                    if got != want:
                        raise ValueError(
                            f"the vector env of envs {first}..{first + count - 1} has the {what} "
                            f"space {got}, but the probe had {want}"
                        )
            except BaseException:
                with contextlib.suppress(Exception):
                    envs.close()
                raise
            return cls(envs, first, obs_space, action_space, cfg["discrete_start"])
        except BaseException as exc:
            raise EncodedEnvError(encode_exception(exc)) from exc

    def _write(self, obs: Any, address: int) -> None:
        self._obs.write_batch(obs, self._obs.rows_at(address, self.n))
        self._last = obs

    def _split(self, info: dict[str, Any]) -> list[dict[str, Any]]:
        """Each env's part of a vector info dict; an ``env_id`` (the async vector envs'
        convention: ale-py, EnvPool) becomes the pool's index, not the block's."""
        ids = info.get("env_id")
        if isinstance(ids, np.ndarray) and ids.shape == (self.n,) and ids.dtype.kind in "iu":
            info = {**info, "env_id": ids + ids.dtype.type(self.first)}
        return split_vector_info(info, self.n)

    def _encode(self, entries: list[list[tuple[str, dict[str, Any]]]]) -> Any:
        """Each env's info bytes from its entries (``None`` for none), or ``None`` if no env
        has any."""
        if not any(entries):
            return None
        encode = self._encoder.encode
        return [encode(e) if e else None for e in entries]

    def _write_final(self, final_obs: Any, ended: Any, address: int) -> None:
        """Write the final observations of the envs ``ended`` to their rows at ``address``."""
        if final_obs is None:
            raise ValueError(
                "the vector env autoresets SAME_STEP but its step info has no 'final_obs' for "
                "the envs whose episode ended"
            )
        for j in ended:
            self._obs.writer_at(address + int(j) * self._obs.stride)(final_obs[j])

    def reset(
        self, mask: bytes, seeds: bytes, episodes: bytes, address: int
    ) -> Optional[list[Optional[bytes]]]:
        """Reset the envs of ``mask`` (one byte per env), each seeded with its entry of
        ``seeds`` (``uint64``) if it is its schedule's first episode (``episodes``) or its
        first reset, unless it is :data:`~rogue_gym.protocol.NO_SEED`; write every env's
        observation at ``address``. Returns each env's info bytes, or ``None``."""
        try:
            which = np.frombuffer(mask, np.bool_)
            seed_of = np.frombuffer(seeds, np.uint64)
            first = (np.frombuffer(episodes, np.uint64) == 0) | self._fresh
            ids = np.flatnonzero(which)
            if ids.size == 0:  # no env of this block is reset: the same observations again
                if self._last is None:
                    raise RuntimeError("the vector env has no observations yet: reset it first")
                self._write(self._last, address)
                return None
            use: list[Optional[int]] = [None] * self.n
            for i in ids.tolist():
                scheduled = int(seed_of[i]) if first[i] and seed_of[i] != NO_SEED else None
                use[i] = self._seeds.pop(i, scheduled)
            options = dict(self._options or {})
            self._options = None
            if not which.all():
                options["reset_mask"] = which.copy()
            seed = _seed_arg(use, self.envs)
            obs, info = self.envs.reset(seed=seed, options=options or None)
            self._fresh[ids] = False
            self._write(obs, address)
            if not info:
                return None
            rows = self._split(info)
            return self._encode(
                [[("reset", rows[i])] if rows[i] and which[i] else [] for i in range(self.n)]
            )
        except BaseException as exc:
            raise EncodedEnvError(encode_exception(exc)) from exc

    def step(
        self, actions: bytes, address: int, final_address: int
    ) -> tuple[bytes, bytes, bytes, Any]:
        """Step every env with ``actions`` (one ``uint64`` index per env for a Discrete
        space, else each env's action bytes in rows of whole words) and write the observations
        at ``address`` (and, ``SAME_STEP`` when ``final_address`` is not 0, the final
        observations of the envs whose episode ended there). Returns the rewards
        (``float64``), terminations and truncations (one byte each) and each env's info bytes,
        or ``None``."""
        try:
            if self._discrete_start is not None:
                acts: Any = np.frombuffer(actions, np.int64) + self._discrete_start
            else:
                rows = np.frombuffer(actions, np.uint8).reshape(self.n, -1)
                acts = self._act.batch_views(rows.copy())
            obs, rewards, terminated, truncated, info = self.envs.step(acts)
            self._write(obs, address)
            terminated = np.asarray(terminated, np.bool_)
            truncated = np.asarray(truncated, np.bool_)
            ended = np.flatnonzero(terminated | truncated) if final_address else ()
            finals: list[dict[str, Any]] = []
            if len(ended):  # SAME_STEP: the final observations and infos ride in the info
                info = dict(info)
                self._write_final(info.pop("final_obs", None), ended, final_address)
                finals = self._split(info.pop("final_info", None) or {})
                for key in ("_final_obs", "_final_info"):
                    info.pop(key, None)
            parts = self._split(info) if info else [{}] * self.n
            entries = [[("step", p)] if p else [] for p in parts]
            for j in ended:  # the last step's info, then the reset's
                entries[j] = [("step", finals[j])] if finals[j] else []
                if parts[j]:
                    entries[j].append(("reset", parts[j]))
            return (
                np.asarray(rewards, np.float64).tobytes(),
                terminated.tobytes(),
                truncated.tobytes(),
                self._encode(entries),
            )
        except BaseException as exc:
            raise EncodedEnvError(encode_exception(exc)) from exc

    def call(self, row: int, request: bytes) -> bytes:
        """Answer a call for env ``row`` (a pickled ``(op, name, args, kwargs)``, as
        :meth:`rogue_gym.worker.env_adapter.HostedEnv.call`) through the vector env's own
        ``call``/``get_attr``/``set_attr``/``render`` (this env's element), or the next
        reset's options and seed. The operations that need the env itself (``setattr`` on the
        outermost wrapper, ``is_wrapped``) are refused: a vector env does not hand its envs
        out."""
        try:
            op, name, args, kwargs = pickle.loads(request)
            value = run_op(self._ops, WHO, op, name, row, *args, **kwargs)
            return bytes(cloudpickle.dumps(("ok", value)))
        except BaseException as exc:
            return bytes(cloudpickle.dumps(("err", encode_exception(exc))))

    # The env operations (protocol.ops) for env ``row`` of the block.
    def _op_call(self, name: str, row: int, *args: Any, **kwargs: Any) -> Any:
        if name in ("reset", "step", "close"):
            raise ValueError(f"call({name!r}) is not allowed; use the vector env's own")
        return self.envs.call(name, *args, **kwargs)[row]

    _op_env_method = _op_call

    def _op_get_attr(self, name: str, row: int) -> Any:
        return self.envs.get_attr(name)[row]

    def _op_has_attr(self, name: str, row: int) -> bool:
        try:
            self.envs.get_attr(name)
        except AttributeError:
            return False
        return True

    def _op_set_wrapper_attr(self, name: str, row: int, value: Any) -> None:
        values = list(self.envs.get_attr(name))
        values[row] = value
        self.envs.set_attr(name, values)

    def _op_render(self, name: str, row: int) -> Any:
        return self.envs.call("render")[row]

    def _op_set_reset_options(self, name: str, row: int, options: Any) -> None:
        self._options = options

    def _op_set_reset_seed(self, name: str, row: int, seed: int) -> None:
        self._seeds[row] = int(seed)

    def close(self) -> None:
        """Close the vector env (when the worker exits); errors are ignored."""
        with contextlib.suppress(Exception):
            self.envs.close()
