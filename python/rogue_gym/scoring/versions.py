"""What a result is comparable with: the versions it records, and the refusal to mix them.

Every ``summary.json`` carries ``versions``: the package's version, the engine's
(``rogue_gym._native.ENGINE_VERSION``, raised whenever a seed's dungeon or a rule changes), the
suite's name and digest, and its seeding. Scores are comparable only where all of these agree
but the package's own version (a release that changes no game keeps the engine's):
:func:`mismatches` says what differs, and the aggregating commands refuse such a mix unless
told to.
"""

from __future__ import annotations

from typing import Any, Dict, List, Sequence

__all__ = ["COMPARED", "mismatches", "result_versions"]

#: The fields two results must share to be compared or aggregated.
COMPARED = ("engine", "suite", "suite_digest", "seeding")


def result_versions(suite: Any) -> Dict[str, Any]:
    """The versions an evaluation of ``suite`` records now."""
    from .. import __version__, _native

    return {
        "package": __version__,
        "engine": int(_native.ENGINE_VERSION),
        "suite": suite.name,
        "suite_digest": suite.digest(),
        "seeding": suite.config.get("seeding", "mixed"),
    }


def mismatches(docs: Sequence[Dict[str, Any]], names: Sequence[str]) -> List[str]:
    """What the results ``docs`` (``summary.json`` contents, named ``names``) do not share
    of :data:`COMPARED`, one line per field; a result without versions (written before they
    were recorded) is a mismatch of its own."""
    out: List[str] = []
    first = docs[0].get("versions")
    for doc, name in zip(docs, names):
        if "versions" not in doc:
            out.append(f"{name} records no versions (written by an older rogue_gym): run it again")
    if out or first is None:
        return out
    for field in COMPARED:
        values = {str(d["versions"].get(field)) for d in docs}
        if len(values) > 1:
            which = ", ".join(f"{n}: {d['versions'].get(field)}" for d, n in zip(docs, names))
            out.append(f"{field} differs ({which})")
    return out
