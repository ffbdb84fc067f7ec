"""Registry parity: every id that ``gym.make`` can make in the process that builds a pool can be
made in its workers (never forked), however it was registered: by importing a package, by
``gym.register`` in ``__main__`` (a script run as a subprocess) or in a module, with an entry
point given as a string or as a callable; through ``make_vec``, ``PoolVectorEnv``,
``from_vector_env`` and the SB3 class."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import rogue_gym
from gymnasium.vector import SyncVectorEnv
from rogue_gym import PoolVectorEnv

#: A package that registers its env when imported, as highway-env or popgym do.
PACKAGE = {
    "__init__.py": """
        import gymnasium as gym
        gym.register("RgTestPkg-v0", entry_point="rgtestpkg.envs:CounterEnv", max_episode_steps=7)
    """,
    "envs.py": """
        import gymnasium as gym
        import numpy as np

        class CounterEnv(gym.Env):
            observation_space = gym.spaces.Box(-1e9, 1e9, (2,), np.float64)
            action_space = gym.spaces.Discrete(3)

            def reset(self, seed=None, options=None):
                super().reset(seed=seed)
                self.t = 0
                return np.array([self.np_random.random(), 0.0]), {}

            def step(self, action):
                self.t += 1
                return np.array([self.np_random.random(), self.t * int(action)]), 1.0, False, False, {}
    """,
}


def _write_package(root: Path) -> None:
    (root / "rgtestpkg").mkdir()
    for name, text in PACKAGE.items():
        (root / "rgtestpkg" / name).write_text(textwrap.dedent(text))


def _same_games(ours: gym.vector.VectorEnv, ref: gym.vector.VectorEnv, steps: int = 20) -> None:
    o1, _ = ours.reset(seed=3)
    o2, _ = ref.reset(seed=3)
    np.testing.assert_array_equal(o1, o2)
    rng = np.random.default_rng(0)
    for _ in range(steps):
        actions = rng.integers(0, 3, ours.num_envs)
        r1, r2 = ours.step(actions), ref.step(actions)
        for x, y in zip(r1[:4], r2[:4]):
            np.testing.assert_array_equal(x, y)


def test_a_package_registration_reaches_the_workers(tmp_path, monkeypatch) -> None:
    """The package is imported here only; the workers have its ids without importing it, and
    play the same games as SyncVectorEnv (the spec's max_episode_steps included)."""
    _write_package(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    import rgtestpkg  # noqa: F401  # registers RgTestPkg-v0, as a user's import would

    try:
        ours = rogue_gym.make_vec("RgTestPkg-v0", 4, num_workers=2)
        ref = SyncVectorEnv([lambda: gym.make("RgTestPkg-v0")] * 4)
        try:
            _same_games(ours, ref)
        finally:
            ours.close()
            ref.close()
        vec = PoolVectorEnv.from_vector_env(
            lambda n: gym.make_vec("RgTestPkg-v0", n, vectorization_mode="sync"), 4, num_workers=2
        )
        try:
            assert vec.reset(seed=0)[0].shape == (4, 2)
        finally:
            vec.close()
    finally:
        del gym.registry["RgTestPkg-v0"]
        sys.modules.pop("rgtestpkg", None)
        sys.modules.pop("rgtestpkg.envs", None)


def test_a_callable_entry_point_registered_in_a_module_reaches_the_workers() -> None:
    """A closure as the entry point (pickled by value) and a module's class (by reference)."""
    from hosted_envs import BoundedEnv

    bound = 5.0
    gym.register("RgTestClosure-v0", entry_point=lambda **kw: BoundedEnv(bound))
    gym.register("RgTestClass-v0", entry_point=BoundedEnv, kwargs={"high": 2.0})
    try:
        for env_id in ("RgTestClosure-v0", "RgTestClass-v0"):
            ours = PoolVectorEnv([lambda env_id=env_id: gym.make(env_id)] * 3, num_workers=3)
            ref = SyncVectorEnv([lambda env_id=env_id: gym.make(env_id)] * 3)
            try:
                o1, _ = ours.reset(seed=1)
                o2, _ = ref.reset(seed=1)
                np.testing.assert_array_equal(o1, o2)
                actions = np.zeros(3, np.int64)
                for x, y in zip(ours.step(actions)[:4], ref.step(actions)[:4]):
                    np.testing.assert_array_equal(x, y)
            finally:
                ours.close()
                ref.close()
    finally:
        del gym.registry["RgTestClosure-v0"]
        del gym.registry["RgTestClass-v0"]


MAIN_SCRIPT = """
import gymnasium as gym
import numpy as np
import rogue_gym
from gymnasium.vector import SyncVectorEnv


class MainEnv(gym.Env):
    observation_space = gym.spaces.Box(-10, 10, (3,), np.float32)
    action_space = gym.spaces.Discrete(2)

    def reset(self, seed=None, options=None):
        super().reset(seed=seed)
        return self.np_random.random(3).astype(np.float32), {}

    def step(self, action):
        obs = self.np_random.random(3).astype(np.float32) + int(action)
        return obs, 1.0, False, False, {}


gym.register("RgMainCallable-v0", entry_point=MainEnv, max_episode_steps=4)
gym.register("RgMainString-v0", entry_point="__main__:MainEnv", max_episode_steps=4)

if __name__ == "__main__":
    from rogue_gym.sb3 import PoolVecEnv

    for env_id in ("RgMainCallable-v0", "RgMainString-v0"):
        builds = {
            "make_vec": lambda: rogue_gym.make_vec(env_id, 4, num_workers=2),
            "PoolVectorEnv": lambda: rogue_gym.PoolVectorEnv(
                [lambda: gym.make(env_id)] * 4, num_workers=2
            ),
        }
        for how, build in builds.items():
            ours, ref = build(), SyncVectorEnv([lambda: gym.make(env_id)] * 4)
            o1, _ = ours.reset(seed=5)
            o2, _ = ref.reset(seed=5)
            assert np.array_equal(o1, o2), (env_id, how)
            for t in range(6):
                a = np.array([t % 2] * 4)
                for x, y in zip(ours.step(a)[:4], ref.step(a)[:4]):
                    assert np.array_equal(x, y), (env_id, how, t)
            ours.close()
            ref.close()
            print("ok", env_id, how)
        sb3 = PoolVecEnv([lambda: gym.make(env_id)] * 2, num_workers=2)
        sb3.seed(0)
        assert sb3.reset().shape == (2, 3)
        sb3.close()
        print("ok", env_id, "sb3")
"""


def test_a_main_registration_reaches_the_workers(tmp_path) -> None:
    """``gym.register`` in a script's ``__main__``, with a class and with a
    ``"__main__:Class"`` string, run as the script a user runs."""
    pytest.importorskip("stable_baselines3")
    script = tmp_path / "train.py"
    script.write_text(MAIN_SCRIPT)
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=180, cwd=tmp_path
    )
    assert done.returncode == 0, done.stderr[-3000:]
    for env_id in ("RgMainCallable-v0", "RgMainString-v0"):
        for how in ("make_vec", "PoolVectorEnv", "sb3"):
            assert f"ok {env_id} {how}" in done.stdout


def test_an_id_a_worker_cannot_make_names_it_and_what_the_worker_tried() -> None:
    """Env 1's id exists nowhere: construction fails with gymnasium's error naming the id, and
    a note on what the worker did with the caller's registry."""
    fns = [lambda: gym.make("CartPole-v1"), lambda: gym.make("RgNowhere-v0")]
    with pytest.raises(gym.error.NameNotFound, match="RgNowhere") as info:
        PoolVectorEnv(fns, num_workers=2)
    notes = "\n".join(getattr(info.value, "__notes__", []))
    assert "installed the caller's gymnasium registry" in notes
    assert "register it" in notes and "env 1" in notes
