#!/usr/bin/env bash
# Host decoding time on the Kodak set (768x512 grayscale), two ways:
#   1. in process: `decode_speed` (host-encoder example), median of REPEATS decodes per stream,
#      then the median over the streams of each rate; with OLD_SPEED=path/to/another/decode_speed,
#      the two are run in turn on each stream, ROUNDS times, and the medians over the rounds and
#      their ratio are printed instead;
#   2. whole process: `pifs decode STREAM -o out.pgm` wall time, the median of ROUNDS runs per
#      stream; with OLD=path/to/another/pifs, runs of the two binaries are interleaved and the
#      ratio of their medians is printed too (this machine's load drifts, so only interleaved
#      runs compare binaries).
# Streams: STREAMS_DIR/kodimNN-RATEbpp.pifs (default target/kodak-streams-gray, made with
# `pifs rd --gray IMAGE --out-dir target/kodak-streams-gray` for every Kodak image when missing).
#
#   [OLD=target/baseline/pifs-before] [OLD_SPEED=target/baseline/decode_speed-before]
#   [REPEATS=15] [ROUNDS=5] bash bench/host_decode.sh
set -euo pipefail
cd "$(dirname "$0")/.."
dir=${STREAMS_DIR:-target/kodak-streams-gray}
repeats=${REPEATS:-15}
rounds=${ROUNDS:-5}
cargo build --release -q -p host-encoder --bin pifs --example decode_speed
mkdir -p "$dir"
for img in ../shared/images/kodak/kodim*.png; do
    stem=$(basename "$img" .png)
    [ -s "$dir/$stem-0.5bpp.pifs" ] || ./target/release/pifs rd --gray "$img" --out-dir "$dir" >/dev/null
done
speed=target/release/examples/decode_speed
if [ -n "${OLD_SPEED:-}" ]; then
    echo "| rate (bpp) | in process, median over the images of the rounds' median (ms) | previous binary (ms) | ratio |"
    echo "|---:|---:|---:|---:|"
    for rate in 0.05 0.1 0.25 0.5; do
        for _ in $(seq "$rounds"); do
            for s in "$dir"/kodim*-${rate}bpp.pifs; do
                new=$(REPEATS=$repeats "$speed" "$s" | awk 'NR == 1 {print $NF}')
                old=$(REPEATS=$repeats "$OLD_SPEED" "$s" | awk 'NR == 1 {print $NF}')
                echo "$s $new $old"
            done
        done | python3 -c '
import collections, statistics, sys
runs = collections.defaultdict(lambda: ([], []))
for line in sys.stdin:
    name, new, old = line.split()
    runs[name][0].append(float(new))
    runs[name][1].append(float(old))
new = statistics.median(statistics.median(n) for n, _ in runs.values())
old = statistics.median(statistics.median(o) for _, o in runs.values())
print(f"| {sys.argv[1]} | {new:.2f} | {old:.2f} | {new / old:.3f} |")' "$rate"
    done
    echo
fi
echo "| rate (bpp) | in process, median of the per-image medians (ms) | min | max |"
echo "|---:|---:|---:|---:|"
for rate in 0.05 0.1 0.25 0.5; do
    line=$(REPEATS=$repeats "$speed" "$dir"/kodim*-${rate}bpp.pifs | tail -1)
    med=$(echo "$line" | sed 's/.*streams: \([0-9.]*\) ms.*/\1/')
    min=$(echo "$line" | sed 's/.*min \([0-9.]*\),.*/\1/')
    max=$(echo "$line" | sed 's/.*max \([0-9.]*\)).*/\1/')
    echo "| $rate | $med | $min | $max |"
done
echo
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
time_one() { # binary stream -> milliseconds
    local t0 t1
    t0=$(date +%s%N)
    "$1" decode "$2" -o "$out/x.pgm" >/dev/null
    t1=$(date +%s%N)
    echo $(((t1 - t0) / 1000))
}
declare -A new_t old_t
for s in "$dir"/kodim*.pifs; do
    for _ in $(seq "$rounds"); do
        new_t[$s]="${new_t[$s]:-} $(time_one target/release/pifs "$s")"
        if [ -n "${OLD:-}" ]; then old_t[$s]="${old_t[$s]:-} $(time_one "$OLD" "$s")"; fi
    done
done
python3 - "$dir" "${OLD:-}" <<PY "$(for s in "${!new_t[@]}"; do echo "$s|${new_t[$s]}|${old_t[$s]:-}"; done)"
import statistics, sys
rows = [l.split("|") for l in sys.argv[3].splitlines() if l]
by_rate = {}
for name, new, old in rows:
    rate = name.rsplit("-", 1)[1].replace("bpp.pifs", "")
    new_med = statistics.median(int(v) for v in new.split()) / 1000
    old_med = statistics.median(int(v) for v in old.split()) / 1000 if old.strip() else None
    by_rate.setdefault(rate, []).append((new_med, old_med))
print("| rate (bpp) | whole process \`pifs decode\`, median (ms) |" + (" previous binary (ms) | ratio |" if sys.argv[2] else ""))
print("|---:|---:|" + ("---:|---:|" if sys.argv[2] else ""))
for rate in sorted(by_rate, key=float):
    v = by_rate[rate]
    new = statistics.median(n for n, _ in v)
    row = f"| {rate} | {new:.1f} |"
    if sys.argv[2]:
        old = statistics.median(o for _, o in v)
        row += f" {old:.1f} | {new / old:.2f} |"
    print(row)
PY
