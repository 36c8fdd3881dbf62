#!/usr/bin/env python3
"""base_layer.py - would a smooth base layer remove the leaf squares? (issue 21, an experiment)

Emulates a two-layer stream with today's codec: a coarse base (the means of f x f blocks,
quantised with step q, DPCM-coded with the LOCO-I median predictor; its size is the ideal code
length of an adaptive frequency model over the residuals, plus 2 bytes) is upsampled
bilinearly to the image, and `pifs` codes the residual image clip(I - U + 128) with the rest of
the budget (`--bytes`); the picture is clip(R' + U - 128). Compared with `pifs` on the image at
the same total bytes: PSNR, SSIM, B_16 and B_16s of bench/seams.py. Not part of the codec (see
docs/decisions.md, "Leaf edges: what did not work").

    python3 bench/experiments/base_layer.py --work DIR [--pifs PIFS] [--factor 16] [--step 4]
        [--rates 0.05 0.1 0.25] IMAGE...
"""

import argparse
import concurrent.futures as cf
import math
import os
import sys

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from seams import metrics, prepare, read_gray, run  # noqa: E402


def block_means(img, f):
    h, w = img.shape
    bh, bw = -(-h // f), -(-w // f)
    pad = np.pad(img.astype(np.float64), ((0, bh * f - h), (0, bw * f - w)), mode="edge")
    return pad.reshape(bh, f, bw, f).mean(axis=(1, 3))


def med_residuals(q):
    """LOCO-I median prediction residuals of an integer grid, raster order."""
    bh, bw = q.shape
    res = np.zeros_like(q)
    for y in range(bh):
        for x in range(bw):
            a = q[y, x - 1] if x > 0 else (q[y - 1, x] if y > 0 else 0)
            b = q[y - 1, x] if y > 0 else a
            c = q[y - 1, x - 1] if x > 0 and y > 0 else b
            if c >= max(a, b):
                p = min(a, b)
            elif c <= min(a, b):
                p = max(a, b)
            else:
                p = a + b - c
            res[y, x] = q[y, x] - p
    return res


def adaptive_bits(symbols):
    """Ideal code length of an adaptive frequency model (counts start at 1 over the range)."""
    lo, hi = int(symbols.min()), int(symbols.max())
    counts = np.ones(hi - lo + 1)
    total = counts.sum()
    bits = 0.0
    for s in symbols.ravel():
        i = int(s) - lo
        bits -= math.log2(counts[i] / total)
        counts[i] += 1
        total += 1
    # The alphabet's range, sent first.
    return bits + 16


def upsample(base, f, h, w):
    """Bilinear between block centres, clamped beyond the outer ones."""
    bh, bw = base.shape
    ys = (np.arange(h) + 0.5) / f - 0.5
    xs = (np.arange(w) + 0.5) / f - 0.5
    y0 = np.clip(np.floor(ys).astype(int), 0, bh - 1)
    x0 = np.clip(np.floor(xs).astype(int), 0, bw - 1)
    y1 = np.clip(y0 + 1, 0, bh - 1)
    x1 = np.clip(x0 + 1, 0, bw - 1)
    fy = np.clip(ys - np.floor(ys), 0, 1)[:, None]
    fx = np.clip(xs - np.floor(xs), 0, 1)[None, :]
    fy = np.where((ys < 0)[:, None] | (ys > bh - 1)[:, None], 0.0, fy)
    fx = np.where((xs < 0)[None, :] | (xs > bw - 1)[None, :], 0.0, fx)
    top = base[y0][:, x0] * (1 - fx) + base[y0][:, x1] * fx
    bot = base[y1][:, x0] * (1 - fx) + base[y1][:, x1] * fx
    return top * (1 - fy) + bot * fy


def bench(job):
    path, rates, work, pifs, f, step = job
    name, tdir, orig, pgm = prepare(path, work)
    h, w = orig.shape
    qb = np.round(block_means(orig, f) / step).astype(np.int64)
    base_bytes = int(math.ceil((adaptive_bits(med_residuals(qb)) + 16) / 8))
    up = upsample(qb * float(step), f, h, w)
    resid = np.clip(np.round(orig - up + 128), 0, 255).astype(np.uint8)
    rpgm = os.path.join(tdir, "resid_f%d_q%d.pgm" % (f, step))
    Image.fromarray(resid, "L").save(rpgm)
    rows = []
    for rate in rates:
        budget = int(rate * w * h / 8)
        plain = os.path.join(tdir, "plain_%g" % rate)
        run([pifs, "encode", pgm, "-o", plain + ".pifs", "--bytes", str(budget)])
        run([pifs, "decode", plain + ".pifs", "-o", plain + ".pgm"])
        rows.append(dict(image=name, codec="plain", rate=rate,
                         bytes=os.path.getsize(plain + ".pifs"),
                         **metrics(orig, read_gray(plain + ".pgm"))))
        two = os.path.join(tdir, "base_f%d_q%d_%g" % (f, step, rate))
        run([pifs, "encode", rpgm, "-o", two + ".pifs", "--bytes", str(budget - base_bytes)])
        run([pifs, "decode", two + ".pifs", "-o", two + ".pgm"])
        rec = np.clip(np.round(read_gray(two + ".pgm") + up - 128), 0, 255).astype(np.uint8)
        Image.fromarray(rec, "L").save(two + "_rec.png")
        rows.append(dict(image=name, codec="base", rate=rate,
                         bytes=os.path.getsize(two + ".pifs") + base_bytes, base=base_bytes,
                         **metrics(orig, rec)))
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--work", required=True)
    ap.add_argument("--pifs", default="target/release/pifs")
    ap.add_argument("--factor", type=int, default=16)
    ap.add_argument("--step", type=int, default=4)
    ap.add_argument("--rates", type=float, nargs="+", default=[0.05, 0.1, 0.25])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("images", nargs="+")
    a = ap.parse_args()
    jobs = [(p, a.rates, a.work, os.path.abspath(a.pifs), a.factor, a.step) for p in a.images]
    rows = []
    with cf.ProcessPoolExecutor(a.jobs) as ex:
        for r in ex.map(bench, jobs):
            rows.extend(r)
    print("f=%d q=%d" % (a.factor, a.step))
    print("| codec | bpp | PSNR dB | SSIM | B_16 | B_16s | base bytes |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for rate in a.rates:
        for codec in ("plain", "base"):
            sel = [r for r in rows if r["codec"] == codec and r["rate"] == rate]
            m = lambda k: sum(r[k] for r in sel) / len(sel)  # noqa: E731
            b16s = [r["b16s"] for r in sel if not math.isnan(r["b16s"])]
            print("| %s | %g | %.3f | %.4f | %.3f | %.3f | %s |" % (
                codec, rate, m("psnr"), m("ssim"), m("b16"), sum(b16s) / len(b16s),
                "%.0f" % m("base") if codec == "base" else ""))
    for r in rows:
        print(r["image"], r["codec"], r["rate"], r["bytes"], "%.3f" % r["psnr"],
              "%.3f" % r["b16s"], file=sys.stderr)


if __name__ == "__main__":
    main()
