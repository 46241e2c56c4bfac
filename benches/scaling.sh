#!/usr/bin/env bash
# Wall time and peak memory of `calibrate`, `fit` and `learn` (whole process, default
# settings) on 300 to 100,000 rows simulated from the industrial arm's hidden truth (payload
# and compliant joints the nominal model lacks), as BENCHMARKS.md's scaling table reports them.
#
#   bash benches/scaling.sh [ROWS ...]      (default: 300 3000 30000 100000)
#
# Needs the release build (`cargo build --release`) and GNU time (`/usr/bin/time`). Prints one
# Markdown row per command and size; the scratch files go to a temporary directory.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=target/release/armcomp
[ -x "$bin" ] || { echo "error: $bin missing: run cargo build --release first" >&2; exit 1; }
[ -x /usr/bin/time ] || { echo "error: GNU time (/usr/bin/time) is needed for the peak memory" >&2; exit 1; }
sizes=("$@")
[ ${#sizes[@]} -gt 0 ] || sizes=(300 3000 30000 100000)
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT

# Runs a command under GNU time; prints `| rows | what | wall s | peak MiB | exit |`.
measure() {
    local rows=$1 what=$2
    shift 2
    local code=0
    /usr/bin/time -f '%e %M' -o "$scratch/time" "$@" >"$scratch/out" 2>"$scratch/err" || code=$?
    read -r wall kib <"$scratch/time"
    printf '| %s | `%s` | %.1f | %d | %s |\n' "$rows" "$what" "$wall" $((kib / 1024)) "$code"
}

echo '| rows | command | wall time (s) | peak memory (MiB) | exit code |'
echo '|---:|---|---:|---:|---:|'
for n in "${sizes[@]}"; do
    data="$scratch/rows-$n.csv"
    # Sobol's table holds 65,536 points; Halton's sequence draws more.
    sampler=sobol
    [ "$n" -le 65536 ] || sampler=halton
    "$bin" simulate --robot robots/industrial-6dof-truth.toml --n "$n" --sampler "$sampler" --noise-mm 0.05 --seed 1 \
        --out "$data" >/dev/null
    measure "$n" calibrate "$bin" calibrate --robot robots/industrial-6dof.toml --data "$data" --out "$scratch/calibrated-$n.toml"
    measure "$n" fit "$bin" fit --robot robots/industrial-6dof.toml --data "$data" --out "$scratch/fit-$n.toml"
    measure "$n" "learn --predictor gp" "$bin" learn --model "$scratch/calibrated-$n.toml" --data "$data" \
        --predictor gp --out "$scratch/learned-$n.toml"
done
