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

The paper's two analyses, on the same checkpoints:

* ``--entropy``: the policy's mean entropy per step on the first 10 *training* seeds, 10
  episodes each, for every checkpoint (the authors' ``agents/eval_cog_ent.py``), into
  ``RUN/entropy-S-E.csv`` (``frames, entropy, seeds, episodes``; resumable). The entropy is
  averaged over every step the policy takes while those episodes are played.
* ``--one-seed 1008 --trials 10``: the last checkpoint's returns on one test seed, and its
  mean action probabilities there (the authors' ``agents/eval_1seed.py``), into
  ``RUN/seed-1008.json``.

``python -m rogue_gym.train.plot`` draws all three.
"""

from __future__ import annotations

import argparse
import csv
import json
import re
import sys
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

import numpy as np
import torch

from ..suites import Suite, get_suite
from .config import TrainConfig
from .evaluation import CONFIDENCE, TorchPolicy, generalization
from .networks import PolicyNet, build_network

__all__ = [
    "CheckpointPolicy",
    "checkpoint_policy",
    "checkpoints",
    "entropy_runs",
    "one_seed_runs",
    "score_runs",
]

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
    from ..suite_pool import suite_pool

    env = suite_pool(suite, 1, num_workers=1, seed=0, obs="symbol_index")
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

    original = cfg.compat == "original"
    net = build_network(cfg.variant, symbols, height, width, NUM_ACTIONS, original=original)
    net.load_state_dict(torch.load(path, map_location=device, weights_only=True))
    net.to(device).train(original)  # the paper's code never left train mode
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
    """The policy of checkpoint ``path`` (``RUN/models/frames-N.pt``), or of a run folder's
    last checkpoint."""
    if Path(path).is_dir():
        saved = checkpoints(Path(path))
        if not saved:
            raise ValueError(f"{path}: a run folder with no checkpoint in models/")
        path = saved[-1][1]
    net, cfg = load_network(path, device)
    return CheckpointPolicy(net, torch.device(device), cfg)


class _MeasuringPolicy(CheckpointPolicy):
    """A checkpoint policy that also sums its entropy and action probabilities over steps."""

    def __init__(self, net: PolicyNet, device: torch.device, cfg: TrainConfig) -> None:
        super().__init__(net, device, cfg)
        self.entropy_sum = 0.0
        self.prob_sum: Optional[torch.Tensor] = None
        self.rows = 0

    @torch.no_grad()
    def __call__(self, obs: Any) -> Any:
        x = torch.from_numpy(np.array(obs, copy=True)).to(self.device)
        logp = torch.log_softmax(self.net(x).logits.float(), dim=-1).cpu()
        probs = logp.exp()
        self.entropy_sum += float(-(probs * logp).sum())
        total = probs.sum(0)
        self.prob_sum = total if self.prob_sum is None else self.prob_sum + total
        self.rows += probs.shape[0]
        return torch.multinomial(probs, 1, generator=self.generator).squeeze(1).numpy()


def _measure(
    path: Path, seeds: List[int], episodes: int, num_workers: int, seed: int, device: str
) -> tuple[_MeasuringPolicy, np.ndarray]:
    """Play ``episodes`` episodes on each of ``seeds`` (one batch of ``episodes`` envs per seed,
    as the authors' scripts did) with checkpoint ``path``; the policy and the returns."""
    from ..evaluate import run_episodes
    from .evaluation import same_seed_schedule

    net, cfg = load_network(path, device)
    policy = _MeasuringPolicy(net, torch.device(device), cfg)
    w = num_workers if episodes % num_workers == 0 else 1
    returns = run_episodes(
        get_suite(cfg.suite),
        policy,
        same_seed_schedule(seeds, episodes),
        1,
        num_envs=episodes,
        num_workers=w,
        obs="symbol_index",
        policy_seed=seed,
        progress=False,
    )
    return policy, returns.reshape(len(seeds), episodes)


def entropy_runs(
    runs: Sequence[Path],
    seeds: int = 10,
    episodes: int = 10,
    num_workers: int = 2,
    seed: int = 0,
    device: str = "cpu",
    log: Any = print,
) -> Dict[Path, Path]:
    """Each checkpoint's mean policy entropy per step on the first ``seeds`` training seeds,
    ``episodes`` episodes each, into ``RUN/entropy-S-E.csv`` (checkpoints done are skipped)."""
    out: Dict[Path, Path] = {}
    for run in map(Path, runs):
        cfg = run_config(run)
        train_seeds = get_suite(cfg.suite).train_seed_list()[:seeds]
        results = run / f"entropy-{seeds}-{episodes}.csv"
        done = _done(results)
        for frames, path in checkpoints(run):
            if frames in done:
                continue
            policy, _ = _measure(path, train_seeds, episodes, num_workers, seed, device)
            ent = policy.entropy_sum / max(policy.rows, 1)
            new = not results.exists()
            with results.open("a", newline="") as f:
                w = csv.writer(f)
                if new:
                    w.writerow(["frames", "entropy", "seeds", "episodes"])
                w.writerow([frames, ent, len(train_seeds), episodes])
            log(f"{run} frames {frames}: entropy {ent:.4f} nats per step")
        out[run] = results
    return out


def one_seed_runs(
    runs: Sequence[Path],
    test_seed: int = 1008,
    trials: int = 10,
    num_workers: int = 2,
    seed: int = 0,
    device: str = "cpu",
    log: Any = print,
) -> Dict[Path, Path]:
    """The last checkpoint's returns in ``trials`` episodes on ``test_seed`` and its mean
    action probabilities there, into ``RUN/seed-S.json``."""
    from ..envs.rogue_env import ACTIONS

    out: Dict[Path, Path] = {}
    for run in map(Path, runs):
        found = checkpoints(run)
        if not found:
            raise FileNotFoundError(f"{run}: no checkpoint in {run / 'models'}")
        frames, path = found[-1]
        policy, returns = _measure(path, [test_seed], trials, num_workers, seed, device)
        rows = max(policy.rows, 1)
        probs = [] if policy.prob_sum is None else (policy.prob_sum / rows).tolist()
        result = {
            "run": run.name,
            "variant": policy.config.variant,
            "suite": policy.config.suite,
            "frames": frames,
            "seed": test_seed,
            "returns": [float(r) for r in returns[0]],
            "mean": float(returns.mean()),
            "action_probs": dict(zip(ACTIONS, probs)),
        }
        path_out = run / f"seed-{test_seed}.json"
        path_out.write_text(json.dumps(result, indent=1) + "\n")
        log(f"{run}: seed {test_seed}, {trials} trials, mean {result['mean']:.2f}")
        out[run] = path_out
    return out


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
                cfg.compat,
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
    p.add_argument(
        "--entropy",
        action="store_true",
        help="measure each checkpoint's policy entropy on the first --eval-seeds training "
        "seeds instead (the paper: 10 seeds x 10 episodes)",
    )
    p.add_argument(
        "--one-seed",
        type=int,
        default=None,
        help="score the last checkpoint on this one test seed instead (the paper: 1008), with "
        "its action probabilities",
    )
    p.add_argument("--trials", type=int, default=10, help="episodes for --one-seed")
    a = p.parse_args(argv)
    if a.one_seed is not None:
        one_seed_runs(a.runs, a.one_seed, a.trials, a.num_workers, a.seed, a.device)
    elif a.entropy:
        entropy_runs(a.runs, a.eval_seeds, a.eval_episodes, a.num_workers, a.seed, a.device)
    else:
        score_runs(
            a.runs, a.eval_seeds, a.eval_episodes, a.num_envs, a.num_workers, a.seed, a.device
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
