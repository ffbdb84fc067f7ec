"""Generalization evaluator: score a policy on a frozen suite's test seeds through the pool.

Command line::

    python -m rogue_gym.evaluate --suite paper-40 --policy random
    python -m rogue_gym.evaluate --suite paper-40 --policy my_pkg.agents:policy \\
        [--episodes-per-seed 10] [--num-envs 64] [--num-workers 2] [--seeds-limit 50] \\
        [--out DIR] [--policy-seed 0] [--confidence 0.95]
    python -m rogue_gym.evaluate --suite paper-40 --manifest-only [--out DIR]

What it reports (printed, and written under ``--out``):

* ``per_seed.csv``: one row per test seed: the policy's mean/std/min/max return over the
  seed's episodes, the random agent's mean on the same seed, and the seed's difficulty
  metadata (see :func:`seed_manifest`).
* ``summary.json``: the suite (with its digest), the settings, the per-episode returns of
  both agents as ``(seeds, episodes)`` arrays, and for each agent the mean over seeds with a
  bootstrap confidence interval **across seeds** (per-seed means are resampled, never single
  episodes: episodes of one seed are not independent samples of the benchmark).
* ``manifest.csv`` / ``manifest.json`` with ``--manifest-only``.

The random agent is always scored on the same seeds in the same run (unless the policy *is*
the random agent), so the two numbers are directly comparable.

**Policy interface.** ``--policy module:attr`` (or ``path/to/file.py:attr``) names a Python
object. If it is a class it is instantiated with no arguments. The result must be callable as
``policy(obs) -> actions``: ``obs`` is a numpy array of shape ``(N, *obs_shape)`` (one row per
environment of the pool, in environment order; the encoding is ``--obs ENCODING[:DTYPE]``,
default ``symbol_onehot`` in uint8, ``symbol_onehot:float32`` for the paper's input), and
``actions`` an integer array-like of shape ``(N,)`` with values in ``[0, 11)``. The array
``obs`` is only valid during the call: copy what you keep. If the policy has a
``seed(seed: int)`` method it is called once before evaluation with ``--policy-seed``; a
policy must be deterministic given that seed, and then the whole evaluation is: the pool's
episodes are a pure function of the seed schedule, independent of the number of workers.
A policy with a ``required_obs`` attribute is given that encoding whatever ``--obs`` says.
``--policy checkpoint:RUN/models/frames-N.pt`` (or ``checkpoint:RUN``, its last) scores a network saved by ``rogue_gym.train``
(:mod:`rogue_gym.train.posthoc`; it reads symbol indices).

**Episode schedule.** With ``K`` test seeds and ``E`` episodes per seed, the evaluator hands
the pool the seed list with the sequential (round-robin) seed policy: environment ``i``'s
``e``-th episode has schedule index ``j = i + e * N`` and plays ``seeds[j % K]``. The first
``M = K * E`` indices cover every seed exactly ``E`` times; episodes with ``j >= M`` are played
out (the pool steps all environments together) but discarded. Results therefore depend on
``(policy, policy seed, num_envs)`` but never on the number of workers.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

from .agents import ReferenceAgent
from .scoring.episodes import InProcessVec, run_episodes
from .scoring.policies import NUM_ACTIONS, Policy, RandomPolicy, load_policy
from .scoring.reports import (
    describe_manifest,
    per_seed_rows,
    seed_manifest,
    strata_rows,
    write_manifest,
    write_results,
)
from .scoring.runs import iqm
from .scoring.stats import AgentResult, bootstrap_ci, gap_ci, normalized
from .scoring.versions import result_versions
from .suites import Suite, get_suite, suite_names

__all__ = [
    "NUM_ACTIONS",
    "AgentResult",
    "InProcessVec",
    "RandomPolicy",
    "bootstrap_ci",
    "evaluate",
    "load_policy",
    "main",
    "per_seed_rows",
    "run_episodes",
    "score",
    "seed_manifest",
    "write_manifest",
    "write_results",
]


#: The splits of a suite an evaluation scores: the unseen test seeds and the training seeds.
SPLITS = ("test", "train")


def score(
    suite: Suite,
    policy: Policy,
    seeds: Sequence[int],
    episodes_per_seed: int,
    *,
    name: str = "policy",
    obs: str = "symbol_onehot",
    num_envs: int = 16,
    num_workers: Optional[int] = None,
    policy_seed: int = 0,
    confidence: float = 0.95,
    bootstrap_seed: int = 0,
    progress: bool = False,
    backend: str = "pool",
    desc: str = "",
) -> AgentResult:
    """One agent's score on ``seeds`` of ``suite``: its episodes played through the pool, the
    mean over seeds with its bootstrap interval, each episode's deepest floor. Every score of
    the benchmark is made here: the evaluator's, per agent and split, and the trainer's
    generalization score."""
    floors = np.zeros((len(seeds), episodes_per_seed), np.int64) if backend == "pool" else None
    returns = run_episodes(
        suite,
        policy,
        seeds,
        episodes_per_seed,
        num_envs=num_envs,
        num_workers=num_workers,
        obs=obs,
        policy_seed=policy_seed,
        progress=progress,
        desc=desc,
        backend=backend,
        max_floor=floors,
    )
    result = AgentResult.from_returns(name, returns, confidence, bootstrap_seed)
    result.max_floor = floors
    return result


def _split_seeds(suite: Suite, split: str, limit: Optional[int]) -> List[int]:
    seeds = suite.test_seed_list() if split == "test" else suite.train_seed_list()
    return seeds if limit is None else seeds[: int(limit)]


def evaluate(
    suite: Suite,
    policy_spec: str = "random",
    policy: Optional[Policy] = None,
    episodes_per_seed: Optional[int] = None,
    num_envs: int = 16,
    num_workers: Optional[int] = None,
    seeds_limit: Optional[int] = None,
    obs: str = "symbol_onehot",
    policy_seed: int = 0,
    confidence: float = 0.95,
    bootstrap_seed: int = 0,
    with_random: bool = True,
    with_manifest: bool = True,
    progress: bool = True,
    backend: str = "pool",
    with_reference: bool = True,
    with_train: bool = True,
) -> Dict[str, Any]:
    """Evaluate a policy on ``suite``; returns the summary dict written to ``summary.json``.

    ``policy`` (a callable) takes precedence over ``policy_spec``. ``seeds_limit`` keeps the
    first K seeds of each split (quick runs; say so when quoting numbers). The policy plays
    the test seeds and (``with_train``) the training seeds; the random agent and the reference
    agent (:class:`rogue_gym.agents.ReferenceAgent`: deterministic, so one episode per seed
    stands for all) play the same seeds, and scores are normalized between them.
    """
    if policy is None:
        policy = load_policy(policy_spec)
    # A policy that reads one observation only (a trained network: symbol indices) says so.
    obs = getattr(policy, "required_obs", obs)
    is_random = policy_spec == "random" and isinstance(policy, RandomPolicy)
    is_reference = isinstance(policy, ReferenceAgent)
    name = "random" if is_random else policy_spec
    e_per = int(episodes_per_seed or suite.episodes_per_seed)
    common: Dict[str, Any] = dict(
        num_envs=num_envs,
        num_workers=num_workers,
        policy_seed=policy_seed,
        progress=progress,
        backend=backend,
    )
    t0 = time.perf_counter()
    splits = [s for s in SPLITS if with_train or s == "test"]
    agents: Dict[str, List[AgentResult]] = {}
    seeds_of: Dict[str, List[int]] = {}
    for split in splits:
        seeds = seeds_of[split] = _split_seeds(suite, split, seeds_limit)
        runs = [(name, policy, e_per, obs)]
        if with_random and not is_random:
            runs.append(("random", RandomPolicy(), e_per, obs))
        if with_reference and not is_reference:
            ref = ReferenceAgent()
            runs.append(("reference", ref, 1, ref.required_obs))
        agents[split] = [
            score(
                suite,
                p,
                seeds,
                e,
                name=who,
                obs=o,
                confidence=confidence,
                bootstrap_seed=bootstrap_seed,
                desc=f"{suite.name} {split} {who}",
                **common,
            )
            for who, p, e, o in runs
        ]
    elapsed = time.perf_counter() - t0
    manifest: List[Dict[str, Any]] = []
    if with_manifest:
        try:
            manifest = seed_manifest(suite, seeds_of["test"])
        except (ImportError, AttributeError) as exc:
            print(f"note: no seed manifest ({exc})", file=sys.stderr)
    result: Dict[str, Any] = {
        "format": 2,
        "versions": result_versions(suite),
        "suite": suite.canonical() | {"digest": suite.digest(), "description": suite.description},
        "settings": {
            "policy": policy_spec,
            "policy_seed": policy_seed,
            "episodes_per_seed": e_per,
            "seeds": seeds_of["test"],
            "train_seeds": seeds_of.get("train", []),
            "seeds_limit": seeds_limit,
            "num_envs": num_envs,
            "num_workers": num_workers,
            "obs": obs,
            "backend": backend,
            "confidence": confidence,
            "bootstrap_seed": bootstrap_seed,
            "bootstrap_resamples": 10_000,
            "elapsed_s": round(elapsed, 3),
            "python": platform.python_version(),
            "host": platform.node(),
        },
        "agents": [a.to_json() for a in agents["test"]],
        "train_agents": [a.to_json() for a in agents.get("train", [])],
        "manifest": manifest,
        "_agents": agents["test"],
        "_train_agents": agents.get("train", []),
    }
    result.update(_headline(agents, confidence, bootstrap_seed))
    if manifest:
        per_seed = {a.name: a.returns.mean(axis=1) for a in agents["test"]}
        result["strata"] = strata_rows(manifest, per_seed)
    return result


def _headline(
    agents: Dict[str, List[AgentResult]], confidence: float, bootstrap_seed: int
) -> Dict[str, Any]:
    """The normalized scores of the policy (per split: per seed, their mean with its interval
    and their IQM) and the generalization gap, raw and normalized; empty without the random
    and the reference agent (or when the policy is one of them)."""
    out: Dict[str, Any] = {"normalized": {}, "gap": {}}
    norm: Dict[str, np.ndarray] = {}
    for split, results in agents.items():
        by = {a.name: a.returns.mean(axis=1) for a in results}
        if "random" not in by or "reference" not in by:
            continue
        scores = normalized(results[0].returns.mean(axis=1), by["random"], by["reference"])
        norm[split] = scores
        mean, lo, hi = bootstrap_ci(scores, confidence=confidence, seed=bootstrap_seed)
        out["normalized"][split] = {
            "mean": mean,
            "ci_low": lo,
            "ci_high": hi,
            "iqm": iqm(scores),
            "per_seed": scores.tolist(),
        }
    if "train" in agents:
        train, test = (agents[s][0].returns.mean(axis=1) for s in ("train", "test"))
        gap, lo, hi = gap_ci(train, test, confidence, seed=bootstrap_seed)
        out["gap"]["raw"] = {"value": gap, "low": lo, "high": hi}
        if "train" in norm and "test" in norm:
            gap, lo, hi = gap_ci(norm["train"], norm["test"], confidence, seed=bootstrap_seed)
            out["gap"]["normalized"] = {"value": gap, "low": lo, "high": hi}
    return out


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m rogue_gym.evaluate",
        description="Score a policy on a frozen Rogue-Gym generalization suite's test seeds.",
    )
    p.add_argument("--suite", required=True, choices=suite_names())
    p.add_argument(
        "--policy",
        default="random",
        help="'random', 'reference', 'module:attr' or 'checkpoint:RUN/models/frames-N.pt'",
    )
    p.add_argument("--policy-seed", type=int, default=0)
    p.add_argument("--episodes-per-seed", type=int, default=None, help="default: the suite's")
    p.add_argument("--num-envs", type=int, default=64)
    p.add_argument("--num-workers", type=int, default=None, help="default: the pool's")
    p.add_argument("--seeds-limit", type=int, default=None, help="first K test seeds only")
    p.add_argument(
        "--obs",
        default="symbol_onehot",
        help="observation for the policy: ENCODING[:DTYPE], e.g. symbol_onehot:float32 (the "
        "paper's), symbol_onehot (uint8), symbol_index",
    )
    p.add_argument("--confidence", type=float, default=0.95)
    p.add_argument("--bootstrap-seed", type=int, default=0)
    p.add_argument("--no-random", action="store_true", help="skip the random-agent baseline")
    p.add_argument(
        "--no-reference", action="store_true", help="skip the reference agent (no normalized score)"
    )
    p.add_argument("--no-train", action="store_true", help="score the test seeds only (no gap)")
    p.add_argument("--manifest-only", action="store_true", help="write the seed manifest only")
    p.add_argument("--out", type=Path, default=None, help="output folder")
    p.add_argument("--no-progress", action="store_true")
    p.add_argument(
        "--backend",
        choices=["pool", "inprocess"],
        default="pool",
        help="pool (worker processes) or inprocess (RogueEnv games here; same results)",
    )
    return p


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Command-line entry point; returns the exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv and argv[0] in ("aggregate", "compare"):
        from .scoring.aggregate import main as runs_main

        return runs_main(argv)
    args = _parser().parse_args(argv)
    suite = get_suite(args.suite)
    seeds = suite.test_seed_list()
    if args.seeds_limit is not None:
        seeds = seeds[: args.seeds_limit]
    if args.manifest_only:
        rows = seed_manifest(suite, seeds)
        out = args.out or Path(f"rogue_gym_eval/{suite.name}")
        paths = write_manifest(rows, out)
        print(f"suite {suite.name} (digest {suite.digest()[:12]}), {len(rows)} test seeds")
        print(describe_manifest(rows))
        print("wrote " + ", ".join(str(p) for p in paths))
        return 0
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    result = evaluate(
        suite,
        policy_spec=args.policy,
        episodes_per_seed=args.episodes_per_seed,
        num_envs=args.num_envs,
        num_workers=args.num_workers,
        seeds_limit=args.seeds_limit,
        obs=args.obs,
        policy_seed=args.policy_seed,
        confidence=args.confidence,
        bootstrap_seed=args.bootstrap_seed,
        with_random=not args.no_random,
        with_reference=not args.no_reference,
        with_train=not args.no_train,
        progress=not args.no_progress,
        backend=args.backend,
    )
    tag = "random" if args.policy == "random" else _safe_name(args.policy)
    out = args.out or Path(f"rogue_gym_eval/{suite.name}-{tag}")
    paths = write_results(result, out)
    print(f"suite {suite.name} (digest {suite.digest()[:12]}): {suite.description}")
    for split, key in (("test", "_agents"), ("train", "_train_agents")):
        for agent in result[key]:
            print(f"{split} {agent.line(args.confidence)}")
        norm = result["normalized"].get(split)
        if norm:
            print(
                f"{split} normalized (0 random, 1 reference): {norm['mean']:.3f} "
                f"[{norm['ci_low']:.3f}, {norm['ci_high']:.3f}], IQM {norm['iqm']:.3f}"
            )
    for kind, gap in result["gap"].items():
        print(
            f"gap train - test ({kind}): {gap['value']:.3f} [{gap['low']:.3f}, {gap['high']:.3f}]"
        )
    print(f"elapsed {result['settings']['elapsed_s']:.1f} s; wrote " + ", ".join(map(str, paths)))
    return 0


def _safe_name(spec: str) -> str:
    keep = [c if c.isalnum() or c in "-_." else "_" for c in spec]
    return "".join(keep)[:60] or "policy"


if __name__ == "__main__":
    sys.exit(main())
