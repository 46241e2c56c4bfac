#!/usr/bin/env bash
# Regenerates docs/images/fit-report.png, the README's picture of a report page: `armcomp fit`
# on TALOS' even rows with --report, opened in headless Chromium (Debian's `chromium`).
set -euo pipefail
cd "$(dirname "$0")/../.."
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cargo run --release --quiet -- fit --robot robots/talos-left-arm.toml --data data/talos-left-arm/measurements.csv \
  --rows even --out "$work/geo.toml" --report "$work/report" >/dev/null
chromium --headless --no-sandbox --disable-gpu --hide-scrollbars --window-size=1280,800 \
  --screenshot="$work/shot.png" "file://$work/report/index.html" 2>/dev/null
mv "$work/shot.png" docs/images/fit-report.png
echo "wrote docs/images/fit-report.png"
