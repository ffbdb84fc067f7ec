"""``python -m rogue_gym.train.plot``: the paper's figures from ``progress.csv`` files.

Two panels against frames: the training score (mean of the last 1000 training episodes) and
the generalization score on the test seeds with its 95% interval, one line per run, labelled
``variant / suite`` from the run's ``config.json``. The random agent's scores (the run's
``random.json``) are drawn as dashed lines::

    python -m rogue_gym.train.plot runs/small-paper10 runs/l2-paper10 --out curves.png

Each argument is a run folder or its ``progress.csv``. Needs matplotlib.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

from .progress import read_progress

__all__ = ["load_run", "main", "plot_runs"]


def load_run(path: Path) -> Tuple[str, List[Dict[str, float]], Optional[Dict[str, Any]]]:
    """``(label, rows, random)`` of a run folder or a ``progress.csv`` path."""
    path = Path(path)
    folder = path.parent if path.suffix == ".csv" else path
    rows = [
        {k: (float(v) if v not in ("", None) else math.nan) for k, v in r.items()}
        for r in read_progress(folder / "progress.csv")
    ]
    label = folder.name
    cfg_path = folder / "config.json"
    if cfg_path.exists():
        cfg = json.loads(cfg_path.read_text())
        label = f"{cfg.get('variant', '?')} / {cfg.get('suite', '?')}"
    rnd_path = folder / "random.json"
    rnd = json.loads(rnd_path.read_text()) if rnd_path.exists() else None
    return label, rows, rnd


def plot_runs(paths: Sequence[Path], out: Path, title: str = "") -> Path:
    """Draw the training and generalization curves of ``paths`` into ``out`` (PNG, SVG...)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_train, ax_gen) = plt.subplots(1, 2, figsize=(12, 4.5), sharex=True)
    randoms: Dict[str, Dict[str, Any]] = {}
    for path in paths:
        label, rows, rnd = load_run(path)
        frames = [r["frames"] for r in rows]
        (line,) = ax_train.plot(frames, [r["train_score"] for r in rows], label=label)
        ev = [r for r in rows if not math.isnan(r["gen_score"])]
        xs = [r["frames"] for r in ev]
        ax_gen.plot(
            xs, [r["gen_score"] for r in ev], marker="o", color=line.get_color(), label=label
        )
        ax_gen.fill_between(
            xs,
            [r["gen_ci_low"] for r in ev],
            [r["gen_ci_high"] for r in ev],
            color=line.get_color(),
            alpha=0.2,
        )
        if rnd is not None:
            randoms[rnd["suite"]] = rnd
    for suite, rnd in randoms.items():
        ax_train.axhline(rnd["train_score"], ls="--", color="gray", label=f"random / {suite}")
        ax_gen.axhline(rnd["gen_score"], ls="--", color="gray", label=f"random / {suite}")
    ax_train.set_title("training score (last 1000 episodes)")
    ax_gen.set_title("generalization score (test seeds, 95% CI)")
    for ax in (ax_train, ax_gen):
        ax.set_xlabel("frames")
        ax.set_ylabel("return")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Command-line entry point; returns the exit status."""
    p = argparse.ArgumentParser(
        prog="python -m rogue_gym.train.plot",
        description="Plot training and generalization curves from progress.csv files.",
    )
    p.add_argument("runs", nargs="+", type=Path, help="run folders or progress.csv files")
    p.add_argument("--out", type=Path, default=Path("curves.png"))
    p.add_argument("--title", default="")
    args = p.parse_args(argv)
    try:
        path = plot_runs(args.runs, args.out, args.title)
    except FileNotFoundError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
