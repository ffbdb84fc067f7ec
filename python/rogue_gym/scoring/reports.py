"""What an evaluation writes: the seed manifest (difficulty metadata per seed), per-seed rows,
``summary.json`` and the CSV files."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any, Callable, Dict, List, Sequence, Tuple

import numpy as np

from ..suites import Suite

__all__ = [
    "STRATA",
    "compact_json",
    "describe_manifest",
    "per_seed_rows",
    "seed_manifest",
    "strata_rows",
    "write_csv",
    "write_manifest",
    "write_results",
]


def seed_manifest(suite: Suite, seeds: Sequence[int]) -> List[Dict[str, Any]]:
    """Difficulty metadata of level 1 of each seed, from the engine's floor summary.

    One dict per seed with the keys returned by
    ``rogue_gym._native.floor_summary(config_json, seed)``: ``rooms`` (real rooms),
    ``normal_rooms``, ``maze_rooms``, ``dark_rooms``, ``gone_rooms``, ``doors``,
    ``hidden_doors`` (secret doors), ``passage_cells``, ``hidden_passages`` (hidden passage
    cells), ``gold_piles``, ``gold_total``, ``stairs_distance`` (shortest walk in moves from
    the start cell to the stairs under the movement rule, without searching; ``None`` when
    the stairs need a search) and ``stairs_distance_unhidden`` (the same with every hidden
    feature found). Exact definitions: ``engine/src/summary.rs``.
    """
    from .. import _native

    config_json = suite.config_json()
    rows = []
    for s in seeds:
        row: Dict[str, Any] = {"seed": int(s)}
        row.update(_native.floor_summary(config_json, int(s)))
        row.pop("level", None)
        rows.append(row)
    return rows


def write_csv(path: Path, rows: List[Dict[str, Any]]) -> None:
    """Rows as CSV, the columns in order of first appearance."""
    if not rows:
        return
    fields: List[str] = []
    for row in rows:
        for key in row:
            if key not in fields:
                fields.append(key)
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)


def compact_json(doc: Dict[str, Any]) -> str:
    """One line per top-level key: readable, without one line per number."""
    body = ",\n".join(f"{json.dumps(k)}: {json.dumps(v)}" for k, v in doc.items())
    return "{\n" + body + "\n}\n"


def per_seed_rows(result: Dict[str, Any], split: str = "test") -> List[Dict[str, Any]]:
    """One row per seed of ``split`` (``"test"`` or ``"train"``): each agent's mean, std, min
    and max, the policy's normalized score, then (test seeds) the manifest columns."""
    seeds = result["settings"]["seeds" if split == "test" else "train_seeds"]
    agents = result["agents"] if split == "test" else result.get("train_agents", [])
    manifest = {m["seed"]: m for m in result.get("manifest", [])} if split == "test" else {}
    norm = result.get("normalized", {}).get(split, {}).get("per_seed")
    rows = []
    for k, s in enumerate(seeds):
        row: Dict[str, Any] = {"seed": s}
        for a_i, agent in enumerate(agents):
            r = np.asarray(agent["returns"][k], dtype=np.float64)
            prefix = "policy" if a_i == 0 else agent["name"]
            row[f"{prefix}_mean"] = round(float(r.mean()), 4)
            row[f"{prefix}_std"] = round(float(r.std()), 4)
            row[f"{prefix}_min"] = float(r.min())
            row[f"{prefix}_max"] = float(r.max())
        if norm is not None:
            row["policy_normalized"] = round(float(norm[k]), 4)
        for key, val in manifest.get(s, {}).items():
            if key != "seed":
                row[key] = val
        rows.append(row)
    return rows


def write_results(result: Dict[str, Any], out: Path) -> List[Path]:
    """Write ``per_seed.csv`` (test seeds), ``per_seed_train.csv`` (training seeds, when
    scored) and ``summary.json`` under ``out``; returns the paths."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "per_seed.csv"]
    write_csv(paths[0], per_seed_rows(result))
    if result.get("train_agents"):
        paths.append(out / "per_seed_train.csv")
        write_csv(paths[-1], per_seed_rows(result, "train"))
    summary = out / "summary.json"
    clean = {k: v for k, v in result.items() if not k.startswith("_")}
    summary.write_text(compact_json(clean))
    return [*paths, summary]


def write_manifest(rows: List[Dict[str, Any]], out: Path) -> List[Path]:
    """Write ``manifest.csv`` and ``manifest.json`` under ``out``; returns the paths."""
    out.mkdir(parents=True, exist_ok=True)
    csv_path, json_path = out / "manifest.csv", out / "manifest.json"
    write_csv(csv_path, rows)
    json_path.write_text("[\n" + ",\n".join(json.dumps(r) for r in rows) + "\n]\n")
    return [csv_path, json_path]


def describe_manifest(rows: List[Dict[str, Any]]) -> str:
    """Per-column summary lines of a manifest."""
    lines = []
    for key in rows[0]:
        if key == "seed":
            continue
        vals = np.asarray([r[key] for r in rows if r[key] is not None], dtype=np.float64)
        if vals.size:
            missing = len(rows) - vals.size
            note = f"  ({missing} seeds: none)" if missing else ""
            lines.append(
                f"  {key:24s} mean {vals.mean():8.3f}  min {vals.min():6g}  max {vals.max():6g}"
                + note
            )
    return "\n".join(lines)


#: The difficulty strata of a suite's seeds, from the manifest (level 1 of each seed): a name
#: and a test of a manifest row.
STRATA: List[Tuple[str, Callable[[Dict[str, Any]], bool]]] = [
    ("all seeds", lambda m: True),
    ("a dark room", lambda m: m["dark_rooms"] > 0),
    ("no dark room", lambda m: m["dark_rooms"] == 0),
    ("a maze", lambda m: m["maze_rooms"] > 0),
    ("a secret door or hidden passage", lambda m: m["hidden_doors"] + m["hidden_passages"] > 0),
    ("stairs behind a search", lambda m: m["stairs_distance"] is None),
]


def _walk(lo: float, hi: float) -> Callable[[Dict[str, Any]], bool]:
    """The test of a manifest row whose walk to the stairs is in ``(lo, hi]`` moves."""

    def test(m: Dict[str, Any]) -> bool:
        walk = m["stairs_distance_unhidden"]
        return walk is not None and lo < walk <= hi

    return test


def strata_rows(
    manifest: Sequence[Dict[str, Any]], per_seed: Dict[str, np.ndarray]
) -> List[Dict[str, Any]]:
    """Each agent's mean by difficulty stratum (:data:`STRATA`, then the quartiles of the walk
    from the start to the stairs): ``per_seed`` maps an agent's name to its per-seed means,
    in the manifest's seed order. Strata with no seed are left out."""
    walks = np.array(
        [
            m["stairs_distance_unhidden"]
            for m in manifest
            if m["stairs_distance_unhidden"] is not None
        ],
        np.float64,
    )
    tests = list(STRATA)
    if walks.size:
        q = np.quantile(walks, [0.25, 0.5, 0.75])
        edges = [(-np.inf, q[0]), (q[0], q[1]), (q[1], q[2]), (q[2], np.inf)]
        for i, (lo, hi) in enumerate(edges):
            span = f"{max(lo, walks.min()):.0f}-{min(hi, walks.max()):.0f}"
            tests.append((f"walk to the stairs, quartile {i + 1} ({span} moves)", _walk(lo, hi)))
    rows = []
    for name, test in tests:
        pick = np.array([bool(test(m)) for m in manifest])
        if not pick.any():
            continue
        row: Dict[str, Any] = {"stratum": name, "seeds": int(pick.sum())}
        for agent, means in per_seed.items():
            row[agent] = round(float(np.asarray(means)[pick].mean()), 3)
        rows.append(row)
    return rows
