"""Bound of chroma ramps across chroma patch edges, on decoded colour pictures (issue 21).

For each luma leaf of a colour stream that lies along the top or left edge of its chroma node
(`cargo run --release -p host-encoder --example chroma_nodes -- S.pifs > S.nodes`), the
chroma step across that edge is taken from the decoded picture (Cb and Cr of the decoded RGB,
BT.601 full range, at full resolution) and the leaf's chroma is ramped towards the chroma
beside it: the first row (column) moves by a fraction `a` of the step, the correction falling
linearly to nothing `T` luma pixels into the leaf (`T = S * t`, `S` the luma leaf's side, at
most `tmax`). Kept inside the leaf that touches the edge, a ramp needs nothing a decoder
without a frame buffer lacks: the chroma frontier holds the chroma beside the leaf.
Steps larger than `L` chroma levels taper off to no correction at `4 L` (a colour edge, not a
seam). The RGB change is the chroma change through the BT.601
inverse, so a zero correction leaves the decode's pixels exactly as they were.

Prints, per rate, the mean PSNR-RGB and B_16 / B_32 / B_64 of the decoded Cb and Cr
(bench/experiments/chroma_seams.py's measure) without and with each setting, and how large
the grid's steps are in each plane: the mean absolute step across the lines of the 32-pixel
grid less the mean step elsewhere, in levels of Y, Cb and Cr (a ratio such as B_g makes
chroma's steps look large because flat chroma patches vary little between the lines).

    python3 bench/experiments/chroma_ramps.py DIR ORIGINALS_DIR

docs/decisions.md ("Leaf edges: what did not work", chroma ramps) quotes it on kodim01, 03,
05, 13, 19 and 23 made by `pifs encode kodimNN.png -o DIR/kNN_R.pifs --bpp R` and `pifs decode
DIR/kNN_R.pifs -o DIR/kNN_R.png` at 0.05, 0.1 and 0.25 bpp. DIR holds, for each image NAME and rate R, NAME_R.pifs's decode NAME_R.png and its chroma
nodes NAME_R.nodes (kNN_R for kodimNN). Needs numpy and Pillow.
"""
import glob
import math
import os
import sys

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.dirname(__file__))
from chroma_seams import grid_measure, grid_steps, ycc  # noqa: E402


def taper(d, limit):
    m = np.abs(d)
    w = np.where(m <= limit, 1.0, np.clip((4 * limit - m) / (3 * limit), 0, 1))
    return d * w


def edges(nodes):
    """The luma leaves that lie along their chroma node's top or left edge: (x, y, side, top,
    left) in luma pixels."""
    out = []
    node = None
    for kind, x, y, s in nodes:
        if kind == "C":
            node = (2 * x, 2 * y)
        else:
            out.append((x, y, s, y == node[1], x == node[0]))
    return out


def ramps(planes, nodes, a, t, tmax, limit):
    h, w = planes[0].shape
    delta = [np.zeros((h, w)), np.zeros((h, w))]
    for x0, y0, side, top, left in edges(nodes):
        x1, y1 = min(x0 + side, w), min(y0 + side, h)
        n = max(1, min(int(side * t), tmax))
        fall = 1 - np.arange(n) / n
        for p in (0, 1):
            c = planes[p]
            if top and y0 > 0:
                d = taper(c[y0, x0:x1] - c[y0 - 1, x0:x1], limit)
                k = min(n, y1 - y0)
                delta[p][y0:y0 + k, x0:x1] -= a * fall[:k, None] * d[None, :]
            if left and x0 > 0:
                d = taper(c[y0:y1, x0] - c[y0:y1, x0 - 1], limit)
                k = min(n, x1 - x0)
                delta[p][y0:y1, x0:x0 + k] -= a * fall[None, :k] * d[:, None]
    return delta


def apply(rgb, delta):
    cb, cr = delta
    out = rgb.astype(np.float64)
    out[..., 0] += 1.402 * cr
    out[..., 1] += -0.344136 * cb - 0.714136 * cr
    out[..., 2] += 1.772 * cb
    return np.clip(np.rint(out), 0, 255)


def excess(p, g=32):
    """Mean absolute step across the lines of a g-pixel grid less the mean step elsewhere."""
    on, off = grid_steps(p, g)
    return on - off


def psnr(a, b):
    mse = max(np.mean((a.astype(float) - b.astype(float)) ** 2), 1e-12)
    return 10 * math.log10(255 ** 2 / mse)


SETTINGS = [
    # (a, t, tmax, limit)
    (0.5, 0.5, 16, 1e9),
    (0.75, 0.25, 16, 1e9),
    (0.75, 0.5, 16, 1e9),
    (0.75, 0.5, 16, 16),
    (1.0, 0.25, 16, 1e9),
    (1.0, 0.5, 16, 1e9),
]


def main():
    work, originals = sys.argv[1], sys.argv[2]
    files = sorted(glob.glob(os.path.join(work, "*.nodes")))
    by_rate = {}
    for f in files:
        stem = os.path.basename(f)[:-6]
        name, rate = stem.rsplit("_", 1)
        by_rate.setdefault(float(rate), []).append((name, f[:-6]))
    for rate in sorted(by_rate):
        rows = []
        for name, base in by_rate[rate]:
            orig = np.asarray(Image.open(os.path.join(originals, name.replace("k", "kodim") + ".png")).convert("RGB"))
            dec = np.asarray(Image.open(base + ".png").convert("RGB"))
            nodes = [(k, *map(int, v)) for k, *v in (line.split() for line in open(base + ".nodes"))]
            planes = ycc(dec)[1:]
            row = []
            for setting in [None] + SETTINGS:
                if setting is None:
                    out = dec
                else:
                    out = apply(dec, ramps(planes, nodes, *setting))
                yc = ycc(out)
                row.append([psnr(orig, out)] + [grid_measure(yc[c], g) for c in (1, 2) for g in (16, 32, 64)]
                           + [excess(yc[c]) for c in (0, 1, 2)])
            rows.append(row)
        m = np.mean(np.array(rows), axis=0)
        print(f"{rate} bpp ({len(rows)} images): PSNR-RGB, Cb B_16/32/64, Cr B_16/32/64")
        for setting, r in zip([None] + SETTINGS, m):
            label = "decoded" if setting is None else "a %.2f t %.2f tmax %d L %g" % (
                setting[0], setting[1], setting[2], setting[3])
            print(f"  {label:36s} {r[0]:.3f}  {r[1]:.2f} {r[2]:.2f} {r[3]:.2f}  {r[4]:.2f} {r[5]:.2f} {r[6]:.2f}"
                  f"  excess steps Y / Cb / Cr {r[7]:.2f} / {r[8]:.2f} / {r[9]:.2f}")


if __name__ == "__main__":
    main()
