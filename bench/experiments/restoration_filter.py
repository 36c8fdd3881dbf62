#!/usr/bin/env python3
"""restoration_filter.py - issue 27 exploration: what would a restoration filter after the
decoder buy (a Wiener filter fitted per image by least squares, as AV1's loop restoration and
VVC's adaptive loop filter fit theirs)? A bound on decoded pictures, not part of the codec (see
docs/decisions.md, "A restoration filter after the decoder: measured, not built").

Inputs, with any build of `pifs` (grayscale, the Kodak images):

    pifs rd --gray kodimNN.png --rates 0.1,0.25,0.5 --out-dir DIR/kNN
    pifs decode DIR/kNN/kodimNN-Rbpp.pifs -o DIR/kNN/kodimNN-Rbpp.pgm      (each stream)
    python3 bench/experiments/restoration_filter.py [--images ../shared/images/kodak] DIR/k*

For each decode, filters fitted on the decode against the original (BT.601 luma, as `pifs`
reads it) and applied to it; the mean PSNR change per rate:

- one point-symmetric filter per image on a 3x3, a 5-tap diamond (radius 2), a 5x5 or a
  7-tap diamond (radius 3) support, with an offset, coefficients unquantised;
- 15 classes per image (ALF-like: 5 activity levels by the 3x3 sum of the horizontal and
  vertical Laplacians, times 3 directions), one filter each (diamond5 and 5x5), unquantised;
- the same diamond5 classes in a form that keeps the mean (the correction is a sum of the
  pairs' second differences, no offset), coefficients rounded to 1/64, with what signalling
  them would cost (1 bit a class plus Exp-Golomb bits of each coefficient) against the
  stream's bytes.

Needs numpy and Pillow.
"""

import argparse
import glob
import os
import re

import numpy as np
from PIL import Image

SHAPES = {
    "3x3": [(0, 1), (1, 0), (1, 1), (1, -1)],
    "diamond5": [(0, 1), (0, 2), (1, 0), (2, 0), (1, 1), (1, -1)],
    "5x5": [(dy, dx) for dy in range(0, 3) for dx in range(-2, 3) if (dy, dx) > (0, 0)],
    "diamond7": [(dy, dx) for dy in range(0, 4) for dx in range(-3, 4)
                 if (dy, dx) > (0, 0) and abs(dy) + abs(dx) <= 3],
}
CLASSES = 15
MIN_CLASS = 200


def shifted(img, dy, dx):
    p = np.pad(img, 4, mode="edge")
    h, w = img.shape
    return p[4 + dy:4 + dy + h, 4 + dx:4 + dx + w]


def features(d, taps):
    """The centre, then each symmetric pair's sum."""
    cols = [d] + [shifted(d, dy, dx) + shifted(d, -dy, -dx) for dy, dx in taps]
    return np.stack([c.ravel() for c in cols], axis=1)


def classes(d):
    lap_h = np.abs(2 * d - shifted(d, 0, 1) - shifted(d, 0, -1))
    lap_v = np.abs(2 * d - shifted(d, 1, 0) - shifted(d, -1, 0))
    box = lambda a: sum(shifted(a, y, x) for y in (-1, 0, 1) for x in (-1, 0, 1))
    gh, gv = box(lap_h), box(lap_v)
    activity = np.digitize((gh + gv) / 9.0, [0.5, 2, 5, 10])
    direction = np.where(gh > 2 * gv, 1, np.where(gv > 2 * gh, 2, 0))
    return (activity * 3 + direction).ravel()


def psnr(out, orig):
    out = np.clip(np.round(out), 0, 255).reshape(orig.shape)
    return 10 * np.log10(255.0 ** 2 / np.mean((out - orig) ** 2))


def least_squares(X, y, cls, n_cls):
    out = X[:, 0].copy()
    for c in range(n_cls):
        m = cls == c
        if m.sum() < MIN_CLASS:
            continue
        A = np.concatenate([X[m], np.ones((m.sum(), 1))], axis=1)
        sol, *_ = np.linalg.lstsq(A, y[m], rcond=None)
        out[m] = A @ sol
    return out


def quantised(X, y, cls):
    """Mean-keeping classes, coefficients in 1/64: the picture and the bits to send them."""
    second = X[:, 1:] - 2 * X[:, :1]
    out, bits = X[:, 0].copy(), 0
    for c in range(CLASSES):
        m = cls == c
        bits += 1
        if m.sum() < MIN_CLASS:
            continue
        sol, *_ = np.linalg.lstsq(second[m], y[m] - X[m, 0], rcond=None)
        q = np.round(sol * 64).astype(int)
        bits += sum(2 * int(np.floor(np.log2(2 * abs(v) + 1))) + 1 for v in q)
        out[m] = X[m, 0] + second[m] @ (q / 64)
    return out, bits / 8


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--images", default="../shared/images/kodak")
    ap.add_argument("dirs", nargs="+")
    args = ap.parse_args()
    rows = {}
    for d in args.dirs:
        for f in sorted(glob.glob(os.path.join(d, "*.pgm"))):
            m = re.match(r"(kodim\d+)-([0-9.]+)bpp\.pgm", os.path.basename(f))
            if not m:
                continue
            name, rate = m.group(1), m.group(2)
            orig = np.asarray(Image.open(os.path.join(args.images, name + ".png")).convert("L"),
                              dtype=np.float64)
            dec = np.asarray(Image.open(f), dtype=np.float64)
            y = orig.ravel()
            r = {"none": psnr(dec, orig)}
            one = np.zeros(len(y), int)
            for shape, taps in SHAPES.items():
                r[shape] = psnr(least_squares(features(dec, taps), y, one, 1), orig)
            cls = classes(dec)
            for shape in ("diamond5", "5x5"):
                X = features(dec, SHAPES[shape])
                r[f"{shape}/15"] = psnr(least_squares(X, y, cls, CLASSES), orig)
            out, filter_bytes = quantised(features(dec, SHAPES["diamond5"]), y, cls)
            r["diamond5/15/q64"] = psnr(out, orig)
            r["filter_bytes"] = filter_bytes
            r["stream_bytes"] = os.path.getsize(f[:-4] + ".pifs")
            rows.setdefault(rate, []).append(r)
            print(name, rate, " ".join(f"{k}={v:.3f}" for k, v in r.items()), flush=True)
    for rate, rs in sorted(rows.items(), key=lambda kv: float(kv[0])):
        mean = lambda k: np.mean([x[k] for x in rs])
        gains = "  ".join(f"{k} {mean(k) - mean('none'):+.3f}" for k in rs[0]
                          if k not in ("none", "filter_bytes", "stream_bytes"))
        print(f"{rate} bpp, {len(rs)} images: {mean('none'):.3f} dB; {gains}; "
              f"filters {mean('filter_bytes'):.1f} of {mean('stream_bytes'):.0f} bytes")


if __name__ == "__main__":
    main()
