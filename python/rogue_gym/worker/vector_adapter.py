"""The worker side of a hosted *vector* env: one gymnasium ``VectorEnv`` (for instance ale-py's
C++ ``AtariVectorEnv``) for a worker's whole block of envs, built from the caller's cloudpickled
``vector_env_fn(num_envs)``.

The pool's Rust worker loop (``python/src/worker/hosted_vector.rs``) calls :class:`HostedVectorEnv` once per
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
from ..protocol.ops import Interpreter, op_table, run_op
from ..protocol.vector_contract import check_vector_env
from .env_adapter import explained, prepare

__all__ = ["WHO", "HostedVectorEnv"]

#: The operations that read or act on every env of the vector env at once (one vector call).
_ONCE_FOR_ALL = frozenset({"call", "env_method", "get_attr", "has_attr", "render"})


def _refuse_some(name: str, n: int) -> Any:
    raise ValueError(
        f"call({name!r}): a vector env per worker runs a call on all its {n} envs at once, "
        "with the same arguments: call it on every env (the pool's call() does), not on "
        "some of them"
    )


#: This interpreter in :data:`rogue_gym.protocol.ops.SERVED_BY`.
WHO = Interpreter.HOSTED_VECTOR


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

    def call_block(self, rows: list[int], requests: list[bytes]) -> list[bytes]:
        """Answer one call file's requests, ``requests[i]`` (a pickled ``(op, name, args,
        kwargs)``, as :meth:`rogue_gym.worker.env_adapter.HostedEnv.call`) for env ``rows[i]``
        of the block: each env's reply a cloudpickled ``("ok", value)`` or ``("err", encoded
        exception)``, with the vector env's operations run once
        for all the envs that asked, not once per env. The same ``call``/``env_method`` (or
        ``get_attr``, ``has_attr``, ``render``) asked of every env is one vector call; a
        ``set_attr`` of every env one ``set_attr`` with each env's value (a new attribute
        too). ``call``/``env_method`` of some of the envs only, or with different arguments
        per env, is refused: the vector env runs a call on all its envs."""
        try:
            decoded = [pickle.loads(r) for r in requests]
        except BaseException as exc:
            failed = bytes(cloudpickle.dumps(("err", encode_exception(exc))))
            return [failed] * len(rows)
        whole = sorted(rows) == list(range(self.n))
        ops = {d[0] for d in decoded}
        if len(ops) == 1:
            op = next(iter(ops))
            if op in _ONCE_FOR_ALL and len(set(requests)) == 1:
                return self._once_for_all(decoded[0], rows, whole)
            if op == "set_wrapper_attr" and whole and len({d[1] for d in decoded}) == 1:
                return self._set_all(decoded, rows)
        return [self._one(row, d) for row, d in zip(rows, decoded)]

    def _reply(self, run: Any) -> bytes:
        try:
            return bytes(cloudpickle.dumps(("ok", run())))
        except BaseException as exc:
            return bytes(cloudpickle.dumps(("err", encode_exception(exc))))

    def _one(self, row: int, request: tuple[Any, ...]) -> bytes:
        op, name, args, kwargs = request
        if op in ("call", "env_method"):
            return self._reply(lambda: _refuse_some(name, self.n))
        return self._reply(lambda: run_op(self._ops, WHO, op, name, row, *args, **kwargs))

    def _once_for_all(self, request: tuple[Any, ...], rows: list[int], whole: bool) -> list[bytes]:
        """One vector operation for every env that asked, each env's element its reply."""
        op, name, args, kwargs = request
        if op in ("call", "env_method") and not whole:
            return [self._reply(lambda: _refuse_some(name, self.n))] * len(rows)
        try:
            values = run_op(self._ops, WHO, op, name, None, *args, **kwargs)
        except BaseException as exc:
            failed = bytes(cloudpickle.dumps(("err", encode_exception(exc))))
            return [failed] * len(rows)
        if op == "has_attr":
            return [bytes(cloudpickle.dumps(("ok", values)))] * len(rows)
        return [bytes(cloudpickle.dumps(("ok", values[row]))) for row in rows]

    def _set_all(self, requests: list[tuple[Any, ...]], rows: list[int]) -> list[bytes]:
        """``set_attr`` of every env of the block: one vector ``set_attr``."""
        name = requests[0][1]
        values: list[Any] = [None] * self.n
        for row, (_op, _name, args, _kwargs) in zip(rows, requests):
            values[row] = args[0]
        reply = self._reply(lambda: self.envs.set_attr(name, values))
        return [reply] * len(rows)

    # The env operations (protocol.ops) for env ``row`` of the block (``None``: every env,
    # for the operations run once for all; their value is then one per env, has_attr's one).
    def _op_call(self, name: str, row: Optional[int], *args: Any, **kwargs: Any) -> Any:
        if name in ("reset", "step", "close"):
            raise ValueError(f"call({name!r}) is not allowed; use the vector env's own")
        values = self.envs.call(name, *args, **kwargs)
        return values if row is None else values[row]

    _op_env_method = _op_call

    def _op_get_attr(self, name: str, row: Optional[int]) -> Any:
        values = self.envs.get_attr(name)
        return values if row is None else values[row]

    def _op_has_attr(self, name: str, row: Optional[int]) -> bool:
        try:
            self.envs.get_attr(name)
        except AttributeError:
            return False
        return True

    def _op_set_wrapper_attr(self, name: str, row: int, value: Any) -> None:
        values = list(self.envs.get_attr(name))
        values[row] = value
        self.envs.set_attr(name, values)

    def _op_render(self, name: str, row: Optional[int]) -> Any:
        values = self.envs.call("render")
        return values if row is None else values[row]

    def _op_set_reset_options(self, name: str, row: int, options: Any) -> None:
        self._options = options

    def _op_set_reset_seed(self, name: str, row: int, seed: int) -> None:
        self._seeds[row] = int(seed)

    def close(self) -> None:
        """Close the vector env (when the worker exits); errors are ignored."""
        with contextlib.suppress(Exception):
            self.envs.close()
