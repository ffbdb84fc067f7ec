"""A sustained crash storm: how many calls succeed, and whether every call keeps its bound.

A thread SIGKILLs a random live worker every ``--interval`` seconds for ``--seconds`` while the
main thread steps the pool (16 envs, 4 workers, ``step_timeout=2`` by default) under
``on_worker_failure="restart"``. A step that raises (``WorkerCrashedError``: lost workers not
back within the call's bound) is followed by ``reset()``, as a training loop would. After the
storm one ``reset()`` must make the pool step again.

    .venv/bin/python benchmarks/storm.py                       # native and hosted CartPole
    .venv/bin/python benchmarks/storm.py --kinds native --seconds 30 --interval 0.2

Prints one row per kind and writes ``results/storm/storm.{md,json}`` (``--out`` to change).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import random
import signal
import threading
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import rogue_gym
from rogue_gym import PoolVectorEnv, WorkerCrashedError

RESULTS = Path(__file__).resolve().parent / "results" / "storm"


def cartpole() -> gym.Env:
    return gym.make("CartPole-v1")


def make(kind: str, args: argparse.Namespace) -> Any:
    opts: dict[str, Any] = {
        "num_workers": args.workers,
        "step_timeout": args.step_timeout,
        "start_timeout": args.start_timeout,
        "max_restarts": 1_000_000,
    }
    if kind == "native":
        return rogue_gym.make_vec(args.num_envs, config="paper", seed=0, **opts)
    return PoolVectorEnv([cartpole] * args.num_envs, **opts)


class Killer(threading.Thread):
    """SIGKILLs a random live worker every ``interval`` seconds until stopped."""

    def __init__(self, envs: Any, interval: float, seed: int) -> None:
        super().__init__(daemon=True)
        self.envs, self.interval, self.rng = envs, interval, random.Random(seed)
        self.stop = threading.Event()
        self.kills = 0

    def run(self) -> None:
        while not self.stop.wait(self.interval):
            live = [p for p in self.envs.worker_pids if p and os.path.exists(f"/proc/{p}")]
            if not live:
                continue
            try:
                os.kill(self.rng.choice(live), signal.SIGKILL)
                self.kills += 1
            except ProcessLookupError:
                pass


def run_kind(kind: str, args: argparse.Namespace) -> dict[str, Any]:
    envs = make(kind, args)
    bound = args.step_timeout + args.start_timeout
    try:
        envs.reset(seed=0)
        killer = Killer(envs, args.interval, seed=args.seed)
        calls = ok = raised = flagged = 0
        longest = 0.0
        killer.start()
        t0 = time.monotonic()
        need_reset = False
        while time.monotonic() - t0 < args.seconds:
            start = time.monotonic()
            try:
                if need_reset:
                    envs.reset()
                    need_reset = False
                else:
                    *_, infos = envs.step(envs.action_space.sample())
                    flagged += int(np.sum(infos.get("worker_restarted", False)))
                ok += 1
            except WorkerCrashedError:
                raised += 1
                need_reset = True
            calls += 1
            longest = max(longest, time.monotonic() - start)
        killer.stop.set()
        killer.join()
        # After the storm: one reset, then plain steps.
        start = time.monotonic()
        envs.reset()
        after_reset_s = time.monotonic() - start
        for _ in range(50):
            envs.step(envs.action_space.sample())
        return {
            "kind": kind,
            "calls": calls,
            "succeeded": ok,
            "raised": raised,
            "success_rate": ok / max(calls, 1),
            "longest_call_s": longest,
            "bound_s": bound,
            "kills": killer.kills,
            "restarts": envs.restarts,
            "flagged_envs": flagged,
            "reset_after_storm_s": after_reset_s,
            "recovered": True,
        }
    finally:
        envs.close()


def table(rows: list[dict[str, Any]]) -> str:
    head = (
        "| kind | calls | succeeded | raised | longest call (s) | bound (s) | kills | restarts "
        "| flagged envs | reset after (s) |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    )
    lines = [
        f"| {r['kind']} | {r['calls']} | {r['succeeded']} ({100 * r['success_rate']:.1f} %) "
        f"| {r['raised']} | {r['longest_call_s']:.2f} | {r['bound_s']:.1f} | {r['kills']} "
        f"| {r['restarts']} | {r['flagged_envs']} | {r['reset_after_storm_s']:.2f} |"
        for r in rows
    ]
    return "\n".join([head, *lines])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument(
        "--kinds", nargs="+", default=["native", "hosted"], choices=["native", "hosted"]
    )
    ap.add_argument("--seconds", type=float, default=15.0, help="length of the storm")
    ap.add_argument("--interval", type=float, default=0.5, help="seconds between kills")
    ap.add_argument("--num-envs", type=int, default=16)
    ap.add_argument("--workers", type=int, default=4)
    ap.add_argument("--step-timeout", type=float, default=2.0)
    ap.add_argument(
        "--start-timeout", type=float, default=rogue_gym.settings.PoolSettings.start_timeout
    )
    ap.add_argument("--seed", type=int, default=0, help="seed of the killer's choices")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()
    print(
        f"storm: a SIGKILL every {args.interval} s for {args.seconds} s, {args.num_envs} envs, "
        f"{args.workers} workers, kinds {' '.join(args.kinds)} "
        f"(about {len(args.kinds) * (args.seconds + 3):.0f} s)",
        flush=True,
    )
    rows = []
    for kind in args.kinds:
        rows.append(run_kind(kind, args))
        print(f"  {kind}: {rows[-1]['succeeded']}/{rows[-1]['calls']} calls", flush=True)
    md = table(rows)
    print(md)
    args.out.mkdir(parents=True, exist_ok=True)
    meta = {
        "command": "benchmarks/storm.py " + " ".join(os.sys.argv[1:]),
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, {platform.platform()}",
        "when": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "settings": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
    }
    (args.out / "storm.json").write_text(json.dumps({**meta, "rows": rows}, indent=1) + "\n")
    (args.out / "storm.md").write_text(
        f"# Crash storm\n\n`{meta['command']}` on {meta['machine']}, {meta['when']}.\n\n{md}\n"
    )
    print(f"wrote {args.out}/storm.md and storm.json")


if __name__ == "__main__":
    main()
