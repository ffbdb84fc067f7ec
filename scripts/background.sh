# Sourced by .ci/run and scripts/test.sh: set-up work run in the background while the caller
# does something else. Each job runs in its own process group (pip, cargo and their children
# go with it), and every group still running is killed if the caller exits first.

bg_groups=()
bg_log=
bg_job_dir=
_bg_kill_all() {
    local g
    for g in ${bg_groups[@]+"${bg_groups[@]}"}; do
        kill -- -"$g" 2>/dev/null || kill "$g" 2>/dev/null || true
    done
    if [[ -n $bg_log ]]; then rm -f "$bg_log"; fi
    if [[ -n $bg_job_dir ]]; then rm -rf "$bg_job_dir"; fi
}
trap _bg_kill_all EXIT

# _bg_forget PID: it has ended, so its number may be reused: never kill it at exit.
_bg_forget() {
    local g kept=()
    for g in ${bg_groups[@]+"${bg_groups[@]}"}; do
        if [[ $g != "$1" ]]; then kept+=("$g"); fi
    done
    bg_groups=(${kept[@]+"${kept[@]}"})
}

# bg_start COMMAND [ARGS...]: start one set-up script; bg_wait waits for it.
bg_start() {
    bg_cmd="$*"
    bg_log=$(mktemp)
    setsid "$@" >"$bg_log" 2>&1 &
    bg_pid=$!
    bg_groups+=("$bg_pid")
}

# bg_wait: wait for it and show its output; exit loudly if it failed.
bg_wait() {
    local status=0
    wait "$bg_pid" || status=$?
    _bg_forget "$bg_pid"
    cat "$bg_log"
    if [[ $status -ne 0 ]]; then
        echo "error: $bg_cmd failed with status $status (its output is above)" >&2
        exit 1
    fi
}

# bg_job DIR COMMAND [ARGS...]: run one job beside bg_start's, for whoever reads DIR: its
# output goes to DIR/log, and DIR/rc holds its exit status once it has ended. DIR is the
# job's: it is removed with the job (bg_job_end, or when the caller exits).
bg_job() {
    bg_job_dir=$1
    shift
    setsid bash -c '"${@:2}" >"$1/log" 2>&1; echo $? >"$1/rc.tmp"; mv "$1/rc.tmp" "$1/rc"' \
        _ "$bg_job_dir" "$@" &
    bg_job_pid=$!
    bg_groups+=("$bg_job_pid")
}

# bg_job_wait: wait for it; exit loudly, with its output, if it failed.
bg_job_wait() {
    wait "$bg_job_pid" || true
    _bg_forget "$bg_job_pid"
    if [[ $(cat "$bg_job_dir/rc" 2>/dev/null) != 0 ]]; then
        cat "$bg_job_dir/log"
        echo "error: the background job writing $bg_job_dir failed (its output is above)" >&2
        exit 1
    fi
}

# bg_job_end: remove its DIR (its reader is done with it).
bg_job_end() {
    if [[ -n ${bg_job_dir:-} ]]; then rm -rf "$bg_job_dir"; fi
    bg_job_dir=
}
