"""Run logging: ``progress.csv`` (one row per update) and the console progress bar.

Columns: ``frames, updates, episodes, restarted_envs, train_score, gen_score, gen_ci_low,
gen_ci_high, fps`` (``restarted_envs``: envs whose episode a crashed or hung worker's restart
cut short, so far), then the update's losses and where the time went (``env_s``, ``policy_s``, ``update_s``,
``eval_s``: seconds since the process started or resumed the run). ``gen_*`` are empty except
on the rows of an evaluation. ``train_score`` is the mean return of the last 1000 finished
training episodes.

Every column but the wall-clock ones (``fps`` and the ``*_s`` columns) is a function of the
config and seed: two CPU runs with the same seed write the same values there.
"""

from __future__ import annotations

import csv
import math
import sys
from pathlib import Path
from typing import Any, Dict, List, Optional

__all__ = ["COLUMNS", "TIMING_COLUMNS", "ProgressLog", "read_progress"]

#: ``progress.csv``'s columns, in order.
COLUMNS: List[str] = [
    "frames",
    "updates",
    "episodes",
    "restarted_envs",
    "train_score",
    "gen_score",
    "gen_ci_low",
    "gen_ci_high",
    "fps",
    "policy_loss",
    "value_loss",
    "entropy",
    "aux_loss",
    "approx_kl",
    "clip_fraction",
    "env_s",
    "policy_s",
    "update_s",
    "eval_s",
]

#: The wall-clock columns (they differ between identical runs).
TIMING_COLUMNS = frozenset({"fps", "env_s", "policy_s", "update_s", "eval_s"})


def _fmt(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return "" if math.isnan(v) else repr(round(v, 6))
    return str(v)


class ProgressLog:
    """Appends rows to ``progress.csv`` (flushed each row) and drives a tqdm bar."""

    def __init__(self, path: Path, total_frames: int, start_frames: int, bar: bool) -> None:
        self.path = path
        new = not path.exists() or path.stat().st_size == 0
        self._file = path.open("a", newline="")
        self._writer = csv.DictWriter(self._file, fieldnames=COLUMNS)
        if new:
            self._writer.writeheader()
            self._file.flush()
        self._bar: Optional[Any] = None
        if bar:
            try:
                from tqdm import tqdm

                self._bar = tqdm(
                    total=total_frames,
                    initial=start_frames,
                    unit="frame",
                    unit_scale=True,
                    dynamic_ncols=True,
                    file=sys.stderr,
                    mininterval=0.5 if sys.stderr.isatty() else 30.0,
                )
            except ImportError:  # pragma: no cover - tqdm is optional
                self._bar = None

    def row(self, values: Dict[str, Any], frames_done: int) -> None:
        """Write one row and advance the bar by ``frames_done``."""
        self._writer.writerow({k: _fmt(values.get(k)) for k in COLUMNS})
        self._file.flush()
        if self._bar is not None:
            self._bar.update(frames_done)
            self._bar.set_postfix(
                train=f"{values.get('train_score', float('nan')):.1f}",
                fps=f"{values.get('fps', 0.0):.0f}",
                refresh=False,
            )

    def message(self, text: str) -> None:
        """Print a line without breaking the bar."""
        if self._bar is not None:
            self._bar.write(text, file=sys.stderr)
        else:
            print(text, file=sys.stderr, flush=True)

    def close(self) -> None:
        """Close the bar and the file."""
        if self._bar is not None:
            self._bar.close()
        self._file.close()


def read_progress(path: Path) -> List[Dict[str, str]]:
    """The rows of a ``progress.csv``."""
    with Path(path).open(newline="") as f:
        return list(csv.DictReader(f))


def truncate_after(path: Path, frames: int) -> None:
    """Drop the rows past ``frames`` (a resumed run rewrites them)."""
    if not path.exists():
        return
    rows = [r for r in read_progress(path) if int(r["frames"]) <= frames]
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        w.writerows(rows)
