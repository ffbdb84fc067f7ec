"""The vector envs ``vecenv_throughput.py`` compares over the native game, and one measured
cell of them (run in a child process of its own: ``vecenv_throughput.py --_cell JSON``).

Backends are built by name (:func:`make_pool`, :func:`make_single_env`); :func:`run_cell`
steps one for a window and measures it (steps/s, the process tree's CPU time and memory from
``/proc``); :func:`cell_main` prints its result for the parent.
"""

from __future__ import annotations

import functools
import json
import os
import sys
import time
from typing import Any, Dict, List, Optional, Sequence, Tuple

BACKENDS = ["pool-sync", "pool-async", "gym-sync", "gym-async-shm", "sb3-dummy", "sb3-subproc"]
BACKEND_LABELS = {
    "pool-sync": "rogue_gym pool, sync step()",
    "pool-async": "rogue_gym pool, async send/recv",
    "gym-sync": "gymnasium SyncVectorEnv",
    "gym-async-shm": "gymnasium AsyncVectorEnv(shared_memory=True)",
    "sb3-dummy": "SB3 DummyVecEnv",
    "sb3-subproc": "SB3 SubprocVecEnv",
}
ENCODINGS = ["symbol_onehot_f32", "symbol_onehot_u8", "symbol_index"]
FULL_NUM_ENVS = [8, 16, 64, 256]
SHORT_NUM_ENVS = [8, 64]
NUM_ACTIONS = 11
ACTION_SEED = 12345
HEADLINE_ENVS = 64


def _paper_config() -> Dict[str, Any]:
    """The paper's game config (the suites' copy: no training seed range)."""
    from rogue_gym.suites import PAPER_CONFIG

    return dict(PAPER_CONFIG)


MAX_STEPS = 500
STAIR_REWARD = 50.0


# ============================================================================================
# backends (used inside the per-cell child process)


def _encoding(enc: str) -> Tuple[str, Optional[str]]:
    """(observation name, dtype) of an encoding id."""
    if enc == "symbol_onehot_f32":
        return "symbol_onehot", "float32"
    if enc == "symbol_onehot_u8":
        return "symbol_onehot", "uint8"
    if enc == "symbol_index":
        return "symbol_index", None
    raise ValueError(f"unknown encoding {enc}")


def make_single_env(enc: str) -> Any:
    """One ``RogueEnv`` playing the paper config with the encoding ``enc`` (picklable factory)."""
    from rogue_gym.envs import RogueEnv

    obs, dtype = _encoding(enc)
    kwargs: Dict[str, Any] = {
        "config_dict": _paper_config(),
        "max_steps": MAX_STEPS,
        "stair_reward": STAIR_REWARD,
        "obs": obs,
    }
    if dtype is not None:
        kwargs["dtype"] = dtype
    return RogueEnv(**kwargs)


def make_pool(
    num_envs: int, enc: str, num_workers: Optional[int], batch_size: Optional[int] = None
) -> Any:
    """Our pool's gymnasium VectorEnv facade (``batch_size`` for the async API)."""
    import rogue_gym

    obs, dtype = _encoding(enc)
    kwargs: Dict[str, Any] = {
        "config": _paper_config(),
        "max_steps": MAX_STEPS,
        "stair_reward": STAIR_REWARD,
        "obs": obs,
        "seed": 0,
    }
    if batch_size is not None:
        kwargs["batch_size"] = batch_size
    if dtype is not None:
        kwargs["dtype"] = dtype
    if num_workers is not None:
        kwargs["num_workers"] = num_workers
    return rogue_gym.make_vec(num_envs, **kwargs)


class Driver:
    """Uniform ``step(actions)`` over every backend; ``batch`` = env steps per call."""

    def __init__(self, backend: str, num_envs: int, enc: str, num_workers: Optional[int]):
        self.backend = backend
        self.num_envs = num_envs
        self.batch = num_envs
        fn = functools.partial(make_single_env, enc)
        if backend == "pool-sync":
            self.env = make_pool(num_envs, enc, num_workers)
            self.env.reset(seed=0)
            self.step = self._gym_step
        elif backend == "pool-async":
            # Two workers, each one block of num_envs/2 envs: recv() returns one worker's
            # block (a zero-copy view) while the other worker steps.
            workers = num_workers or 2
            self.batch = max(1, num_envs // workers)
            self.env = make_pool(num_envs, enc, workers, batch_size=self.batch)
            self.env.async_reset()
            self.step = self._async_step
        elif backend == "gym-sync":
            import gymnasium as gym

            self.env = gym.vector.SyncVectorEnv([fn] * num_envs)
            self.env.reset(seed=0)
            self.step = self._gym_step
        elif backend == "gym-async-shm":
            import gymnasium as gym

            self.env = gym.vector.AsyncVectorEnv([fn] * num_envs, shared_memory=True)
            self.env.reset(seed=0)
            self.step = self._gym_step
        elif backend in ("sb3-dummy", "sb3-subproc"):
            import torch

            torch.set_num_threads(1)
            from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

            if backend == "sb3-dummy":
                self.env = DummyVecEnv([fn] * num_envs)
            else:
                import multiprocessing as mp

                # Import the heavy modules once in the forkserver instead of in every worker:
                # start-up only, excluded from the timed window either way.
                mp.set_forkserver_preload(
                    ["stable_baselines3.common.vec_env.subproc_vec_env", "rogue_gym.envs"]
                )
                self.env = SubprocVecEnv([fn] * num_envs, start_method="forkserver")
            self.env.seed(0)
            self.env.reset()
            self.step = self._sb3_step
        else:
            raise ValueError(f"unknown backend {backend}")

    def _gym_step(self, actions: Any) -> None:
        self.env.step(actions)

    def _sb3_step(self, actions: Any) -> None:
        self.env.step(actions)

    def _async_step(self, actions: Any) -> None:
        _obs, _rew, _term, _trunc, info = self.env.recv()
        env_id = info["env_id"]
        self.env.send(actions[env_id], env_id)

    def close(self) -> None:
        self.env.close()


# ============================================================================================
# /proc accounting of a process tree


def _children_map() -> Dict[int, List[int]]:
    kids: Dict[int, List[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                stat = f.read()
        except OSError:
            continue
        ppid = int(stat[stat.rindex(")") + 2 :].split()[1])
        kids.setdefault(ppid, []).append(int(entry))
    return kids


def process_tree(root: int) -> List[int]:
    """``root`` and all its descendants."""
    kids = _children_map()
    out, todo = [], [root]
    while todo:
        pid = todo.pop()
        out.append(pid)
        todo.extend(kids.get(pid, []))
    return out


def tree_cpu_seconds(pids: Sequence[int]) -> float:
    """user+sys CPU seconds of ``pids`` (live processes, all threads)."""
    tick = os.sysconf("SC_CLK_TCK")
    total = 0
    for pid in pids:
        try:
            with open(f"/proc/{pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += int(fields[11]) + int(fields[12])  # utime, stime
    return total / tick


def tree_peak_rss_mib(pids: Sequence[int]) -> float:
    """Sum of ``VmHWM`` (peak resident set) over ``pids``, MiB."""
    kib = 0
    for pid in pids:
        try:
            with open(f"/proc/{pid}/status") as f:
                for line in f:
                    if line.startswith("VmHWM:"):
                        kib += int(line.split()[1])
                        break
        except OSError:
            continue
    return kib / 1024.0


def tree_pss_mib(pids: Sequence[int]) -> float:
    """Sum of proportional set size (``Pss`` of ``smaps_rollup``) over ``pids``, MiB.

    Shared pages are divided among the processes that map them, so unlike summed RSS this
    does not count a forked interpreter's shared pages once per worker.
    """
    kib = 0
    for pid in pids:
        try:
            with open(f"/proc/{pid}/smaps_rollup") as f:
                for line in f:
                    if line.startswith("Pss:"):
                        kib += int(line.split()[1])
                        break
        except OSError:
            continue
    return kib / 1024.0


# ============================================================================================
# one cell (child process)


def run_cell(cell: Dict[str, Any]) -> Dict[str, Any]:
    """Build the backend, warm up, step for ``cell['seconds']``; return the measurements."""
    import numpy as np

    n = int(cell["num_envs"])
    t0 = time.perf_counter()
    drv = Driver(cell["backend"], n, cell["encoding"], cell.get("num_workers"))
    setup_s = time.perf_counter() - t0
    rng = np.random.default_rng(ACTION_SEED)
    acts = [rng.integers(0, NUM_ACTIONS, size=n, dtype=np.int64) for _ in range(256)]
    try:
        for i in range(int(cell["warmup"])):
            drv.step(acts[i % 256])
        pids = process_tree(os.getpid())
        lat: List[float] = []
        cpu0 = tree_cpu_seconds(pids)
        start = time.perf_counter()
        deadline = start + float(cell["seconds"])
        i = 0
        now = start
        while now < deadline or i < int(cell["min_batches"]):
            drv.step(acts[i % 256])
            t = time.perf_counter()
            lat.append(t - now)
            now = t
            i += 1
        wall = now - start
        pids = process_tree(os.getpid())
        cpu = tree_cpu_seconds(pids) - cpu0
        rss = tree_peak_rss_mib(pids)
        pss = tree_pss_mib(pids)
    finally:
        drv.close()
    steps = i * drv.batch
    lat_a = np.asarray(lat)
    workers = getattr(drv.env, "num_workers", None)
    if workers is None:
        workers = n if cell["backend"] in ("gym-async-shm", "sb3-subproc") else 0
    return {
        "workers": int(workers),
        "steps_per_s": steps / wall,
        "p50_ms": float(np.percentile(lat_a, 50) * 1e3),
        "p99_ms": float(np.percentile(lat_a, 99) * 1e3),
        "cpu_us_per_step": cpu / steps * 1e6,
        "peak_rss_mib": rss,
        "pss_mib": pss,
        "processes": len(pids),
        "setup_s": setup_s,
        "batches": i,
        "steps": steps,
        "wall_s": wall,
    }


def cell_main(spec: str) -> int:
    """Run the cell ``spec`` (JSON) and print its result (or its error) for the parent."""
    cell = json.loads(spec)
    try:
        res = run_cell(cell)
        res["status"] = "ok"
    except Exception as exc:  # reported, not raised: one backend failing must not stop the run
        res = {"status": "error", "error": f"{type(exc).__name__}: {exc}"}
    sys.stdout.write("\n@@RESULT@@" + json.dumps(res) + "\n")
    sys.stdout.flush()
    return 0
