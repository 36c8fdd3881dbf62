#!/usr/bin/env python3
"""step_profile.py - issue 21: where does a decode's variation lie in the smooth parts, on the
16-pixel grid lines or between them? Squares show where the steps are on the lines and the
patches between them are flat.

For each vertical (horizontal) line, cut into segments of 16 pixels lying where the original is
smooth (`smooth_mask` of bench/seams.py), the step across it is the mean of the K pixels after
the line less the mean of the K before it, averaged along the segment (so that grain averages
out and a straight step stays); the profile is the mean absolute step over the segments, on
the lines x = 0 mod 16 ("on the grid") and on the lines x = 2 mod 4, which no leaf edge
reaches ("inside leaves"; so K is 1 or 2, which keeps both halves clear of
the edges at x = 0 mod 4); the means pool the segments of every image. Also prints
A_16s and B_16s of bench/seams.py. With --grain SIGMA, Gaussian noise of that deviation
(seeded) is added to each decode first, to show what noise does to the ratio B_16s and not to
the steps.

    python3 bench/experiments/step_profile.py [--k 2] [--grain SIGMA] ORIGINAL DECODE [DECODE...]
    python3 bench/experiments/step_profile.py --pairs LIST   (lines "ORIGINAL DECODE"; means)
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from seams import (psnr, read_gray, smooth_grid_measure, smooth_grid_step,  # noqa: E402
                   smooth_mask)


def segment_steps(img, mask, first, k, g=16, seg=16):
    """The absolute steps over the smooth 16-px segments of the lines first, first + g, ..."""
    a = img.astype(np.float64)
    steps = []
    for t in (a, a.T):
        m = mask if t is a else mask.T
        h, w = t.shape
        for x in range(first, w - k, g):
            if x < k:
                continue
            d = t[:, x:x + k].mean(1) - t[:, x - k:x].mean(1)
            ok = m[:, x - k:x + k].all(1)
            for y in range(0, h - seg + 1, seg):
                if ok[y:y + seg].all():
                    steps.append(abs(d[y:y + seg].mean()))
    return steps


def profile(orig, dec, k):
    mask = smooth_mask(orig)
    inside = [s for first in (2, 6, 10, 14) for s in segment_steps(dec, mask, first, k)]
    return dict(on=segment_steps(dec, mask, 16, k), inside=inside,
                a16s=smooth_grid_step(orig, dec), b16s=smooth_grid_measure(orig, dec),
                psnr=psnr(orig, dec))


def pooled(steps):
    return float(np.mean(steps)) if steps else float("nan")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--k", type=int, default=2, choices=(1, 2))
    ap.add_argument("--grain", type=float, default=0.0)
    ap.add_argument("--pairs")
    ap.add_argument("files", nargs="*")
    a = ap.parse_args()
    if a.pairs:
        pairs = [line.split() for line in open(a.pairs) if line.strip()]
    elif len(a.files) >= 2:
        pairs = [(a.files[0], d) for d in a.files[1:]]
    else:
        sys.exit(__doc__)
    rng = np.random.default_rng(7)
    rows = []
    for o, d in pairs:
        orig = read_gray(o)
        dec = read_gray(d).astype(np.float64)
        if a.grain > 0:
            dec = np.clip(np.round(dec + rng.standard_normal(dec.shape) * a.grain), 0, 255)
        r = profile(orig, dec, a.k)
        rows.append(r)
        print("%s: on the grid %.3f, inside leaves %.3f, A_16s %.3f, B_16s %.3f, PSNR %.3f dB"
              % (d, pooled(r["on"]), pooled(r["inside"]), r["a16s"], r["b16s"], r["psnr"]))
    if len(rows) > 1:
        m = {key: np.nanmean([r[key] for r in rows]) for key in ("a16s", "b16s", "psnr")}
        print("all %d: on the grid %.3f, inside leaves %.3f (segments pooled), mean A_16s %.3f,"
              " B_16s %.3f, PSNR %.3f dB" % (
                  len(rows), pooled([s for r in rows for s in r["on"]]),
                  pooled([s for r in rows for s in r["inside"]]), m["a16s"], m["b16s"], m["psnr"]))


if __name__ == "__main__":
    main()
