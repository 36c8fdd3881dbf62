#!/usr/bin/env python3
"""Concealment of lost blocks dispersed over the image (issue 23's design experiment).

    PIFS=target/release/pifs python3 bench/experiments/dispersed_blocks.py RATE LOSS IMAGE...

For each IMAGE (gray): the single stream at RATE bpp (`pifs encode --gray --bpp RATE`) stands
for what every packet gives, a 236-byte whole-image stream (`--bytes 236`) for the preview.
Blocks of B x B pixels (B = 16, 32, 64, 128) are lost at random, each with probability LOSS
(seeds 1-5), and filled with the preview, with the received pixels interpolated across them
(along the row and the column between the nearest received pixels, averaged: the reference
receiver's rule), and with the preview plus the interpolated difference between the received
pixels and the preview. Prints the mean PSNR drop against the full decode per block size and
fill.
"""
import os, sys, subprocess, numpy as np
from PIL import Image
PIFS = os.environ.get("PIFS", "target/release/pifs")
WORK = os.environ.get("WORK", "target/dispersed")
os.makedirs(WORK, exist_ok=True)

def lininterp(vals, mask):
    out = np.zeros_like(vals); wt = np.zeros_like(vals)
    for axis in (0, 1):
        V = vals if axis == 1 else vals.T
        M = mask if axis == 1 else mask.T
        O = np.zeros_like(V); Wt = np.zeros_like(V)
        x = np.arange(V.shape[1])
        for i in range(V.shape[0]):
            idx = np.nonzero(M[i])[0]
            if len(idx) == 0 or len(idx) == V.shape[1]:
                if len(idx): O[i] = V[i]; Wt[i] = 1
                continue
            O[i] = np.interp(x, idx, V[i, idx]); Wt[i] = 1
        if axis == 0: O = O.T; Wt = Wt.T
        out += O; wt += Wt
    r = out / np.maximum(wt, 1)
    return np.where(mask, vals, r)

def psnr(a, b): return 10 * np.log10(255 ** 2 / np.mean((a - b) ** 2))

rate, loss, images = sys.argv[1], float(sys.argv[2]), sys.argv[3:]
sizes = [16, 32, 64, 128]
fills = ["preview", "interp", "preview+interp"]
drops = {(b, f): [] for b in sizes for f in fills}
for img in images:
    name = os.path.splitext(os.path.basename(img))[0]
    orig = np.asarray(Image.open(img).convert('L'), dtype=float)
    full_s, prev_s = f"{WORK}/{name}-{rate}.pifs", f"{WORK}/{name}-prev.pifs"
    for s, arg in ((full_s, ["--bpp", rate]), (prev_s, ["--bytes", "236"])):
        if not os.path.exists(s):
            subprocess.run([PIFS, "encode", img, "--gray", *arg, "-o", s], check=True, capture_output=True)
        subprocess.run([PIFS, "decode", s, "-o", s + ".png"], check=True, capture_output=True)
    full = np.asarray(Image.open(full_s + ".png"), dtype=float)
    prev = np.asarray(Image.open(prev_s + ".png"), dtype=float)
    p_full = psnr(full, orig)
    H, W = orig.shape
    for b in sizes:
        for seed in range(1, 6):
            rng = np.random.default_rng(seed)
            lost = rng.random(((H + b - 1) // b, (W + b - 1) // b)) < loss
            mask = ~np.kron(lost, np.ones((b, b), bool))[:H, :W]  # True where received
            got = {
                "preview": np.where(mask, full, prev),
                "interp": lininterp(full, mask),
                "preview+interp": prev + lininterp(full - prev, mask),
            }
            for f in fills:
                drops[(b, f)].append(p_full - psnr(np.clip(got[f], 0, 255), orig))
    print(name, f"{p_full:.2f} dB", flush=True)
print(f"| block | " + " | ".join(fills) + " |")
print("|---:|" + "---:|" * len(fills))
for b in sizes:
    print(f"| {b} | " + " | ".join(f"{np.mean(drops[(b, f)]):.2f}" for f in fills) + " |")
