#!/usr/bin/env bash
# Scale-out under a real Slurm: starts a single-node cluster on this machine (Debian's
# slurm-wlm: munged, slurmctld and slurmd), submits a simulated campaign as an array job
# with `unz run --shard I/N`, waits for it, merges the shards' summaries with
# `unz campaign merge`, and checks that the merged summary equals one plain `unz run`
# (every column but the wall times), and the runs pooled across the shards (sections and
# settings) the plain run's. Needs root (it installs slurm-wlm when missing and
# runs the daemons); everything it writes is under WORK (default: target/slurm-check).
#
#   bash scripts/slurm_check.sh [SHARDS]        # SHARDS array tasks, default 3
set -euo pipefail

here="$(cd "$(dirname "$0")/.." && pwd)"
shards="${1:-3}"
work="${WORK:-$here/target/slurm-check}"
unz="$here/target/release/unz"
py="${UNZ_PYTHON:-$here/.venv/bin/python}"

[ "$(id -u)" = 0 ] || { echo "slurm_check: needs root (daemons, apt)"; exit 2; }
[ -x "$unz" ] || cargo build --release --manifest-path "$here/Cargo.toml"
if ! command -v slurmctld > /dev/null; then
  DEBIAN_FRONTEND=noninteractive apt-get install -y -q slurm-wlm > /dev/null
fi

rm -rf "$work"
mkdir -p "$work"/{state,spool,log}
node="$(hostname -s)"
cpus="$(nproc)"
conf="$work/slurm.conf"
cat > "$conf" <<EOF
ClusterName=unzcheck
SlurmctldHost=$node
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/log/slurmctld.log
SlurmdLogFile=$work/log/slurmd.log
SlurmctldPort=16817
SlurmdPort=16818
NodeName=$node CPUs=$cpus State=UNKNOWN
PartitionName=unz Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$conf"

cleanup() {
  [ -f "$work/slurmd.pid" ] && kill "$(cat "$work/slurmd.pid")" 2> /dev/null || true
  [ -f "$work/slurmctld.pid" ] && kill "$(cat "$work/slurmctld.pid")" 2> /dev/null || true
  [ -n "${munge_pid:-}" ] && kill "$munge_pid" 2> /dev/null || true
}
trap cleanup EXIT

# munge: a key of our own and a daemon on its own socket.
mkdir -p "$work/munge"
dd if=/dev/urandom of="$work/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$work/munge/munge.key"
socket="$work/munge/munge.socket"
munged --force --key-file="$work/munge/munge.key" --socket="$socket" \
  --pid-file="$work/munge/munged.pid" --log-file="$work/munge/munged.log" \
  --seed-file="$work/munge/munged.seed"
munge_pid="$(cat "$work/munge/munged.pid")"
printf 'AuthInfo=socket=%s\n' "$socket" >> "$conf"

slurmctld -f "$conf"
slurmd -f "$conf"
for _ in $(seq 60); do
  sinfo -h -o %T 2> /dev/null | grep -qE '^(idle|mixed|allocated)' && break
  sleep 1
done
sinfo

# A small campaign: 6 simulated runs of 5 minutes, of a vehicle whose path climbs 1.5°
# above its IMU's x (the runs pool the angle to configure).
"$unz" simulate --out "$work/campaign" --seed 300 --runs 6 --duration-s 300 \
  --odo-pitch-deg 1.5 --odo-lag-s 0.4 > /dev/null

t0=$(date +%s.%N)
job=$(sbatch --parsable --wait --array=0-$((shards - 1)) --cpus-per-task=1 \
  --output="$work/log/task-%a.out" \
  --wrap "\"$unz\" run \"$work/campaign\" --out \"$work/shard-\$SLURM_ARRAY_TASK_ID\" --shard \$SLURM_ARRAY_TASK_ID/$shards --jobs 1")
t1=$(date +%s.%N)
echo "array job $job: $shards tasks in $(echo "$t1 - $t0" | bc) s"
sacct_state=$(scontrol show job "$job" 2> /dev/null | grep -o 'JobState=[A-Z]*' | sort -u | tr '\n' ' ' || true)
echo "job states: ${sacct_state:-gone from the controller (completed)}"
for i in $(seq 0 $((shards - 1))); do
  [ -f "$work/shard-$i/campaign.parquet" ] || { echo "shard $i wrote no summary:"; cat "$work/log/task-$i.out"; exit 1; }
done

"$unz" campaign merge $(for i in $(seq 0 $((shards - 1))); do echo "$work/shard-$i"; done) \
  --into "$work/merged.parquet"
"$unz" run "$work/campaign" --out "$work/single" > /dev/null 2>&1

"$py" - "$work/merged.parquet" "$work/single/campaign.parquet" <<'EOF'
import sys
import pyarrow.parquet as pq

merged, single = (pq.read_table(p) for p in sys.argv[1:3])
timing = [c for c in single.column_names if c.endswith("_s") and c not in ("joint_odo_lag_s", "joint_odo_lag_sigma_s")]
common = [c for c in single.column_names if c in merged.column_names and c not in timing]
assert len(common) > 20, common
def rows(t):
    return sorted(t.select(common).to_pylist(), key=lambda r: r["run"])
a, b = rows(merged), rows(single)
assert [r["run"] for r in a] == [r["run"] for r in b], (len(a), len(b))
for x, y in zip(a, b):
    assert x == y, f"{x['run']}: merged {x} != single {y}"
print(f"merged summary of {len(a)} runs equals a single unz run "
      f"({len(common)} columns; the {len(timing)} wall-time columns left out)")
EOF

# The runs pooled across the shards (merged.md's sections, merged-settings.toml) are the
# single run's (campaign.md's sections, campaign-settings.toml).
"$py" - "$work" <<'EOF2'
import os, sys
work = sys.argv[1]
def read(p):
    return open(p).read() if os.path.exists(p) else None
def sections(md, settings_name):
    i = md.find("\n## ")
    return md[i:].replace(settings_name, "SETTINGS") if i >= 0 else ""
merged = sections(read(f"{work}/merged.md"), "merged-settings.toml")
single = sections(read(f"{work}/single/campaign.md"), "campaign-settings.toml")
assert merged == single, f"merged pools {merged!r} != single {single!r}"
assert "## The vehicle's odometer pitch" in single, single
assert read(f"{work}/merged-settings.toml") == read(f"{work}/single/campaign-settings.toml")
print(f"merged pools equal a single unz run's ({merged.count(chr(10) + '## ')} sections)")
EOF2
