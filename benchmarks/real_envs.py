#!/usr/bin/env python3
"""Third-party gymnasium envs through the pool and the usual vector envs, side by side.

Envs (nobody here wrote them):

===============  ===========================================================================
``pong``         ``ALE/Pong-v5`` as registered (210x160x3 frames, frameskip 4)
``pong-pre``     the usual training set-up: ``ALE/Pong-v5`` with ``frameskip=1``,
                 ``AtariPreprocessing`` (84x84 gray, frame skip 4) and a 4-frame stack
``nethack``      NLE's ``NetHackScore-v0``
``halfcheetah``  MuJoCo ``HalfCheetah-v5`` (a continuous action, four per-step info numbers)
``minigrid``     ``MiniGrid-DoorKey-8x8-v0`` with ``ImgObsWrapper``
``crafter``      Crafter (``crafter.Env``) behind a small gymnasium adapter; its info holds
                 nested dicts and a 64x64 map (about 5 KB pickled)
``cartpole``     ``CartPole-v1`` (the cheap pure-Python anchor)
===============  ===========================================================================

Backends: ``pool`` (``rogue_gym.PoolVectorEnv``), ``gym-sync`` (``SyncVectorEnv``),
``gym-async`` (``AsyncVectorEnv(shared_memory=True)``, one process per env), ``sb3-subproc``
(``SubprocVecEnv``, forkserver, one process per env), ``envpool`` (EnvPool's C++ pool, Pong
and HalfCheetah only), ``ale-vector`` (ale-py's C++ ``AtariVectorEnv``, Pong only) and
``pool-vector`` (the pool hosting one ale-py ``AtariVectorEnv`` of one thread per worker
block, ``PoolVectorEnv.from_vector_env``, Pong only); named only, ``pool-copy`` (the pool
copying every batch of observations, as ``copy=True`` did before it lent its slots). EnvPool
and ale-py's vector env are asked for the same frames as the Python set-up (raw 210x160x3 for
``pong``; 84x84 gray, 4-stack for ``pong-pre``).

Protocol: every cell (env x backend x num_envs x repetition) runs in a fresh child process;
construction and the first reset are excluded; after a warm-up, ``step`` is called with
actions sampled in advance from the action space for a fixed wall-clock window. The order
of cells is shuffled per repetition and the median over repetitions is reported.
``OMP_NUM_THREADS=1``; the pool and the C++ pools use ``--workers`` workers or threads.

Set-up (once; installs the envs into ``.venv-bench``, not into the test set-up's ``.venv``)::

    bash benchmarks/setup-real-envs.sh

Usage::

    .venv-bench/bin/python benchmarks/real_envs.py                      # 64 envs, ~25 min
    .venv-bench/bin/python benchmarks/real_envs.py --num-envs 16 64 256  # the sweep
    .venv-bench/bin/python benchmarks/real_envs.py --envs pong --backends pool gym-sync
    .venv-bench/bin/python benchmarks/real_envs.py --from-json benchmarks/results/real_envs/real_envs.json
    .venv-bench/bin/python benchmarks/real_envs.py --profile halfcheetah --seconds 6  # py-spy
    .venv-bench/bin/python benchmarks/real_envs.py --scaling --num-envs 32  # 1 vs 2 processes
    .venv-bench/bin/python benchmarks/real_envs.py --parity 200   # same outputs as SyncVectorEnv?

Writes ``real_envs.md``, ``real_envs.json`` and ``real_envs.png`` under ``--out`` (default
``benchmarks/results/real_envs``). A backend that is not installed, or that does not offer an
env, is listed as skipped with the reason.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path
from typing import Any, Optional

os.environ.setdefault("OMP_NUM_THREADS", "1")

from common import env_fn, run_cells, write_results
from real_envs_backends import (
    ALE_BACKENDS,
    BACKENDS,
    ENVS,
    EXTRA_BACKENDS,
    PER_ENV_PROCESS,
    ale_vector,
    run_cell,
)

#: Where a sample's time goes, by its innermost Python frame (first match wins). The pool's
#: Rust code runs under the worker's module frame and under the caller's native calls.
PROFILE_GROUPS = [
    ("the pool's Rust loop (waiting, polling, transport)", ("rogue_gym/worker/__main__.py",)),
    ("waiting for the workers (native call)", ("native (rogue_gym/front/core.py",)),
    ("rogue_gym: infos", ("rogue_gym/protocol/infos.py",)),
    ("rogue_gym: observations, actions", ("rogue_gym/protocol/layout.py",)),
    ("rogue_gym: adapter and front end", ("rogue_gym/",)),
    ("the benchmark loop", ("benchmarks/",)),
]


def profile(env: str, workers: int, seconds: float, out: Path) -> None:
    """Sample the caller and worker 0 of a pool cell with py-spy and print where their time
    goes (idle time, blocked in the kernel, excluded); the raw samples go to ``out``."""
    import shutil
    import subprocess

    spy = shutil.which("py-spy") or str(Path(sys.executable).parent / "py-spy")
    if not Path(spy).exists():
        raise SystemExit("py-spy is not installed (bash benchmarks/setup-real-envs.sh installs it)")
    cell = {"env": env, "backend": "pool", "num_envs": 64, "workers": workers}
    cell |= {"seconds": seconds + 30, "warmup": 10}
    proc = subprocess.Popen([sys.executable, __file__, "--cell", json.dumps(cell)])
    try:
        deadline = time.monotonic() + 120
        workers_of: list[str] = []
        while not workers_of and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(1)
            ps = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True, text=True)
            workers_of = ps.stdout.split()
        if not workers_of:
            raise SystemExit(f"no worker of the {env} pool appeared")
        time.sleep(10)  # past construction and warm-up
        out.mkdir(parents=True, exist_ok=True)
        spies = [
            subprocess.Popen(
                [
                    *(spy, "record", "-p", pid, "-d", str(int(seconds)), "-r", "200"),
                    *("-f", "raw", "-o", str(out / f"{env}-{who}.txt")),
                ],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            for who, pid in (("caller", str(proc.pid)), ("worker", workers_of[0]))
        ]
        for p in spies:
            p.wait(timeout=seconds + 60)
    finally:
        proc.kill()
        proc.wait()
    for who in ("caller", "worker"):
        groups: dict[str, int] = {}
        total = 0
        for line in (out / f"{env}-{who}.txt").read_text().splitlines():
            stack, _, count = line.rpartition(" ")
            inner = stack.split(";")
            frame = inner[-1]
            n = int(count)
            total += n
            group = next((g for g, keys in PROFILE_GROUPS if any(k in frame for k in keys)), None)
            if group is None:
                in_ours = any("rogue_gym/" in f for f in inner[-3:])
                group = "rogue_gym: adapter and front end" if in_ours else "the env and the rest"
            groups[group] = groups.get(group, 0) + n
        print(f"\n{env}, {who} ({total} samples):")
        for g, n in sorted(groups.items(), key=lambda x: -x[1]):
            print(f"  {n / max(total, 1):6.1%}  {g}")


def _first_difference(a: Any, b: Any, where: str = "") -> Optional[str]:
    """Where two trees of arrays differ (keys, shapes, dtypes or values; NaN equals NaN), or
    ``None``."""
    import numpy as np

    if isinstance(a, dict) or isinstance(b, dict):
        if not (isinstance(a, dict) and isinstance(b, dict)) or sorted(a) != sorted(b):
            return f"{where}: keys {sorted(a) if isinstance(a, dict) else a!r} vs {sorted(b) if isinstance(b, dict) else b!r}"
        for k in a:
            d = _first_difference(a[k], b[k], f"{where}[{k!r}]")
            if d:
                return d
        return None
    if isinstance(a, tuple):
        for i, (x, y) in enumerate(zip(a, b)):
            d = _first_difference(x, y, f"{where}[{i}]")
            if d:
                return d
        return None
    x, y = np.asarray(a), np.asarray(b)
    if x.dtype == object or y.dtype == object:
        same = x.shape == y.shape and all(
            _first_difference(u, v) is None for u, v in zip(x.ravel(), y.ravel())
        )
        return None if same else f"{where}: object arrays differ"
    if x.shape != y.shape or x.dtype != y.dtype:
        return f"{where}: {x.dtype}{x.shape} vs {y.dtype}{y.shape}"
    if not np.array_equal(x, y, equal_nan=x.dtype.kind in "fc"):
        return f"{where}: values differ"
    return None


def _bare_loop(job: tuple[str, int, int, float]) -> float:
    """Steps/s of ``n`` envs stepped in a plain loop in this process (seeded envs, actions
    sampled in advance), for ``seconds``."""
    env, n, seed, seconds = job
    fn = env_fn(env)
    envs = [fn() for _ in range(n)]
    for i, e in enumerate(envs):
        e.reset(seed=seed + i)
    space = envs[0].action_space
    space.seed(seed)
    acts = [[space.sample() for _ in range(n)] for _ in range(32)]
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        for e, a in zip(envs, acts[(steps // n) % 32]):
            _, _, term, trunc, _ = e.step(a)
            if term or trunc:
                e.reset()
        steps += n
    rate = steps / (time.perf_counter() - start)
    for e in envs:
        e.close()
    return rate


def scaling(envs: list[str], n: int, seconds: float, reps: int, out: Path) -> None:
    """What two cores give without any vector env: ``n`` envs stepped in a plain loop by one
    process alone, then by two such processes at once (other seeds); the sum over the alone
    figure is the machine's ceiling for a pool of 2 workers over one process."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    rows = []
    for env in envs:
        for rep in range(reps):
            with ctx.Pool(1) as p:
                alone = p.map(_bare_loop, [(env, n, 0, seconds)])[0]
            with ctx.Pool(2) as p:
                two = p.map(_bare_loop, [(env, n, 0, seconds), (env, n, 1000, seconds)])
            rows.append({"env": env, "rep": rep, "alone": alone, "two": two})
            print(
                f"{env:12s} alone {alone:10,.0f}  two at once {two[0]:10,.0f} + {two[1]:10,.0f}"
                f"  = {sum(two) / alone:.2f}x",
                flush=True,
            )
    out.mkdir(parents=True, exist_ok=True)
    (out / "scaling.json").write_text(json.dumps({"num_envs": n, "runs": rows}, indent=1) + "\n")


def parity(env: str, steps: int, num_envs: int = 5, hosted_vector: bool = False) -> str:
    """Step the pool and SyncVectorEnv with the same seeds and actions (``hosted_vector``:
    the pool hosting ale-py's vector env per worker, against one such vector env of all the
    envs); the first difference of observations, rewards, flags or infos, or "equal"."""
    import gymnasium as gym
    import rogue_gym

    if hosted_vector:
        block = functools.partial(ale_vector, env, workers=1)
        ours = rogue_gym.PoolVectorEnv.from_vector_env(block, num_envs, num_workers=2)
        ref = ale_vector(env, num_envs, 2)
    else:
        fn = env_fn(env)
        ours = rogue_gym.PoolVectorEnv([fn] * num_envs, num_workers=2)
        ref = gym.vector.SyncVectorEnv([fn] * num_envs)

    def masked(out: Any) -> Any:
        # ale-py's infos have no `_key` masks (every env has every key); the pool's merge
        # adds them, all set.
        *rest, info = out
        assert all(m.all() for k, m in info.items() if k.startswith("_"))
        return (*rest, {k: v for k, v in info.items() if not k.startswith("_")})

    def theirs(out: Any) -> Any:
        # ale-py's rewards are int32; the pool's are float64, as gymnasium's vector envs give.
        if len(out) == 2:
            return out
        obs, rewards, *rest = out
        return (obs, rewards.astype("float64"), *rest)

    mine = masked if hosted_vector else (lambda out: out)
    ref_out = theirs if hosted_vector else (lambda out: out)
    try:
        d = _first_difference(mine(ours.reset(seed=0)), ref.reset(seed=0), "reset")
        if d:
            return d
        ref.action_space.seed(0)
        for t in range(steps):
            actions = ref.action_space.sample()
            d = _first_difference(mine(ours.step(actions)), ref_out(ref.step(actions)), f"step {t}")
            if d:
                return d
        return "equal"
    finally:
        ours.close()
        ref.close()


def cells(args: argparse.Namespace) -> list[dict[str, Any]]:
    out = []
    for env in args.envs:
        for n in args.num_envs:
            for backend in args.backends:
                if backend == "envpool" and env not in ("pong", "pong-pre", "halfcheetah"):
                    continue
                if backend in ALE_BACKENDS and env not in ("pong", "pong-pre"):
                    continue
                if backend in PER_ENV_PROCESS and n > args.max_processes:
                    continue
                workers = 1 if backend == "gym-sync" else args.workers
                out.append(
                    {
                        "env": env,
                        "backend": backend,
                        "num_envs": n,
                        "workers": workers,
                        "seconds": args.seconds,
                        "warmup": args.warmup,
                    }
                )
    return out


Key = tuple[str, str, int]


def key(c: dict[str, Any]) -> Key:
    return (c["env"], c["backend"], int(c["num_envs"]))


def main(argv: Optional[list[str]] = None) -> None:
    p = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    p.add_argument("--envs", nargs="+", default=ENVS, choices=ENVS)
    p.add_argument("--backends", nargs="+", default=BACKENDS, choices=BACKENDS + EXTRA_BACKENDS)
    p.add_argument("--num-envs", nargs="+", type=int, default=[64])
    p.add_argument("--workers", type=int, default=2, help="pool workers, C++ pool threads")
    p.add_argument("--reps", type=int, default=3)
    p.add_argument("--seconds", type=float, default=4.0)
    p.add_argument("--warmup", type=int, default=10)
    p.add_argument(
        "--max-processes",
        type=int,
        default=64,
        help="skip one-process-per-env backends above this many envs",
    )
    p.add_argument(
        "--timeout", type=float, default=240.0, help="seconds per cell, start-up included"
    )
    p.add_argument("--out", default=str(Path(__file__).parent / "results" / "real_envs"))
    p.add_argument(
        "--profile",
        choices=ENVS,
        help="instead of timing: sample the pool's caller and a worker on this env (py-spy)",
    )
    p.add_argument(
        "--parity",
        type=int,
        metavar="STEPS",
        help="instead of timing: compare the pool with SyncVectorEnv (5 envs) for STEPS steps",
    )
    p.add_argument(
        "--scaling",
        action="store_true",
        help="instead of timing backends: num-envs envs in a plain loop in one process, then in "
        "two processes at once (the machine's ceiling for 2 workers), for each of --envs",
    )
    p.add_argument("--cell", help=argparse.SUPPRESS)
    p.add_argument("--from-json", help="rewrite the table and plot from a results JSON")
    args = p.parse_args(argv)
    if args.cell:
        print(json.dumps(run_cell(json.loads(args.cell))))
        return
    if args.parity:
        for env in args.envs:
            print(f"{env:12s} {parity(env, args.parity)}", flush=True)
            if env in ("pong", "pong-pre") and "pool-vector" in args.backends:
                found = parity(env, args.parity, hosted_vector=True)
                print(f"{env:12s} pool-vector against ale-py's vector env: {found}", flush=True)
        return
    if args.scaling:
        scaling(args.envs, args.num_envs[0], args.seconds, args.reps, Path(args.out))
        return
    if args.profile:
        profile(args.profile, args.workers, args.seconds, Path(args.out) / "profiles")
        return
    if args.from_json:
        raw = json.loads(Path(args.from_json).read_text())
        for name in ("envs", "backends", "reps", "seconds", "warmup", "num_envs", "workers"):
            setattr(args, name, raw["args"][name])
        runs = {tuple(r["cell"]): r["runs"] for r in raw["runs"]}
        failed = {tuple(r["cell"]): r["reason"] for r in raw["failed"]}
        write(args, runs, failed)
        return

    runs, failed = run_cells(__file__, cells(args), key, args.reps, args.timeout, dict(os.environ))
    write(args, runs, failed)


def _median(rs: list[dict[str, Any]], field: str = "steps_per_s") -> float:
    return statistics.median(r[field] for r in rs)


def write(args: argparse.Namespace, runs: dict[Key, list[dict[str, Any]]], failed: dict) -> None:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    med = {k: _median(v) for k, v in runs.items()}
    lines = [
        "# Third-party envs: steps/s by backend",
        "",
        f"Machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}. "
        f"Median of {args.reps} runs of {args.seconds:.0f} s each; random actions sampled in "
        f"advance; one fresh process per run. The pool and the C++ pools: {args.workers} "
        "workers or threads; SyncVectorEnv steps in the caller; AsyncVectorEnv and "
        "SubprocVecEnv start one process per env.",
        "",
        "| env | num_envs | backend | steps/s (median) | min-max | caller CPU | pool / this |",
        "|---|---:|---|---:|---:|---:|---:|",
    ]
    for k in sorted(set(runs) | set(failed)):
        env, backend, n = k
        if k in failed:
            lines.append(f"| {env} | {n} | {backend} | skipped: {failed[k]} | | | |")
            continue
        v = [r["steps_per_s"] for r in runs[k]]
        pool = med.get((env, "pool", n))
        ratio = f"{pool / med[k]:.2f}x" if pool and backend != "pool" else ""
        cpu = _median(runs[k], "caller_cpu")
        lines.append(
            f"| {env} | {n} | {backend} | {med[k]:,.0f} | {min(v):,.0f}-{max(v):,.0f} | {cpu:.0%} | {ratio} |"
        )
    for ours in ("pool", "pool-vector"):
        others = [b for b in BACKENDS + EXTRA_BACKENDS if b != ours and any(k[1] == b for k in med)]
        rows = [
            (env, n, med[(env, ours, n)])
            for n in args.num_envs
            for env in ENVS
            if (env, ours, n) in med
        ]
        if not rows:
            continue
        lines += ["", f"## {ours} against each backend (ratio of medians)", ""]
        lines += ["| env | num_envs | " + " | ".join(others) + " |"]
        lines.append("|---|---:|" + "---:|" * len(others))
        for env, n, mine in rows:
            cols = [f"{mine / med[(env, b, n)]:.2f}x" if (env, b, n) in med else "" for b in others]
            lines.append(f"| {env} | {n} | " + " | ".join(cols) + " |")
    lines.append("")
    raw = {
        "args": {k: v for k, v in vars(args).items() if k not in ("cell", "from_json")},
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
        "runs": [{"cell": list(k), "runs": v} for k, v in runs.items()],
        "failed": [{"cell": list(k), "reason": r} for k, r in failed.items()],
    }
    write_results(out, "real_envs", "\n".join(lines), raw)
    plot(med, out / "real_envs.png")
    print("\n".join(lines))


COLORS = {
    "pool": "tab:red",
    "gym-sync": "tab:blue",
    "gym-async": "tab:green",
    "sb3-subproc": "tab:purple",
    "envpool": "tab:orange",
    "ale-vector": "tab:brown",
    "pool-vector": "tab:pink",
    "pool-copy": "tab:gray",
}


def plot(med: dict[Key, float], path: Path) -> None:
    """Steps/s per backend, one panel per env (bars for one ``num_envs``, lines for a sweep);
    skipped without matplotlib."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no plot")
        return
    envs = [e for e in ENVS if any(k[0] == e for k in med)]
    if not envs:
        return
    sizes = sorted({k[2] for k in med})
    cols = min(4, len(envs))
    rows = -(-len(envs) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.4 * rows), squeeze=False)
    for ax, env in zip(axes.flat, envs):
        for backend in BACKENDS + EXTRA_BACKENDS:
            pts = [(n, med[(env, backend, n)]) for n in sizes if (env, backend, n) in med]
            if not pts:
                continue
            if len(sizes) > 1:
                ax.plot(
                    *zip(*pts),
                    marker="o",
                    color=COLORS[backend],
                    label=backend,
                    linewidth=2.5 if backend == "pool" else 1.2,
                )
            else:
                ax.bar(backend, pts[0][1], color=COLORS[backend])
        if len(sizes) > 1:
            ax.set_xscale("log", base=2)
            ax.set_yscale("log")
            ax.set_xlabel("num_envs")
            ax.legend(fontsize=7)
        else:  # bars from zero, so that their heights compare
            ax.tick_params(axis="x", labelsize=7, rotation=30)
        ax.set_ylabel("steps/s (median)")
        ax.set_title(env)
    for ax in list(axes.flat)[len(envs) :]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
