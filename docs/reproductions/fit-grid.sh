#!/usr/bin/env bash
# The grid of fixed recipes beside `armcomp fit`: every level (registration, joint offsets,
# geometry) under every prior scheme (the evidence per parameter and per group, the file's
# priors at ×0.1 … ×10, none), with and without a GP, each fitted on a split's training rows
# and scored on its held-out rows; then `armcomp fit` on the same training rows. Prints, per
# split, the best recipe after the fact, fit's choice and the ratio of their held-out RMS.
# Usage: docs/reproductions/fit-grid.sh ROBOT DATA NAME:TRAIN:TEST [NAME:TRAIN:TEST ...]
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release -q
A=target/release/armcomp
R=$1
D=$2
shift 2
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
rms() { "$A" evaluate --model "$1" --data "$D" --rows "$2" 2>/dev/null | awk '/RMS/ {for (i = 1; i <= NF; i++) if ($i == "RMS") {print $(i + 1); exit}}'; }
echo "| split | recipes | best recipe (held-out RMS mm) | fit's choice | fit held out | fit / best | fit expected | fit seconds |"
echo "|---|---|---|---|---|---|---|---|"
for split in "$@"; do
  IFS=: read -r name train test <<< "$split"
  best=""; best_rms=1e9; n=0
  for level in base,markers base,markers,offsets base,markers,geometry; do
    for prior in evidence evidence-groups 0.1 0.3 1 3 10 none; do
      m="$OUT/m.toml"
      "$A" calibrate --robot "$R" --data "$D" --rows "$train" --identify "$level" --prior "$prior" --out "$m" > /dev/null 2>&1 || true
      [ -f "$m" ] || continue
      for gp in off on; do
        model=$m
        if [ $gp = on ]; then
          "$A" learn --model "$m" --predictor gp --data "$D" --rows "$train" --out "$OUT/g.toml" > /dev/null 2>&1 || continue
          model="$OUT/g.toml"
        fi
        r=$(rms "$model" "$test")
        n=$((n + 1))
        if awk "BEGIN{exit !($r < $best_rms)}"; then best_rms=$r; best="$level $prior gp:$gp"; fi
      done
      rm -f "$m" "$OUT/g.toml"
    done
  done
  start=$(date +%s.%N)
  "$A" fit --robot "$R" --data "$D" --rows "$train" --out "$OUT/fit.toml" --json > "$OUT/fit.json" 2>/dev/null || true
  end=$(date +%s.%N)
  chosen=$(python3 -c "import json,sys; r=json.load(open('$OUT/fit.json')); c=r['chosen']; print(c['rung'], c['prior'], 'gp:' + ('on' if c['predictor'] else 'off'))" | tr -d ' {}"' )
  expected=$(python3 -c "import json; print('%.3f' % json.load(open('$OUT/fit.json'))['expected_rms_mm'])")
  fit_rms=$(rms "$OUT/fit.toml" "$test")
  printf '| %s | %d | %s (%s) | %s | %s | %.3f | %s | %.1f |\n' "$name" "$n" "$best" "$best_rms" "$chosen" "$fit_rms" \
    "$(awk "BEGIN{print $fit_rms / $best_rms}")" "$expected" "$(awk "BEGIN{print $end - $start}")"
done
