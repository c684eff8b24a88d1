#!/usr/bin/env bash
# One-node throw-away Slurm cluster for CI: Debian 12, run as root, no systemd needed.
# Source it from a script running under `set -euo pipefail`, or run it to self-test.

log() { printf '[%(%H:%M:%S)T] %s\n' -1 "$*" >&2; }

SLURM_DIR=""                       # set by slurm_start; everything lives under it

slurm_install() {
    local b missing=0
    for b in munged mungekey slurmctld slurmd sbatch fuser ps; do
        command -v "$b" >/dev/null || missing=1
    done
    [ "$missing" = 1 ] || return 0
    local own_policy=0             # stop package scripts from starting stock daemons
    if [ ! -e /usr/sbin/policy-rc.d ]; then
        printf '#!/bin/sh\nexit 101\n' > /usr/sbin/policy-rc.d
        chmod 755 /usr/sbin/policy-rc.d; own_policy=1
    fi
    DEBIAN_FRONTEND=noninteractive timeout 900 apt-get update -qq
    DEBIAN_FRONTEND=noninteractive timeout 900 apt-get install -y -qq \
        --no-install-recommends munge slurmctld slurmd slurm-client psmisc procps >/dev/null
    if [ "$own_policy" = 1 ]; then rm -f /usr/sbin/policy-rc.d; fi
}

slurm_start() {
    SLURM_DIR=$(mktemp -d /tmp/ci-slurm.XXXXXX)
    chmod 0711 "$SLURM_DIR"        # munged wants x-for-all on the socket's directories
    mkdir -p "$SLURM_DIR"/state "$SLURM_DIR"/spool "$SLURM_DIR"/log
    mkdir -m 0711 "$SLURM_DIR"/munge
    export SLURM_CONF=$SLURM_DIR/slurm.conf   # read by daemons, clients and jobs
    local host ncpu mem_mb
    host=${SLURM_CI_HOST:-$(hostname -s)}   # "localhost" also works, whatever the hostname
    ncpu=$(env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc)
    mem_mb=$(awk '/^MemAvailable:/ {m = int($2 / 2048); print (m < 256 ? 256 : m)}' /proc/meminfo)

    cat > "$SLURM_CONF" <<EOF
ClusterName=ci
SlurmctldHost=${host}(127.0.0.1)
SlurmUser=root
SlurmctldPort=${SLURM_CTLD_PORT:-16817}
SlurmdPort=${SLURM_SLURMD_PORT:-16818}
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=${SLURM_DIR}/munge/munge.socket
StateSaveLocation=${SLURM_DIR}/state
SlurmdSpoolDir=${SLURM_DIR}/spool
SlurmctldPidFile=${SLURM_DIR}/slurmctld.pidfile
SlurmdPidFile=${SLURM_DIR}/slurmd.pidfile
SlurmctldLogFile=${SLURM_DIR}/log/slurmctld.log
SlurmdLogFile=${SLURM_DIR}/log/slurmd.log
MailProg=/bin/true
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
KillWait=5
NodeName=${host} NodeAddr=127.0.0.1 CPUs=${ncpu} RealMemory=${mem_mb} State=UNKNOWN
PartitionName=ci Nodes=${host} Default=YES MaxTime=INFINITE State=UP
EOF

    mungekey --create --bits=1024 --keyfile="$SLURM_DIR/munge/munge.key"
    # Each daemon runs in the foreground, backgrounded by us: $! is the daemon's PID.
    munged --foreground --key-file="$SLURM_DIR/munge/munge.key" \
        --socket="$SLURM_DIR/munge/munge.socket" --pid-file="$SLURM_DIR/munge/munged.pidfile" \
        --log-file="$SLURM_DIR/munge/munged.log" --seed-file="$SLURM_DIR/munge/munged.seed" \
        </dev/null >"$SLURM_DIR/log/munged.out" 2>&1 &
    echo $! > "$SLURM_DIR/munged.pid"
    slurm_wait 20 "munged to answer" munge_ok

    slurmctld -D </dev/null >"$SLURM_DIR/log/slurmctld.out" 2>&1 &
    echo $! > "$SLURM_DIR/slurmctld.pid"
    slurmd -D -N "$host" </dev/null >"$SLURM_DIR/log/slurmd.out" 2>&1 &
    echo $! > "$SLURM_DIR/slurmd.pid"
    slurm_wait 60 "node $host to be idle" node_idle "$host"
}

munge_ok()  { munge -n -S "$SLURM_DIR/munge/munge.socket" 2>/dev/null \
                | unmunge -S "$SLURM_DIR/munge/munge.socket" >/dev/null 2>&1 || return 1; }
node_idle() {                      # 0: idle, 1: not yet, 99: never (drained or invalid)
    local s; s=$(sinfo -h -n "$1" -o %T 2>/dev/null)
    case $s in
        idle) return 0 ;;
        *drain*|*inval*) log "node $1 is $s: $(sinfo -h -R -o %E)"; return 99 ;;
        *) return 1 ;;
    esac
}
jobs_gone() { [ -z "$(squeue -h -o %i ${1:+-j "$1"} 2>/dev/null)" ]; }   # no arg: all jobs
ctld_up()   { scontrol ping 2>/dev/null | grep -q 'is UP'; }
# Distinct final states of a job (all tasks of an array), e.g. COMPLETED or COMPLETED,FAILED.
job_states() { scontrol -o show job "$1" | grep -o 'JobState=[A-Z_]*' | cut -d= -f2 | sort -u | paste -sd, -; }

# slurm_wait SECONDS WHAT CMD...: poll CMD until it succeeds; fail on timeout, when CMD
# returns 99 (never), or when a daemon has died.
slurm_wait() {
    local limit=$1 what=$2 d r; shift 2
    local end=$((SECONDS + limit))
    while true; do
        "$@" && return 0
        r=$?
        if [ "$r" = 99 ]; then log "gave up waiting for $what"; return 1; fi
        for d in munged slurmctld slurmd; do
            if [ -s "$SLURM_DIR/$d.pid" ] && ! kill -0 "$(cat "$SLURM_DIR/$d.pid")" 2>/dev/null; then
                log "$d has exited while waiting for $what"; return 1
            fi
        done
        if [ $SECONDS -ge $end ]; then log "timed out after ${limit}s waiting for $what"; return 1; fi
        sleep 0.5
    done
}

# stop_pid NAME: SIGTERM the PID in $SLURM_DIR/NAME.pid, SIGKILL after 15 s, reap it.
stop_pid() {
    local f=$SLURM_DIR/$1.pid pid end
    [ -s "$f" ] || return 0
    pid=$(cat "$f")
    if kill -0 "$pid" 2>/dev/null; then
        kill -TERM "$pid" 2>/dev/null || true
        end=$((SECONDS + 15))
        while kill -0 "$pid" 2>/dev/null && [ $SECONDS -lt $end ]; do sleep 0.2; done
        kill -KILL "$pid" 2>/dev/null || true
    fi
    wait "$pid" 2>/dev/null || true
    rm -f "$f"
}

# Job steps run under slurmstepd, which is reparented to PID 1, survives slurmd and then
# ignores SIGTERM. Each stepd holds the slurmd log open, so fuser finds exactly this
# cluster's leftovers; SIGKILL each one's session (stepd + the job's processes).
kill_strays() {
    local end=$((SECONDS + 10)) pids pid sid me
    while pids=$(fuser "$SLURM_DIR/log/slurmd.log" 2>/dev/null) && [ $SECONDS -lt $end ]; do
        sleep 0.5
    done
    [ -n "$pids" ] || return 0
    me=$(ps -o sid= -p $$ | tr -d ' ')
    for pid in $pids; do
        sid=$(ps -o sid= -p "$pid" | tr -d ' ')
        if [ -n "$sid" ] && [ "$sid" != "$me" ]; then
            log "killing leftover session $sid: $(ps -s "$sid" -o pid=,args= | tr '\n' ';')"
            kill -KILL $(ps -s "$sid" -o pid=) 2>/dev/null || true
        fi
    done
}

slurm_stop() {
    local rc=$?
    set +e
    [ -n "$SLURM_DIR" ] || return "$rc"
    if [ -s "$SLURM_DIR/slurmctld.pid" ] && ctld_up; then
        if [ "$rc" != 0 ]; then { sinfo -R; squeue; } >&2; fi
        scancel --quiet --user=root       # shutdown alone would leave running jobs behind
        slurm_wait 30 "jobs to end" jobs_gone
        scontrol shutdown >/dev/null 2>&1 # stops slurmctld and slurmd
    fi
    stop_pid slurmd
    stop_pid slurmctld
    kill_strays
    stop_pid munged
    if [ "$rc" != 0 ]; then
        for f in "$SLURM_DIR"/log/* "$SLURM_DIR"/munge/munged.log; do
            [ -s "$f" ] && { echo "==== $f"; tail -n 30 "$f"; }
        done >&2
    fi
    [ "${KEEP_SLURM_DIR:-0}" = 1 ] || rm -rf "$SLURM_DIR"
    SLURM_DIR=""
    return "$rc"
}

# ------------------------------------------------------------------ demo / self-test
[[ "${BASH_SOURCE[0]}" == "$0" ]] || return 0
set -euo pipefail
trap slurm_stop EXIT
trap 'exit 130' INT TERM

T0=$SECONDS; slurm_install; log "install: $((SECONDS - T0))s"
T1=$SECONDS; slurm_start;   log "start: $((SECONDS - T1))s"; sinfo

work=$SLURM_DIR/work; mkdir -p "$work"
printf '%s\n' '#!/bin/bash' \
    'echo "task $SLURM_ARRAY_TASK_ID of $SLURM_ARRAY_JOB_ID on $(hostname -s)" > part_$SLURM_ARRAY_TASK_ID.txt' \
    'sleep 1' > "$work/task.sh"
printf '%s\n' '#!/bin/bash' 'cat part_*.txt > all.txt' > "$work/gather.sh"

T2=$SECONDS
A=$(sbatch --parsable --array=0-3 --chdir="$work" --output="$work/task-%A_%a.out" "$work/task.sh")
D=$(sbatch --parsable --dependency=afterok:"$A" --kill-on-invalid-dep=yes \
        --chdir="$work" --output="$work/gather-%j.out" "$work/gather.sh")
slurm_wait 300 "jobs $A and $D" jobs_gone "$A,$D"
log "jobs: $((SECONDS - T2))s; array $A: $(job_states "$A"); dependent $D: $(job_states "$D")"
[ "$(job_states "$A")" = COMPLETED ]
[ "$(job_states "$D")" = COMPLETED ]
[ "$(wc -l < "$work/all.txt")" = 4 ]
cat "$work/all.txt"

T3=$SECONDS; slurm_stop; trap - EXIT
log "stop: $((SECONDS - T3))s; total: $((SECONDS - T0))s"
