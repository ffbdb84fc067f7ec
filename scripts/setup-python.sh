#!/usr/bin/env bash
# Creates (or refreshes) the repository's .venv, installs the Python dev dependencies and builds
# and installs the rogue_gym extension into it. Idempotent and non-interactive.
# Usage: bash scripts/setup-python.sh
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT="$PWD"
PY="${PYTHON:-python3}"

if [ ! -x .venv/bin/python ]; then
    echo "== creating .venv with $($PY --version 2>&1)"
    "$PY" -m venv .venv
fi
VPY="$ROOT/.venv/bin/python"

echo "== pip install -r python/requirements-dev.txt"
"$VPY" -m pip install -q --disable-pip-version-check --upgrade pip
"$VPY" -m pip install -q --disable-pip-version-check -r python/requirements-dev.txt

echo "== maturin develop --release (rogue_gym._native)"
# maturin installs into the active virtualenv.
VIRTUAL_ENV="$ROOT/.venv" PATH="$ROOT/.venv/bin:$PATH" \
    "$ROOT/.venv/bin/maturin" develop --release --quiet -m python/Cargo.toml

"$VPY" -c "import rogue_gym, rogue_gym._native as n; print('rogue_gym', rogue_gym.__version__, 'ok:', n.__file__)"
