"""The paper's experiment as one command: its run matrix at its protocol.

The paper (Kanagawa & Kaneko, CoG 2019) trains the six variants on 10 training seeds, then
Large, L2 and the beta-VAE on 20 and on 40: 12 runs. Its protocol (the authors' code,
``agents/env.py``): the original's dungeons (suites ``paper-N-original``), 40M frames,
weights saved every 2M, and each checkpoint scored on the 1000 test seeds x 10 episodes.

``python -m rogue_gym.train.matrix`` prints the commands of every run (or of ``--only``
some), ``--run`` runs them one after another: each run trains (resuming a run folder that
stopped), then :mod:`.posthoc` scores all its checkpoints (resuming too), then the evaluator
scores its last checkpoint on the suite's training and test seeds (``RUN/eval/summary.json``).
A run's folder is ``OUT/VARIANT-N`` and holds its ``config.json`` (variant, suite, frames,
compat mode, seed), so it describes itself; ``python -m rogue_gym.train.plot`` draws the
figures from the folders, and ``--report`` prints the paper's table from the evaluations: per
variant and suite, the train score, the test score and the gap, each with its 95% interval,
and the normalized test score (``docs/benchmark.md``); runs of one variant and suite made
with several ``--seed``s (``--out`` folders of their own, all given to ``--report``) are
aggregated across runs.
"""

from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import List, Optional, Sequence

from .config import TrainConfig

__all__ = ["PAPER_RUNS", "PROTOCOL", "Run", "commands", "report", "runs"]

#: The paper's protocol, :class:`TrainConfig`'s defaults (the authors' ``agents/env.py``:
#: ``max_steps = int(2e7) * 2``, ``save_freq = int(2e6)``; ``agents/eval_cog.py``: 1000 test
#: seeds x 10 episodes).
PROTOCOL = {
    key: getattr(TrainConfig, key)
    for key in ("frames", "checkpoint_every", "eval_seeds", "eval_episodes")
}

#: ``(variant, training seeds)`` of the paper's 12 runs.
PAPER_RUNS = [(v, 10) for v in ("small", "large", "batchnorm", "l2", "vae", "betavae")] + [
    (v, n) for n in (20, 40) for v in ("large", "l2", "betavae")
]


@dataclass(frozen=True)
class Run:
    """One run of the matrix."""

    variant: str
    seeds: int

    @property
    def name(self) -> str:
        """``VARIANT-N``, the run folder's name."""
        return f"{self.variant}-{self.seeds}"

    @property
    def suite(self) -> str:
        """The original's dungeons with ``seeds`` training seeds."""
        return f"paper-{self.seeds}-original"


def runs(only: Optional[Sequence[str]] = None) -> List[Run]:
    """The matrix's runs, or those named in ``only`` (``small-10``, ``l2-40``, ...)."""
    every = [Run(v, n) for v, n in PAPER_RUNS]
    if not only:
        return every
    names = {r.name: r for r in every}
    unknown = [o for o in only if o not in names]
    if unknown:
        raise ValueError(f"unknown runs {unknown}; the paper's are {', '.join(names)}")
    return [names[o] for o in only]


def _train_args(run: Run, args: argparse.Namespace, resume: bool) -> List[str]:
    cmd = [
        "-m",
        "rogue_gym.train",
        "--variant",
        run.variant,
        "--suite",
        run.suite,
        "--frames",
        str(args.frames),
        "--checkpoint-every",
        str(args.checkpoint_every),
        "--eval-every",
        "0",
        "--eval-seeds",
        str(args.eval_seeds),
        "--eval-episodes",
        str(args.eval_episodes),
        "--device",
        args.device,
        "--seed",
        str(args.seed),
        "--compat",
        args.compat,
        "--num-workers",
        str(args.num_workers),
        "--out",
        str(args.out / run.name),
    ]
    return cmd + (["--resume"] if resume else []) + list(args.train_args)


def _posthoc_args(run: Run, args: argparse.Namespace) -> List[str]:
    return [
        "-m",
        "rogue_gym.train.posthoc",
        str(args.out / run.name),
        "--eval-seeds",
        str(args.eval_seeds),
        "--eval-episodes",
        str(args.eval_episodes),
        "--device",
        args.device,
        "--num-workers",
        str(args.num_workers),
    ]


def _eval_args(run: Run, args: argparse.Namespace) -> List[str]:
    """The evaluator on the run's last checkpoint (``checkpoint:RUN``), training and test
    seeds, into ``RUN/eval``."""
    return [
        "-m",
        "rogue_gym.evaluate",
        "--suite",
        run.suite,
        "--policy",
        f"checkpoint:{args.out / run.name}",
        "--episodes-per-seed",
        str(args.eval_episodes),
        "--seeds-limit",
        str(args.eval_seeds),
        "--num-workers",
        str(args.num_workers),
        "--out",
        str(args.out / run.name / "eval"),
        "--no-progress",
    ]


def _trained_frames(folder: Path) -> int:
    """Frames of the last ``progress.csv`` row (0 without one)."""
    path = folder / "progress.csv"
    if not path.exists():
        return 0
    lines = path.read_text().strip().splitlines()
    return int(lines[-1].split(",")[0]) if len(lines) > 1 else 0


def commands(run: Run, args: argparse.Namespace) -> List[List[str]]:
    """The commands still due for ``run``: training (resumed if its folder has a checkpoint;
    none once it has its frames), then the post-hoc scoring."""
    folder = args.out / run.name
    due = []
    if _trained_frames(folder) < args.frames:
        due.append(_train_args(run, args, resume=(folder / "checkpoint.pt").exists()))
    due.append(_posthoc_args(run, args))
    due.append(_eval_args(run, args))
    return [[sys.executable, *c] for c in due]


def report(folders: Sequence[Path]) -> List[dict]:
    """The paper's table from the evaluations of the runs under ``folders`` (each a matrix's
    ``--out``): one row per variant and suite, train and test scores and the gap with 95%
    intervals (across seeds for one run, across runs where several ``--out`` folders hold
    it), and the normalized test score."""
    from ..scoring.aggregate import aggregate, load_runs

    groups: dict = {}
    for folder in folders:
        for summary in sorted(Path(folder).glob("*/eval/summary.json")):
            cfg = json.loads((summary.parent.parent / "config.json").read_text())
            groups.setdefault((cfg["variant"], cfg["suite"]), []).append(summary.parent)
    rows = []
    for (variant, suite), dirs in sorted(groups.items()):
        docs = load_runs(dirs)
        raw = aggregate(docs, raw=True)
        row = {"variant": variant, "suite": suite, "runs": len(docs)}
        if len(docs) == 1:
            d = docs[0]
            train, test = d["train_agents"][0], d["agents"][0]
            row["train"] = [train["mean"], train["ci_low"], train["ci_high"]]
            row["test"] = [test["mean"], test["ci_low"], test["ci_high"]]
            gap = d["gap"]["raw"]
            row["gap"] = [gap["value"], gap["low"], gap["high"]]
            row["normalized_test"] = d.get("normalized", {}).get("test", {}).get("mean")
        else:
            row["train"] = [raw["train"]["mean"][k] for k in ("value", "low", "high")]
            row["test"] = [raw["test"]["mean"][k] for k in ("value", "low", "high")]
            row["gap"] = [raw["gap"][k] for k in ("value", "low", "high")]
            row["normalized_test"] = aggregate(docs)["test"]["iqm"]["value"]
        rows.append(row)
    return rows


def _iv(v: Sequence[float]) -> str:
    return f"{v[0]:.1f} [{v[1]:.1f}, {v[2]:.1f}]"


def parser() -> argparse.ArgumentParser:
    """The command line."""
    p = argparse.ArgumentParser(
        prog="python -m rogue_gym.train.matrix",
        description="The paper's 12 runs at its protocol: print their commands, or --run them.",
    )
    p.add_argument("--only", nargs="*", default=None, help="runs to keep, e.g. small-10 l2-40")
    p.add_argument("--run", action="store_true", help="run the commands (resumable)")
    p.add_argument(
        "--report",
        nargs="*",
        type=Path,
        default=None,
        help="print the paper's table from the runs' evaluations (this --out, or the folders given)",
    )
    p.add_argument("--out", type=Path, default=Path("runs/paper"), help="folder of the runs")
    p.add_argument("--device", default="cuda")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--compat", default="ours", choices=("ours", "original"))
    p.add_argument("--num-workers", type=int, default=2)
    for key, value in PROTOCOL.items():
        p.add_argument("--" + key.replace("_", "-"), type=int, default=value)
    p.add_argument(
        "train_args", nargs="*", help="more flags for rogue_gym.train, after --", default=[]
    )
    return p


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Print or run the matrix; returns the exit status."""
    args = parser().parse_args(argv)
    if args.report is not None:
        rows = report(args.report or [args.out])
        print("| variant | suite | runs | train | test | gap (train - test) | normalized test |")
        print("|---|---|---:|---|---|---|---:|")
        for r in rows:
            norm = "" if r["normalized_test"] is None else f"{r['normalized_test']:.3f}"
            print(
                f"| {r['variant']} | {r['suite']} | {r['runs']} | {_iv(r['train'])} | "
                f"{_iv(r['test'])} | {_iv(r['gap'])} | {norm} |"
            )
        return 0
    chosen = runs(args.only)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "matrix.json").write_text(
        json.dumps(
            {
                "runs": [r.name for r in chosen],
                "protocol": {k: getattr(args, k) for k in PROTOCOL},
                "compat": args.compat,
                "seed": args.seed,
            },
            indent=1,
        )
        + "\n"
    )
    for i, run in enumerate(chosen, 1):
        for cmd in commands(run, args):
            line = " ".join(shlex.quote(c) for c in cmd)
            print(f"[{i}/{len(chosen)} {run.name}] {line}", flush=True)
            if args.run:
                code = subprocess.call(cmd)
                if code != 0:
                    print(f"{run.name}: exited with {code}; rerun to resume", file=sys.stderr)
                    return code
    return 0


if __name__ == "__main__":
    sys.exit(main())
