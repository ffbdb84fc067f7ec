#!/usr/bin/env bash
# Builds the portable binary wheel of rogue_gym: abi3 (one wheel for every CPython >= 3.9),
# release profile, tagged manylinux_2_17 (glibc 2.17, CentOS 7 and newer), linked with zig so
# the tag is true; maturin audits the wheel against the tag's symbol policy and fails if it
# does not meet it. Needs cargo; installs maturin and ziglang into .venv if missing.
#
# Usage: bash scripts/build-wheel.sh [--target aarch64] [OUT_DIR]   (default: target/wheels)
#   --target aarch64   cross-builds the wheel for ARM64 Linux (manylinux_2_17_aarch64) on this
#                      machine: zig links it, and cargo needs the aarch64 standard library
#                      (`rustup target add aarch64-unknown-linux-gnu`, done here if missing).
# Prints the wheel's path and size on its last line.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT="$PWD"
TARGET=()
ARCH=$(uname -m)
if [ "${1:-}" = "--target" ]; then
    case "${2:-}" in
        aarch64 | arm64) ARCH=aarch64 ;;
        x86_64 | amd64) ARCH=x86_64 ;;
        *) echo "usage: bash scripts/build-wheel.sh [--target aarch64|x86_64] [OUT_DIR]" >&2; exit 2 ;;
    esac
    TARGET=(--target "$ARCH-unknown-linux-gnu")
    shift 2
    if ! rustup target list --installed 2>/dev/null | grep -qx "$ARCH-unknown-linux-gnu"; then
        echo "== rustup target add $ARCH-unknown-linux-gnu (the standard library for it)"
        rustup target add "$ARCH-unknown-linux-gnu"
    fi
fi
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
echo "== maturin build --release --zig --compatibility manylinux_2_17 (abi3, $ARCH)"
# --zig links against glibc 2.17 symbols through zig's cross toolchain; maturin's own
# auditwheel check then verifies the manylinux_2_17 policy (it fails the build otherwise).
PATH="$ROOT/.venv/bin:$PATH" "$VPY" -m maturin build --release --strip \
    --zig --compatibility manylinux_2_17 --auditwheel check ${TARGET[@]+"${TARGET[@]}"} \
    -m python/Cargo.toml --out "$OUT"

wheel=$(ls -t "$OUT"/rogue_gym-*-cp39-abi3-*"$ARCH".whl | head -n 1)
size=$(du -k "$wheel" | cut -f1)
echo "wheel: $wheel ($size KiB)"
