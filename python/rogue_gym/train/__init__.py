"""PPO for Rogue-Gym: the CoG'19 paper's agents, trained through the pool.

Run it as ``python -m rogue_gym.train --variant small --suite paper-10 --frames N --out DIR``
and draw the curves with ``python -m rogue_gym.train.plot DIR [DIR ...]``. Modules, one concern
each, in the order a run uses them:

* :mod:`.config`: :class:`TrainConfig`, the run's settings with the paper's hyperparameters;
* :mod:`.networks`: the six variants (small, large, batchnorm, l2, vae, betavae);
* :mod:`.rollout`: collection from the pool in two overlapping halves;
* :mod:`.ppo`: GAE and the clipped PPO update;
* :mod:`.evaluation`: the generalization score on the suite's test seeds;
* :mod:`.progress`: ``progress.csv`` and the progress bar;
* :mod:`.checkpoint`: resumable checkpoints;
* :mod:`.allocator`: keeping freed memory, so the update loop does not page-fault;
* :mod:`.trainer`: the loop tying them together; :mod:`.cli`: the command line;
* :mod:`.plot`: the paper's figures from ``progress.csv`` files.

Needs torch (``pip install torch``); the rest of ``rogue_gym`` does not.
"""

from .config import TrainConfig
from .networks import VARIANTS

__all__ = ["VARIANTS", "TrainConfig", "train"]


def train(cfg: TrainConfig) -> dict:
    """Train one agent (see :func:`rogue_gym.train.trainer.train`)."""
    from .trainer import train as _train

    return _train(cfg)
