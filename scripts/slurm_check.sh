#!/usr/bin/env bash
# Sweeps on a real Slurm cluster, end to end, on this one Debian machine (run as root: `make slurm-check`).
#
# Installs Slurm 22.05 with accounting from Debian's packages (slurm-wlm, slurmdbd, mariadb-server,
# munge), starts a private single-node cluster whose whole state lives in $STATE (its own config,
# munge key, MariaDB data directory and ports, so an existing cluster or database on the machine is
# left alone), and runs through hydra/launcher=submitit_slurm:
#   1. a tiny two-job sweep with the default settings: both jobs COMPLETED, their runs and the
#      summary written, the last console line naming the summary; each job's wall time printed;
#   2. a three-job sweep whose last job is cancelled while it waits: the summary of the other two, the
#      cancelled job marked with its log, exit status 1 and one line;
#   3. refused launches (a partition that does not exist, more memory than the node has): one
#      line each, exit status 1, outputs/ as it was.
# Every daemon it started is stopped when it ends, whatever the outcome. Not part of `make test`.
set -euo pipefail

REPO=$(cd "$(dirname "$0")/.." && pwd)
STATE=${WATERAIR_SLURM_STATE:-/var/tmp/waterair-slurm}
CLUSTER=waterair
PORTS=(16817 16818 16819 13306)  # slurmctld, slurmd, slurmdbd, mariadb: away from the usual ones
PACKAGES=(slurm-wlm slurmdbd mariadb-server munge)
MUNGE_SOCKET=/run/munge/munge.socket.2
TINY=(total_frames=3200 eval.realisations=8 eval.steps=100 logger.progress_bar=false)
STARTED=()  # pid files of the daemons this run started, stopped in reverse order on exit
start_time=$(date +%s)

say() { printf '[slurm-check %3ds] %s\n' $(($(date +%s) - start_time)) "$*"; }
fail() { say "FAILED: $*"; exit 1; }

stop_daemons() {
    local status=$?
    for ((i = ${#STARTED[@]} - 1; i >= 0; i--)); do
        local pidfile=${STARTED[i]} pid
        pid=$(cat "$pidfile" 2>/dev/null) || continue
        kill "$pid" 2>/dev/null || continue
        for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
        say "stopped $(basename "$pidfile" .pid) (pid $pid)"
    done
    say "$( ((status == 0)) && echo "passed" || echo "failed (exit $status)") in $(($(date +%s) - start_time)) s"
}

[[ $(id -u) == 0 ]] || fail "run as root (it installs packages and starts daemons)"
command -v apt-get >/dev/null || fail "needs a Debian machine (apt-get)"

# --- Packages (skipped when installed). No service may start during the install: this script starts its own.
missing=()
for package in "${PACKAGES[@]}"; do dpkg -s "$package" >/dev/null 2>&1 || missing+=("$package"); done
if ((${#missing[@]})); then
    say "installing ${missing[*]}"
    policy_added=false
    if [[ ! -e /usr/sbin/policy-rc.d ]]; then
        printf '#!/bin/sh\nexit 101\n' >/usr/sbin/policy-rc.d && chmod +x /usr/sbin/policy-rc.d && policy_added=true
    fi
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
    $policy_added && rm -f /usr/sbin/policy-rc.d
fi
say "packages: $(dpkg-query -W -f='${Package} ${Version}, ' "${PACKAGES[@]}")"

# --- Leftovers of an interrupted earlier run are ours: stop them before starting afresh.
for pidfile in "$STATE"/run/*.pid "$STATE"/mysql/mysqld.pid "$STATE"/munge/munged.pid; do
    [[ -e $pidfile ]] && kill "$(cat "$pidfile")" 2>/dev/null && sleep 2 && say "stopped a leftover $(basename "$pidfile" .pid)"
done
for port in "${PORTS[@]}"; do
    ! (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null || fail "port $port is taken; free it or change PORTS"
done
trap stop_daemons EXIT

HOST=$(hostname -s)
mkdir -p "$STATE"/{etc,run,log,munge,ctld,slurmd,mysql}
chown slurm:slurm "$STATE"/{ctld,log,run}
chown munge:munge "$STATE/munge" && chmod 0755 "$STATE/munge"
chown mysql:mysql "$STATE/mysql"
export SLURM_CONF=$STATE/etc/slurm.conf

# --- munge on its usual socket (Slurm's clients talk to slurmdbd through that one whatever AuthInfo says):
# a munged already serving it is used as it is; else one with a key of its own.
if munge -n -S "$MUNGE_SOCKET" >/dev/null 2>&1; then
    say "munged: the one already running"
else
    if [[ ! -s $STATE/munge/munge.key ]]; then
        dd if=/dev/urandom bs=1 count=1024 of="$STATE/munge/munge.key" status=none
        chown munge:munge "$STATE/munge/munge.key" && chmod 0400 "$STATE/munge/munge.key"
    fi
    mkdir -p "$(dirname "$MUNGE_SOCKET")" && chown munge:munge "$(dirname "$MUNGE_SOCKET")"
    runuser -u munge -- munged --force --key-file="$STATE/munge/munge.key" --socket="$MUNGE_SOCKET" \
        --pid-file="$STATE/munge/munged.pid" --log-file="$STATE/munge/munged.log" --seed-file="$STATE/munge/munged.seed"
    STARTED+=("$STATE/munge/munged.pid")
    say "munged started"
fi

# --- MariaDB: a data directory of its own, on its own port, for slurmdbd's accounting.
if [[ ! -d $STATE/mysql/mysql ]]; then
    mariadb-install-db --user=mysql --datadir="$STATE/mysql" --auth-root-authentication-method=socket >/dev/null 2>&1
fi
SQL=(mariadb --socket="$STATE/mysql/mysqld.sock")
mariadbd --no-defaults --user=mysql --datadir="$STATE/mysql" --socket="$STATE/mysql/mysqld.sock" \
    --port="${PORTS[3]}" --bind-address=127.0.0.1 --skip-name-resolve --pid-file="$STATE/mysql/mysqld.pid" \
    --log-error="$STATE/mysql/mysqld.log" --skip-log-bin >/dev/null 2>&1 &
STARTED+=("$STATE/mysql/mysqld.pid")
for _ in $(seq 60); do "${SQL[@]}" -e 'select 1' >/dev/null 2>&1 && break; sleep 0.5; done
"${SQL[@]}" -e 'select 1' >/dev/null || fail "mariadbd did not start ($STATE/mysql/mysqld.log)"
DB_PASS=$(cat "$STATE/etc/db.pass" 2>/dev/null || head -c 12 /dev/urandom | od -An -tx1 | tr -d ' \n' | tee "$STATE/etc/db.pass")
"${SQL[@]}" -e "CREATE USER IF NOT EXISTS 'slurm'@'127.0.0.1' IDENTIFIED BY '$DB_PASS';
    ALTER USER 'slurm'@'127.0.0.1' IDENTIFIED BY '$DB_PASS';
    GRANT ALL ON waterair_acct.* TO 'slurm'@'127.0.0.1';"
say "mariadbd started"

# --- Slurm: one node, this machine, as slurmd -C describes it; linuxproc tracking (no cgroups needed).
NODE=$(slurmd -C | head -1 | sed "s/^NodeName=[^ ]*/NodeName=$HOST NodeAddr=127.0.0.1/")
cat >"$STATE/etc/slurm.conf" <<EOF
# Written by scripts/slurm_check.sh: a private single-node cluster for the sweep check.
ClusterName=$CLUSTER
SlurmctldHost=$HOST(127.0.0.1)
SlurmctldPort=${PORTS[0]}
SlurmdPort=${PORTS[1]}
SlurmUser=slurm
AuthType=auth/munge
StateSaveLocation=$STATE/ctld
SlurmdSpoolDir=$STATE/slurmd
SlurmctldPidFile=$STATE/run/slurmctld.pid
SlurmdPidFile=$STATE/run/slurmd.pid
SlurmctldLogFile=$STATE/log/slurmctld.log
SlurmdLogFile=$STATE/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/linux
AccountingStorageType=accounting_storage/slurmdbd
AccountingStorageHost=127.0.0.1
AccountingStoragePort=${PORTS[2]}
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ReturnToService=2
MpiDefault=none
$NODE State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
cat >"$STATE/etc/slurmdbd.conf" <<EOF
AuthType=auth/munge
DbdHost=$HOST
DbdAddr=127.0.0.1
DbdPort=${PORTS[2]}
SlurmUser=slurm
StorageType=accounting_storage/mysql
StorageHost=127.0.0.1
StoragePort=${PORTS[3]}
StorageUser=slurm
StoragePass=$DB_PASS
StorageLoc=waterair_acct
LogFile=$STATE/log/slurmdbd.log
PidFile=$STATE/run/slurmdbd.pid
EOF
chown slurm:slurm "$STATE/etc/slurmdbd.conf" && chmod 0600 "$STATE/etc/slurmdbd.conf"

slurmdbd
STARTED+=("$STATE/run/slurmdbd.pid")
for _ in $(seq 60); do sacctmgr -n show cluster >/dev/null 2>&1 && break; sleep 0.5; done
sacctmgr -n show cluster >/dev/null || fail "slurmdbd does not answer ($STATE/log/slurmdbd.log)"
sacctmgr -n show cluster format=cluster | grep -qw "$CLUSTER" || sacctmgr -i add cluster "$CLUSTER" >/dev/null
say "slurmdbd started"
slurmctld
STARTED+=("$STATE/run/slurmctld.pid")
slurmd
STARTED+=("$STATE/run/slurmd.pid")
for _ in $(seq 60); do [[ $(sinfo -h -o %T 2>/dev/null) == idle ]] && break; sleep 0.5; done
[[ $(sinfo -h -o %T) == idle ]] || fail "the node is not idle: $(sinfo -h -o '%T %E') ($STATE/log/slurmd.log)"
say "slurmctld and slurmd started: $(sinfo -h -o '%P %D %c CPUs %m MB %T')"

# --- The sweeps, from the repository.
cd "$REPO"
[[ -x .venv/bin/python ]] || make install
PYTHON=.venv/bin/python
ROOT=outputs/slurm-check/$(date +%Y-%m-%d_%H-%M-%S)

say "1. two tiny jobs with the default settings"
$PYTHON train.py -m seed=0,1 hydra/launcher=submitit_slurm "${TINY[@]}" hydra.sweep.dir="$ROOT/pair" | tee "$STATE/log/pair.out"
last=$(tail -1 "$STATE/log/pair.out")
[[ $last == "Summary of 2 jobs: $ROOT/pair/summary.md" ]] || fail "the last line is not the summary's: $last"
for job in 0 1; do [[ -s $ROOT/pair/$job/final_metrics.json ]] || fail "job $job has no final_metrics.json"; done
[[ $(grep -c ',finished,' "$ROOT/pair/summary.csv") == 2 ]] || fail "summary.csv does not list 2 finished jobs"
[[ -s $ROOT/pair/learning_curves.png ]] || fail "no learning_curves.png"
array=$($PYTHON -c "import json, sys; print(json.load(open(sys.argv[1]))['id'].split('_')[0])" "$ROOT/pair/0/job.json")
sacct -n -X -j "$array" -o JobID,State,Elapsed | tee "$STATE/log/pair.sacct"
[[ $(grep -c COMPLETED "$STATE/log/pair.sacct") == 2 ]] || fail "sacct does not show both jobs COMPLETED"
say "per job: $(awk '{printf "%s %s; ", $1, $3}' "$STATE/log/pair.sacct")(load: $(cut -d' ' -f1-3 /proc/loadavg))"

say "2. three jobs, the last cancelled while it waits"
$PYTHON train.py -m seed=0,1,2 hydra/launcher=submitit_slurm hydra.launcher.array_parallelism=2 "${TINY[@]}" \
    hydra.sweep.dir="$ROOT/cancelled" >"$STATE/log/cancelled.out" 2>"$STATE/log/cancelled.err" &
sweep=$!
for _ in $(seq 120); do
    pending=$(squeue -h -t PENDING -r -o %i | grep '_2$' || true)
    [[ -n $pending ]] && break
    sleep 0.5
done
[[ -n $pending ]] || fail "job 2 never waited in the queue"
scancel "$pending"
status=0 && wait "$sweep" || status=$?
cat "$STATE/log/cancelled.err"
((status == 1)) || fail "exit status $status, not 1"
[[ $(wc -l <"$STATE/log/cancelled.err") == 1 ]] || fail "the error is not one line"
grep -q "job 2 (seed=2) cancelled" "$STATE/log/cancelled.err" || fail "the error does not name the cancelled job"
[[ $(grep -c ',finished,' "$ROOT/cancelled/summary.csv") == 2 ]] || fail "the summary does not hold the 2 finished jobs"
grep -q "| 2 | \`seed=2\` | cancelled |" "$ROOT/cancelled/summary.md" || fail "summary.md does not mark job 2 cancelled"
$PYTHON -m waterair.cli.sweep "$ROOT/cancelled" 2>/dev/null && fail "the rebuild does not report the cancelled job"
say "the summary of the two, job 2 marked cancelled, exit 1, one line; the rebuild says the same"

say "3. refused launches: one line, outputs/ as it was"
before=$(find outputs | sort | md5sum)
for refused in hydra.launcher.partition=nowhere hydra.launcher.mem_gb=100000; do
    status=0 && $PYTHON train.py -m seed=0,1 hydra/launcher=submitit_slurm "$refused" 2>"$STATE/log/refused.err" || status=$?
    cat "$STATE/log/refused.err"
    ((status == 1)) && [[ $(wc -l <"$STATE/log/refused.err") == 1 ]] || fail "$refused: exit $status, not 1 with one line"
done
[[ $(find outputs | sort | md5sum) == "$before" ]] || fail "a refused launch left files in outputs/"
say "all checks passed; the sweeps are in $ROOT"
