#!/usr/bin/env bash
# TALOS torso and left arm (data/talos-left-arm/): each calibration level on both splits of
# the data's README, trained on the training rows only and scored on the held-out rows.
# Prints one line per split and level: train and held-out RMSE / mean / max in mm.
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release -q
A=target/release/armcomp
D=data/talos-left-arm/measurements.csv
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
stats() { awk '{printf "%.2f / %.2f / %.2f", $10, $4, $13}'; }
level() { # split-name train-rows test-rows level robot identify prior [calibrate options]
  local model="$OUT/$1-$4.toml"
  local start=$(date +%s.%N)
  "$A" calibrate --robot "$5" --data "$D" --rows "$2" --identify "$6" --prior "$7" "${@:8}" --out "$model" > "$OUT/log" 2>&1 || true
  local end=$(date +%s.%N)
  # With --prior auto: the chosen factor and its cross-validated RMS on the training rows.
  local chosen=$(grep -o 'cross-validation on these data[^:]*: [^ ]*' "$OUT/log" | awk '{print $NF}')
  local cv=$(grep -o "$chosen → [0-9.]*" "$OUT/log" | head -1 | awk '{print $3}')
  printf '| %s | %s | %s | %s | %s | %.2f |\n' "$1" "$4" "${chosen:+×$chosen, $cv mm}" \
    "$("$A" evaluate --model "$model" --data "$D" --rows "$2" 2>/dev/null | stats)" \
    "$("$A" evaluate --model "$model" --data "$D" --rows "$3" 2>/dev/null | stats)" \
    "$(awk "BEGIN{print $end - $start}")"
}
# FIGAROH 1.0.2's full_params parameters for each split (its QR selection; the file says how
# they were obtained and named).
figaroh() { grep "^$1=" tests/data/figaroh_talos_full_params.txt | cut -d= -f2; }
FIGAROH_INTERLEAVED=$(figaroh interleaved)
FIGAROH_TIME=$(figaroh time)
echo "| split | level | prior (training CV RMS) | train RMSE / mean / max | held-out RMSE / mean / max | seconds |"
echo "|---|---|---|---|---|---|"
for split in "interleaved even odd $FIGAROH_INTERLEAVED" "time ..40 40.. $FIGAROH_TIME"; do
  set -- $split
  # FIGAROH's level: its parameters, no priors, the Levenberg–Marquardt run to convergence.
  level "$1" "$2" "$3" full_params robots/talos-left-arm.toml "base,markers,$4" none --max-iterations 5000 --restarts 0
  level "$1" "$2" "$3" registration robots/talos-left-arm.toml base,markers 1
  level "$1" "$2" "$3" joint_offset robots/talos-left-arm.toml base,markers,offsets none
  level "$1" "$2" "$3" full_geometry robots/talos-left-arm.toml base,markers,geometry auto
  level "$1" "$2" "$3" geometry+compliance robots/talos-left-arm-compliant.toml base,markers,geometry,errors auto
done
