"""The caller's gymnasium registry, carried to the workers (both sides of the wire).

A worker is a fresh process (never a fork), so ids that the caller registered (by importing a
package such as ``highway_env``, by ``gym.register`` in ``__main__`` or in any module, with an
entry point given as a string or as a callable) do not exist there by themselves. The caller
captures its whole registry once per pool (:func:`capture`); each worker installs the ids it
lacks before it builds its first env (:func:`install`), so every id that ``gym.make`` can make
in the caller can be made in the workers, as ``AsyncVectorEnv``'s forked workers can.

* A string entry point stays a string (the worker imports it, from the caller's ``sys.path``),
  except one in ``__main__``: the caller's ``__main__`` is not the worker's, so it travels as
  the object it names, pickled by value.
* A callable entry point travels as cloudpickle sends it: by reference when its module can be
  imported, by value otherwise (``__main__``, a closure).
* A spec that cannot be pickled is left out and named; making it in a worker then fails with
  an error that says so (:func:`explain_failure`).

A package that registers its ids when imported registers them again in the worker when an
entry point imports it; the spec is the same, and gymnasium's "Overriding environment"
warning for it is silenced in the workers.
"""

from __future__ import annotations

import base64
import dataclasses
import importlib
import warnings
from typing import Any

import cloudpickle

__all__ = ["capture", "explain_failure", "install"]

#: What the last :func:`install` in this process did: the ids it added and those left out.
_INSTALLED: dict[str, Any] = {"blob": None, "added": [], "left_out": [], "errors": {}}


def _by_value(entry_point: Any) -> Any:
    """An entry point as it can travel: a string naming ``__main__`` becomes its object."""
    if isinstance(entry_point, str) and entry_point.startswith("__main__:"):
        module = importlib.import_module("__main__")
        return getattr(module, entry_point.split(":", 1)[1])
    return entry_point


def capture() -> str:
    """The caller's registry as it travels to the workers (base64 of a cloudpickle): every
    spec that pickles, and the ids that do not with the reason."""
    from gymnasium.envs.registration import registry

    specs: list[Any] = []
    left_out: dict[str, str] = {}
    for env_id, spec in list(registry.items()):
        try:
            moved = dataclasses.replace(
                spec,
                entry_point=_by_value(spec.entry_point),
                vector_entry_point=_by_value(spec.vector_entry_point),
            )
            specs.append(cloudpickle.dumps(moved))
        except Exception as exc:  # an unpicklable kwarg or entry point: named, not fatal
            left_out[env_id] = f"{type(exc).__name__}: {exc}"
    return base64.b64encode(cloudpickle.dumps((specs, left_out))).decode("ascii")


def install(blob: str) -> None:
    """Add to this process's registry every id of the caller's (``capture()``'s ``blob``) that
    it lacks. Idempotent; a spec that fails to unpickle is recorded for
    :func:`explain_failure`, not raised."""
    if _INSTALLED["blob"] == blob:
        return
    from gymnasium.envs.registration import registry

    specs, left_out = cloudpickle.loads(base64.b64decode(blob))
    added: list[str] = []
    errors: dict[str, str] = {}
    for data in specs:
        try:
            spec = cloudpickle.loads(data)
        except Exception as exc:  # e.g. a module importable in the caller only
            errors[f"spec #{len(errors)}"] = f"{type(exc).__name__}: {exc}"
            continue
        if spec.id not in registry:
            registry[spec.id] = spec
            added.append(spec.id)
    # A package imported later by an entry point registers its ids again, with the same spec.
    warnings.filterwarnings("ignore", message=r".*Overriding environment .* already in registry")
    _INSTALLED.update(blob=blob, added=added, left_out=left_out, errors=errors)


def explain_failure(exc: BaseException) -> str:
    """A note for an env that failed to build in a worker: what the worker tried with the
    caller's registry (empty when ``exc`` is not about an id)."""
    from gymnasium import error

    if _INSTALLED["blob"] is None:
        return ""
    id_error = isinstance(
        exc, (error.NameNotFound, error.NamespaceNotFound, error.VersionNotFound)
    ) or (isinstance(exc, error.Error) and "registry" in str(exc))
    import_error = isinstance(exc, (ImportError, AttributeError))
    if not (id_error or import_error):
        return ""
    lines = [
        "rogue_gym: this worker installed the caller's gymnasium registry "
        f"({len(_INSTALLED['added'])} ids it lacked) before building its envs."
    ]
    if _INSTALLED["left_out"]:
        names = ", ".join(f"{k} ({v})" for k, v in sorted(_INSTALLED["left_out"].items()))
        lines.append(f"Ids left out because their spec could not be pickled: {names}.")
    if _INSTALLED["errors"]:
        lines.append(
            "Specs that could not be unpickled here: " + "; ".join(_INSTALLED["errors"].values())
        )
    if id_error:
        lines.append(
            "The id was not registered in the caller when the pool was built: register it "
            "(or import the package that does) before building the pool."
        )
    else:
        lines.append(
            "The entry point's module could not be imported in the worker, which has the "
            "caller's sys.path: install the package for this interpreter, or make its module "
            "importable from a path on sys.path."
        )
    return "\n".join(lines)
