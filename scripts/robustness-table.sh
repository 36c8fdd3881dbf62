#!/usr/bin/env bash
# Regenerates docs/robustness.md: runs the `pifs` command line against every malformed and
# unusual input of host-encoder/tests/robustness_table.rs and writes the table of outcomes.
set -euo pipefail
cd "$(dirname "$0")/.."
PIFS_WRITE_ROBUSTNESS_TABLE=1 cargo test -q -p host-encoder --test robustness_table
echo "wrote docs/robustness.md"
