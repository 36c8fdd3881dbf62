#!/usr/bin/env bash
# Per-function instruction profile of one decode on an emulated Cortex-M (QEMU TCG plugin).
#
#   bash bench/qemu-profile/run.sh thumbv7m-none-eabi|thumbv6m-none-eabi STREAM.pifs [TOP [CALLEE...]]
#
# Builds the firmware-example `bench` firmware with STREAM alone, runs it under QEMU with
# profile.c counting from decode_once's first instruction to the instruction after its call, and
# prints the functions by instructions (per output pixel too). Files go to target/qemu-profile/.
set -euo pipefail
cd "$(dirname "$0")/../.."
root=$PWD
target=$1
stream=$(realpath "$2")
top=${3:-25}
out=$root/target/qemu-profile
mkdir -p "$out"
gcc -shared -fPIC -O2 -o "$out/libprofile.so" bench/qemu-profile/profile.c
(cd firmware-example && env -u CARGO_TARGET_DIR -u CARGO_BUILD_TARGET -u RUSTFLAGS -u CARGO_ENCODED_RUSTFLAGS \
    PIFS_BENCH_STREAMS="$stream" cargo build --release -q --target "$target" --features bench)
elf=$out/fw-$target.elf
cp "target/firmware/$target/release/pifs-firmware-example" "$elf"
case $target in
    thumbv7m-none-eabi) cpu=cortex-m3 machine=lm3s6965evb ;;
    *) cpu=cortex-m0 machine=microbit ;;
esac
entry=$(nm "$elf" | awk '/decode_once/ {print $1}' | head -1)
entry=$(printf '%x' $((0x$entry & ~1)))
ret=$(llvm-objdump -d --no-show-raw-insn "$elf" | grep -A1 -E "bl\s+0x$entry\b|bl\s+$entry\b" | tail -1 | awk '{print $1}' | tr -d :)
timeout 600 qemu-system-arm -cpu $cpu -machine $machine -display none -monitor none -serial none \
    -semihosting-config enable=on,target=native -icount shift=0 -kernel "$elf" \
    -plugin "$out/libprofile.so,start=0x$entry,end=0x$ret,out=$out/profile-$target.txt" \
    2>"$out/qemu.err" >/dev/null || true
line=$(grep '^PIFS-BENCH ' "$out/qemu.err")
echo "$line"
w=$(echo "$line" | sed 's/.* w=\([0-9]*\).*/\1/')
h=$(echo "$line" | sed 's/.* h=\([0-9]*\).*/\1/')
python3 bench/qemu-profile/symbolize.py "$elf" "$out/profile-$target.txt" $((w * h)) "$top" "${@:4}"
