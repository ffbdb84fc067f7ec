#!/usr/bin/env bash
# Today's Pythons: Debian's own CPython 3.14 and 3.15 (a Debian forky root made with
# debootstrap), each with a venv that installs the abi3 wheel and runs a selection of the
# Python tests against it. Needs root (chroot, mounts) on a Debian-like x86-64 machine;
# installs debootstrap with apt-get where it is missing. Downloads only from the registries:
# Debian's forky packages (the root, about 120 MB, once) and PyPI's wheels for each
# interpreter (about 60 MB, once), fetched by this machine's pip.
#
#   bash scripts/debian-pythons.sh root              # make the root and its venvs (once)
#   bash scripts/debian-pythons.sh test WHEEL_DIR    # the wheel of WHEEL_DIR, the chosen tests,
#                                                    # on every interpreter, one after another
#   bash scripts/debian-pythons.sh run 3.14 -- CMD   # run CMD in that interpreter's venv
#                                                    # (the repository is at /src, read-only)
#
# The root lives in $ROGUE_GYM_FORKY_ROOT (default ~/.cache/rogue-gym/forky-root) and is
# reused; `rm -rf` it to start afresh. Every mount is made in a private mount namespace
# (unshare), so nothing stays mounted when the script ends, however it ends. What bookworm's
# tools need for forky: debootstrap has no forky script (sid's builds it), and forky's Release
# files carry a Valid-Until that apt must not hold against them.
# The chosen tests (TESTS below) drive the pool through its public API: the gymnasium faces,
# hosted envs, the async API, envs on threads, trust, faults, /dev/shm, EnvPool's API, the
# registry, multiprocessing's start methods; SB3's and torch's tests skip where they are not
# installed (torch's PyPI wheels carry CUDA, gigabytes per interpreter: not in CI's budget).
# Times on the 2-core VM: the root 5-7 min (once), the tests about 3 min per interpreter.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT="$PWD"
FORKY="${ROGUE_GYM_FORKY_ROOT:-$HOME/.cache/rogue-gym/forky-root}"
MIRROR="${DEBIAN_MIRROR:-http://deb.debian.org/debian}"
PYTHONS=(3.14 3.15)
# What each venv installs (wheels from PyPI for that interpreter).
PY_PKGS=("numpy>=1.24" "gymnasium>=1.1,<2" "cloudpickle>=2" "pytest>=7" "pytest-timeout")
TESTS=(test_platform.py test_start_methods.py test_async.py test_threads.py test_trust.py
    test_shm.py test_registry.py test_vector.py test_envpool.py test_security.py)
# Another selection (pytest node ids, space-separated), for a quick look at one test.
[ -n "${ROGUE_GYM_DEBIAN_TESTS:-}" ] && read -ra TESTS <<<"$ROGUE_GYM_DEBIAN_TESTS"
HOST_PY="${PYTHON:-python3}"
[ -x "$ROOT/.venv/bin/python" ] && HOST_PY="$ROOT/.venv/bin/python"

die() { echo "error: $*" >&2; exit 1; }
[ "$(id -u)" = 0 ] || die "needs root (chroot, mounts): run it as root"
[ "$(uname -m)" = x86_64 ] || die "made for an x86-64 host (this is $(uname -m))"

# Run "$@" inside the root (a private mount namespace: /proc, a 512 MiB /dev/shm of its own,
# a private /tmp, the repository read-only at /src).
in_root() {
    mkdir -p "$FORKY/src" "$FORKY/dev/shm"
    cp /etc/resolv.conf "$FORKY/etc/resolv.conf"
    unshare --mount --propagation private -- sh -c '
        set -e
        r=$1; src=$2; shift 2
        mount -t proc proc "$r/proc"
        mount --rbind /dev "$r/dev"
        mount -t tmpfs -o size=512m,mode=1777 tmpfs "$r/dev/shm"
        mount -t tmpfs tmpfs "$r/tmp"
        mount --bind "$src" "$r/src"
        mount -o remount,bind,ro "$r/src"
        exec chroot "$r" /usr/bin/env -i HOME=/root PATH=/usr/bin:/bin LANG=C.UTF-8 "$@"
    ' sh "$FORKY" "$ROOT" "$@"
}

make_root() {
    if ! command -v debootstrap >/dev/null; then
        echo "== apt-get install debootstrap"
        apt-get update -q >/dev/null
        DEBIAN_FRONTEND=noninteractive apt-get install -y -q debootstrap >/dev/null
    fi
    if [ ! -x "$FORKY/usr/bin/python3.15" ]; then
        echo "== debootstrap forky into $FORKY"
        rm -rf "$FORKY"
        mkdir -p "$(dirname "$FORKY")"
        local pkgs=ca-certificates
        for v in "${PYTHONS[@]}"; do pkgs+=",python$v,python$v-venv"; done
        # Bookworm's debootstrap has no forky script; sid's makes it.
        debootstrap --variant=minbase --include="$pkgs" forky "$FORKY" "$MIRROR" \
            /usr/share/debootstrap/scripts/sid
        echo 'Acquire::Check-Valid-Until "false";' >"$FORKY/etc/apt/apt.conf.d/99no-valid-until"
    fi
    for v in "${PYTHONS[@]}"; do
        local venv="/opt/py$v"
        # The venv's python links to the root's interpreter: the marker says it is complete.
        [ -e "$FORKY$venv/.complete" ] && continue
        # The wheels are fetched here, by this machine's pip (its certificates and proxy), for
        # that interpreter, then installed in the root from the folder.
        echo "== wheels for CPython $v: ${PY_PKGS[*]}"
        "$HOST_PY" -m pip download -q --disable-pip-version-check --retries 10 --timeout 60 \
            --only-binary=:all: --implementation cp --python-version "$v" \
            --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 \
            --platform manylinux_2_28_x86_64 --platform any \
            -d "$FORKY/opt/wheels-$v" "${PY_PKGS[@]}"
        echo "== the venv of CPython $v ($venv)"
        in_root "/usr/bin/python$v" -m venv "$venv"
        in_root "$venv/bin/python" -m pip install -q --disable-pip-version-check --no-index \
            --find-links "/opt/wheels-$v" "${PY_PKGS[@]}"
        touch "$FORKY$venv/.complete"
    done
    for v in "${PYTHONS[@]}"; do
        in_root "/opt/py$v/bin/python" -c \
            "import platform, numpy, gymnasium; print('== root ok: CPython', platform.python_version(), 'numpy', numpy.__version__, 'gymnasium', gymnasium.__version__)"
    done
}

install_wheel() {
    local dir=$1 v=$2 wheel
    wheel=$(ls -t "$dir"/rogue_gym-*-manylinux*_x86_64.whl 2>/dev/null | head -n 1)
    [ -n "$wheel" ] || die "no x86-64 wheel in $dir: run 'bash scripts/build-wheel.sh $dir'"
    mkdir -p "$FORKY/opt/wheel"
    cp "$wheel" "$FORKY/opt/wheel/"
    echo "== installing $(basename "$wheel") in CPython $v's venv"
    in_root "/opt/py$v/bin/python" -m pip install -q --disable-pip-version-check --no-deps \
        --force-reinstall "/opt/wheel/$(basename "$wheel")"
}

run_tests() {
    local v=$1 t0=$SECONDS
    echo "== the chosen tests on Debian's CPython $v"
    # Outside /src: the tests import the installed wheel, not the checkout's package (the
    # examples some tests run come along, where the tests look for them).
    in_root /bin/sh -c "mkdir -p /tmp/w/tests /tmp/w/python && cp -r /src/tests/python /tmp/w/tests/ &&
        cp -r /src/python/examples /tmp/w/python/ && cd /tmp/w/tests/python &&
        /opt/py$v/bin/python -c 'import rogue_gym, sys; print(\"rogue_gym\", rogue_gym.__version__, \"on\", sys.version.split()[0])' &&
        timeout 1200 /opt/py$v/bin/python -m pytest -q -p no:cacheprovider -o addopts='' \
            --rootdir /tmp/w/tests/python ${TESTS[*]}"
    echo "== CPython $v: the chosen tests passed in $((SECONDS - t0)) s"
}

case "${1:-}" in
    root) make_root ;;
    test)
        [ -n "${2:-}" ] || die "usage: bash scripts/debian-pythons.sh test WHEEL_DIR"
        make_root
        for v in "${PYTHONS[@]}"; do
            install_wheel "$2" "$v"
            run_tests "$v"
        done
        ;;
    run)
        v=${2:-}
        shift 2 || true
        [ "${1:-}" = "--" ] && shift
        [[ " ${PYTHONS[*]} " == *" $v "* ]] && (($#)) ||
            die "usage: bash scripts/debian-pythons.sh run 3.14|3.15 -- CMD..."
        make_root >/dev/null
        in_root "/opt/py$v/bin/python" "$@"
        ;;
    *)
        sed -n '2,27p' "$0" | sed 's/^# \{0,1\}//'
        exit 2
        ;;
esac
