"""Chroma seams of colour PIFS decodes: mean PSNR-RGB and the grid measure B_8 / B_16 on the
Cb and Cr planes (and on Y) of the decoded RGB, and B_32 / B_64, over a set of images at target bit rates.
B_g is bench/seams.py's measure (the mean absolute step across the lines of a g-pixel grid
over the mean step elsewhere), taken here on the full-resolution planes of the decode
converted with BT.601 full range; the Kodak originals measure 0.97-1.00. Chroma leaves start
on multiples of 4 and 8 luma pixels or more, so B_8 and B_16 see their edges; the large chroma
patches of smooth areas at low rates show in B_32 and B_64.

docs/decisions.md ("Leaf edges: what did not work", chroma edge pull) quotes it, run on an
experiment build (chroma_edge_pull.patch, on commit 39f9023; its PIFS_PULL and PIFS_PULL_NUM
environment variables set the strength and the fraction, in sixths):

    python3 bench/experiments/chroma_seams.py target/release/pifs WORKDIR 0.05 0.1 0.25 -- \
        ../shared/images/kodak/kodim{01,03,05,13,19,23}.png

With `original` for the pifs binary it measures the originals' planes (their PSNR is then
meaningless): about 1 at every grid, an image not knowing the grid.

Needs numpy and Pillow.
"""
import concurrent.futures as cf
import math
import os
import subprocess
import sys

import numpy as np
from PIL import Image


def ycc(a):
    a = a.astype(np.float64)
    r, g, b = a[..., 0], a[..., 1], a[..., 2]
    return [0.299 * r + 0.587 * g + 0.114 * b,
            128 - 0.168736 * r - 0.331264 * g + 0.5 * b,
            128 + 0.5 * r - 0.418688 * g - 0.081312 * b]


GRIDS = (8, 16, 32, 64)


def grid_steps(p, g):
    """Mean absolute step between neighbouring pixels across the lines of a g-pixel grid, and
    elsewhere."""
    dx = np.abs(np.diff(p, axis=1))
    dy = np.abs(np.diff(p, axis=0))
    mx = np.arange(1, p.shape[1]) % g == 0
    my = np.arange(1, p.shape[0]) % g == 0
    on = (dx[:, mx].sum() + dy[my, :].sum()) / (mx.sum() * p.shape[0] + my.sum() * p.shape[1])
    off = (dx[:, ~mx].sum() + dy[~my, :].sum()) / ((~mx).sum() * p.shape[0] + (~my).sum() * p.shape[1])
    return on, off


def grid_measure(p, g):
    on, off = grid_steps(p, g)
    return on / off


def one(pifs, work, img, rate):
    a = np.asarray(Image.open(img).convert("RGB"))
    if pifs == "original":
        b = a
    else:
        out = os.path.join(work, f"{os.path.basename(img)[:-4]}_{rate}")
        subprocess.run([pifs, "encode", img, "-o", out + ".pifs", "--bpp", str(rate)],
                       check=True, capture_output=True)
        subprocess.run([pifs, "decode", out + ".pifs", "-o", out + ".png"], check=True,
                       capture_output=True)
        b = np.asarray(Image.open(out + ".png").convert("RGB"))
    mse = max(np.mean((a.astype(float) - b.astype(float)) ** 2), 1e-12)
    planes = ycc(b)
    return rate, [10 * math.log10(255 ** 2 / mse)] + [
        grid_measure(planes[c], g) for c in (1, 2, 0) for g in GRIDS]


def main():
    pifs, work = sys.argv[1], sys.argv[2]
    split = sys.argv.index("--")
    rates = [float(r) for r in sys.argv[3:split]]
    images = sys.argv[split + 1:]
    os.makedirs(work, exist_ok=True)
    with cf.ThreadPoolExecutor(2) as ex:
        rows = list(ex.map(lambda t: one(pifs, work, *t), [(i, r) for r in rates for i in images]))
    for rate in rates:
        m = np.mean([r for q, r in rows if q == rate], axis=0)
        n = len(GRIDS)
        planes = "  ".join(
            name + " " + " ".join(f"B_{g} {m[1 + k * n + j]:.3f}" for j, g in enumerate(GRIDS))
            for k, name in enumerate(("Cb", "Cr", "Y")))
        print(f"{rate} bpp: PSNR-RGB {m[0]:.3f}  {planes}")


if __name__ == "__main__":
    main()
