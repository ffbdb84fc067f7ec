"""Many pools on one machine (docs/performance.md, "Many pools on one machine"): the cores a
process really has decide the defaults, live pools record themselves in their user's ledger
and see each other within a second, a killed pool's entry is ignored and swept, and
``cpu_affinity="disjoint"`` hands out cores no other pool holds. The ledger's refusals (links,
loose modes, other users) and the reading of cgroup quotas from fake files are tested in
``ipc/src/ledger.rs`` and ``ipc/src/cores.rs``; two users' ledgers in test_security.py."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rogue_gym
from rogue_gym import _native

from conftest import PAPER, pool_files, wait_until


def _names() -> list[str]:
    return [p["pool"] for p in _native.live_pools()]


def test_pools_see_each_other_within_a_second_and_leave_when_closed(make_vec: Any) -> None:
    a = make_vec(4, num_workers=1)
    a.reset(seed=0)
    b = make_vec(4, num_workers=1)
    b.reset(seed=0)
    names = {a.pool_name, b.pool_name}
    assert names <= set(_names())
    seen = b.stats().machine
    assert seen["cores"] == _native.usable_cores()
    assert [o["pool"] for o in seen["others"]] == [a.pool_name]
    assert seen["demand"] == 1 + (1 + 1), "its worker, and the other pool's worker and caller"
    assert seen["worker_pace"] == "short", "no long polls while another pool shares the machine"
    # The first pool reads the ledger again within a second.
    assert wait_until(
        lambda: [o["pool"] for o in a.stats().machine["others"]] == [b.pool_name], 2.5
    )
    a.step(np.zeros(4, np.int64))
    b.close()
    assert b.pool_name not in _names()
    assert wait_until(lambda: a.stats().machine["others"] == [], 2.5)
    assert a.stats().machine["worker_pace"] == "expected", "alone again: as before"


def test_a_killed_pools_entry_is_ignored_and_swept() -> None:
    code = (
        "import sys, time, rogue_gym\n"
        f"e = rogue_gym.make_vec(4, config={PAPER!r}, num_workers=1, seed=0)\n"
        "e.reset(seed=0)\n"
        "print(e.pool_name, flush=True)\n"
        "time.sleep(120)\n"
    )
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert p.stdout is not None
        name = p.stdout.readline().strip()
        assert name in _names()
        entry = Path(_native.default_runtime_dir()) / "ledger" / name
        assert entry.exists()
    finally:
        p.send_signal(signal.SIGKILL)
        p.wait(timeout=30)
    assert name not in _names(), "a dead pool is no live pool"
    assert not entry.exists(), "its entry was swept by the reading"
    # Its other files go with the next pool's start (the stale-pool sweep), as ever.
    envs = rogue_gym.make_vec(4, config=PAPER, num_workers=1, seed=0)
    envs.close()
    assert wait_until(lambda: pool_files(name) == [], 5), pool_files(name)


def _in_subprocess(code: str, prefix: list[str]) -> str:
    done = subprocess.run(
        [*prefix, sys.executable, "-c", code], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


DEFAULTS = (
    "import rogue_gym\n"
    "from rogue_gym import _native\n"
    f"e = rogue_gym.make_vec(8, config={PAPER!r}, seed=0)\n"
    "print(_native.usable_cores(), _native.cpu_limits()[1], e.num_workers)\n"
    "e.close()\n"
)


def test_the_affinity_mask_decides_the_default_workers() -> None:
    if len(os.sched_getaffinity(0)) < 2:
        pytest.skip("one CPU: nothing to narrow")
    out = _in_subprocess(DEFAULTS, ["taskset", "-c", "0"])
    usable, _, workers = out.split()
    assert (usable, workers) == ("1", "1"), out


def test_a_cpu_quota_decides_the_default_workers() -> None:
    """A cgroup whose CPU quota is half a CPU: one usable core (rounded up), one worker."""
    v1 = Path("/sys/fs/cgroup/cpu")
    group = v1 / f"rogue-gym-test-{os.getpid()}"
    try:
        group.mkdir()
        period = int((group / "cpu.cfs_period_us").read_text())
        (group / "cpu.cfs_quota_us").write_text(str(period // 2))
    except OSError as exc:
        pytest.skip(f"no writable cgroup v1 cpu controller here: {exc}")
    try:
        out = _in_subprocess(
            DEFAULTS, ["sh", "-c", f'echo $$ > {group}/cgroup.procs && exec "$@"', "sh"]
        )
        usable, quota, workers = out.split()
        assert (usable, float(quota), workers) == ("1", 0.5, "1"), out
    finally:
        time.sleep(0.2)
        group.rmdir()


def test_disjoint_cores_are_handed_out_and_too_few_is_an_error_naming_the_holders(
    make_vec: Any,
) -> None:
    cores = sorted(os.sched_getaffinity(0))
    a = make_vec(4, num_workers=1, cpu_affinity="disjoint")
    theirs = a.stats().machine["others"]
    assert theirs == [] or all(o["cores"] == [] for o in theirs)
    mine = next(p for p in _native.live_pools() if p["pool"] == a.pool_name)["cores"]
    assert len(mine) == 1 and mine[0] in cores
    with open(f"/proc/{a.worker_pids[0]}/status") as f:
        allowed = next(line for line in f if line.startswith("Cpus_allowed_list"))
    assert allowed.split()[-1] == str(mine[0]), "the worker runs on its core"
    if len(cores) < 2:
        return
    b = make_vec(4, num_workers=len(cores) - 1, cpu_affinity="disjoint")
    theirs = next(p for p in _native.live_pools() if p["pool"] == b.pool_name)["cores"]
    assert sorted(mine + theirs) == cores, "disjoint, and every core taken"
    with pytest.raises(ValueError, match="disjoint") as raised:
        make_vec(4, num_workers=1, cpu_affinity="disjoint")
    assert a.pool_name in str(raised.value) and b.pool_name in str(raised.value)
    with pytest.raises(ValueError, match="cpu_affinity must be"):
        make_vec(4, num_workers=1, cpu_affinity="spread")
