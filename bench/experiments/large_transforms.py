#!/usr/bin/env python3
"""large_transforms.py - issue 27 exploration, after format 21: would a 16 px pixel grid coded by
a 16-point DCT beat four 8 px pixel grids (the largest the format has) on the same 16 x 16
blocks? Codes every 16 x 16 block of the grayscale Kodak images both ways with the DCT (unit
norm basis), the same dead-zone quantiser and the same rate model as block_transforms.py (the
zero-order entropy of the indices at each position over all blocks), and prints, for the
blocks grouped by their activity (quartiles of the mean absolute difference between
neighbouring pixels), the bits each needs at equal PSNR. Not the codec (no prediction, no
rate/distortion rounding, no contexts, no subdivision surfaces for smooth blocks): the same
crude coder on both sides, so only the transform size differs. See docs/decisions.md.

    python3 bench/experiments/large_transforms.py [IMAGE...]   (default ../shared/images/kodak)

Needs numpy and Pillow.
"""

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from block_transforms import entropy_bits, image_blocks  # noqa: E402

STEPS = [3, 4, 6, 8, 12, 16, 24, 32, 48, 64]


def dct(n):
    """The orthonormal n-point DCT-II analysis matrix."""
    c = np.array([[np.cos(np.pi * (i + 0.5) * k / n) for i in range(n)] for k in range(n)])
    c[0] *= np.sqrt(1 / n)
    c[1:] *= np.sqrt(2 / n)
    return c


def code(blocks, n, step):
    """Bits and squared error of `blocks` (k x 16 x 16) coded as n x n DCT blocks."""
    k = len(blocks)
    sub = blocks.reshape(k, 16 // n, n, 16 // n, n).transpose(0, 1, 3, 2, 4).reshape(-1, n, n)
    a = dct(n)
    c = np.einsum("ij,bjk,lk->bil", a, sub, a)
    q = np.sign(c) * np.floor(np.abs(c) / step + 0.5 - 0.18)
    back = np.einsum("ji,bjk,kl->bil", a, q * step, a)
    return entropy_bits(q.reshape(len(q), -1)), ((back - sub) ** 2).sum()


def curve(blocks, n):
    """(bits per pixel, PSNR) at every step."""
    pixels = blocks.size
    out = []
    for step in STEPS:
        bits, sse = code(blocks, n, step)
        out.append((bits / pixels, 10 * np.log10(255**2 * pixels / sse)))
    return out


def bits_at(curve_points, psnr):
    """Bits per pixel at `psnr`, interpolated in log(bits) against PSNR."""
    pts = sorted(curve_points, key=lambda p: p[1])
    for (b0, p0), (b1, p1) in zip(pts, pts[1:]):
        if p0 <= psnr <= p1:
            t = (psnr - p0) / (p1 - p0)
            return float(np.exp(np.log(b0) + t * (np.log(b1) - np.log(b0))))
    return None


def main():
    blocks = image_blocks(sys.argv[1:], 16)
    x = np.concatenate(blocks) - 128.0
    activity = np.abs(np.diff(x, axis=1)).mean(axis=(1, 2)) + np.abs(np.diff(x, axis=2)).mean(
        axis=(1, 2)
    )
    edges = np.quantile(activity, [0.25, 0.5, 0.75])
    group = np.searchsorted(edges, activity)
    print(f"{len(blocks)} images, {len(x)} blocks of 16 x 16")
    print("| blocks (activity quartile) | PSNR (dB) | bpp, four 8-point DCTs | bpp, one 16-point DCT | change |")
    print("|---|---:|---:|---:|---:|")
    for g, name in enumerate(["smoothest", "second", "third", "busiest"]):
        b = x[group == g]
        eight, sixteen = curve(b, 8), curve(b, 16)
        for psnr in [30.0, 35.0, 40.0]:
            b8, b16 = bits_at(eight, psnr), bits_at(sixteen, psnr)
            if b8 is None or b16 is None:
                continue
            print(f"| {name} | {psnr:.0f} | {b8:.3f} | {b16:.3f} | {100 * (b16 / b8 - 1):+.1f}% |")


if __name__ == "__main__":
    main()
