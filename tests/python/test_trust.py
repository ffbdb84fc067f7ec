"""What the caller trusts of its workers (docs/security.md, "What a worker can and cannot
do"): every value a worker writes into shared memory is checked before it is used, a
misbehaving worker is named (or restarted, per the failure policy), the pool's buffer cannot
be resized by anyone, and ``reset()`` recovers. The misdeeds come from the pool's test hook
(``sabotage``: one worker writes one bad value on cue) or from an env that scribbles over its
worker's memory as a corrupting C extension would."""

from __future__ import annotations

import os
import subprocess
import sys
from typing import Any

import numpy as np
import pytest
import rogue_gym
from rogue_gym import CorruptInfoError, WorkerCrashedError
from rogue_gym.kinds.hosted import HostedKind

from conftest import pool_files
from hosted_envs import InfoEnv, RaisingEnv, ScribblingEnv


def _sabotage(monkeypatch: pytest.MonkeyPatch, worker: int, at: int, **what: Any) -> None:
    """Pools made from now on have worker ``worker`` commit ``what`` in its ``at``-th reset
    or step (the pool's own test hook; no public setting reaches it)."""
    settings = HostedKind.pool_settings

    def with_sabotage(self: HostedKind) -> dict[str, Any]:
        return {**settings(self), "sabotage": {"worker": worker, "at": at, "what": what}}

    monkeypatch.setattr(HostedKind, "pool_settings", with_sabotage)


def _batch_fds() -> list[str]:
    """This process's descriptors of pool batch buffers."""
    out = []
    for fd in os.listdir("/proc/self/fd"):
        try:
            if "memfd:rogue-gym-batch" in os.readlink(f"/proc/self/fd/{fd}"):
                out.append(fd)
        except FileNotFoundError:  # the listing's own descriptor, closed by now
            pass
    return out


def _closed_clean(envs: Any) -> None:
    name = envs._core.name
    envs.close()
    assert pool_files(name) == []


GARBAGE = {
    "a pickle that is none": b"\x80\x05\x95garbage that is no pickle at all",
    "a typed row of no layout": b"RGi1\x01\x00\x00\x00"
    + b"\xff" * 8
    + b"\x7f\xff\xff\xff"
    + b"\x00" * 40,
    "a typed row with a huge structure": b"RGi1\x01\x00\x00\x00"
    + bytes(8)
    + b"\xff\xff\xff\xff"
    + bytes(4),
    "random bytes": bytes(np.random.default_rng(0).integers(0, 256, 200, np.uint8)),
}


@pytest.mark.parametrize("garbage", list(GARBAGE), ids=list(GARBAGE))
def test_info_bytes_that_do_not_decode_name_the_env_and_worker(
    monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str], garbage: str
) -> None:
    _sabotage(monkeypatch, 1, 3, kind="info_bytes", bytes=list(GARBAGE[garbage]))
    envs = rogue_gym.PoolVectorEnv([InfoEnv] * 4, num_workers=2)
    try:
        envs.reset(seed=0)
        envs.step(np.zeros(4, np.int64))
        with pytest.raises(CorruptInfoError) as raised:
            envs.step(np.zeros(4, np.int64))
        err = raised.value
        assert (err.env, err.worker, err.pid) == (2, 1, envs.worker_pids[1])
        assert err.__cause__ is not None
        assert "env 2 (worker 1" in str(err) and type(err.__cause__).__name__ in str(err)
        envs.reset(seed=1)
        envs.step(np.zeros(4, np.int64))
    finally:
        _closed_clean(envs)
    assert "SystemError" not in capfd.readouterr().err


def test_flag_bytes_that_are_no_bool_are_the_workers_fault(monkeypatch: pytest.MonkeyPatch) -> None:
    """Under ``raise`` the step fails naming worker 1 and the byte; under ``restart`` its envs
    come back restarted; the flags a user gets are 0 or 1 either way."""
    _sabotage(monkeypatch, 1, 3, kind="flag_byte", byte=0x80)
    envs = rogue_gym.PoolVectorEnv([RaisingEnv] * 4, num_workers=2, on_worker_failure="raise")
    try:
        envs.reset(seed=0)
        envs.step(np.zeros(4, np.int64))
        with pytest.raises(WorkerCrashedError, match=r"worker 1.*flag byte 128") as raised:
            envs.step(np.zeros(4, np.int64))
        assert raised.value.worker == 1 and raised.value.envs == (2, 3)
        envs.reset(seed=0)
        envs.step(np.zeros(4, np.int64))
    finally:
        _closed_clean(envs)
    envs = rogue_gym.PoolVectorEnv([RaisingEnv] * 4, num_workers=2)
    try:
        envs.reset(seed=0)
        envs.step(np.zeros(4, np.int64))
        _, _, terminated, truncated, infos = envs.step(np.zeros(4, np.int64))
        assert infos["worker_restarted"].tolist() == [False, False, True, True]
        for flags in (terminated, truncated):
            assert flags.dtype == np.bool_ and flags.view(np.uint8).max() <= 1
    finally:
        _closed_clean(envs)


def test_a_reset_mask_is_read_as_bytes(make_vec: Any) -> None:
    """A bool array may hold any byte: every nonzero one masks its env, never read as a Rust
    ``bool``."""
    envs = make_vec(4)
    envs.reset(seed=0)
    envs.step(np.zeros(4, np.int64))
    mask = np.frombuffer(bytes([0, 2, 255, 1]), np.bool_)
    _, infos = envs.reset(options={"reset_mask": mask})
    assert infos["_seed"].tolist() == [False, True, True, True]
    assert infos["episode_index"].tolist() == [0, 1, 1, 1]


def test_no_process_can_resize_the_pools_buffer() -> None:
    """The caller's own descriptor, or any process of the user through ``/proc``: the buffer
    is sealed. (A file in /dev/shm could be truncated, and the caller would die of SIGBUS.)"""
    envs = rogue_gym.make_vec(4, config=rogue_gym.PAPER_CONFIG, num_workers=2, seed=0)
    try:
        envs.reset(seed=0)
        fds = _batch_fds()
        assert fds, "the batch buffer is a memory file of this process"
        path = f"/proc/{os.getpid()}/fd/{fds[0]}"
        size = os.stat(path).st_size
        for attempt in (0, size // 2, size * 2):
            with pytest.raises(PermissionError):
                os.truncate(path, attempt)
        done = subprocess.run(
            [sys.executable, "-c", f"import os; os.truncate({path!r}, 0)"],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert done.returncode != 0 and "PermissionError" in done.stderr, done.stderr
        assert os.stat(path).st_size == size
        for _ in range(5):
            envs.step(np.zeros(4, np.int64))
    finally:
        _closed_clean(envs)


@pytest.mark.parametrize("policy", ["raise", "restart"])
def test_an_env_that_scribbles_over_its_workers_memory(policy: str) -> None:
    """Every byte of the worker's mapping of the batch buffer set to 0xff, once: the call
    names the worker (or restarts it), no signal, no hang; a reset recovers."""
    envs = rogue_gym.PoolVectorEnv(
        [ScribblingEnv] * 4, num_workers=1, on_worker_failure=policy, step_timeout=20
    )
    try:
        envs.reset(seed=0)
        for _ in range(4):
            envs.step(np.zeros(4, np.int64))
        if policy == "raise":
            with pytest.raises(WorkerCrashedError, match=r"worker 0.*flag byte 255"):
                envs.step(np.zeros(4, np.int64))
            envs.reset(seed=0)
        else:
            infos = envs.step(np.zeros(4, np.int64))[4]
            assert infos["worker_restarted"].all()
        for _ in range(8):  # the restarted envs scribble again at their 5th step
            envs.step(np.zeros(4, np.int64))
    except WorkerCrashedError as err:
        assert "worker 0" in str(err)
    finally:
        _closed_clean(envs)


def test_another_process_scribbling_the_pools_memory_costs_no_signal_or_hang() -> None:
    """A process of the user maps the pool's buffer through ``/proc`` and writes 0xff over it
    again and again while the pool steps: calls return or raise errors that name a worker;
    once it stops, a reset recovers."""
    envs = rogue_gym.make_vec(
        8, config=rogue_gym.PAPER_CONFIG, num_workers=2, seed=0, on_worker_failure="raise"
    )
    scribbler = None
    try:
        envs.reset(seed=0)
        fd = _batch_fds()[0]
        code = (
            "import mmap, os, sys, time\n"
            f"f = os.open('/proc/{os.getpid()}/fd/{fd}', os.O_RDWR)\n"
            "m = mmap.mmap(f, os.fstat(f).st_size)\n"
            "sys.stdout.write('ready\\n'); sys.stdout.flush()\n"
            "end = time.monotonic() + 3\n"
            "while time.monotonic() < end:\n"
            "    m[:] = b'\\xff' * len(m)\n"
        )
        scribbler = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE)
        assert scribbler.stdout is not None and scribbler.stdout.readline() == b"ready\n"
        named, must_reset = 0, False
        while scribbler.poll() is None:
            try:
                if must_reset:
                    envs.reset(seed=0)
                    must_reset = False
                envs.step(np.zeros(8, np.int64))
            except WorkerCrashedError as err:  # a step or reset that read a scribble
                assert err.worker in (0, 1), err
                named += 1
                must_reset = True
        envs.reset(seed=0)
        for _ in range(5):
            obs = envs.step(np.zeros(8, np.int64))[0]
        assert obs.max() <= 1, "the observations are the envs' again"
        assert named > 0, "the scribbles were caught"
    finally:
        if scribbler is not None:
            scribbler.kill()
            scribbler.wait()
        _closed_clean(envs)
