"""Plays the same random keys on the original (through ``probe``) and on this engine, and
compares gold, floor and the screen after every key, under ``"seeding": "original"``.

usage: python compare.py PROBE_BINARY [--seeds 1000:2000] [--steps 500] [--runs] [--seed 0]

The one difference allowed is the documented display fix: a dark room's stairs stay shown
after the player leaves the room (ours ``%``, the original's blank).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile

import numpy as np
from rogue_gym import _native
from rogue_gym.suites import PAPER_ORIGINAL_CONFIG

ACTION_KEYS = "hjklyubns>."
RUN_KEYS = "HJKLYUBN"


def play_original(
    probe: str, config: dict, keys: str
) -> list[tuple[int, int, list[str]]]:
    with tempfile.NamedTemporaryFile("w", suffix=".json") as f:
        json.dump(config, f)
        f.flush()
        out = subprocess.run(
            [probe, f.name, keys],
            check=False,
            capture_output=True,
            text=True,
            timeout=120,
        )
    if out.returncode != 0:
        raise RuntimeError(f"the probe failed: {out.stderr}")
    states = []
    for line in out.stdout.splitlines():
        gold, floor, screen = line.split("\t")
        states.append((int(gold), int(floor), screen.split("\x01")))
    return states


def first_difference(probe: str, seed: int, keys: str) -> tuple[int, str] | None:
    """The first step where the two games differ, with what differs; ``None`` if never."""
    config = {**PAPER_ORIGINAL_CONFIG, "seed": seed}
    game = _native.Game(json.dumps(config), len(keys) + 1, 0.0)
    game.reset(seed)
    for t, (gold, floor, rows) in enumerate(play_original(probe, config, keys)):
        status = game.status()
        if (gold, floor) != (status["gold"], status["dungeon_level"]):
            return (
                t,
                f"gold/floor {gold}/{floor} against ours {status['gold']}/{status['dungeon_level']}",
            )
        ours = game.screen()
        cells = [
            (a, b)
            for r in range(1, len(rows) - 1)
            for a, b in zip(rows[r], ours[r])
            if a != b
        ]
        if any((a, b) != (" ", "%") for a, b in cells):
            return t, "screen:\n" + "\n".join(f"{a}   {b}" for a, b in zip(rows, ours))
        if t < len(keys):
            game.step_key(keys[t])
    return None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("probe")
    parser.add_argument("--seeds", default="1000:2000", help="LO:HI, half-open")
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument(
        "--runs", action="store_true", help="also press the run keys HJKLYUBN"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the random keys")
    args = parser.parse_args(argv)
    lo, hi = (int(x) for x in args.seeds.split(":"))
    alphabet = list(ACTION_KEYS + (RUN_KEYS if args.runs else ""))
    rng = np.random.default_rng(args.seed)
    differing = 0
    for seed in range(lo, hi):
        keys = "".join(rng.choice(alphabet, args.steps))
        diff = first_difference(args.probe, seed, keys)
        if diff is not None:
            differing += 1
            print(f"seed {seed} differs at step {diff[0]}: {diff[1]}")
    print(
        f"{hi - lo - differing} of {hi - lo} seeds play identically for {args.steps} keys"
    )
    return 1 if differing else 0


if __name__ == "__main__":
    sys.exit(main())
