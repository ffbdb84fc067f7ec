"""What a per-row stamp would cost the caller (issue: can a cheap check catch stale or
half-written rows?): the native game's sync ``step()`` with and without one vectorized compare
of a worker-written 8-byte column per call, the check a stamp would need (every env's stamp
equal to the call's). The stand-in column is ``episode_index``, written by the workers every
step as a stamp would be: the same cache lines, the same compare.

Both forms run in one pool, in alternating bursts (A B, then B A, ...): the median of the
pairs' ratios and its 95% interval.

    .venv/bin/python benchmarks/row_stamp.py --envs 64 4096 --pairs 200

Writes ``results/row_stamp/row_stamp.{md,json}`` (``--out``).
"""

from __future__ import annotations

import argparse
import platform
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np

from common import median_interval, write_results

RESULTS = Path(__file__).resolve().parent / "results" / "row_stamp"


def burst(envs: Any, actions: np.ndarray, seconds: float, check: bool) -> float:
    """Steps/s of sync steps for ``seconds``, each followed by the stamp compare if
    ``check``."""
    core = envs._core
    n, calls, t0 = envs.num_envs, 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        envs.step(actions[calls % len(actions)])
        if check:
            stamps = core.cols[core.state.slot]["episode_index"]
            if not (stamps >= 0).all():  # never: the stand-in has no bad stamp
                raise AssertionError("a stale row")
        calls += 1
    return calls * n / (time.perf_counter() - t0)


def run(num_envs: int, pairs: int, seconds: float) -> dict[str, Any]:
    import rogue_gym

    envs = rogue_gym.make_vec(num_envs, config="paper", num_workers=1, seed=0)
    try:
        rng = np.random.default_rng(0)
        actions = rng.integers(0, 11, size=(64, num_envs))
        envs.reset(seed=0)
        for i in range(20):
            envs.step(actions[i % 64])
        ratios, plain, checked = [], [], []
        for p in range(pairs):
            order = (False, True) if p % 2 == 0 else (True, False)
            got = {c: burst(envs, actions, seconds, c) for c in order}
            plain.append(got[False])
            checked.append(got[True])
            ratios.append(got[True] / got[False])
    finally:
        envs.close()
    lo, hi = median_interval(ratios)
    return {
        "num_envs": num_envs,
        "plain": statistics.median(plain),
        "checked": statistics.median(checked),
        "ratio": statistics.median(ratios),
        "interval": [lo, hi],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--envs", type=int, nargs="+", default=[64, 4096])
    ap.add_argument("--pairs", type=int, default=200)
    ap.add_argument("--seconds", type=float, default=0.1)
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()
    rows = []
    for n in args.envs:
        r = run(n, args.pairs, args.seconds if n <= 256 else args.seconds * 4)
        rows.append(r)
        print(
            f"{n} envs: checked/plain {r['ratio']:.4f} ({r['interval'][0]:.4f}-{r['interval'][1]:.4f})"
        )
    md = [
        f"{args.pairs} pairs of bursts, native game, 1 worker, {platform.node()}",
        "",
        "| envs | plain steps/s | with the compare | ratio (median) | 95% interval |",
        "|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        md.append(
            f"| {r['num_envs']:,} | {r['plain']:,.0f} | {r['checked']:,.0f} | {r['ratio']:.4f} "
            f"| {r['interval'][0]:.4f}-{r['interval'][1]:.4f} |"
        )
    text = "\n".join(md)
    print(text)
    write_results(
        args.out, "row_stamp", text, {"rows": rows, "args": vars(args) | {"out": str(args.out)}}
    )


if __name__ == "__main__":
    main()
