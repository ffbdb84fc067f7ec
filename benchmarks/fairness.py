"""Fair service of the async API beside a CPU hog: 8 envs in 4 workers, ``batch_size=2``,
10,000 ``recv``s (each sends back the envs it got), with a process spinning on a core
meanwhile; per run, how far the env served most or least is from the mean.

    .venv/bin/python benchmarks/fairness.py [--runs 10] [--recvs 10000] [--kinds cartpole native]

The pool promises that among the ready envs the one sent first is served first
(``docs/performance.md``, "Fair service"); the target is every env within 10% of the mean in
every run. Writes ``results/fairness/fairness.{md,json}`` (``--out``).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from common import write_results

RESULTS = Path(__file__).resolve().parent / "results" / "fairness"


def _pool(kind: str) -> Any:
    import rogue_gym

    if kind == "native":
        return rogue_gym.make_vec(
            "RogueGym-v0", num_envs=8, num_workers=4, batch_size=2, max_steps=10_000
        )
    return rogue_gym.make_vec("CartPole-v1", num_envs=8, num_workers=4, batch_size=2)


def one_run(kind: str, recvs: int) -> dict[str, Any]:
    """One run beside a fresh CPU hog: per-env counts and the worst deviation."""
    hog = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        env = _pool(kind)
        try:
            count: Counter = Counter()
            env.async_reset(seed=0)
            t0 = time.perf_counter()
            for _ in range(recvs):
                _, _, _, _, info = env.recv()
                ids = info["env_id"]
                count.update(ids.tolist())
                env.send(np.zeros(len(ids), np.int64), ids)
            seconds = time.perf_counter() - t0
        finally:
            env.close()
    finally:
        hog.kill()
        hog.wait(timeout=10)
    per_env = [count[e] for e in range(8)]
    mean = sum(per_env) / 8
    worst = max(abs(c - mean) / mean for c in per_env)
    return {"per_env": per_env, "worst": worst, "seconds": seconds}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=10)
    p.add_argument("--recvs", type=int, default=10_000)
    p.add_argument("--kinds", nargs="+", default=["cartpole", "native"])
    p.add_argument("--out", type=Path, default=RESULTS)
    args = p.parse_args()
    rows, data = [], {}
    for kind in args.kinds:
        runs = []
        for r in range(args.runs):
            got = one_run(kind, args.recvs)
            runs.append(got)
            print(
                f"{kind} run {r + 1}: worst {got['worst']:.1%} counts {got['per_env']}", flush=True
            )
        worst = max(g["worst"] for g in runs)
        ok = sum(g["worst"] <= 0.10 for g in runs)
        rows.append(
            f"| {kind} | {args.runs} | {ok} | {worst:.1%} | "
            f"{np.median([g['worst'] for g in runs]):.1%} |"
        )
        data[kind] = runs
    md = "\n".join(
        [
            f"# Fair service beside a CPU hog ({args.recvs} recvs, 8 envs, 4 workers, batch 2)",
            "",
            "| kind | runs | runs within 10% | worst deviation | median run's worst |",
            "|---|---:|---:|---:|---:|",
            *rows,
        ]
    )
    print(md)
    md_path, _ = write_results(args.out, "fairness", md, data)
    print(f"wrote {md_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
