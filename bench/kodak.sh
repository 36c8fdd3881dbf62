#!/usr/bin/env bash
# Rate/distortion and speed of the PIFS encoder on the Kodak set (grayscale), at 0.05, 0.1,
# 0.25 and 0.5 bpp. Writes bench/results/kodak-pifs.csv and prints per-rate means, then the
# Bjøntegaard deltas against JPEG 2000 (bench/bd.py).
#
#   bash bench/kodak.sh [IMAGES...]      (default: ../shared/images/kodak/*.png)
set -euo pipefail
cd "$(dirname "$0")/.."
images=("$@")
[ ${#images[@]} -gt 0 ] || images=(../shared/images/kodak/kodim*.png)
mkdir -p bench/results
cargo build --release -q -p host-encoder --example rd_sweep
csv=bench/results/kodak-pifs.csv
./target/release/examples/rd_sweep "${images[@]}" | tee "$csv"
python3 bench/summarise.py "$csv"
# Bjøntegaard deltas against JPEG 2000 (the anchors' per-image points), when they are present.
if [ -f ../shared/bench/kodak-anchors.md ]; then
    echo
    python3 bench/bd.py "$csv" ../shared/bench/kodak-anchors.md jpeg2000
fi
