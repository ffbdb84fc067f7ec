"""Small gymnasium envs for the hosting tests: nested spaces of every supported kind, and envs
that fail on purpose. Workers import this module by name (it is on the caller's sys.path)."""

from __future__ import annotations

import os
import random
import time
from typing import Any, Optional

import gymnasium as gym
import numpy as np
from gymnasium import spaces


class NestedEnv(gym.Env):
    """Dict/Tuple observations and actions with Box (float64, float16, uint8), Discrete (with a
    start), MultiDiscrete and MultiBinary leaves. Each observation echoes the last action and
    the generator's draws, so a test sees both that actions arrive intact and that seeding
    follows gymnasium's convention. Episodes last 3 to 7 steps; every step has an info."""

    observation_space = spaces.Dict(
        {
            "pos": spaces.Box(-10.0, 10.0, (2,), np.float64),
            "grid": spaces.Box(0, 255, (3, 4), np.uint8),
            "flags": spaces.MultiBinary(3),
            "nest": spaces.Tuple(
                (
                    spaces.Discrete(5, start=2),
                    spaces.MultiDiscrete([3, 4]),
                    spaces.Box(-1.0, 1.0, (2,), np.float16),
                )
            ),
        }
    )
    action_space = spaces.Dict(
        {
            "move": spaces.Box(-1.0, 1.0, (2,), np.float64),
            "pick": spaces.Discrete(3, start=1),
            "multi": spaces.MultiDiscrete([2, 5]),
        }
    )

    def __init__(self) -> None:
        self.t = 0
        self.length = 0
        self.last: Any = None
        self.options: Optional[dict] = None

    def render(self) -> np.ndarray:
        return np.full((2, 2, 3), self.t, np.uint8)

    def scaled_t(self, factor: int, *, offset: int = 0) -> int:
        if factor < 0:
            raise SpecialError("negative factor")
        return self.t * factor + offset

    def _obs(self) -> dict[str, Any]:
        move = np.zeros(2) if self.last is None else np.asarray(self.last["move"], np.float64)
        pick = 2 if self.last is None else int(self.last["pick"]) + 1
        multi = np.zeros(2, np.int64) if self.last is None else np.asarray(self.last["multi"])
        grid = self.np_random.integers(0, 256, (3, 4), dtype=np.uint8)
        return {
            "pos": move * 3.0 + self.t,
            "grid": grid,
            "flags": np.array([self.t % 2, 1, 0], np.int8),
            "nest": (np.int64(pick), multi % np.array([3, 4]), np.full(2, 0.5, np.float16)),
        }

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> Any:
        super().reset(seed=seed)
        self.options = options
        self.t = 0
        self.last = None
        self.length = int(self.np_random.integers(3, 8))
        return self._obs(), {"start": self.length}

    def step(self, action: Any) -> Any:
        assert self.action_space.contains(action), action
        self.t += 1
        self.last = action
        reward = float(action["pick"]) + float(np.sum(action["move"]))
        return self._obs(), reward, self.t >= self.length, False, {"t": self.t}


class RaisingEnv(gym.Env):
    """CartPole-like spaces; raises ``SpecialError`` in ``reset`` when seeded with 999, and in
    ``step`` on action 1 once ``fail_after`` steps have passed."""

    observation_space = spaces.Box(-1.0, 1.0, (4,), np.float32)
    action_space = spaces.Discrete(2)

    def __init__(self, fail_after: int = 3) -> None:
        self.fail_after = fail_after
        self.t = 0

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> Any:
        super().reset(seed=seed)
        if seed == 999:
            raise SpecialError("reset refused seed 999")
        self.t = 0
        return np.zeros(4, np.float32), {}

    def step(self, action: Any) -> Any:
        self.t += 1
        if action == 1 and self.t > self.fail_after:
            raise SpecialError(f"step {self.t} refused action 1")
        return np.full(4, self.t / 100, np.float32), 1.0, False, self.t >= 50, {}


class SpecialError(ValueError):
    """A user-defined exception, to check that the type survives the trip."""


class InfoEnv(RaisingEnv):
    """Infos of every kind on every step, drawn from the env's generator: Python and numpy
    scalars (NaN included), arrays, nested and empty dicts, a key only some steps have, a key
    that is an int at reset and a float on steps, and now and then values that only pickle (a
    string, a numpy bool). Episodes end at random or after 30 steps."""

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> Any:
        super().reset(seed=seed)
        return np.zeros(4, np.float32), {"count": 0, "lives": np.int16(3)}

    def step(self, action: Any) -> Any:
        self.t += 1
        r = self.np_random
        info: dict[str, Any] = {
            "count": float(self.t),
            "x": float(r.normal()),
            "f32": np.float32(r.normal()),
            "u64": np.uint64(2**63 + self.t),
            "flag": bool(self.t % 2),
            "maybe_nan": float("nan") if self.t % 5 == 0 else 0.5,
            "pos": r.normal(size=3).astype(np.float32),
            "mask": r.integers(0, 2, (2, 2)).astype(bool),
            "inventory": {"wood": int(r.integers(5)), "stone": np.int32(self.t)},
            "achievements": {},
        }
        if self.t % 3 == 0:
            info["sometimes"] = np.int8(self.t)
        if self.t % 7 == 0:
            info["note"] = f"step {self.t}"
        if self.t % 11 == 0:
            info["np_bool"] = np.bool_(True)
        obs = np.full(4, self.t / 100, np.float32)
        return obs, float(action), bool(r.random() < 0.1), self.t >= 30, info


class FlatInfoEnv(RaisingEnv):
    """Flat per-step infos of every scalar kind a worker packs itself (Python and numpy floats,
    ints of every width, bools, NaN); on some steps a value's type changes or the keys come in
    another order (each a new layout). Observations are now and then views (strided, or at an
    offset), and rewards and flags are numpy scalars. Episodes end at random or after 30
    steps."""

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> Any:
        super().reset(seed=seed)
        return np.zeros(4, np.float32), {"lives": 3}

    def step(self, action: Any) -> Any:
        self.t += 1
        r, t = self.np_random, self.t
        info: dict[str, Any] = {
            "x": float(r.normal()),
            "x64": np.float64(r.normal()),
            "x32": np.float32(r.normal()),
            "n": int(r.integers(-(2**40), 2**40)),
            "i64": np.int64(r.integers(-(2**62), 2**62)),
            "u64": np.uint64(2**63 + t),
            "i32": np.int32(-t),
            "u32": np.uint32(t),
            "i16": np.int16(-t),
            "u16": np.uint16(t),
            "i8": np.int8(-t),
            "u8": np.uint8(t),
            "flag": bool(t % 2),
            "nan": float("nan") if t % 5 == 0 else 0.5,
        }
        if t % 4 == 0:
            info["x"] = np.float32(info["x"])  # the same keys, another type
        if t % 6 == 0:
            info = dict(reversed(info.items()))  # the same keys, another order
        obs = np.full(4, t / 100, np.float32)
        if t % 3 == 0:
            obs = np.full(8, t / 100, np.float32)[::2]  # not contiguous
        elif t % 7 == 0:
            obs = np.full(6, t / 100, np.float32)[2:]  # a view at an offset
        terminated = np.bool_(r.random() < 0.05)
        return obs, np.float32(r.normal()), terminated, t >= 30, info


class BadStepEnv(RaisingEnv):
    """An env whose ``step`` breaks the gymnasium API on action 1: four values (the old gym
    API) for env 0 of a seed, a reward that is not a number for the others."""

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> Any:
        self.old_api = seed == 0
        return super().reset(seed=seed, options=options)

    def step(self, action: Any) -> Any:
        obs, reward, terminated, truncated, info = super().step(0)
        if action == 1:
            if self.old_api:
                return obs, reward, terminated or truncated, info
            return obs, "1.0", terminated, truncated, info
        return obs, reward, terminated, truncated, info


class GrowingInfoEnv(RaisingEnv):
    """Infos that outgrow the pool's default room per env (4096 bytes) as an episode goes on,
    some envs sooner than others: an array of ``300 t`` int64 values, on some steps of some
    envs one more array of 700 values (typed rows), and on even steps a string of ``100 t``
    or ``100 t + 5000`` characters (pickled)."""

    def step(self, action: Any) -> Any:
        self.t += 1
        big = bool(self.np_random.integers(2))
        info: dict[str, Any] = {"blob": np.arange(300 * self.t, dtype=np.int64)}
        if self.t % 2 == 0:
            info["log"] = "x" * (100 * self.t + 5000 * big)
        elif big:
            info["pad"] = np.ones(700, np.int64)
        return np.full(4, self.t / 100, np.float32), 1.0, False, self.t >= 25, info


class NoteEnv(gym.Env):
    """Leaves of no fixed size beside fixed ones, both ways. The observation: a Box, a Text
    that echoes the last action's text and grows past the pool's default info room (4096
    bytes) as an episode goes on, and a Sequence of random length; the action: a Discrete and
    a Text. The reward tells both action leaves arrived; episodes end after 6 steps."""

    observation_space = spaces.Dict(
        {
            "pos": spaces.Box(0.0, 100.0, (2,), np.float32),
            "note": spaces.Text(20000, min_length=0),
            "path": spaces.Sequence(spaces.Discrete(5)),
        }
    )
    action_space = spaces.Dict({"move": spaces.Discrete(3), "say": spaces.Text(8)})

    def __init__(self) -> None:
        self.t = 0
        self.said = ""

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> Any:
        super().reset(seed=seed)
        self.t, self.said = 0, ""
        return self._obs(), {"first": True}  # an info of its own beside the dynamic values

    def _obs(self) -> dict[str, Any]:
        k = int(self.np_random.integers(0, 5))
        note = self.said + "x" * (1000 * self.t)
        return {"pos": np.array([self.t, k], np.float32), "note": note, "path": tuple(range(k))}

    def step(self, action: Any) -> Any:
        assert action in self.action_space, action
        self.t += 1
        self.said = action["say"]
        reward = float(len(action["say"]) + 10 * int(action["move"]))
        return self._obs(), reward, self.t >= 6, False, {"t": self.t}


class TextEnv(gym.Env):
    """A Text observation and a Text action: the observation is the last action's text."""

    observation_space = spaces.Text(8)
    action_space = spaces.Text(8)

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> Any:
        super().reset(seed=seed)
        return "start", {}

    def step(self, action: Any) -> Any:
        return action, 0.0, False, False, {}


def fails_in_workers(creator: int) -> gym.Env:
    """An env that builds in the creating process but raises in any other (a worker)."""
    if os.getpid() != creator:
        raise SpecialError("no env in a worker")
    return RaisingEnv()


class BoundedEnv(RaisingEnv):
    """RaisingEnv with an observation bound of its own (``high``): envs whose observation
    spaces differ only in their bounds."""

    def __init__(self, high: float) -> None:
        super().__init__()
        self.observation_space = spaces.Box(-high, high, (4,), np.float32)


class Word(spaces.Space):
    """A custom space: any string."""

    def contains(self, x: Any) -> bool:
        return isinstance(x, str)

    def sample(self, mask: Any = None, probability: Any = None) -> str:
        return "w"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Word)


class WordEnv(RaisingEnv):
    """A custom observation space (:class:`Word`): the observation counts the steps in words."""

    observation_space = Word()  # type: ignore[assignment]

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> Any:
        super().reset(seed=seed)
        return "reset", {}

    def step(self, action: Any) -> Any:
        self.t += 1
        return f"step {self.t}", 0.0, False, False, {}


class SleepEnv(gym.Env):
    """An env whose step waits ``delay`` seconds and uses no CPU: ``k`` workers step ``k``
    of them at once whatever the core count."""

    observation_space = spaces.Box(0.0, 1.0, (1,), np.float32)
    action_space = spaces.Discrete(2)

    def __init__(self, delay: float = 0.001) -> None:
        self.delay = delay

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> Any:
        super().reset(seed=seed)
        return np.zeros(1, np.float32), {}

    def step(self, action: Any) -> Any:
        time.sleep(self.delay)
        return np.zeros(1, np.float32), 0.0, False, False, {}


class SlowResetEnv(gym.Env):
    """TorchRL's "fast step, slow reset" env: ``step_s`` a step, ``reset_s`` a reset, an
    episode end every ``every`` steps; its waits use no CPU."""

    observation_space = spaces.Box(0.0, 1.0, (1,), np.float32)
    action_space = spaces.Discrete(2)

    def __init__(self, step_s: float = 0.001, reset_s: float = 0.05, every: int = 20) -> None:
        self.step_s, self.reset_s, self.every, self.t = step_s, reset_s, every, 0

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> Any:
        super().reset(seed=seed)
        time.sleep(self.reset_s)
        self.t = 0
        return np.zeros(1, np.float32), {}

    def step(self, action: Any) -> Any:
        time.sleep(self.step_s)
        self.t += 1
        return np.zeros(1, np.float32), 1.0, self.t >= self.every, False, {}


def slow_in_workers(creator: int, delay: float) -> gym.Env:
    """CartPole, built at once in the creating process and after ``delay`` seconds in any other
    (a worker): a pool of it takes that long to start."""
    if os.getpid() != creator:
        time.sleep(delay)
    return gym.make("CartPole-v1")


class LeakyEnv(gym.Env):
    """Keeps ``leak_mib`` MiB more at every step (a simulator that leaks); observations count
    the steps of the episode."""

    observation_space = spaces.Box(0.0, 1e9, (1,), np.float32)
    action_space = spaces.Discrete(2)

    def __init__(self, leak_mib: float = 1.0, refuse_if: str = "", build_s: float = 0.0) -> None:
        if refuse_if and os.path.exists(refuse_if):
            raise RuntimeError(f"refusing to start: {refuse_if} exists")
        time.sleep(build_s)  # a slow simulator start-up
        self.leak = int(leak_mib * (1 << 20))
        self.hoard: list[np.ndarray] = []
        self.t = 0

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> Any:
        super().reset(seed=seed)
        self.t = 0
        return np.zeros(1, np.float32), {}

    def step(self, action: Any) -> Any:
        if self.leak:
            self.hoard.append(np.ones(self.leak, np.uint8))  # touched: resident
        self.t += 1
        return np.full(1, self.t, np.float32), 1.0, False, False, {}


class CountingEnv(gym.Env):
    """CartPole-like spaces and an env method with a side effect: ``bump()`` counts its own
    calls and returns the count, so a test sees how often an env operation ran on each env."""

    observation_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
    action_space = spaces.Discrete(2)

    def __init__(self) -> None:
        self.bumps = 0

    def bump(self) -> int:
        self.bumps += 1
        return self.bumps

    def reset(self, *, seed: Any = None, options: Any = None) -> Any:
        super().reset(seed=seed)
        return np.zeros(2, np.float32), {}

    def step(self, action: Any) -> Any:
        return np.zeros(2, np.float32), 0.0, False, False, {}


class ModulesEnv(CountingEnv):
    """An env that notes which ``rogue_gym`` modules its process has loaded when it is made
    (in a pool: the worker's)."""

    def __init__(self) -> None:
        super().__init__()
        import sys

        self.modules = sorted(m for m in sys.modules if m.split(".")[0] == "rogue_gym")


def _batch_mappings() -> list[tuple[int, int]]:
    """This process's mappings of a pool's batch buffer, as ``(start, end)`` addresses."""
    out = []
    with open("/proc/self/maps") as f:
        for line in f:
            if "memfd:rogue-gym-batch" in line:
                start, end = (int(x, 16) for x in line.split()[0].split("-"))
                out.append((start, end))
    return out


class ScribblingEnv(RaisingEnv):
    """CartPole-like spaces; at its ``at``-th step it writes ``byte`` over every byte of its
    worker's mapping of the pool's batch buffer (as a corrupting C extension could), once."""

    def __init__(self, at: int = 5, byte: int = 0xFF) -> None:
        super().__init__(fail_after=10**9)
        self.at, self.byte = at, byte

    def step(self, action: Any) -> Any:
        out = super().step(action)
        if self.t == self.at:
            import ctypes

            for start, end in _batch_mappings():
                ctypes.memset(start, self.byte, end - start)
        return out


class JitterEnv(gym.Env):
    """Waits a random 0-3 ms at each step and reset (so that envs on threads finish in a
    different order every time), and plays a trajectory of its own seed: observations and
    rewards from its generator, an episode end at random."""

    observation_space = spaces.Box(0.0, 1.0, (3,), np.float32)
    action_space = spaces.Discrete(3)

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> Any:
        super().reset(seed=seed)
        time.sleep(random.random() * 0.003)
        return self.np_random.random(3).astype(np.float32), {
            "start": int(self.np_random.integers(100))
        }

    def step(self, action: Any) -> Any:
        time.sleep(random.random() * 0.003)
        r = self.np_random
        obs = r.random(3).astype(np.float32)
        return (
            obs,
            float(r.random() + int(action)),
            bool(r.random() < 0.1),
            False,
            {"x": float(r.random())},
        )


class FailingSleeper(SleepEnv):
    """A ``SleepEnv`` that raises ``SpecialError`` at its ``fail_at``-th step when its seed is
    ``fail_seed`` (one env of a pool fails; its mates go on sleeping)."""

    def __init__(self, delay: float = 0.01, fail_at: int = 3, fail_seed: int = 2) -> None:
        super().__init__(delay)
        self.fail_at, self.fail_seed, self.t, self.seed_ = fail_at, fail_seed, 0, None

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> Any:
        if seed is not None:
            self.seed_ = seed
        self.t = 0
        return super().reset(seed=seed, options=options)

    def step(self, action: Any) -> Any:
        self.t += 1
        if self.seed_ == self.fail_seed and self.t == self.fail_at:
            raise SpecialError(f"env of seed {self.seed_} failed at step {self.t}")
        return super().step(action)
