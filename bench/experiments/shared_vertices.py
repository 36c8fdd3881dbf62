"""Bound of large leaves made continuous through shared corners, as a post-filter with a frame
buffer (issue 21). In each plane (luma with the stream's luma leaves, Cb and Cr with its chroma
nodes, both from `cargo run --release -p host-encoder --example chroma_nodes -- S.pifs`), every
leaf of at least MIN_SIDE pixels has the bilinear surface through four corner values fitted
to its decoded pixels (least squares); a corner shared only by such leaves, whose fits there
are within LIMIT grey levels of each other, takes their mean, and each leaf moves by the
bilinear surface of its corners' changes. Two such leaves then meet without a step along an
edge whose ends are both shared; corners beside small leaves or across an edge of the picture
(fits further apart than LIMIT) stay. Prints PSNR-RGB before and after and writes crops
(original / decoded / filtered) at 2x.

    python3 bench/experiments/shared_vertices.py DECODED.png ORIGINAL.png NODES MIN_SIDE LIMIT \
        X0 Y0 X1 Y1 OUT.png

docs/decisions.md ("Leaf edges: what did not work", shared corners) runs it on kodim23 at 0.05
bpp and kodim03 at 0.1 bpp (`pifs encode kodimNN.png --bpp R`, `pifs decode`). Needs numpy
and Pillow.
"""
import math
import os
import sys

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.dirname(__file__))
from chroma_seams import ycc  # noqa: E402
from plane_swap import psnr, rgb, sheet  # noqa: E402


def read_nodes(path):
    """(luma leaves, chroma nodes), both as (x, y, side) in luma pixels."""
    leaves, chroma = [], []
    for kind, *v in (line.split() for line in open(path)):
        x, y, s = map(int, v)
        if kind == "L":
            leaves.append((x, y, s))
        else:
            chroma.append((2 * x, 2 * y, 2 * s))
    return leaves, chroma


def bilinear_basis(s):
    u = (np.arange(s) + 0.5) / s
    uu, vv = np.meshgrid(u, u)
    return np.stack([(1 - uu) * (1 - vv), uu * (1 - vv), (1 - uu) * vv, uu * vv], -1).reshape(-1, 4)


def continuous(plane, leaves, min_side, limit):
    h, w = plane.shape
    out = plane.copy()
    inside = lambda x, y, s: s >= min_side and x + s <= w and y + s <= h
    beside_small = np.zeros((h + 1, w + 1), bool)
    for x, y, s in leaves:
        if not inside(x, y, s):
            beside_small[y:min(y + s, h) + 1, x:min(x + s, w) + 1] = True
    fits, votes = {}, {}
    for x, y, s in (leaf for leaf in leaves if inside(*leaf)):
        basis = bilinear_basis(s)
        corners, *_ = np.linalg.lstsq(basis, plane[y:y + s, x:x + s].reshape(-1), rcond=None)
        fits[(x, y, s)] = (corners, basis)
        for vertex, value in zip(((x, y), (x + s, y), (x, y + s), (x + s, y + s)), corners):
            votes.setdefault(vertex, []).append(value)
    shared = {v: float(np.mean(vals)) for v, vals in votes.items()
              if not beside_small[v[1], v[0]] and len(vals) > 1 and max(vals) - min(vals) <= limit}
    for (x, y, s), (corners, basis) in fits.items():
        vertices = ((x, y), (x + s, y), (x, y + s), (x + s, y + s))
        new = np.array([shared.get(v, c) for v, c in zip(vertices, corners)])
        out[y:y + s, x:x + s] += (basis @ (new - corners)).reshape(s, s)
    return out


def main():
    decoded = np.asarray(Image.open(sys.argv[1]).convert("RGB")).astype(np.float64)
    original = np.asarray(Image.open(sys.argv[2]).convert("RGB")).astype(np.float64)
    leaves, chroma = read_nodes(sys.argv[3])
    min_side, limit = int(sys.argv[4]), float(sys.argv[5])
    box = tuple(int(v) for v in sys.argv[6:10])
    y, cb, cr = ycc(decoded)
    filtered = rgb(continuous(y, leaves, min_side, limit), continuous(cb, chroma, min_side, limit),
                   continuous(cr, chroma, min_side, limit))
    print(f"min side {min_side}, limit {limit}: PSNR-RGB {psnr(decoded, original):.3f} -> "
          f"{psnr(filtered, original):.3f} dB")
    sheet([original, decoded, filtered], box, sys.argv[10], columns=3)


if __name__ == "__main__":
    main()
