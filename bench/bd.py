#!/usr/bin/env python3
"""Bjøntegaard deltas of PIFS against an anchor codec on the Kodak set, per image and on average.

    python3 bench/bd.py bench/results/kodak-pifs.csv [anchors.md] [codec]

Reads PIFS's points (actual bpp, PSNR) from an rd_sweep CSV and the anchor's per-image points
from the "#### <codec>" table of ../shared/bench/kodak-anchors.md (default codec: jpeg2000),
at the rates both have. Per image, each codec's curve is the cubic through its points, PSNR over
ln(bpp) for BD-PSNR and ln(bpp) over PSNR for BD-rate (Bjøntegaard, VCEG-M33), integrated over
the range both cover. Negative BD-rate and positive BD-PSNR mean PIFS is better. Standard
library only.
"""
import csv
import math
import os
import re
import statistics
import sys


def lagrange(xs, ys):
    """The polynomial through the points (a cubic for four)."""
    def p(x):
        total = 0.0
        for i, (xi, yi) in enumerate(zip(xs, ys)):
            term = yi
            for j, xj in enumerate(xs):
                if j != i:
                    term *= (x - xj) / (xi - xj)
            total += term
        return total
    return p


def mean_over(p, lo, hi, steps=2000):
    """Mean of p over [lo, hi] (Simpson's rule)."""
    h = (hi - lo) / steps
    s = p(lo) + p(hi) + sum((4 if k % 2 else 2) * p(lo + k * h) for k in range(1, steps))
    return s * h / 3 / (hi - lo)


def bd(ours, theirs):
    """(BD-rate %, BD-PSNR dB) of `ours` against `theirs`: lists of (bpp, psnr)."""
    ours, theirs = sorted(ours), sorted(theirs)
    xo, po = [math.log(r) for r, _ in ours], [p for _, p in ours]
    xt, pt = [math.log(r) for r, _ in theirs], [p for _, p in theirs]
    lo, hi = max(min(xo), min(xt)), min(max(xo), max(xt))
    bd_psnr = mean_over(lagrange(xo, po), lo, hi) - mean_over(lagrange(xt, pt), lo, hi)
    lo, hi = max(min(po), min(pt)), min(max(po), max(pt))
    if hi <= lo:
        return float("nan"), bd_psnr
    # PSNR must rise with the rate for the inverse curve; it does on every image measured.
    by_p_o = sorted(zip(po, xo))
    by_p_t = sorted(zip(pt, xt))
    d = mean_over(lagrange(*zip(*by_p_o)), lo, hi) - mean_over(lagrange(*zip(*by_p_t)), lo, hi)
    return (math.exp(d) - 1) * 100, bd_psnr


def main():
    csv_path = sys.argv[1]
    anchors_path = sys.argv[2] if len(sys.argv) > 2 else os.path.join(
        os.path.dirname(__file__), "..", "..", "shared", "bench", "kodak-anchors.md")
    codec = sys.argv[3] if len(sys.argv) > 3 else "jpeg2000"

    ours = {}
    for r in csv.DictReader(open(csv_path)):
        if r["psnr_db"]:
            ours.setdefault(r["image"], {})[float(r["target_bpp"])] = (float(r["bpp"]), float(r["psnr_db"]))

    theirs = {}
    lines = open(anchors_path).read().splitlines()
    start = lines.index(f"#### {codec}")
    header = next(l for l in lines[start:] if l.startswith("| image |"))
    rates = [float(c) for c in header.strip("|").split("|")[1:]]
    for line in lines[lines.index(header, start) + 2:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        for rate, cell in zip(rates, cells[1:]):
            m = re.match(r"([\d.]+) \(([\d.]+)\)", cell)
            if m:
                theirs.setdefault(cells[0], {})[rate] = (float(m.group(2)), float(m.group(1)))

    rows = []
    for image in sorted(ours):
        common = sorted(set(ours[image]) & set(theirs.get(image, {})))
        if len(common) < 4:
            continue
        # A cubic takes four points: the lowest, the highest and two spread between them.
        common = [common[round(k * (len(common) - 1) / 3)] for k in range(4)]
        rate, psnr = bd([ours[image][t] for t in common], [theirs[image][t] for t in common])
        rows.append((image, rate, psnr, common))
    if not rows:
        sys.exit("no image with four rates in common")
    used = sorted({t for *_, c in rows for t in c})
    print(f"PIFS against {codec}, Bjøntegaard deltas over {used[0]}-{used[-1]} bpp "
          f"(rates {', '.join(map(str, used))}), {len(rows)} images\n")
    print("| image | BD-rate (%) | BD-PSNR (dB) |")
    print("|---|---:|---:|")
    for image, rate, psnr, _ in rows:
        print(f"| {image} | {rate:+.1f} | {psnr:+.2f} |")
    rates_ok = [r for _, r, _, _ in rows if not math.isnan(r)]
    print(f"| **mean** | **{statistics.mean(rates_ok):+.1f}** | "
          f"**{statistics.mean(p for _, _, p, _ in rows):+.2f}** |")


if __name__ == "__main__":
    main()
