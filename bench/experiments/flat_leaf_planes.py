#!/usr/bin/env python3
"""flat_leaf_planes.py - issue 21 exploration: would flat leaves look less like squares drawn
as planes that continue the pixels above and left of them? A post-filter on decodes made
without edge smoothing, judged by PSNR and the grid measure B_16 of bench/seams.py. Not part of
the codec (see docs/decisions.md, "Leaf edges: what did not work").

Inputs, with any build of `pifs`:

    pifs encode IMAGE --gray --bpp R --deblock 0 -o S.pifs
    pifs decode S.pifs -o S.pgm
    pifs info S.pifs --svg S.svg            (the leaves, in coding order)
    python3 bench/experiments/flat_leaf_planes.py IMAGE S.pgm S.svg OUT.png [THRESHOLD [MIN_SIZE]]

Rule, leaf by leaf in coding order on the filtered image: a leaf of at least MIN_SIZE pixels
(8) whose decoded pixels lie within one grey level is replaced by the plane through its mean
M whose top edge meets T, the mean of the row above it, and whose left edge meets L, the mean
of the column left of it: slopes (M - T) / ((S + 1) / 2) down and (M - L) / ((S + 1) / 2)
across, each only where that edge is known and |M - T| (|M - L|) is at most THRESHOLD grey
levels (12). Prints the leaves redrawn and PSNR and B_16 before and after.

Needs numpy and Pillow.
"""

import os
import sys

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from seam_ramps import leaves  # noqa: E402
from seams import grid_measure, psnr  # noqa: E402


def main():
    if len(sys.argv) < 5:
        sys.exit(__doc__)
    original = np.asarray(Image.open(sys.argv[1]).convert("L"), dtype=np.float64)
    decoded = np.asarray(Image.open(sys.argv[2]).convert("L"), dtype=np.float64)
    threshold = float(sys.argv[5]) if len(sys.argv) > 5 else 12.0
    min_size = int(sys.argv[6]) if len(sys.argv) > 6 else 8
    out = decoded.copy()
    all_leaves = leaves(sys.argv[3])
    redrawn = 0
    for x, y, s in all_leaves:
        block = decoded[y : y + s, x : x + s]
        if s < min_size or block.max() - block.min() > 1:
            continue
        mean = block.mean()
        h, w = block.shape
        down = across = 0.0
        if y > 0:
            top = out[y - 1, x : x + w].mean()
            if abs(top - mean) <= threshold:
                down = (mean - top) / ((s + 1) / 2)
        if x > 0:
            left = out[y : y + h, x - 1].mean()
            if abs(left - mean) <= threshold:
                across = (mean - left) / ((s + 1) / 2)
        jj, ii = np.mgrid[0:h, 0:w]
        out[y : y + h, x : x + w] = mean + across * (ii - (s - 1) / 2) + down * (jj - (s - 1) / 2)
        redrawn += 1
    out = np.clip(np.round(out), 0, 255)
    print(
        f"{sys.argv[2]}: {redrawn} of {len(all_leaves)} leaves redrawn, "
        f"PSNR {psnr(original, decoded):.3f} -> {psnr(original, out):.3f} dB, "
        f"B_16 {grid_measure(decoded, 16):.3f} -> {grid_measure(out, 16):.3f}"
    )
    Image.fromarray(out.astype(np.uint8)).save(sys.argv[4])


if __name__ == "__main__":
    main()
