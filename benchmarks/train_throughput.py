#!/usr/bin/env python3
"""Training throughput: our PPO trainer against SB3 PPO, same network, same hyperparameters.

Cells (each in a fresh child process, run one after another on this machine):

=====================  ===================================================================
``ours``               ``python -m rogue_gym.train`` (symbol indices on the wire, two halves)
``sb3-subproc``        SB3 ``PPO`` on ``SubprocVecEnv`` over ``RogueEnv`` (one-hot float32)
``sb3-pool``           SB3 ``PPO`` on ``rogue_gym.sb3.RogueVecEnv`` (one-hot float32)
``sb3-subproc-kept``   ``sb3-subproc`` with our trainer's allocator setting
                       (:func:`rogue_gym.train.allocator.keep_freed_memory`) in SB3's process:
                       how much of the gap is that setting, which SB3 users could also make
=====================  ===================================================================

All use the paper's PPO Small network (convs 8/4/3 with 32/64/32 channels, FC 256) and its
hyperparameters: 32 envs x 125 steps, 10 epochs, minibatch 200, clip 0.1, value clip, lr
2.5e-4, Adam eps 1e-4. Each cell trains ``--updates`` updates; frames/s is measured over the
updates after the first (warm-up), as ``4000 / (collection + update seconds)``. For ``ours``
the split into env, inference and update time comes from ``progress.csv``.

Usage::

    python benchmarks/train_throughput.py [--updates 3] [--reps 1] [--out benchmarks/results/train]

Writes ``train_throughput.md`` and ``train_throughput.json`` under ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

CELLS = ("ours", "sb3-subproc", "sb3-pool", "sb3-subproc-kept")
NUM_ENVS, NUM_STEPS = 32, 125


def _sb3_model(env: Any) -> Any:
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
    from torch import nn

    class SmallCnn(BaseFeaturesExtractor):  # the paper's PPO Small body
        def __init__(self, space: Any) -> None:
            super().__init__(space, 256)
            c, h, w = space.shape
            self.net = nn.Sequential(
                nn.Conv2d(c, 32, 8),
                nn.ReLU(),
                nn.Conv2d(32, 64, 4),
                nn.ReLU(),
                nn.Conv2d(64, 32, 3),
                nn.ReLU(),
                nn.Flatten(),
                nn.Linear(32 * (h - 12) * (w - 12), 256),
                nn.ReLU(),
            )

        def forward(self, x: torch.Tensor) -> torch.Tensor:
            return self.net(x)

    return PPO(
        "MlpPolicy",
        env,
        n_steps=NUM_STEPS,
        batch_size=200,
        n_epochs=10,
        learning_rate=2.5e-4,
        gamma=0.99,
        gae_lambda=0.95,
        clip_range=0.1,
        clip_range_vf=0.1,
        ent_coef=0.01,
        vf_coef=0.5,
        max_grad_norm=0.5,
        policy_kwargs={
            "features_extractor_class": SmallCnn,
            "net_arch": [],
            "optimizer_kwargs": {"eps": 1e-4},
        },
        seed=0,
        device="cpu",
        verbose=0,
    )


def _sb3_cell(cell: str, updates: int) -> Dict[str, Any]:
    from stable_baselines3.common.callbacks import BaseCallback

    if cell == "sb3-subproc-kept":
        from rogue_gym.train.allocator import keep_freed_memory

        keep_freed_memory()
    if cell.startswith("sb3-subproc"):
        from rogue_gym.envs import RogueEnv
        from rogue_gym.suites import PAPER_CONFIG
        from stable_baselines3.common.vec_env import SubprocVecEnv

        def make() -> Any:
            return RogueEnv(
                config_dict=PAPER_CONFIG, max_steps=500, obs="symbol_onehot", dtype="float32"
            )

        env: Any = SubprocVecEnv([make] * NUM_ENVS, start_method="forkserver")
    else:
        from rogue_gym.sb3 import RogueVecEnv

        env = RogueVecEnv(
            NUM_ENVS, "paper", num_workers=2, obs="symbol_onehot", dtype="float32", seed=0
        )

    class Stamps(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.starts: List[float] = []

        def _on_rollout_start(self) -> None:
            self.starts.append(time.perf_counter())

        def _on_step(self) -> bool:
            return True

    stamps = Stamps()
    model = _sb3_model(env)
    model.learn(NUM_ENVS * NUM_STEPS * updates + 1, callback=stamps)
    end = time.perf_counter()
    env.close()
    marks = [*stamps.starts, end]
    per_update = [b - a for a, b in zip(marks[1:], marks[2:])]  # skip the warm-up update
    return {"update_seconds": per_update}


def _ours_cell(updates: int) -> Dict[str, Any]:
    from rogue_gym.train import TrainConfig, train
    from rogue_gym.train.progress import read_progress

    with tempfile.TemporaryDirectory(prefix="rg-bench-train-") as tmp:
        out = Path(tmp) / "run"
        train(
            TrainConfig(
                variant="small",
                frames=NUM_ENVS * NUM_STEPS * updates,
                eval_every=0,
                eval_seeds=1,
                eval_episodes=1,
                eval_envs=2,
                out=out,
                progress=False,
            )
        )
        rows = read_progress(out / "progress.csv")
    per_update = [NUM_ENVS * NUM_STEPS / float(r["fps"]) for r in rows[1:]]
    n = max(1, len(rows) - 1)
    first, last = rows[0], rows[-1]

    def spent(key: str) -> float:
        return (float(last[key]) - float(first[key])) / n

    return {
        "update_seconds": per_update,
        "split": {
            "env_s": spent("env_s"),
            "policy_s": spent("policy_s"),
            "update_s": spent("update_s"),
        },
    }


def _child(spec: str) -> int:
    args = json.loads(spec)
    os.environ.setdefault("OMP_NUM_THREADS", "2")
    result = (
        _ours_cell(args["updates"])
        if args["cell"] == "ours"
        else _sb3_cell(args["cell"], args["updates"])
    )
    print("RESULT " + json.dumps(result), flush=True)
    return 0


def run_cell(cell: str, updates: int, timeout: float) -> Dict[str, Any]:
    spec = json.dumps({"cell": cell, "updates": updates})
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, __file__, "--child", spec],
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    for line in proc.stdout.splitlines():
        if line.startswith("RESULT "):
            r = json.loads(line[7:])
            r["wall_s"] = round(time.perf_counter() - t0, 1)
            return r
    raise RuntimeError(f"cell {cell} failed (exit {proc.returncode}):\n{proc.stderr[-3000:]}")


def _median(xs: Sequence[float]) -> float:
    s = sorted(xs)
    return s[len(s) // 2] if len(s) % 2 else (s[len(s) // 2 - 1] + s[len(s) // 2]) / 2


def main(argv: Optional[Sequence[str]] = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--updates", type=int, default=3, help="updates per cell (first is warm-up)")
    p.add_argument("--reps", type=int, default=1)
    p.add_argument("--cells", default=",".join(CELLS))
    p.add_argument("--timeout", type=float, default=1800.0, help="seconds per cell")
    p.add_argument(
        "--out", type=Path, default=Path(__file__).resolve().parent / "results" / "train"
    )
    p.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        return _child(args.child)
    if args.updates < 2:
        p.error("--updates must be at least 2 (the first is a warm-up)")
    cells = [c for c in args.cells.split(",") if c]
    results: Dict[str, List[Dict[str, Any]]] = {c: [] for c in cells}
    for rep in range(args.reps):
        for cell in cells:
            print(f"rep {rep + 1}/{args.reps}: {cell} ({args.updates} updates)...", flush=True)
            results[cell].append(run_cell(cell, args.updates, args.timeout))
    frames = NUM_ENVS * NUM_STEPS
    rows = []
    for cell in cells:
        secs = [s for r in results[cell] for s in r["update_seconds"]]
        rows.append(
            (cell, frames / _median(secs), frames / max(secs), frames / min(secs), len(secs))
        )
    base = {c: f for c, f, *_ in rows}
    lines = [
        "# Training throughput (PPO Small, 32 envs x 125 steps, 10 epochs, minibatch 200)",
        "",
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs; "
        f"{args.updates - 1} timed update(s) per cell x {args.reps} rep(s)",
        "",
        "| trainer | frames/s (median) | min-max | updates timed | x sb3-subproc |",
        "|---|---|---|---|---|",
    ]
    for cell, med, lo, hi, n in rows:
        ratio = med / base["sb3-subproc"] if "sb3-subproc" in base else float("nan")
        lines.append(f"| {cell} | {med:.0f} | {lo:.0f}-{hi:.0f} | {n} | {ratio:.2f}x |")
    if "ours" in base and "sb3-subproc-kept" in base:
        lines += [
            "",
            "ours against SB3 given the same allocator setting (sb3-subproc-kept): "
            f"{base['ours'] / base['sb3-subproc-kept']:.2f}x",
        ]
    if "ours" in results:
        sp = results["ours"][-1]["split"]
        lines += [
            "",
            "Where one update's time goes in `ours` (seconds per 4000 frames): "
            + ", ".join(f"{k[:-2]} {v:.2f}" for k, v in sp.items()),
        ]
    text = "\n".join(lines) + "\n"
    print(text)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "train_throughput.md").write_text(text)
    (args.out / "train_throughput.json").write_text(
        json.dumps(
            {"args": {"updates": args.updates, "reps": args.reps}, "results": results}, indent=1
        )
        + "\n"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
