#!/usr/bin/env bash
# A real single-node Slurm cluster for the Slurm test, started by hand (no systemd), as root:
#   bash .ci/slurm.sh install   # Debian's slurmctld slurmd slurm-client munge slurmdbd mariadb-server
#   bash .ci/slurm.sh start DIR # configs, state, logs and PIDs under DIR; prints `export SLURM_CONF=...`
#   bash .ci/slurm.sh stop DIR  # stops every daemon start began, by the PID it recorded, in reverse order
# Measured setup (issue 45): slurm-wlm 22.05.8 needs munge (auth/slurm does not exist in 22.05); submitit reads job
# states through sacct, which needs slurmdbd and a database, or it reports every state as UNKNOWN.
set -euo pipefail

cmd=${1:?usage: slurm.sh install | start DIR | stop DIR}
host=$(hostname)
cluster=spnci

wait_for() { # wait_for SECONDS DESCRIPTION COMMAND...: retry COMMAND until it succeeds
    local limit=$1 what=$2
    shift 2
    for _ in $(seq $((limit * 5))); do
        "$@" >/dev/null 2>&1 && return 0
        sleep 0.2
    done
    echo "slurm.sh: $what did not come up within ${limit} s" >&2
    return 1
}

start_daemon() { # start_daemon NAME COMMAND...: run COMMAND in the background, record its PID in DIR/pids
    local name=$1
    shift
    "$@" >"$dir/log/$name.out" 2>&1 &
    echo "$name $!" >>"$dir/pids"
}

case $cmd in
install)
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends slurmctld slurmd slurm-client slurmdbd munge mariadb-server \
        >/dev/null
    ;;
start)
    dir=$(realpath -m "${2:?slurm.sh start DIR}")
    mkdir -p "$dir"/{log,state,spool,mysql}
    chmod 755 "$dir" # mariadbd runs as mysql and must reach DIR/mysql (mktemp -d makes DIR 700)
    : >"$dir/pids"
    # munged: its socket directory is fixed at /run/munge; the package created /etc/munge/munge.key
    mkdir -p /run/munge
    chown munge: /run/munge
    start_daemon munged setpriv --reuid=munge --regid=munge --init-groups munged -F
    wait_for 10 munged munge -n
    # mariadbd: a fresh database in DIR, its socket and PID file where slurmdbd and mariadbd expect them
    mkdir -p /run/mysqld
    chown mysql: /run/mysqld "$dir/mysql"
    mariadb-install-db --user=mysql --datadir="$dir/mysql" --auth-root-authentication-method=socket \
        >"$dir/log/mariadb-install.out" 2>&1
    start_daemon mariadbd mariadbd --user=mysql --datadir="$dir/mysql" --socket=/run/mysqld/mysqld.sock \
        --pid-file=/run/mysqld/mysqld.pid --skip-networking --log-error="$dir/log/mariadbd.log"
    wait_for 30 mariadbd mariadb --socket=/run/mysqld/mysqld.sock -e "select 1"
    cat >"$dir/slurmdbd.conf" <<EOF
AuthType=auth/munge
DbdHost=localhost
SlurmUser=root
StorageType=accounting_storage/mysql
StorageHost=localhost
StorageUser=root
StorageLoc=slurm_acct_db
LogFile=$dir/log/slurmdbd.log
PidFile=$dir/slurmdbd.pid
EOF
    chmod 600 "$dir/slurmdbd.conf"
    cat >"$dir/slurm.conf" <<EOF
ClusterName=$cluster
SlurmctldHost=$host
SlurmUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/slurmdbd
AccountingStorageHost=localhost
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
NodeName=$host CPUs=$(nproc) RealMemory=$(($(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 - 1024)) State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
    export SLURM_CONF=$dir/slurm.conf
    start_daemon slurmdbd env SLURM_CONF="$SLURM_CONF" slurmdbd -D
    wait_for 30 slurmdbd sacctmgr -n list cluster
    sacctmgr -i add cluster "$cluster" >/dev/null
    start_daemon slurmctld slurmctld -D -i
    start_daemon slurmd slurmd -D
    wait_for 30 "the node" sh -c "sinfo -h -o %T | grep -qx idle"
    echo "export SLURM_CONF=$SLURM_CONF"
    ;;
stop)
    dir=$(realpath -m "${2:?slurm.sh stop DIR}")
    [ -f "$dir/pids" ] || exit 0
    tac "$dir/pids" | while read -r name pid; do
        kill "$pid" 2>/dev/null || continue
        for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
        if kill -0 "$pid" 2>/dev/null; then
            echo "slurm.sh: $name (pid $pid) did not stop on SIGTERM; killing it" >&2
            kill -9 "$pid" 2>/dev/null || true
        fi
    done
    rm "$dir/pids"
    ;;
*)
    echo "usage: slurm.sh install | start DIR | stop DIR" >&2
    exit 2
    ;;
esac
