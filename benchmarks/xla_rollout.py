"""Steps/s of a jitted rollout (``envs.xla()`` in a ``lax.scan``) against the Python loop of
``step()`` over the same pool, for the native game and hosted CartPole at 64 and 1,024 envs,
and EnvPool's own ``xla()`` on CartPole where it runs.

Each round runs every system once, in turn (interleaved), ``--steps`` steps each with random
actions drawn beforehand; the table shows the median steps/s over ``--reps`` rounds and the
ratio of the jitted rollout to the Python loop. Compilation happens before the first round.

    python benchmarks/xla_rollout.py --reps 5
    python benchmarks/xla_rollout.py --quick        # a smoke run

Writes ``xla_rollout.json`` and ``xla_rollout.md`` under ``--out`` (default
``benchmarks/results/xla_rollout``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np


def rollout_fns(env: Any, steps: int, n: int, actions: np.ndarray) -> dict[str, Callable[[], None]]:
    """``{"jitted": ..., "python": ...}``: each runs ``steps`` steps of ``env``."""
    import jax
    import jax.numpy as jnp

    handle, _recv, _send, step = env.xla()
    state = {"handle": handle}

    @jax.jit
    def roll(h: Any, acts: Any) -> Any:
        def body(h: Any, a: Any) -> Any:
            h, (_obs, reward, *_rest) = step(h, a)
            return h, reward.sum()

        return jax.lax.scan(body, h, acts)

    jacts = jnp.asarray(actions, jnp.int32)
    h, total = roll(handle, jacts)  # compile
    total.block_until_ready()
    state["handle"] = h

    def jitted() -> None:
        h, total = roll(state["handle"], jacts)
        total.block_until_ready()
        state["handle"] = h

    def python() -> None:
        for a in actions:
            env.step(a)

    return {"jitted": jitted, "python": python}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--envs", type=int, nargs="+", default=[64, 1024])
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--quick", action="store_true", help="a smoke run: 1 rep, 10 steps, 64 envs")
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/xla_rollout"))
    args = ap.parse_args()
    if args.quick:
        args.reps, args.steps, args.envs = 1, 10, [64]

    import jax
    import rogue_gym.envpool as envpool

    rng = np.random.default_rng(0)
    systems: list[tuple[str, str, int, Callable[[], None]]] = []
    opened: list[Any] = []
    for n in args.envs:
        for task, num_actions in (("RogueGym-v0", 11), ("CartPole-v1", 2)):
            env = envpool.make(task, num_envs=n, num_threads=args.workers, seed=1)
            opened.append(env)
            env.reset()
            actions = rng.integers(0, num_actions, (args.steps, n))
            for name, fn in rollout_fns(env, args.steps, n, actions).items():
                systems.append((task, f"rogue_gym {name}", n, fn))
        try:
            import envpool as real  # EnvPool's own xla(), where its C++ pool and jax agree

            env = real.make("CartPole-v1", env_type="gymnasium", num_envs=n, seed=1)
            env.reset()
            actions = rng.integers(0, 2, (args.steps, n))
            fns = rollout_fns(env, args.steps, n, actions)
            systems.append(("CartPole-v1", "EnvPool jitted", n, fns["jitted"]))
            systems.append(("CartPole-v1", "EnvPool python", n, fns["python"]))
            opened.append(env)
        except Exception as err:  # reported, not fatal
            print(f"EnvPool's own xla() does not run here: {type(err).__name__}: {err}"[:300])

    times: dict[tuple[str, str, int], list[float]] = {(t, s, n): [] for t, s, n, _ in systems}
    for rep in range(args.reps):
        for task, system, n, fn in systems:
            start = time.perf_counter()
            fn()
            times[(task, system, n)].append(args.steps * n / (time.perf_counter() - start))
        print(f"round {rep + 1}/{args.reps} done", flush=True)
    for env in opened:
        env.close()

    rows = []
    for (task, system, n), values in times.items():
        med = statistics.median(values)
        base = times.get((task, system.replace("jitted", "python"), n))
        ratio = med / statistics.median(base) if base and "jitted" in system else None
        rows.append(
            {"task": task, "system": system, "envs": n, "steps_per_s": med, "vs_python": ratio}
        )
    lines = [
        f"# Jitted rollout against the Python loop ({platform.node()}, {os.cpu_count()} CPUs, "
        f"jax {jax.__version__}, {args.workers} workers, {args.steps} steps, median of "
        f"{args.reps})",
        "",
        "| task | system | envs | steps/s | vs the Python loop |",
        "|---|---|---:|---:|---:|",
    ]
    for r in rows:
        ratio = "" if r["vs_python"] is None else f"{r['vs_python']:.2f}x"
        lines.append(
            f"| {r['task']} | {r['system']} | {r['envs']} | {r['steps_per_s']:,.0f} | {ratio} |"
        )
    table = "\n".join(lines)
    print(table)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "xla_rollout.md").write_text(table + "\n")
    (args.out / "xla_rollout.json").write_text(
        json.dumps({"args": vars(args) | {"out": str(args.out)}, "rows": rows}, indent=1)
    )


if __name__ == "__main__":
    main()
