"""What the benchmark scripts share: env factories, the isolated cell runner, the result
writer and a bootstrap interval. A library, not a benchmark: scripts import it (and their own
``*_backends.py``), never each other.

* :func:`env_fn`: one env by name (:data:`ENV_NAMES`): the third-party envs of
  ``real_envs.py`` and the Python envs of ``hosted_throughput.py``.
* :func:`run_cells`: every cell of a sweep, each repetition in a fresh ``script --cell JSON``
  process of its own session (killed whole on a timeout), the order shuffled per repetition.
* :func:`write_results`: a script's Markdown table and JSON beside it, under ``--out``.
* :func:`median_interval`: a 95% bootstrap interval of a median.
"""

from __future__ import annotations

import contextlib
import json
import os
import random
import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Callable, ClassVar, Optional

#: Every env :func:`env_fn` builds.
ENV_NAMES = (
    "pong",
    "pong-pre",
    "nethack",
    "halfcheetah",
    "minigrid",
    "crafter",
    "cartpole",
    "rogue-py",
    "slow",
    "text",
)
#: Seconds a ``slow`` env waits per step (an env bound by I/O or a simulator).
SLOW_STEP_S = 0.001


def _slow_env() -> Any:
    import gymnasium as gym
    import numpy as np
    from gymnasium import spaces

    class SlowEnv(gym.Env):
        """Waits ``SLOW_STEP_S`` per step (the CPU is free meanwhile)."""

        observation_space = spaces.Box(-1.0, 1.0, (8,), np.float32)
        action_space = spaces.Discrete(4)

        def reset(self, *, seed: Any = None, options: Any = None) -> Any:
            super().reset(seed=seed)
            self.t = 0
            return np.zeros(8, np.float32), {}

        def step(self, action: Any) -> Any:
            time.sleep(SLOW_STEP_S)
            self.t += 1
            return np.full(8, self.t / 1000, np.float32), 0.0, False, self.t >= 200, {}

    return SlowEnv()


def _text_env() -> Any:
    import gymnasium as gym
    import numpy as np
    from gymnasium import spaces

    class TextLeafEnv(gym.Env):
        """A grid and a short mission string that changes with each episode."""

        observation_space = spaces.Dict(
            {
                "grid": spaces.Box(0, 10, (7, 7, 3), np.uint8),
                "mission": spaces.Text(64, charset="abcdefghijklmnopqrstuvwxyz0123456789 "),
            }
        )
        action_space = spaces.Discrete(4)

        def reset(self, *, seed: Any = None, options: Any = None) -> Any:
            super().reset(seed=seed)
            self.t = 0
            self.mission = f"get to the {int(self.np_random.integers(100))} square"
            return self._obs(), {}

        def _obs(self) -> Any:
            return {"grid": np.full((7, 7, 3), self.t % 10, np.uint8), "mission": self.mission}

        def step(self, action: Any) -> Any:
            self.t += 1
            return self._obs(), 0.0, False, self.t >= 200, {}

    return TextLeafEnv()


def _crafter_env() -> Any:
    """Crafter (old gym API) as a gymnasium env."""
    import crafter
    import gymnasium as gym
    import numpy as np
    from gymnasium import spaces

    class Crafter(gym.Env):
        observation_space = spaces.Box(0, 255, (64, 64, 3), np.uint8)
        action_space = spaces.Discrete(17)
        metadata: ClassVar[dict[str, Any]] = {"render_modes": []}

        def __init__(self) -> None:
            self.env: Any = None

        def reset(self, *, seed: Optional[int] = None, options: Any = None) -> Any:
            super().reset(seed=seed)
            if self.env is None or seed is not None:
                self.env = crafter.Env(seed=int(self.np_random.integers(2**31)))
            return self.env.reset(), {}

        def step(self, action: Any) -> Any:
            obs, reward, done, info = self.env.step(int(action))
            # Crafter ends an episode by time (10000 steps) or by death (health 0).
            dead = info["inventory"]["health"] <= 0
            return obs, float(reward), bool(done and dead), bool(done and not dead), info

    return Crafter()


def env_fn(env: str) -> Callable[[], Any]:
    """A callable building one env named ``env`` (:data:`ENV_NAMES`), picklable by
    cloudpickle."""
    import gymnasium as gym

    if env == "pong":

        def pong() -> Any:
            import ale_py

            gym.register_envs(ale_py)
            return gym.make("ALE/Pong-v5")

        return pong
    if env == "pong-pre":

        def pong_pre() -> Any:
            import ale_py

            gym.register_envs(ale_py)
            e = gym.make("ALE/Pong-v5", frameskip=1)
            e = gym.wrappers.AtariPreprocessing(e, frame_skip=4, screen_size=84, noop_max=30)
            return gym.wrappers.FrameStackObservation(e, 4)

        return pong_pre
    if env == "nethack":

        def nethack() -> Any:
            import nle  # noqa: F401  (registers the envs)

            return gym.make("NetHackScore-v0")

        return nethack
    if env == "halfcheetah":
        return lambda: gym.make("HalfCheetah-v5")
    if env == "minigrid":

        def minigrid() -> Any:
            import minigrid as mg
            from minigrid.wrappers import ImgObsWrapper

            mg.register_minigrid_envs()
            return ImgObsWrapper(gym.make("MiniGrid-DoorKey-8x8-v0"))

        return minigrid
    if env == "crafter":
        return _crafter_env
    if env == "cartpole":
        return lambda: gym.make("CartPole-v1")
    if env == "rogue-py":
        from rogue_gym.envs import RogueEnv
        from rogue_gym.suites import PAPER_CONFIG

        config = dict(PAPER_CONFIG)
        return lambda: RogueEnv(config_dict=config, max_steps=500, obs="symbol_index")
    if env == "slow":
        return _slow_env
    if env == "text":
        return _text_env
    raise ValueError(f"unknown env {env!r}; known: {', '.join(ENV_NAMES)}")


def run_isolated(cmd: list[str], timeout: float, env: dict[str, str]) -> tuple[Any, str, str]:
    """Run a cell in its own session; on timeout kill the whole session (workers, forkservers
    and all), so nothing it started loads the next cells. Returns (exit code or None, stdout,
    stderr)."""
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        start_new_session=True,
    )
    try:
        out, err = proc.communicate(timeout=timeout)
        code: Any = proc.returncode
    except subprocess.TimeoutExpired:
        code = None
        out, err = "", ""
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    return code, out, err


def run_cells(
    script: str,
    todo: list[dict[str, Any]],
    key: Callable[[dict[str, Any]], tuple[Any, ...]],
    reps: int,
    timeout: float,
    env: dict[str, str],
) -> tuple[dict[Any, list[dict[str, Any]]], dict[Any, str]]:
    """Run every cell ``reps`` times, each in a fresh ``script --cell JSON`` process (see
    :func:`run_isolated`), the order shuffled per repetition, printing each result. Returns
    the results of each cell key (the JSON line each run printed) and the reason of each cell
    that failed or timed out (not run again)."""
    runs: dict[Any, list[dict[str, Any]]] = {}
    failed: dict[Any, str] = {}
    total, done = len(todo) * reps, 0
    for rep in range(reps):
        random.Random(rep).shuffle(todo)
        for cell in todo:
            done += 1
            k = key(cell)
            if k in failed:
                continue
            code, stdout, stderr = run_isolated(
                [sys.executable, script, "--cell", json.dumps(cell)], timeout, env
            )
            if code is None:
                failed[k] = f"timed out after {timeout:.0f} s"
            elif code != 0:
                lines = stderr.strip().splitlines()
                failed[k] = lines[-1][:200] if lines else f"exit code {code}"
            else:
                runs.setdefault(k, []).append(json.loads(stdout.strip().splitlines()[-1]))
            shown = (
                f"{runs[k][-1]['steps_per_s']:>12,.0f} steps/s"
                if k not in failed
                else f"skipped: {failed[k]}"
            )
            print(f"[{done}/{total}] {' '.join(map(str, k)):40s} {shown}", flush=True)
    return runs, failed


def write_results(out: Path, stem: str, markdown: str, data: Any) -> tuple[Path, Path]:
    """Write ``{stem}.md`` (``markdown``) and ``{stem}.json`` (``data``) under ``out`` (made if
    missing); their paths."""
    out.mkdir(parents=True, exist_ok=True)
    md, js = out / f"{stem}.md", out / f"{stem}.json"
    md.write_text(markdown.rstrip("\n") + "\n")
    js.write_text(json.dumps(data, indent=1, default=str) + "\n")
    return md, js


def spin(seconds: float) -> None:
    """Keep the CPU busy for ``seconds``, touching nothing but the clock."""
    t = time.perf_counter()
    while time.perf_counter() - t < seconds:
        pass


def timed_steps(
    vec: Any, actions: list[Any], seconds: float, pause: float = 0.0
) -> tuple[int, float, float]:
    """Sync ``step()`` through ``actions`` in turn for ``seconds`` after ``stats(reset=True)``
    (the vector env is reset and warmed up): ``(calls, wall seconds, paused seconds)``;
    ``vec.stats()`` then covers exactly these calls. ``pause``: spin that long before each
    call (the caller busy with something else, touching nothing of the pool's), counted apart
    from the wall time."""
    vec.stats(reset=True)
    calls, paused, t0 = 0, 0.0, time.perf_counter()
    while time.perf_counter() - t0 - paused < seconds:
        if pause:
            p0 = time.perf_counter()
            spin(pause)
            paused += time.perf_counter() - p0
        vec.step(actions[calls % len(actions)])
        calls += 1
    return calls, time.perf_counter() - t0 - paused, paused


def median_interval(ratios: list[float], draws: int = 2000) -> tuple[float, float]:
    """A 95% bootstrap interval of the median of ``ratios``."""
    rng = random.Random(0)
    meds = sorted(statistics.median(rng.choices(ratios, k=len(ratios))) for _ in range(draws))
    return meds[int(0.025 * draws)], meds[int(0.975 * draws) - 1]
