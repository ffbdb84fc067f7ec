#!/usr/bin/env bash
# Runs every test of Rogue-Gym: the Rust workspace (unit, integration, doc tests), the Python
# package (set-up, type checks, stub check, pytest, ruff), then the Ray tests in their own
# environment (.venv-ray: Ray pins an older gymnasium).
# Usage: bash scripts/test.sh
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== cargo test (workspace)"
cargo test --workspace --exclude rogue-gym-python
# The model-checked handshake between worker and supervisor (loom: every interleaving and
# every reordering the C11 memory model allows; docs/platforms.md).
echo "== loom ($SECONDS s in)"
# The same packages as above, so that only this crate and its dependents are built again.
cargo test --workspace --exclude rogue-gym-python --features rogue-gym-pool/loom --lib loom

echo "== Python package (setup, types, stubs, pytest, ruff) ($SECONDS s in)"
bash scripts/setup-python.sh
(cd python && ../.venv/bin/python -m mypy && ../.venv/bin/python -m mypy.stubtest rogue_gym._native)
# Every test runs under a time limit (tests/python/conftest.py), so no test can hang the run.
echo "== pytest ($SECONDS s in)"
.venv/bin/python -m pytest tests/python -q
.venv/bin/ruff check python tests/python tests/ray benchmarks scripts
.venv/bin/ruff format --check python tests/python tests/ray benchmarks scripts

echo "== Ray (RLlib through pools, actor-backed vector env) on a local 2-CPU cluster ($SECONDS s in)"
bash scripts/setup-ray.sh
# Each test has a time limit (pytest-timeout); the whole run has one too.
timeout 1200 .venv-ray/bin/python -m pytest tests/ray -q -p no:cacheprovider
