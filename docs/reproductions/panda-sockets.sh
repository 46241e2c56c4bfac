#!/usr/bin/env bash
# Franka Emika Panda, a ball on the flange put into two sockets 50 mm apart (MUKCa's data, MIT:
# github.com/platonics-delft/kinematics_calibration, copied to ../shared/data/panda-sockets/
# beside the repository, see panda-sockets.md). Upstream's protocol: train on one table place
# (`front`), score on every other place of the same robot by the consistency (per socket, the
# mean distance of the modelled ball from its mean, weighted by samples, averaged over places)
# and the distance error | ‖mean0 − mean1‖ − 50 mm |. Prints the table and, as its last line,
# one JSON object of the held-out figures.
set -euo pipefail
cd "$(dirname "$0")/../.."
D=../shared/data/panda-sockets
if [ ! -f "$D/data/panda_1/front/hole_0.csv" ]; then
  echo "skipped: $D not found (the MUKCa data of platonics-delft/kinematics_calibration, see docs/reproductions/panda-sockets.md)" >&2
  exit 0
fi
cargo build --release -q -p armcomp
A=target/release/armcomp
R=robots/panda-sockets.toml
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
# Upstream's joint files have no header (np.savetxt: panda_joint1..7 in rad); one file per place
# with the header armcomp reads and the socket of each row in a `fixed_point` column.
convert() { # robot place
  echo "panda_joint1[rad],panda_joint2[rad],panda_joint3[rad],panda_joint4[rad],panda_joint5[rad],panda_joint6[rad],panda_joint7[rad],fixed_point"
  for hole in hole_0 hole_1; do sed -e '/^[[:space:]]*$/d' -e "s/\r\$//; s/\$/,$hole/" "$D/data/$1/$2/$hole.csv"; done
}
# Spread and distance error (mm) of a model on a place, from `evaluate`'s text.
score() {
  "$A" evaluate --model "$1" --data "$2" 2>/dev/null |
    awk '/fixed points: spread/ { s = $4 } /^  distance / { e = $NF == "mm" ? $(NF-1) : $NF } END { print s, e }'
}
echo "| robot | train place | held-out place | nominal spread mm | calibrated spread mm | nominal distance error mm | calibrated distance error mm | calibration s |"
echo "|---|---|---|---|---|---|---|---|"
json=""
for robot in panda_1 panda_6; do
  case $robot in panda_1) tests="right back-high" ;; panda_6) tests="right left" ;; esac
  convert $robot front > "$OUT/$robot-front.csv"
  start=$(date +%s.%N)
  "$A" calibrate --robot "$R" --data "$OUT/$robot-front.csv" --noise-mm 0.1 --out "$OUT/$robot.toml" > "$OUT/$robot.log" 2>&1
  seconds=$(awk "BEGIN { printf \"%.2f\", $(date +%s.%N) - $start }")
  sum_s=0; sum_e=0; n=0
  for test in $tests; do
    convert $robot "$test" > "$OUT/$robot-$test.csv"
    read n_s n_e < <(score "$R" "$OUT/$robot-$test.csv")
    read c_s c_e < <(score "$OUT/$robot.toml" "$OUT/$robot-$test.csv")
    printf '| %s | front | %s | %.3f | %.3f | %.3f | %.3f | %s |\n' $robot "$test" $n_s $c_s $n_e $c_e $seconds
    sum_s=$(awk "BEGIN { print $sum_s + $c_s }"); sum_e=$(awk "BEGIN { print $sum_e + $c_e }"); n=$((n + 1))
  done
  mean_s=$(awk "BEGIN { printf \"%.4f\", $sum_s / $n }"); mean_e=$(awk "BEGIN { printf \"%.4f\", $sum_e / $n }")
  echo "$robot held out: consistency $mean_s mm, distance error $mean_e mm (mean over places)"
  json="$json${json:+, }\"${robot}_heldout_consistency_mm\": $mean_s, \"${robot}_distance_error_mm\": $mean_e"
  if [ $robot = panda_1 ]; then p1_s=$mean_s; p1_e=$mean_e; fi
done
printf '{"heldout_consistency_mm": %s, "distance_error_mm": %s, %s}\n' $p1_s $p1_e "$json"
