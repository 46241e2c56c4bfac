#!/usr/bin/env bash
# TIAGo Pro right arm, 6-D poses from a motion-capture rigid body (FIGAROH's TIAGo Pro example;
# data in ../shared/data/tiago-pro-pose/ beside the repository, see tiago-pro.md for where to get
# it). FIGAROH's held-out protocol: the 48 poses split at random into 36 training and 12 test
# rows, seeds 0-3; then the fit on all 48; then the two position-only days as further held-out
# sets (each day its own mocap frame and marker, registered on the calibrated and on the nominal
# model). Prints the tables and, as its last line, one JSON object of the held-out figures.
set -euo pipefail
cd "$(dirname "$0")/../.."
D=../shared/data/tiago-pro-pose
if [ ! -f "$D/calibration_samples_20260805_1246.csv" ]; then
  echo "skipped: $D not found (the TIAGo Pro data of thanhndv212/figaroh-examples, see docs/reproductions/tiago-pro.md)" >&2
  exit 0
fi
cargo build --release -q -p armcomp
A=target/release/armcomp
R=robots/tiago-pro.toml
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
# FIGAROH's headers name neither the spelling nor the units: phix1..phiz1 are Pinocchio's
# roll-pitch-yaw (rpyToMatrix) in rad, positions in m, the torso lift in m, the arm in rad.
units() {
  sed -e '1s/phix1/roll[rad]/; 1s/phiy1/pitch[rad]/; 1s/phiz1/yaw[rad]/; 1s/x1,y1,z1/x[m],y[m],z[m]/' \
      -e '1s/torso_lift_joint/torso_lift_joint[m]/; 1s/\(arm_right_[1-7]_joint\)/\1[rad]/g' "$1"
}
units "$D/calibration_samples_20260805_1246.csv" > "$OUT/pose.csv"
units "$D/calibration_samples_20260701_0913.csv" > "$OUT/day0701.csv"
units "$D/calibration_samples_20260702_0756.csv" > "$OUT/day0702.csv"
# Rows 0..47 shuffled by seed (Fisher-Yates on the Park-Miller generator, exact in any awk):
# the first 36 train, the last 12 test.
split() {
  awk -v seed="$1" 'BEGIN { x = seed + 1; for (i = 0; i < 48; i++) r[i] = i;
    for (i = 47; i > 0; i--) { x = (16807 * x) % 2147483647; j = x % (i + 1); t = r[i]; r[i] = r[j]; r[j] = t }
    for (i = 0; i < 36; i++) printf "%s%s", (i ? "," : ""), r[i]; printf " ";
    for (i = 36; i < 48; i++) printf "%s%s", (i > 36 ? "," : ""), r[i]; print "" }'
}
# mean and RMS (mm), orientation mean and RMS (deg) of a model on rows of a file.
score() { "$A" evaluate --model "$1" --data "$2" ${3:+--rows "$3"} 2>/dev/null |
  awk 'NR == 1 { m = $4; r = $10 } /orientation:/ { d = $5; rd = $8 } END { print m, r, (d == "" ? "nan" : d), (rd == "" ? "nan" : rd) }'; }
fit() { # out data rows identify
  local start=$(date +%s.%N)
  "$A" calibrate --robot "$R" --data "$2" ${3:+--rows "$3"} --identify "$4" --out "$1" > "$OUT/log" 2>&1 || true
  awk "BEGIN { print $(date +%s.%N) - $start }"
}
IDENTIFY=base,markers,geometry
echo "Held-out, 36 training / 12 test rows (FIGAROH: conservative model 21.2 mm / 5.09°, full 34.5 mm / 6.27°, nominal ~139 mm / ~5.6°)"
echo "| seed | train mean mm / deg | test mean mm | test RMS mm | test mean deg | test RMS deg | seconds |"
echo "|---|---|---|---|---|---|---|"
sum_mm=0; sum_deg=0
for seed in 0 1 2 3; do
  read train test < <(split $seed)
  t=$(fit "$OUT/m$seed.toml" "$OUT/pose.csv" "$train" "$IDENTIFY")
  read tr_mean tr_rms tr_deg tr_rdeg < <(score "$OUT/m$seed.toml" "$OUT/pose.csv" "$train")
  read te_mean te_rms te_deg te_rdeg < <(score "$OUT/m$seed.toml" "$OUT/pose.csv" "$test")
  printf '| %s | %.2f / %.2f | %.2f | %.2f | %.2f | %.2f | %.2f |\n' $seed $tr_mean $tr_deg $te_mean $te_rms $te_deg $te_rdeg $t
  sum_mm=$(awk "BEGIN { print $sum_mm + $te_mean }"); sum_deg=$(awk "BEGIN { print $sum_deg + $te_deg }")
done
heldout_mm=$(awk "BEGIN { print $sum_mm / 4 }"); heldout_deg=$(awk "BEGIN { print $sum_deg / 4 }")
printf 'mean over the seeds: %.2f mm / %.2f deg\n\n' $heldout_mm $heldout_deg
echo "Fit on all 48 rows (FIGAROH: RMSE 7.93 mm / 2.18°, MAE 7.28 mm / 1.89°)"
t=$(fit "$OUT/all.toml" "$OUT/pose.csv" "" "$IDENTIFY")
read a_mean a_rms a_deg a_rdeg < <(score "$OUT/all.toml" "$OUT/pose.csv")
printf '| RMSE %.2f mm / %.2f deg | mean %.2f mm / %.2f deg | %.2f s |\n\n' $a_rms $a_rdeg $a_mean $a_deg $t
echo "Position-only days, each registered (mocap frame and marker) on the model, then scored"
echo "| day | rows | nominal model mean / RMS mm | calibrated model mean / RMS mm |"
echo "|---|---|---|---|"
days_json=""
for day in day0701 day0702; do
  "$A" calibrate --robot "$R" --data "$OUT/$day.csv" --identify base,markers --out "$OUT/$day-nominal.toml" > /dev/null 2>&1 || true
  "$A" calibrate --robot "$OUT/all.toml" --data "$OUT/$day.csv" --identify base,markers --out "$OUT/$day-calibrated.toml" > /dev/null 2>&1 || true
  read n_mean n_rms _ _ < <(score "$OUT/$day-nominal.toml" "$OUT/$day.csv")
  read c_mean c_rms _ _ < <(score "$OUT/$day-calibrated.toml" "$OUT/$day.csv")
  rows=$(($(wc -l < "$OUT/$day.csv") - 1))
  printf '| %s | %s | %.2f / %.2f | %.2f / %.2f |\n' $day $rows $n_mean $n_rms $c_mean $c_rms
  days_json="$days_json, \"${day}_mm\": $(printf '%.3f' $c_mean)"
done
printf '{"heldout_mm": %.3f, "heldout_deg": %.3f, "train48_rmse_mm": %.3f, "train48_rmse_deg": %.3f%s}\n' \
  $heldout_mm $heldout_deg $a_rms $a_rdeg "$days_json"
