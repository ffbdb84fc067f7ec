#!/usr/bin/env bash
# Runs every test of Rogue-Gym: the Rust workspace (unit, integration, doc tests), the Python
# package (set-up, type checks, stub check, pytest, ruff), the Ray tests in their own
# environment (.venv-ray: Ray pins an older gymnasium), then the wheel and a selection of the
# tests on Debian's own CPython 3.14 and 3.15 (scripts/debian-pythons.sh: needs root, as CI
# is; elsewhere it says it skips them).
# Usage: bash scripts/test.sh
set -euo pipefail
cd "$(dirname "$0")/.."

# The Rust tests build in the release profile, as the extension does: the two then share most
# of one build of the dependencies, and what is tested is what ships. On the 2-core VM, from an
# empty target, the tests' build took 203 s in release against 361 s in the dev profile
# (whose dependencies are optimised and carry full debug info), and the extension's 83 s more
# against 120 s.
echo "== cargo test --release (workspace)"
cargo test --release --workspace --exclude rogue-gym-python
# The model-checked handshake between worker and supervisor (loom: every interleaving and
# every reordering the C11 memory model allows; docs/platforms.md).
echo "== loom ($SECONDS s into the test command)"
# The same packages as above, so that only this crate and its dependents are built again.
cargo test --release --workspace --exclude rogue-gym-python --features rogue-gym-pool/loom --lib loom

echo "== Python package (setup, types, stubs, pytest, ruff) ($SECONDS s into the test command)"
bash scripts/setup-python.sh
# Ray's venv is installed meanwhile: its pip runs on one core while the type checks run on the
# other, and it is done before pytest starts (its output is shown then; killed if a check fails).
source scripts/background.sh
bg_start ray bash scripts/setup-ray.sh
# The portable wheel (zig links it anew: about 2 minutes of both cores) builds meanwhile too,
# on what the type checks and Ray's pip leave of the cores, and is done before pytest starts
# (nothing then competes with the tests' timings); tests/python/test_wheel.py takes it from
# ROGUE_GYM_WHEEL_DIR.
if [[ ${ROGUE_GYM_SKIP_WHEEL:-} != 1 ]]; then
    bg_temp_dir ROGUE_GYM_WHEEL_DIR
    export ROGUE_GYM_WHEEL_DIR
    bg_start wheel bash scripts/build-wheel.sh "$ROGUE_GYM_WHEEL_DIR"
fi
# Debian's CPython 3.14 and 3.15 (a forky root, made once per machine, reused after) get
# ready meanwhile too: mostly downloads and unpacking, done before pytest starts.
DEBIAN=0
if [[ ${ROGUE_GYM_SKIP_WHEEL:-} != 1 && ${ROGUE_GYM_SKIP_DEBIAN:-} != 1 && $(id -u) == 0 ]]; then
    DEBIAN=1
    bg_start debian bash scripts/debian-pythons.sh root
fi
(cd python && ../.venv/bin/python -m mypy && ../.venv/bin/python -m mypy.stubtest rogue_gym._native)
echo "== waiting for Ray's set-up ($SECONDS s into the test command)"
bg_wait ray
if [[ ${ROGUE_GYM_SKIP_WHEEL:-} != 1 ]]; then
    echo "== waiting for the wheel's build ($SECONDS s into the test command)"
    bg_wait wheel
fi
if [[ $DEBIAN == 1 ]]; then
    echo "== waiting for Debian's CPython 3.14 and 3.15 ($SECONDS s into the test command)"
    bg_wait debian
fi
# Every test runs under a time limit (tests/python/conftest.py), so no test can hang the run.
echo "== pytest ($SECONDS s into the test command)"
.venv/bin/python -m pytest tests/python -q --durations=15
.venv/bin/ruff check python tests/python tests/ray benchmarks scripts
.venv/bin/ruff format --check python tests/python tests/ray benchmarks scripts

echo "== Ray (RLlib through pools, actor-backed vector env) on a local 2-CPU cluster ($SECONDS s into the test command)"
# Each test has a time limit (pytest-timeout); the whole run has one too.
timeout 1200 .venv-ray/bin/python -m pytest tests/ray -q -p no:cacheprovider

if [[ $DEBIAN == 1 ]]; then
    echo "== the wheel on Debian's CPython 3.14 and 3.15 ($SECONDS s into the test command)"
    timeout 1800 bash scripts/debian-pythons.sh test "$ROGUE_GYM_WHEEL_DIR"
else
    echo "== skipped: the wheel on Debian's CPython 3.14 and 3.15 (needs root for its chroot, and the wheel; CI runs it)"
fi
