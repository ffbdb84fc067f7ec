"""``python -m rogue_gym.train.plot``: the paper's figures from ``progress.csv`` files.

Two panels against frames: the training score (mean of the last 1000 training episodes) and
the generalization score on the test seeds with its 95% interval, one line per run, labelled
``variant / suite`` from the run's ``config.json``. The random agent's scores (the run's
``random.json``) are drawn as dashed lines::

    python -m rogue_gym.train.plot runs/small-paper10 runs/l2-paper10 --out curves.png

Each argument is a run folder or its ``progress.csv``. Needs matplotlib.

From the paper's analyses (:mod:`.posthoc`), when a run folder has them: post-hoc scores
(``posthoc-S-E.csv``, the largest protocol) replace the in-training evaluations in the
generalization panel; entropy curves (``entropy-S-E.csv``) get a third panel; and one-seed
results (``seed-N.json``) a table (``OUT`` with ``-seed.md``) and a figure of each run's action
probabilities (``OUT`` with ``-seed.png``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

from .progress import read_progress

__all__ = ["load_run", "main", "plot_runs", "seed_table"]


def _csv_rows(path: Path) -> List[Dict[str, float]]:
    import csv

    with path.open() as f:
        return [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]


def _largest(folder: Path, pattern: str) -> List[Dict[str, float]]:
    """Rows of the ``pattern`` file with the largest protocol (seeds x episodes), if any."""
    found = []
    for p in folder.glob(pattern):
        parts = p.stem.split("-")
        if len(parts) == 3 and parts[1].isdigit() and parts[2].isdigit():
            found.append((int(parts[1]) * int(parts[2]), p))
    return _csv_rows(max(found)[1]) if found else []


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


def seed_table(paths: Sequence[Path]) -> str:
    """A markdown table of the runs' one-seed results (``seed-N.json``)."""
    lines = [
        "| run | variant / suite | frames | seed | mean | returns |",
        "|---|---|---:|---:|---:|---|",
    ]
    for path in paths:
        folder = Path(path).parent if Path(path).suffix == ".csv" else Path(path)
        for p in sorted(folder.glob("seed-*.json")):
            r = json.loads(p.read_text())
            rets = ", ".join(f"{x:g}" for x in r["returns"])
            lines.append(
                f"| {r['run']} | {r['variant']} / {r['suite']} | {r['frames']} | {r['seed']} "
                f"| {r['mean']:.2f} | {rets} |"
            )
    return "\n".join(lines) + "\n" if len(lines) > 2 else ""


def _plot_seed_actions(paths: Sequence[Path], out: Path) -> Optional[Path]:
    import matplotlib.pyplot as plt

    results = []
    for path in paths:
        folder = Path(path).parent if Path(path).suffix == ".csv" else Path(path)
        results += [json.loads(p.read_text()) for p in sorted(folder.glob("seed-*.json"))]
    if not results:
        return None
    fig, ax = plt.subplots(figsize=(10, 4))
    keys = list(results[0]["action_probs"])
    width = 0.8 / len(results)
    for i, r in enumerate(results):
        xs = [k + i * width for k in range(len(keys))]
        label = f"{r['run']} (seed {r['seed']}, mean {r['mean']:.1f})"
        ax.bar(xs, [r["action_probs"][k] for k in keys], width=width, label=label)
    ax.set_xticks([k + 0.4 - width / 2 for k in range(len(keys))], keys)
    ax.set_ylabel("mean action probability")
    ax.set_title("action probabilities on one test seed")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def plot_runs(paths: Sequence[Path], out: Path, title: str = "") -> Path:
    """Draw the training and generalization curves of ``paths`` into ``out`` (PNG, SVG...),
    with the entropy panel and the one-seed table and figure where the runs have them."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folders = [Path(p).parent if Path(p).suffix == ".csv" else Path(p) for p in paths]
    entropies = [_largest(f, "entropy-*.csv") for f in folders]
    panels = 3 if any(entropies) else 2
    fig, axes = plt.subplots(1, panels, figsize=(6 * panels, 4.5), sharex=True)
    ax_train, ax_gen = axes[0], axes[1]
    randoms: Dict[str, Dict[str, Any]] = {}
    for path, folder, ent in zip(paths, folders, entropies):
        label, rows, rnd = load_run(path)
        frames = [r["frames"] for r in rows]
        (line,) = ax_train.plot(frames, [r["train_score"] for r in rows], label=label)
        if ent:
            axes[2].plot([r["frames"] for r in ent], [r["entropy"] for r in ent], label=label)
        posthoc = _largest(folder, "posthoc-*.csv")
        ev = posthoc or [r for r in rows if not math.isnan(r["gen_score"])]
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
    for ax in axes:
        ax.set_xlabel("frames")
        ax.set_ylabel("return")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    if panels == 3:
        axes[2].set_title("policy entropy on training seeds")
        axes[2].set_ylabel("nats per step")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    table = seed_table(paths)
    if table:
        out.with_name(out.stem + "-seed.md").write_text(table)
        _plot_seed_actions(paths, out.with_name(out.stem + "-seed" + out.suffix))
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
