"""Checkpoints: everything needed to continue a run (``--resume``), written atomically.

``OUT/checkpoint.pt`` holds the latest state: network, optimizer, counters, training-episode
returns and the random generators. ``OUT/models/frames-N.pt`` keeps the weights alone at each
checkpoint, for evaluating intermediate policies (as the paper's curves do).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Dict

import torch

__all__ = ["CHECKPOINT", "load", "save"]

#: The resumable checkpoint's file name inside the run folder.
CHECKPOINT = "checkpoint.pt"


def _atomic_save(obj: Any, path: Path) -> None:
    tmp = path.with_name(path.name + ".tmp")
    torch.save(obj, tmp)
    os.replace(tmp, path)


def save(out: Path, state: Dict[str, Any]) -> Path:
    """Write ``state`` as the run's checkpoint and its weights as ``models/frames-N.pt``."""
    models = out / "models"
    models.mkdir(parents=True, exist_ok=True)
    _atomic_save(state["model"], models / f"frames-{int(state['frames']):010d}.pt")
    path = out / CHECKPOINT
    _atomic_save(state, path)
    return path


def load(out: Path) -> Dict[str, Any]:
    """The checkpoint of the run in ``out``; ``FileNotFoundError`` says how to start one."""
    path = out / CHECKPOINT
    if not path.exists():
        raise FileNotFoundError(
            f"--resume: no checkpoint at {path}; run without --resume to start a new run there"
        )
    return torch.load(path, map_location="cpu", weights_only=False)
