#!/usr/bin/env bash
# Runs a command (as root) in a private mount namespace with a fresh, empty /tmp and /dev/shm,
# so that the security tests can plant files and act as other users without touching the
# machine's real ones. The repository (which may live under /tmp, as CI's clone does) and the
# Python interpreter (under /root) stay reachable, also for another uid: their parents are
# re-made 0755 in the namespace and the directories themselves are bind-mounted back.
# Usage: unshare --mount --propagation private bash private_namespace.sh CMD ARGS...
set -euo pipefail
repo="$(cd "$(dirname "$0")/../../.." && pwd -P)"
python_home="$(dirname "$(dirname "$(readlink -f "$(command -v "$1")")")")"
scratch=/mnt
mount -t tmpfs -o mode=0700 rgsec "$scratch"
mkdir "$scratch/tmp" "$scratch/root"
mount --rbind /tmp "$scratch/tmp"
mount --rbind /root "$scratch/root"
mount -t tmpfs -o mode=1777 rgsec-tmp /tmp
mount -t tmpfs -o mode=1777 rgsec-shm /dev/shm
mount -t tmpfs -o mode=0755 rgsec-root /root
rebind() { # rebind PATH: make PATH reachable again from the kept copy of its top directory
    local path="$1" top="$2"
    case "$path" in
        "$top"/*)
            mkdir -p "$path"
            mount --rbind "$scratch/${top#/}/${path#"$top"/}" "$path"
            ;;
    esac
}
rebind "$repo" /tmp
rebind "$python_home" /root
rebind "$python_home" /tmp
exec "$@"
