#!/usr/bin/env python3
"""leaf_mean_surface.py - issue 21 exploration: would the squares go if each leaf's mean were
drawn as a smooth surface through the means of the leaves around it (two-sided, as a decoder
with a frame buffer, or one that knows the next leaves' means ahead, could)? A post-filter on
decodes, judged by PSNR, SSIM, B_16 and B_16s of bench/seams.py. Not part of the codec.

For every leaf of at least MIN_SIZE pixels whose decoded pixels lie within 2 grey levels: M is the image of leaf means (each pixel the mean
of its leaf's decoded pixels), S(p) the mean of M over the S x S window centred on p (S the
side of p's leaf; a box over a staircase of S-wide steps is the line between their centres),
and the leaf's pixels become decoded + clip(S - M, -T, T).

    python3 bench/experiments/leaf_mean_surface.py --work DIR [--pifs PIFS] [--rates ...]
        [--min-size 8] [--limits 4,8,16] IMAGE...

Runs `pifs encode IMAGE --gray --bpp R` (the stream as the encoder makes it) and the same with
`--deblock 0` (the input of the filter), `pifs info S --svg` for the leaves.
"""

import argparse
import concurrent.futures as cf
import os
import sys

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from seam_ramps import leaves  # noqa: E402
from seams import (grid_measure, prepare, psnr, read_gray, run,  # noqa: E402
                   smooth_grid_measure, ssim)


def surface(dec, lv, min_size, limit, flat, select):
    h, w = dec.shape
    m = dec.copy()
    for x, y, s in lv:
        m[y:y + s, x:x + s] = dec[y:y + s, x:x + s].mean()
    ii = np.zeros((h + 1, w + 1))
    ii[1:, 1:] = m.cumsum(0).cumsum(1)
    out = dec.copy()
    for x, y, s in lv:
        block = select[y:y + s, x:x + s]
        if s < min_size or block.max() - block.min() > flat:
            continue
        ys = np.arange(y, min(y + s, h))
        xs = np.arange(x, min(x + s, w))
        r = s // 2
        y0 = np.clip(ys - r, 0, h)[:, None]
        y1 = np.clip(ys - r + s, 0, h)[:, None]
        x0 = np.clip(xs - r, 0, w)[None, :]
        x1 = np.clip(xs - r + s, 0, w)[None, :]
        area = (y1 - y0) * (x1 - x0)
        sm = (ii[y1, x1] - ii[y0, x1] - ii[y1, x0] + ii[y0, x0]) / area
        mean = m[y, x]
        out[ys[0]:ys[-1] + 1, xs[0]:xs[-1] + 1] += np.clip(sm - mean, -limit, limit)
    return np.clip(np.round(out), 0, 255)


def measure(orig, rec):
    return dict(psnr=psnr(orig, rec), ssim=ssim(orig, rec), b16=grid_measure(rec, 16),
                b16s=smooth_grid_measure(orig, rec))


def bench(job):
    path, rates, work, pifs, min_size, limits = job
    name, tdir, orig, pgm = prepare(path, work)
    rows = []
    for rate in rates:
        for tag, extra in (("stream", []), ("raw", ["--deblock", "0"])):
            s = os.path.join(tdir, "%s_%g" % (tag, rate))
            run([pifs, "encode", pgm, "-o", s + ".pifs", "--bpp", str(rate)] + extra)
            run([pifs, "decode", s + ".pifs", "-o", s + ".pgm"])
        sdec = read_gray(os.path.join(tdir, "stream_%g.pgm" % rate)).astype(np.float64)
        rows.append(dict(image=name, rate=rate, rule="stream", **measure(orig, sdec)))
        raw = os.path.join(tdir, "raw_%g" % rate)
        run([pifs, "info", raw + ".pifs", "--svg", raw + ".svg"])
        lv = leaves(raw + ".svg")
        dec = read_gray(raw + ".pgm").astype(np.float64)
        rows.append(dict(image=name, rate=rate, rule="raw", **measure(orig, dec)))
        for limit in limits:
            out = surface(dec, lv, min_size, limit, 2, dec)
            Image.fromarray(out.astype(np.uint8)).save(raw + "_surface%g.png" % limit)
            rows.append(dict(image=name, rate=rate, rule="raw + surface T=%g" % limit,
                             **measure(orig, out)))
            out = surface(sdec, lv, min_size, limit, 2, dec)
            rows.append(dict(image=name, rate=rate, rule="stream + surface T=%g" % limit,
                             **measure(orig, out)))
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--work", required=True)
    ap.add_argument("--pifs", default="target/release/pifs")
    ap.add_argument("--rates", type=float, nargs="+", default=[0.05, 0.1, 0.25])
    ap.add_argument("--min-size", type=int, default=8)
    ap.add_argument("--limits", default="4,8,16")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("images", nargs="+")
    a = ap.parse_args()
    limits = [float(v) for v in a.limits.split(",")]
    jobs = [(p, a.rates, a.work, os.path.abspath(a.pifs), a.min_size, limits) for p in a.images]
    rows = []
    with cf.ProcessPoolExecutor(a.jobs) as ex:
        for r in ex.map(bench, jobs):
            rows.extend(r)
    print("| rule | bpp | PSNR dB | SSIM | B_16 | B_16s |")
    print("|---|---:|---:|---:|---:|---:|")
    rules = []
    for r in rows:
        if r["rule"] not in rules:
            rules.append(r["rule"])
    for rate in a.rates:
        for rule in rules:
            sel = [r for r in rows if r["rule"] == rule and r["rate"] == rate]
            m = lambda k: np.nanmean([r[k] for r in sel])  # noqa: E731
            print("| %s | %g | %.3f | %.4f | %.3f | %.3f |" % (
                rule, rate, m("psnr"), m("ssim"), m("b16"), m("b16s")))


if __name__ == "__main__":
    main()
