#!/usr/bin/env bash
# Runs every fuzz target for SECONDS each (default 60) with cargo-fuzz (nightly toolchain) and
# prints the executions per target and in total. Seeds: fuzz/seeds/ (made by the encoder:
# tests/tests/fuzz_seeds.rs), the golden vectors for the stream targets, and the committed
# regression inputs; the growing corpus stays in fuzz/corpus/ (not committed). A crash stops the
# run with libFuzzer's report; its input lands in fuzz/artifacts/<target>/ and belongs, once
# fixed, in fuzz/regressions/<target>/ (replayed by `cargo test` on stable).
#
#   bash fuzz/run.sh [--fast] [--jobs N] [--record] [SECONDS] [TARGET...]
#
# --fast builds without the comparison tracing that guides mutations through comparisons
# (`--no-trace-compares`): about four times the executions per second, for long campaigns once
# the corpus has grown with it. --jobs N runs N libFuzzer processes per target (their
# executions are added up). --record
# adds the figures to fuzz/campaign.txt (starting it afresh when the format version changed),
# which docs/robustness.md reports (regenerate it with scripts/robustness-table.sh). A crash
# stops the run before anything is recorded.
set -euo pipefail
cd "$(dirname "$0")"
jobs=1
record=0
fast=()
while [ $# -gt 0 ]; do
    case "$1" in
        --fast) fast=(--no-trace-compares); shift ;;
        --jobs) jobs=$2; shift 2 ;;
        --record) record=1; shift ;;
        *) break ;;
    esac
done
seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(decode_bytes stream_equals_slice roundtrip encode_input large_dimensions decode_packets)
version=$(sed -n 's/^pub const VERSION: u8 = \([0-9]*\);.*/\1/p' ../decoder-core/src/format.rs)
seeds_of() {
    case "$1" in
        decode_bytes | stream_equals_slice) echo "seeds/streams ../tests/golden" ;;
        decode_packets) echo "seeds/packets" ;;
        *) echo "seeds/$1" ;;
    esac
}
total=0
lines=()
for t in "${targets[@]}"; do
    mkdir -p "corpus/$t" "regressions/$t"
    logs=$(mktemp -d)
    # No sanitizer: decoder-core forbids unsafe code, so AddressSanitizer would find nothing
    # the bounds checks do not, at several times the cost per execution. Inputs up to 64 KiB.
    # shellcheck disable=SC2046
    cargo +nightly fuzz run -s none ${fast[@]+"${fast[@]}"} "$t" "corpus/$t" $(seeds_of "$t") "regressions/$t" -- \
        -max_total_time="$seconds" -max_len=65536 -timeout=30 -print_final_stats=1 \
        -jobs="$jobs" -workers="$jobs" >"$logs/main.log" 2>&1 || {
        tail -40 "$logs/main.log"
        for f in fuzz-*.log; do [ -f "$f" ] && tail -40 "$f"; done
        exit 1
    }
    if [ "$jobs" -gt 1 ]; then
        n=$(cat fuzz-*.log | sed -n 's/^stat::number_of_executed_units: *//p' | paste -sd+ | bc)
        rm -f fuzz-*.log
    else
        n=$(sed -n 's/^stat::number_of_executed_units: *//p' "$logs/main.log")
    fi
    echo "$t: $n executions in ${seconds} s x $jobs, no crash"
    lines+=("$t $n")
    total=$((total + n))
    rm -rf "$logs"
done
echo "total: $total executions (format version $version)"
if [ "$record" = 1 ]; then
    # Runs on the same format version add up; a new version starts a new record.
    if ! grep -qx "format_version $version" campaign.txt 2>/dev/null; then
        printf '# Fuzz campaign, written by fuzz/run.sh --record (runs on one format version add up)\nformat_version %s\n' \
            "$version" >campaign.txt
    fi
    {
        echo "command bash fuzz/run.sh ${fast[*]:+--fast }--jobs $jobs --record $seconds ${targets[*]}"
        for l in "${lines[@]}"; do echo "run $l $seconds $jobs $(date -u +%Y-%m-%d)"; done
    } >>campaign.txt
    echo "recorded in fuzz/campaign.txt"
fi
