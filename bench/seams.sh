#!/usr/bin/env bash
# Does the block grid show? PSNR, SSIM and the grid measure B_4, B_8, B_16 of PIFS decodes on
# the 24 grayscale Kodak images at 0.05, 0.1, 0.25 and 0.5 bpp (and B_16s, B_16 over the
# smooth parts alone, and A_16s, its mean step across the lines there in grey levels), beside
# JPEG 2000 (OpenJPEG) at the same bytes and the originals' own measures. Writes
# bench/results/seams.csv and seams.md.
#
#   bash bench/seams.sh [IMAGES...]      (default: ../shared/images/kodak/*.png)
#
# Needs a python3 with numpy and Pillow (PYTHON names another one:
#   python3 -m venv /tmp/venv && /tmp/venv/bin/pip install numpy pillow
#   PYTHON=/tmp/venv/bin/python bash bench/seams.sh)
# and opj_compress / opj_decompress (libopenjp2-tools).
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/need.sh
need_python seams.sh numpy pillow
need_openjpeg seams.sh
images=("$@")
[ ${#images[@]} -gt 0 ] || images=(../shared/images/kodak/kodim*.png)
mkdir -p bench/results
cargo build --release -q -p host-encoder
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$python" bench/seams.py --work "$work" --pifs target/release/pifs --jobs 2 \
    --csv bench/results/seams.csv --md bench/results/seams.md "${images[@]}"
