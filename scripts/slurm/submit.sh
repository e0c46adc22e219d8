#!/usr/bin/env bash
# Submit a study as a SLURM job array of K shards plus a merge job that runs when all succeed.
#
#   scripts/slurm/submit.sh K SCENARIO OUT_ROOT [edgekf run flags…]
#
# Prints the merge job's id; the merged study ends up in OUT_ROOT/merged. Set EDGEKF to the
# binary's path when `edgekf` is not on the compute nodes' PATH; add sbatch options (partition,
# time limit) through SBATCH_* environment variables, e.g. SBATCH_PARTITION=short.
set -euo pipefail
if [ $# -lt 3 ]; then
  echo "usage: $0 K SCENARIO OUT_ROOT [edgekf run flags…]" >&2
  exit 2
fi
k=$1
scenario=$2
root=$3
shift 3
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$root"
array=$(sbatch --parsable --array="1-$k" --chdir="$root" --export=ALL \
  "$here/edgekf-array.sbatch" "$(realpath "$scenario")" "$(realpath "$root")" "$@")
shards=()
for i in $(seq 1 "$k"); do shards+=("$(realpath "$root")/shard-$i"); done
sbatch --parsable --dependency="afterok:$array" --chdir="$root" --export=ALL \
  --job-name=edgekf-merge --output=slurm-merge-%j.out \
  --wrap "${EDGEKF:-edgekf} merge ${shards[*]} --out $(realpath "$root")/merged"
