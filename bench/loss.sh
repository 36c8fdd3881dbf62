#!/usr/bin/env bash
# Packets under loss on the Kodak set (see bench/loss.py): 255-byte packets at 0.1, 0.25 and
# 0.5 bpp, i.i.d. and bursty losses, the first packets, the cost against the single stream, and
# SSDV beside. Grayscale by default; --colour for RGB.
#
#   bash bench/loss.sh [--colour] [IMAGES...]
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -q -p host-encoder
python3 bench/loss.py "$@"
