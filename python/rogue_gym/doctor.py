"""A preflight of this machine for a pool: ``python -m rogue_gym.doctor``.

Command line::

    python -m rogue_gym.doctor                           # the native game, 64 envs
    python -m rogue_gym.doctor CartPole-v1 --num-envs 256 --num-workers 8
    python -m rogue_gym.doctor ALE/Pong-v5 --num-envs 64 --copy

It reports the CPUs this process may use (affinity and the cgroup's quota), your other live
pools on the machine and how booked it is, ``/dev/shm``'s size and free space against the
pool's need, the open-file limit, the runtime directory, and whether a pool of that layout
starts and steps for one second. Each problem comes with its fix; the
exit status is 1 when any check failed. ``docs/containers.md`` shows it in Docker, Kubernetes
and Slurm.
"""

from __future__ import annotations

import argparse
import errno
import os
import resource
import shutil
import sys
import time
from dataclasses import dataclass
from typing import Any, Callable, Optional

from . import _native
from .registration import ENV_ID

__all__ = ["Check", "main", "run_checks"]

#: Where the pool's shared memory lives.
SHM_DIR = "/dev/shm"
#: Open files a pool needs per worker, with room (iceoryx2's ports and events, its stderr file,
#: the envs' own); and for the caller's side besides.
FILES_PER_WORKER = 64
FILES_BASE = 256


@dataclass
class Check:
    """One line of the report: what was checked, whether it passed, and the fix if not."""

    name: str
    ok: bool
    detail: str
    fix: str = ""

    def line(self) -> str:
        mark = "ok  " if self.ok else "FAIL"
        text = f"[{mark}] {self.name}: {self.detail}"
        return text if self.ok or not self.fix else f"{text}\n       fix: {self.fix}"


def _mib(n: float) -> str:
    return f"{n / 2**20:.1f} MiB"


def check_cpus(num_workers: int) -> Check:
    """The cores this process may use (its affinity mask and its cgroup's CPU quota, as the
    pool reads them) against ``num_workers``."""
    usable, quota = _native.cpu_limits()
    cpus = _native.usable_cores()
    detail = f"{usable} usable (affinity)" + (f", cgroup quota {quota:g}" if quota else "")
    if num_workers > 2 * cpus:
        return Check(
            "cpus",
            False,
            f"{detail}; {num_workers} workers is more than twice that",
            f"use num_workers <= {max(1, int(2 * cpus))} (python -m rogue_gym.tuning picks one), "
            "or give the job more CPUs (docker --cpus, Kubernetes resources.limits.cpu, Slurm "
            "--cpus-per-task)",
        )
    return Check("cpus", True, f"{detail}; {num_workers} workers")


def check_other_pools(num_workers: int) -> Check:
    """Your other live pools on this machine (the pools' ledger) and how booked it is with one
    more of ``num_workers`` workers: past its cores, every pool's workers and callers block
    rather than poll (docs/performance.md, "Many pools on one machine")."""
    try:
        pools = _native.live_pools()
    except (OSError, RuntimeError) as exc:
        return Check("other pools", False, f"the pools' ledger cannot be read: {exc}")
    cores = _native.usable_cores()
    demand = num_workers + sum(p["workers"] + 1 for p in pools)
    listed = ", ".join(f"{p['pool']} (pid {p['pid']}, {p['workers']} workers)" for p in pools)
    detail = f"{len(pools)} live" + (f": {listed}" if pools else "")
    detail += f"; with this pool {demand} processes for {cores} cores"
    if demand > cores:
        detail += " (booked: the pools' workers and callers block rather than poll)"
    return Check("other pools", True, detail)


def check_shm(need: Optional[int], refused: str = "") -> Check:
    """``/dev/shm`` against ``need`` bytes (``None``: unknown, the pool did not start);
    ``refused``: the pool's own error when it found no room there."""
    try:
        usage = shutil.disk_usage(SHM_DIR)
    except OSError as exc:
        return Check("/dev/shm", False, f"cannot be read: {exc}", "mount a tmpfs at /dev/shm")
    detail = f"{_mib(usage.total)} in all, {_mib(usage.free)} free"
    if refused:
        return Check("/dev/shm", False, f"{detail}; the pool did not fit: {refused}")
    if need is None:
        return Check("/dev/shm", True, detail)
    detail += f"; this pool needs {_mib(need)}"
    if need > usage.free:
        return Check(
            "/dev/shm",
            False,
            detail,
            f"give the container at least {_mib(2 * need)} of shared memory: docker run "
            "--shm-size=... (or --ipc=host); in Kubernetes mount an emptyDir with medium: Memory "
            "at /dev/shm; or use fewer envs",
        )
    return Check("/dev/shm", True, detail)


def check_open_files(num_workers: int) -> Check:
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    need = FILES_BASE + FILES_PER_WORKER * num_workers
    detail = f"limit {soft} (hard {hard}); a pool of {num_workers} workers wants about {need}"
    if soft != resource.RLIM_INFINITY and soft < need:
        return Check(
            "open files",
            False,
            detail,
            f"raise it: ulimit -n {min(hard, 4 * need) if hard != resource.RLIM_INFINITY else 4 * need} "
            "(docker --ulimit nofile=...; Slurm: ulimit in the batch script)",
        )
    return Check("open files", True, detail)


def check_runtime_dir() -> Check:
    path = _native.default_runtime_dir()
    try:
        os.makedirs(path, mode=0o700, exist_ok=True)
        st = os.lstat(path)
    except OSError as exc:
        return Check(
            "runtime directory",
            False,
            f"{path}: {exc}",
            "set ROGUE_GYM_RUNTIME_DIR to a directory only you can enter",
        )
    private = st.st_uid == os.getuid() and not st.st_mode & 0o077
    if not private:
        return Check(
            "runtime directory",
            False,
            f"{path} is open to others (mode {oct(st.st_mode & 0o777)}) or not yours",
            f"chmod 700 {path}, or set ROGUE_GYM_RUNTIME_DIR to a private directory",
        )
    return Check("runtime directory", True, f"{path} (private)")


def _builder(env: str, num_envs: int, num_workers: int, copy: bool) -> Callable[[], Any]:
    from .vector import make_vec

    if env == ENV_ID:
        return lambda: make_vec(num_envs, num_workers=num_workers, copy=copy)
    return lambda: make_vec(env, num_envs, num_workers=num_workers, copy=copy)


def check_pool(build: Callable[[], Any], seconds: float) -> tuple[Check, Optional[int], str]:
    """Start the pool, step it for ``seconds``: the check, the pool's /dev/shm need, and its
    error when /dev/shm had no room for it."""
    t0 = time.monotonic()
    try:
        envs = build()
    except OSError as exc:
        if exc.errno == errno.ENOSPC:
            return (
                Check("a pool", False, "did not start: no room in /dev/shm (above)"),
                None,
                str(exc),
            )
        if exc.errno == errno.ENOMEM:
            fix = "fewer envs or smaller observations, or more memory for the job"
            return Check("a pool", False, f"did not start: {exc}", fix), None, ""
        return Check("a pool", False, f"did not start: {exc}"), None, ""
    except Exception as exc:
        return Check("a pool", False, f"did not start: {type(exc).__name__}: {exc}"), None, ""
    try:
        started = time.monotonic() - t0
        envs.reset(seed=0)
        steps, t1 = 0, time.monotonic()
        while time.monotonic() - t1 < seconds:
            envs.step(envs.action_space.sample())
            steps += envs.num_envs
        rate = steps / (time.monotonic() - t1)
        stats = envs.stats()
        need = stats.shm_bytes
        detail = (
            f"started in {started:.2f} s, {rate:,.0f} steps/s with {envs.num_workers} workers "
            f"over {seconds:g} s; its buffers take {_mib(stats.buffer_bytes)} of memory"
        )
        return Check("a pool", True, detail), need, ""
    except Exception as exc:
        failed = f"failed while stepping: {type(exc).__name__}: {exc}"
        return Check("a pool", False, failed), None, ""
    finally:
        envs.close()


def run_checks(
    env: str = ENV_ID,
    num_envs: int = 64,
    num_workers: Optional[int] = None,
    copy: bool = False,
    seconds: float = 1.0,
) -> list[Check]:
    """Every check for a pool of ``num_envs`` envs of ``env`` on ``num_workers`` workers."""
    workers = num_workers or min(num_envs, _native.usable_cores())
    others = check_other_pools(workers)
    pool, need, refused = check_pool(_builder(env, num_envs, workers, copy), seconds)
    return [
        check_cpus(workers),
        others,
        check_shm(need, refused),
        check_open_files(workers),
        check_runtime_dir(),
        pool,
    ]


def main(argv: Optional[list[str]] = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m rogue_gym.doctor",
        description="Check this machine for a pool of the given layout; each problem comes "
        "with its fix.",
    )
    p.add_argument("env", nargs="?", default=ENV_ID, help=f"a gymnasium id (default {ENV_ID})")
    p.add_argument("--num-envs", type=int, default=64)
    p.add_argument("--num-workers", type=int, default=None, help="default: the usable CPUs")
    p.add_argument("--copy", action="store_true", help="the pool's copy=True")
    p.add_argument("--seconds", type=float, default=1.0, help="how long the pool steps")
    args = p.parse_args(argv)
    print(f"rogue_gym doctor: {args.num_envs} envs of {args.env}", flush=True)
    checks = run_checks(args.env, args.num_envs, args.num_workers, args.copy, args.seconds)
    for c in checks:
        print(c.line())
    bad = [c for c in checks if not c.ok]
    print("all checks passed" if not bad else f"{len(bad)} problem(s)")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
