# Sourced by .ci/run and scripts/test.sh: set-up work run in the background while the caller
# does something else. Each job has a name, runs in its own process group (pip, cargo and their
# children go with it), and its output is kept and shown when it is waited for. Every job still
# running is killed, and every file and directory made here removed, if the caller exits first.

declare -A bg_pids=() bg_logs=() bg_cmds=()
bg_paths=()
_bg_exit() {
    local name
    for name in "${!bg_pids[@]}"; do
        kill -- -"${bg_pids[$name]}" 2>/dev/null || kill "${bg_pids[$name]}" 2>/dev/null || true
    done
    for name in "${!bg_logs[@]}"; do rm -f "${bg_logs[$name]}"; done
    if ((${#bg_paths[@]})); then rm -rf "${bg_paths[@]}"; fi
}
trap _bg_exit EXIT

# bg_start NAME COMMAND [ARGS...]: start job NAME.
bg_start() {
    local name=$1
    shift
    bg_cmds[$name]="$*"
    bg_logs[$name]=$(mktemp)
    setsid "$@" >"${bg_logs[$name]}" 2>&1 &
    bg_pids[$name]=$!
}

# bg_wait NAME: wait for job NAME and show its output; exit loudly if it failed.
bg_wait() {
    local name=$1 status=0
    wait "${bg_pids[$name]}" || status=$?
    # It has ended, so its number may be reused: never kill it at exit.
    unset "bg_pids[$name]"
    cat "${bg_logs[$name]}"
    rm -f "${bg_logs[$name]}"
    unset "bg_logs[$name]"
    if [[ $status -ne 0 ]]; then
        echo "error: ${bg_cmds[$name]} failed with status $status (its output is above)" >&2
        exit 1
    fi
}

# bg_temp_dir VAR: set VAR to a new private directory, removed when the caller exits.
bg_temp_dir() {
    local dir
    dir=$(mktemp -d)
    bg_paths+=("$dir")
    printf -v "$1" '%s' "$dir"
}
