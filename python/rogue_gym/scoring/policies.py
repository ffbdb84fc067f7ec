"""Policies for the evaluator: the interface (``policy(obs) -> actions``), the random agent,
and loading ``random`` / ``module:attr`` / ``file.py:attr`` / ``checkpoint:PATH`` specs."""

from __future__ import annotations

import importlib
import importlib.util
import inspect
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .. import _native

__all__ = [
    "CHECKPOINT_LOADER",
    "NUM_ACTIONS",
    "Policy",
    "RandomPolicy",
    "load_policy",
    "seed_policy",
]

#: Size of the action space (``. h j k l n b u y > s``).
NUM_ACTIONS: int = _native.NUM_ACTIONS

#: A policy: one integer action per row of a batch of observations.
Policy = Callable[[np.ndarray], Any]


class RandomPolicy:
    """Uniform random actions over the 11 actions, from its own seeded numpy RNG."""

    def __init__(self, seed: int = 0, num_actions: int = NUM_ACTIONS) -> None:
        self.num_actions = num_actions
        self.seed(seed)

    def seed(self, seed: int) -> None:
        """Restart the action stream from ``seed``."""
        self._rng = np.random.default_rng(seed)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """One uniform action per row of ``obs``."""
        return self._rng.integers(0, self.num_actions, size=len(obs), dtype=np.int64)


#: What loads ``checkpoint:PATH`` policies (a saved network of ``rogue_gym.train``, needs
#: torch: ``RUN/models/frames-N.pt``), by name: the trainer builds on this evaluator, not the
#: other way round.
CHECKPOINT_LOADER = ("rogue_gym.train.posthoc", "checkpoint_policy")


def load_policy(spec: str) -> Policy:
    """Resolve ``random``, ``reference`` (:class:`rogue_gym.agents.ReferenceAgent`),
    ``module:attr`` or ``path/to/file.py:attr`` into a policy callable.

    Classes are instantiated with no arguments. See the module docstring for the interface.
    """
    if spec == "random":
        return RandomPolicy()
    if spec == "reference":
        from ..agents import ReferenceAgent

        return ReferenceAgent()
    if spec.startswith("checkpoint:"):
        loader_module, loader_name = CHECKPOINT_LOADER
        loader = getattr(importlib.import_module(loader_module), loader_name)
        return loader(Path(spec.split(":", 1)[1]))
    if ":" not in spec:
        raise ValueError(f"--policy must be 'random', 'reference' or 'module:attr', got {spec!r}")
    mod_name, attr = spec.rsplit(":", 1)
    if mod_name.endswith(".py"):
        path = Path(mod_name)
        mod_spec = importlib.util.spec_from_file_location(path.stem, path)
        if mod_spec is None or mod_spec.loader is None:
            raise ImportError(f"cannot load policy file {path}")
        module = importlib.util.module_from_spec(mod_spec)
        mod_spec.loader.exec_module(module)
    else:
        module = importlib.import_module(mod_name)
    obj: Any = module
    for part in attr.split("."):
        obj = getattr(obj, part)
    if inspect.isclass(obj):
        obj = obj()
    if not callable(obj):
        raise TypeError(f"policy {spec!r} is not callable")
    return obj


def seed_policy(policy: Policy, seed: int) -> None:
    """Call the policy's ``seed(seed)`` if it has one."""
    seeder = getattr(policy, "seed", None)
    if callable(seeder):
        seeder(seed)
