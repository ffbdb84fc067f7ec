"""Behaviour every env kind shares through the one front end, checked for each kind (the native
game, hosted CartPole, and CartPole in a vector env per worker) and, where SB3 sees it too, for
each facade."""

from __future__ import annotations

import gc
import os
import signal

import gymnasium as gym
import numpy as np
import pytest
import rogue_gym
from rogue_gym.protocol.ops import ENV_OPS, SERVED_BY, op_table
from rogue_gym.worker.env_adapter import WHO as ENV_ADAPTER
from rogue_gym.worker.env_adapter import HostedEnv
from rogue_gym.worker.vector_adapter import WHO as VECTOR_ADAPTER
from rogue_gym.worker.vector_adapter import HostedVectorEnv

from conftest import PAPER, pid_alive, pool_files, wait_until

KINDS = ["native", "hosted", "vector"]


def _zeros(env) -> np.ndarray:
    return np.zeros(env.num_envs, np.int64)


@pytest.mark.parametrize("facade", ["gymnasium", "sb3"])
@pytest.mark.parametrize("kind", KINDS)
def test_a_killed_worker_restarts_and_every_facade_counts_it(kind, facade, make_kind) -> None:
    """Worker 1 dies: its envs end truncated and flagged, a new worker takes over, and the
    facade shows one restart and the new pid. SB3: the last observation returned stands for
    the lost episode's end, with no ``episode`` info (its counters died with the worker)."""
    env = make_kind(kind, facade, max_restarts=5)
    sb3 = facade == "sb3"
    first = env.reset() if sb3 else env.reset(seed=0)[0]
    last = first.copy()
    assert env.restarts == 0 and len(env.worker_pids) == env.num_workers == 2
    pids = env.worker_pids
    os.kill(pids[1], signal.SIGKILL)
    assert wait_until(lambda: not pid_alive(pids[1]))
    if sb3:
        _, _, dones, infos = env.step(_zeros(env))
        flagged = [bool(info.get("worker_restarted")) for info in infos]
        assert flagged == [False, False, True, True] and dones[2:].all()
        for i in (2, 3):
            assert infos[i]["TimeLimit.truncated"] and "episode" not in infos[i]
            assert np.array_equal(infos[i]["terminal_observation"], last[i])
            assert env.reset_infos[i] is not None
    else:
        _, _, _, trunc, infos = env.step(_zeros(env))
        assert infos["worker_restarted"].tolist() == [False, False, True, True]
        assert infos["_worker_restarted"].tolist() == [False, False, True, True]
        assert trunc[2:].all()
    assert env.restarts == 1
    assert env.worker_pids[0] == pids[0] and env.worker_pids[1] not in (0, pids[1])
    assert list(env.envs_of_worker(1)) == [2, 3]


@pytest.mark.parametrize("kind", KINDS)
def test_sb3_reports_each_ended_episode_as_monitor_does(kind, make_kind) -> None:
    """``episode`` = the ended episode's return and length (summed here from the rewards),
    beside ``terminal_observation``; ``TimeLimit.truncated`` on every step."""
    kw = {"max_steps": 6} if kind == "native" else {}
    env = make_kind(kind, "sb3", **kw)
    env.reset()
    ret, length = np.zeros(4), np.zeros(4, np.int64)
    rng = np.random.default_rng(1)
    ended = 0
    for _ in range(60):
        _, rewards, dones, infos = env.step(rng.integers(0, 2, 4))
        ret += rewards
        length += 1
        for i, info in enumerate(infos):
            assert "TimeLimit.truncated" in info
            if not dones[i]:
                assert "episode" not in info and "terminal_observation" not in info
                continue
            ended += 1
            assert info["episode"]["l"] == length[i] and info["episode"]["r"] == pytest.approx(
                ret[i]
            )
            assert info["episode"]["t"] >= 0 and "terminal_observation" in info
            ret[i], length[i] = 0, 0
    assert ended >= 4


@pytest.mark.parametrize("kind", KINDS)
def test_close_and_gc_leave_nothing_behind(kind) -> None:
    def build():
        if kind == "native":
            return rogue_gym.make_vec(4, config=PAPER, num_workers=2, seed=0)
        return rogue_gym.make_vec("CartPole-v1", 4, num_workers=2)

    env = build()
    obs, _ = env.reset(seed=0)
    snapshot = obs.copy()
    pids, name = env.worker_pids, env.pool_name
    assert pool_files(name)
    env.close()
    assert np.array_equal(obs, snapshot)  # what was returned stays readable after close
    env.close()  # idempotent
    assert env.closed and env.worker_pids == []
    assert wait_until(lambda: not any(pid_alive(p) for p in pids))
    assert pool_files(name) == []
    with pytest.raises(RuntimeError, match="closed"):
        env.step(_zeros(env))

    env = build()
    env.reset(seed=0)
    pids, name = env.worker_pids, env.pool_name
    del env
    gc.collect()
    assert wait_until(lambda: not any(pid_alive(p) for p in pids))
    assert pool_files(name) == []


@pytest.mark.parametrize("copy", [False, True])
@pytest.mark.parametrize("kind", KINDS)
def test_recv_batches_are_the_callers_whatever_copy_says(kind, copy, make_kind) -> None:
    """A recv batch gathers envs of any workers: it is always a fresh, writable array that a
    later recv leaves alone."""
    env = make_kind(kind, batch_size=2, copy=copy)
    env.async_reset(seed=4)
    obs, _, _, _, infos = env.recv()
    assert obs.flags.writeable and len(infos["env_id"]) == 2
    first = np.array(obs, copy=True)
    env.send(_zeros(env)[:2])
    obs2, *_ = env.recv()
    assert obs2.flags.writeable
    assert np.array_equal(obs, first)


@pytest.mark.parametrize("kind", KINDS)
def test_async_reset_takes_the_seed_reset_takes(kind, make_kind) -> None:
    sync = make_kind(kind)
    want, _ = sync.reset(seed=11)
    env = make_kind(kind)
    env.async_reset(seed=11)
    got = {}
    while len(got) < env.num_envs:
        obs, *_, infos = env.recv()
        got.update({int(e): o.copy() for e, o in zip(infos["env_id"], obs)})
        if len(got) < env.num_envs:
            env.send(_zeros(env)[: len(infos["env_id"])])
    assert all(np.array_equal(got[i], want[i]) for i in range(env.num_envs))


@pytest.mark.parametrize("kind", KINDS)
def test_reset_options_go_to_the_envs_or_are_refused_by_name(kind, make_kind) -> None:
    env = make_kind(kind)
    env.reset(seed=0)
    if kind == "native":
        with pytest.raises(ValueError, match=r"no reset options.*'level'"):
            env.reset(options={"level": 3})
        env.reset(options={"reset_mask": np.ones(4, bool)})  # the mask alone is fine
    else:  # CartPole's reset takes low/high bounds of its initial state
        obs, _ = env.reset(seed=0, options={"low": 0.04, "high": 0.05})
        assert ((obs >= 0.04) & (obs <= 0.05)).all()


@pytest.mark.parametrize("kind", KINDS)
def test_a_scalar_action_is_a_type_error_and_a_wrong_count_a_value_error(kind, make_kind) -> None:
    """As gymnasium's vector envs: a batch needs one action per env."""
    env = make_kind(kind)
    env.reset(seed=0)
    with pytest.raises(TypeError, match="got a scalar"):
        env.step(0)
    with pytest.raises(ValueError, match=r"\(4,\)"):
        env.step(np.zeros(3, np.int64))
    env.step(_zeros(env))  # still usable


#: One call of each env operation that every env of the kinds here can answer.
_SAMPLE_CALLS = {
    "call": ("render_mode", ()),
    "env_method": ("get_wrapper_attr", ("render_mode",)),
    "get_attr": ("render_mode", ()),
    "has_attr": ("render_mode", ()),
    "set_wrapper_attr": ("gravity", (9.8,)),
    "setattr": ("tag", (1,)),
    "is_wrapped": ("", (gym.Wrapper,)),
    "render": ("", ()),
    "set_reset_options": ("", ({},)),
    "set_reset_seed": ("", (5,)),
}


def test_the_worker_side_interpreters_have_a_handler_for_each_operation_they_declare() -> None:
    assert set(_SAMPLE_CALLS) == set(ENV_OPS)
    for cls, who in ((HostedEnv, ENV_ADAPTER), (HostedVectorEnv, VECTOR_ADAPTER)):
        assert set(op_table(cls, who)) == SERVED_BY[who]


@pytest.mark.parametrize("kind", KINDS)
def test_each_kind_serves_the_operations_its_table_declares_and_refuses_the_rest(
    kind, make_kind
) -> None:
    """Every operation a kind declares answers one result per env; every other one is
    refused at the call, naming the kind and the operation."""
    env = make_kind(kind, **({"render_mode": "ansi"} if kind == "native" else {}))
    env.reset(seed=0)
    who, served = env._kind.facts.who, env._kind.facts.ops
    assert served == SERVED_BY[who] and served <= set(ENV_OPS)
    n = env.num_envs
    for op, (name, args) in _SAMPLE_CALLS.items():
        if op in served:
            assert len(env.call_envs(op, name, [(args, {})] * n)) == n, op
        else:
            with pytest.raises(
                NotImplementedError, match=f"{getattr(who, 'value', who)} does not serve .*'{op}'"
            ):
                env.call_envs(op, name, [(args, {})] * n)
    env.step(_zeros(env))  # the pool goes on


#: What a worker process may load of the package: the entry, the native module, the
#: registration (``import rogue_gym`` registers ``RogueGym-v0``), the worker's adapters and the
#: protocol both sides share; none of the caller's side (front, kinds, facades, settings).
WORKER_SIDE = (
    "rogue_gym._native",
    "rogue_gym.registration",
    "rogue_gym.worker",
    "rogue_gym.protocol",
)


def _callers_side(modules: list[str]) -> list[str]:
    return [m for m in modules if m != "rogue_gym" and not m.startswith(WORKER_SIDE)]


def test_a_worker_loads_none_of_the_callers_side() -> None:
    """The modules a worker process has loaded: a native pool's worker entry (as spawned:
    ``python -m rogue_gym.worker``), and a hosted env's worker, read from inside it."""
    import subprocess
    import sys

    from hosted_envs import ModulesEnv

    out = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "rogue_gym.worker"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    loaded = sorted(
        {line.rsplit("|", 1)[-1].strip() for line in out.stderr.splitlines() if "|" in line}
    )
    native = [m for m in loaded if m.split(".")[0] == "rogue_gym"]
    assert "rogue_gym._native" in native, out.stderr[-2000:]
    assert _callers_side(native) == [], native
    env = rogue_gym.PoolVectorEnv([ModulesEnv] * 2, num_workers=1)
    try:
        (hosted, _) = env.get_attr("modules")
    finally:
        env.close()
    assert "rogue_gym.worker.env_adapter" in hosted, hosted
    assert _callers_side(hosted) == [], hosted
