"""An env's own exception, raised in the caller as itself: what the workers' errors become."""

from __future__ import annotations

from typing import Any, Callable, NoReturn, Optional

from ..errors import EnvFailedError
from ..protocol.exceptions import decode_exception

__all__ = ["env_exception", "native_call", "raised_in_worker", "reraise"]


def native_call(fn: Callable[..., Any], *args: Any) -> Any:
    """Run a call of the native pool; an env's own exception is re-raised as itself."""
    try:
        return fn(*args)
    except EnvFailedError as err:
        reraise(err)


def raised_in_worker(detail: str, where: str) -> Optional[BaseException]:
    """The env's exception encoded in ``detail`` (by the worker's adapter), with a note (Python
    3.11+) saying ``where`` it was raised and the worker-side traceback; ``None`` if ``detail``
    is no such encoding."""
    decoded = decode_exception(detail)
    if decoded is None:
        return None
    exc, tb = decoded
    if hasattr(exc, "add_note"):
        exc.add_note(f"raised by {where}. Worker-side traceback:\n{tb}")
    return exc


def env_exception(err: BaseException) -> BaseException:
    """The env's own exception carried by an ``EnvFailedError`` (with the worker-side traceback
    as a note on Python 3.11+), or ``err`` itself if it carries none."""
    if not isinstance(err, EnvFailedError):
        return err
    where = (
        f"env {err.env} during {err.context} in worker {err.worker} (pid {err.pid}); call "
        "reset() to continue"
    )
    return raised_in_worker(err.detail, where) or err


def reraise(err: EnvFailedError) -> NoReturn:
    """Raise the env's own exception carried by ``err``. When several envs or workers failed
    in the same call, the first is raised and the others (decoded too) are in its ``others``
    attribute, one note each on Python 3.11+; one ``reset()`` clears them all."""
    exc = env_exception(err)
    others = [env_exception(o) for o in getattr(err, "others", [])]
    if others:
        if exc is not err:
            exc.__notes__ = [
                n for n in getattr(exc, "__notes__", []) if not n.startswith("also failed")
            ]
        exc.others = others  # type: ignore[attr-defined]
        for o in others:
            if hasattr(exc, "add_note"):
                exc.add_note(f"also failed in the same call: {type(o).__name__}: {o}")
    raise exc from None
