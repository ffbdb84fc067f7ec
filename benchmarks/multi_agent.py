"""PettingZoo envs vectorized, agents as rows: this pool against SuperSuit's
``concat_vec_envs_v1`` (its multiprocess vectorizer with ``num_cpus`` workers, and its
single-process one) and a plain loop over the envs, on ``pistonball_v6`` and mpe2's
``simple_spread_v3``.

Every system steps the same ``num_envs`` envs with random actions, one row per (env, agent);
the figure is agent-steps per second (rows stepped per second). Systems run in turn
(interleaved), ``--reps`` times each, every one freshly built and warmed up; the table gives
medians and the pool's ratio to each other system.

    python benchmarks/multi_agent.py                       # 8 and 64 envs, 2 workers, 3 reps
    python benchmarks/multi_agent.py --quick               # a smoke run

Writes ``multi_agent.json`` and ``multi_agent.md`` under ``--out``
(default ``benchmarks/results/multi_agent``).
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

import numpy as np

ENVS = ("pistonball", "simple_spread")
SYSTEMS = ("pool", "supersuit_mp", "supersuit_1p", "plain_loop")


def env_fn(name: str) -> Callable[[], Any]:
    """The PettingZoo parallel env of ``name`` (default settings)."""
    if name == "pistonball":
        from pettingzoo.butterfly import pistonball_v6

        return pistonball_v6.parallel_env
    from mpe2 import simple_spread_v3

    return simple_spread_v3.parallel_env


class System:
    """One vectorizer of ``n`` envs, driven the same way whatever it is."""

    def __init__(self, env: Any) -> None:
        self.env = env
        self.num_envs = env.num_envs
        self.action_space = env.action_space

    def reset(self, seed: int) -> None:
        self.env.reset(seed=seed)

    def sample(self) -> Any:
        """One batch of random actions, one per row."""
        return self.action_space.sample()

    def step(self, actions: np.ndarray) -> None:
        self.env.step(actions)

    def close(self) -> None:
        self.env.close()


class SuperSuit(System):
    """``concat_vec_envs_v1(pettingzoo_env_to_vec_env_v1(env), n, num_cpus)``, gymnasium
    base class (``num_cpus=0``: one process); its action space is one agent's."""

    def sample(self) -> Any:
        return np.stack([self.action_space.sample() for _ in range(self.num_envs)])


def build(system: str, fn: Callable[[], Any], n: int, workers: int) -> System:
    """``pool``: ``PoolVectorEnv.from_pettingzoo``; ``supersuit_mp``/``supersuit_1p``:
    SuperSuit with ``workers`` processes or none; ``plain_loop``: the envs stepped one after
    the other in this process (the rows the pool hosts, :class:`rogue_gym.multi_agent.AgentRows`)."""
    if system == "pool":
        import rogue_gym

        return System(rogue_gym.PoolVectorEnv.from_pettingzoo(fn, n, num_workers=workers))
    if system.startswith("supersuit"):
        import supersuit as ss

        cpus = workers if system == "supersuit_mp" else 0
        vec = ss.pettingzoo_env_to_vec_env_v1(fn())
        return SuperSuit(ss.concat_vec_envs_v1(vec, n, num_cpus=cpus, base_class="gymnasium"))
    from rogue_gym.multi_agent import AgentRows

    return System(AgentRows([fn] * n))


def run(system: str, fn: Callable[[], Any], n: int, workers: int, seconds: float) -> float:
    """Agent-steps per second of ``system`` over about ``seconds`` of random steps."""
    env = build(system, fn, n, workers)
    try:
        env.reset(seed=0)
        env.action_space.seed(0)
        batches = [env.sample() for _ in range(16)]
        for a in batches[:3]:  # warm-up
            env.step(a)
        steps, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            env.step(batches[steps % len(batches)])
            steps += 1
        return steps * env.num_envs / (time.perf_counter() - start)
    finally:
        env.close()


def main(argv: Optional[list[str]] = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--envs", nargs="+", default=list(ENVS), choices=ENVS)
    ap.add_argument("--num-envs", nargs="+", type=int, default=[8, 64])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seconds", type=float, default=3.0, help="timed seconds per run")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--systems", nargs="+", default=list(SYSTEMS), choices=SYSTEMS)
    ap.add_argument("--quick", action="store_true", help="8 envs, 1 rep of 0.5 s")
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "results" / "multi_agent")
    args = ap.parse_args(argv)
    if args.quick:
        args.num_envs, args.reps, args.seconds = [8], 1, 0.5
    results: dict[str, dict[str, list[float]]] = {}
    for name in args.envs:
        fn = env_fn(name)
        for n in args.num_envs:
            key = f"{name} x {n}"
            results[key] = {s: [] for s in args.systems}
            for rep in range(args.reps):
                order = args.systems if rep % 2 == 0 else list(reversed(args.systems))
                for system in order:
                    try:
                        v = run(system, fn, n, args.workers, args.seconds)
                    except Exception as exc:  # a system that cannot run here: say so
                        print(f"{key} {system}: failed: {type(exc).__name__}: {exc}", flush=True)
                        v = float("nan")
                    results[key][system].append(v)
                    print(f"{key} rep {rep + 1}: {system} {v:,.0f} agent-steps/s", flush=True)
    lines = [
        f"{args.workers} workers (SuperSuit: num_cpus={args.workers}), {args.reps} reps of "
        f"{args.seconds:g} s each, interleaved; agent-steps/s (medians); "
        f"{platform.machine()}, {os.cpu_count()} CPUs",
        "",
        "| envs | " + " | ".join(args.systems) + " | pool / best SuperSuit | pool / plain loop |",
        "|---|" + "---:|" * (len(args.systems) + 2),
    ]
    for key, by in results.items():
        med = {s: statistics.median(v) if v else float("nan") for s, v in by.items()}
        best_ss = max(
            (med[s] for s in ("supersuit_mp", "supersuit_1p") if s in med and med[s] == med[s]),
            default=float("nan"),
        )
        pool = med.get("pool", float("nan"))
        plain = med.get("plain_loop", float("nan"))
        cells = " | ".join(f"{med[s]:,.0f}" for s in args.systems)
        lines.append(f"| {key} | {cells} | {pool / best_ss:.2f}x | {pool / plain:.2f}x |")
    text = "\n".join(lines)
    print(text)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "multi_agent.md").write_text(text + "\n")
    (args.out / "multi_agent.json").write_text(
        json.dumps(
            {"args": {k: str(v) for k, v in vars(args).items()}, "results": results}, indent=1
        )
    )


if __name__ == "__main__":
    main()
