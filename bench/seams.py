#!/usr/bin/env python3
"""seams.py - does the block grid show? PSNR, SSIM and the grid measure B_g of PIFS decodes
beside JPEG 2000 at the same bytes, on grayscale images.

B_g: the mean absolute difference between neighbouring pixels across the lines of a g-pixel
grid (between columns x-1 and x with x = 0 mod g, and the same for rows), divided by the same
mean over every other pair of neighbouring pixels. A natural image has B_g near 1; a codec whose
blocks do not meet has B_g > 1. The quadtree's leaves start on multiples of 4, 8, 16, ..., so
B_4, B_8 and B_16 together see every leaf edge. S_512: the same across the columns x = 0 mod
512 only (x > 0; over every pair but those), where a stream coded in stripes of 512 pixels
starts a stripe (images wider than 512 pixels; the mean is over those).

B_16s: B_16 over the smooth parts of the image only, where the eye sees a step best: both
pixels of a pair (on the grid lines and off them) must lie where the original is smooth, its
mean absolute difference between neighbouring pixels over the 9 x 9 pixels around them below
2 grey levels (NaN for an image with fewer than 500 such pairs on the grid lines).

A_16s: the numerator of B_16s alone, the mean absolute step across the 16-pixel grid lines in
the smooth parts, in grey levels. A ratio also falls when the pixels between the lines vary
more (noise added to a decode lowers B_16s without moving a step); A_16s sees only the steps.

SSIM: Wang, Bovik, Sheikh, Simoncelli (2004), 11x11 Gaussian window (sigma 1.5), K1 = 0.01,
K2 = 0.03, L = 255, mean over the window positions inside the image.

    python3 bench/seams.py --work DIR [--pifs target/release/pifs] [--rates 0.05 0.1 0.25 0.5]
        [--csv OUT.csv] [--md OUT.md] [--no-j2k] [--pifs-args "ARGS"] IMAGE...

--pifs-args: more options for `pifs encode` (such as "--stripe-width 512").

Needs numpy and Pillow, and opj_compress / opj_decompress (libopenjp2-tools) for JPEG 2000.
"""

import argparse
import concurrent.futures as cf
import csv
import math
import os
import subprocess
import sys

import numpy as np
from PIL import Image

GRIDS = (4, 8, 16)


def read_gray(path):
    return np.asarray(Image.open(path).convert("L"), dtype=np.uint8)


def psnr(a, b):
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10 * math.log10(255.0 * 255.0 / mse)


def gaussian_window(size=11, sigma=1.5):
    r = np.arange(size) - (size - 1) / 2.0
    g = np.exp(-(r * r) / (2 * sigma * sigma))
    g /= g.sum()
    return g


def filter_valid(img, g):
    """Separable 'valid' correlation of a 2-D array with the 1-D window g on both axes."""
    n = len(g)
    h, w = img.shape
    rows = np.zeros((h, w - n + 1))
    for k in range(n):
        rows += g[k] * img[:, k:k + w - n + 1]
    out = np.zeros((h - n + 1, w - n + 1))
    for k in range(n):
        out += g[k] * rows[k:k + h - n + 1, :]
    return out


def ssim(a, b):
    a = a.astype(np.float64)
    b = b.astype(np.float64)
    g = gaussian_window()
    c1, c2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2
    mu_a, mu_b = filter_valid(a, g), filter_valid(b, g)
    saa = filter_valid(a * a, g) - mu_a * mu_a
    sbb = filter_valid(b * b, g) - mu_b * mu_b
    sab = filter_valid(a * b, g) - mu_a * mu_b
    num = (2 * mu_a * mu_b + c1) * (2 * sab + c2)
    den = (mu_a * mu_a + mu_b * mu_b + c1) * (saa + sbb + c2)
    return float(np.mean(num / den))


def grid_pairs(img, g, smooth=None):
    """The absolute differences between neighbouring pixels across the lines of a `g`-pixel grid
    and between every other pair, as two arrays; with `smooth` (a mask of the image's pixels),
    only the pairs whose pixels both lie in it."""
    a = img.astype(np.float64)
    dx = np.abs(a[:, 1:] - a[:, :-1])  # pair (x-1, x) at column index x-1
    dy = np.abs(a[1:, :] - a[:-1, :])
    if smooth is None:
        smooth = np.ones(a.shape, dtype=bool)
    mx = smooth[:, 1:] & smooth[:, :-1]
    my = smooth[1:, :] & smooth[:-1, :]
    on_x = (np.arange(1, a.shape[1]) % g) == 0
    on_y = (np.arange(1, a.shape[0]) % g) == 0
    across = np.concatenate([dx[:, on_x][mx[:, on_x]], dy[on_y, :][my[on_y, :]]])
    other = np.concatenate([dx[:, ~on_x][mx[:, ~on_x]], dy[~on_y, :][my[~on_y, :]]])
    return across, other


def grid_measure(img, g, smooth=None, least=1):
    """B_g of a grayscale image (see the module docstring); with `smooth` (a mask of the
    image's pixels), over the pairs whose pixels both lie in it. NaN with fewer than `least`
    pairs on the grid lines."""
    across, other = grid_pairs(img, g, smooth)
    if across.size < max(least, 1) or other.size == 0 or other.mean() == 0:
        return float("nan")
    return float(across.mean() / other.mean())


def stripe_measure(img, g=512):
    """S_512 of a grayscale image (see the module docstring); NaN when no column qualifies."""
    a = img.astype(np.float64)
    dx = np.abs(a[:, 1:] - a[:, :-1])
    dy = np.abs(a[1:, :] - a[:-1, :])
    on_x = (np.arange(1, a.shape[1]) % g) == 0
    if not on_x.any():
        return float("nan")
    other = np.concatenate([dx[:, ~on_x].ravel(), dy.ravel()])
    return float(dx[:, on_x].mean() / other.mean()) if other.mean() > 0 else float("nan")


def box_mean(a, r):
    """The mean of `a` over the (2r + 1)^2 pixels around each pixel (edges repeated)."""
    n = 2 * r + 1
    c = np.pad(np.pad(a, r, mode="edge").cumsum(0).cumsum(1), ((1, 0), (1, 0)))
    return (c[n:, n:] - c[:-n, n:] - c[n:, :-n] + c[:-n, :-n]) / (n * n)


def smooth_mask(orig, radius=4, limit=2.0):
    """Where the original is smooth: the mean absolute difference between neighbouring pixels
    (half the sum of the horizontal and vertical ones) over the pixels around, below `limit`."""
    a = orig.astype(np.float64)
    d = np.zeros_like(a)
    d[:, 1:] += np.abs(a[:, 1:] - a[:, :-1])
    d[1:, :] += np.abs(a[1:, :] - a[:-1, :])
    return box_mean(d / 2, radius) < limit


def smooth_grid_measure(orig, img, g=16):
    """B_16s (see the module docstring): B_g over the pairs whose pixels are both smooth."""
    return grid_measure(img, g, smooth_mask(orig), least=500)


def smooth_grid_step(orig, img, g=16):
    """A_16s (see the module docstring): the mean step across the grid lines, in grey levels,
    over the pairs whose pixels are both smooth (NaN with fewer than 500)."""
    across, _ = grid_pairs(img, g, smooth_mask(orig))
    return float(across.mean()) if across.size >= 500 else float("nan")


def metrics(orig, rec):
    out = {"psnr": psnr(orig, rec), "ssim": ssim(orig, rec)}
    for g in GRIDS:
        out["b%d" % g] = grid_measure(rec, g)
    out["b16s"] = smooth_grid_measure(orig, rec)
    out["a16s"] = smooth_grid_step(orig, rec)
    out["s512"] = stripe_measure(rec)
    return out


def run(cmd):
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def j2k_at_bytes(pgm, budget, tdir, read=read_gray):
    """Largest JPEG 2000 codestream (opj_compress -I -r R) of at most `budget` bytes, decoded
    (by `read`; a PPM input decodes to a PPM); bisection on log2 of the compression ratio.
    Returns (bytes, decoded array) or None."""
    h, w = read_gray(pgm).shape
    raw_bits = 8.0 * w * h * (3 if pgm.endswith(".ppm") else 1)
    lo, hi = math.log2(raw_bits / (8.0 * budget)) - 1.0, math.log2(raw_bits / (8.0 * budget)) + 6.0
    # lo: a smaller ratio (bigger file) than the budget allows; hi: a bigger ratio (smaller).
    best = None
    out = os.path.join(tdir, "j2k.j2k")
    for _ in range(24):
        mid = 0.5 * (lo + hi)
        run(["opj_compress", "-i", pgm, "-o", out, "-I", "-r", "%.6f" % (2.0 ** mid)])
        size = os.path.getsize(out)
        if size <= budget:
            hi = mid
            if best is None or size > best[0]:
                dec = os.path.join(tdir, "j2k" + os.path.splitext(pgm)[1])
                run(["opj_decompress", "-i", out, "-o", dec])
                best = (size, read(dec))
        else:
            lo = mid
        if best is not None and best[0] >= budget * 0.998:
            break
    return best


def prepare(path, work):
    """An image's name, its work directory (made), its grayscale pixels and their PGM there
    (`orig.pgm`, what the codecs are given)."""
    name = os.path.splitext(os.path.basename(path))[0]
    tdir = os.path.join(work, name)
    os.makedirs(tdir, exist_ok=True)
    orig = read_gray(path)
    pgm = os.path.join(tdir, "orig.pgm")
    Image.fromarray(orig, "L").save(pgm)
    return name, tdir, orig, pgm


def bench_image(job):
    path, rates, work, pifs, with_j2k, pifs_args = job
    name, tdir, orig, pgm = prepare(path, work)
    h, w = orig.shape
    rows = [dict(image=name, codec="original", target_bpp="", bytes="", bpp="",
                 **{k: v for k, v in metrics(orig, orig).items()})]
    for rate in rates:
        stream = os.path.join(tdir, "pifs_%g.pifs" % rate)
        dec = os.path.join(tdir, "pifs_%g.pgm" % rate)
        run([pifs, "encode", pgm, "-o", stream, "--bpp", str(rate)] + pifs_args)
        run([pifs, "decode", stream, "-o", dec])
        size = os.path.getsize(stream)
        rec = read_gray(dec)
        rows.append(dict(image=name, codec="pifs", target_bpp=rate, bytes=size,
                         bpp=8.0 * size / (w * h), **metrics(orig, rec)))
        if with_j2k:
            j2k = j2k_at_bytes(pgm, size, tdir)
            if j2k is not None:
                rows.append(dict(image=name, codec="jpeg2000", target_bpp=rate, bytes=j2k[0],
                                 bpp=8.0 * j2k[0] / (w * h), **metrics(orig, j2k[1])))
    return rows


def mean(values):
    values = [v for v in values if v != "" and not math.isnan(v) and not math.isinf(v)]
    return sum(values) / len(values) if values else float("nan")


def markdown(rows, rates):
    keys = ["psnr", "ssim"] + ["b%d" % g for g in GRIDS] + ["b16s", "a16s", "s512"]
    out = ["| codec | bpp | n | PSNR dB | SSIM | B_4 | B_8 | B_16 | B_16s | A_16s | S_512 |",
           "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    orig = [r for r in rows if r["codec"] == "original"]
    out.append("| original | | %d | | | %s |" % (
        len(orig), " | ".join("%.3f" % mean([r[k] for r in orig]) for k in keys[2:])))
    for rate in rates:
        for codec in ("pifs", "jpeg2000"):
            sel = [r for r in rows if r["codec"] == codec and r["target_bpp"] == rate]
            if not sel:
                continue
            out.append("| %s | %.4f | %d | %.3f | %.4f | %s |" % (
                codec, mean([r["bpp"] for r in sel]), len(sel), mean([r["psnr"] for r in sel]),
                mean([r["ssim"] for r in sel]),
                " | ".join("%.3f" % mean([r[k] for r in sel]) for k in keys[2:])))
    return "\n".join(out) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("images", nargs="+")
    ap.add_argument("--work", required=True)
    ap.add_argument("--pifs", default="target/release/pifs")
    ap.add_argument("--rates", type=float, nargs="+", default=[0.05, 0.1, 0.25, 0.5])
    ap.add_argument("--csv")
    ap.add_argument("--md")
    ap.add_argument("--no-j2k", action="store_true")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--pifs-args", default="", help="more options for `pifs encode`")
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)
    jobs = [(p, args.rates, args.work, os.path.abspath(args.pifs), not args.no_j2k,
             args.pifs_args.split()) for p in args.images]
    rows = []
    with cf.ProcessPoolExecutor(max_workers=args.jobs) as ex:
        for r in ex.map(bench_image, jobs):
            rows.extend(r)
            print("%s done" % r[0]["image"], file=sys.stderr)
    fields = ["image", "codec", "target_bpp", "bytes", "bpp", "psnr", "ssim"] + [
        "b%d" % g for g in GRIDS] + ["b16s", "a16s", "s512"]
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            wr = csv.DictWriter(f, fieldnames=fields)
            wr.writeheader()
            wr.writerows(rows)
    md = markdown(rows, args.rates)
    if args.md:
        with open(args.md, "w") as f:
            f.write(md)
    print(md)


if __name__ == "__main__":
    main()
