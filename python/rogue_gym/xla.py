"""Jit-able stepping for JAX: ``handle, recv, send, step = envs.xla()``.

The functions run inside ``jax.jit``, ``lax.scan`` and ``lax.fori_loop``. Each is one call of
an XLA FFI handler in the native extension (``rogue_gym_send``, ``rogue_gym_recv``), which
steps the pool directly: no Python runs per step. The calls are declared side-effecting, so
XLA never drops, merges or reorders them, and ``handle`` threads them in program order:
``send`` returns it and ``recv`` takes it, as EnvPool's ``xla()`` does.

* ``send(handle, action, env_id=None) -> handle``: a sync pool (``batch_size == num_envs``)
  keeps the actions for the next ``recv``; an async one sends them to ``env_id`` (default:
  the envs of the last ``recv``).
* ``recv(handle) -> (handle, outputs)``: the next batch, in the facade's ``env_type`` form.
* ``step(handle, action, env_id=None) = recv(send(handle, action, env_id))``.

The handlers are registered for jax's CPU backend (the pool's shared memory is host memory);
see ``docs/jax.md`` for the semantics, the versions and what differs from EnvPool.
"""

from __future__ import annotations

import functools
from typing import Any, Callable, NamedTuple, Optional

import numpy as np

from . import _native

__all__ = ["JAX_MIN", "Raw", "XlaFunctions", "build", "require_jax"]

#: The oldest jax whose FFI the handlers are tested with (``jax.ffi.ffi_call`` returning a
#: callable, ``has_side_effect``).
JAX_MIN = (0, 5, 0)


class Raw(NamedTuple):
    """What ``recv``'s handler returns for a batch of ``rows`` envs, before the facade puts it
    in its own form."""

    obs: Any
    reward: Any
    terminated: Any
    truncated: Any
    env_id: Any
    elapsed_step: Any
    restarted: Any
    #: ``(rows, n_info)`` float32 info values in the pool's ``info_names`` order, or ``None``.
    info: Any


class XlaFunctions(NamedTuple):
    """EnvPool's ``xla()`` four."""

    handle: Any
    recv: Callable[[Any], tuple[Any, Any]]
    send: Callable[..., Any]
    step: Callable[..., tuple[Any, Any]]


def _version(text: str) -> tuple[int, ...]:
    parts = []
    for p in text.split(".")[:3]:
        digits = "".join(c for c in p if c.isdigit())
        parts.append(int(digits or 0))
    return tuple(parts)


@functools.lru_cache(maxsize=1)
def require_jax() -> Any:
    """jax, with the handlers registered (once); ``ImportError`` naming the jax needed when it
    is missing or too old."""
    need = ".".join(map(str, JAX_MIN))
    try:
        import jax
    except ImportError as err:
        raise ImportError(
            f"xla() needs jax >= {need}: pip install 'rogue_gym[jax]' (or jax[cpu])"
        ) from err
    if _version(jax.__version__) < JAX_MIN or not hasattr(jax, "ffi"):
        raise ImportError(
            f"xla() needs jax >= {need} (its jax.ffi API); this is jax {jax.__version__}: "
            "pip install -U 'rogue_gym[jax]'"
        )
    for name, capsule in _native.xla_handlers().items():
        jax.ffi.register_ffi_target(name, capsule, platform="cpu")
    return jax


def build(
    pool: Any,
    obs_shape: tuple[int, ...],
    obs_dtype: Any,
    action_space: Any,
    assemble: Callable[[Raw], Any],
) -> XlaFunctions:
    """The four functions over ``pool`` (a ``rogue_gym._native.Pool``): ``recv`` returns
    ``assemble(raw)``, traced once per compilation (jnp operations on the handler's arrays).

    ``obs_shape``/``obs_dtype``: one env's observation as the workers write it (its bytes);
    ``action_space``: one env's (``Discrete``: indices, its ``start`` taken off; ``Box``: its
    dtype's raw bytes)."""
    jax = require_jax()
    import jax.numpy as jnp
    from gymnasium import spaces

    rows = int(pool.batch_size)
    n_info = len(pool.info_names)
    obs_dtype = np.dtype(obs_dtype)
    x64 = bool(jax.config.jax_enable_x64)
    if obs_dtype.itemsize == 8 and not x64:
        raise TypeError(
            f"this env's observations are {obs_dtype}: enable jax's 64-bit types "
            "(jax.config.update('jax_enable_x64', True)) before calling xla()"
        )
    if isinstance(action_space, spaces.Discrete):
        start = int(action_space.start)

        def action_of(a: Any) -> Any:
            a = jnp.asarray(a)
            return (a - start) if start else a

    elif isinstance(action_space, spaces.Box):
        act_dtype = np.dtype(action_space.dtype)
        if act_dtype.itemsize == 8 and not x64:
            raise TypeError(
                f"this env's actions are {act_dtype}: enable jax's 64-bit types before xla()"
            )

        def action_of(a: Any) -> Any:
            return jnp.asarray(a, act_dtype)

    else:
        raise TypeError(
            f"xla() takes envs whose action space is Discrete or Box, not {action_space}"
        )

    handle = jnp.array([pool.xla_key()], jnp.int32)
    handle_type = jax.ShapeDtypeStruct(handle.shape, handle.dtype)
    column = functools.partial(jax.ShapeDtypeStruct, (rows,))
    out_types = [
        handle_type,
        jax.ShapeDtypeStruct((rows, *obs_shape), obs_dtype),
        column(jnp.float32),
        column(jnp.bool_),
        column(jnp.bool_),
        column(jnp.int32),
        column(jnp.int32),
        column(jnp.bool_),
    ]
    if n_info:
        out_types.append(jax.ShapeDtypeStruct((rows, n_info), jnp.float32))
    send_call = jax.ffi.ffi_call("rogue_gym_send", handle_type, has_side_effect=True)
    recv_call = jax.ffi.ffi_call("rogue_gym_recv", out_types, has_side_effect=True)

    def send(handle: Any, action: Any, env_id: Optional[Any] = None) -> Any:
        """Send ``action`` (one row per env of ``env_id``); returns the handle."""
        args = [handle, action_of(action)]
        if env_id is not None:
            args.append(jnp.asarray(env_id, jnp.int32))
        return send_call(*args)

    def recv(handle: Any) -> tuple[Any, Any]:
        """The next batch: ``(handle, outputs)``."""
        handle, *outs = recv_call(handle)
        obs, reward, terminated, truncated, env_id, elapsed, restarted = outs[:7]
        info = outs[7] if n_info else None
        raw = Raw(obs, reward, terminated, truncated, env_id, elapsed, restarted, info)
        return handle, assemble(raw)

    def step(handle: Any, action: Any, env_id: Optional[Any] = None) -> tuple[Any, Any]:
        """``recv(send(handle, action, env_id))``."""
        return recv(send(handle, action, env_id))

    return XlaFunctions(handle, recv, send, step)
