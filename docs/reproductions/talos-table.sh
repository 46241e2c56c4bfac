#!/usr/bin/env bash
# TALOS with a gripper pressed flush on a table, only its joint encoders recorded (FIGAROH's
# talos_table_contact example, Apache-2.0: github.com/thanhndv212/figaroh-examples, data copied
# to ../shared/data/talos-table-contact/ beside the repository, see talos-table.md). FIGAROH's
# protocol: one chain sole → gripper per side, fitted on the `*_train` postures and scored with
# the same parameters (the table's included) on the `*_validation` postures by the RMS of the
# gap to the table: its height (mm) and the contact frame's roll and pitch (deg). Prints the
# table beside the published numbers and, as its last line, one JSON object of the held-out
# figures. ARMCOMP=path uses an armcomp binary already built instead of a release build.
set -euo pipefail
cd "$(dirname "$0")/../.."
D=../shared/data/talos-table-contact
if [ ! -f "$D/left_train.csv" ]; then
  echo "skipped: $D not found (FIGAROH's talos_table_contact data, see docs/reproductions/talos-table.md)" >&2
  exit 0
fi
if [ -z "${ARMCOMP:-}" ]; then
  cargo build --release -q -p armcomp
fi
A=${ARMCOMP:-target/release/armcomp}
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
# Every data row is 5 metadata fields then 32 joint values in rad. Only left_train.csv has a
# right header; the *_fixed.csv copies have line 1 replaced, their fields 6–37 naming the joints.
# One table per file, named `table` in a `plane` column.
convert() {
  awk -F, 'NR == 1 { h = ""; for (i = 6; i <= 37; i++) h = h $i "[rad],"; print h "plane"; next }
           { r = ""; for (i = 6; i <= 37; i++) r = r $i ","; print r "table" }' "$1"
}
convert "$D/left_train.csv" > "$OUT/left_train.csv"
convert "$D/left_validation_fixed.csv" > "$OUT/left_validation.csv"
convert "$D/right_train_fixed.csv" > "$OUT/right_train.csv"
convert "$D/right_validation_fixed.csv" > "$OUT/right_validation.csv"
# Out-of-plane RMS (mm), roll and pitch RMS (deg) of a model on a file, from `evaluate`'s text.
score() {
  "$A" evaluate --model "$1" --data "$2" 2>/dev/null |
    awk '/^    table/ { for (i = 1; i <= NF; i++) { if ($i == "out-of-plane") z = $(i + 2); if ($i == "roll") r = $(i + 2); if ($i == "pitch") p = $(i + 2) } } END { print z, r, p }'
}
echo "| chain | set | z mm before → after | published z mm | roll deg before → after | published roll deg | pitch deg before → after | published pitch deg | calibration s |"
echo "|---|---|---|---|---|---|---|---|---|"
for side in left right; do
  R=robots/talos-table-$side.toml
  start=$(date +%s.%N)
  # The joints' placements and offsets, the contact frame's two tilts and the table; the contact's
  # height stays the file's (with flush contact it and the table's height are one direction).
  "$A" calibrate --robot "$R" --data "$OUT/${side}_train.csv" --identify geometry,marker.contact.rx,marker.contact.ry \
    --noise-mm 1 --noise-deg 0.3 --out "$OUT/$side.toml" > "$OUT/$side.log" 2>&1
  seconds=$(awk "BEGIN { printf \"%.2f\", $(date +%s.%N) - $start }")
  for set in train validation; do
    case $side-$set in
      left-train) pub="0.78 0.17 0.16" ;; left-validation) pub="9.26 0.75 0.52" ;;
      right-train) pub="1.33 0.32 0.38" ;; right-validation) pub="8.03 0.98 0.59" ;;
    esac
    read bz br bp < <(score "$R" "$OUT/${side}_$set.csv")
    read az ar ap < <(score "$OUT/$side.toml" "$OUT/${side}_$set.csv")
    read pz pr pp <<< "$pub"
    printf '| %s | %s | %.2f → %.2f | %s | %.3f → %.3f | %s | %.3f → %.3f | %s | %s |\n' \
      $side $set $bz $az $pz $br $ar $pr $bp $ap $pp $seconds
    if [ $set = validation ]; then
      eval "${side}_z=$az; ${side}_r=$ar; ${side}_p=$ap"
    fi
  done
done
printf '{"left_mm": %s, "right_mm": %s, "left_roll_deg": %s, "left_pitch_deg": %s, "right_roll_deg": %s, "right_pitch_deg": %s}\n' \
  $left_z $right_z $left_r $left_p $right_r $right_p
