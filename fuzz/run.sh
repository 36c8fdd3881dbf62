#!/usr/bin/env bash
# Runs every fuzz target for SECONDS each (default 60) with cargo-fuzz (nightly toolchain) and
# prints the executions per target and in total. Seeds: the golden vectors and the committed
# regression inputs; the growing corpus stays in fuzz/corpus/ (not committed). A crash stops the
# run with libFuzzer's report; its input lands in fuzz/artifacts/<target>/ and belongs, once
# fixed, in fuzz/regressions/<target>/ (replayed by `cargo test` on stable).
#
#   bash fuzz/run.sh [SECONDS] [TARGET...]
set -euo pipefail
cd "$(dirname "$0")"
seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(decode_bytes stream_equals_slice roundtrip)
total=0
for t in "${targets[@]}"; do
    mkdir -p "corpus/$t" "regressions/$t"
    log=$(mktemp)
    # No sanitizer: decoder-core forbids unsafe code, so AddressSanitizer would find nothing
    # the bounds checks do not, at several times the cost per execution.
    cargo +nightly fuzz run -s none "$t" "corpus/$t" ../tests/golden "regressions/$t" -- \
        -max_total_time="$seconds" -print_final_stats=1 >"$log" 2>&1 || { tail -40 "$log"; exit 1; }
    n=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
    echo "$t: $n executions in ${seconds} s, no crash"
    total=$((total + n))
    rm -f "$log"
done
echo "total: $total executions"
