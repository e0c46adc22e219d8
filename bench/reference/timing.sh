#!/bin/bash
# One-core timings, Rust vs the NumPy references, interleaved; whole-process wall and CPU time.
#   bash bench/reference/timing.sh SCENARIO.json PYTHON [ROUNDS [GARKF_ROUNDS]]
# SCENARIO.json: the resolved EUSIPCO scenario (`edgekf run scenarios/eusipco.toml --out D`).
set -euo pipefail
cd "$(dirname "$0")/../.."
SC=${1:?resolved scenario.json}; PY=${2:?python with numpy}; ROUNDS=${3:-5}; GA_ROUNDS=${4:-3}
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1
OUT=$(mktemp -d /tmp/pyref-timing.XXXX)
# the resolved scenario without plots, and with rkf only
"$PY" - "$SC" "$OUT" <<'EOF'
import json, sys
s = json.load(open(sys.argv[1])); s["plots"] = []
json.dump(s, open(sys.argv[2] + "/noplots.json", "w"))
s["estimators"] = ["rkf"]; s["estimator_specs"] = [x for x in s["estimator_specs"] if x["label"] == "rkf"]
json.dump(s, open(sys.argv[2] + "/rkfonly.json", "w"))
EOF
T() { /usr/bin/time -f "$1 wall=%e user=%U sys=%S" "${@:2}" > /dev/null 2>> "$OUT/time.txt"; tail -1 "$OUT/time.txt"; }
for rep in $(seq 1 "$ROUNDS"); do
  echo "== round $rep load $(cut -d' ' -f1-3 /proc/loadavg)"
  T rust5 nice -n 10 target/release/edgekf run "$OUT/noplots.json" --out "$OUT/rs5" --threads 1
  T py5 nice -n 10 "$PY" bench/reference/eusipco.py "$SC" --out "$OUT/py5" --quiet
  T rustrkf nice -n 10 target/release/edgekf run "$OUT/rkfonly.json" --out "$OUT/rsrkf" --threads 1
  T pyrkf nice -n 10 "$PY" bench/reference/eusipco.py "$SC" --out "$OUT/pyrkf" --estimators rkf --quiet
done
for rep in $(seq 1 "$GA_ROUNDS"); do
  echo "== garkf round $rep load $(cut -d' ' -f1-3 /proc/loadavg)"
  T ga20 nice -n 10 "$PY" bench/reference/garkf.py "$SC" --lam 0.4 --gain 1 --runs 20 --quiet --out "$OUT/ga20"
  grep -o '"cpu": [0-9.]*\|"agent_steps_per_s": [0-9.]*' "$OUT/ga20/summary.json" | tr '\n' ' '; echo
  T ga100 nice -n 10 "$PY" bench/reference/garkf.py "$SC" --lam 0.4 --gain 1 --runs 100 --quiet --out "$OUT/ga100"
  grep -o '"cpu": [0-9.]*\|"agent_steps_per_s": [0-9.]*' "$OUT/ga100/summary.json" | tr '\n' ' '; echo
done
echo "outputs in $OUT"
