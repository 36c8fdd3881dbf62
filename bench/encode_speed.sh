#!/usr/bin/env bash
# Encoder speed on the Kodak set, whole process, on this machine:
#   1. `pifs encode --gray --bpp 0.25` and `pifs encode --bpp 0.25` (colour) per image, wall and
#      CPU time (user + system; median of REPEATS interleaved runs per image), then the median
#      over the images: the "one target, analysis included" figures;
#   2. extra targets from one analysis: the per-target encode time of `rd_sweep` (0.05, 0.1,
#      0.25 and 0.5 bpp), median over images and rates, apart for each smallest leaf size;
#      The peak resident memory of the same runs: median over the images, and the largest;
#   3. scaling: the wall time of (1) on THREADS_IMAGES images with 1 and with 2 threads
#      (RAYON_NUM_THREADS), and the speed-up.
# Prints a markdown summary. Needs python3 (standard library) and GNU time (/usr/bin/time).
#
#   bash bench/encode_speed.sh [IMAGES...]   (default: ../shared/images/kodak/*.png)
set -euo pipefail
cd "$(dirname "$0")/.."
images=("$@")
[ ${#images[@]} -gt 0 ] || images=(../shared/images/kodak/kodim*.png)
REPEATS=${REPEATS:-3}
THREADS_IMAGES=${THREADS_IMAGES:-3}
cargo build --release -q -p host-encoder --bin pifs --example rd_sweep
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
wall() { # command... -> wall seconds on stdout
    /usr/bin/time -f "%e" -o "$out/t" "$@" >/dev/null 2>&1
    cat "$out/t"
}
times() { # command... -> "wall cpu peak" (seconds, seconds, MB of 10^6 bytes) on stdout
    /usr/bin/time -f "%e %U %S %M" -o "$out/t" "$@" >/dev/null 2>&1
    python3 -c 'import sys; w,u,s,m=map(float,sys.argv[1:]); print(f"{w:.2f} {u+s:.2f} {m*1.024/1000:.1f}")' $(cat "$out/t")
}
largest() { python3 -c 'import sys; print(f"{max(float(x) for x in sys.argv[1:]):.1f}")' "$@"; }
median() { python3 -c 'import sys,statistics; print(f"{statistics.median(float(x) for x in sys.argv[1:]):.3f}")' "$@"; }

gray_wall=(); gray_cpu=(); gray_peak=(); colour_wall=(); colour_cpu=(); colour_peak=()
for img in "${images[@]}"; do
    gw=(); gc=(); gm=(); cw=(); cc=(); cm=()
    for _ in $(seq "$REPEATS"); do
        read -r w c m < <(times ./target/release/pifs encode "$img" --gray -o "$out/x.pifs" --bpp 0.25)
        gw+=("$w"); gc+=("$c"); gm+=("$m")
        read -r w c m < <(times ./target/release/pifs encode "$img" -o "$out/x.pifs" --bpp 0.25)
        cw+=("$w"); cc+=("$c"); cm+=("$m")
    done
    gray_wall+=("$(median "${gw[@]}")"); gray_cpu+=("$(median "${gc[@]}")"); gray_peak+=("$(median "${gm[@]}")")
    colour_wall+=("$(median "${cw[@]}")"); colour_cpu+=("$(median "${cc[@]}")"); colour_peak+=("$(median "${cm[@]}")")
    echo "$(basename "$img"): gray ${gray_wall[-1]} s wall ${gray_cpu[-1]} s CPU ${gray_peak[-1]} MB, colour ${colour_wall[-1]} s wall ${colour_cpu[-1]} s CPU ${colour_peak[-1]} MB" >&2
done

./target/release/examples/rd_sweep "${images[@]}" >"$out/sweep.csv"
extra=$(python3 - "$out/sweep.csv" <<'PY'
import csv, statistics, sys
from collections import defaultdict
groups = defaultdict(list)
for r in csv.DictReader(open(sys.argv[1])):
    if r["encode_s"]:
        groups[int(r["min_leaf_px"])].append(r)
parts = []
for leaf, rows in sorted(groups.items(), reverse=True):
    rates = sorted({r["target_bpp"] for r in rows}, key=float)
    median = statistics.median(float(r["encode_s"]) for r in rows)
    parts.append(f"{median:.3f} s ({'/'.join(rates)} bpp, leaves from {leaf} px)")
print("; ".join(parts))
PY
)

subset=("${images[@]:0:$THREADS_IMAGES}")
t1=(); t2=()
for img in "${subset[@]}"; do
    t1+=("$(RAYON_NUM_THREADS=1 wall ./target/release/pifs encode "$img" --gray -o "$out/x.pifs" --bpp 0.25)")
    t2+=("$(RAYON_NUM_THREADS=2 wall ./target/release/pifs encode "$img" --gray -o "$out/x.pifs" --bpp 0.25)")
done
s1=$(median "${t1[@]}"); s2=$(median "${t2[@]}")
speedup=$(python3 -c "print(f'{$s1/$s2:.2f}')")

echo
echo "| measure | value |"
echo "|---|---:|"
echo "| images | ${#images[@]} |"
echo "| one target, grayscale (--gray --bpp 0.25), whole process, median wall / CPU | $(median "${gray_wall[@]}") s / $(median "${gray_cpu[@]}") s |"
echo "| one target, colour (--bpp 0.25), whole process, median wall / CPU | $(median "${colour_wall[@]}") s / $(median "${colour_cpu[@]}") s |"
echo "| peak resident memory, grayscale, median / largest over the images | $(median "${gray_peak[@]}") MB / $(largest "${gray_peak[@]}") MB |"
echo "| peak resident memory, colour, median / largest over the images | $(median "${colour_peak[@]}") MB / $(largest "${colour_peak[@]}") MB |"
echo "| each extra target from the same analysis (grayscale), median | ${extra} |"
echo "| 1 thread / 2 threads (grayscale, ${#subset[@]} images, median wall) | ${s1} s / ${s2} s = ${speedup}x |"
