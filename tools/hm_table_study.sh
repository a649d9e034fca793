#!/bin/bash
# The histogram mixture's table study (docs/results.md, "The histogram mixture's tables"): trains the
# mixture with each table setting on three neural materials (one thread, seed 1, two runs at a
# time), prints KL and χ² from each run's summary.json, then times each setting's blob on the
# goat leather with `neusample bench` (three runs; run it on a quiet machine).
#
#   bash tools/hm_table_study.sh [OUT_DIR]        # about 25 minutes on two cores
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=$(realpath -m "${1:-hm-table-study}")
cargo build --release -p neusample-precompute --bin neusample
BIN=$PWD/target/release/neusample
MATERIALS="goat_leather_neural brushed_metal_neural victorian_fabric_neural"
CONFIGS=(
  "t8n32|--t-levels 8 --hist-res 32 --interpolate-t"
  "t8n32near|--t-levels 8 --hist-res 32 --nearest-t"
  "t16n32|--t-levels 16 --hist-res 32 --interpolate-t"
  "t8n64|--t-levels 8 --hist-res 64 --interpolate-t"
  "t8n64near|--t-levels 8 --hist-res 64 --nearest-t"
  "t32n64|--t-levels 32 --hist-res 64 --interpolate-t"
  "t8n32x3|--t-levels 8 --hist-res 32 --interpolate-t --steps-scale 3"
  "t8n64x3|--t-levels 8 --hist-res 64 --interpolate-t --steps-scale 3"
)
jobs_file=$(mktemp)
for m in $MATERIALS; do
  for c in "${CONFIGS[@]}"; do
    echo "$m|$c" >>"$jobs_file"
  done
done
export BIN OUT
run_one() {
  IFS='|' read -r m name args <<<"$1"
  d=$OUT/$m/$name
  [ -f "$d/summary.json" ] && return 0
  mkdir -p "$d"
  # shellcheck disable=SC2086
  "$BIN" train --material "fixtures/materials/neural/$m.nsb" --method histogram-mixture, \
    --out-dir "$d" --threads 1 --seed 1 --eval-conditions 48 $args >"$d/log" 2>&1 ||
    { echo "failed: $m $name (see $d/log)" >&2; return 1; }
}
export -f run_one
xargs -P 2 -I{} bash -c 'run_one "$1"' _ {} <"$jobs_file"
rm -f "$jobs_file"
python3 - "$OUT" <<'EOF'
import glob, json, sys
print(f"{'material':<24} {'setting':<10} {'KL':>7} {'chi2':>7} {'worst':>7} {'bytes':>9} {'train s':>7}")
for f in sorted(glob.glob(f"{sys.argv[1]}/*/*/summary.json")):
    m, c = f.split("/")[-3:-1]
    hm = next(x for x in json.load(open(f))["methods"] if x["method"] == "histogram-mixture")
    print(f"{m:<24} {c:<10} {hm['kl']:7.4f} {hm['chi2']:7.3f} {hm['chi2_worst']:7.2f} "
          f"{hm['blob_bytes']:9d} {hm['train_seconds']:7.0f}")
EOF
for r in 1 2 3; do
  for c in "${CONFIGS[@]}"; do
    name=${c%%|*}
    case $name in *x3) continue ;; esac
    d=$OUT/goat_leather_neural/$name
    cp fixtures/blobs/goat_leather_neural/conditions.txt "$d/"
    echo "== $name, run $r"
    "$BIN" bench --blobs "$d" --methods histogram-mixture | grep -E "^histogram-mixture|eval batched:"
  done
done
