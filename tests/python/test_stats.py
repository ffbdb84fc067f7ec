"""``stats()``: the counters add up, for every kind and facade, and a restart is counted."""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest

from conftest import pid_alive, wait_until

KINDS = ["native", "hosted"]


@pytest.mark.parametrize("kind", KINDS)
def test_counters_add_up(kind, make_kind) -> None:
    # From before the pool is made: a worker's counters include its start-up (its first
    # answer, the iceoryx2 pages it touches first).
    t0 = time.perf_counter()
    env = make_kind(kind)
    env.reset(seed=0)
    steps = 30
    for _ in range(steps):
        env.step(np.zeros(4, np.int64))
    wall = time.perf_counter() - t0
    s = env.stats()
    assert len(s.workers) == 2
    # Every env step and reset is counted once, by the worker that served it.
    assert s.env_steps == 4 * (steps + 1)
    assert [w.env_steps for w in s.workers] == [2 * (steps + 1)] * 2
    assert all(w.commands == steps + 1 for w in s.workers)
    # Time: nothing exceeds the wall clock; the caller's clock covers its calls.
    assert 0 < s.waiting_s <= s.seconds <= wall + 0.5
    for w in s.workers:
        assert 0 < w.env_s <= wall and w.publish_s <= wall and w.wait_s <= wall + 0.5
    assert abs(s.env_share + s.transport_share + s.caller_share - 1) < 1e-6
    assert s.restarts == 0 and s.batches_lent + s.batches_copied + s.batches_viewed == steps + 1
    line = str(s)
    assert "steps/s" in line and "env" in line and "restarts 0" in line
    # reset=True starts a new span.
    env.stats(reset=True)
    env.step(np.zeros(4, np.int64))
    assert env.stats().env_steps == 4 and env.stats().calls >= 1


@pytest.mark.parametrize("facade", ["gymnasium", "sb3"])
@pytest.mark.parametrize("kind", KINDS)
def test_a_restart_is_counted_with_its_cause(kind, facade, make_kind) -> None:
    env = make_kind(kind, facade)
    env.reset()
    victim = env.worker_pids[1]
    os.kill(victim, signal.SIGKILL)
    assert wait_until(lambda: not pid_alive(victim))
    env.step(np.zeros(4, np.int64))
    s = env.stats()
    assert [w.restarts for w in s.workers] == [0, 1] and s.restarts == env.restarts == 1
    assert str(victim) in (s.workers[1].last_failure or "")
    assert "restarts 1" in str(s)


def test_hosted_infos_are_counted_as_typed_rows(make_kind) -> None:
    env = make_kind("hosted")
    env.reset(seed=0)
    for _ in range(5):
        env.step(np.zeros(4, np.int64))
    s = env.stats()
    # CartPole returns empty infos: nothing travels; copy=True lends or copies every batch.
    assert s.info_rows_pickled == 0 and s.batches_viewed == 0
