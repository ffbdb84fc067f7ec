"""The worker side of a hosted env: builds the caller's env from its cloudpickled callable and
speaks the pool's flat bytes.

The pool's Rust worker loop calls :class:`HostedEnv` (through ``python/src/worker/hosted.rs``) for
every reset of the env, and steps the env itself with the parts of :meth:`HostedEnv.step_parts`
(the hot path has no Python frame of ours). An observation's dynamic leaves (Text, Graph,
Sequence, OneOf, custom spaces) travel pickled in the command's info, as entries of their own
beside the env's info (``STEP_OBS``, ``RESET_OBS``); a step's dynamic actions arrive with
its command, in a private file beside it, and reach :meth:`HostedEnv.set_action_extra` first.
Any exception of the env is raised as an encoded
:class:`~rogue_gym.protocol.exceptions.EncodedEnvError`, which the caller rebuilds.
"""

from __future__ import annotations

import base64
import contextlib
import json
import pickle
import sys
from typing import Any, Optional

import cloudpickle
import numpy as np

from ..protocol import NO_SEED, registry
from ..protocol.exceptions import EncodedEnvError, encode_exception
from ..protocol.infos import RESET_OBS, STEP_OBS, FlatPlan, InfoEncoder
from ..protocol.layout import SpaceLayout
from ..protocol.ops import Interpreter, op_table, run_op

__all__ = ["WHO", "HostedEnv", "explained", "prepare"]

#: This interpreter in :data:`rogue_gym.protocol.ops.SERVED_BY`.
WHO = Interpreter.HOSTED


def prepare(cfg: dict[str, Any]) -> None:
    """Make the caller's world before an env is built: its ``sys.path`` and its gymnasium
    registry (:mod:`rogue_gym.protocol.registry`)."""
    for path in reversed(cfg["sys_path"]):
        if path not in sys.path:
            sys.path.insert(0, path)
    if cfg.get("registry"):
        registry.install(cfg["registry"])


@contextlib.contextmanager
def explained() -> Any:
    """Build an env; an error about its id or its entry point gets a note of what the worker
    tried (:func:`rogue_gym.protocol.registry.explain_failure`)."""
    try:
        yield
    except Exception as exc:
        note = registry.explain_failure(exc)
        if note:
            notes = getattr(exc, "__notes__", None)
            exc.__notes__ = [*(notes or []), note]  # add_note, also before Python 3.11
        raise


def _guarded(method: Any) -> Any:
    """Run ``method``; any exception becomes an :class:`EncodedEnvError`."""

    def run(*args: Any) -> Any:
        try:
            return method(*args)
        except EncodedEnvError:
            raise
        except BaseException as exc:
            raise EncodedEnvError(encode_exception(exc)) from exc

    run.__name__ = method.__name__
    run.__doc__ = method.__doc__
    return run


class _DiscreteActions:
    """A Discrete space's actions by index, as numpy scalars of the space's own dtype (what
    ``space.sample()`` gives and ``action in space`` accepts), from a table for spaces of up to
    65536 actions."""

    def __init__(self, start: int, n: int, dtype: Any = np.int64) -> None:
        self.start = start
        self.make = np.dtype(dtype).type
        self.table = [self.make(start + i) for i in range(n)] if n <= 1 << 16 else None

    def __getitem__(self, index: int) -> Any:
        if self.table is not None:
            return self.table[index]
        return self.make(self.start + index)


def _space_mismatch(got: Any, want: Any, same: bool, what: str = "observation") -> str:
    """Why an env's space ``got`` cannot be batched with env 0's ``want`` (``same``: they
    must be equal; otherwise only have one layout), or ``""``."""
    if same and got == want:
        return ""
    if not same and SpaceLayout(got).signature == SpaceLayout(want).signature:
        return ""
    if what == "action":
        hint = "Every env must have the same action space."
    elif same:
        hint = (
            "If this is intentional, use `observation_mode='different'` instead (spaces that "
            "differ only in their bounds)."
        )
    else:
        hint = "Their leaves must have the same dtypes and shapes."
    return (
        f"its {what} space is {got}, where env 0's is {want}: the sub-environments {what} "
        f"spaces are not equivalent. {hint}"
    )


class _StepInfo(dict[str, Any]):
    """A step's info as the env returned it, with the values of the observation's dynamic
    leaves beside it (``dynamic``), not in it; always true, so that the worker encodes it
    (:meth:`HostedEnv.step_info`) even when the env's own info is empty."""

    def __init__(self, info: dict[str, Any], dynamic: list[Any]) -> None:
        super().__init__(info)
        self.dynamic = dynamic

    def __bool__(self) -> bool:
        return True


def _step_entries(info: dict[str, Any]) -> list[tuple[str, Any]]:
    """A step's encoded entries: its info if any, and its observation's dynamic values."""
    entries: list[tuple[str, Any]] = [("step", dict(info))] if len(info) else []
    if isinstance(info, _StepInfo):
        entries.append((STEP_OBS, info.dynamic))
    return entries


class _DynamicObsEnv:
    """The env as the worker's Rust step calls it when the observation has dynamic leaves:
    ``step`` returns the info as a :class:`_StepInfo` that carries their values."""

    def __init__(self, env: Any, layout: SpaceLayout) -> None:
        self.env = env
        self.layout = layout

    def step(self, action: Any) -> tuple[Any, ...]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        return obs, reward, terminated, truncated, _StepInfo(info, self.layout.dynamic_values(obs))


class HostedEnv:
    """One hosted env (built by :meth:`build`) and the byte codecs of its spaces."""

    def __init__(self, env: Any, obs_space: Any, action_space: Any, discrete_start: Optional[int]):
        self.env = env
        self._obs = SpaceLayout(obs_space)
        self._act = SpaceLayout(action_space)
        self._discrete = (
            None
            if discrete_start is None
            else _DiscreteActions(discrete_start, int(action_space.n), action_space.dtype)
        )
        self._fresh = True
        #: Options for the next reset only (set by a call, as SB3's set_options does).
        self._options: Optional[dict[str, Any]] = None
        #: The seed of the next reset only (a partial reset with seeds sets it by a call).
        self._seed: Optional[int] = None
        #: The last observation (for :meth:`observe`).
        self._last: Any = None
        self._info_encoder = InfoEncoder()
        #: The dynamic leaves of the next step's action (see :meth:`set_action_extra`).
        self._dynamic_actions: list[Any] = []
        self._decode = self._act.decoder() if not self._act.dynamic else self._decode_dynamic
        self._ops = op_table(self, WHO)

    def _decode_dynamic(self, data: bytes) -> Any:
        """An action with dynamic leaves: its fixed leaves from ``data``, the others as the
        step's command brought them (each used once)."""
        dynamic, self._dynamic_actions = self._dynamic_actions, []
        if len(dynamic) != len(self._act.dynamic):
            raise RuntimeError("no dynamic action values arrived for this step")
        return self._act.decode(data, dynamic)

    @classmethod
    @_guarded
    def build(cls, config_json: str, index: int) -> HostedEnv:
        """Build env number ``index`` from the front end's adapter config: the caller's
        ``sys_path``, the pickled callables and which one builds which env, and the spaces
        every env must have."""
        cfg = json.loads(config_json)
        prepare(cfg)
        env_fn = cloudpickle.loads(base64.b64decode(cfg["env_fns"][cfg["fn_of_env"][index]]))
        obs_space, action_space = cloudpickle.loads(base64.b64decode(cfg["spaces"]))
        with explained():
            env = env_fn()
        problem = _space_mismatch(
            env.observation_space, obs_space, cfg.get("same_obs_space", True)
        ) or _space_mismatch(env.action_space, action_space, True, "action")
        if problem:
            env.close()
            raise RuntimeError(f"env {index}: {problem}")
        return cls(env, obs_space, action_space, cfg["discrete_start"])

    def reset(
        self, seed: int, episode: int, step_info: Optional[dict[str, Any]], address: int
    ) -> Optional[bytes]:
        """Start an episode and write its first observation at ``address``: seeded with
        ``seed`` if it is the schedule's first (episode 0) or this env was just built, unless it
        is :data:`NO_SEED`; otherwise the env continues its own generator (gymnasium's
        convention). ``step_info``: the info of the step this reset follows in the same command
        (an autoreset), if any. Returns the command's info bytes, or ``None``."""
        try:
            infos = [] if step_info is None else _step_entries(step_info)
            use_seed = seed if (episode == 0 or self._fresh) and seed != NO_SEED else None
            self._fresh = False
            if self._seed is not None:  # a partial reset's own seed for this env
                use_seed, self._seed = self._seed, None
            options, self._options = self._options, None
            obs, info = self.env.reset(seed=use_seed, options=options)
            self.write_obs(obs, address)
            if info:
                infos.append(("reset", info))
            if self._obs.dynamic:
                infos.append((RESET_OBS, self._obs.dynamic_values(obs)))
            return self._info_encoder.encode(infos) if infos else None
        except BaseException as exc:
            raise EncodedEnvError(encode_exception(exc)) from exc

    def step_parts(self) -> tuple[Any, Any, Any, Optional[tuple[int, ...]]]:
        """What the worker's Rust step calls directly (``python/src/worker/hosted.rs``): the env, the
        actions (a list of a Discrete space's actions by index, or a function from an action's
        bytes to its value), the observation's dtype and shape when it is one array (which
        the worker then copies itself from an ndarray of exactly that dtype and shape), or
        ``None`` and ``None`` (every observation goes through :meth:`write_obs`)."""
        if self._discrete is None:
            actions: Any = self._decode
        else:
            table = self._discrete.table
            actions = table if table is not None else self._discrete.__getitem__
        leaf = self._obs.leaves[0] if self._obs.single else None
        return (
            self.env if not self._obs.dynamic else _DynamicObsEnv(self.env, self._obs),
            actions,
            None if leaf is None else leaf.dtype,
            None if leaf is None else leaf.shape,
        )

    def write_obs(self, obs: Any, address: int) -> None:
        """Write an observation at ``address`` (any value of the space: casts, reshapes,
        nested spaces) and keep it as the last one."""
        self._obs.writer_at(address)(obs)
        self._last = obs

    def step_info(self, info: dict[str, Any]) -> tuple[bytes, Optional[FlatPlan]]:
        """The bytes of a step's (non-empty) info, and the plan of its layout when it is a
        flat row of scalars (which the worker then packs itself while infos keep it)."""
        if isinstance(info, _StepInfo):
            return self._info_encoder.encode(_step_entries(info)), None
        return self._info_encoder.encode_step(info)

    def call(self, request: bytes) -> bytes:
        """Answer a call from the caller (off the hot path): ``request`` is a pickled
        ``(op, name, args, kwargs)``; the reply a cloudpickled ``("ok", value)`` or ``("err",
        encoded exception)``. ``op`` is one of :data:`~rogue_gym.protocol.ops.ENV_OPS`."""
        try:
            op, name, args, kwargs = pickle.loads(request)
            value = run_op(self._ops, WHO, op, name, *args, **kwargs)
            return bytes(cloudpickle.dumps(("ok", value)))
        except BaseException as exc:
            return bytes(cloudpickle.dumps(("err", encode_exception(exc))))

    # The env operations (protocol.ops): gymnasium's and SB3's worker commands.
    def _op_call(self, name: str, *args: Any, **kwargs: Any) -> Any:
        if name in ("reset", "step", "close", "set_wrapper_attr"):
            raise ValueError(f"call({name!r}) is not allowed; use the vector env's own {name}()")
        attr = self.env.get_wrapper_attr(name)
        return attr(*args, **kwargs) if callable(attr) else attr

    def _op_env_method(self, name: str, *args: Any, **kwargs: Any) -> Any:
        return self.env.get_wrapper_attr(name)(*args, **kwargs)

    def _op_get_attr(self, name: str) -> Any:
        return self.env.get_wrapper_attr(name)

    def _op_has_attr(self, name: str) -> bool:
        try:
            self.env.get_wrapper_attr(name)
        except AttributeError:
            return False
        return True

    def _op_set_wrapper_attr(self, name: str, value: Any) -> None:
        self.env.set_wrapper_attr(name, value)

    def _op_setattr(self, name: str, value: Any) -> None:
        setattr(self.env, name, value)

    def _op_is_wrapped(self, name: str, wrapper_class: type) -> bool:
        env = self.env
        while True:
            if isinstance(env, wrapper_class):
                return True
            inner = getattr(env, "env", None)
            if inner is None or inner is env:
                return False
            env = inner

    def _op_render(self, name: str) -> Any:
        return self.env.render()

    def _op_set_reset_options(self, name: str, options: Optional[dict[str, Any]]) -> None:
        self._options = options

    def _op_set_reset_seed(self, name: str, seed: int) -> None:
        self._seed = int(seed)

    @_guarded
    def set_action_extra(self, data: bytes) -> None:
        """The values of the dynamic leaves of the next step's action (a pickled list, in the
        order of the action layout's dynamic leaves), from the step's command: a private file
        of the pool's, written by the caller."""
        values = pickle.loads(data)
        if not isinstance(values, list) or len(values) != len(self._act.dynamic):
            raise ValueError(
                f"the step's action extra holds {values!r}; expected a list of "
                f"{len(self._act.dynamic)} values"
            )
        self._dynamic_actions = values

    def observe(self, address: int) -> None:
        """Write the current observation again, at ``address`` (for partial resets)."""
        if self._last is None:
            raise RuntimeError("the env has no observation yet: reset it first")
        self.write_obs(self._last, address)

    def close(self) -> None:
        """Close the env (when the worker exits); errors are ignored."""
        with contextlib.suppress(Exception):
            self.env.close()
