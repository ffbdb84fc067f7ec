"""The generalization suites are frozen: their definitions may never change silently."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from rogue_gym.suites import PAPER_CONFIG, SUITES, get_suite, suite_names

ORACLE = (
    Path(__file__).resolve().parents[3]
    / "shared/reference/original-dungeons/paper-seeds-v0.0.2.jsonl"
)

# sha256 of each suite's canonical JSON (config + max_steps + stair_reward + seed lists +
# episodes per seed). DO NOT UPDATE these to make a test pass: a suite whose definition
# changes is a different benchmark and needs a NEW suite name (published scores refer to
# these digests).
FROZEN_DIGESTS = {
    "paper-10": "4e2db96dbf9beba6b878cf8a370bfd59265975de04841025f71b9069ddd6c372",
    "paper-20": "db9d5d2076a323751b4a6c83f67517df13eda59753ca13bbf43c36ab0a55c3b9",
    "paper-40": "0ec825986afa9aaf6866c100bc90a6cc5edad07a00eaccd9e109b2862a250608",
    "paper-10-original": "4dbf37eba7892745dd84f4724dbc0b7c5bb414ddaf03e7786c0e9c775a73cbe8",
    "paper-20-original": "f77614390f4fb257a591b5c698d0fed3a0e5395ab4bf4233d84f1d9ded087b4c",
    "paper-40-original": "3319f4b233612a8048e23c676524cf73e23bfc877ae9240a5a6b6f300abbd57c",
    "rogue-80x24-enemies": "a58d8f3554ca509a20bb2571b89f6b8bdb9faae08d30c51bfb6b4a09ca2f69a1",
}


def test_every_suite_is_frozen() -> None:
    assert set(suite_names()) == set(FROZEN_DIGESTS)
    for name, digest in FROZEN_DIGESTS.items():
        assert get_suite(name).digest() == digest, f"suite {name} changed: use a new name"


@pytest.mark.parametrize("n", [10, 20, 40])
def test_paper_suites_follow_the_paper(n: int) -> None:
    s = get_suite(f"paper-{n}")
    assert s.config == PAPER_CONFIG
    assert s.config["width"] == 32 and s.config["height"] == 16
    assert s.config["dungeon"]["room_num_x"] == 2 and s.config["dungeon"]["room_num_y"] == 2
    assert s.config["enemies"] == {"enemies": []}
    assert s.max_steps == 500 and s.stair_reward == 50.0
    assert s.train_seed_list() == list(range(n))
    assert s.test_seed_list() == list(range(1000, 2000))
    assert s.episodes_per_seed == 10


@pytest.mark.parametrize("n", [10, 20, 40])
def test_original_suites_are_the_paper_suites_with_the_originals_seeding(n: int) -> None:
    paper, original = get_suite(f"paper-{n}"), get_suite(f"paper-{n}-original")
    assert original.config == {**paper.config, "seeding": "original"}
    assert original.canonical() == {
        **paper.canonical(),
        "name": original.name,
        "config": original.config,
    }


def test_original_suites_start_in_the_originals_dungeons() -> None:
    """Through the Python env: the player starts where the original put it, on the test seeds."""
    if not ORACLE.exists():
        assert os.environ.get("CI") != "true", f"CI needs ../shared beside the repository: {ORACLE}"
        pytest.skip(f"{ORACLE} is missing")
    from rogue_gym.envs import RogueEnv

    starts = {}
    for line in ORACLE.read_text().splitlines():
        rec = json.loads(line)
        if rec["floor"] == 1 and 1000 <= rec["seed"] < 1020:
            starts[rec["seed"]] = tuple(rec["player_start"])
    assert len(starts) == 20
    env = RogueEnv(config_dict=get_suite("paper-10-original").config)
    for seed, (x, y) in starts.items():
        env.reset(seed=seed)
        assert env.get_dungeon()[y][x] == "@", seed
    env.close()


def test_train_and_test_seeds_are_disjoint() -> None:
    for s in SUITES.values():
        assert not set(s.train_seed_list()) & set(s.test_seed_list()), s.name
        assert "seed" not in s.config and "seed_range" not in s.config


def test_harder_suite() -> None:
    s = get_suite("rogue-80x24-enemies")
    assert (s.config["width"], s.config["height"]) == (80, 24)
    assert "enemies" not in s.config  # the default: all 26 monsters
    assert s.max_steps == 1000
    assert s.train_seed_list() == list(range(40))


def test_canonical_json_is_stable_and_complete() -> None:
    s = get_suite("paper-40")
    doc = json.loads(s.canonical_json())
    assert doc["config"] == PAPER_CONFIG
    assert doc["train_seeds"] == list(range(40))
    assert len(doc["test_seeds"]) == 1000
    assert s.canonical_json() == get_suite("paper-40").canonical_json()
    assert json.loads(s.config_json()) == PAPER_CONFIG


def test_unknown_suite_names_the_known_ones() -> None:
    with pytest.raises(KeyError, match="paper-40"):
        get_suite("paper-41")
