#!/usr/bin/env bash
# Pictures at a small display's size: the 24 Kodak images scaled to 240x160 (portrait ones to
# 160x240; Pillow's Lanczos filter), in colour and in grayscale, coded by PIFS beside JPEG,
# JPEG 2000, WebP and AVIF at 0.05, 0.1, 0.25, 0.5 and 1.0 bpp, whole files (at 240x160,
# 0.05 bpp is 240 bytes: one LoRa packet; 0.25 bpp is 1200 bytes). The other codecs run as
# ../shared/bench/anchors.py runs them (the best quality whose whole file fits); PIFS takes
# the byte budget itself (`pifs encode --bytes`). Writes bench/results/small-colour.{md,csv}
# and small-gray.{md,csv}.
#
#   bash bench/small.sh
#   SIZE=128x128 bash bench/small.sh    (another size: bench/results/small-MODE-128x128.*;
#                                         square sizes crop the centre square first)
#
# Needs a python3 with numpy and Pillow (PYTHON names another one:
#   python3 -m venv /tmp/venv && /tmp/venv/bin/pip install numpy pillow
#   PYTHON=/tmp/venv/bin/python bash bench/small.sh)
# and the codecs' tools: apt-get install -y libjpeg-turbo-progs libopenjp2-tools webp
# libavif-bin (a codec whose tools are missing is left out of the tables).
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/need.sh
need_python small.sh numpy pillow
mkdir -p bench/results
cargo build --release -q -p host-encoder --bin pifs
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/images"
size=${SIZE:-240x160}
suffix=$([ "$size" = 240x160 ] || echo "-$size")
"$python" - "$work/images" "$size" ../shared/images/kodak/kodim*.png <<'PY'
import os
import sys

from PIL import Image

out = sys.argv[1]
w, h = map(int, sys.argv[2].split("x"))
for path in sys.argv[3:]:
    image = Image.open(path).convert("RGB")
    if w == h:
        side = min(image.size)
        left, top = (image.width - side) // 2, (image.height - side) // 2
        image = image.crop((left, top, left + side, top + side))
    size = (w, h) if image.width >= image.height else (h, w)
    image.resize(size, Image.LANCZOS).save(os.path.join(out, os.path.basename(path)))
PY
pifs=$PWD/target/release/pifs
for mode in colour gray; do
    flag=()
    [ "$mode" = colour ] && flag=(--colour)
    "$python" ../shared/bench/anchors.py "${flag[@]}" --work "$work/$mode" --jobs 2 \
        --label "Kodak 24 at $size ($mode)" --rates 0.05 0.1 0.25 0.5 1.0 \
        --csv "bench/results/small-$mode$suffix.csv" --md "bench/results/small-$mode$suffix.md" \
        --codec "pifs|$pifs encode {in} -o {out} --bytes {bytes}|$pifs decode {in} -o {out}|ext=.pifs" \
        "$work"/images/*.png >/dev/null 2>"$work/$mode.log" || { cat "$work/$mode.log" >&2; exit 1; }
    echo "$mode: mean PSNR$([ "$mode" = colour ] && echo -RGB) (dB), [n/24] where a codec cannot reach every image"
    sed -n '/^### Mean PSNR/,/^###/p' "bench/results/small-$mode$suffix.md" | grep '^|' | head -7
done
