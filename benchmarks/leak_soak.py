"""A long run of envs that leak, with the pool's planned worker replacement (recycling) on, and a
short one with it off for contrast.

Each env keeps 1 MiB more at every step (``--leak-mib``). With ``recycle_above_rss`` each
worker is replaced before its resident memory passes the bound; the run records, second by
second, every worker's and the pool's total resident memory, the replacements, failed calls and
steps/s, and prints one row per ``--row-s`` seconds.

    python benchmarks/leak_soak.py --minutes 10 --bound-mib 256

Writes ``leak_soak.json`` and ``leak_soak.md`` under ``--out``
(default ``benchmarks/results/leak_soak``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path
from typing import Any, Optional

import gymnasium as gym
import numpy as np
import rogue_gym


class Leaky(gym.Env):
    """Keeps ``leak_mib`` MiB more at every step."""

    observation_space = gym.spaces.Box(0.0, 1e9, (4,), np.float32)
    action_space = gym.spaces.Discrete(2)

    def __init__(self, leak_mib: float) -> None:
        self.leak = int(leak_mib * (1 << 20))
        self.hoard: list[np.ndarray] = []

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> Any:
        super().reset(seed=seed)
        return np.zeros(4, np.float32), {}

    def step(self, action: Any) -> Any:
        self.hoard.append(np.ones(self.leak, np.uint8))
        return np.zeros(4, np.float32), 1.0, False, False, {}


def rss(pid: int) -> int:
    try:
        with open(f"/proc/{pid}/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except OSError:
        return 0


def run(args: argparse.Namespace, seconds: float, bound: Optional[int]) -> dict[str, Any]:
    envs = rogue_gym.PoolVectorEnv(
        [lambda: Leaky(args.leak_mib)] * args.num_envs,
        num_workers=args.num_workers,
        recycle_above_rss=bound,
    )
    samples: list[dict[str, Any]] = []
    failed = steps = 0
    try:
        envs.reset(seed=0)
        t0 = last = time.monotonic()
        peak_worker = peak_total = 0
        while (now := time.monotonic()) - t0 < seconds:
            try:
                envs.step(np.zeros(args.num_envs, np.int64))
                steps += args.num_envs
            except Exception as exc:  # every failure is recorded, none stops the run
                failed += 1
                print(f"call failed: {type(exc).__name__}: {exc}", flush=True)
                envs.reset()
            sizes = [rss(p) for p in envs.worker_pids]
            peak_worker, peak_total = max(peak_worker, *sizes), max(peak_total, sum(sizes))
            if now - last >= 1.0 or now - t0 >= seconds:
                stats = envs.stats()
                samples.append(
                    {
                        "t": round(now - t0, 2),
                        "steps": steps,
                        "peak_worker_mib": peak_worker / 2**20,
                        "peak_total_mib": peak_total / 2**20,
                        "recycles": stats.recycles,
                        "restarts": stats.restarts,
                        "failed_calls": failed,
                    }
                )
                last, peak_worker, peak_total = now, 0, 0
                if bound is None and sum(sizes) > args.stop_without_mib << 20:
                    break  # without recycling: stop before the machine runs out
    finally:
        envs.close()
    return {"bound_mib": None if bound is None else bound / 2**20, "samples": samples}


def rows(result: dict[str, Any], every: float) -> list[str]:
    out, start, steps0 = [], 0.0, 0
    samples = result["samples"]
    for i, s in enumerate(samples):
        if s["t"] - start < every and i != len(samples) - 1:
            continue
        window = [x for x in samples if start < x["t"] <= s["t"]] or [s]
        rate = (s["steps"] - steps0) / max(s["t"] - start, 1e-9)
        out.append(
            f"| {start:.0f}-{s['t']:.0f} | {rate:,.0f} | "
            f"{max(x['peak_worker_mib'] for x in window):.0f} | "
            f"{max(x['peak_total_mib'] for x in window):.0f} | {s['recycles']} | "
            f"{s['restarts']} | {s['failed_calls']} |"
        )
        start, steps0 = s["t"], s["steps"]
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--minutes", type=float, default=10.0)
    p.add_argument("--num-envs", type=int, default=16)
    p.add_argument("--num-workers", type=int, default=4)
    p.add_argument("--leak-mib", type=float, default=1.0)
    p.add_argument("--bound-mib", type=int, default=256)
    p.add_argument("--row-s", type=float, default=60.0, help="seconds per table row")
    p.add_argument("--without-s", type=float, default=15.0, help="the run without recycling")
    p.add_argument("--stop-without-mib", type=int, default=4096)
    p.add_argument("--out", type=Path, default=Path(__file__).parent / "results" / "leak_soak")
    args = p.parse_args()
    header = [
        "| seconds | steps/s | peak worker RSS (MiB) | peak total RSS (MiB) | recycles | restarts | failed calls |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    with_bound = run(args, args.minutes * 60, args.bound_mib << 20)
    print(f"with recycle_above_rss = {args.bound_mib} MiB:")
    table = rows(with_bound, args.row_s)
    print("\n".join(header + table))
    without = run(args, args.without_s, None)
    table_without = rows(without, 5.0)
    print("without recycling:")
    print("\n".join(header + table_without))
    args.out.mkdir(parents=True, exist_ok=True)
    meta = {
        "command": "python benchmarks/leak_soak.py "
        + " ".join(f"--{k.replace('_', '-')} {v}" for k, v in vars(args).items() if k != "out"),
        "machine": f"{platform.node()} {os.cpu_count()} CPUs",
        "num_envs": args.num_envs,
        "num_workers": args.num_workers,
        "leak_mib_per_step": args.leak_mib,
    }
    doc = {**meta, "with_recycling": with_bound, "without_recycling": without}
    (args.out / "leak_soak.json").write_text(json.dumps(doc, indent=1))
    md = [
        "# Envs that leak, with and without planned worker replacement",
        "",
        f"`{meta['command']}` on {meta['machine']}: {args.num_envs} envs, {args.num_workers} "
        f"workers, each env keeping {args.leak_mib} MiB more at every step.",
        "",
        f"With `recycle_above_rss = {args.bound_mib} MiB` (each window's peaks):",
        "",
        *header,
        *table,
        "",
        "Without recycling (stopped at "
        f"{args.stop_without_mib} MiB in all, or after {args.without_s:g} s):",
        "",
        *header,
        *table_without,
        "",
    ]
    (args.out / "leak_soak.md").write_text("\n".join(md))
    print(f"wrote {args.out}/leak_soak.md and .json")


if __name__ == "__main__":
    main()
