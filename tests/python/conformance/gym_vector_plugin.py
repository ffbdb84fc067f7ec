"""A pytest plugin that runs gymnasium's own tests/vector against ``rogue_gym.PoolVectorEnv``.

Loaded with ``-p gym_vector_plugin`` (this folder on ``PYTHONPATH``) by
``tests/python/test_gymnasium_conformance.py``. Before any test module is imported it rebinds
``gymnasium.vector.AsyncVectorEnv`` to a subclass of ``PoolVectorEnv`` that notes which tests
construct it (``SyncVectorEnv`` stays as it is); at the end it writes, to the JSON file named by
``$ROGUE_GYM_CONFORMANCE_OUT``, each test's outcome and whether it constructed the class.
"""

from __future__ import annotations

import json
import os
from typing import Any

import gymnasium.vector
import gymnasium.vector.async_vector_env
import pytest
from rogue_gym import PoolVectorEnv

_current: list[str] = [""]
_constructed: set[str] = set()
_outcomes: dict[str, str] = {}


class CountedPoolVectorEnv(PoolVectorEnv):
    """``PoolVectorEnv`` under the name the tests import, noting the test that builds it."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        _constructed.add(_current[0])
        super().__init__(*args, **kwargs)


def pytest_configure(config: pytest.Config) -> None:
    gymnasium.vector.AsyncVectorEnv = CountedPoolVectorEnv  # type: ignore[misc]
    gymnasium.vector.async_vector_env.AsyncVectorEnv = CountedPoolVectorEnv  # type: ignore[misc]


def pytest_runtest_setup(item: pytest.Item) -> None:
    _current[0] = item.nodeid


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    # A failure in any phase is the test's outcome; otherwise the call's (or a skip).
    if report.failed:
        _outcomes[report.nodeid] = "failed"
    elif report.when == "call" or (report.skipped and report.nodeid not in _outcomes):
        _outcomes.setdefault(report.nodeid, report.outcome)


def pytest_sessionfinish(session: pytest.Session) -> None:
    out = os.environ.get("ROGUE_GYM_CONFORMANCE_OUT")
    if out:
        tests = {
            node: {"outcome": outcome, "constructed": node in _constructed}
            for node, outcome in _outcomes.items()
        }
        with open(out, "w") as f:
            json.dump(tests, f, indent=1, sort_keys=True)
