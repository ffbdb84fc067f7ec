"""Two builds of the Python package side by side: the Python ``step()`` of the native game, of
hosted CartPole and of hosted HalfCheetah (``--kinds ... halfcheetah``, where MuJoCo imports:
``.venv-bench``), at 64 envs; and the async API in two halves (``native-halves``,
``hosted-halves``: ``recv`` one half, ``send`` it).

Each build runs in its own process, both alive at once, each with its pool built, reset and
warmed up; this process has them step in alternating bursts of ``--seconds`` (A B, then B A,
...), one pair after another. The table gives each build's median env-steps/s, the median of
the B/A ratios of the pairs and a 95% interval of that median (bootstrap over pairs): bursts a
fraction of a second apart see the same machine, so the ratio holds when the machine's speed
drifts, as this shared VM's does, and many short pairs resolve differences of 1%.

    # A: another checkout with its extension built (e.g. a git worktree of the commit before)
    .venv/bin/python benchmarks/builds_ab.py --a /tmp/old/python --pairs 400 --seconds 0.1

``--a`` and ``--b`` are directories put first on ``PYTHONPATH`` (``--b`` defaults to this
checkout's ``python/``). Writes ``results/builds_ab/builds_ab.{md,json}`` (``--out``).
What the pool's counters cost: build A without them (``maturin develop --release
--no-default-features -m python/Cargo.toml`` in a worktree) and B as it is.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from common import env_fn, median_interval, write_results

ROOT = Path(__file__).resolve().parent.parent
RESULTS = Path(__file__).resolve().parent / "results" / "builds_ab"
KINDS = ("native", "hosted", "halfcheetah", "native-halves", "hosted-halves")
#: The kinds run when ``--kinds`` is not given.
DEFAULT_KINDS = ("native", "hosted")


def make_env(kind: str, num_envs: int, workers: int) -> tuple[Any, Any]:
    """The vector env of ``kind`` under the build this process imports, and 256 batches of
    actions for it."""
    import numpy as np
    import rogue_gym

    rng = np.random.default_rng(0)
    # The async API in two halves (``*-halves``): recv one half, send it, as a trainer does.
    halves = {"batch_size": num_envs // 2} if kind.endswith("-halves") else {}
    if kind.startswith("native"):
        env = rogue_gym.make_vec(num_envs, config="paper", num_workers=workers, seed=0, **halves)
        return env, rng.integers(0, 11, size=(256, num_envs))
    if kind.startswith("hosted"):
        fns = [env_fn("cartpole")] * num_envs
        env = rogue_gym.PoolVectorEnv(fns, num_workers=workers, **halves)
        return env, rng.integers(0, 2, size=(256, num_envs))
    fns = [env_fn("halfcheetah")] * num_envs
    env = rogue_gym.PoolVectorEnv(fns, num_workers=workers)
    return env, rng.uniform(-1, 1, size=(256, num_envs, 6)).astype(np.float32)


def serve(kind: str, num_envs: int, workers: int) -> None:
    """A build's side: build, reset and warm up the env, say ``ready``, then for every line
    ``burst SECONDS`` on stdin step for that long and print env-steps/s; stop at end of
    input."""
    env, actions = make_env(kind, num_envs, workers)
    halves = kind.endswith("-halves")
    half = num_envs // 2

    def one(i: int) -> int:
        """One step of every env (sync), or of a half (async); env-steps taken."""
        if not halves:
            env.step(actions[i % 256])
            return num_envs
        *_, infos = env.recv()
        env.send(actions[i % 256][:half], infos["env_id"])
        return half

    try:
        if halves:
            env.async_reset(seed=0)  # both halves in flight from here on
        else:
            env.reset(seed=0)
        for i in range(50):
            one(i)
        print("ready", flush=True)
        i = 0
        for line in sys.stdin:
            seconds = float(line.split()[1])
            steps, t0 = 0, time.perf_counter()
            while time.perf_counter() - t0 < seconds:
                for _ in range(20):
                    steps += one(i)
                    i += 1
            print(steps / (time.perf_counter() - t0), flush=True)
    finally:
        env.close()


class Side:
    """One build's serving process."""

    def __init__(self, path: str, kind: str, args: argparse.Namespace) -> None:
        cmd = [sys.executable, __file__, "--serve", kind, "--num-envs", str(args.num_envs)]
        cmd += ["--num-workers", str(args.num_workers)]
        env = {**os.environ, "PYTHONPATH": path}
        self.proc = subprocess.Popen(
            cmd, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
        )
        self._expect("ready")

    def _expect(self, what: str) -> str:
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if not line or (what and line.strip() != what):
            self.close()
            raise RuntimeError(f"a build's process stopped (exit {self.proc.wait(10)})")
        return line

    def burst(self, seconds: float) -> float:
        """Env-steps/s over a burst of ``seconds``."""
        assert self.proc.stdin is not None
        self.proc.stdin.write(f"burst {seconds}\n")
        self.proc.stdin.flush()
        return float(self._expect(""))

    def close(self) -> None:
        if self.proc.stdin is not None and not self.proc.stdin.closed:
            self.proc.stdin.close()
        try:
            self.proc.wait(30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--a", help="PYTHONPATH of build A (the baseline)")
    ap.add_argument("--b", default=str(ROOT / "python"), help="PYTHONPATH of build B")
    ap.add_argument("--pairs", type=int, default=200, help="pairs of bursts per kind")
    ap.add_argument("--seconds", type=float, default=0.1, help="seconds of each burst")
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
    ap.add_argument("--serve", choices=KINDS, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.serve:
        serve(args.serve, args.num_envs, args.num_workers)
        return
    if not args.a:
        ap.error("--a (the baseline build's PYTHONPATH) is required")
    per: dict[str, dict[str, list[float]]] = {k: {"a": [], "b": []} for k in args.kinds}
    for kind in args.kinds:
        sides: dict[str, Side] = {}
        try:
            sides["a"] = Side(args.a, kind, args)
            sides["b"] = Side(args.b, kind, args)
            for p in range(args.pairs):
                # Alternate which build goes first, so neither always meets a warmer machine.
                for side in ("a", "b") if p % 2 == 0 else ("b", "a"):
                    per[kind][side].append(sides[side].burst(args.seconds))
                if (p + 1) % 50 == 0 or p + 1 == args.pairs:
                    r = per[kind]
                    now = statistics.median(b / a for a, b in zip(r["a"], r["b"]))
                    print(f"{kind}: {p + 1} pairs, B/A median {now:.4f}", flush=True)
        finally:
            for side in sides.values():
                side.close()
    rows = []
    for kind, r in per.items():
        ratios = [b / a for a, b in zip(r["a"], r["b"])]
        rows.append(
            {
                "kind": kind,
                "a_median": statistics.median(r["a"]),
                "b_median": statistics.median(r["b"]),
                "ratio_median": statistics.median(ratios),
                "ratio_interval": median_interval(ratios),
                "ratio_min": min(ratios),
                "ratio_max": max(ratios),
                "a": r["a"],
                "b": r["b"],
            }
        )
    lines = [
        f"{args.pairs} pairs, {args.num_envs} envs, {args.num_workers} worker(s), "
        f"bursts of {args.seconds:g} s, both builds alive, alternating; "
        f"A = {args.a}, B = {args.b}",
        "",
        "| kind | A median steps/s | B median steps/s | B/A median | 95% interval | min-max |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lo, hi = r["ratio_interval"]
        lines.append(
            f"| {r['kind']} | {r['a_median']:,.0f} | {r['b_median']:,.0f} | "
            f"{r['ratio_median']:.4f} | {lo:.4f}-{hi:.4f} | "
            f"{r['ratio_min']:.2f}-{r['ratio_max']:.2f} |"
        )
    print("\n".join(lines))
    meta = {
        "machine": platform.node(),
        "cpus": os.cpu_count(),
        "args": {k: str(v) for k, v in vars(args).items()},
    }
    write_results(args.out, "builds_ab", "\n".join(lines), {"meta": meta, "rows": rows})


if __name__ == "__main__":
    main()
