#!/usr/bin/env bash
# Builds the portable binary wheel of rogue_gym: abi3 (one wheel for every CPython >= 3.9),
# release profile, tagged manylinux_2_17 (glibc 2.17, CentOS 7 and newer), linked with zig so
# the tag is true; maturin audits the wheel against the tag's symbol policy and fails if it
# does not meet it. Needs cargo; installs maturin and ziglang into .venv if missing.
#
# Usage: bash scripts/build-wheel.sh [OUT_DIR]      (default: target/wheels)
# Prints the wheel's path and size on its last line.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT="$PWD"
OUT="${1:-$ROOT/target/wheels}"
PY="${PYTHON:-python3}"

if [ ! -x .venv/bin/python ]; then
    "$PY" -m venv .venv
fi
VPY="$ROOT/.venv/bin/python"
if ! "$VPY" -c "import maturin, ziglang" 2>/dev/null; then
    echo "== pip install maturin ziglang"
    "$VPY" -m pip install -q --disable-pip-version-check --retries 10 --timeout 60 \
        "maturin>=1.16,<2" "ziglang>=0.13"
fi

mkdir -p "$OUT"
echo "== maturin build --release --zig --compatibility manylinux_2_17 (abi3)"
# --zig links against glibc 2.17 symbols through zig's cross toolchain; maturin's own
# auditwheel check then verifies the manylinux_2_17 policy (it fails the build otherwise).
PATH="$ROOT/.venv/bin:$PATH" "$VPY" -m maturin build --release --strip \
    --zig --compatibility manylinux_2_17 --auditwheel check \
    -m python/Cargo.toml --out "$OUT"

wheel=$(ls -t "$OUT"/rogue_gym-*-cp39-abi3-*.whl | head -n 1)
size=$(du -k "$wheel" | cut -f1)
echo "wheel: $wheel ($size KiB)"
