"""Multicore scaling: the pool's sync ``step()`` throughput from 1 to N workers, each worker with
the same envs (weak scaling), as efficiency against linear (``rate(k) / (k * rate(1))``), and
the model behind it (``--model``).

The model: with k workers stepping in parallel, each taking ``t_w`` per call, a sync step takes
``t_w + o(k·n)``, where ``o(N)`` is the caller's own time for a batch of N envs (the wall time
of a call minus the worker's env time, measured with one worker so that the two never
overlap); efficiency against linear is then ``t_w / (t_w + o(k·n))``. ``--model`` measures
``o`` and ``t_w`` for each batch size on this machine and prints the projected efficiency at
2 to 16 workers.

Envs: the native game (``--rogue-envs`` a worker, 256 by default, as the design's target
says), gymnasium's CartPole-v1 and HalfCheetah-v5 (``--hosted-envs`` a worker; HalfCheetah
needs mujoco, and is left out without it). Random actions, precomputed; each cell runs
``--seconds`` after a warm-up, ``--reps`` times, cells interleaved.

    python benchmarks/scaling.py --workers 1 2 4 8 16
    python benchmarks/scaling.py --model               # the caller's own time, projected
    python benchmarks/scaling.py --quick               # a smoke run (CI)

Writes ``scaling.json`` and ``scaling.md`` (``model.json`` and ``model.md`` for ``--model``)
under ``--out`` (default ``benchmarks/results/scaling``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path
from typing import Any, Optional

import gymnasium as gym
import numpy as np
import rogue_gym

from common import timed_steps, write_results


def make(env: str, num_envs: int, workers: int, **options: Any) -> Any:
    if env == "rogue":
        return rogue_gym.make_vec("RogueGym-v0", num_envs=num_envs, num_workers=workers, **options)
    return rogue_gym.PoolVectorEnv(
        [lambda: gym.make(env)] * num_envs, num_workers=workers, **options
    )


def rate(env: str, per_worker: int, workers: int, seconds: float) -> float:
    """Env steps/s of ``workers`` workers with ``per_worker`` envs each, sync ``step()``."""
    n = per_worker * workers
    vec = make(env, n, workers)
    try:
        vec.reset(seed=0)
        rng = np.random.default_rng(0)
        acts = [np.stack([vec.single_action_space.sample() for _ in range(n)]) for _ in range(8)]
        if env == "rogue":
            acts = [rng.integers(0, vec.single_action_space.n, n) for _ in range(8)]
        for a in acts:  # warm-up
            vec.step(a)
        steps, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            vec.step(acts[steps % 8])
            steps += 1
        return steps * n / (time.perf_counter() - t0)
    finally:
        vec.close()


def split(
    env: str, num_envs: int, seconds: float, pause: float = 0.0
) -> tuple[float, float, float, float]:
    """``(caller's own time, worker's env time, worker idle, caller between calls)`` per sync
    ``step()`` in seconds, for one worker with ``num_envs`` envs: the wall time per call minus
    the worker's env time (from ``stats()``), which it spends while the caller waits; of that
    own time, how long the worker waited for its next command (the caller's turnaround: its
    Python between calls, and its Rust before the command and after the answer) and how long
    the caller spent between pool calls. ``pause``: the caller spins that long before each
    call (see :func:`model`'s control), left out of all four figures; the worker then polls
    through it, as it stays busy through the same wait with a larger batch."""
    options = {"worker_poll_us": int(pause * 2e6) + 1000} if pause else {}
    vec = make(env, num_envs, 1, **options)
    try:
        vec.reset(seed=0)
        rng = np.random.default_rng(0)
        if env == "rogue":
            acts = [rng.integers(0, vec.single_action_space.n, num_envs) for _ in range(8)]
        else:
            acts = [np.stack([vec.single_action_space.sample() for _ in range(num_envs)])] * 8
        for a in acts * 4:  # warm-up
            vec.step(a)
        calls, wall, paused = timed_steps(vec, acts, seconds, pause)
        st = vec.stats()
        w = st.workers[0]
        return (
            (wall - w.env_s) / calls,
            w.env_s / calls,
            (w.wait_s - paused) / calls,
            (st.caller_s - paused) / calls,
        )
    finally:
        vec.close()


#: Batch sizes the model measures: a worker's envs at 1 worker, and the whole batch at 2 to 16
#: workers (native 256 a worker, hosted 8).
MODEL_BATCHES = {"rogue": (64, 256, 512, 1024, 2048, 4096), "CartPole-v1": (8, 16, 32, 64, 128)}
MODEL_PER_WORKER = {"rogue": 256, "CartPole-v1": 8}
#: The same, a sixteenth of the size and at 1, 4 and 16 workers only (``--quick``).
QUICK_BATCHES = {"rogue": (16, 64, 256), "CartPole-v1": (2, 8, 32)}
QUICK_PER_WORKER = {"rogue": 16, "CartPole-v1": 2}


def model(args: argparse.Namespace) -> None:
    """Measure the caller's own time and the worker's env time per call for each batch size
    (cells interleaved, medians of ``--reps``), and project the efficiency at k workers.

    The control: each batch size's worker time makes the caller wait that long, and a cache
    left alone that long goes cold on a shared host whatever the batch (another tenant's
    thread on the same core, the hypervisor). So for every batch but the smallest, the
    smallest batch is measured again with the caller spinning as long as that batch's worker
    step before each call: the same wait, without the envs. What the batch itself costs the
    caller is its own time beyond the control's."""
    batches, per_worker = (
        (QUICK_BATCHES, QUICK_PER_WORKER) if args.quick else (MODEL_BATCHES, MODEL_PER_WORKER)
    )
    envs = [e for e in batches if e in args.envs or e == "rogue"]
    Cell = tuple[float, float, float, float]
    cells: dict[tuple[str, int], list[Cell]] = {}
    controls: dict[tuple[str, int], list[Cell]] = {}
    for rep in range(args.reps):
        for e in envs:
            smallest = batches[e][0]
            for n in batches[e]:
                cell = split(e, n, args.seconds)
                cells.setdefault((e, n), []).append(cell)
                line = f"rep {rep + 1}: {e} x {n}: caller {cell[0] * 1e6:.1f} us"
                if n != smallest:
                    control = split(e, smallest, args.seconds, pause=cell[1])
                    controls.setdefault((e, n), []).append(control)
                    line += f" ({smallest} envs after the same wait: {control[0] * 1e6:.1f} us)"
                print(f"{line}, worker {cell[1] * 1e6:.1f} us")

    def medians(table: dict[tuple[str, int], list[Cell]]) -> dict[tuple[str, int], Cell]:
        return {
            key: (
                statistics.median(v[0] for v in vals),
                statistics.median(v[1] for v in vals),
                statistics.median(v[2] for v in vals),
                statistics.median(v[3] for v in vals),
            )
            for key, vals in table.items()
        }

    med, ctl = medians(cells), medians(controls)
    lines = [
        f"# The caller's own time per sync step() ({platform.node()}, "
        f"{len(os.sched_getaffinity(0))} cores, 1 worker, {args.seconds:g} s x {args.reps} runs, "
        "medians)",
        "",
        "Control: the smallest batch again, the caller spinning as long as this batch's worker "
        "step before each call (the same wait, without the envs).",
        "",
        "| env | envs | caller's own time (us) | ns per env-step | worker's env time (us) "
        "| of the own time: worker idle (us) | caller between calls (us) "
        "| control: own time (us) | control: between calls (us) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for (e, n), (o, t, idle, between) in sorted(med.items()):
        c = ctl.get((e, n))
        shown = ("-", "-") if c is None else (f"{c[0] * 1e6:.1f}", f"{c[3] * 1e6:.1f}")
        lines.append(
            f"| {e} | {n} | {o * 1e6:.1f} | {o * 1e9 / n:.1f} | {t * 1e6:.1f} "
            f"| {idle * 1e6:.1f} | {between * 1e6:.1f} | {shown[0]} | {shown[1]} |"
        )
    lines += [
        "",
        "Projected efficiency against linear, t_w / (t_w + o(k·n)). With k workers the caller "
        "waits about t_w, not the k·t_w of one worker stepping the whole batch; the last two "
        "columns take out what the longer wait alone costs (the control at k·n less the "
        "control at n, or the smallest batch's own time where n is the smallest):",
        "",
        "| env | envs a worker | workers | t_w (us) | o(k·n) (us) | projected "
        "| the longer wait's cost (us) | projected at a wait of t_w |",
        "|---|---|---|---|---|---|---|---|",
    ]
    projected, at_t_w = {}, {}
    for e in envs:
        per = per_worker[e]
        t_w = med[(e, per)][1]
        base = ctl[(e, per)][0] if (e, per) in ctl else med[(e, batches[e][0])][0]
        for k in (1, 2, 4, 8, 16):
            if (e, k * per) in med:
                o = med[(e, k * per)][0]
                eff = t_w / (t_w + o)
                projected[f"{e}/{k}"] = eff
                cost = (
                    max(ctl[(e, k * per)][0] - base, 0.0) if k > 1 and (e, k * per) in ctl else 0.0
                )
                fair = t_w / (t_w + max(o - cost, base))
                at_t_w[f"{e}/{k}"] = fair
                lines.append(
                    f"| {e} | {per} | {k} | {t_w * 1e6:.1f} | {o * 1e6:.1f} | {eff:.0%} "
                    f"| {cost * 1e6:.1f} | {fair:.0%} |"
                )
    text = "\n".join(lines)
    print(text)
    data = {
        "seconds": args.seconds,
        "reps": args.reps,
        "cells": {f"{e}/{n}": v for (e, n), v in cells.items()},
        "controls": {f"{e}/{n}": v for (e, n), v in controls.items()},
        "projected": projected,
        "projected_at_t_w": at_t_w,
    }
    write_results(Path(args.out), "model", text, data)


def available(env: str) -> bool:
    if env == "rogue":
        return True
    try:
        gym.make(env).close()
        return True
    except Exception as exc:  # e.g. mujoco missing
        print(f"{env} is left out: {exc}")
        return False


def main(argv: Optional[list[str]] = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--workers", type=int, nargs="+", default=[1, 2, 4, 8, 16])
    p.add_argument("--envs", nargs="+", default=["rogue", "CartPole-v1", "HalfCheetah-v5"])
    p.add_argument("--rogue-envs", type=int, default=256, help="native envs per worker")
    p.add_argument("--hosted-envs", type=int, default=8, help="hosted envs per worker")
    p.add_argument("--seconds", type=float, default=3.0)
    p.add_argument("--reps", type=int, default=1)
    p.add_argument("--quick", action="store_true", help="1 and 2 workers, 1 s, few envs (CI)")
    p.add_argument(
        "--model", action="store_true", help="the caller's own time and the projection instead"
    )
    p.add_argument("--out", default=str(Path(__file__).parent / "results" / "scaling"))
    args = p.parse_args(argv)
    if args.quick and args.model:
        args.seconds, args.reps = min(args.seconds, 0.3), 1
    elif args.quick:
        args.workers, args.seconds, args.reps = [1, 2], 1.0, 1
        args.rogue_envs, args.hosted_envs = 16, 2
        args.envs = [e for e in args.envs if e != "HalfCheetah-v5"]
    if args.model:
        model(args)
        return
    envs = [e for e in args.envs if available(e)]
    runs: dict[str, dict[int, list[float]]] = {e: {k: [] for k in args.workers} for e in envs}
    for rep in range(args.reps):
        for k in args.workers:
            for e in envs:
                per = args.rogue_envs if e == "rogue" else args.hosted_envs
                value = rate(e, per, k, args.seconds)
                runs[e][k].append(value)
                print(f"rep {rep + 1}: {e}, {k} workers x {per} envs: {value:,.0f} steps/s")
    write(args, runs)


def write(args: argparse.Namespace, runs: dict[str, dict[int, list[float]]]) -> None:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cores = len(os.sched_getaffinity(0))
    lines = [
        f"# Scaling of sync step() ({platform.node()}, {cores} cores, {args.seconds:g} s x "
        f"{args.reps} runs; envs per worker: native {args.rogue_envs}, hosted {args.hosted_envs})",
        "",
        "| env | workers | steps/s (median) | x 1 worker | efficiency vs linear |",
        "|---|---|---|---|---|",
    ]
    for e, table in runs.items():
        med = {k: statistics.median(v) for k, v in table.items() if v}
        base = med.get(min(med)) if med else None
        for k, v in sorted(med.items()):
            speedup = v / base if base else float("nan")
            lines.append(f"| {e} | {k} | {v:,.0f} | {speedup:.2f}x | {speedup / k:.0%} |")
    text = "\n".join(lines)
    print(text)
    (out / "scaling.md").write_text(text + "\n")
    (out / "scaling.json").write_text(
        json.dumps(
            {
                "cores": cores,
                "seconds": args.seconds,
                "reps": args.reps,
                "rogue_envs": args.rogue_envs,
                "hosted_envs": args.hosted_envs,
                "runs": {e: {str(k): v for k, v in t.items()} for e, t in runs.items()},
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    main()
