"""The env operations a vector env's ``call``/``get_attr``/``set_attr``/``render`` (and SB3's
``env_method``/``env_is_wrapped``) become, written once: every interpreter (the native game's
kind on the caller's side, the env adapter and the vector-env adapter in the workers) declares
the operations it serves in a table keyed by these names, and an operation missing from a
table is refused with one message naming who refused it.
"""

from __future__ import annotations

from enum import Enum
from typing import Any, Callable, Mapping, Union

__all__ = ["ENV_OPS", "SERVED_BY", "Interpreter", "OpTable", "op_table", "refuse_op", "run_op"]


class Interpreter(Enum):
    """Who serves env operations; the value is how a refusal names it."""

    #: The native game's kind, on the caller's side.
    NATIVE = "the native game"
    #: A worker's adapter of one gymnasium env per row.
    HOSTED = "a hosted env"
    #: A worker's adapter of one vector env per block.
    HOSTED_VECTOR = "a hosted vector env"


#: Every env operation, with what it does to one env.
ENV_OPS: Mapping[str, str] = {
    "call": "getattr(env, name)(*args, **kwargs), or the attribute if it is not callable",
    "env_method": "getattr(env, name)(*args, **kwargs) (SB3's env_method)",
    "get_attr": "the attribute name",
    "has_attr": "whether the env has the attribute name",
    "set_wrapper_attr": "set the attribute name to a value (gymnasium's set_attr)",
    "setattr": "set the attribute name on the outermost env (SB3's set_attr)",
    "is_wrapped": "whether a wrapper class wraps the env (SB3's env_is_wrapped)",
    "render": "the env's frame in its render mode",
    "set_reset_options": "options for the env's next reset",
    "set_reset_seed": "a seed for the env's next reset (a seeded partial reset)",
}

#: The operations each interpreter serves (its handlers are its ``_op_<operation>`` methods).
SERVED_BY: Mapping[Interpreter, frozenset[str]] = {
    Interpreter.NATIVE: frozenset(
        {"call", "env_method", "get_attr", "has_attr", "is_wrapped", "render", "set_reset_options"}
    ),
    Interpreter.HOSTED: frozenset(ENV_OPS),
    Interpreter.HOSTED_VECTOR: frozenset(
        {
            "call",
            "env_method",
            "get_attr",
            "has_attr",
            "set_wrapper_attr",
            "render",
            "set_reset_options",
            "set_reset_seed",
        }
    ),
}

#: An interpreter's table: the operations it serves, each ``handler(name, *args, **kwargs)``.
OpTable = Mapping[str, Callable[..., Any]]


def op_table(interpreter: Any, who: Interpreter) -> OpTable:
    """The table of ``interpreter`` (one of :data:`SERVED_BY`): its ``_op_<operation>`` method
    for each operation it serves."""
    return {op: getattr(interpreter, f"_op_{op}") for op in sorted(SERVED_BY[who])}


def refuse_op(who: Union[Interpreter, str], op: str) -> NotImplementedError:
    """The error for ``op`` asked of an interpreter (``who``: one of ours, or a kind of the
    caller's own, by its name) whose table lacks it."""
    if op not in ENV_OPS:
        return NotImplementedError(f"{op!r} is no env operation; the operations: {list(ENV_OPS)}")
    return NotImplementedError(
        f"{getattr(who, 'value', who)} does not serve the env operation {op!r} ({ENV_OPS[op]})"
    )


def run_op(table: OpTable, who: Interpreter, op: str, name: str, *args: Any, **kwargs: Any) -> Any:
    """Run ``op`` through ``table``, or raise :func:`refuse_op`'s error."""
    handler = table.get(op)
    if handler is None:
        raise refuse_op(who, op)
    return handler(name, *args, **kwargs)
