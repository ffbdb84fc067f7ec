"""The trainer's settings: the paper's PPO hyperparameters, each written once.

:class:`TrainConfig` holds every knob of a run with the paper's value as its default
(``../shared/reference/python-api-and-paper-protocol.md`` §3.3). The command line
(:mod:`rogue_gym.train.cli`) builds its flags from these fields, and a run saves its config as
``config.json`` beside ``progress.csv``.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any, Dict, Optional

from .networks import VARIANTS

__all__ = ["COMPAT_MODES", "TrainConfig"]

#: ``--compat``: this trainer's behaviour, or the paper's code's where they differ.
COMPAT_MODES = ("ours", "original")

#: Minibatch size per ``--compat`` mode: the paper's table says 200, its code uses 400.
MINIBATCH = {"ours": 200, "original": 400}


@dataclasses.dataclass
class TrainConfig:
    """One training run.

    The PPO values are the paper's: 32 envs x 125 steps per update, 10 epochs of minibatches of
    200, clip 0.1 (policy and value), value coefficient 0.5, entropy 0.01, gamma 0.99, GAE
    lambda 0.95, Adam lr 2.5e-4 with eps 1e-4, gradient norm clipped at 0.5. The ``l2`` variant
    adds ``weight_decay`` (1e-4) to Adam.
    """

    variant: str = "small"
    """Network variant, one of ``small, large, batchnorm, l2, vae, betavae``."""
    suite: str = "paper-10"
    """Suite whose training seeds the agent plays and whose test seeds score it."""
    frames: int = 40_000_000
    """Environment steps to train for (all envs together; the paper's code: 40M)."""
    device: str = "cpu"
    """``cpu`` or ``cuda`` (or any torch device string)."""
    seed: int = 0
    """Seeds the network, the action sampling and the training levels' schedule."""
    out: Path = Path("runs/ppo")
    """Run folder: ``progress.csv``, ``config.json``, ``random.json``, checkpoints."""
    resume: bool = False
    """Continue from ``out/checkpoint.pt`` instead of starting afresh."""

    eval_every: int = 1_000_000
    """Frames between generalization evaluations (0: only at the end)."""
    eval_seeds: int = 1000
    """Test seeds per evaluation (the first M of the suite's; the paper: all 1000)."""
    eval_episodes: int = 10
    """Episodes per test seed (the paper: 10)."""
    eval_envs: int = 64
    """Envs of the evaluation pool."""
    random_episodes: int = 1000
    """Episodes behind the random agent's training score in ``random.json`` (spread evenly
    over the training seeds; the trainer's own score averages 1000 too)."""
    checkpoint_every: int = 2_000_000
    """Frames between checkpoints (the last one is always written; the paper's code: 2M)."""

    num_envs: int = 32
    num_workers: int = 2
    """Worker processes of the training pool; each one's block of envs steps while the policy
    acts on another's (with 2, two halves; with 1, nothing overlaps)."""
    num_steps: int = 125
    """Rollout length per env and update."""
    epochs: int = 10
    minibatch_size: Optional[int] = None
    """Samples per minibatch (default: 200, the paper's table; 400 with ``--compat original``,
    the paper's code)."""
    compat: str = "ours"
    """``ours``, or ``original``: the paper's code's behaviours where it differs from the paper
    (docs/training.md, "--compat original"): BatchNorm in train mode while acting and
    evaluating, evaluation in same-seed batches, its initialisation, advantages normalised once
    per rollout, minibatch 400."""
    lr: float = 2.5e-4
    adam_eps: float = 1e-4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip: float = 0.1
    value_coef: float = 0.5
    entropy_coef: float = 0.01
    max_grad_norm: float = 0.5
    weight_decay: Optional[float] = None
    """L2 weight decay; ``None`` means the variant's (1e-4 for ``l2``, else 0)."""
    threads: Optional[int] = None
    """torch CPU threads (default: torch's)."""
    progress: bool = True
    """Show a progress bar on stderr."""

    def checked(self) -> TrainConfig:
        """A copy with defaults resolved; ``ValueError`` names a bad value."""
        from ..suites import get_suite

        if self.compat not in COMPAT_MODES:
            raise ValueError(
                f"compat must be one of {', '.join(COMPAT_MODES)}, got {self.compat!r}"
            )
        mb = MINIBATCH[self.compat] if self.minibatch_size is None else int(self.minibatch_size)
        if self.variant not in VARIANTS:
            raise ValueError(f"variant must be one of {', '.join(VARIANTS)}, got {self.variant!r}")
        get_suite(self.suite)  # KeyError listing the suites
        batch = self.num_envs * self.num_steps
        for name in ("frames", "num_envs", "num_workers", "num_steps", "epochs"):
            if int(getattr(self, name)) <= 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if not 0 < mb <= batch:
            raise ValueError(
                f"minibatch_size {mb} must be positive and at most the rollout batch "
                f"{batch} (num_envs x num_steps)"
            )
        if self.num_envs % self.num_workers:
            raise ValueError(
                f"num_workers ({self.num_workers}) must divide num_envs ({self.num_envs})"
            )
        if self.eval_seeds <= 0 or self.eval_episodes <= 0 or self.random_episodes <= 0:
            raise ValueError("eval_seeds, eval_episodes and random_episodes must be positive")
        if str(self.device).startswith("cuda"):
            import torch

            if not torch.cuda.is_available():
                raise ValueError(
                    f"device {self.device!r}: torch sees no CUDA device (torch "
                    f"{torch.__version__}); use --device cpu or a CUDA build of torch"
                )
        wd = self.weight_decay
        if wd is None:
            wd = 1e-4 if self.variant == "l2" else 0.0
        return dataclasses.replace(
            self, out=Path(self.out), weight_decay=float(wd), minibatch_size=mb
        )

    @property
    def batch_size(self) -> int:
        """Samples per update: ``num_envs * num_steps``."""
        return self.num_envs * self.num_steps

    def to_json(self) -> Dict[str, Any]:
        """JSON-able dict of every field."""
        d = dataclasses.asdict(self)
        d["out"] = str(self.out)
        return d

    def save(self, path: Path) -> None:
        """Write :meth:`to_json` to ``path``."""
        path.write_text(json.dumps(self.to_json(), indent=1) + "\n")
