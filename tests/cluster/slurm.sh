#!/usr/bin/env bash
# A real Slurm cluster in the tests: installs Slurm and munge from Debian's packages when they are
# missing (as root), starts a one-node cluster on localhost with its own config in a temporary
# folder, runs a sharded `bench` as a job array with `sbatch --array` exactly as README.md's
# "On a cluster" section documents, waits, runs `bench merge`, and checks that the merged rows equal
# an unsharded run's (ignoring the wall-clock fields). It stops the daemons it started, by their
# pids, and removes its folder.
#
#   tests/cluster/slurm.sh            # uses target/release/tensorscout (built if missing)
#   TENSORSCOUT_BIN=/path/to/tensorscout tests/cluster/slurm.sh
#
# About a minute once the packages are installed. Exit 0 on success, 1 on any failure.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
SHARDS=3

say() { echo "slurm.sh: $*" >&2; }
fail() { say "FAILED: $*"; exit 1; }

BIN=${TENSORSCOUT_BIN:-$ROOT/target/release/tensorscout}
if [ ! -x "$BIN" ]; then
    say "building the release binary"
    (cd "$ROOT" && cargo build --release --locked)
fi

if ! command -v sbatch >/dev/null 2>&1 || ! command -v slurmctld >/dev/null 2>&1 \
    || ! command -v slurmd >/dev/null 2>&1 || ! command -v munged >/dev/null 2>&1; then
    [ "$(id -u)" = 0 ] || fail "Slurm and munge are missing and installing them needs root"
    say "installing slurm-wlm and munge from Debian"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends slurm-wlm munge >/dev/null
fi

WORK=$(mktemp -d /tmp/tensorscout-slurm.XXXXXX)
chmod 755 "$WORK"
PIDS=()
cleanup() {
    local pid
    for pid in "${PIDS[@]}"; do
        kill "$pid" 2>/dev/null || true
    done
    for pid in "${PIDS[@]}"; do
        # Every daemon runs in the foreground as this shell's child: wait for it to end.
        wait "$pid" 2>/dev/null || true
    done
    rm -rf "$WORK"
}
trap cleanup EXIT

# munge: its own key, socket and files in the temporary folder.
mkdir -m 700 "$WORK/munge"
dd if=/dev/urandom of="$WORK/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$WORK/munge/munge.key"
SOCKET="$WORK/munge/munge.socket"
munged --foreground --force --key-file="$WORK/munge/munge.key" --socket="$SOCKET" \
    --pid-file="$WORK/munge/munged.pid" --log-file="$WORK/munge/munged.log" \
    --seed-file="$WORK/munge/munged.seed" >"$WORK/munge/munged.out" 2>&1 &
PIDS+=($!)
for _ in $(seq 100); do [ -S "$SOCKET" ] && break; sleep 0.1; done
[ -S "$SOCKET" ] || fail "munged did not start: $(cat "$WORK/munge/munged.log" 2>/dev/null)"

# Slurm: one node (this machine) with every CPU, ports away from a system cluster's.
HOST=$(hostname -s)
CPUS=$(nproc)
mkdir -p "$WORK/state" "$WORK/spool" "$WORK/log"
export SLURM_CONF="$WORK/slurm.conf"
cat > "$SLURM_CONF" <<CONF
ClusterName=tensorscout-test
SlurmctldHost=$HOST(127.0.0.1)
SlurmctldPort=16817
SlurmdPort=16818
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$SOCKET
CredType=cred/munge
StateSaveLocation=$WORK/state
SlurmdSpoolDir=$WORK/spool
SlurmctldPidFile=$WORK/slurmctld.pid
SlurmdPidFile=$WORK/slurmd.pid
SlurmctldLogFile=$WORK/log/slurmctld.log
SlurmdLogFile=$WORK/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
MpiDefault=none
NodeName=$HOST NodeAddr=127.0.0.1 CPUs=$CPUS State=UNKNOWN
PartitionName=test Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
slurmctld -D -i -f "$SLURM_CONF" >"$WORK/log/slurmctld.out" 2>&1 &
PIDS+=($!)
slurmd -D -f "$SLURM_CONF" >"$WORK/log/slurmd.out" 2>&1 &
PIDS+=($!)
for _ in $(seq 300); do
    sinfo -h -o %t 2>/dev/null | grep -qE '^(idle|mix|alloc)' && break
    sleep 0.2
done
sinfo -h -o %t 2>/dev/null | grep -qE '^(idle|mix|alloc)' \
    || fail "the node did not come up: $(tail -n 5 "$WORK"/log/* 2>/dev/null)"
say "cluster up: node $HOST with $CPUS CPUs"

# The batch: one small shipped scene, GREEDY, 3 seeds, a short budget.
cd "$WORK"
mkdir scenes results
cp "$ROOT/scenes/apartment_small.obj" scenes/
mkdir bin
ln -s "$BIN" bin/tensorscout
export PATH="$WORK/bin:$PATH"
COMMON=(--planners greedy --set sim.budget_s=30 --quiet)

# The job array, as README.md documents it (array size and shard count N = $SHARDS here).
cat > bench.sbatch <<JOB
#!/bin/bash
#SBATCH --array=0-$((SHARDS - 1))
#SBATCH --cpus-per-task=1
tensorscout bench --scenes scenes/ --seeds 3 --jobs "\$SLURM_CPUS_PER_TASK" \\
    --shard \$((SLURM_ARRAY_TASK_ID+1))/$SHARDS --out "results/shard_\$SLURM_ARRAY_TASK_ID" --resume \\
    ${COMMON[*]}
JOB
say "sbatch --array=0-$((SHARDS - 1)): $SHARDS shards of 3 runs"
timeout 600 sbatch --wait --quiet bench.sbatch \
    || fail "the job array failed: $(cat slurm-*.out 2>/dev/null; tail -n 5 "$WORK"/log/*)"
for k in $(seq 0 $((SHARDS - 1))); do
    [ -s "results/shard_$k/results.jsonl" ] || fail "shard $k wrote no results: $(cat slurm-*.out 2>/dev/null)"
done
tensorscout bench merge results/shard_* --out results/all
tensorscout bench --scenes scenes/ --seeds 3 --jobs 1 --out results/single "${COMMON[@]}"

python3 - results/all/results.jsonl results/single/results.jsonl <<'PY' || fail "merged rows differ from the unsharded run"
import json, sys
def rows(path):
    out = []
    for line in open(path):
        r = json.loads(line)
        for k in ("wall_time_s", "real_time_factor", "timings_ms"):
            (r.get("result") or {}).pop(k, None)
        out.append(r)
    return out
merged, single = rows(sys.argv[1]), rows(sys.argv[2])
assert len(single) == 3, f"{len(single)} rows in the unsharded run"
assert all(r["status"] == "ok" for r in single), single
assert merged == single, "rows differ"
print(f"slurm.sh: {len(merged)} merged rows equal the unsharded run's", file=sys.stderr)
PY
say "ok"
