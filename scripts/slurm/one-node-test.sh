#!/usr/bin/env bash
# Runs the job-array recipe on a real one-node SLURM cluster started here, and checks that the
# merged study equals the unsharded one byte for byte (metrics.csv, status.csv, scenario.json).
#
#   scripts/slurm/one-node-test.sh [EDGEKF_BINARY]
#
# Needs root and Debian's slurm-wlm and munge (installed when missing, with apt-get). Starts
# munged, slurmctld and slurmd from a temporary configuration (no systemd) and stops them on exit
# (and removes the temporary directory unless EDGEKF_KEEP_SLURM is set).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
bin=$(realpath "${1:-$repo/target/release/edgekf}")
[ -x "$bin" ] || { echo "error: $bin is not an executable edgekf binary (build it first)" >&2; exit 1; }
[ "$(id -u)" = 0 ] || { echo "error: starting a SLURM cluster needs root" >&2; exit 1; }
if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
  command -v apt-get >/dev/null || { echo "error: slurm-wlm/munge missing and no apt-get" >&2; exit 1; }
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge >/dev/null
fi

work=$(mktemp -d /tmp/edgekf-slurm.XXXXXX)
chmod 755 "$work"
host=$(hostname -s)
cpus=$(nproc)
mem=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 / 2 ))
mkdir -p "$work/state" "$work/spool" "$work/munge" "$work/log"
export SLURM_CONF="$work/slurm.conf"
cat >"$SLURM_CONF" <<CONF
ClusterName=edgekf-test
SlurmctldHost=$host
SlurmUser=root
AuthType=auth/munge
CredType=cred/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
ReturnToService=2
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/log/slurmctld.log
SlurmdLogFile=$work/log/slurmd.log
SlurmctldPort=16817
SlurmdPort=16818
NodeName=$host CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
# munge: a fresh key and socket of our own, so an existing munged is left alone.
sock="$work/munge/munge.socket"
dd if=/dev/urandom bs=1 count=1024 of="$work/munge/munge.key" status=none
chmod 400 "$work/munge/munge.key"
munged --force --key-file="$work/munge/munge.key" --socket="$sock" \
  --pid-file="$work/munge/munged.pid" --log-file="$work/log/munged.log" \
  --seed-file="$work/munge/seed"
cleanup() {
  set +e
  for p in slurmd slurmctld; do [ -f "$work/$p.pid" ] && kill "$(cat "$work/$p.pid")" 2>/dev/null; done
  [ -f "$work/munge/munged.pid" ] && kill "$(cat "$work/munge/munged.pid")" 2>/dev/null
  sleep 1
  [ -n "${EDGEKF_KEEP_SLURM:-}" ] || rm -rf "$work"
}
trap cleanup EXIT
echo "AuthInfo=socket=$sock" >>"$SLURM_CONF"
slurmctld -i
slurmd
for _ in $(seq 1 60); do
  sinfo -h -o %t 2>/dev/null | grep -qx idle && break
  sleep 1
done
sinfo -h -o %t | grep -qx idle || { echo "error: the node never became idle" >&2; sinfo >&2; cat "$work"/log/*.log >&2; exit 1; }
echo "one-node cluster up: $(sinfo -h -o '%P %D %t %c CPUs')"

# The study: the smallest shipped scenario at reduced size, in 3 shards.
scenario="$repo/scenarios/eusipco.toml"
flags=(--runs 6 --steps 300 --every 10)
out="$work/study"
mkdir -p "$out"
"$bin" run "$scenario" --out "$out/unsharded" "${flags[@]}" >/dev/null
merge=$(EDGEKF="$bin" "$here/submit.sh" 3 "$scenario" "$out/sharded" "${flags[@]}")
echo "submitted 3 array tasks and merge job $merge"
for _ in $(seq 1 600); do
  [ -z "$(squeue -h 2>/dev/null)" ] && break
  sleep 1
done
if [ -n "$(squeue -h)" ]; then
  echo "error: jobs still queued after 600 s" >&2; squeue >&2; exit 1
fi
for f in metrics.csv status.csv scenario.json; do
  if ! cmp "$out/unsharded/$f" "$out/sharded/merged/$f"; then
    echo "error: merged $f differs from the unsharded run's" >&2
    cat "$out"/sharded/slurm-*.out >&2 || true
    exit 1
  fi
done
echo "SLURM job array: 3 shards merged; metrics.csv, status.csv, scenario.json byte-identical to the unsharded run"
