"""``rogue_gym.tune``: it times every candidate within the time it announces, and its advice
names a layout it measured."""

from __future__ import annotations

import functools
import io
import re
import subprocess
import sys
import time

import gymnasium as gym
import pytest
import rogue_gym
import rogue_gym.tuning as tune_mod
from rogue_gym.tuning import search as tune_search
from rogue_gym.tuning import timing as tune_timing

from hosted_envs import SleepEnv, SlowResetEnv


def cartpole() -> gym.Env:
    return gym.make("CartPole-v1")


def test_tune_finishes_within_its_stated_time_and_names_a_layout() -> None:
    out = io.StringIO()
    t0 = time.monotonic()
    result = rogue_gym.tune([cartpole] * 4, 4, seconds=0.1, rounds=1, cpus=1, out=out)
    took = time.monotonic() - t0
    text = out.getvalue()
    found = re.search(r"at most ([\d.]+) (s|min)\)", text)
    assert found, text
    stated = float(found.group(1)) * (60 if found.group(2) == "min" else 1)
    assert took <= stated + 5, (took, stated)
    labels = [t.candidate.label for t in result.timings]
    # 1 CPU: 1 and 2 workers, lent or not; async with 2 workers and with one per env; the
    # deadline harvest with 1 worker and one per env; one worker with its envs on threads, in
    # lockstep and harvested; and SyncVectorEnv.
    assert len(labels) == 11 and "SyncVectorEnv" in labels, labels
    threaded = [label for label in labels if "env_concurrency=threads" in label]
    assert len(threaded) == 2, labels
    assert all(t.error is None and t.median > 0 for t in result.timings)
    # Best first: by median, but for the winner of the side-by-side duels, which it names.
    ranked = result.timings
    assert ranked[1:] == sorted(ranked[1:], key=lambda t: -t.median)
    if not result.duels:
        assert ranked[0].median >= ranked[1].median
    else:
        assert result.duels[-1].first == ranked[0].candidate.label
        for d in result.duels:
            assert d.ratio >= 1 and len(d.ratios) == 8
            assert f"side by side: {d.first} at {d.ratio:.3f}x {d.second}" in text
    assert result.advice() in text and ("make_vec" in result.advice() or "Sync" in result.advice())


def test_tune_runs_from_the_command_line_on_the_native_game() -> None:
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "rogue_gym.tuning",
            "RogueGym-v0",
            "--num-envs",
            "4",
            "--seconds",
            "0.1",
            "--rounds",
            "1",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert "steps/s" in proc.stdout and "best: make_vec(env, 4," in proc.stdout
    assert "RuntimeWarning" not in proc.stderr


def test_tune_refuses_what_it_cannot_build() -> None:
    with pytest.raises(ValueError, match="not a registered gymnasium id"):
        rogue_gym.tune("NoSuchEnv-v9", 4)


def test_a_duel_names_the_faster_layout_first() -> None:
    # A single worker stepping 4 envs of 2 ms each cannot match 4 workers stepping one each.
    slow = [functools.partial(SleepEnv, 0.002)] * 4
    one = tune_mod.Candidate("pool", {"num_workers": 1, "copy": True})
    four = tune_mod.Candidate("pool", {"num_workers": 4, "copy": True})
    d = tune_mod.duel(slow, 4, one, four, pairs=4, burst=0.1)
    assert (d.first, d.second) == (four.label, one.label)
    assert len(d.ratios) == 4 and d.ratio > 1.5


def test_an_async_layout_leaves_nothing_running_between_bursts() -> None:
    # In a duel the other pool is timed between this one's bursts: steps still in flight would
    # take its CPUs and start this one's next burst with work already done.
    slow = [functools.partial(SleepEnv, 0.002)] * 4
    target = tune_timing.Target("hosted", slow, None, 4)
    batched = tune_mod.Candidate("async", {"num_workers": 4, "batch_size": 2})
    with tune_timing.Live(target, batched) as live:
        assert live.burst(0.1) > 0
        before = live.env.stats().env_steps
        time.sleep(0.2)  # 100 steps' time of each env, were any running
        assert live.env.stats().env_steps == before
        assert live.burst(0.1) > 0  # and the held batches go on where they stopped


def test_tune_times_again_only_the_layouts_within_half_the_best(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Each layout's speed, made up: the workers' count squared, half as much again for
    # shared-memory views (no rival is within a duel's reach of the best).
    def fake_run(target: object, timing: tune_mod.Timing, seconds: float) -> float:
        kw = timing.candidate.kwargs
        bonus = 1.5 if kw.get("copy") is False else 1.0
        timing.steps_per_s.append(1000.0 * kw.get("num_workers", 1) ** 2 * bonus)
        timing.shares.append((0.5, 0.3, 0.2))
        return 0.01

    monkeypatch.setattr(tune_search, "time_run", fake_run)
    out = io.StringIO()
    result = rogue_gym.tune([cartpole] * 4, 4, seconds=0.01, rounds=3, cpus=2, out=out)
    runs = {t.candidate.label: len(t.steps_per_s) for t in result.timings}
    best = result.best.candidate
    assert best.kwargs == {"num_workers": 4, "copy": False} and not result.duels
    # 24,000 steps/s best: 1 and 2 workers, 3 workers copying (9,000) and SyncVectorEnv run
    # once; 3 workers with views (13,500) and 4 copying (16,000) go on.
    assert runs["pool: num_workers=1, copy=True"] == runs["SyncVectorEnv"] == 1
    assert runs["pool: num_workers=2, copy=False"] == runs["pool: num_workers=3, copy=True"] == 1
    assert runs["pool: num_workers=3, copy=False"] == runs[best.label] == 3
    assert runs["pool: num_workers=4, copy=True"] == 3
    kept = sum(1 for n in runs.values() if n == 3)
    assert f"tune: {kept} of {len(runs)} layouts within 50% of the best go on" in out.getvalue()


def test_a_candidate_is_named_by_its_label() -> None:
    for c in tune_mod.candidates("hosted", 8, "CartPole-v1", 2, lends=True):
        assert tune_mod.Candidate.from_label(c.label) == c


def test_three_batch_slots_are_a_candidate_where_batches_are_lent() -> None:
    """Two slots lend every other batch of a loop that holds the previous one; three lend
    every batch: tune times them where the batch is large enough to be lent."""
    slots = [c.kwargs.get("batch_slots") for c in tune_mod.candidates("hosted", 8, None, 2, True)]
    assert slots.count(3) == 4  # one per worker count, 1 to 4 on 2 CPUs
    assert 3 not in [c.kwargs.get("batch_slots") for c in tune_mod.candidates("hosted", 8, None, 2)]
    assert tune_timing.obs_bytes("native", None) == 17 * 16 * 32
    assert tune_timing.obs_bytes("hosted", lambda: gym.make("CartPole-v1")) == 4 * 4


def test_tune_recommends_envs_served_as_they_are_ready_for_slow_resets() -> None:
    """Envs that spend most of their time in slow resets are best served so that none waits
    behind another: one per worker or each on a thread of its worker, received as soon as it
    is ready or stepped together; never one after another in lockstep. Tune times both ways
    of stepping a worker's envs and says which is faster."""
    result = rogue_gym.tune([SlowResetEnv] * 8, 8, seconds=0.6, rounds=1, cpus=1, out=io.StringIO())
    best = result.best_pool.candidate
    concurrent = best.kwargs["num_workers"] == 8 or best.kwargs.get("env_concurrency") == "threads"
    assert concurrent, result.table()
    medians = {t.candidate.label: t.median for t in result.timings}
    threaded = medians["pool: num_workers=1, env_concurrency=threads"]
    assert threaded > 3 * medians["pool: num_workers=1, copy=False"], result.table()
    # Threads against one worker per env: either may win or they tie; tune says which.
    assert re.search(
        r"env_concurrency: (threads|serial) (is faster|and serial are within)", result.table()
    )
    assert "make_vec(env, 8" in result.advice()
