#!/usr/bin/env bash
# The aarch64 (ARM64 Linux) wheel, cross-built here and run under emulation: an arm64 Debian
# root (debootstrap) whose programs run through binfmt_misc and qemu-user-static, so that the
# pool's worker processes, which are exec'd, run emulated too. Needs root (chroot, mounts) on
# a Debian-like x86-64 machine; installs qemu-user-static, binfmt-support and debootstrap with
# apt-get where they are missing. Downloads only from the registries: Debian's arm64 packages
# (the root, about 90 MB, once), PyPI's aarch64 wheels of numpy, gymnasium and pytest (about
# 20 MB, once, fetched by this machine's pip), and the aarch64 standard library for cargo
# (rustup, once).
#
#   bash scripts/aarch64.sh build          # cross-build the wheel (target/wheels-aarch64)
#   bash scripts/aarch64.sh root           # make the arm64 root with its Python venv
#   bash scripts/aarch64.sh test           # build + root, then the chosen tests, emulated
#   bash scripts/aarch64.sh run -- CMD...  # run CMD in the root, the wheel installed
#                                          # (the repository is at /src, read-only)
#
# The root lives in $ROGUE_GYM_AARCH64_ROOT (default ~/.cache/rogue-gym/aarch64-root) and is
# reused; `rm -rf` it to start afresh. Every mount is made in a private mount namespace
# (unshare), so nothing stays mounted when the script ends, however it ends.
# The chosen tests: tests/python/test_platform.py (the native pool sync and async, a hosted env
# against SyncVectorEnv, a worker killed mid-step, the /dev/shm budget, determinism across 1
# and 2 workers, a stress test of rows and kills). Times on the 2-core VM: the cross-build
# 4-6 min, the root 3-5 min (once), the tests 3-6 min under emulation.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT="$PWD"
ARM_ROOT="${ROGUE_GYM_AARCH64_ROOT:-$HOME/.cache/rogue-gym/aarch64-root}"
WHEELS="$ROOT/target/wheels-aarch64"
SUITE=bookworm
MIRROR="${DEBIAN_MIRROR:-http://deb.debian.org/debian}"
# The Python packages of the emulated venv (aarch64 wheels from PyPI).
PY_PKGS=("numpy>=1.24" "gymnasium>=1.1,<2" "cloudpickle>=2" "pytest>=7" "pytest-timeout")
# The Python that fetches them (with pip): the checkout's venv, else the system's.
HOST_PY="${PYTHON:-python3}"
[ -x "$ROOT/.venv/bin/python" ] && HOST_PY="$ROOT/.venv/bin/python"

die() { echo "error: $*" >&2; exit 1; }
[ "$(id -u)" = 0 ] || die "needs root (chroot, mounts): run it as root"
[ "$(uname -m)" = x86_64 ] || die "made for an x86-64 host (this is $(uname -m))"

need_tools() {
    local missing=()
    command -v qemu-aarch64-static >/dev/null || missing+=(qemu-user-static)
    command -v update-binfmts >/dev/null || missing+=(binfmt-support)
    command -v debootstrap >/dev/null || missing+=(debootstrap)
    if ((${#missing[@]})); then
        echo "== apt-get install ${missing[*]}"
        apt-get update -q >/dev/null
        DEBIAN_FRONTEND=noninteractive apt-get install -y -q "${missing[@]}" >/dev/null
    fi
    # binfmt_misc: the kernel hands aarch64 programs to qemu (F: the interpreter is opened
    # now, so it works inside the chroot too).
    if [ ! -e /proc/sys/fs/binfmt_misc/status ]; then
        mount -t binfmt_misc binfmt_misc /proc/sys/fs/binfmt_misc
    fi
    if [ ! -e /proc/sys/fs/binfmt_misc/qemu-aarch64 ]; then
        update-binfmts --enable qemu-aarch64 >/dev/null 2>&1 || update-binfmts --import qemu-aarch64
    fi
    grep -q enabled /proc/sys/fs/binfmt_misc/qemu-aarch64 ||
        die "binfmt_misc has no enabled qemu-aarch64 entry"
}

build() {
    echo "== cross-building the aarch64 wheel"
    rm -rf "$WHEELS"
    bash scripts/build-wheel.sh --target aarch64 "$WHEELS"
}

# Run "$@" inside the root (a private mount namespace: /proc, a 256 MiB /dev/shm of its own,
# the repository read-only at /src).
in_root() {
    mkdir -p "$ARM_ROOT/src" "$ARM_ROOT/dev/shm"
    cp /etc/resolv.conf "$ARM_ROOT/etc/resolv.conf"
    unshare --mount --propagation private -- sh -c '
        set -e
        r=$1; src=$2; shift 2
        mount -t proc proc "$r/proc"
        mount --rbind /dev "$r/dev"
        mount -t tmpfs -o size=256m,mode=1777 tmpfs "$r/dev/shm"
        mount -t tmpfs tmpfs "$r/tmp"
        mount --bind "$src" "$r/src"
        mount -o remount,bind,ro "$r/src"
        exec chroot "$r" /usr/bin/env -i HOME=/root PATH=/opt/venv/bin:/usr/bin:/bin \
            LANG=C.UTF-8 "$@"
    ' sh "$ARM_ROOT" "$ROOT" "$@"
}

make_root() {
    need_tools
    if [ ! -x "$ARM_ROOT/opt/venv/bin/python" ]; then
        if [ ! -x "$ARM_ROOT/usr/bin/python3" ]; then
            echo "== debootstrap $SUITE arm64 into $ARM_ROOT"
            rm -rf "$ARM_ROOT"
            mkdir -p "$(dirname "$ARM_ROOT")"
            debootstrap --arch=arm64 --variant=minbase \
                --include=python3,python3-venv,ca-certificates,util-linux \
                "$SUITE" "$ARM_ROOT" "$MIRROR"
        fi
        # The aarch64 wheels are fetched here, by this machine's pip (its proxy and
        # certificates), for the root's CPython, then installed there from the folder.
        local pyver
        pyver=$(in_root /usr/bin/python3 -c 'import sys; print(f"{sys.version_info[0]}.{sys.version_info[1]}")')
        echo "== aarch64 wheels for CPython $pyver: ${PY_PKGS[*]}"
        "$HOST_PY" -m pip download -q --disable-pip-version-check --retries 10 --timeout 60 \
            --only-binary=:all: --implementation cp --python-version "$pyver" \
            --platform manylinux_2_17_aarch64 --platform manylinux2014_aarch64 \
            --platform manylinux_2_28_aarch64 --platform any \
            -d "$ARM_ROOT/opt/wheels" "${PY_PKGS[@]}"
        echo "== the emulated venv (/opt/venv)"
        in_root /usr/bin/python3 -m venv /opt/venv
        in_root /opt/venv/bin/python -m pip install -q --disable-pip-version-check --no-index \
            --find-links /opt/wheels "${PY_PKGS[@]}"
    fi
    in_root /opt/venv/bin/python -c \
        "import platform, numpy; print('== root ok:', platform.machine(), platform.python_version(), 'numpy', numpy.__version__)"
}

install_wheel() {
    local wheel
    wheel=$(ls -t "$WHEELS"/rogue_gym-*-manylinux*_aarch64.whl 2>/dev/null | head -n 1)
    [ -n "$wheel" ] || die "no aarch64 wheel in $WHEELS: run 'bash scripts/aarch64.sh build'"
    echo "== installing $(basename "$wheel") in the emulated venv"
    in_root /opt/venv/bin/python -m pip install -q --disable-pip-version-check --no-deps \
        --force-reinstall "/src/${wheel#"$ROOT"/}"
}

run_tests() {
    echo "== the chosen tests under emulation (tests/python/test_platform.py)"
    local t0=$SECONDS
    # Outside /src: the tests import the installed wheel, not the checkout's package.
    in_root /bin/sh -c 'cp -r /src/tests/python /tmp/tests && cd /tmp/tests &&
        python -c "import rogue_gym, platform; print(\"rogue_gym\", rogue_gym.__version__, \"on\", platform.machine())" &&
        timeout 1800 python -m pytest -q -p no:cacheprovider -o addopts="" \
            --rootdir /tmp/tests test_platform.py'
    echo "== emulated tests passed in $((SECONDS - t0)) s"
}

case "${1:-}" in
    build) build ;;
    root) make_root ;;
    test)
        build
        make_root
        install_wheel
        run_tests
        ;;
    run)
        shift
        [ "${1:-}" = "--" ] && shift
        (($#)) || die "usage: bash scripts/aarch64.sh run -- CMD..."
        make_root >/dev/null
        install_wheel
        in_root "$@"
        ;;
    *)
        sed -n '2,23p' "$0" | sed 's/^# \{0,1\}//'
        exit 2
        ;;
esac
