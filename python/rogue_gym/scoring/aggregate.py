"""Results of several runs: ``python -m rogue_gym.evaluate aggregate`` and ``compare``.

    python -m rogue_gym.evaluate aggregate RUN_DIR... [--raw] [--out DIR] [--allow-mixed]
    python -m rogue_gym.evaluate compare --a RUN_DIR... --b RUN_DIR... [--raw] [--allow-mixed]

Each ``RUN_DIR`` holds the ``summary.json`` of one evaluation (one training run of a method,
scored by ``python -m rogue_gym.evaluate``). ``aggregate`` reads the runs of one method and
reports, over the ``(runs, test seeds)`` matrix of per-seed scores (normalized between the
random and the reference agent, or ``--raw`` returns), the IQM, median, mean and optimality
gap with stratified bootstrap intervals (:mod:`rogue_gym.scoring.runs`), the train score, the
test score and the gap across runs, the scores by difficulty stratum, and two plots
(``performance_profile.png``, ``strata.png``). ``compare`` reports the probability that method
A improves on method B and a paired test on the same seeds. Both refuse results of different
engine versions, suites or seedings (:mod:`rogue_gym.scoring.versions`) unless
``--allow-mixed`` is given, and say what differs.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

from .reports import compact_json, strata_rows
from .runs import (
    AGGREGATES,
    Interval,
    paired_test,
    performance_profile,
    probability_of_improvement,
    stratified_bootstrap,
)
from .versions import mismatches

__all__ = ["aggregate", "compare", "load_runs", "main"]


def load_runs(dirs: Sequence[Path], allow_mixed: bool = False) -> List[Dict[str, Any]]:
    """The ``summary.json`` of each run folder (or file), checked to be comparable."""
    docs, names = [], []
    for d in dirs:
        path = Path(d)
        path = path / "summary.json" if path.is_dir() else path
        if not path.is_file():
            raise FileNotFoundError(f"{path}: no summary.json (run python -m rogue_gym.evaluate)")
        docs.append(json.loads(path.read_text()))
        names.append(str(d))
    if not docs:
        raise ValueError("no runs given")
    bad = mismatches(docs, names)
    if bad and not allow_mixed:
        raise ValueError(
            "these results are not comparable:\n  "
            + "\n  ".join(bad)
            + "\nscore every run with the same engine and suite, or pass --allow-mixed to "
            "aggregate them anyway"
        )
    seeds = {tuple(d["settings"]["seeds"]) for d in docs}
    if len(seeds) > 1:
        raise ValueError("the runs were scored on different test seeds: use the same seeds_limit")
    return docs


def _scores(docs: Sequence[Dict[str, Any]], split: str, raw: bool) -> np.ndarray:
    """The ``(runs, seeds)`` matrix of the policy's per-seed scores on ``split``."""
    rows = []
    for d in docs:
        norm = d.get("normalized", {}).get(split)
        if not raw and norm is None:
            raise ValueError(
                f"a run has no normalized {split} scores (evaluated without the random or the "
                "reference agent): evaluate it again with both, or pass --raw"
            )
        if raw:
            agents = d["agents"] if split == "test" else d.get("train_agents", [])
            if not agents:
                raise ValueError(f"a run has no {split} scores")
            rows.append(agents[0]["per_seed_mean"])
        else:
            rows.append(norm["per_seed"])
    return np.asarray(rows, np.float64)


def aggregate(
    docs: Sequence[Dict[str, Any]],
    raw: bool = False,
    confidence: float = 0.95,
    reps: int = 2000,
    seed: int = 0,
) -> Dict[str, Any]:
    """The aggregate statistics of one method's runs (see the module docs)."""
    test = _scores(docs, "test", raw)
    out: Dict[str, Any] = {
        "runs": len(docs),
        "seeds": test.shape[1],
        "scores": "raw" if raw else "normalized",
        "versions": docs[0].get("versions"),
        "test": {
            name: stratified_bootstrap(test, fn, confidence, reps, seed).to_json()
            for name, fn in AGGREGATES.items()
        },
    }
    if all(d.get("train_agents") for d in docs):
        train = _scores(docs, "train", raw)
        out["train"] = {
            name: stratified_bootstrap(train, fn, confidence, reps, seed).to_json()
            for name, fn in AGGREGATES.items()
        }
        # The gap of each run (its train mean minus its test mean), across runs.
        gaps = (train.mean(axis=1) - test.mean(axis=1))[:, None]
        out["gap"] = stratified_bootstrap(gaps, np.mean, confidence, reps, seed).to_json()
    lo = float(test.min()) if raw else min(0.0, float(test.min()))
    taus = np.linspace(lo, max(lo + 1.0, float(test.max())), 41)
    out["profile"] = {
        "tau": taus.tolist(),
        "fraction": [p.to_json() for p in performance_profile(test, taus, confidence, 500, seed)],
    }
    manifest = docs[0].get("manifest") or []
    if manifest:
        out["strata"] = strata_rows(manifest, {"mean over runs": test.mean(axis=0)})
    return out


def compare(
    a: Sequence[Dict[str, Any]],
    b: Sequence[Dict[str, Any]],
    raw: bool = False,
    confidence: float = 0.95,
    seed: int = 0,
) -> Dict[str, Any]:
    """Method A against method B on the same test seeds: ``P(A > B)`` with its interval, and
    Wilcoxon's signed-rank test of the per-seed means."""
    x, y = _scores(a, "test", raw), _scores(b, "test", raw)
    diff, stat, p = paired_test(x, y)
    return {
        "runs": [len(a), len(b)],
        "seeds": x.shape[1],
        "scores": "raw" if raw else "normalized",
        "probability_of_improvement": probability_of_improvement(
            x, y, confidence, seed=seed
        ).to_json(),
        "paired": {"mean_difference": diff, "wilcoxon_statistic": stat, "p_value": p},
    }


def _plots(report: Dict[str, Any], out: Path) -> List[Path]:
    """The performance profile and the scores by stratum, as PNG files under ``out``."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("note: no plots (matplotlib is not installed: pip install rogue-gym[report])")
        return []
    paths = []
    prof = report["profile"]
    fig, ax = plt.subplots(figsize=(5, 3.5))
    tau = np.asarray(prof["tau"])
    frac = prof["fraction"]
    ax.plot(tau, [f["value"] for f in frac])
    ax.fill_between(tau, [f["low"] for f in frac], [f["high"] for f in frac], alpha=0.3)
    ax.set_xlabel(f"{report['scores']} score tau")
    ax.set_ylabel("fraction of runs x seeds above tau")
    ax.set_title(f"performance profile ({report['runs']} runs, {report['seeds']} seeds)")
    fig.tight_layout()
    paths.append(out / "performance_profile.png")
    fig.savefig(paths[-1], dpi=120)
    plt.close(fig)
    if report.get("strata"):
        rows = report["strata"]
        fig, ax = plt.subplots(figsize=(6, 0.4 * len(rows) + 1))
        ax.barh(
            [f"{r['stratum']} ({r['seeds']})" for r in rows], [r["mean over runs"] for r in rows]
        )
        ax.invert_yaxis()
        ax.set_xlabel(f"mean {report['scores']} score over runs")
        ax.set_title("scores by seed difficulty (level 1 of each seed)")
        fig.tight_layout()
        paths.append(out / "strata.png")
        fig.savefig(paths[-1], dpi=120)
        plt.close(fig)
    return paths


def _line(name: str, iv: Dict[str, float]) -> str:
    return f"  {name:16s} {Interval(iv['value'], iv['low'], iv['high']).text()}"


def main(argv: Sequence[str]) -> int:
    """``aggregate`` or ``compare`` (``argv`` starts with the command's name)."""
    p = argparse.ArgumentParser(prog="python -m rogue_gym.evaluate")
    sub = p.add_subparsers(dest="command", required=True)
    agg = sub.add_parser("aggregate", help="one method's runs: IQM, median, mean, gap, profile")
    agg.add_argument("runs", nargs="+", type=Path)
    cmp_ = sub.add_parser("compare", help="method A against method B on the same seeds")
    cmp_.add_argument("--a", nargs="+", type=Path, required=True)
    cmp_.add_argument("--b", nargs="+", type=Path, required=True)
    for q in (agg, cmp_):
        q.add_argument("--raw", action="store_true", help="raw returns, not normalized scores")
        q.add_argument("--allow-mixed", action="store_true", help="mix versions anyway")
        q.add_argument("--confidence", type=float, default=0.95)
        q.add_argument("--out", type=Path, default=None)
    args = p.parse_args(list(argv))
    try:
        if args.command == "aggregate":
            docs = load_runs(args.runs, args.allow_mixed)
            report = aggregate(docs, args.raw, args.confidence)
            print(f"{report['runs']} runs x {report['seeds']} seeds, {report['scores']} scores")
            for split in ("test", "train"):
                if split in report:
                    print(f"{split}:")
                    for name, iv in report[split].items():
                        print(_line(name, iv))
            if "gap" in report:
                print(_line("gap (train-test)", report["gap"]))
        else:
            a, b = load_runs(args.a, args.allow_mixed), load_runs(args.b, args.allow_mixed)
            bad = mismatches([a[0], b[0]], ["A", "B"])
            if bad and not args.allow_mixed:
                raise ValueError("A and B are not comparable:\n  " + "\n  ".join(bad))
            report = compare(a, b, args.raw, args.confidence)
            poi, pair = report["probability_of_improvement"], report["paired"]
            print(f"P(A > B) = {Interval(poi['value'], poi['low'], poi['high']).text()}")
            print(
                f"paired (Wilcoxon, {report['seeds']} seeds): mean A - B "
                f"{pair['mean_difference']:.3f}, p = {pair['p_value']:.3g}"
            )
    except (ValueError, FileNotFoundError) as exc:
        print(f"error: {exc}")
        return 2
    out: Optional[Path] = args.out
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / f"{args.command}.json").write_text(compact_json(report))
        written: List[Path] = [out / f"{args.command}.json"]
        if args.command == "aggregate":
            written += _plots(report, out)
        print("wrote " + ", ".join(map(str, written)))
    return 0
