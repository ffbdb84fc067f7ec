"""A pool on a shared machine (docs/security.md): what another local user can do to it.

Each attack runs in ``security/probe.py`` as root inside a private mount namespace with a fresh
/tmp and /dev/shm (``security/private_namespace.sh``), the other user being a forked child that
drops to another uid. Without root, or where mount namespaces are not allowed, the tests are
skipped with the reason.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

HERE = Path(__file__).parent / "security"
OTHER = 4321


def _namespace_reason() -> str:
    if os.geteuid() != 0:
        return "needs root (to mount a private /tmp and /dev/shm and act as another uid)"
    if shutil.which("unshare") is None:
        return "needs unshare (util-linux)"
    ok = subprocess.run(
        ["unshare", "--mount", "--propagation", "private", "true"], capture_output=True
    )
    if ok.returncode != 0:
        return f"mount namespaces are not allowed here: {ok.stderr.decode().strip()}"
    return ""


REASON = _namespace_reason()
pytestmark = pytest.mark.skipif(bool(REASON), reason=REASON)


def probe(scenario: str) -> dict[str, Any]:
    """Run one scenario of the probe in a fresh private namespace; its JSON result."""
    out = subprocess.run(
        [
            "unshare",
            "--mount",
            "--propagation",
            "private",
            "bash",
            str(HERE / "private_namespace.sh"),
            sys.executable,
            str(HERE / "probe.py"),
            scenario,
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, f"probe {scenario} failed:\n{out.stdout}\n{out.stderr}"
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_every_path_of_a_live_pool_is_private_to_its_user() -> None:
    r = probe("modes")
    assert r["native_paths"] >= 10 and r["hosted_paths"] >= 10, r
    assert r["native_loose"] == [], r
    assert r["hosted_loose"] == [], r
    # No XDG_RUNTIME_DIR in the probe: the per-user directory in /tmp, made 0700.
    assert r["runtime_dir"] == "/tmp/rogue-gym-0"
    assert r["runtime_dir_mode"] == "0o700"


@pytest.mark.parametrize("kind", ["file", "dir"])
def test_a_runtime_directory_planted_by_another_user_is_refused(kind: str) -> None:
    r = probe(f"planted-{kind}")
    # The default name is bypassed for a fresh private directory of ours.
    assert r["bypassed_to"].startswith("/tmp/rogue-gym-0-"), r
    assert r["bypass_mode"] == "0o700" and r["bypass_owner"] == 0, r
    # Named explicitly, it is a clear error, and the planted path is left as it was.
    err = r["explicit_error"]
    assert err is not None, r
    reason = "is not a directory" if kind == "file" else f"owned by uid {OTHER}"
    assert reason in err and "ROGUE_GYM_RUNTIME_DIR" in err, err
    assert r["planted_untouched"]


def test_links_planted_by_a_racing_user_write_nothing_and_no_pool_file_opens() -> None:
    r = probe("race")
    assert r["seen"] >= 1, r  # the attacker did see the pools
    assert r["started"] + r["failed"] == 8, r
    assert r["started"] >= 1, r
    assert r["victim"] == "precious", r
    assert r["opened"] == [], r


def test_two_users_run_pools_side_by_side() -> None:
    r = probe("two-users")
    assert r["other_exit"] == 0, r
    assert r["theirs"]["steps"] == 200
    assert r["mine"] == "/tmp/rogue-gym-0"
    assert r["theirs"]["dir"] == f"/tmp/rogue-gym-{OTHER}"
    # Each user's ledger of live pools holds its own pool only, both pools alive.
    assert r["ledger"] == [r["name"]], r
    assert r["theirs"]["ledger"] == [r["theirs"]["name"]], r
