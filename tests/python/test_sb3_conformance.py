"""Stable-Baselines3's own vector-env tests, run against ``rogue_gym.sb3.PoolVecEnv``.

The test file is taken at test time from the stable-baselines3 sdist that matches the installed
version (never copied into this repository) and run in a child pytest whose conftest rebinds
``stable_baselines3.common.vec_env.SubprocVecEnv`` to ``PoolVecEnv``: every test that uses
``SubprocVecEnv`` then exercises the pool.
"""

from __future__ import annotations

import subprocess
import sys
import tarfile
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

sb3 = pytest.importorskip("stable_baselines3")

#: The suite's file inside the sdist.
SUITE = "tests/test_vec_envs.py"
#: Skips we accept, with their reasons (they need a display or an optional package).
ALLOWED_SKIPS = ("No X-Server", "moviepy is not installed")

CONFTEST = '''\
"""Rebind SubprocVecEnv to rogue_gym's PoolVecEnv before the suite imports it."""
import stable_baselines3.common.vec_env as vec_env
from rogue_gym.sb3 import PoolVecEnv

vec_env.SubprocVecEnv = PoolVecEnv
'''


def fetch_suite(dest: Path) -> Path:
    """Download the matching sdist and extract the vector-env test file into ``dest``."""
    version = sb3.__version__
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "download",
            "--quiet",
            "--no-deps",
            "--no-binary",
            ":all:",
            f"stable-baselines3=={version}",
            "-d",
            str(dest),
        ],
        check=True,
        timeout=300,
    )
    (sdist,) = dest.glob("stable_baselines3-*.tar.gz")
    with tarfile.open(sdist) as tar:
        member = tar.getmember(f"stable_baselines3-{version}/{SUITE}")
        data = tar.extractfile(member)
        assert data is not None
        suite = dest / "suite"
        suite.mkdir()
        (suite / "test_vec_envs.py").write_bytes(data.read())
    (suite / "conftest.py").write_text(CONFTEST)
    return suite


@pytest.mark.timeout(1500)
def test_sb3_vec_env_suite_passes_with_pool_vec_env(tmp_path: Path) -> None:
    suite = fetch_suite(tmp_path)
    report = tmp_path / "report.xml"
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "-W",
            "ignore",
            f"--junitxml={report}",
            "test_vec_envs.py",
        ],
        cwd=suite,
        capture_output=True,
        text=True,
        timeout=1200,
    )
    root = ET.parse(report).getroot()
    cases = root.iter("testcase")
    failed, skipped, passed, ours = [], [], 0, 0
    for case in cases:
        name = case.get("name", "")
        ours += "PoolVecEnv" in name or name.startswith(("test_subproc", "test_vec_env_is_wrapped"))
        if case.find("failure") is not None or case.find("error") is not None:
            failed.append(name)
        elif (skip := case.find("skipped")) is not None:
            skipped.append((name, skip.get("message", "")))
        else:
            passed += 1
    assert not failed and run.returncode == 0, f"failed: {failed}\n{run.stdout[-4000:]}"
    assert ours >= 15, f"only {ours} tests used PoolVecEnv: the rebinding did not take"
    for name, reason in skipped:
        assert any(r in reason for r in ALLOWED_SKIPS), f"unexpected skip {name}: {reason}"
    print(f"SB3 {sb3.__version__} test_vec_envs.py: {passed} passed, skipped {skipped}")
