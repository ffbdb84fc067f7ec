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
    """64 hosted envs with 1 MiB of info room each need about 128 MiB of channels (two
    blocks per worker): an OSError(ENOSPC) at construction, not a SIGBUS restart loop, naming
    the place, its size and free space, the need and the fixes; nothing is left behind."""
    out = _ok(
        _in_small_shm(
            """
            t = time.monotonic()
            try:
                rogue_gym.PoolVectorEnv([Frames] * 64, num_workers=2, info_bytes=1 << 20)
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
    """The async API writes observations into blocks whose pages are not reserved; with
    /dev/shm filled up by someone else, the worker dies of SIGBUS. The call fails at once with
    the numbers (not after a restart loop), and once there is room again a reset recovers."""
    out = _ok(
        _in_small_shm(
            """
            envs = rogue_gym.make_vec(1024, config="paper", num_workers=2, batch_size=512)
            envs.reset(seed=0)
            with open("/dev/shm/filler", "wb") as f:
                try:
                    while True:
                        f.write(bytes(1 << 20))
                except OSError:
                    pass
            t = time.monotonic()
            try:
                envs.async_reset()
                for _ in range(20):
                    out = envs.recv()
                    envs.send(np.zeros(512, np.int64), out[4]["env_id"])
                raise SystemExit("no error")
            except rogue_gym.WorkerCrashedError as err:
                took = time.monotonic() - t
                assert err.signal == 7, err
                assert "out of shared memory" in str(err) and "--shm-size" in str(err), err
            os.unlink("/dev/shm/filler")
            for _ in range(3):  # a second worker's SIGBUS may surface at the next call
                try:
                    envs.reset(seed=0)
                    break
                except rogue_gym.WorkerCrashedError:
                    pass
            obs = envs.step(np.zeros(1024, np.int64))[0]
            assert obs.shape[0] == 1024
            print(f"took {took:.3f} restarts {envs.stats().restarts}")
            envs.close()
            """
        )
    )
    took = float(out.split("took")[1].split()[0])
    restarts = int(out.split("restarts")[1])
    assert took < 1.0 and restarts <= 2
