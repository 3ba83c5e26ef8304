#!/usr/bin/env bash
# A live test of deploy/slurm on a one-node Slurm cluster made here, on localhost:
#
#   tests/slurm/check.sh EVBENCH WORKDIR
#
# As root: installs Debian's slurm-wlm and munge when missing, writes a private munge key and a
# slurm.conf for this host under WORKDIR (own socket, ports, state and spool: a real cluster's
# daemons are not touched), starts munged, slurmctld and slurmd, then
#   1. submits a small variant of benchmark/configs/quick.toml (the same two methods on the
#      tiny scene, shrunk to 48x32 and a few iterations) as a 2-task array
#      (deploy/slurm/array.sbatch) plus the merge job (deploy/slurm/merge.sbatch,
#      --dependency=afterok), waits, and checks that the merged table equals an unsharded
#      `evbench run` of the same matrix byte for byte;
#   2. submits the array again into a fresh results folder, cancels the task training nerf in
#      the middle of its cell (scancel sends SIGTERM: evbench checkpoints and exits), checks that
#      the cell is left partial, resubmits that one task (EVBENCH_SHARDS=2) with the merge job
#      after it, and checks that the cell resumed and the merged table is again the unsharded
#      one;
# and stops the daemons it started, by their pids. Not root: prints SKIPPED and exits 77.
set -euo pipefail
if [ $# -ne 2 ]; then
    echo "usage: tests/slurm/check.sh EVBENCH WORKDIR" >&2
    exit 2
fi
EVBENCH=$(realpath "$1")
WORK=$2
REPO=$(cd "$(dirname "$0")/../.." && pwd)
if [ "$(id -u)" != 0 ]; then
    echo "SKIPPED: the Slurm test needs root (it installs slurm-wlm and munge and starts their daemons)"
    exit 77
fi
if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null || ! command -v sbatch >/dev/null \
    || ! command -v munged >/dev/null; then
    command -v apt-get >/dev/null || { echo "check.sh: no slurm-wlm/munge and no apt-get to install them" >&2; exit 1; }
    export DEBIAN_FRONTEND=noninteractive
    (apt-get install -y slurm-wlm munge || (apt-get update && apt-get install -y slurm-wlm munge)) >&2
fi

rm -rf "$WORK"
mkdir -p "$WORK"/{munge,state,spool,jobs}
WORK=$(realpath "$WORK")
chmod 700 "$WORK/munge"
log() { echo "[slurm test $(date +%T)] $*"; }
pids=()
stop_daemons() {
    for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
    for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
}
fail() {
    echo "check.sh: FAILED: $*" >&2
    for f in "$WORK"/slurmctld.log "$WORK"/slurmd.log "$WORK"/jobs/*.out; do
        [ -f "$f" ] && { echo "--- $f (last lines)" >&2; tail -n 30 "$f" >&2; }
    done
    exit 1
}
trap stop_daemons EXIT

# munge: a private key and socket.
dd if=/dev/urandom of="$WORK/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$WORK/munge/munge.key"
SOCK="$WORK/munge/munge.socket"
munged --foreground --force --socket="$SOCK" --key-file="$WORK/munge/munge.key" \
    --pid-file="$WORK/munge/munged.pid" --log-file="$WORK/munge/munged.log" \
    --seed-file="$WORK/munge/munged.seed" >"$WORK/munge/stdout.log" 2>&1 &
pids+=($!)

# slurm: one node (this host, all its CPUs), one partition, free ports.
HOST=$(hostname -s)
CPUS=$(nproc)
port() { python3 -c 'import socket; s = socket.socket(); s.bind(("", 0)); print(s.getsockname()[1])'; }
export SLURM_CONF="$WORK/slurm.conf"
cat >"$SLURM_CONF" <<EOF
ClusterName=evblurtest
SlurmctldHost=$HOST
SlurmctldPort=$(port)
SlurmdPort=$(port)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$SOCK
StateSaveLocation=$WORK/state
SlurmdSpoolDir=$WORK/spool
SlurmctldPidFile=$WORK/slurmctld.pid
SlurmdPidFile=$WORK/slurmd.pid
SlurmctldLogFile=$WORK/slurmctld.log
SlurmdLogFile=$WORK/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
ReturnToService=2
KillWait=60
MinJobAge=3600
NodeName=$HOST CPUs=$CPUS RealMemory=1000 State=UNKNOWN
PartitionName=test Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF
for i in $(seq 50); do [ -S "$SOCK" ] && break; sleep 0.1; done
[ -S "$SOCK" ] || fail "munged did not start: $(cat "$WORK/munge/stdout.log" "$WORK/munge/munged.log" 2>/dev/null)"
slurmctld -D -i -f "$SLURM_CONF" >"$WORK/slurmctld.stdout" 2>&1 &
pids+=($!)
slurmd -D -f "$SLURM_CONF" -N "$HOST" >"$WORK/slurmd.stdout" 2>&1 &
pids+=($!)
for i in $(seq 120); do
    state=$(sinfo -h -n "$HOST" -o %t 2>/dev/null || true)
    [ "$state" = idle ] && break
    sleep 0.5
done
[ "$state" = idle ] || fail "the node did not come up (sinfo says '${state}')"
log "cluster up: node $HOST, $CPUS CPUs, slurm $(sinfo --version | cut -d' ' -f2)"

# The matrix: quick.toml's methods on tiny, shrunk to seconds per cell; nerf (the cell to cancel
# in part 2) trains longer, so that the cancel surely lands in the middle of it.
MATRIX="$WORK/quick-small.toml"
sed -e 's/^iterations = .*/iterations = 100/' -e '/^results = /d' \
    -e "s|^scene = .*|scene = \"$REPO/scenes/tiny/scene.toml\"|" \
    -e 's/^scale = "cpu"$/scale = "cpu"\nset = ["model.coarse_volume.res=32", "batch_rays=256", "eval_every=0"]/' \
    -e 's/^preset = "nerf"$/preset = "nerf"\nname = "nerf"\nset = ["iterations=300"]/' \
    "$REPO/benchmark/configs/quick.toml" >"$MATRIX"
printf '\n[dataset]\nwidth = 48\nheight = 32\nspp = 1\nsharp_spp = 1\n' >>"$MATRIX"

# Waits until none of the jobs is pending or running; fails after $2 seconds.
wait_jobs() {
    local jobs=$1 limit=$2 t=0
    while [ -n "$(squeue -h -j "$jobs" -o %i 2>/dev/null)" ]; do
        [ "$t" -ge $((limit * 2)) ] && fail "jobs $jobs still queued or running after ${limit} s"
        sleep 0.5
        t=$((t + 1))
    done
}
# The state of job $1 (e.g. COMPLETED, CANCELLED, FAILED).
job_state() { scontrol show job "$1" | sed -n 's/.*JobState=\([A-Z_]*\).*/\1/p' | head -n 1; }
submit() { sbatch --parsable --chdir="$WORK/jobs" --export="ALL,EVBENCH=$EVBENCH${EXTRA_EXPORT:-}" "$@"; }

log "unsharded reference run"
"$EVBENCH" run "$MATRIX" --results "$WORK/unsharded" --threads 1 --quiet >"$WORK/unsharded.log" 2>&1 \
    || fail "unsharded run: $(cat "$WORK/unsharded.log")"
want="$WORK/unsharded/table1.csv"
[ -f "$want" ] || fail "the unsharded run wrote no table1.csv"

log "1. a 2-task array and the merge job"
array=$(submit --array=0-1 --cpus-per-task=1 --output="$WORK/jobs/a-%A_%a.out" \
    "$REPO/deploy/slurm/array.sbatch" "$MATRIX" --results "$WORK/sharded")
merge=$(submit --dependency=afterok:"$array" --output="$WORK/jobs/merge-%j.out" \
    "$REPO/deploy/slurm/merge.sbatch" "$MATRIX" "$WORK/sharded")
wait_jobs "$array,$merge" 900
for t in 0 1; do
    [ "$(job_state "${array}_$t")" = COMPLETED ] || fail "array task $t: $(job_state "${array}_$t")"
done
[ "$(job_state "$merge")" = COMPLETED ] || fail "merge job: $(job_state "$merge")"
cmp "$want" "$WORK/sharded/table1.csv" || fail "the merged table differs from the unsharded one"
log "merged table = unsharded table:"
cat "$WORK/sharded/table1.md"

log "2. cancel the array task training nerf in the middle of its cell, resubmit it"
# The dataset is there this time (phase 1 checked that shards simulate it): the cells start at once.
mkdir -p "$WORK/preempted"
cp -r "$WORK/unsharded/datasets" "$WORK/preempted/"
array=$(submit --array=0-1 --cpus-per-task=1 --output="$WORK/jobs/b-%A_%a.out" \
    "$REPO/deploy/slurm/array.sbatch" "$MATRIX" --results "$WORK/preempted")
# The nerf cell: its shard (task = shard - 1), and its start (its log.csv appears).
for shard in 1 2; do
    cell=$("$EVBENCH" run "$MATRIX" --results "$WORK/preempted" --dry-run --shard $shard/2 \
        | awk '$3 == "nerf" { print $1 }')
    if [ -n "$cell" ]; then break; fi
done
[ -n "$cell" ] || fail "no nerf cell in the dry run"
task=$((shard - 1))
t=0
until [ -n "$(find "$WORK/preempted" -path "*$cell*" -name log.csv 2>/dev/null)" ]; do
    [ "$t" -ge 3000 ] && fail "the nerf cell $cell (task $task) did not start training in 600 s"
    sleep 0.2
    t=$((t + 1))
done
scancel "${array}_$task"
wait_jobs "${array}_$task" 120
status=$("$EVBENCH" run "$MATRIX" --results "$WORK/preempted" --dry-run --shard $shard/2 | grep "^$cell" || true)
log "after scancel of task $task: $status"
case "$status" in
    *"partial (step"*) ;;
    *) fail "cell $cell is not left partial by the cancel: '$status' (did it finish before the cancel?)" ;;
esac
again=$(EXTRA_EXPORT=",EVBENCH_SHARDS=2" submit --array=$task --cpus-per-task=1 --output="$WORK/jobs/c-%A_%a.out" \
    "$REPO/deploy/slurm/array.sbatch" "$MATRIX" --results "$WORK/preempted")
merge=$(submit --dependency=afterany:"$array",afterok:"$again" --output="$WORK/jobs/merge2-%j.out" \
    "$REPO/deploy/slurm/merge.sbatch" "$MATRIX" "$WORK/preempted")
wait_jobs "$array,$again,$merge" 900
other=$((1 - task))
[ "$(job_state "${array}_$other")" = COMPLETED ] || fail "array task $other: $(job_state "${array}_$other")"
[ "$(job_state "${array}_$task")" = CANCELLED ] || fail "array task $task was to be cancelled: $(job_state "${array}_$task")"
[ "$(job_state "${again}_$task")" = COMPLETED ] || fail "resubmitted task: $(job_state "${again}_$task")"
[ "$(job_state "$merge")" = COMPLETED ] || fail "merge job: $(job_state "$merge")"
resumed="$WORK/jobs/c-${again}_$task.out"
grep -q "1 resumed" "$resumed" || fail "the resubmitted task did not resume: $(cat "$resumed")"
cmp "$want" "$WORK/preempted/table1.csv" || fail "after the cancel and resubmission the table differs from the unsharded one"
log "cancelled and resubmitted: $(grep -h "cells:" "$resumed")"
log "merged table = unsharded table; PASSED"
