"""Many pools on one machine: 1, 2, 4 and 8 pools started together, each in a process of its
own (as RLlib's EnvRunners, a sweep's trainings or a training and an evaluation pool run), and
their aggregate steps/s against one pool alone; for each build given (``--builds``: before and
after a change), interleaved: every repetition runs every (kind, count, build) once, in a
shuffled order, so that each ratio compares runs minutes apart at most.

    .venv/bin/python benchmarks/many_pools.py --builds before=/tmp/old/python after=python
    .venv/bin/python benchmarks/many_pools.py --quota       # one pool under a 1-CPU quota

Kinds: the native game (64 envs, 2 workers) and hosted CartPole (16 envs, 2 workers). Each
pool process builds, resets and warms up its pool, then all start stepping together (a
barrier) for ``--seconds``; the aggregate is the sum of their steps/s.

``--quota`` runs one pool in a cgroup whose CPU quota is one CPU (cgroup v1 ``cpu.cfs_quota_us``
or v2 ``cpu.max``; where no cgroup is writable, pinned to one core with ``taskset``): the
defaults (``num_workers`` unset) against ``num_workers=1`` set by hand, alternating.

Writes ``results/many_pools/many_pools.{md,json}`` (or ``quota.{md,json}``; ``--out``).
"""

from __future__ import annotations

import argparse
import os
import random
import select
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Optional

from common import write_results

ROOT = Path(__file__).resolve().parent.parent
RESULTS = Path(__file__).resolve().parent / "results" / "many_pools"
KINDS = {"native": (64, 2), "cartpole": (16, 2)}
#: The two layouts of the quota run.
LABELS = ("defaults", "num_workers=1")


def run_pool(kind: str, seconds: float, num_workers: Optional[int]) -> None:
    """One pool's process: build, reset, warm up, say ``ready``; on ``go`` step for
    ``seconds`` and print ``steps/s num_workers``."""
    import numpy as np
    import rogue_gym

    n, workers = KINDS[kind]
    workers = num_workers if num_workers != 0 else None  # 0: the defaults
    if kind == "native":
        envs = rogue_gym.make_vec(n, config="paper", num_workers=workers, seed=0)
        actions = np.random.default_rng(0).integers(0, 11, size=(64, n))
    else:
        import gymnasium as gym

        envs = rogue_gym.PoolVectorEnv([lambda: gym.make("CartPole-v1")] * n, num_workers=workers)
        actions = np.random.default_rng(0).integers(0, 2, size=(64, n))
    envs.reset(seed=0)
    for i in range(50):
        envs.step(actions[i % 64])
    print("ready", flush=True)
    sys.stdin.readline()
    steps, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        for i in range(10):
            envs.step(actions[i])
        steps += 10 * n
    rate = steps / (time.perf_counter() - t0)
    print(f"{rate} {envs.num_workers}", flush=True)
    envs.close()


def start(kind: str, seconds: float, path: str, prefix: list[str], workers: int) -> Any:
    env = {**os.environ, "PYTHONPATH": path, "OPENBLAS_NUM_THREADS": "1"}
    cmd = [*prefix, sys.executable, __file__, "--run", kind, "--seconds", str(seconds)]
    cmd += ["--num-workers", str(workers)]
    return subprocess.Popen(cmd, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)


def together(
    kind: str, count: int, seconds: float, path: str, prefix: list[str] = (), workers: int = 2
) -> list[tuple[float, int]]:
    """``count`` pools started together; each one's ``(steps/s, num_workers)``."""
    procs = [start(kind, seconds, path, list(prefix), workers) for _ in range(count)]
    try:
        for p in procs:
            assert p.stdout is not None
            ready, _, _ = select.select([p.stdout], [], [], 300)
            line = p.stdout.readline() if ready else ""
            if line.strip() != "ready":
                raise RuntimeError(f"a pool did not start: {line!r}")
        for p in procs:  # the barrier: every pool is built before any steps
            assert p.stdin is not None
            p.stdin.write("go\n")
            p.stdin.flush()
        out = []
        for p in procs:
            assert p.stdout is not None
            rate, nw = p.stdout.readline().split()
            out.append((float(rate), int(nw)))
        return out
    finally:
        for p in procs:
            try:
                p.wait(timeout=60)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def many(args: argparse.Namespace) -> None:
    builds = dict(b.split("=", 1) for b in args.builds)
    builds = {
        k: str((ROOT / v).resolve()) if not os.path.isabs(v) else v for k, v in builds.items()
    }
    cells = [(k, c, b) for k in args.kinds for c in args.pools for b in builds]
    agg: dict[tuple[str, int, str], list[float]] = {c: [] for c in cells}
    rng = random.Random(0)
    for rep in range(args.reps):
        rng.shuffle(cells)
        for kind, count, build in cells:
            rates = together(kind, count, args.seconds, builds[build])
            agg[(kind, count, build)].append(sum(r for r, _ in rates))
            print(
                f"rep {rep + 1}: {kind} x {count} pools, {build}: {sum(r for r, _ in rates):,.0f} steps/s",
                flush=True,
            )
    lines = [
        f"{args.reps} repetitions, {args.seconds:g} s each, pools started together (a process each)",
        "",
        "| kind | pools | build | aggregate steps/s (median) | of one pool alone |",
        "|---|---:|---|---:|---:|",
    ]
    data = []
    for kind in args.kinds:
        for build in builds:
            alone = agg[(kind, 1, build)]
            for count in args.pools:
                runs = agg[(kind, count, build)]
                ratios = [a / b for a, b in zip(runs, alone)]
                med = statistics.median(runs)
                lines.append(
                    f"| {kind} | {count} | {build} | {med:,.0f} | {statistics.median(ratios):.2f}x "
                    f"({min(ratios):.2f}-{max(ratios):.2f}) |"
                )
                data.append(
                    {
                        "kind": kind,
                        "pools": count,
                        "build": build,
                        "aggregate": runs,
                        "ratios": ratios,
                    }
                )
    text = "\n".join(lines)
    print(text)
    write_results(
        args.out,
        "many_pools",
        text,
        {"cells": data, "builds": builds, "args": vars(args) | {"out": str(args.out)}},
    )


def cpu_quota_prefix() -> tuple[list[str], str, Optional[Path]]:
    """A command prefix that runs a process under a one-CPU quota, what it is, and the cgroup
    to remove afterwards."""
    name = f"rogue-gym-bench-{os.getpid()}"
    v1 = Path("/sys/fs/cgroup/cpu")
    v2 = Path("/sys/fs/cgroup")
    try:
        if (v1 / "cpu.cfs_period_us").exists():
            d = v1 / name
            d.mkdir()
            period = int((d / "cpu.cfs_period_us").read_text())
            (d / "cpu.cfs_quota_us").write_text(str(period))
            procs = d / "cgroup.procs"
            return (
                ["sh", "-c", f'echo $$ > {procs} && exec "$@"', "sh"],
                "cgroup v1 cpu.cfs_quota_us, 1 CPU",
                d,
            )
        if (v2 / "cgroup.controllers").exists() and "cpu" in (
            v2 / "cgroup.controllers"
        ).read_text():
            d = v2 / name
            d.mkdir()
            (d / "cpu.max").write_text("100000 100000")
            procs = d / "cgroup.procs"
            return (
                ["sh", "-c", f'echo $$ > {procs} && exec "$@"', "sh"],
                "cgroup v2 cpu.max, 1 CPU",
                d,
            )
    except OSError:
        pass
    if shutil.which("taskset"):
        return ["taskset", "-c", "0"], "taskset to one core (no writable cgroup)", None
    raise SystemExit("neither a writable cgroup nor taskset: no quota to run under")


def quota(args: argparse.Namespace) -> None:
    prefix, how, cgroup = cpu_quota_prefix()
    path = str(ROOT / "python")
    rows: dict[str, list[float]] = {f"{k} {lab}": [] for k in args.kinds for lab in LABELS}
    chosen: list[int] = []
    try:
        for rep in range(args.reps):
            for label in LABELS if rep % 2 == 0 else LABELS[::-1]:
                for kind in args.kinds:
                    workers = 0 if label == "defaults" else 1
                    ((rate, nw),) = together(kind, 1, args.seconds, path, prefix, workers)
                    rows[f"{kind} {label}"].append(rate)
                    if label == "defaults":
                        chosen.append(nw)
                    print(
                        f"rep {rep + 1}: {kind}, {label}: {rate:,.0f} steps/s ({nw} workers)",
                        flush=True,
                    )
    finally:
        if cgroup is not None:
            time.sleep(0.5)
            cgroup.rmdir()
    lines = [
        f"One pool under a CPU quota ({how}), {args.reps} repetitions, {args.seconds:g} s each, "
        "alternating",
        "",
        f"the defaults picked num_workers: {sorted(set(chosen))}",
        "",
        "| kind | defaults steps/s | num_workers=1 by hand | defaults / by hand (median, range) |",
        "|---|---:|---:|---:|",
    ]
    ratios = {}
    for kind in args.kinds:
        d, h = rows[f"{kind} defaults"], rows[f"{kind} num_workers=1"]
        r = ratios[kind] = [a / b for a, b in zip(d, h)]
        lines.append(
            f"| {kind} | {statistics.median(d):,.0f} | {statistics.median(h):,.0f} | "
            f"{statistics.median(r):.3f} ({min(r):.3f}-{max(r):.3f}) |"
        )
    text = "\n".join(lines)
    print(text)
    write_results(
        args.out, "quota", text, {"rows": rows, "chosen": chosen, "how": how, "ratios": ratios}
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--run", choices=list(KINDS), help=argparse.SUPPRESS)
    ap.add_argument("--num-workers", type=int, default=2, help=argparse.SUPPRESS)
    ap.add_argument("--builds", nargs="+", default=["after=python"], help="NAME=PYTHONPATH")
    ap.add_argument("--kinds", nargs="+", default=list(KINDS), choices=list(KINDS))
    ap.add_argument("--pools", type=int, nargs="+", default=[1, 2, 4, 8])
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--quota", action="store_true", help="one pool under a one-CPU quota")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()
    if args.run:
        run_pool(args.run, args.seconds, args.num_workers)
    elif args.quota:
        quota(args)
    else:
        if 1 not in args.pools:
            args.pools = [1, *args.pools]
        many(args)


if __name__ == "__main__":
    main()
