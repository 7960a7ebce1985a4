#!/usr/bin/env bash
# A throwaway single-node Slurm cluster on this machine, for tests.
#
#   tests/slurm/cluster.sh up            start munged, slurmctld and slurmd;
#                                        print the SLURM_CONF line to export
#   tests/slurm/cluster.sh down          stop them again
#   tests/slurm/cluster.sh status        sinfo and squeue of the cluster
#   tests/slurm/cluster.sh run CMD...    up, run CMD with SLURM_CONF set,
#                                        down (also on failure or Ctrl-C);
#                                        runs wait for each other
#
# It needs root, Debian's `slurm-wlm` and `munge` packages and nothing else:
# no systemd, no cgroups, nothing written outside its own folder. Everything
# (munge key and socket, slurm.conf, state, spool, logs, pid files) lives in
# $PIDM_SLURM_DIR (default /tmp/pidm-slurm); the daemons listen on
# 127.0.0.1 ports $PIDM_SLURM_PORT and $PIDM_SLURM_PORT + 1 (default 16817,
# away from a real cluster's 6817/6818). Clients find the cluster through
# SLURM_CONF=$PIDM_SLURM_DIR/slurm.conf. `up` first stops a cluster left
# over in the same folder by an earlier run, and wipes its state, so it can
# be run again and again.
set -euo pipefail

DIR=${PIDM_SLURM_DIR:-/tmp/pidm-slurm}
PORT=${PIDM_SLURM_PORT:-16817}
CONF=$DIR/slurm.conf
SOCKET=$DIR/munge/munge.socket
# How long to wait for the node to come up, in seconds.
WAIT=${PIDM_SLURM_WAIT:-60}

say() { echo "cluster.sh: $*" >&2; }
die() {
    say "$*"
    exit 1
}

# The pid recorded in $1 when it names a live process called $2, else nothing.
# The name check keeps a recycled pid of some other process safe.
live_pid() {
    local file=$1 name=$2 pid
    [[ -s $file ]] || return 0
    pid=$(tr -dc '0-9' <"$file")
    [[ -n $pid && -r /proc/$pid/comm ]] || return 0
    [[ $(cat "/proc/$pid/comm") == "$name" ]] && echo "$pid"
    return 0
}

# The daemons (and job steps) of this folder's cluster: those its pid files
# name, and any other whose environment or command line names this folder
# (a cluster whose pid files were deleted, say). Nothing else.
our_pids() {
    local name pid proc env cmd
    for name in slurmd slurmctld munged; do
        live_pid "$DIR/run/$name.pid" "$name"
    done
    for proc in /proc/[0-9]*; do
        pid=${proc#/proc/}
        name=$(cat "$proc/comm" 2>/dev/null) || continue
        case $name in slurmd | slurmctld | munged | slurmstepd) ;; *) continue ;; esac
        env=$(tr '\0' '\n' 2>/dev/null <"$proc/environ") || true
        cmd=$(tr '\0' ' ' 2>/dev/null <"$proc/cmdline") || true
        if [[ $'\n'$env$'\n' == *$'\n'"SLURM_CONF=$CONF"$'\n'* || $cmd == *"$DIR/"* ]]; then
            echo "$pid"
        fi
    done
}

# True while process $1 runs (a zombie has finished).
alive() {
    local stat
    stat=$(cat "/proc/$1/stat" 2>/dev/null) || return 1
    stat=${stat##*) }
    [[ ${stat:0:1} != Z ]]
}

# Stops this folder's cluster, gently and then firmly.
stop_daemons() {
    local pid pids waited
    pids=$(our_pids | sort -un)
    for pid in $pids; do
        kill -TERM "$pid" 2>/dev/null || true
    done
    for pid in $pids; do
        for ((waited = 0; waited < 100; waited++)); do
            alive "$pid" || break
            sleep 0.1
        done
        if alive "$pid"; then
            say "pid $pid ignored SIGTERM for 10 s; sending SIGKILL"
            kill -KILL "$pid" 2>/dev/null || true
        fi
    done
    rm -f "$DIR"/run/*.pid
}

# The last lines of every log, for a failure message.
show_logs() {
    local log
    for log in "$DIR"/log/*.log; do
        [[ -s $log ]] || continue
        echo "---- $log (last 20 lines)" >&2
        tail -n 20 "$log" >&2
    done
}

# True when something already listens on TCP port $1.
port_busy() {
    (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null
}

# The name slurmd knows its node by: the host name up to the first dot.
short_hostname() {
    hostname -s 2>/dev/null || uname -n | cut -d. -f1
}

write_conf() {
    local host cpus
    host=$(short_hostname)
    cpus=$(nproc)
    cat >"$CONF" <<EOF
# Written by tests/slurm/cluster.sh: a single-node test cluster.
ClusterName=pidmtest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$PORT
SlurmdPort=$((PORT + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$SOCKET
StateSaveLocation=$DIR/state
SlurmdSpoolDir=$DIR/spool
SlurmctldPidFile=$DIR/run/slurmctld.pid
SlurmdPidFile=$DIR/run/slurmd.pid
SlurmctldLogFile=$DIR/log/slurmctld.log
SlurmdLogFile=$DIR/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
# No cgroups and no systemd in a container: track processes by parentage.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SwitchType=switch/none
SchedulerType=sched/backfill
# A job whose dependency can never be met (afterok on a failed job) is
# cancelled instead of pending for ever, so \`sbatch --wait\` on it returns.
SchedulerParameters=kill_invalid_depend
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
# Trust the CPU count below rather than draining the node over topology.
SlurmdParameters=config_overrides
SlurmdTimeout=60
InactiveLimit=0
KillWait=5
MinJobAge=300
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
}

up() {
    [[ $(id -u) == 0 ]] || die "must run as root (the daemons and jobs run as root)"
    local tool
    for tool in munged slurmctld slurmd sinfo sbatch; do
        command -v "$tool" >/dev/null ||
            die "$tool not found: install it with apt-get install -y --no-install-recommends slurm-wlm munge"
    done

    # A cluster left over in this folder by an earlier run goes first.
    stop_daemons
    local port
    for port in "$PORT" $((PORT + 1)); do
        if port_busy "$port"; then
            die "port $port is in use by a process this script did not start (set PIDM_SLURM_PORT to move)"
        fi
    done
    rm -rf "$DIR"
    # Only the key is secret (0400); the socket's folders must be searchable.
    mkdir -p "$DIR"/{munge,state,spool,run,log}
    chmod 0755 "$DIR" "$DIR/munge"

    # If starting fails halfway, stop whatever did start.
    trap 'status=$?; if ((status != 0)); then show_logs; stop_daemons; fi' EXIT

    # Munge: a fresh key, its own socket, no system paths.
    dd if=/dev/urandom of="$DIR/munge/munge.key" bs=1024 count=1 status=none
    chmod 0400 "$DIR/munge/munge.key"
    munged --force --socket="$SOCKET" --key-file="$DIR/munge/munge.key" \
        --pid-file="$DIR/run/munged.pid" --log-file="$DIR/log/munged.log" \
        --seed-file="$DIR/munge/munged.seed" </dev/null >>"$DIR/log/munged.log" 2>&1 9>&- ||
        die "munged did not start"
    if command -v munge >/dev/null && command -v unmunge >/dev/null; then
        munge --socket="$SOCKET" -n | unmunge --socket="$SOCKET" >/dev/null ||
            die "munge does not round-trip a credential through $SOCKET"
    fi

    write_conf
    export SLURM_CONF=$CONF
    # -i: ignore (there is no) saved state; the daemons fork into the
    # background themselves and write the pid files named in slurm.conf. No
    # daemon keeps the lock of `run` (fd 9), or a cluster left running would
    # hold it.
    slurmctld -i </dev/null >>"$DIR/log/slurmctld.log" 2>&1 9>&- || die "slurmctld did not start"
    slurmd </dev/null >>"$DIR/log/slurmd.log" 2>&1 9>&- || die "slurmd did not start"

    local waited state=""
    for ((waited = 0; waited < WAIT * 2; waited++)); do
        state=$(sinfo -h -N -o %t 2>/dev/null | head -n 1 || true)
        [[ $state == idle ]] && break
        sleep 0.5
    done
    [[ $state == idle ]] || die "the node is not idle after ${WAIT} s (state '${state:-no answer}')"
    trap - EXIT
    say "single-node cluster up ($(short_hostname), $(nproc) CPUs, state in $DIR)"
    echo "SLURM_CONF=$CONF"
}

down() {
    # Jobs still running would outlive slurmd (their slurmstepd is detached).
    if [[ -n $(live_pid "$DIR/run/slurmctld.pid" slurmctld) ]]; then
        SLURM_CONF=$CONF timeout 10 scancel --quiet --user=root 2>/dev/null || true
    fi
    stop_daemons
    say "cluster in $DIR stopped"
}

case ${1:-} in
up) up ;;
down) down ;;
status)
    export SLURM_CONF=$CONF
    sinfo
    squeue
    ;;
run)
    shift
    [[ ${1:-} == -- ]] && shift
    (($# > 0)) || die "run needs a command"
    # One cluster at a time on this machine: a second `run` (another
    # checkout's test, say) waits here instead of tearing this one down.
    exec 9>"$DIR.lock"
    flock -w 900 9 || die "another run still holds $DIR.lock after 900 s"
    up >/dev/null
    trap 'down' EXIT
    trap 'exit 130' INT TERM
    export SLURM_CONF=$CONF
    status=0
    "$@" 9>&- || status=$?
    if ((status != 0)); then
        say "the command exited with $status; the cluster's logs:"
        show_logs
    fi
    exit "$status"
    ;;
*)
    sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//' >&2
    exit 2
    ;;
esac
