#!/usr/bin/env python3
"""terrain_max_error.py - `pifs encode --max-error` on the terrain benchmark's surfaces (the two
real DEMs matplotlib ships and the fBm surface of bench/terrain.py): for bounds of 0.25%, 0.5%,
1% and 2% of each surface's range (in its units, rounded to whole units), the bytes of the
smallest stream found and its largest error and RMSE, checked by decoding it; with `--before
PIFS`, the same for another pifs binary beside it. Prints a markdown table.

    python3 bench/terrain_max_error.py [--pifs target/release/pifs] [--before OTHER_PIFS]

Needs numpy, pillow and matplotlib (its sample data only), as bench/terrain.sh.
"""

import argparse
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from terrain import dems, errors, read_pnm, write_pgm  # noqa: E402

SHARES = [0.0025, 0.005, 0.01, 0.02]


def bounded(pifs, z, bound, work):
    """Bytes, largest error and RMSE of `pifs`'s stream of `z` within `bound`, or None when it
    refuses the bound as unreachable."""
    lo = float(z.min())
    src, stream, dec = (os.path.join(work, n) for n in ("in.pgm", "x.pifs", "x.pgm"))
    write_pgm(src, np.round(z - lo), 65535)
    if os.path.exists(stream):
        os.remove(stream)
    done = subprocess.run([pifs, "encode", src, "--max-error", str(bound), "-o", stream],
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode != 0:
        if "unreachable" in done.stderr:
            return None
        raise RuntimeError(done.stderr)
    subprocess.run([pifs, "decode", stream, "-o", dec], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    rmse, largest, _ = errors(z, lo + read_pnm(dec))
    assert largest <= bound, f"{largest} above {bound}"
    return os.path.getsize(stream), largest, rmse


def cell(result):
    if result is None:
        return "unreachable"
    size, largest, rmse = result
    return f"{size:,}".replace(",", " ") + f" B (max {largest:g}, RMSE {rmse:.2f})"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--pifs", default="target/release/pifs")
    ap.add_argument("--before", help="another pifs binary to measure beside it")
    args = ap.parse_args()
    header = "| surface | size | range | bound | pifs |"
    if args.before:
        header += " before |"
    print(header)
    print("|---|---|---:|---:|---:|" + ("---:|" if args.before else ""))
    with tempfile.TemporaryDirectory() as work:
        for name, _, z in dems():
            span = float(z.max() - z.min())
            for share in SHARES:
                bound = max(1, math.ceil(share * span))
                row = f"| {name} | {z.shape[1]}x{z.shape[0]} | {span:g} | {bound} | "
                row += cell(bounded(args.pifs, z, bound, work)) + " |"
                if args.before:
                    row += " " + cell(bounded(args.before, z, bound, work)) + " |"
                print(row, flush=True)


if __name__ == "__main__":
    main()
