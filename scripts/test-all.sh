#!/usr/bin/env bash
# Runs every test of the project, the QEMU (Cortex-M3 and Cortex-M0) firmware tests included,
# installing first what a fresh machine lacks: the Cortex-M Rust targets, qemu-system-arm and
# python3.
# Every test binary runs even when one fails; the last line gives the totals, and the exit
# status is non-zero when any test failed.
set -euo pipefail
cd "$(dirname "$0")/.."

# rust-toolchain.toml pins the toolchain, but its targets are not installed automatically here.
rustup target add thumbv7m-none-eabi thumbv6m-none-eabi
# qemu-system-arm runs the firmware; python3 the depacketiser written from the specification
# (host-encoder/tests/depacketise.rs).
missing=()
command -v qemu-system-arm >/dev/null 2>&1 || missing+=(qemu-system-arm)
command -v python3 >/dev/null 2>&1 || missing+=(python3)
if [ ${#missing[@]} -gt 0 ]; then
    sudo_if_needed() { if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi; }
    sudo_if_needed apt-get update
    sudo_if_needed apt-get install -y --no-install-recommends "${missing[@]}"
fi

# decoder-core must stay no_std: build it for a Cortex-M0 target.
cargo build -p decoder-core --release --target thumbv6m-none-eabi

# Host tests, integration tests and the firmware under QEMU (tests/tests/qemu.rs), then one
# closing line with the totals over every test binary, whatever happened before it.
log=$(mktemp)
trap 'rm -f "$log"' EXIT
status=0
cargo test --workspace --no-fail-fast 2>&1 | tee "$log" || status=$?
# decoder-core without its default `colour` feature (a grayscale-only decoder).
cargo test -p decoder-core --no-default-features --lib 2>&1 | tee -a "$log" || status=$?
awk '/^test result:/ { p += $4; f += $6 } END { printf "%d passed, %d failed\n", p, f }' "$log"
exit "$status"
