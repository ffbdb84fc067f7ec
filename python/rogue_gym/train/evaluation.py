"""The generalization score: the policy on the suite's unseen test seeds, via the evaluator.

Each evaluation plays ``eval_episodes`` episodes on each of the first ``eval_seeds`` test seeds
through :func:`rogue_gym.evaluate.score`, the evaluator's own (the paper: 1000 seeds x 10
episodes) with the stochastic policy, as the paper's evaluation does, and reports the mean with
a 95% bootstrap interval across seeds (:class:`rogue_gym.evaluate.AgentResult`).
"""

from __future__ import annotations

from typing import Any, Dict, List

import numpy as np
import torch
import torch.nn.functional as F

from ..evaluate import AgentResult, RandomPolicy, run_episodes, score
from ..suites import Suite
from .networks import PolicyNet

__all__ = ["TorchPolicy", "generalization", "random_baseline", "same_seed_schedule"]

#: Confidence level of the reported intervals.
CONFIDENCE = 0.95


class TorchPolicy:
    """A network as an evaluator policy: symbol-index screens in, sampled actions out."""

    def __init__(self, net: PolicyNet, device: torch.device) -> None:
        self.net = net
        self.device = device
        self.generator = torch.Generator(device="cpu")

    def seed(self, seed: int) -> None:
        """Restart the action sampling from ``seed``."""
        self.generator.manual_seed(seed)

    @torch.no_grad()
    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """One action per screen, sampled from the policy."""
        x = torch.from_numpy(np.array(obs, copy=True)).to(self.device)
        probs = F.softmax(self.net(x).logits.float(), dim=-1).cpu()
        return torch.multinomial(probs, 1, generator=self.generator).squeeze(1).numpy()


def _run(
    suite: Suite,
    policy: Any,
    seeds: List[int],
    episodes: int,
    num_envs: int,
    workers: int,
    seed: int,
) -> np.ndarray:
    return run_episodes(
        suite,
        policy,
        seeds,
        episodes,
        num_envs=num_envs,
        num_workers=workers,
        obs="symbol_index",
        policy_seed=seed,
        progress=False,
    )


def same_seed_schedule(seeds: List[int], episodes: int) -> List[int]:
    """Each seed ``episodes`` times in a row: with ``episodes`` envs and the evaluator's
    round-robin schedule, round ``r`` starts every env on seed ``r`` together (the paper's
    code evaluated each test seed with all its envs seeded alike)."""
    return [s for s in seeds for _ in range(episodes)]


def generalization(
    net: PolicyNet,
    device: torch.device,
    suite: Suite,
    seeds: int,
    episodes: int,
    num_envs: int,
    workers: int,
    seed: int,
    compat: str = "ours",
) -> AgentResult:
    """The policy's score on the first ``seeds`` test seeds, ``episodes`` each.

    ``compat="original"`` evaluates as the paper's code did: the network stays in train mode
    (BatchNorm uses each batch's statistics) and the ``episodes`` episodes of a seed are
    played side by side as one batch of ``episodes`` envs (``num_envs`` is then ignored).
    """
    was_training = net.training
    original = compat == "original"
    net.train(original)
    try:
        policy = TorchPolicy(net, device)
        test = suite.test_seed_list()[:seeds]
        if original:
            w = workers if episodes % workers == 0 else 1
            flat = _run(suite, policy, same_seed_schedule(test, episodes), 1, episodes, w, seed)
            return AgentResult.from_returns(
                "policy", flat.reshape(len(test), episodes), CONFIDENCE, 0
            )
        # The evaluator's own scoring, so that the two report one statistic.
        return score(
            suite,
            policy,
            test,
            episodes,
            obs="symbol_index",
            num_envs=num_envs,
            num_workers=workers,
            policy_seed=seed,
            confidence=CONFIDENCE,
        )
    finally:
        net.train(was_training)


def random_baseline(
    suite: Suite, seeds: int, episodes: int, num_envs: int, workers: int, train_episodes: int
) -> Dict[str, Any]:
    """The uniform random agent's training score (about ``train_episodes`` episodes spread
    evenly over the training seeds) and generalization score (on the same test seeds as
    :func:`generalization`), for the plots."""
    train_seeds = suite.train_seed_list()
    per_seed = -(-train_episodes // len(train_seeds))
    train = _run(suite, RandomPolicy(), train_seeds, per_seed, num_envs, workers, 0)
    test = _run(
        suite, RandomPolicy(), suite.test_seed_list()[:seeds], episodes, num_envs, workers, 0
    )
    gen = AgentResult.from_returns("random", test, CONFIDENCE, 0)
    return {
        "suite": suite.name,
        "train_score": float(train.mean()),
        "train_episodes": int(train.size),
        "gen_score": gen.mean,
        "gen_ci_low": gen.ci_low,
        "gen_ci_high": gen.ci_high,
        "eval_seeds": seeds,
        "eval_episodes": episodes,
    }
