#!/usr/bin/env python3
"""Throughput of vector envs hosting Python gymnasium envs, side by side.

Envs:

============  ==============================================================================
``cartpole``  ``gymnasium.make("CartPole-v1")`` (a fast pure-Python env)
``rogue-py``  Rogue-Gym's single ``RogueEnv`` (paper config, ``symbol_index``) as a Python env
``slow``      an env that waits 1 ms per step (an env bound by I/O or a simulator)
``text``      a Dict observation of a Box and a Text leaf of no fixed size (MiniGrid's shape:
              a grid and a short mission string); not in the default set
============  ==============================================================================

Backends: ``pool`` (``rogue_gym.PoolVectorEnv``), ``gym-sync`` (``SyncVectorEnv``, one
process), ``gym-async-shm`` (``AsyncVectorEnv(shared_memory=True)``), ``gym-async``
(``AsyncVectorEnv(shared_memory=False)``, not in the default set), ``sb3-subproc``
(``SubprocVecEnv``, forkserver), ``puffer-mp`` (PufferLib 3 ``Multiprocessing``, synchronous,
batch = all envs; needs ``--puffer-path`` to a ``pip install --no-deps --target DIR
pufferlib-core psutil rich``), and for ``rogue-py`` also ``native-pool`` (the pool's own
Rust game, ``rogue_gym.make_vec``).

Protocol: every cell (env x backend x num_envs x workers x repetition) runs in a fresh child
process; start-up is excluded; after a warm-up, ``step`` is called with pre-generated random
actions for a fixed wall-clock window. The order of cells is shuffled per repetition and the
median over repetitions is reported. ``OMP_NUM_THREADS=1``.

Usage::

    python benchmarks/hosted_throughput.py                      # the headline set (~10 min)
    python benchmarks/vecenv_throughput.py hosted ...           # the same
    python benchmarks/hosted_throughput.py --num-envs 8 64 256  # a sweep
    python benchmarks/hosted_throughput.py --puffer-path /tmp/puffer
    python benchmarks/hosted_throughput.py --envs text --backends pool gym-async gym-async-shm \
        gym-sync --reps 5 --out benchmarks/results/text-leaf   # a leaf of no fixed size

Writes ``hosted_throughput.md`` and ``hosted_throughput.json`` under ``--out`` (default
``benchmarks/results``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path
from typing import Any, Callable, Optional

os.environ.setdefault("OMP_NUM_THREADS", "1")

from common import env_fn, run_cells, write_results

ENVS = ["cartpole", "rogue-py", "slow", "text"]
BACKENDS = ["pool", "gym-sync", "gym-async-shm", "sb3-subproc", "puffer-mp", "native-pool"]
#: Backends run only when named.
EXTRA_BACKENDS = ["gym-async"]
#: What runs when ``--envs``/``--backends`` are not given.
DEFAULT_ENVS = ["cartpole", "rogue-py", "slow"]


def num_actions(env: str) -> int:
    return {"cartpole": 2, "rogue-py": 11, "slow": 4, "text": 4}[env]


def build(backend: str, env: str, n: int, workers: int) -> tuple[Any, Callable[[Any], Any]]:
    """The vector env and its step function."""
    fn = env_fn(env)
    if backend == "pool":
        import rogue_gym

        v: Any = rogue_gym.PoolVectorEnv([fn] * n, num_workers=workers)
        v.reset(seed=0)
        return v, v.step
    if backend == "native-pool":
        import rogue_gym

        v = rogue_gym.make_vec(n, config="paper", num_workers=workers, obs="symbol_index", seed=0)
        v.reset(seed=0)
        return v, v.step
    if backend in ("gym-sync", "gym-async-shm", "gym-async"):
        import gymnasium as gym

        if backend == "gym-sync":
            v = gym.vector.SyncVectorEnv([fn] * n)
        else:
            shm = backend == "gym-async-shm"
            v = gym.vector.AsyncVectorEnv([fn] * n, shared_memory=shm)
        v.reset(seed=0)
        return v, v.step
    if backend == "sb3-subproc":
        import multiprocessing as mp

        from stable_baselines3.common.vec_env import SubprocVecEnv

        # Import the heavy modules once in the forkserver, not in each of the n processes
        # (start-up only, excluded from the timed window either way).
        mp.set_forkserver_preload(["stable_baselines3.common.vec_env.subproc_vec_env", "gymnasium"])
        v = SubprocVecEnv([fn] * n, start_method="forkserver")
        v.seed(0)
        v.reset()
        return v, v.step
    if backend == "puffer-mp":
        import pufferlib.emulation as emulation
        import pufferlib.vector as pvector

        def creator(*args: Any, **kwargs: Any) -> Any:
            return emulation.GymnasiumPufferEnv(env_creator=fn)

        v = pvector.make(
            creator, backend=pvector.Multiprocessing, num_envs=n, num_workers=workers, batch_size=n
        )
        v.reset(seed=0)
        return v, v.step
    raise ValueError(f"unknown backend {backend}")


def run_cell(cell: dict[str, Any]) -> dict[str, Any]:
    import numpy as np

    n, env = int(cell["num_envs"]), cell["env"]
    v, step = build(cell["backend"], env, n, int(cell["workers"]))
    rng = np.random.default_rng(12345)
    acts = [rng.integers(0, num_actions(env), size=n) for _ in range(64)]
    try:
        for i in range(int(cell["warmup"])):
            step(acts[i % 64])
        i, start = 0, time.perf_counter()
        deadline = start + float(cell["seconds"])
        while time.perf_counter() < deadline or i < 3:
            step(acts[i % 64])
            i += 1
        wall = time.perf_counter() - start
    finally:
        v.close()
    return {**cell, "steps_per_s": i * n / wall, "batches": i}


def cells(args: argparse.Namespace) -> list[dict[str, Any]]:
    out = []
    base = {"seconds": args.seconds, "warmup": args.warmup}
    for env in args.envs:
        for n in args.num_envs:
            for backend in args.backends:
                if backend == "native-pool" and env != "rogue-py":
                    continue
                if backend == "puffer-mp" and not args.puffer_path:
                    continue
                single = backend == "gym-sync"
                for workers in [1] if single else args.workers:
                    if workers > n or (backend == "puffer-mp" and n % workers):
                        continue
                    out.append(
                        {**base, "env": env, "backend": backend, "num_envs": n, "workers": workers}
                    )
        if env == "slow" and "pool" in args.backends:
            for workers in (2, 8):
                for n in args.num_envs:
                    extra = {
                        **base,
                        "env": env,
                        "backend": "pool",
                        "num_envs": n,
                        "workers": workers,
                    }
                    if extra not in out and workers <= n:
                        out.append(extra)
    return out


def key(c: dict[str, Any]) -> tuple[str, str, int, int]:
    return (c["env"], c["backend"], int(c["num_envs"]), int(c["workers"]))


def main(argv: Optional[list[str]] = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--envs", nargs="+", default=DEFAULT_ENVS, choices=ENVS)
    p.add_argument("--backends", nargs="+", default=BACKENDS, choices=BACKENDS + EXTRA_BACKENDS)
    p.add_argument("--num-envs", nargs="+", type=int, default=[64])
    p.add_argument("--workers", nargs="+", type=int, default=[2])
    p.add_argument("--reps", type=int, default=3)
    p.add_argument("--seconds", type=float, default=3.0)
    p.add_argument("--warmup", type=int, default=20)
    p.add_argument(
        "--timeout", type=float, default=180.0, help="seconds per cell, start-up included"
    )
    p.add_argument("--puffer-path", default="", help="a --target dir holding pufferlib-core")
    p.add_argument("--out", default=str(Path(__file__).parent / "results"))
    p.add_argument("--cell", help=argparse.SUPPRESS)
    p.add_argument("--from-json", help="rewrite the table and plot from a results JSON")
    args = p.parse_args(argv)
    if args.cell:
        print(json.dumps(run_cell(json.loads(args.cell))))
        return
    if args.from_json:
        raw = json.loads(Path(args.from_json).read_text())
        for name in ("reps", "seconds", "num_envs"):
            setattr(args, name, raw["args"][name])
        results = {tuple(r["cell"]): r["steps_per_s"] for r in raw["runs"]}
        failed = {tuple(r["cell"]): r["reason"] for r in raw["failed"]}
        write(args, results, failed)
        return

    todo = cells(args)
    env = dict(os.environ)
    if args.puffer_path:
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [args.puffer_path, env.get("PYTHONPATH")]))
    runs, failed = run_cells(__file__, todo, key, args.reps, args.timeout, env)
    results = {k: [r["steps_per_s"] for r in v] for k, v in runs.items()}
    write(args, results, failed)


def write(args: argparse.Namespace, results: dict, failed: dict) -> None:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    med = {k: statistics.median(v) for k, v in results.items()}
    lines = [
        "# Hosted gymnasium envs: steps/s by backend",
        "",
        f"Machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}. "
        f"Median of {args.reps} runs of {args.seconds:.0f} s each, random actions, one fresh process per run.",
        "",
        "Workers: the pool's and PufferLib's worker processes; SyncVectorEnv steps in the caller,",
        "AsyncVectorEnv and SubprocVecEnv start one process per env.",
        "",
        "| env | num_envs | backend | workers | steps/s (median) | min-max | vs gym-sync |",
        "|---|---|---|---|---|---|---|",
    ]
    for k in sorted(set(results) | set(failed)):
        env, backend, n, w = k
        sync = med.get((env, "gym-sync", n, 1))
        if k in failed:
            lines.append(f"| {env} | {n} | {backend} | {w} | skipped: {failed[k]} | | |")
            continue
        v = results[k]
        ratio = f"{med[k] / sync:.2f}x" if sync else ""
        procs = {"gym-sync": "in-process", "gym-async-shm": f"{n} (one per env)"}
        procs["sb3-subproc"] = procs["gym-async"] = procs["gym-async-shm"]
        lines.append(
            f"| {env} | {n} | {backend} | {procs.get(backend, w)} | {med[k]:,.0f} | {min(v):,.0f}-{max(v):,.0f} | {ratio} |"
        )
    lines += ["", "## Against the targets", ""]
    for n in args.num_envs:
        pool = med.get(("cartpole", "pool", n, 2))
        if pool:
            for other in ("gym-sync", "gym-async-shm", "sb3-subproc", "puffer-mp"):
                ref = med.get(("cartpole", other, n, 1 if other == "gym-sync" else 2))
                if ref:
                    lines.append(
                        f"- CartPole, {n} envs, 2 workers: pool / {other} = **{pool / ref:.2f}x**"
                    )
        two, eight = med.get(("slow", "pool", n, 2)), med.get(("slow", "pool", n, 8))
        if two and eight:
            lines.append(
                f"- slow env, {n} envs: 8 workers / 2 workers = **{eight / two:.2f}x** "
                f"({eight / two / 4:.0%} of the ideal 4x)"
            )
    raw = {
        "args": vars(args),
        "runs": [{"cell": list(k), "steps_per_s": v} for k, v in results.items()],
        "failed": [{"cell": list(k), "reason": r} for k, r in failed.items()],
    }
    write_results(out, "hosted_throughput", "\n".join(lines), raw)
    plot(med, out / "hosted_throughput.png")
    print("\n".join(lines))


#: One colour per (backend, workers) in every panel; ours in red.
PLOT_COLORS = {
    ("pool", 2): "tab:red",
    ("pool", 8): "darkred",
    ("native-pool", 2): "tab:orange",
    ("gym-sync", 1): "tab:blue",
    ("gym-async-shm", 2): "tab:green",
    ("sb3-subproc", 2): "tab:purple",
    ("puffer-mp", 2): "tab:gray",
}


def plot(med: dict[tuple[str, str, int, int], float], path: Path) -> None:
    """Steps/s per backend, one panel per env (log scale): bars for one ``num_envs``, lines
    against ``num_envs`` for a sweep; skipped without matplotlib."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no plot")
        return
    envs = sorted({k[0] for k in med})
    sweep = len({k[2] for k in med}) > 1
    fig, axes = plt.subplots(1, len(envs), figsize=(5 * len(envs), 4), squeeze=False)
    for ax, env in zip(axes[0], envs):
        cells = sorted((k, v) for k, v in med.items() if k[0] == env)
        if sweep:
            for backend, workers in sorted({(k[1], k[3]) for k, _ in cells}):
                pts = sorted((k[2], v) for k, v in cells if (k[1], k[3]) == (backend, workers))
                ours = backend in ("pool", "native-pool")
                procs = {"gym-sync": "", "gym-async-shm": " (1 proc/env)"}
                procs["sb3-subproc"] = procs["gym-async"] = procs["gym-async-shm"]
                ax.plot(
                    [n for n, _ in pts],
                    [v for _, v in pts],
                    marker="o",
                    color=PLOT_COLORS.get((backend, workers), "black"),
                    linewidth=2.5 if ours else 1.2,
                    label=backend + procs.get(backend, f" ({workers} workers)"),
                )
            ax.set_xscale("log", base=2)
            ax.set_xlabel("num_envs")
            ax.set_ylabel("env steps/s (median)")
            ax.legend(fontsize=7)
        else:
            labels = [
                f"{k[1]}\n{k[2]} envs, "
                + (f"{k[3]} workers" if k[1] in ("pool", "native-pool", "puffer-mp") else "")
                for k, _ in cells
            ]
            colors = [
                "tab:red" if k[1] in ("pool", "native-pool") else "tab:gray" for k, _ in cells
            ]
            ax.barh(labels, [v for _, v in cells], color=colors)
            ax.set_xlabel("env steps/s (median)")
            ax.tick_params(axis="y", labelsize=7)
        if sweep:
            ax.set_yscale("log")
        else:
            ax.set_xscale("log")
        ax.set_title(env)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
