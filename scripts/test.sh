#!/usr/bin/env bash
# Runs every test of Rogue-Gym: the Rust workspace (unit, integration, doc tests).
# Usage: bash scripts/test.sh
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== cargo test (workspace)"
cargo test --workspace --exclude rogue-gym-python
