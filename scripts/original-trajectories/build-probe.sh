#!/usr/bin/env bash
# Builds the probe against the original's core (Rogue-Gym v0.0.2). Usage:
#   scripts/original-trajectories/build-probe.sh ORIGINAL_CORE_DIR BUILD_DIR
# ORIGINAL_CORE_DIR is the `core` folder of the original at tag v0.0.2
# (`git -C <clone> archive v0.0.2 core | tar -x -C <dest>`). Prints the probe binary's path.
set -euo pipefail
core=$(cd "$1" && pwd)
build=$2
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$build/src"
cat > "$build/Cargo.toml" <<TOML
[package]
name = "rogue-gym-original-probe"
version = "0.0.0"
edition = "2021"
publish = false

[dependencies]
rogue-gym-core = { path = "$core" }

[workspace]
TOML
cp "$here/probe.rs" "$build/src/main.rs"
cd "$build"
cargo generate-lockfile -q
# The pins the original's README of the oracle gives (../shared/reference/original-dungeons/).
cargo update -q -p ndarray@0.17.2 --precise 0.12.1 2>/dev/null || true
cargo update -q -p termion --precise 1.5.2
cargo build -q --release >&2
echo "$build/target/release/rogue-gym-original-probe"
