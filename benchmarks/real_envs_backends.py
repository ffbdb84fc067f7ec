"""The vector envs ``real_envs.py`` compares, built by name, and one timed cell of them.

``build(backend, env, n, workers)`` makes a vector env of ``n`` envs ``env`` (see
:func:`common.env_fn`) with ``backend``; :func:`run_cell` times its ``step`` for a cell's
window. ``real_envs.py`` runs each cell in a process of its own and writes the report.
"""

from __future__ import annotations

import copy
import functools
import time
from typing import Any

from common import env_fn

ENVS = ["pong", "pong-pre", "nethack", "halfcheetah", "minigrid", "crafter", "cartpole"]
BACKENDS = ["pool", "gym-sync", "gym-async", "sb3-subproc", "envpool", "ale-vector", "pool-vector"]
#: Backends run only when named: ``pool-copy`` is the pool copying every batch of observations
#: into fresh arrays, as ``copy=True`` did before it lent the slots (the A/B of that change).
EXTRA_BACKENDS = ["pool-copy"]
#: Backends that run ale-py's C++ vector env (Pong only).
ALE_BACKENDS = ("ale-vector", "pool-vector")
#: Backends with one process per env (the worker count does not apply).
PER_ENV_PROCESS = ("gym-async", "sb3-subproc")


def _envpool(env: str, n: int, workers: int) -> Any:
    import envpool

    common = {"num_envs": n, "num_threads": workers, "seed": 0}
    if env == "pong":
        raw = {"img_height": 210, "img_width": 160, "gray_scale": False, "stack_num": 1}
        raw |= {"episodic_life": False, "reward_clip": False, "noop_max": 1}
        raw |= {"repeat_action_probability": 0.25, "use_fire_reset": False}
        return envpool.make_gymnasium("Pong-v5", **common, **raw)
    if env == "pong-pre":
        pre = {"episodic_life": False, "reward_clip": False, "repeat_action_probability": 0.25}
        return envpool.make_gymnasium("Pong-v5", **common, **pre, use_fire_reset=False)
    if env == "halfcheetah":
        return envpool.make_gymnasium("HalfCheetah-v5", **common)
    raise LookupError(f"envpool has no {env} here")


def ale_vector(env: str, n: int, workers: int) -> Any:
    from ale_py.vector_env import AtariVectorEnv

    common = {"num_envs": n, "num_threads": workers, "repeat_action_probability": 0.25}
    common |= {"reward_clipping": False, "use_fire_reset": False}
    if env == "pong":
        raw = {"img_height": 210, "img_width": 160, "grayscale": False, "stack_num": 1}
        return AtariVectorEnv("pong", **common, **raw, maxpool=False, noop_max=0)
    if env == "pong-pre":
        return AtariVectorEnv("pong", **common)
    raise LookupError(f"ale-py's vector env runs Atari only, not {env}")


class _Copying:
    """A vector env whose observations are copied into fresh arrays after every call."""

    def __init__(self, env: Any) -> None:
        self.env = env
        self.action_space = env.action_space

    def reset(self, **kw: Any) -> Any:
        obs, info = self.env.reset(**kw)
        return copy.deepcopy(obs), info

    def step(self, actions: Any) -> Any:
        obs, *rest = self.env.step(actions)
        return (copy.deepcopy(obs), *rest)

    def close(self) -> None:
        self.env.close()


def build(backend: str, env: str, n: int, workers: int) -> Any:
    """The vector env, reset (everything before the timed window)."""
    if backend == "envpool":
        v = _envpool(env, n, workers)
        v.reset()
        return v
    if backend == "ale-vector":
        v = ale_vector(env, n, workers)
        v.reset(seed=0)
        return v
    if backend == "pool-vector":
        import rogue_gym

        block = functools.partial(ale_vector, env, workers=1)
        v = rogue_gym.PoolVectorEnv.from_vector_env(block, n, num_workers=workers)
        v.reset(seed=0)
        return v
    fn = env_fn(env)
    if backend == "pool":
        import rogue_gym

        v = rogue_gym.PoolVectorEnv([fn] * n, num_workers=workers)
    elif backend == "pool-copy":
        import rogue_gym

        v = _Copying(rogue_gym.PoolVectorEnv([fn] * n, num_workers=workers, copy=False))
    elif backend == "gym-sync":
        import gymnasium as gym

        v = gym.vector.SyncVectorEnv([fn] * n)
    elif backend == "gym-async":
        import gymnasium as gym

        v = gym.vector.AsyncVectorEnv([fn] * n, shared_memory=True)
    elif backend == "sb3-subproc":
        import multiprocessing as mp

        from stable_baselines3.common.vec_env import SubprocVecEnv

        mp.set_forkserver_preload(["stable_baselines3.common.vec_env.subproc_vec_env", "gymnasium"])
        v = SubprocVecEnv([fn] * n, start_method="forkserver")
        v.seed(0)
        v.reset()
        return v
    else:
        raise ValueError(f"unknown backend {backend}")
    v.reset(seed=0)
    return v


def run_cell(cell: dict[str, Any]) -> dict[str, Any]:
    n, env, backend = int(cell["num_envs"]), cell["env"], cell["backend"]
    import numpy as np

    v = build(backend, env, n, int(cell["workers"]))
    space = v.action_space
    space.seed(12345)
    if backend in ("envpool", "sb3-subproc"):  # their action_space is one env's
        dtype = np.int32 if backend == "envpool" and space.dtype.kind == "i" else space.dtype
        acts = [np.stack([space.sample() for _ in range(n)]).astype(dtype) for _ in range(32)]
    else:
        acts = [space.sample() for _ in range(32)]
    step = v.step
    try:
        for i in range(int(cell["warmup"])):
            step(acts[i % 32])
        i, start = 0, time.perf_counter()
        deadline = start + float(cell["seconds"])
        cpu0 = time.process_time()
        while time.perf_counter() < deadline or i < 3:
            step(acts[i % 32])
            i += 1
        wall = time.perf_counter() - start
        caller_cpu = time.process_time() - cpu0
    finally:
        v.close()
    return {**cell, "steps_per_s": i * n / wall, "batches": i, "caller_cpu": caller_cpu / wall}
