#!/usr/bin/env bash
# Runs every test of Rogue-Gym: the Rust workspace (unit, integration, doc tests).
# Usage: bash scripts/test.sh
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== cargo test (workspace)"
cargo test --workspace --exclude rogue-gym-python

echo "== Python package (setup, pytest, ruff)"
bash scripts/setup-python.sh
.venv/bin/python -m pytest tests/python -q
.venv/bin/ruff check python tests/python
.venv/bin/ruff format --check python tests/python
