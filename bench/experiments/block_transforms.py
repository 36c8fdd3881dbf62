#!/usr/bin/env python3
"""block_transforms.py - issue 27 exploration, before format 20: how much does the transform of
a leaf's grid matter? Codes every 8 x 8 block of the grayscale Kodak images with two
transforms, format 19's three-level 5/3 wavelet (LeGall, symmetric extension) and the DCT, both
with basis vectors scaled to unit norm, through the same dead-zone quantiser (rounding offset
0.32) and the same rate model (the zero-order entropy of the indices at each position over
all blocks), and prints bits per pixel and PSNR for each step. Not the codec (no prediction,
no rate/distortion rounding, no contexts): the same crude coder on both sides, so only the
transforms differ. See docs/decisions.md, "The grid transform: a DCT (format 20)".

    python3 bench/experiments/block_transforms.py [IMAGE...]   (default ../shared/images/kodak)

Needs numpy and Pillow.
"""

import glob
import os
import sys

import numpy as np
from PIL import Image

N = 8


def lifting_53(x):
    """One level of the real-valued 5/3 analysis of an even-length line: low band, high band."""
    even, odd = x[0::2], x[1::2]
    right = np.append(even[1:], even[-1])  # x[n] mirrored to x[n - 2]
    high = odd - 0.5 * (even + right)
    left = np.insert(high[:-1], 0, high[0])  # d[-1] mirrored to d[0]
    low = even + 0.25 * (left + high)
    return low, high


def wavelet_53(x):
    """The multi-level 5/3 of a line of N values, low band first (format 19's layout)."""
    bands = []
    low = x
    while len(low) > 1:
        low, high = lifting_53(low)
        bands.insert(0, high)
    return np.concatenate([low] + bands)


def matrix(transform):
    """The N x N analysis matrix of a 1-D transform."""
    return np.stack([transform(np.eye(N)[i]) for i in range(N)], axis=1)


def dct():
    c = np.array([[np.cos(np.pi * (i + 0.5) * k / N) for i in range(N)] for k in range(N)])
    c[0] *= np.sqrt(1 / N)
    c[1:] *= np.sqrt(2 / N)
    return c


def unit_norm(analysis):
    """The analysis matrix with its synthesis vectors scaled to unit norm, and that synthesis."""
    synthesis = np.linalg.inv(analysis)
    norms = np.linalg.norm(synthesis, axis=0)
    return analysis * norms[:, None], synthesis / norms[None, :]


def entropy_bits(indices):
    bits = 0.0
    for p in range(indices.shape[1]):
        _, counts = np.unique(indices[:, p], return_counts=True)
        bits -= (counts * np.log2(counts / counts.sum())).sum()
    return bits


def image_blocks(paths, n):
    """The n x n blocks of the grayscale images `paths` (the 24 Kodak images when none), one
    array of them per image."""
    paths = paths or sorted(
        glob.glob(os.path.join(os.path.dirname(__file__), "../../../shared/images/kodak/*.png"))
    )
    blocks = []
    for path in paths:
        image = np.asarray(Image.open(path).convert("L"), dtype=float)
        h, w = (s - s % n for s in image.shape)
        b = image[:h, :w].reshape(h // n, n, w // n, n).transpose(0, 2, 1, 3).reshape(-1, n, n)
        blocks.append(b)
    return blocks


def main():
    blocks = image_blocks(sys.argv[1:], N)
    x = np.concatenate(blocks) - 128.0
    print(f"{len(blocks)} images, {len(x)} blocks of {N} x {N}")
    print("| transform | step | bits per pixel | PSNR (dB) |")
    print("|---|---:|---:|---:|")
    for name, analysis in [("5/3 wavelet", matrix(wavelet_53)), ("DCT", dct())]:
        a, s = unit_norm(analysis)
        coefficients = np.einsum("ij,bjk,lk->bil", a, x, a)
        for step in [4, 8, 16, 32, 64]:
            q = np.sign(coefficients) * np.floor(np.abs(coefficients) / step + 0.5 - 0.18)
            back = np.einsum("ij,bjk,lk->bil", s, q * step, s)
            mse = ((back - x) ** 2).mean()
            bpp = entropy_bits(q.reshape(len(q), -1)) / x.size
            print(f"| {name} | {step} | {bpp:.3f} | {10 * np.log10(255**2 / mse):.2f} |")


if __name__ == "__main__":
    main()
