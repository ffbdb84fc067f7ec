"""An env's exception on its trip from a worker to the caller: encoded as JSON text in the
env error message (type, message, worker-side traceback, and the exception itself pickled when
it can be), and rebuilt on the caller's side."""

from __future__ import annotations

import base64
import contextlib
import json
import pickle
import traceback
from typing import Any, Optional

import cloudpickle

__all__ = ["EncodedEnvError", "decode_exception", "encode_exception"]

#: The key of an encoded exception in an env error message.
_KEY = "rogue_gym_exception"


class EncodedEnvError(Exception):
    """An env's exception on its way to the caller; its message is the JSON encoding."""


def encode_exception(exc: BaseException) -> str:
    """Encode an exception for the trip to the caller (see :func:`decode_exception`)."""
    kind = type(exc)
    record: dict[str, Any] = {
        "type": f"{kind.__module__}.{kind.__qualname__}",
        "message": str(exc),
        "traceback": "".join(traceback.format_exception(kind, exc, exc.__traceback__)),
        "pickle": None,
    }
    # An exception that cannot be pickled still travels as text.
    with contextlib.suppress(Exception):
        record["pickle"] = base64.b64encode(cloudpickle.dumps(exc)).decode("ascii")
    return json.dumps({_KEY: record})


def decode_exception(message: str) -> Optional[tuple[BaseException, str]]:
    """The exception and worker-side traceback encoded in an env error message, or ``None``
    if the message is not such an encoding. An exception that cannot be unpickled comes back
    as a ``RuntimeError`` naming its type."""
    try:
        record = json.loads(message)[_KEY]
    except (ValueError, KeyError, TypeError):
        return None
    exc: Optional[BaseException] = None
    if record.get("pickle"):
        try:
            exc = pickle.loads(base64.b64decode(record["pickle"]))
        except Exception:
            exc = None
    if not isinstance(exc, BaseException):
        exc = RuntimeError(f"{record['type']}: {record['message']}")
    return exc, str(record.get("traceback", ""))
