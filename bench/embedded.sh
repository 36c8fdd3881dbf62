#!/usr/bin/env bash
# Embedded budgets of the PIFS decoder, measured on emulated MCUs (QEMU):
#   RAM   = static RAM (.data + .bss of the firmware) + peak stack of the deepest of a stream's
#           decodes at 1, 1/2, 1/4, 1/8, 2 and 4 times its size (stack painting; the CSV keeps
#           the full, reduced and enlarged decodes' apart), on Cortex-M3 (lm3s6965evb, 64 KiB RAM) and Cortex-M0 (microbit,
#           16 KiB RAM);
#   flash = code + read-only data the decoder adds (the harness divides nowhere, so a division
#           routine the decoder needed would count): firmware with the decoder call minus the
#           same firmware with a stand-in for the decoder call (`baseline` feature: the same
#           harness, scaled decodes included), size-optimised release build;
#   speed = instructions per output pixel on Cortex-M3 and Cortex-M0 (SysTick under
#           `-icount shift=0`, from decode entry to return), the instructions of decodes at
#           1/2, 1/4 and 1/8 of the size as a share of the full decode's, and per output pixel
#           of decodes at 2 and 4 times the size;
#   draw  = the same streams drawn as an application draws them (`draw` feature:
#           `graphics::PifsImage` onto an RGB565 display that only sums the colours, ordered
#           dither): instructions per pixel and peak stack, the display adapter included.
# Images: kodim23 as 128x128, 320x240 and 768x512, grayscale and colour (format 13, decoded to
# RGB as a display gets it), encoded at 0.1 and 0.5 bpp with the host `pifs` encoder in
# stripes of 512 pixels (what decoder-core's default decoder holds; the encoder's default is
# one stripe as wide as the image); and the 320x240 grayscale image as a 16-bit surface (its samples times 257), a 16-bit stream beside
# its 8-bit twin (the same stream with an 8-bit header: same payload, same pixels), for what
# making values costs. The 8-bit streams are also decoded by a decoder without the `deep`
# feature (16-bit streams), for what supporting them costs 8-bit streams. Generated files go to target/bench-embedded/. Prints markdown tables
# (with ChaN's TJpgDec R0.03 beside ours when ../shared/bench/tjpgdec/out/compare.md is there)
# and writes bench/results/embedded.csv: one row per target, image and rate.
#
#   bash bench/embedded.sh [KODIM23.png]      (default: ../shared/images/kodak/kodim23.png)
#
# Needs qemu-system-arm and python3 (standard library only).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
src=${1:-../shared/images/kodak/kodim23.png}
out=$root/target/bench-embedded
fw=$root/firmware-example
mkdir -p "$out"
command -v qemu-system-arm >/dev/null || {
    echo "bench/embedded.sh needs qemu-system-arm:" >&2
    echo "  apt-get update && apt-get install -y --no-install-recommends qemu-system-arm" >&2
    exit 1
}
rustup target add thumbv7m-none-eabi thumbv6m-none-eabi >/dev/null 2>&1 || true

# 1. Images and streams.
cargo build --release -q -p host-encoder 2>"$out/build.log" || { cat "$out/build.log" >&2; exit 1; }
python3 bench/crop_png.py "$src" "$out" kodim23 128x128/4 320x240/2 768x512 >/dev/null
python3 bench/crop_png.py --colour "$src" "$out" kodim23c 128x128/4 320x240/2 768x512 >/dev/null
streams=()
for kind in kodim23 kodim23c; do
    ext=pgm
    [ $kind = kodim23 ] || ext=ppm
    for size in 128x128 320x240 768x512; do
        for bpp in 0.1 0.5; do
            s=$out/${kind}_${size}_${bpp}bpp.pifs
            if [ ! -s "$s" ] || [ "$out/${kind}_$size.$ext" -nt "$s" ] || [ target/release/pifs -nt "$s" ]; then
                ./target/release/pifs encode "$out/${kind}_$size.$ext" -o "$s" --bpp "$bpp" \
                    --stripe-width 512 >/dev/null
            fi
            streams+=("$s")
        done
    done
done
python3 - "$out/kodim23_320x240.pgm" "$out/kodim23d_320x240.pgm" <<'PY'
import sys
data = open(sys.argv[1], "rb").read()
fields, pos = [], 0
while len(fields) < 4:
    while data[pos:pos + 1].isspace():
        pos += 1
    end = pos
    while not data[end:end + 1].isspace():
        end += 1
    fields.append(data[pos:end])
    pos = end
w, h = int(fields[1]), int(fields[2])
pixels = data[pos + 1:pos + 1 + w * h]
with open(sys.argv[2], "wb") as f:
    f.write(b"P5\n%d %d\n65535\n" % (w, h))
    f.write(b"".join((257 * p).to_bytes(2, "big") for p in pixels))
PY
for bpp in 0.1 0.5; do
    d=$out/kodim23d_320x240_${bpp}bpp.pifs
    ./target/release/pifs encode "$out/kodim23d_320x240.pgm" -o "$d" --bpp "$bpp" --stripe-width 512 >/dev/null
    # The twin: the header made 8-bit (depth 8, no range), the payload as it is.
    python3 - "$d" "$out/kodim23s_320x240_${bpp}bpp.pifs" <<'PY'
import sys, zlib
s = bytearray(open(sys.argv[1], "rb").read())
# docs/bitstream.md, section 1: tag, flags, CRC-32, width and height less one (LEB128), the
# coding fields if flag bit 2, the payload length (LEB128), a 16-bit stream's value range.
assert s[1] & 2, "not a 16-bit stream"
def skip_leb128(pos):
    while s[pos] & 0x80:
        pos += 1
    return pos + 1
pos = skip_leb128(skip_leb128(6))
if s[1] & 4:
    pos += 2
pos = skip_leb128(pos)
twin = s[:pos] + s[pos + 4:]
twin[1] &= ~2 & 0xFF
twin[2:6] = zlib.crc32(bytes(twin[:2] + twin[6:])).to_bytes(4, "little")
open(sys.argv[2], "wb").write(twin)
PY
    streams+=("$d" "$out/kodim23s_320x240_${bpp}bpp.pifs")
done

# 2. Firmware builds (one per target and variant, all streams embedded) and runs.
build() { # target features streams... -> prints the ELF path (a copy under $out)
    # features: cargo features of the firmware; "gray:..." builds without its defaults (`colour`,
    # `deep`, `smooth-enlarged`).
    local target=$1 features=$2
    shift 2
    # "nodeep:..." builds without `deep` alone.
    local list defaults=() wanted=${features#*:}
    list=$(IFS=:; echo "$*")
    case $features in
        gray:*) defaults=(--no-default-features) ;;
        nodeep:*) defaults=(--no-default-features) wanted=colour,smooth-enlarged,$wanted ;;
    esac
    (cd "$fw" && env -u CARGO_TARGET_DIR -u CARGO_BUILD_TARGET -u RUSTFLAGS -u CARGO_ENCODED_RUSTFLAGS \
        PIFS_BENCH_STREAMS="$list" cargo build --release -q --target "$target" "${defaults[@]}" --features "$wanted") \
        2>"$out/build.log" || { cat "$out/build.log" >&2; exit 1; }
    local elf=$out/fw-$target-${features/:/-}.elf
    cp "$root/target/firmware/$target/release/pifs-firmware-example" "$elf"
    echo "$elf"
}
run() { # target elf -> PIFS-BENCH lines on stdout; QEMU's status in $out/status
    local cpu machine
    case $1 in
        thumbv7m-none-eabi) cpu=cortex-m3 machine=lm3s6965evb ;;
        *) cpu=cortex-m0 machine=microbit ;;
    esac
    local status=0
    timeout 300 qemu-system-arm -cpu $cpu -machine $machine -display none -monitor none \
        -serial none -semihosting-config enable=on,target=native -icount shift=0 \
        -kernel "$2" 2>"$out/qemu.err" >/dev/null || status=$?
    echo $status >"$out/status"
    grep '^PIFS-BENCH' "$out/qemu.err" || true
}
field() { sed -n "s/.* $1=\([^ ]*\).*/\1/p"; }
# The compiler's division routines an ELF links, space-separated (empty: none).
divisions() {
    nm "$1" | awk '{print $NF}' | { grep -E '^__aeabi_[a-z]*div|^__[a-z]*divmod|div_rem' || true; } | sed -E 's/.*(u[0-9]+_div_rem).*/\1/' | sort -u | tr '\n' ' ' | sed 's/ $//'
}
declare -A division stack instr static flash base_flash gray_flash scaled scaled_stack nodeep_flash nodeep_stack nodeep_instr draw_instr draw_stack
gray_streams=()
for s in "${streams[@]}"; do
    case $(basename "$s") in kodim23_*) gray_streams+=("$s") ;; esac
done
for target in thumbv7m-none-eabi thumbv6m-none-eabi; do
    elf=$(build $target bench "${streams[@]}")
    read -r text data bss _ < <(size "$elf" | tail -1)
    static[$target]=$((data + bss))
    flash[$target]=$((text + data))
    belf=$(build $target baseline "${streams[@]}")
    read -r btext bdata bbss _ < <(size "$belf" | tail -1)
    base_flash[$target]=$((btext + bdata))
    # Division routines (a Cortex-M0 has no divide instruction): the harness links none, so
    # one the decoder needed would count in its flash; the decoder should link none either.
    division[$target]=$(divisions "$elf")
    if [ -n "$(divisions "$belf")" ]; then
        echo "warning: the baseline harness links a division routine: $(divisions "$belf")" >&2
    fi
    # The grayscale-only decoder (decoder-core without `colour`), on the grayscale streams.
    gelf=$(build $target gray:bench "${gray_streams[@]}")
    read -r gtext gdata _ < <(size "$gelf" | tail -1)
    gelf=$(build $target gray:baseline "${gray_streams[@]}")
    read -r gbtext gbdata _ < <(size "$gelf" | tail -1)
    gray_flash[$target]=$((gtext + gdata - gbtext - gbdata))
    # Without `deep`: flash, and the 8-bit grayscale streams' stack and instructions.
    nelf=$(build $target nodeep:bench "${gray_streams[@]}")
    read -r ntext ndata _ < <(size "$nelf" | tail -1)
    lines=$(run $target "$nelf")
    for s in "${gray_streams[@]}"; do
        n=$(basename "$s")
        l=$(echo "$lines" | grep "^PIFS-BENCH name=$n " || true)
        nodeep_stack[$target/$n]=$(echo "$l" | field stack)
        nodeep_instr[$target/$n]=$(echo "$l" | field instr)
    done
    nelf=$(build $target nodeep:baseline "${gray_streams[@]}")
    read -r nbtext nbdata _ < <(size "$nelf" | tail -1)
    nodeep_flash[$target]=$((ntext + ndata - nbtext - nbdata))
    # Drawn through embedded-graphics onto RGB565 (instructions and stack only: the build holds
    # the display adapter, which the decoder's flash above leaves out).
    delf=$(build $target draw "${streams[@]}")
    lines=$(run $target "$delf")
    for s in "${streams[@]}"; do
        n=$(basename "$s")
        l=$(echo "$lines" | grep "^PIFS-BENCH-DRAW name=$n " || true)
        draw_instr[$target/$n]=$(echo "$l" | field instr)
        draw_stack[$target/$n]=$(echo "$l" | field stack)
    done
    # A decode that overflows the board's RAM locks the core up: note it, rebuild without that
    # stream and go on with the rest.
    todo=("${streams[@]}")
    while [ ${#todo[@]} -gt 0 ]; do
        lines=$(run $target "$elf")
        done_names=$(echo "$lines" | grep '^PIFS-BENCH ' | field name)
        rest=()
        for s in "${todo[@]}"; do
            n=$(basename "$s")
            if echo "$done_names" | grep -qx "$n"; then
                l=$(echo "$lines" | grep "^PIFS-BENCH name=$n ")
                stack[$target/$n]=$(echo "$l" | field stack)
                instr[$target/$n]=$(echo "$l" | field instr)
                for k in -1 -2 -3 1 2; do
                    l=$(echo "$lines" | grep "^PIFS-BENCH-SCALED name=$n scale=$k ")
                    scaled[$target/$n/$k]=$(echo "$l" | field instr)
                    scaled_stack[$target/$n/$k]=$(echo "$l" | field stack)
                done
            else
                rest+=("$s")
            fi
        done
        [ ${#rest[@]} -gt 0 ] || break
        if [ "$(cat "$out/status")" = 0 ]; then
            echo "firmware exited without results for: ${rest[*]}" >&2
            exit 1
        fi
        first=$(basename "${rest[0]}")
        stack[$target/$first]=overflow
        echo "$target: decoding $first locked the core up (stack overflow?): $(grep -m1 -o 'Lockup.*' "$out/qemu.err" || tail -1 "$out/qemu.err")" >&2
        todo=("${rest[@]:1}")
        [ ${#todo[@]} -gt 0 ] || break
        elf=$(build $target bench "${todo[@]}")
    done
done

# 3. The tables and the CSV.
v7=thumbv7m-none-eabi
v6=thumbv6m-none-eabi
scaled_peak() { # target name scales... -> the deepest of those decodes' stacks (empty if none)
    local t=$1 n=$2 k s peak=
    shift 2
    for k in "$@"; do
        s=${scaled_stack[$t/$n/$k]:-}
        [[ $s =~ ^[0-9]+$ ]] && { [ -z "$peak" ] || [ "$s" -gt "$peak" ]; } && peak=$s
    done
    echo "$peak"
}
peak_stack() { # target name -> the deepest stack of its decodes at every scale
    local s=${stack[$1/$2]:-} k
    k=$(scaled_peak "$1" "$2" -1 -2 -3 1 2)
    [[ $s =~ ^[0-9]+$ && -n $k && $k -gt $s ]] && s=$k
    echo "$s"
}
ram() { # target name
    local s
    s=$(peak_stack "$1" "$2")
    if [[ $s =~ ^[0-9]+$ ]]; then echo "$((s + static[$1])) ($s + ${static[$1]})"; else echo "${s:-n/a}"; fi
}
per_px() { # instructions pixels
    if [[ ${1:-} =~ ^[0-9]+$ ]]; then awk -v i="$1" -v p="$2" 'BEGIN { printf "%.1f", i / p }'; else echo n/a; fi
}
share() { # part whole
    if [[ ${1:-} =~ ^[0-9]+$ && ${2:-} =~ ^[0-9]+$ ]]; then awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f", a / b }'; else echo n/a; fi
}
describe() { # stream file name [twin label] -> sets size, bpp, kind, px and label
    size=$(echo "$1" | sed 's/kodim23[a-z]*_\([0-9x]*\)_.*/\1/')
    bpp=$(echo "$1" | sed 's/.*_\([0-9.]*\)bpp.pifs/\1/')
    kind=${1%%_*}
    px=$(( ${size%x*} * ${size#*x} ))
    case $kind in
        kodim23c) label="kodim23 $size colour" ;;
        kodim23d) label="kodim23 $size 16-bit" ;;
        kodim23s) label="kodim23 $size, ${2:-8-bit twin}" ;;
        *) label="kodim23 $size" ;;
    esac
}
csv=$root/bench/results/embedded.csv
mkdir -p "$root/bench/results"
echo "target,image,bpp,stream_bytes,ram_static,ram_stack,ram_stack_reduced,ram_stack_enlarged,ram_total,decoder_flash,instructions,instr_per_pixel,half_share,quarter_share,eighth_share,double_instr_per_pixel,quadruple_instr_per_pixel,draw_rgb565_instr_per_pixel,draw_rgb565_stack" >"$csv"
echo
echo "### PIFS decoder on Cortex-M (QEMU), firmware-example \`bench\` build, opt-level \"s\", LTO"
echo
echo "| image | bpp | stream bytes | M3 RAM: static + peak stack (bytes) | M0 RAM: static + peak stack (bytes) | M3 instr/pixel | M0 instr/pixel | M3 1/4 decode / full | M0 1/4 decode / full |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|"
for s in "${streams[@]}"; do
    n=$(basename "$s")
    describe "$n" "the 16-bit stream's 8-bit twin"
    bytes=$(stat -c %s "$s")
    echo "| $label | $bpp | $bytes | $(ram $v7 "$n") | $(ram $v6 "$n") | $(per_px "${instr[$v7/$n]:-}" $px) | $(per_px "${instr[$v6/$n]:-}" $px) | $(share "${scaled[$v7/$n/-2]:-}" "${instr[$v7/$n]:-}") | $(share "${scaled[$v6/$n/-2]:-}" "${instr[$v6/$n]:-}") |"
    for t in $v7 $v6; do
        st=$(peak_stack $t "$n")
        total=n/a
        [[ $st =~ ^[0-9]+$ ]] && total=$((st + static[$t]))
        echo "$t,${kind}_$size,$bpp,$bytes,${static[$t]},${stack[$t/$n]:-},$(scaled_peak $t "$n" -1 -2 -3),$(scaled_peak $t "$n" 1 2),$total,$((flash[$t] - base_flash[$t])),${instr[$t/$n]:-},$(per_px "${instr[$t/$n]:-}" $px),$(share "${scaled[$t/$n/-1]:-}" "${instr[$t/$n]:-}"),$(share "${scaled[$t/$n/-2]:-}" "${instr[$t/$n]:-}"),$(share "${scaled[$t/$n/-3]:-}" "${instr[$t/$n]:-}"),$(per_px "${scaled[$t/$n/1]:-}" $((4 * px))),$(per_px "${scaled[$t/$n/2]:-}" $((16 * px))),$(per_px "${draw_instr[$t/$n]:-}" $px),${draw_stack[$t/$n]:-}" >>"$csv"
    done
done
echo
echo "| target | firmware text+data, with decoder | without (baseline) | decoder flash (code + rodata) | without the \`deep\` feature | grayscale-only decoder (no \`colour\`, \`deep\` or \`smooth-enlarged\`) | division routines linked |"
echo "|---|---:|---:|---:|---:|---:|---|"
for t in $v7 $v6; do
    echo "| $t | ${flash[$t]} | ${base_flash[$t]} | $((flash[$t] - base_flash[$t])) | ${nodeep_flash[$t]} | ${gray_flash[$t]} | ${division[$t]:-none} |"
done
echo
echo "8-bit streams decoded without the \`deep\` feature (16-bit streams refused on their header):"
echo
echo "| image | bpp | M3 RAM | M0 RAM | M3 instr/pixel | M0 instr/pixel |"
echo "|---|---:|---:|---:|---:|---:|"
for s in "${gray_streams[@]}"; do
    n=$(basename "$s")
    describe "$n"
    row="| $label | $bpp |"
    for t in $v7 $v6; do
        st=${nodeep_stack[$t/$n]:-}
        if [[ $st =~ ^[0-9]+$ ]]; then row="$row $((st + static[$t])) |"; else row="$row n/a |"; fi
    done
    for t in $v7 $v6; do
        row="$row $(per_px "${nodeep_instr[$t/$n]:-}" $px) |"
    done
    echo "$row"
done
echo
echo "Scaled decodes (share of the full decode's instructions; every leaf's edge pixels are still"
echo "made at the coded size, for prediction):"
echo
echo "| image | bpp | M3 1/2 | M3 1/4 | M3 1/8 | M0 1/2 | M0 1/4 | M0 1/8 |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
for s in "${streams[@]}"; do
    n=$(basename "$s")
    describe "$n"
    row="| $label | $bpp |"
    for t in $v7 $v6; do
        for k in -1 -2 -3; do
            row="$row $(share "${scaled[$t/$n/$k]:-}" "${instr[$t/$n]:-}") |"
        done
    done
    echo "$row"
done
echo
echo "Enlarged decodes (instructions per output pixel), and the peak stack of each kind of decode"
echo "(bytes; the RAM columns above add the static RAM to the deepest):"
echo
echo "| image | bpp | M3 2x | M3 4x | M0 2x | M0 4x | M3 stack: full / 1/2..1/8 / 2x, 4x | M0 stack: full / 1/2..1/8 / 2x, 4x |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
for s in "${streams[@]}"; do
    n=$(basename "$s")
    describe "$n"
    row="| $label | $bpp |"
    for t in $v7 $v6; do
        row="$row $(per_px "${scaled[$t/$n/1]:-}" $((4 * px))) | $(per_px "${scaled[$t/$n/2]:-}" $((16 * px))) |"
    done
    for t in $v7 $v6; do
        row="$row ${stack[$t/$n]:-n/a} / $(scaled_peak $t "$n" -1 -2 -3) / $(scaled_peak $t "$n" 1 2) |"
    done
    echo "$row"
done
echo
echo "Drawn as an application draws them: \`graphics::PifsImage\` onto an RGB565 display (ordered"
echo "dither; the display sums the colours it is given, a driver at no cost of its own), against"
echo "the decode into a sink that sums the pixels (instructions per pixel; peak stack in bytes):"
echo
echo "| image | bpp | M3 draw | M3 decode | M0 draw | M0 decode | M3 draw stack | M0 draw stack |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
for s in "${streams[@]}"; do
    n=$(basename "$s")
    describe "$n"
    row="| $label | $bpp |"
    for t in $v7 $v6; do
        row="$row $(per_px "${draw_instr[$t/$n]:-}" $px) | $(per_px "${instr[$t/$n]:-}" $px) |"
    done
    echo "$row ${draw_stack[$v7/$n]:-n/a} | ${draw_stack[$v6/$n]:-n/a} |"
done
tj=$root/../shared/bench/tjpgdec/out/compare.md
if [ -f "$tj" ]; then
    echo
    echo "Beside ChaN's TJpgDec R0.03 (instructions per output pixel, fastest configuration of"
    echo "each, from $tj; same images, JPEG at the nearest rate; M3 then M0):"
    echo
    python3 - "$tj" "$csv" <<'PY'
import csv, re, sys
tj, ours = sys.argv[1], sys.argv[2]
rows = {}
core = None
for line in open(tj):
    if line.startswith("### M3"):
        core = "thumbv7m-none-eabi"
    elif line.startswith("### M0"):
        core = "thumbv6m-none-eabi"
    elif core and line.startswith("| ") and "x" in line.split("|")[1]:
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        m = re.match(r"(\d+x\d+) ~([0-9.]+)", cells[0])
        if not m:
            continue
        fastest = min(float(c) for c in cells[3:7])
        rows[(core, m.group(1), float(m.group(2)))] = (cells[3], fastest, cells[2])
print("| image | bpp | TJpgDec M3 (f0t0 / fastest) | PIFS M3 | TJpgDec M0 (f0t0 / fastest) | PIFS M0 |")
print("|---|---:|---:|---:|---:|---:|")
data = {}
for r in csv.DictReader(open(ours)):
    if r["image"].split("_")[0] != "kodim23":
        continue  # TJpgDec's figures are for the 8-bit grayscale images
    data[(r["target"], r["image"].split("_")[1], float(r["bpp"]))] = r["instr_per_pixel"]
for size in ["128x128", "320x240", "768x512"]:
    for bpp in [0.1, 0.5]:
        cells = []
        for t in ["thumbv7m-none-eabi", "thumbv6m-none-eabi"]:
            tjr = rows.get((t, size, bpp))
            cells.append(f"{tjr[0]} / {tjr[1]:.1f}" if tjr else "n/a")
            cells.append(data.get((t, size, bpp), "n/a"))
        print(f"| kodim23 {size} | {bpp} | " + " | ".join(cells) + " |")
PY
fi
echo
echo "Targets (issue 24): <= 80 instr/pixel on Cortex-M3, <= 110 on Cortex-M0, RAM <= 3072 bytes,"
echo "decoder flash <= 16384 bytes on thumbv6m, a 1/4 decode <= 1/8 of the full decode's"
echo "instructions. Static RAM is the whole firmware's (SysTick counter, loggers); the decoder itself"
echo "has no static data. CSV: bench/results/embedded.csv."
