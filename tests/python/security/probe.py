"""One attack on a pool from another local user, run as root inside a private mount namespace
(``private_namespace.sh``: fresh /tmp and /dev/shm). The other user is a forked child that
drops to uid/gid ``OTHER``. Prints one JSON object (what happened) and exits 0; the test
(``test_security.py``) asserts on it.

Usage: python probe.py SCENARIO
"""

from __future__ import annotations

import json
import os
import stat
import sys
import time
from typing import Any, Callable

OTHER = 4321


def as_other(fn: Callable[[], Any], wait: bool = True) -> int:
    """Run ``fn`` in a forked child as uid/gid ``OTHER``; its return value is its exit code."""
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            os.setgroups([])
            os.setgid(OTHER)
            os.setuid(OTHER)
            os.environ.pop("XDG_RUNTIME_DIR", None)
            os.environ["HOME"] = "/tmp"
            code = int(fn() or 0)
        except BaseException as exc:  # the child must never return into the caller's code
            print(f"other user: {type(exc).__name__}: {exc}", file=sys.stderr)
        finally:
            os._exit(code)
    if wait:
        return os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
    return pid


def pool_paths(name: str, runtime_dir: str) -> list[str]:
    """Every path of pool ``name``: its /dev/shm files, and its directories with their content."""
    paths = [f"/dev/shm/{f}" for f in os.listdir("/dev/shm") if f.startswith(f"{name}_")]
    todo = [os.path.join(runtime_dir, name), os.path.join(runtime_dir, f"{name}.d")]
    while todo:
        p = todo.pop()
        paths.append(p)
        if os.path.isdir(p) and not os.path.islink(p):
            todo.extend(os.path.join(p, f) for f in os.listdir(p))
    return paths


def loose(paths: list[str]) -> list[str]:
    """The paths open to group or others, or not owned by this user."""
    out = []
    for p in paths:
        st = os.lstat(p)
        if st.st_mode & 0o077 or st.st_uid != os.geteuid() or stat.S_ISLNK(st.st_mode):
            out.append(f"{p} {stat.filemode(st.st_mode)} uid {st.st_uid}")
    return out


def cartpole() -> Any:
    import gymnasium as gym

    return gym.make("CartPole-v1")


def native(**kw: Any) -> Any:
    import rogue_gym

    return rogue_gym.make_vec(4, num_workers=2, seed=0, **kw)


def modes() -> dict[str, Any]:
    """The modes and owners of every path a live native and hosted pool make."""
    from rogue_gym import PoolVectorEnv

    out: dict[str, Any] = {}
    envs = native()
    envs.reset()
    envs.step(envs.action_space.sample())
    rd = envs._core.pool.runtime_dir()
    paths = pool_paths(envs.pool_name, rd)
    out["native_paths"] = len(paths)
    out["native_loose"] = loose([*paths, rd])
    hosted = PoolVectorEnv([cartpole] * 4, num_workers=2)
    hosted.reset(seed=0)
    hosted.step(hosted.action_space.sample())
    paths = pool_paths(hosted.pool_name, hosted._core.pool.runtime_dir())
    out["hosted_paths"] = len(paths)
    out["hosted_loose"] = loose(paths)
    out["runtime_dir"] = rd
    out["runtime_dir_mode"] = oct(os.lstat(rd).st_mode & 0o7777)
    envs.close()
    hosted.close()
    return out


def planted(kind: str) -> dict[str, Any]:
    """The other user plants the default runtime directory first (as a file, or as a directory
    of theirs open to all): the default is bypassed for a private one; naming it is an error."""
    target = f"/tmp/rogue-gym-{os.geteuid()}"

    def plant() -> None:
        if kind == "file":
            with open(target, "w") as f:
                f.write("not a directory")
        else:
            os.mkdir(target)
            os.chmod(target, 0o777)

    assert as_other(plant) == 0
    out: dict[str, Any] = {}
    envs = native()
    envs.reset()
    rd = envs._core.pool.runtime_dir()
    out["bypassed_to"] = rd
    out["bypass_mode"] = oct(os.lstat(rd).st_mode & 0o7777)
    out["bypass_owner"] = os.lstat(rd).st_uid
    envs.close()
    try:
        native(runtime_dir=target)
        out["explicit_error"] = None
    except Exception as exc:  # the message is what the test checks
        out["explicit_error"] = f"{type(exc).__name__}: {exc}"
    out["planted_untouched"] = os.lstat(target).st_uid == OTHER
    return out


def race() -> dict[str, Any]:
    """The other user watches /dev/shm and the runtime directory while pools start, and for each
    new pool plants links to a file of ours under its likely names and tries to open every
    file of it. Nothing of ours may be written, no file of a pool opened."""
    victim = "/tmp/victim"
    with open(victim, "w") as f:
        f.write("precious")
    os.chmod(victim, 0o600)
    os.chmod("/tmp", 0o1777)
    ready = os.pipe()

    def attack() -> int:
        os.close(ready[0])
        os.write(ready[1], b"x")
        opened, planted, seen = [], 0, set()
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and not os.path.exists("/tmp/stop"):
            for f in os.listdir("/dev/shm"):
                if not f.startswith("rg"):
                    continue
                prefix = f.split("_", 1)[0]
                if prefix not in seen:
                    seen.add(prefix)
                    for name in ("batch", "node.global_mgmt"):
                        try:
                            os.symlink(victim, f"/dev/shm/{prefix}_{name}")
                            planted += 1
                        except OSError:
                            pass
                for mode in (os.O_RDWR, os.O_RDONLY):
                    try:
                        fd = os.open(f"/dev/shm/{f}", mode | os.O_NOFOLLOW)
                        os.close(fd)
                        opened.append(f)
                    except OSError:
                        pass
        with open("/tmp/attack.json", "w") as out:
            json.dump({"opened": sorted(set(opened)), "planted": planted, "seen": len(seen)}, out)
        return 0

    # A first pool, before the attack: the process learns iceoryx2's node counter name with a
    # throwaway root that no pool uses (PoolId::create_node_counter).
    native().close()
    pid = as_other(attack, wait=False)
    os.close(ready[1])
    os.read(ready[0], 1)
    started = failed = 0
    for _ in range(8):
        try:
            envs = native()
            envs.reset()
            for _ in range(20):
                envs.step(envs.action_space.sample())
            envs.close()
            started += 1
        except Exception:  # a pool may fail cleanly if a name was taken
            failed += 1
    with open("/tmp/stop", "w"):
        pass
    os.waitpid(pid, 0)
    with open("/tmp/attack.json") as f:
        attack_result = json.load(f)
    with open(victim) as f:
        victim_text = f.read()
    return {"started": started, "failed": failed, "victim": victim_text, **attack_result}


def two_users() -> dict[str, Any]:
    """A second user runs a pool at the same time as the first, each in its own directory,
    each user's pool ledger listing its own pools only (read while both pools are alive)."""
    done, other_up, mine_up = os.pipe(), os.pipe(), os.pipe()

    def other_pool() -> int:
        from rogue_gym import _native

        for fd in (done[0], other_up[0], mine_up[1]):
            os.close(fd)
        envs = native()
        envs.reset()
        os.write(other_up[1], b"x")
        os.read(mine_up[0], 1)  # both pools are alive from here
        ledger = [p["pool"] for p in _native.live_pools()]
        steps = 0
        for _ in range(200):
            envs.step(envs.action_space.sample())
            steps += 1
        rd = envs._core.pool.runtime_dir()
        name = envs._core.name
        envs.close()
        out = {"steps": steps, "dir": rd, "ledger": ledger, "name": name}
        os.write(done[1], json.dumps(out).encode())
        return 0

    from rogue_gym import _native

    pid = as_other(other_pool, wait=False)
    for fd in (done[1], other_up[1], mine_up[0]):  # a side that dies is seen as an end of file
        os.close(fd)
    envs = native()
    envs.reset()
    os.read(other_up[0], 1)
    ledger = [p["pool"] for p in _native.live_pools()]
    os.write(mine_up[1], b"x")
    for _ in range(200):
        envs.step(envs.action_space.sample())
    mine = envs._core.pool.runtime_dir()
    name = envs._core.name
    envs.close()
    code = os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
    theirs = json.loads(os.read(done[0], 4096) or b"{}")
    return {"mine": mine, "theirs": theirs, "other_exit": code, "ledger": ledger, "name": name}


SCENARIOS: dict[str, Callable[[], dict[str, Any]]] = {
    "modes": modes,
    "planted-file": lambda: planted("file"),
    "planted-dir": lambda: planted("dir"),
    "race": race,
    "two-users": two_users,
}

if __name__ == "__main__":
    os.environ.pop("XDG_RUNTIME_DIR", None)
    os.environ.pop("ROGUE_GYM_RUNTIME_DIR", None)
    print(json.dumps(SCENARIOS[sys.argv[1]]()))
