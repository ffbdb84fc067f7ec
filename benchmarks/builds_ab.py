"""Two builds of the Python package side by side: the Python ``step()`` of the native game, of
hosted CartPole and of hosted HalfCheetah (``--kinds ... halfcheetah``, where MuJoCo imports:
``.venv-bench``), at 64 envs, each build in its own fresh process, in turns (A B A B ...).

Each turn runs ``--seconds`` of steps after a warm-up and reports env-steps/s; the table gives
each build's median and the median of the B/A ratios of neighbouring turns (a ratio pair by
pair holds when the machine's speed drifts, as this shared VM's does).

    # A: another checkout with its extension built (e.g. a git worktree of the commit before)
    .venv/bin/python benchmarks/builds_ab.py --a /tmp/old/python --pairs 12

``--a`` and ``--b`` are directories put first on ``PYTHONPATH`` (``--b`` defaults to this
checkout's ``python/``). Writes ``results/builds_ab/builds_ab.{md,json}`` (``--out``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = Path(__file__).resolve().parent / "results" / "builds_ab"
KINDS = ("native", "hosted", "halfcheetah")
#: The kinds run when ``--kinds`` is not given.
DEFAULT_KINDS = ("native", "hosted")


def child(kind: str, num_envs: int, seconds: float, workers: int) -> float:
    """Env-steps/s of ``kind`` under the build this process imports."""
    import gymnasium as gym
    import numpy as np
    import rogue_gym

    if kind == "native":
        env = rogue_gym.make_vec(num_envs, config="paper", num_workers=workers, seed=0)
        actions = np.random.default_rng(0).integers(0, 11, size=(256, num_envs))
    elif kind == "hosted":
        fns = [lambda: gym.make("CartPole-v1")] * num_envs
        env = rogue_gym.PoolVectorEnv(fns, num_workers=workers)
        actions = np.random.default_rng(0).integers(0, 2, size=(256, num_envs))
    else:
        fns = [lambda: gym.make("HalfCheetah-v5")] * num_envs
        env = rogue_gym.PoolVectorEnv(fns, num_workers=workers)
        rng = np.random.default_rng(0)
        actions = rng.uniform(-1, 1, size=(256, num_envs, 6)).astype(np.float32)
    try:
        env.reset(seed=0)
        for i in range(50):
            env.step(actions[i % 256])
        steps, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            for i in range(100):
                env.step(actions[i % 256])
            steps += 100
        return steps * num_envs / (time.perf_counter() - t0)
    finally:
        env.close()


def run_turn(path: str, kind: str, args: argparse.Namespace) -> float:
    env = {**os.environ, "PYTHONPATH": path}
    out = subprocess.run(
        [
            sys.executable,
            __file__,
            "--child",
            kind,
            "--num-envs",
            str(args.num_envs),
            "--seconds",
            str(args.seconds),
            "--num-workers",
            str(args.num_workers),
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    ).stdout
    return float(out.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--a", help="PYTHONPATH of build A (the baseline)")
    ap.add_argument("--b", default=str(ROOT / "python"), help="PYTHONPATH of build B")
    ap.add_argument("--pairs", type=int, default=10)
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--num-envs", type=int, default=64)
    ap.add_argument(
        "--num-workers",
        type=int,
        default=1,
        help="1 (default) leaves a core to the caller: 2 workers and the caller on 2 cores "
        "measure the scheduler more than the builds",
    )
    ap.add_argument("--kinds", nargs="+", default=list(DEFAULT_KINDS), choices=KINDS)
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--child", choices=KINDS, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(child(args.child, args.num_envs, args.seconds, args.num_workers))
        return
    if not args.a:
        ap.error("--a (the baseline build's PYTHONPATH) is required")
    per: dict[str, dict[str, list[float]]] = {k: {"a": [], "b": []} for k in args.kinds}
    for p in range(args.pairs):
        for kind in args.kinds:
            # Alternate which build goes first, so neither always meets a warmer machine.
            order = ("a", "b") if p % 2 == 0 else ("b", "a")
            for side in order:
                per[kind][side].append(run_turn(getattr(args, side), kind, args))
            a, b = per[kind]["a"][-1], per[kind]["b"][-1]
            print(f"pair {p} {kind}: A {a:,.0f}  B {b:,.0f}  B/A {b / a:.3f}", flush=True)
    rows = []
    for kind, r in per.items():
        ratios = [b / a for a, b in zip(r["a"], r["b"])]
        rows.append(
            {
                "kind": kind,
                "a_median": statistics.median(r["a"]),
                "b_median": statistics.median(r["b"]),
                "ratio_median": statistics.median(ratios),
                "ratio_min": min(ratios),
                "ratio_max": max(ratios),
                "a": r["a"],
                "b": r["b"],
            }
        )
    lines = [
        f"{args.pairs} pairs, {args.num_envs} envs, {args.num_workers} worker(s), "
        f"{args.seconds:g} s a turn; "
        f"A = {args.a}, B = {args.b}",
        "",
        "| kind | A median steps/s | B median steps/s | B/A median (min-max) |",
        "|---|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['kind']} | {r['a_median']:,.0f} | {r['b_median']:,.0f} | "
            f"{r['ratio_median']:.3f} ({r['ratio_min']:.2f}-{r['ratio_max']:.2f}) |"
        )
    print("\n".join(lines))
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "builds_ab.md").write_text("\n".join(lines) + "\n")
    meta = {
        "machine": platform.node(),
        "cpus": os.cpu_count(),
        "args": {k: str(v) for k, v in vars(args).items()},
    }
    (args.out / "builds_ab.json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
