"""Pools in a small /dev/shm (Docker's, GitHub Actions' and Kubernetes' default is 64 MiB),
where only the workers' channels live (the pool's buffers are process memory): pools whose
batches alone are larger step, one whose channels do not fit fails within 1 s with the
numbers and the fixes, a pool whose extra slots get no memory falls back to two, and a
worker killed by SIGBUS (a page the filesystem could not give) is reported as such once, not
restarted in a loop.

Each case runs as a script in a private mount namespace (``unshare -m``) with a 64 MiB tmpfs
over /dev/shm; where that is not permitted the tests are skipped with the reason."""

from __future__ import annotations

import shutil
import subprocess
import sys
import textwrap

import pytest

SHM_MIB = 64

PRELUDE = """
import errno, os, time
import gymnasium as gym
import numpy as np
import rogue_gym


class Frames(gym.Env):
    # Atari-sized frames: 256 of them are 24.6 MiB a batch.
    observation_space = gym.spaces.Box(0, 255, (210, 160, 3), np.uint8)
    action_space = gym.spaces.Discrete(2)

    def reset(self, seed=None, options=None):
        return np.zeros((210, 160, 3), np.uint8), {}

    def step(self, action):
        return np.full((210, 160, 3), int(action), np.uint8), 0.0, False, False, {}


class WideActions(gym.Env):
    # 256 KiB of actions per env: they travel in the workers' command channels.
    observation_space = gym.spaces.Box(0, 255, (4,), np.uint8)
    action_space = gym.spaces.Box(0, 1, (1 << 16,), np.float32)

    def reset(self, seed=None, options=None):
        return np.zeros(4, np.uint8), {}

    def step(self, action):
        return np.zeros(4, np.uint8), 0.0, False, False, {}


def used_mib():
    st = os.statvfs("/dev/shm")
    return (st.f_blocks - st.f_bavail) * st.f_frsize / 2**20
"""


def _in_small_shm(body: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    """Run ``PRELUDE + body`` with a fresh 64 MiB tmpfs over /dev/shm."""
    if shutil.which("unshare") is None:
        pytest.skip("unshare is not installed")
    probe = subprocess.run(
        ["unshare", "-m", "sh", "-c", f"mount -t tmpfs -o size={SHM_MIB}m tmpfs /dev/shm"],
        capture_output=True,
        text=True,
        timeout=30,
    )
    if probe.returncode != 0:
        pytest.skip(f"no private mount namespace here: {probe.stderr.strip()}")
    script = PRELUDE + textwrap.dedent(body)
    return subprocess.run(
        [
            "unshare",
            "-m",
            "sh",
            "-c",
            f'mount -t tmpfs -o size={SHM_MIB}m tmpfs /dev/shm && exec "$0" -c "$1"',
            sys.executable,
            script,
        ],
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def _ok(done: subprocess.CompletedProcess[str]) -> str:
    assert done.returncode == 0, done.stdout + done.stderr[-3000:]
    return done.stdout


def test_pools_that_fit_step_and_say_what_they_need() -> None:
    """The native game at 4096 envs (a 34 MiB batch, 69 MiB with its two slots) and 256
    hosted Atari-sized envs (24.6 MiB a batch, lent): both step in a 64 MiB /dev/shm, since
    their buffers are process memory (memory files); ``stats().shm_bytes`` is what /dev/shm
    lost (the workers' channels), ``stats().buffer_bytes`` the buffers, twice the batch and
    its rows."""
    out = _ok(
        _in_small_shm(
            """
            for make, batch in (
                (lambda: rogue_gym.make_vec(4096, config="paper", num_workers=2), 4096 * 17 * 16 * 32),
                (lambda: rogue_gym.PoolVectorEnv([Frames] * 256, num_workers=2, copy=True), 256 * 210 * 160 * 3),
            ):
                before = used_mib()
                envs = make()
                envs.reset(seed=0)
                for _ in range(3):
                    envs.step(np.ones(envs.num_envs, np.int64))
                stats = envs.stats()
                need, used = stats.shm_bytes / 2**20, used_mib() - before
                print(f"need {need:.2f} used {used:.2f} buffers {stats.buffer_bytes / batch:.2f}")
                assert used <= need + 0.5, (used, need)
                envs.close()
            """
        )
    )
    lines = [line.split() for line in out.splitlines() if line.startswith("need")]
    assert len(lines) == 2
    for line in lines:
        assert float(line[3]) < 8, "the channels are a small part of /dev/shm's 64 MiB"
        assert 2.0 <= float(line[5]) <= 2.1 + 4 * 4096 / (210 * 160 * 3), "two slots and rows"


def test_a_pool_that_does_not_fit_fails_within_a_second_with_the_fixes() -> None:
    """64 hosted envs whose actions are 256 KiB each need about 160 MiB of channels (a
    worker's command channel holds ten commands of its 32 envs' actions): an OSError(ENOSPC)
    at construction, not a SIGBUS restart loop, naming the place, its size and free space, the
    need and the fixes; nothing is left behind."""
    out = _ok(
        _in_small_shm(
            """
            t = time.monotonic()
            try:
                rogue_gym.PoolVectorEnv([WideActions] * 64, num_workers=2)
                raise SystemExit("the pool was built")
            except OSError as err:
                took = time.monotonic() - t
                assert err.errno == errno.ENOSPC, err
                msg = str(err)
                for part in ("/dev/shm", "free", "64.0 MiB in all", "needs", "--shm-size", "--ipc=host", "fewer envs", "rogue_gym.doctor"):
                    assert part in msg, (part, msg)
                print(f"took {took:.3f}")
            assert used_mib() < 1, os.listdir("/dev/shm")
            """
        )
    )
    took = float(out.split("took")[1])
    assert took < 1.0


def test_a_pool_asked_for_more_slots_than_memory_allows_falls_back_to_two(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """When the buffers of the slots asked for cannot get their pages (an OSError(ENOMEM):
    the machine's or the container's memory limit), the pool is built with the default two
    and steps; with two too big, the error is the caller's."""
    import errno

    import gymnasium as gym
    import numpy as np
    import rogue_gym
    from rogue_gym import _native

    real = _native.Pool
    asked: list[object] = []

    def limited(settings_json: str, command: list[str]) -> object:
        slots = __import__("json").loads(settings_json).get("batch_slots")
        asked.append(slots)
        if slots is not None and slots > 2:
            raise OSError(errno.ENOMEM, "cannot reserve the pool's batch buffer")
        return real(settings_json, command)

    limited.close = real.close  # type: ignore[attr-defined]  # what the finalizer calls
    monkeypatch.setattr(_native, "Pool", limited)
    env_fn = lambda: gym.make("CartPole-v1")  # noqa: E731
    envs = rogue_gym.PoolVectorEnv([env_fn] * 4, num_workers=2, batch_slots=4, copy=True)
    try:
        envs.reset(seed=0)
        envs.step(np.zeros(4, np.int64))
        assert asked == [4, None] and len(envs._core.slots) == 2
    finally:
        envs.close()


def test_a_worker_killed_by_sigbus_is_reported_once_and_the_pool_recovers() -> None:
    """A worker killed by SIGBUS (a page of /dev/shm the filesystem could not give: every
    answer's rows are in the pool's own buffers, so only a channel's page, or an env's own
    shared memory, can be refused) fails the call at once with the numbers and the fixes, not
    after a restart loop; once the cause is gone a reset recovers. The envs here raise the
    signal in their worker while a marker file exists."""
    out = _ok(
        _in_small_shm(
            """
            import signal

            MARK = "/dev/shm/rg-test-sigbus"

            class Bus(gym.Env):
                observation_space = gym.spaces.Box(0, 255, (4,), np.uint8)
                action_space = gym.spaces.Discrete(2)

                def reset(self, seed=None, options=None):
                    return np.zeros(4, np.uint8), {}

                def step(self, action):
                    if os.path.exists(MARK):
                        os.kill(os.getpid(), signal.SIGBUS)
                    return np.zeros(4, np.uint8), 0.0, False, False, {}

            envs = rogue_gym.PoolVectorEnv([Bus] * 8, num_workers=2, batch_size=4)
            envs.reset(seed=0)
            open(MARK, "w").close()
            t = time.monotonic()
            try:
                envs.async_reset()
                for _ in range(20):
                    out = envs.recv()
                    envs.send(np.zeros(4, np.int64), out[4]["env_id"])
                raise SystemExit("no error")
            except rogue_gym.WorkerCrashedError as err:
                took = time.monotonic() - t
                assert err.signal == 7, err
                assert "out of shared memory" in str(err) and "--shm-size" in str(err), err
            os.unlink(MARK)
            for _ in range(3):  # a second worker's SIGBUS may surface at the next call
                try:
                    envs.reset(seed=0)
                    break
                except rogue_gym.WorkerCrashedError:
                    pass
            obs = envs.step(np.zeros(8, np.int64))[0]
            assert obs.shape[0] == 8
            print(f"took {took:.3f} restarts {envs.stats().restarts}")
            envs.close()
            """
        )
    )
    took = float(out.split("took")[1].split()[0])
    restarts = int(out.split("restarts")[1])
    assert took < 1.0 and restarts <= 2


def test_a_running_async_pool_maps_what_it_said_it_needs() -> None:
    """What a pool maps in /dev/shm (its iceoryx2 files, each in whole pages, as tmpfs charges
    them) is exactly ``stats().shm_bytes``, the need checked before the pool was made: for
    sync and async pools, small and wide actions, even and uneven blocks, envs on threads."""
    import glob
    import os

    import gymnasium as gym
    import numpy as np
    import rogue_gym

    class Wide(gym.Env):
        def __init__(self, n: int) -> None:
            self.observation_space = gym.spaces.Box(0, 255, (4,), np.uint8)
            self.action_space = gym.spaces.Box(0, 1, (n,), np.float32)

        def reset(self, seed=None, options=None):  # type: ignore[no-untyped-def]
            return np.zeros(4, np.uint8), {}

        def step(self, action):  # type: ignore[no-untyped-def]
            return np.zeros(4, np.uint8), 0.0, False, False, {}

    for width, n, workers, extra in (
        (1, 8, 2, {}),
        (4096, 33, 5, {}),
        (100, 16, 4, {"env_concurrency": 2}),
    ):
        envs = rogue_gym.PoolVectorEnv(
            [lambda w=width: Wide(w)] * n, num_workers=workers, batch_size=n // 2, **extra
        )
        try:
            envs.async_reset()
            for _ in range(6):
                got = envs.recv()
                ids = got[4]["env_id"]
                envs.send(np.zeros((len(ids), width), np.float32), ids)
            files = glob.glob(f"/dev/shm/{envs._core.name}*")
            mapped = sum(-(-os.stat(f).st_size // 4096) * 4096 for f in files)
            assert mapped == envs.stats().shm_bytes, (width, n, workers, mapped)
        finally:
            envs.close()
