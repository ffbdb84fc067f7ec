"""``python -m rogue_gym.train``: the command line of the PPO trainer.

Every flag is a :class:`~rogue_gym.train.config.TrainConfig` field with its default there::

    python -m rogue_gym.train --variant small --suite paper-10 --frames 2000000 \\
        --device cpu --seed 0 --eval-every 500000 --eval-episodes 2 --eval-seeds 100 \\
        --out runs/small-paper10
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import signal
import sys
from pathlib import Path
from typing import Any, Optional, Sequence

from ..suites import suite_names
from .config import COMPAT_MODES, TrainConfig
from .networks import VARIANTS

__all__ = ["main", "parser"]

_HELP = {
    "variant": "network variant",
    "suite": "suite: training seeds to learn on, test seeds to score on",
    "frames": "environment steps to train for",
    "device": "torch device (cpu, cuda, cuda:1, ...)",
    "seed": "seed of the network, the sampling and the level schedule",
    "out": "run folder (progress.csv, config.json, random.json, checkpoints)",
    "resume": "continue the run in --out from its checkpoint",
    "eval_every": "frames between generalization evaluations (0: at the end only)",
    "eval_seeds": "test seeds per evaluation (paper: 1000)",
    "eval_episodes": "episodes per test seed (paper: 10)",
    "random_episodes": "episodes behind random.json's training score",
    "threads": "torch CPU threads",
    "weight_decay": "L2 weight decay (default: 1e-4 for l2, else 0)",
    "minibatch_size": "samples per minibatch (default: 200; 400 with --compat original)",
    "compat": "ours, or original: the paper's code's behaviours (docs/training.md)",
}


def parser() -> argparse.ArgumentParser:
    """The argument parser, one flag per :class:`TrainConfig` field."""
    p = argparse.ArgumentParser(
        prog="python -m rogue_gym.train",
        description="Train PPO (the CoG'19 paper's variants) on a Rogue-Gym suite through the pool.",
    )
    defaults = TrainConfig()
    for f in dataclasses.fields(TrainConfig):
        flag = "--" + f.name.replace("_", "-")
        default = getattr(defaults, f.name)
        help_text = _HELP.get(f.name, f.name.replace("_", " "))
        if f.name == "progress":
            p.add_argument("--no-progress", dest="progress", action="store_false")
            continue
        if isinstance(default, bool):
            p.add_argument(flag, action="store_true", help=help_text)
            continue
        kind: Any = type(default)
        if f.name == "weight_decay":
            kind = float
        elif f.name in ("threads", "minibatch_size"):
            kind = int
        elif kind is Path:
            kind = Path
        kwargs: dict = {
            "type": kind,
            "default": default,
            "help": f"{help_text} (default: %(default)s)",
        }
        if f.name == "variant":
            kwargs["choices"] = VARIANTS
        elif f.name == "compat":
            kwargs["choices"] = COMPAT_MODES
        elif f.name == "suite":
            kwargs["choices"] = suite_names()
        p.add_argument(flag, **kwargs)
    return p


def _raise_interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt(f"signal {signum}")


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Parse the flags, train, print the final scores; returns the exit status."""
    args = parser().parse_args(argv)
    os.environ.setdefault("OMP_NUM_THREADS", str(args.threads or os.cpu_count() or 1))
    from .trainer import train  # torch is imported here, after the flags are checked

    # SIGTERM (a scheduler's stop, `kill`) unwinds like Ctrl-C: the pools close and remove
    # their shared memory; the last checkpoint stays for --resume.
    signal.signal(signal.SIGTERM, _raise_interrupt)
    try:
        row = train(TrainConfig(**vars(args)))
    except (ValueError, KeyError, FileExistsError, FileNotFoundError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(
            f"interrupted; resume with: python -m rogue_gym.train --out {args.out} --resume "
            "(and the same flags)",
            file=sys.stderr,
        )
        return 130
    print(
        f"done: {row.get('frames')} frames, train score {row.get('train_score', float('nan')):.2f}, "
        f"generalization {row.get('gen_score', float('nan')):.2f} "
        f"[{row.get('gen_ci_low', float('nan')):.2f}, {row.get('gen_ci_high', float('nan')):.2f}]; "
        f"wrote {Path(args.out) / 'progress.csv'}"
    )
    return 0
