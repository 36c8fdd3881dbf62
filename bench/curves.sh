#!/usr/bin/env bash
# Projected-IFS curves on real and synthetic data (issue 26): the error against the number
# of parameters, fitted weights against the smooth rules, and quantised parameters
# (host-encoder/examples/curve_study.rs), on a terrain profile, a contour line and a
# coastline taken from the two real DEMs matplotlib ships (bench/curves/extract.py); also the
# affine IFS of Guérin & Tosan §6.1 (host-encoder/examples/affine_ifs.rs).
#
#   bash bench/curves.sh
#
# Needs a python3 with numpy and matplotlib, for the extraction only: PYTHON=... names it
# (default: python3), e.g.  python3 -m venv /tmp/venv && /tmp/venv/bin/pip install matplotlib
# and PYTHON=/tmp/venv/bin/python bash bench/curves.sh. Writes target/bench-curves/.
set -euo pipefail
cd "$(dirname "$0")/.."
out=target/bench-curves
mkdir -p "$out"
. bench/need.sh
need_python curves.sh numpy matplotlib
"$python" bench/curves/extract.py "$out" >&2
cargo run --release -q -p host-encoder --example curve_study -- \
    "$out/jacksboro-profile.csv" "$out/jacksboro-contour.csv" "$out/topobathy-coast.csv"
cargo run --release -q -p host-encoder --example affine_ifs
