"""``python -m rogue_gym.tuning ENV``: tune from the command line."""

from __future__ import annotations

import argparse
import sys
from typing import Optional, Sequence

from ..registration import ENV_ID
from .search import tune


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Command-line entry point."""
    p = argparse.ArgumentParser(
        prog="python -m rogue_gym.tuning",
        description="Time the pool's candidate layouts for one env and print the best.",
    )
    p.add_argument("env", help=f"a gymnasium id, module:callable, or {ENV_ID} (the native game)")
    p.add_argument("--num-envs", type=int, default=64)
    p.add_argument("--seconds", type=float, default=2.0, help="timed seconds per run")
    p.add_argument("--rounds", type=int, default=3)
    args = p.parse_args(argv)
    if args.num_envs < 1 or args.seconds <= 0 or args.rounds < 1:
        p.error("--num-envs, --seconds and --rounds must be positive")
    tune(args.env, args.num_envs, seconds=args.seconds, rounds=args.rounds, out=sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
