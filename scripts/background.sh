# Sourced by .ci/run and scripts/test.sh: set-up work run in the background while the caller
# does something else. Each job runs in its own process group (pip, cargo and their children
# go with it), and every group still running is killed if the caller exits first.

bg_groups=()
bg_log=
bg_idle_dir=
_bg_kill_all() {
    local g
    for g in ${bg_groups[@]+"${bg_groups[@]}"}; do
        kill -- -"$g" 2>/dev/null || kill "$g" 2>/dev/null || true
    done
    if [[ -n $bg_log ]]; then rm -f "$bg_log"; fi
    if [[ -n $bg_idle_dir ]]; then rm -rf "$bg_idle_dir"; fi
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

# bg_idle DIR COMMAND [ARGS...]: run one job on the CPU time others leave idle (SCHED_IDLE:
# a core only while nothing else wants it; nice 19 where that is refused), for whoever reads
# DIR: its output goes to DIR/log, and DIR/rc holds its exit status once it has ended. DIR is
# the job's: it is removed with the job.
bg_idle() {
    local dir=$1 idle=(chrt --idle 0)
    shift
    bg_idle_dir=$dir
    if ! chrt --idle 0 true 2>/dev/null; then idle=(nice -n 19); fi
    setsid "${idle[@]}" bash -c '"${@:2}" >"$1/log" 2>&1; echo $? >"$1/rc.tmp"; mv "$1/rc.tmp" "$1/rc"' \
        _ "$dir" "$@" &
    bg_idle_pid=$!
    bg_groups+=("$bg_idle_pid")
}

# bg_idle_stop: end the idle job, done or not (its reader is done with it), and remove DIR.
bg_idle_stop() {
    if [[ -z ${bg_idle_pid:-} ]]; then return 0; fi
    kill -- -"$bg_idle_pid" 2>/dev/null || true
    wait "$bg_idle_pid" 2>/dev/null || true
    _bg_forget "$bg_idle_pid"
    rm -rf "$bg_idle_dir"
    bg_idle_dir= bg_idle_pid=
}
