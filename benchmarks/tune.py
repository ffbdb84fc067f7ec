"""``rogue_gym.tune``'s pick against an exhaustive sweep of the same candidates.

For each env and size, ``tune`` runs as a user would (its defaults), then an independent sweep
times every one of its candidates again; the pick's sweep median is compared with the sweep's
best, and where they differ the two are timed side by side in pairs (``--final-pairs``), whose
median ratio is the figure that holds on a machine whose speed drifts (``rogue_gym.tuning.duel``:
both pools alive, stepped in alternating bursts). PufferLib's
``autotune`` runs beside it where pufferlib imports.

    .venv-bench/bin/python benchmarks/tune.py                       # every env and size
    .venv-bench/bin/python benchmarks/tune.py --envs cartpole --num-envs 64
    .venv-bench/bin/python benchmarks/tune.py --judge-again results/tune/tune.json  # judge only

Envs: ``cartpole`` (the gymnasium id, so one CartPole vector env per worker is a candidate),
``halfcheetah`` (MuJoCo), ``pong`` (raw ``ALE/Pong-v5``), ``sleep`` (1 ms a step). Set-up:
``bash benchmarks/setup-real-envs.sh``. Writes ``results/tune/tune.{md,json}`` (``--out``).
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
from typing import Any

import rogue_gym
from rogue_gym.tuning import Candidate

from common import env_fn, median_interval

RESULTS = Path(__file__).resolve().parent / "results" / "tune"
ENVS = ("cartpole", "halfcheetah", "pong", "sleep")


def env_of(name: str) -> Any:
    """What tune is given for ``name``."""
    if name == "cartpole":
        return "CartPole-v1"
    if name == "sleep":
        return env_fn("slow")
    return env_fn(name)


def puffer_autotune(name: str, n: int, seconds: float) -> dict[str, Any]:
    """PufferLib's ``autotune`` on the same env and batch size: the best SPS it printed and its
    config (it prints, it does not return)."""
    import contextlib
    import io
    import re

    import pufferlib.emulation
    import pufferlib.vector

    fn = env_of(name)
    if isinstance(fn, str):
        import gymnasium as gym

        fn = functools.partial(gym.make, fn)
    creator = functools.partial(pufferlib.emulation.GymnasiumPufferEnv, env_creator=fn)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        pufferlib.vector.autotune(creator, batch_size=n, max_envs=n, time_per_test=seconds)
    text = out.getvalue()
    blocks = re.split(r"(?m)^SPS: ", text)[1:]
    best = max(blocks, key=lambda b: float(b.split()[0]))
    return {"sps": float(best.split()[0]), "config": " ".join(best.split()[1:])}


def head_to_head(
    env: Any, n: int, pick: Any, best: Any, pairs: int, burst: float
) -> dict[str, Any]:
    """The pick against the sweep's best, side by side (``rogue_gym.tuning.duel``: both pools
    alive, ``pairs`` pairs of alternating bursts): the median of the pairs' ratios, pick over
    best. The sweep's medians move by more than 5% between sweeps on this VM; bursts a fraction
    of a second apart do not see the machine's drift."""
    if pick == best:
        return {"pairs": 0, "ratio": 1.0, "ratios": [], "interval": [1.0, 1.0]}
    d = rogue_gym.tuning.duel(env, n, pick, best, pairs=pairs, burst=burst)
    ratios = d.ratios if d.first == pick.label else [1 / r for r in d.ratios]
    return {
        "pairs": pairs,
        "ratio": statistics.median(ratios),
        "ratios": ratios,
        "interval": list(median_interval(ratios)),
    }


def judge_again(args: argparse.Namespace) -> None:
    """The rows of an earlier run (``--judge-again``), their side-by-side figure timed again
    with ``--final-pairs`` pairs where the pick is not the sweep's best."""
    rows = json.loads(Path(args.judge_again).read_text())["rows"]
    for row in rows:
        if row["pick"] != row["sweep_best"]:
            row["head_to_head"] = head_to_head(
                env_of(row["env"]),
                row["num_envs"],
                Candidate.from_label(row["pick"]),
                Candidate.from_label(row["sweep_best"]),
                args.final_pairs,
                args.final_burst,
            )
            row["judged_again"] = True
            print(
                f"{row['env']} x {row['num_envs']}: side by side {row['head_to_head']['ratio']:.3f}",
                flush=True,
            )
        write(args, rows)
    print(write(args, rows))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--envs", nargs="+", default=list(ENVS), choices=ENVS)
    ap.add_argument("--num-envs", nargs="+", type=int, default=[8, 64, 256])
    # tune as a user runs it: its own defaults.
    ap.add_argument("--tune-seconds", type=float, default=2.0)
    ap.add_argument("--tune-rounds", type=int, default=3)
    ap.add_argument("--sweep-seconds", type=float, default=1.0)
    ap.add_argument("--sweep-rounds", type=int, default=3)
    ap.add_argument(
        "--final-pairs",
        type=int,
        default=160,
        help="where tune's pick is not the sweep's best: this many pairs of alternating "
        "bursts of the two, side by side, for the ratio",
    )
    ap.add_argument("--final-burst", type=float, default=0.25, help="seconds of each burst")
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument(
        "--puffer-path",
        default=None,
        help="a folder holding pufferlib (pip install --no-deps --target DIR pufferlib-core "
        "psutil rich): run its autotune beside",
    )
    ap.add_argument(
        "--judge-again",
        metavar="TUNE_JSON",
        default=None,
        help="an earlier run's tune.json: time its picks against its sweeps' bests side by "
        "side again (--final-pairs pairs), nothing else",
    )
    args = ap.parse_args()
    if args.judge_again:
        judge_again(args)
        return
    if args.puffer_path:
        sys.path.insert(0, args.puffer_path)
    rows = []
    for name in args.envs:
        for n in args.num_envs:
            env = env_of(name)
            t0 = time.monotonic()
            pick = rogue_gym.tune(
                env, n, seconds=args.tune_seconds, rounds=args.tune_rounds, out=None
            )
            tune_s = time.monotonic() - t0
            sweep = rogue_gym.tune(
                env, n, seconds=args.sweep_seconds, rounds=args.sweep_rounds, out=None
            )
            by_label = {t.candidate.label: t.median for t in sweep.timings}
            chosen = pick.best.candidate.label
            final = head_to_head(
                env,
                n,
                pick.best.candidate,
                sweep.best.candidate,
                args.final_pairs,
                args.final_burst,
            )
            row = {
                "env": name,
                "num_envs": n,
                "pick": chosen,
                "pick_in_sweep": by_label.get(chosen, 0.0),
                "sweep_best": sweep.best.candidate.label,
                "sweep_best_steps_per_s": sweep.best.median,
                "ratio": by_label.get(chosen, 0.0) / sweep.best.median
                if sweep.best.median
                else 0.0,
                "head_to_head": final,
                "tune_seconds": round(tune_s, 1),
                "sweep": {t.candidate.label: t.steps_per_s for t in sweep.timings},
                "errors": {t.candidate.label: t.error for t in sweep.timings if t.error},
            }
            if args.puffer_path:
                try:
                    row["puffer"] = puffer_autotune(name, n, args.sweep_seconds)
                except Exception as exc:  # PufferLib cannot run every env: say so
                    row["puffer"] = {"sps": 0.0, "config": f"failed: {type(exc).__name__}: {exc}"}
            rows.append(row)
            write(args, rows)  # after every row: an interrupted run keeps what it measured
            print(
                f"{name} x {n}: tune picked {chosen} ({row['pick_in_sweep']:,.0f} steps/s in the "
                f"sweep), sweep best {row['sweep_best']} ({row['sweep_best_steps_per_s']:,.0f}): "
                f"{row['ratio']:.3f}, side by side {final['ratio']:.3f}; tune took {tune_s:.0f} s",
                flush=True,
            )
    print(write(args, rows))


def write(args: argparse.Namespace, rows: list[dict[str, Any]]) -> str:
    """Write the table and the JSON of the rows so far; returns the table."""
    lines = [
        f"tune: {args.tune_rounds} rounds of {args.tune_seconds:g} s; sweep: "
        f"{args.sweep_rounds} rounds of {args.sweep_seconds:g} s, the same candidates; "
        f"{os.cpu_count()} CPUs",
        "",
        "| env | envs | tune's pick | sweep's best | pick / best (sweep medians) | "
        "pick / best (side by side) | 95% interval | best steps/s | tune took | "
        "PufferLib autotune's best |",
        "|---|---:|---|---|---:|---:|---:|---:|---:|---|",
    ]
    for r in rows:
        puffer = r.get("puffer")
        p = f"{puffer['sps']:,.0f} ({puffer['config'][:60]})" if puffer else "-"
        h = r["head_to_head"]
        if h.get("interval"):
            lo, hi = h["interval"]
        elif h["ratios"]:
            lo, hi = median_interval(h["ratios"])
        else:
            lo, hi = 1.0, 1.0
        how = f" ({h['pairs']} pairs)" if h["pairs"] else " (the same)"
        lines.append(
            f"| {r['env']} | {r['num_envs']} | {r['pick']} | {r['sweep_best']} | "
            f"{r['ratio']:.3f} | {h['ratio']:.3f}{how} | {lo:.3f}-{hi:.3f} | "
            f"{r['sweep_best_steps_per_s']:,.0f} | {r['tune_seconds']:.0f} s | "
            f"{p} |"
        )
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "tune.md").write_text("\n".join(lines) + "\n")
    meta = {
        "machine": platform.node(),
        "cpus": os.cpu_count(),
        "args": {k: str(v) for k, v in vars(args).items()},
    }
    (args.out / "tune.json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=1))

    return "\n".join(lines)


if __name__ == "__main__":
    main()
