#!/usr/bin/env bash
# Rate/distortion of the PIFS encoder on the Kodak set in colour (format 13, YCbCr 4:2:0), at
# 0.05, 0.1, 0.25, 0.5 and 1.0 bpp (whole file). Writes bench/results/kodak-colour-pifs.csv and
# prints per-rate means of PSNR-RGB, PSNR-YCbCr (6:1:1) and the chroma share of the payload
# beside the anchors of ../shared/bench/kodak-colour-anchors.md (JPEG, JPEG 2000, WebP, AVIF).
#
#   bash bench/kodak-colour.sh [IMAGES...]      (default: ../shared/images/kodak/*.png)
#   PIFS_RATES=0.1,0.5 bash bench/kodak-colour.sh ...   (other rates)
set -euo pipefail
cd "$(dirname "$0")/.."
images=("$@")
[ ${#images[@]} -gt 0 ] || images=(../shared/images/kodak/kodim*.png)
rates=${PIFS_RATES:-0.05,0.1,0.25,0.5,1.0}
mkdir -p bench/results
cargo build --release -q -p host-encoder --example rd_sweep_colour
csv=bench/results/kodak-colour-pifs.csv
./target/release/examples/rd_sweep_colour --bpp "$rates" "${images[@]}" | tee "$csv"
python3 bench/summarise_colour.py "$csv" ../shared/bench/kodak-colour-anchors.md
