"""The async head-to-head: this pool against TorchRL's ``AsyncEnvPool`` and gymnasium's
``AsyncVectorEnv`` on TorchRL's own two workloads (pytorch/rl PR #4182).

- ``dispatch``: 8 zero-latency envs; the figure is the consumer's cost per transition
  (recv, write the actions, send), harvesting ``--transitions`` (1,024) per round.
- ``slow_reset``: 32 envs with 1 ms steps and a 200 ms reset every 200 steps; the env supply caps
  it near 16k transitions/s (each env gives 200 steps per 0.4 s). This pool runs it at 1 to 32
  envs per worker with the envs on threads (``env_concurrency="threads"``), and serial.
- ``io``: 256 envs whose every step waits a random 2-60 ms (log-normal, median 10 ms), as envs
  that talk to a simulator or a service do; the ceiling is envs / mean latency. This pool with
  its envs on threads in 2 and 4 workers, against gymnasium's ``AsyncVectorEnv`` (a process per
  env) and TorchRL's ``AsyncEnvPool``; the table adds the memory (PSS) of their processes.

Both drive each async pool as PR #4182 does: ``min_get=1, max_get=num_envs, timeout=1e-3``
(here ``recv(min_batch=1, max_batch=num_envs, timeout=1e-3)``), answering every env received at
once; rows marked "no deadline" take every env ready as soon as one is (``timeout=None``),
which waits less: the deadline holds back envs that are ready early in its millisecond. ``AsyncVectorEnv`` and this pool's ``step()`` run lockstep steps of all envs. Systems
run in turn (interleaved), ``--reps`` times each; the table shows medians and ratios.

    python benchmarks/async_pools.py --reps 3
    python benchmarks/async_pools.py --quick         # a smoke run (CI)
    PYTHONPATH=/tmp/old/python python benchmarks/async_pools.py --only rogue_gym --out ...
                                                     # this pool only: one build of an A/B

Writes ``async_pools.json`` and ``async_pools.md`` under ``--out``
(default ``benchmarks/results/async_pools``).
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import platform
import random
import statistics
import time
from pathlib import Path
from typing import Any, Callable, Optional

import gymnasium as gym
import numpy as np
import rogue_gym

#: PR #4182's recv deadline, seconds (with ``min_get=1, max_get=num_envs``).
HARVEST = 1e-3
WORKLOADS = {
    # envs, step seconds, reset seconds, steps between resets
    "dispatch": (8, 0.0, 0.0, 200),
    "slow_reset": (32, 1e-3, 0.2, 200),
    # step seconds 0: a random latency a step (`IoEnv`); no episode end.
    "io": (256, 0.0, 0.0, 10**9),
}
#: The ``io`` workload's latency: log-normal with this median and sigma, clipped to these.
IO_MEDIAN, IO_SIGMA, IO_CLIP = 0.010, 0.75, (0.002, 0.060)


class Workload(gym.Env):
    """An env that sleeps ``step_s`` a step and ``reset_s`` a reset, ending every ``every``
    steps; observations are 4 float32."""

    observation_space = gym.spaces.Box(-1.0, 1.0, (4,), np.float32)
    action_space = gym.spaces.Discrete(2)

    def __init__(self, step_s: float, reset_s: float, every: int) -> None:
        self.step_s, self.reset_s, self.every, self.t = step_s, reset_s, every, 0

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> Any:
        super().reset(seed=seed)
        if self.reset_s:
            time.sleep(self.reset_s)
        self.t = 0
        return np.zeros(4, np.float32), {}

    def step(self, action: Any) -> Any:
        if self.step_s:
            time.sleep(self.step_s)
        self.t += 1
        return np.full(4, self.t / self.every, np.float32), 1.0, self.t >= self.every, False, {}


class IoEnv(gym.Env):
    """An env whose every step waits a random latency (see ``IO_*``), from a generator of its
    own; observations are 4 float32. Its own CPU work is a few microseconds (the standard
    library's generator, one array made once), as an env that waits on I/O has."""

    observation_space = gym.spaces.Box(-1.0, 1.0, (4,), np.float32)
    action_space = gym.spaces.Discrete(2)
    OBS = np.zeros(4, np.float32)

    def __init__(self) -> None:
        self.rng = random.Random()

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> Any:
        super().reset(seed=seed)
        self.rng = random.Random(seed)
        return self.OBS, {}

    def step(self, action: Any) -> Any:
        time.sleep(io_latency(self.rng))
        return self.OBS, 1.0, False, False, {}


def io_latency(rng: random.Random) -> float:
    """One draw of the ``io`` workload's latency, seconds."""
    lo, hi = IO_CLIP
    return min(hi, max(lo, rng.lognormvariate(math.log(IO_MEDIAN), IO_SIGMA)))


def tree_pss(pid: int) -> int:
    """Bytes of proportional set size of the processes below ``pid`` (its children and theirs):
    what a pool's worker processes take."""
    kids: dict[int, list[int]] = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    ppid = int(f.read().rsplit(")", 1)[1].split()[1])
                kids.setdefault(ppid, []).append(int(d))
            except (OSError, ValueError, IndexError):
                pass
    total, todo = 0, list(kids.get(pid, []))
    while todo:
        p = todo.pop()
        todo += kids.get(p, [])
        try:
            with open(f"/proc/{p}/smaps_rollup") as f:
                total += next(int(line.split()[1]) * 1024 for line in f if line.startswith("Pss:"))
        except (OSError, StopIteration):
            pass
    return total


#: PSS of the worker processes of the last run of each system (``io``), bytes.
MEMORY: dict[str, int] = {}

#: Real envs recorded beside the workloads: gymnasium id and number of envs; async with
#: ``batch_size = num_envs / 2`` against lockstep ``step()`` (HalfCheetah needs mujoco).
REAL = {"native game": ("RogueGym-v0", 64), "HalfCheetah": ("HalfCheetah-v5", 16)}


def run_real(name: str, seconds: float, workers: int, batch: Optional[int]) -> float:
    """Env steps/s of a real env: ``recv()``/``send()`` of ``batch`` envs, or ``step()``."""
    gym_id, n = REAL[name]
    if gym_id == "RogueGym-v0":
        env = rogue_gym.make_vec(gym_id, num_envs=n, num_workers=workers, batch_size=batch)
    else:
        env = rogue_gym.make_vec(gym_id, n, num_workers=workers, batch_size=batch)
    try:
        if batch is None:
            space = env.single_action_space
            return lockstep_rate(env, n, seconds, np.zeros((n, *space.shape), space.dtype))
        env.async_reset(seed=0)
        acts = np.zeros((batch, *env.single_action_space.shape), env.single_action_space.dtype)
        done, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            _, _, _, _, info = env.recv()
            env.send(acts, info["env_id"])
            done += batch
        return done / (time.perf_counter() - t0)
    finally:
        env.close()


def real_systems(name: str, cores: int) -> dict[str, Callable[[float], float]]:
    gym_id, n = REAL[name]
    w = min(cores, n)
    out: dict[str, Callable[[float], float]] = {
        f"rogue_gym async, {w} workers, batch_size {n // 2}": lambda s: run_real(
            name, s, w, n // 2
        ),
        f"rogue_gym step(), {w} workers": lambda s: run_real(name, s, w, None),
    }
    if gym_id != "RogueGym-v0":

        def gym_async(s: float) -> float:
            env = gym.vector.AsyncVectorEnv([lambda: gym.make(gym_id)] * n)
            try:
                return lockstep_rate(env, n, s, np.zeros((n, *env.single_action_space.shape)))
            finally:
                env.close()

        out["gymnasium AsyncVectorEnv"] = gym_async
    return out


def maker(name: str) -> Callable[[], gym.Env]:
    if name == "io":
        return IoEnv
    _, step_s, reset_s, every = WORKLOADS[name]
    return lambda: Workload(step_s, reset_s, every)


def torchrl_env(name: str) -> Any:
    """The same workload as a TorchRL ``EnvBase`` (TorchRL's own env type)."""
    import torch
    from tensordict import TensorDict
    from torchrl.data import Categorical, Composite, Unbounded
    from torchrl.envs import EnvBase

    _, step_s, reset_s, every = WORKLOADS[name]

    class TorchWorkload(EnvBase):
        def __init__(self) -> None:
            super().__init__(batch_size=())
            self.observation_spec = Composite(observation=Unbounded(shape=(4,)))
            self.action_spec = Categorical(2)
            self.reward_spec = Unbounded(shape=(1,))
            self.t = 0
            self.rng = random.Random()

        def _reset(self, td: Any) -> Any:
            if reset_s:
                time.sleep(reset_s)
            self.t = 0
            done = torch.zeros(1, dtype=torch.bool)
            return TensorDict(
                observation=torch.zeros(4), done=done, terminated=done.clone(), batch_size=()
            )

        def _step(self, td: Any) -> Any:
            if name == "io":
                time.sleep(io_latency(self.rng))
            elif step_s:
                time.sleep(step_s)
            self.t += 1
            done = torch.tensor([self.t >= every])
            return TensorDict(
                observation=torch.full((4,), self.t / every),
                reward=torch.ones(1),
                done=done,
                terminated=done.clone(),
                batch_size=(),
            )

        def _set_seed(self, seed: Optional[int]) -> None:
            pass

    return TorchWorkload()


def lockstep_rate(env: Any, n: int, seconds: float, acts: Any = None) -> float:
    """Transitions/s of ``step()`` of all ``n`` envs of a vector env, after a reset (actions
    ``acts``, default zeros)."""
    env.reset(seed=0)
    acts = np.zeros(n, np.int64) if acts is None else acts
    done, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        env.step(acts)
        done += n
    return done / (time.perf_counter() - t0)


def run_pool(
    name: str,
    seconds: float,
    workers: int,
    lockstep: bool,
    timeout: Optional[float],
    concurrency: Any = "serial",
    label: str = "",
    normal_scheduling: bool = False,
) -> float:
    """This pool: async with ``recv(min_batch=1, max_batch=num_envs, timeout=timeout)`` (PR
    #4182's harvest loop with ``timeout=1e-3``; with None, every env ready at once), or
    lockstep ``step()``; ``concurrency``: its ``env_concurrency``. ``normal_scheduling``: the
    control for threaded workers' batch scheduling: their threads are put back on the normal
    policy once started."""
    n = WORKLOADS[name][0]
    env = rogue_gym.PoolVectorEnv(
        [maker(name)] * n, num_workers=workers, batch_size=n, env_concurrency=concurrency
    )
    try:
        if lockstep:
            return lockstep_rate(env, n, seconds)
        # As TorchRL's loop starts: every env reset, then every env sent an action.
        env.reset(seed=0)
        if normal_scheduling:
            for pid in env.worker_pids:
                for tid in os.listdir(f"/proc/{pid}/task"):
                    os.sched_setscheduler(int(tid), os.SCHED_OTHER, os.sched_param(0))
        env.send(np.zeros(n, np.int64), np.arange(n))
        done, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            try:
                _, _, _, _, info = env.recv(min_batch=1, max_batch=n, timeout=timeout)
            except TimeoutError:
                continue
            ids = info["env_id"]
            env.send(np.zeros(len(ids), np.int64), ids)
            done += len(ids)
        rate = done / (time.perf_counter() - t0)
        if label:
            MEMORY[label] = tree_pss(os.getpid())
        return rate
    finally:
        env.close()


def run_torchrl(
    name: str,
    seconds: float,
    exchange: str,
    per_worker: int,
    timeout: Optional[float],
    label: str = "",
) -> float:
    import torch
    from torchrl.envs import AsyncEnvPool

    n = WORKLOADS[name][0]
    pool = AsyncEnvPool(
        [functools.partial(torchrl_env, name)] * n,
        backend="multiprocessing",
        exchange=exchange,
        envs_per_worker=per_worker,
    )
    try:
        td = pool.reset()
        td["action"] = torch.zeros(n, dtype=torch.long)
        pool.async_step_and_maybe_reset_send(td)
        done, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            try:
                _, nxt = pool.async_step_and_maybe_reset_recv(min_get=1, max_get=n, timeout=timeout)
            except TimeoutError:
                continue
            k = nxt.batch_size[0]
            nxt["action"] = torch.zeros(k, dtype=torch.long)
            pool.async_step_and_maybe_reset_send(nxt)
            done += k
        rate = done / (time.perf_counter() - t0)
        if label:
            MEMORY[label] = tree_pss(os.getpid())
        return rate
    finally:
        pool.shutdown() if hasattr(pool, "shutdown") else pool.close()


def supply(name: str, seconds: float) -> float:
    """The env supply: ``num_envs`` times what one env gives in a plain loop here (its sleeps
    overshoot a little, so this is below the nominal figure); for ``io``, envs over the mean
    latency of the distribution."""
    n = WORKLOADS[name][0]
    if name == "io":
        rng = random.Random(0)
        return n / statistics.fmean(io_latency(rng) for _ in range(200_000))
    env = maker(name)()
    env.reset()
    done, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        _, _, end, _, _ = env.step(0)
        done += 1
        if end:
            env.reset()
    return n * done / (time.perf_counter() - t0)


def handoff_us(cores: Optional[tuple[int, int]], rounds: int = 20_000) -> float:
    """This machine's cost of a hand-off between processes: microseconds for a byte to go to
    a child process and back through pipes (two wake-ups), the two pinned to ``cores`` (the
    same core twice, or two). Every round trip of an env through a pool crosses several such
    hand-offs, so this sets a floor under the envs that wait a millisecond."""
    down_r, down_w = os.pipe()
    up_r, up_w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: echo every byte back until the parent closes its end
        try:
            os.close(down_w)
            os.close(up_r)
            if cores:
                os.sched_setaffinity(0, {cores[1]})
            while os.read(down_r, 1):
                os.write(up_w, b"x")
        finally:
            os._exit(0)
    os.close(down_r)
    os.close(up_w)
    before = os.sched_getaffinity(0)
    try:
        if cores:
            os.sched_setaffinity(0, {cores[0]})
        for _ in range(1000):  # the child has pinned itself and both are warm
            os.write(down_w, b"x")
            os.read(up_r, 1)
        t0 = time.perf_counter()
        for _ in range(rounds):
            os.write(down_w, b"x")
            os.read(up_r, 1)
        return (time.perf_counter() - t0) / rounds * 1e6
    finally:
        os.sched_setaffinity(0, before)
        os.close(down_w)  # the child reads the end and exits
        os.close(up_r)
        os.waitpid(pid, 0)


def handoffs(rounds: int) -> dict[str, float]:
    """:func:`handoff_us` on one core and across two (where there are two), median of 3."""
    usable = sorted(os.sched_getaffinity(0))
    pairs = {"one core": (usable[0], usable[0])}
    if len(usable) > 1:
        pairs["two cores"] = (usable[0], usable[1])
    return {k: statistics.median(handoff_us(c, rounds) for _ in range(3)) for k, c in pairs.items()}


def run_gym_async(name: str, seconds: float, label: str = "") -> float:
    n = WORKLOADS[name][0]
    env = gym.vector.AsyncVectorEnv([maker(name)] * n)
    try:
        rate = lockstep_rate(env, n, seconds)
        if label:
            MEMORY[label] = tree_pss(os.getpid())
        return rate
    finally:
        env.close()


def systems(name: str, cores: int, quick: bool) -> dict[str, Callable[[float], float]]:
    """Every system to run on workload ``name``: this pool with the layouts tune tries (one
    worker per core, one per env), TorchRL with each exchange and 1 or several envs per worker,
    and AsyncVectorEnv."""
    n = WORKLOADS[name][0]
    out: dict[str, Callable[[float], float]] = {}
    if name == "io":
        return io_systems(cores, quick)
    if name == "slow_reset":
        # Envs on threads at 1 to 32 envs per worker (the four, and the fewest workers,
        # which suit envs that wait: docs/performance.md), serial at 2 and 4 beside them.
        for per in [1, 2, 4, 8, 16, 32] if not quick else [4]:
            w = n // per
            out[f"rogue_gym async, threads, {per} env/worker ({w} workers)"] = lambda s, w=w: (
                run_pool(name, s, w, False, None, "threads")
            )
        if not quick:
            out["rogue_gym async, threads, 8 env/worker, normal scheduling (control)"] = lambda s: (
                run_pool(name, s, n // 8, False, None, "threads", normal_scheduling=True)
            )
        for per in [2, 4] if not quick else []:
            w = n // per
            out[f"rogue_gym async, serial, {per} env/worker ({w} workers)"] = lambda s, w=w: (
                run_pool(name, s, w, False, None)
            )
    # One worker per core, one per env (what tune tries); quick: the one that suits the load.
    layouts = sorted({min(cores, n), n}) if not quick else [n if name == "slow_reset" else cores]
    for w in layouts:
        out[f"rogue_gym async, {w} workers"] = lambda s, w=w: run_pool(name, s, w, False, HARVEST)
    for w in layouts:
        out[f"rogue_gym async, {w} workers, no deadline"] = lambda s, w=w: run_pool(
            name, s, w, False, None
        )
    out[f"rogue_gym step(), {min(cores, n)} workers"] = lambda s: run_pool(
        name, s, min(cores, n), True, None
    )
    if quick and name != "dispatch":
        return out  # the smoke run starts TorchRL once (its 32 processes take long to start)
    try:
        import torchrl  # noqa: F401

        for exchange in ("shm", "queue") if not quick else ("shm",):
            # Quick: one worker per core (each TorchRL worker imports torch: seconds apiece).
            for per in sorted({1, max(1, n // cores)}) if not quick else [max(1, n // cores)]:
                out[f"torchrl AsyncEnvPool {exchange}, {per} env/worker"] = (
                    lambda s, e=exchange, p=per: run_torchrl(name, s, e, p, HARVEST)
                )
        if not quick:
            out["torchrl AsyncEnvPool shm, 1 env/worker, no deadline"] = lambda s: run_torchrl(
                name, s, "shm", 1, None
            )
    except ImportError:
        print("torchrl is not installed: its rows are left out")
    if not quick:
        out["gymnasium AsyncVectorEnv"] = lambda s: run_gym_async(name, s)
    return out


def io_systems(cores: int, quick: bool) -> dict[str, Callable[[float], float]]:
    """The ``io`` workload's systems (see the module docs)."""
    n = WORKLOADS["io"][0]
    out: dict[str, Callable[[float], float]] = {}
    for w in [4, 2] if not quick else [4]:
        label = f"rogue_gym async, threads, {w} workers ({n // w} env/worker)"
        out[label] = lambda s, w=w, label=label: run_pool("io", s, w, False, None, "threads", label)
    if quick:
        return out
    label = "rogue_gym async, threads, 2 workers, normal scheduling (control)"
    out[label] = lambda s, label=label: run_pool(
        "io", s, 2, False, None, "threads", label, normal_scheduling=True
    )
    label = f"rogue_gym async, serial, {cores} workers"
    out[label] = lambda s, label=label: run_pool("io", s, cores, False, None, "serial", label)
    try:
        import torchrl  # noqa: F401

        for per in (64, 8):
            label = f"torchrl AsyncEnvPool shm, {per} env/worker ({n // per} workers)"
            out[label] = lambda s, per=per, label=label: run_torchrl(
                "io", s, "shm", per, HARVEST, label
            )
    except ImportError:
        print("torchrl is not installed: its rows are left out")
    label = f"gymnasium AsyncVectorEnv ({n} processes)"
    out[label] = lambda s, label=label: run_gym_async("io", s, label)
    return out


def main(argv: Optional[list[str]] = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=5.0, help="per run")
    p.add_argument("--reps", type=int, default=3, help="runs per system (interleaved)")
    p.add_argument("--workloads", nargs="*", default=list(WORKLOADS), choices=list(WORKLOADS))
    p.add_argument("--real", nargs="*", default=list(REAL), choices=list(REAL), help="real envs")
    p.add_argument("--quick", action="store_true", help="one short run of a few systems (CI)")
    p.add_argument(
        "--only",
        nargs="*",
        default=None,
        help="run only the systems whose label starts with one of these (e.g. 'rogue_gym' to "
        "compare two builds of this pool, each run on its own PYTHONPATH)",
    )
    p.add_argument("--out", default=str(Path(__file__).parent / "results" / "async_pools"))
    args = p.parse_args(argv)
    if args.quick:
        args.seconds, args.reps, args.real = min(args.seconds, 1.0), 1, []
    cores = len(os.sched_getaffinity(0))
    handoff = handoffs(2_000 if args.quick else 20_000)
    print(
        "hand-off (a byte to another process and back):",
        ", ".join(f"{v:.1f} µs on {k}" for k, v in handoff.items()),
    )
    runs: dict[str, dict[str, list[float]]] = {}
    supplies: dict[str, float] = {}
    tables: dict[str, dict[str, Callable[[float], float]]] = {}
    for name in args.workloads:
        if WORKLOADS[name][1] or WORKLOADS[name][2] or name == "io":
            supplies[name] = supply(name, max(args.seconds, 2.5))
            print(f"{name}: env supply here {supplies[name]:,.0f} transitions/s")
        tables[name] = systems(name, cores, args.quick)
        if args.only is not None:
            tables[name] = {
                k: v for k, v in tables[name].items() if any(k.startswith(o) for o in args.only)
            }
    for name in args.real:
        try:
            gym.make(REAL[name][0]).close()
        except Exception as exc:  # mujoco missing, say
            print(f"{name} is left out: {exc}")
            continue
        tables[name] = real_systems(name, cores)
    for name, table in tables.items():
        runs[name] = {k: [] for k in table}
        for rep in range(args.reps):
            for label, run in table.items():
                try:
                    value = run(args.seconds)
                except Exception as exc:  # a system that cannot run here: say so, go on
                    print(f"{name}: {label}: failed: {exc!r}")
                    continue
                runs[name][label].append(value)
                print(f"{name} rep {rep + 1}/{args.reps}: {label}: {value:,.0f} transitions/s")
    write(args, runs, cores, supplies, handoff)


def write(
    args: argparse.Namespace,
    runs: dict[str, dict[str, list[float]]],
    cores: int,
    supplies: dict[str, float],
    handoff: dict[str, float],
) -> None:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    lines = [
        f"# Async head-to-head ({platform.node()}, {cores} cores, {args.seconds:g} s x "
        f"{args.reps} runs, interleaved)",
        "",
        "Hand-off here (`handoff_us`: a byte to another process and back through pipes, two "
        "wake-ups): " + ", ".join(f"{v:.1f} µs on {k}" for k, v in handoff.items()) + ".",
        "",
    ]
    for name, table in runs.items():
        if name in REAL:
            lines += [f"## {name}: {REAL[name][0]}, {REAL[name][1]} envs (env steps/s)", ""]
            lines += ["| system | steps/s (median) | x step() |", "|---|---|---|"]
            med = {k: statistics.median(v) for k, v in table.items() if v}
            lock = next((v for k, v in med.items() if "step()" in k), None)
            for k, v in sorted(med.items(), key=lambda kv: -kv[1]):
                lines.append(
                    f"| {k} | {v:,.0f} | {v / lock:.2f}x |" if lock else f"| {k} | {v:,.0f} | - |"
                )
            lines.append("")
            continue
        n, step_s, reset_s, every = WORKLOADS[name]
        nominal = n * every / (every * step_s + reset_s) if step_s or reset_s else None
        ceiling = supplies.get(name)
        med = {k: statistics.median(v) for k, v in table.items() if v and statistics.median(v) > 0}
        trl = [v for k, v in med.items() if k.startswith("torchrl")]
        best_trl = max(trl) if trl else None
        title = (
            f"{n} envs, each step waits {IO_CLIP[0] * 1e3:g}-{IO_CLIP[1] * 1e3:g} ms (log-normal, "
            f"median {IO_MEDIAN * 1e3:g} ms)"
            if name == "io"
            else f"{n} envs, {step_s * 1e3:g} ms step, {reset_s * 1e3:g} ms reset every {every} "
            "steps"
        )
        lines += [f"## {name}: {title}", ""]
        mem = name == "io"
        lines += [
            "| system | transitions/s (median) | µs per transition | vs TorchRL best |"
            + (" of the env supply |" if ceiling else "")
            + (" workers' PSS |" if mem else ""),
            "|---|---|---|---|" + ("---|" if ceiling else "") + ("---|" if mem else ""),
        ]
        for k, v in sorted(med.items(), key=lambda kv: -kv[1]):
            ratio = f"{v / best_trl:.2f}x" if best_trl else "-"
            row = f"| {k} | {v:,.0f} | {1e6 / v:.1f} | {ratio} |"
            if ceiling:
                row += f" {v / ceiling:.0%} |"
            if mem:
                pss = MEMORY.get(k)
                row += f" {pss / 2**20:,.0f} MiB |" if pss else " - |"
            lines.append(row)
        if ceiling and nominal:
            lines += [
                "",
                f"Env supply: {ceiling:,.0f} transitions/s measured here ({n} x one env in a plain "
                f"loop; its sleeps overshoot), {nominal:,.0f} nominal.",
            ]
        elif ceiling:
            lines += [
                "",
                f"Ceiling: {ceiling:,.0f} transitions/s ({n} envs over the mean latency of the "
                f"distribution, {n / ceiling * 1e3:.1f} ms).",
            ]
        lines.append("")
    text = "\n".join(lines)
    print(text)
    (out / "async_pools.md").write_text(text + "\n")
    (out / "async_pools.json").write_text(
        json.dumps(
            {
                "cores": cores,
                "seconds": args.seconds,
                "reps": args.reps,
                "supply": supplies,
                "handoff_us": handoff,
                "runs": runs,
                "pss_bytes": MEMORY,
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    main()
