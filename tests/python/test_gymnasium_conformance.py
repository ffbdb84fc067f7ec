"""gymnasium 1.4.0's own tests/vector against ``rogue_gym.PoolVectorEnv``.

The suite is read at test time from ``../shared/reference/gymnasium-1.4.0-tests`` (verbatim,
MIT; the PyPI sdists do not ship it), copied into a temporary folder and run in a subprocess with
``AsyncVectorEnv`` rebound to ``PoolVectorEnv`` (``conformance/gym_vector_plugin.py``);
``SyncVectorEnv`` stays as it is. Counted: the tests that construct the class (184).

Every counted test passes except the deliberate differences listed below, each with its
reason (and any open gap, listed with its cause). A counted test outside both lists that fails is a
regression. The counts are printed, e.g. "160 passed, 0 open gaps, 5 known differences".
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from collections import Counter
from pathlib import Path

import gymnasium
import pytest

ROOT = Path(__file__).resolve().parents[2]
SUITE = ROOT.parent / "shared" / "reference" / "gymnasium-1.4.0-tests"
PLUGIN_DIR = Path(__file__).resolve().parent / "conformance"

#: Deliberate differences from AsyncVectorEnv (test function -> reason).
KNOWN_DIFFERENCES: dict[str, str] = {
    "test_async_vector_env.py::test_step_timeout_async_vector_env": (
        "actions reach the envs in the action space's dtype (float32 here); the test's env "
        "sleeps for its action and time.sleep refuses numpy.float32, where AsyncVectorEnv hands "
        "over the caller's float64 elements unconverted. Its timeout itself is checked by "
        "tests/python/test_vector.py::test_step_wait_times_out_and_the_step_stays_pending"
    ),
    "test_async_vector_env.py::test_async_vector_subenv_error": (
        "AsyncVectorEnv's internals: the test counts the warnings AsyncVectorEnv logs as it "
        "shuts down the worker process whose env raised (its own messages about its worker and "
        "pipes). The pool raises the env's exception (its check of ValueError('Error in reset') "
        "passes) with the worker-side traceback as a note, and keeps the worker, whose env is "
        "reset by the next reset(): there is no shutdown to warn about. Its second half also "
        "steps envs that were never reset, which the pool refuses (stricter, as gym.make's "
        "OrderEnforcing wrapper refuses it)"
    ),
    "test_vector_env.py::test_final_obs_info": (
        "stricter: the test steps a Discrete(4) env with action 4, outside its action space; "
        "the pool checks every action against the space before the envs see it and raises a "
        "ValueError naming the env and the value, where AsyncVectorEnv hands it over unchecked"
    ),
}

#: Counted tests that fail today, by test function, with the cause (none: a test that fails and
#: is in neither list is a regression).
OPEN_GAPS: dict[str, str] = {}

pytestmark = [
    pytest.mark.timeout(900),
    pytest.mark.skipif(not SUITE.is_dir(), reason=f"gymnasium's suite is not at {SUITE}"),
    pytest.mark.skipif(
        not gymnasium.__version__.startswith("1.4."),
        reason=f"the suite is gymnasium 1.4.0's; gymnasium {gymnasium.__version__} is installed",
    ),
]


def function_of(node: str) -> str:
    """``tests/vector/test_x.py::test_y[params]`` -> ``test_x.py::test_y``."""
    return node.split("[")[0].removeprefix("tests/vector/")


def test_gymnasium_vector_suite_against_pool_vector_env(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    suite = tmp_path / "gymnasium-tests"
    shutil.copytree(SUITE, suite)
    for p in suite.rglob("*"):
        p.chmod(p.stat().st_mode | 0o200)  # ../shared has no write bits
    out = tmp_path / "outcomes.json"
    env = {
        **os.environ,
        "ROGUE_GYM_CONFORMANCE_OUT": str(out),
        "PYTHONPATH": os.pathsep.join([str(PLUGIN_DIR), os.environ.get("PYTHONPATH", "")]),
        "PYTHONDONTWRITEBYTECODE": "1",
    }
    cmd = [sys.executable, "-m", "pytest", "tests/vector", "-q", "-p", "gym_vector_plugin"]
    cmd += ["-p", "no:cacheprovider", "--timeout", "60", "-W", "ignore::DeprecationWarning"]
    run = subprocess.run(cmd, cwd=suite, env=env, capture_output=True, text=True, timeout=800)
    assert out.exists(), run.stdout[-3000:] + run.stderr[-3000:]
    outcomes = json.loads(out.read_text())
    counted = {node: o["outcome"] for node, o in outcomes.items() if o["constructed"]}
    assert len(counted) >= 180, f"only {len(counted)} tests constructed the class"
    for name in [*OPEN_GAPS, *KNOWN_DIFFERENCES]:
        assert any(function_of(n) == name for n in outcomes), f"no test {name} in the suite"
    failed = {n for n, o in counted.items() if o == "failed"}
    by_kind = Counter(
        "passed"
        if o == "passed"
        else "known difference"
        if function_of(n) in KNOWN_DIFFERENCES
        else "open gap"
        if function_of(n) in OPEN_GAPS
        else o
        for n, o in counted.items()
    )
    regressions = sorted(
        n for n in failed if function_of(n) not in {**OPEN_GAPS, **KNOWN_DIFFERENCES}
    )
    fixed = sorted(name for name in OPEN_GAPS if not any(function_of(n) == name for n in failed))
    summary = (
        f"gymnasium tests/vector against PoolVectorEnv: {by_kind['passed']} passed, "
        f"{by_kind['open gap']} open gaps, {by_kind['known difference']} known differences, "
        f"{by_kind['skipped']} skipped, {len(regressions)} unexpected failures "
        f"of {len(counted)} counted"
    )
    with capsys.disabled():  # the counts belong in CI's log
        print(f"\n{summary}")
        if fixed:
            print("open gaps that pass now (take them off OPEN_GAPS):", ", ".join(fixed))
    assert not regressions, f"{summary}; failing outside the lists:\n" + "\n".join(regressions)
