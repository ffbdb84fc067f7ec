# Sourced by .ci/run and scripts/test.sh: one set-up script run in the background while the
# caller does something else. It runs in its own process group (pip and its children go with
# it), its output is kept and shown when it is waited for, and the group is killed if the
# caller exits first.

# bg_start COMMAND [ARGS...]: start it.
bg_start() {
    bg_cmd="$*"
    bg_log=$(mktemp)
    setsid "$@" >"$bg_log" 2>&1 &
    bg_pid=$!
    # Its process group; or itself, before setsid has made the group.
    trap 'if [[ -n ${bg_pid:-} ]]; then kill -- -"$bg_pid" 2>/dev/null ||
        kill "$bg_pid" 2>/dev/null || true; fi; rm -f "$bg_log"' EXIT
}

# bg_wait: wait for it and show its output; exit loudly if it failed.
bg_wait() {
    local status=0
    wait "$bg_pid" || status=$?
    bg_pid=
    cat "$bg_log"
    if [[ $status -ne 0 ]]; then
        echo "error: $bg_cmd failed with status $status (its output is above)" >&2
        exit 1
    fi
}
