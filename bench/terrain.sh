#!/usr/bin/env bash
# Terrain heightmaps (issue 26): PIFS beside OpenJPEG (16-bit lossy) at the same bytes on the
# two real DEMs matplotlib ships and on fBm terrain; RMSE and largest error in the data's units
# and PSNR relative to the data's range; hillshaded views. See bench/terrain.py.
#
#   bash bench/terrain.sh [RATES]      (bits per sample, default 0.1,0.25,0.5,1,2)
#
# Needs opj_compress/opj_decompress and a python3 with numpy, pillow and matplotlib (its sample
# data only): PYTHON=... names it (default python3), e.g.
#   python3 -m venv /tmp/venv && /tmp/venv/bin/pip install numpy pillow matplotlib
#   PYTHON=/tmp/venv/bin/python bash bench/terrain.sh
# Writes bench/results/terrain.csv and target/bench-terrain/ (the hillshaded views).
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/need.sh
need_python terrain.sh numpy pillow matplotlib
need_openjpeg terrain.sh
cargo build --release -q -p host-encoder
"$python" bench/terrain.py --rates "${1:-0.1,0.25,0.5,1,2}"
