#!/usr/bin/env bash
# The main job: builds Rogue-Gym and its Python package (the light set-up: numpy, gymnasium,
# maturin), then a random agent plays the paper's config (embedded default) through the
# shared-memory pool, printing steps/s and score.
# Usage: bash scripts/demo.sh [extra args for python/examples/random_agent.py]
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup-python.sh --light
exec .venv/bin/python python/examples/random_agent.py "$@"
