#!/usr/bin/env bash
# Packets under loss on the Kodak set (see bench/loss.py): 255-byte packets at 0.1, 0.25 and
# 0.5 bpp, i.i.d. and bursty losses, the first packets, the cost against the single stream, and
# SSDV beside. Grayscale by default; --colour for RGB.
#
#   bash bench/loss.sh [--colour] [IMAGES...]
#
# Needs a python3 with numpy and Pillow (PYTHON names another one):
#   python3 -m venv /tmp/venv && /tmp/venv/bin/pip install numpy pillow
#   PYTHON=/tmp/venv/bin/python bash bench/loss.sh
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/need.sh
need_python loss.sh numpy pillow
cargo build --release -q -p host-encoder
"$python" bench/loss.py "$@"
