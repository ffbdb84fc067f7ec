"""Scoring saved checkpoints after training, at any evaluation protocol.

A run saves its weights at every checkpoint (``RUN/models/frames-N.pt``, :mod:`.checkpoint`)
beside its ``config.json``. This module turns one into an evaluator policy
(:func:`checkpoint_policy`, also reached as ``python -m rogue_gym.evaluate --policy
checkpoint:RUN/models/frames-N.pt``) and scores every checkpoint of one or more runs
(:func:`score_runs`), so a run trained with a cheap in-training evaluation can be re-scored at
the paper's protocol (1000 test seeds x 10 episodes) without writing code::

    python -m rogue_gym.train.posthoc runs/small-10 runs/l2-40 --eval-seeds 1000 --eval-episodes 10

Each run gets ``RUN/posthoc-S-E.csv`` (S seeds, E episodes) with the progress columns of an
evaluation (``frames, gen_score, gen_ci_low, gen_ci_high``) plus ``seeds, episodes``; a
checkpoint already in that file is skipped, so an interrupted scoring resumes where it stopped.
"""

from __future__ import annotations

import argparse
import csv
import json
import re
import sys
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

import torch

from ..suites import Suite, get_suite
from .config import TrainConfig
from .evaluation import CONFIDENCE, TorchPolicy, generalization
from .networks import PolicyNet, build_network

__all__ = ["CheckpointPolicy", "checkpoint_policy", "checkpoints", "score_runs"]

#: Columns of ``posthoc-S-E.csv``.
COLUMNS = ["frames", "gen_score", "gen_ci_low", "gen_ci_high", "seeds", "episodes"]

_FRAMES = re.compile(r"frames-(\d+)\.pt$")


def run_config(run: Path) -> TrainConfig:
    """The ``TrainConfig`` a run saved in ``RUN/config.json``."""
    path = Path(run) / "config.json"
    if not path.exists():
        raise FileNotFoundError(f"{path} not found: is {run} a run folder of rogue_gym.train?")
    fields = {f for f in TrainConfig.__dataclass_fields__}
    data = {k: v for k, v in json.loads(path.read_text()).items() if k in fields}
    data["out"] = Path(data.get("out", run))
    return TrainConfig(**data)


def _screen(suite: Suite) -> tuple[int, int, int]:
    """``(symbols, height, width)`` of the suite's symbol-index screens."""
    from .. import make_vec

    env = make_vec(1, config=suite.config, num_workers=1, seed=0, obs="symbol_index")
    try:
        space: Any = env.single_observation_space  # Box(0, symbols - 1, (H, W))
        return int(space.high.max()) + 1, int(space.shape[0]), int(space.shape[1])
    finally:
        env.close()


def load_network(path: Path, device: str = "cpu") -> tuple[PolicyNet, TrainConfig]:
    """The network saved at checkpoint ``path`` (``RUN/models/frames-N.pt``) and its run's
    config."""
    path = Path(path)
    if not _FRAMES.search(path.name):
        raise ValueError(f"{path}: expected a checkpoint named like RUN/models/frames-N.pt")
    cfg = run_config(path.parent.parent)
    symbols, height, width = _screen(get_suite(cfg.suite))
    from ..evaluate import NUM_ACTIONS

    net = build_network(cfg.variant, symbols, height, width, NUM_ACTIONS)
    net.load_state_dict(torch.load(path, map_location=device, weights_only=True))
    net.to(device).eval()
    return net, cfg


class CheckpointPolicy(TorchPolicy):
    """A saved checkpoint as an evaluator policy (stochastic, as the paper evaluates).

    ``required_obs`` tells the evaluator which observation the network reads.
    """

    required_obs = "symbol_index"

    def __init__(self, net: PolicyNet, device: torch.device, cfg: TrainConfig) -> None:
        super().__init__(net, device)
        #: The run's config (its suite, variant and seed).
        self.config = cfg


def checkpoint_policy(path: Path, device: str = "cpu") -> CheckpointPolicy:
    """The policy of checkpoint ``path`` (``RUN/models/frames-N.pt``)."""
    net, cfg = load_network(path, device)
    return CheckpointPolicy(net, torch.device(device), cfg)


def checkpoints(run: Path) -> List[tuple[int, Path]]:
    """``(frames, path)`` of every saved checkpoint of ``run``, in order."""
    found = []
    for p in (Path(run) / "models").glob("frames-*.pt"):
        m = _FRAMES.search(p.name)
        if m:
            found.append((int(m.group(1)), p))
    return sorted(found)


def _done(path: Path) -> set[int]:
    if not path.exists():
        return set()
    with path.open() as f:
        return {int(row["frames"]) for row in csv.DictReader(f)}


def score_runs(
    runs: Sequence[Path],
    eval_seeds: int = 1000,
    eval_episodes: int = 10,
    num_envs: int = 64,
    num_workers: int = 2,
    seed: int = 0,
    device: str = "cpu",
    log: Any = print,
) -> Dict[Path, Path]:
    """Score every checkpoint of each run on its suite's first ``eval_seeds`` test seeds,
    ``eval_episodes`` each; returns each run's results file. Checkpoints already scored at
    this protocol are skipped."""
    out: Dict[Path, Path] = {}
    for run in map(Path, runs):
        cfg = run_config(run)
        suite = get_suite(cfg.suite)
        results = run / f"posthoc-{eval_seeds}-{eval_episodes}.csv"
        done = _done(results)
        todo = [(f, p) for f, p in checkpoints(run) if f not in done]
        log(f"{run}: {cfg.variant} on {cfg.suite}, {len(done)} scored, {len(todo)} to score")
        for frames, path in todo:
            net, _ = load_network(path, device)
            r = generalization(
                net,
                torch.device(device),
                suite,
                eval_seeds,
                eval_episodes,
                num_envs,
                num_workers,
                seed,
            )
            new = not results.exists()
            with results.open("a", newline="") as f:
                w = csv.writer(f)
                if new:
                    w.writerow(COLUMNS)
                w.writerow([frames, r.mean, r.ci_low, r.ci_high, eval_seeds, eval_episodes])
            log(
                f"  frames {frames}: {r.mean:.2f} [{r.ci_low:.2f}, {r.ci_high:.2f}] "
                f"({CONFIDENCE:.0%} CI over {eval_seeds} seeds)"
            )
        out[run] = results
    return out


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``python -m rogue_gym.train.posthoc RUN [RUN ...]``; returns the exit status."""
    p = argparse.ArgumentParser(
        prog="python -m rogue_gym.train.posthoc",
        description="Score every saved checkpoint of one or more runs on their suite's test "
        "seeds (resumable).",
    )
    p.add_argument("runs", nargs="+", type=Path, help="run folders (with config.json, models/)")
    p.add_argument("--eval-seeds", type=int, default=1000, help="test seeds (the paper: 1000)")
    p.add_argument("--eval-episodes", type=int, default=10, help="episodes per seed (paper: 10)")
    p.add_argument("--num-envs", type=int, default=64)
    p.add_argument("--num-workers", type=int, default=2)
    p.add_argument("--seed", type=int, default=0, help="seeds the policy's action sampling")
    p.add_argument("--device", default="cpu")
    a = p.parse_args(argv)
    score_runs(a.runs, a.eval_seeds, a.eval_episodes, a.num_envs, a.num_workers, a.seed, a.device)
    return 0


if __name__ == "__main__":
    sys.exit(main())
