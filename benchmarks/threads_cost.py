"""What envs on threads cost an env that computes: hosted CartPole stepped by the same pool
layout with ``env_concurrency="serial"`` and ``"threads"``, side by side (both pools alive,
alternating bursts, :func:`rogue_gym.tuning.duel`), in lockstep (``step()``) and received as
ready (``recv`` with TorchRL's deadline harvest).

    .venv/bin/python benchmarks/threads_cost.py --pairs 40

An env that computes holds the GIL while it steps, so its threads take turns on one core and
pay for the handoffs: the table says how much (serial / threads, above 1 when serial is
faster). Writes ``threads_cost.{md,json}`` under ``--out`` (default
``benchmarks/results/threads_cost``).
"""

from __future__ import annotations

import argparse
import datetime
import platform
from pathlib import Path
from typing import Optional

from rogue_gym.tuning import Candidate, duel

from common import write_results

#: (label, mode, keyword arguments) of the layouts, each timed serial and on threads.
LAYOUTS = [
    ("step(), 2 workers", "pool", {"num_workers": 2, "copy": False}),
    ("recv as ready, 2 workers", "harvest", {"num_workers": 2, "batch_size": 1}),
]


def main(argv: Optional[list[str]] = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--env", default="CartPole-v1")
    p.add_argument("--num-envs", type=int, default=64)
    p.add_argument("--pairs", type=int, default=40, help="pairs of alternating bursts")
    p.add_argument("--burst", type=float, default=0.25, help="seconds a burst")
    p.add_argument("--out", default=str(Path(__file__).parent / "results" / "threads_cost"))
    args = p.parse_args(argv)
    rows, data = [], []
    for label, mode, kwargs in LAYOUTS:
        serial = Candidate(mode, dict(kwargs))
        threads = Candidate(mode, {**kwargs, "env_concurrency": "threads"})
        d = duel(args.env, args.num_envs, serial, threads, pairs=args.pairs, burst=args.burst)
        ratio = d.ratio if d.first == serial.label else 1 / d.ratio
        ratios = sorted(r if d.first == serial.label else 1 / r for r in d.ratios)
        lo, hi = ratios[len(ratios) // 10], ratios[-1 - len(ratios) // 10]
        rows.append(f"| {label} | {ratio:.2f}x | {lo:.2f}-{hi:.2f} |")
        data.append({"layout": label, "serial_over_threads": ratio, "ratios": ratios})
        print(rows[-1], flush=True)
    md = "\n".join(
        [
            f"{args.env} x {args.num_envs}, serial against threads side by side, "
            f"{args.pairs} pairs of {args.burst} s bursts; {datetime.date.today()}, "
            f"{platform.node() or 'this machine'}",
            "",
            "| layout | serial / threads (median) | 10th-90th percentile of the pairs |",
            "|---|---:|---:|",
            *rows,
        ]
    )
    print(md)
    write_results(Path(args.out), "threads_cost", md, {"env": args.env, "layouts": data})


if __name__ == "__main__":
    main()
