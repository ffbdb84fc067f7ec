#!/usr/bin/env bash
# Creates (or refreshes) the repository's .venv, installs the Python dependencies and builds
# and installs the rogue_gym extension into it. Idempotent and non-interactive.
#
# Usage: bash scripts/setup-python.sh            # everything the test suite needs
#        bash scripts/setup-python.sh --light    # only the package (numpy, gymnasium): no torch
#        bash scripts/setup-python.sh --deps     # the downloads only, no build (CI starts
#                                                # them beside its lints; a later run builds)
#
# The full set-up downloads about 3 GB from PyPI (torch and its CUDA libraries are most of it;
# PyPI has no CPU-only torch for Linux) and fills about 5.6 GB; allow 5-10 minutes on a fresh
# machine. The light set-up downloads about 60 MB. Both build the extension with cargo
# (2-4 minutes on 2 cores). A failed download is retried.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT="$PWD"
PY="${PYTHON:-python3}"
LIGHT=0
BUILD=1
case "${1:-}" in
    --light) LIGHT=1 ;;
    --deps) BUILD=0 ;;
    "") ;;
    *) echo "usage: bash scripts/setup-python.sh [--light | --deps]" >&2; exit 2 ;;
esac

# pip with its own network retries, and the whole call retried with a pause: a dropped
# connection in the middle of a large wheel otherwise ends the set-up (seen once on a fresh
# machine as an OSError).
pip_install() {
    local attempt
    for attempt in 1 2 3; do
        if "$VPY" -m pip install -q --disable-pip-version-check --retries 10 --timeout 60 "$@"; then
            return 0
        fi
        echo "== pip install failed (attempt $attempt of 3); retrying in $((attempt * 10)) s" >&2
        sleep $((attempt * 10))
    done
    echo "error: pip install $* failed 3 times; check the network or the package index" >&2
    return 1
}

if [ ! -x .venv/bin/python ]; then
    echo "== creating .venv with $($PY --version 2>&1)"
    "$PY" -m venv .venv
fi
VPY="$ROOT/.venv/bin/python"

pip_install --upgrade pip
if [ "$LIGHT" = 1 ]; then
    echo "== pip install maturin (light set-up: the package only)"
    pip_install "maturin>=1.16,<2"
else
    echo "== pip install -r python/requirements-dev.txt"
    pip_install -r python/requirements-dev.txt
fi

if [ "$BUILD" = 0 ]; then
    echo "== dependencies installed ($SECONDS s); the extension is built by a later run"
    exit 0
fi

echo "== maturin develop --release (rogue_gym._native) ($SECONDS s into the set-up)"
# maturin installs into the active virtualenv, with the package's own dependencies.
VIRTUAL_ENV="$ROOT/.venv" PATH="$ROOT/.venv/bin:$PATH" \
    "$VPY" -m maturin develop --release --quiet -m python/Cargo.toml

"$VPY" -c "import rogue_gym, rogue_gym._native as n; print('rogue_gym', rogue_gym.__version__, 'ok:', n.__file__)"
