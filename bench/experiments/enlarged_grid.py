#!/usr/bin/env python3
"""enlarged_grid.py - enlarged decodes (`pifs decode --scale 2`) of half-size colour pictures:
PSNR-RGB against the full-size original and the grid measure B_g (bench/seams.py's: the mean
step across the lines of a g-pixel grid over the mean step elsewhere) of their luma, for
several `pifs` binaries, beside bicubic upscaling of the normal decode. Each Kodak image is
halved (2 x 2 means), coded with the first binary (`pifs encode SMALL --bpp R`), and decoded at
2x by each. With --crop X,Y,W,H, also writes WORK/crop_NAME_R.png for each image and rate:
the original, each binary's enlarged decode and the bicubic one side by side, at 2x zoom.

    python3 bench/experiments/enlarged_grid.py WORK 0.1,0.25,0.5 [--crop X,Y,W,H] \
        before=PIFS_BEFORE after=PIFS -- ../shared/images/kodak/kodim23.png ...

Needs numpy and Pillow.
"""
import os
import subprocess
import sys

import numpy as np
from PIL import Image


def b_g(y, g):
    y = y.astype(np.float64)
    dx = np.abs(np.diff(y, axis=1))
    dy = np.abs(np.diff(y, axis=0))
    on_x = (np.arange(1, y.shape[1]) % g) == 0
    on_y = (np.arange(1, y.shape[0]) % g) == 0
    across = np.concatenate([dx[:, on_x].ravel(), dy[on_y, :].ravel()])
    other = np.concatenate([dx[:, ~on_x].ravel(), dy[~on_y, :].ravel()])
    return across.mean() / other.mean()


def luma(rgb):
    return 0.299 * rgb[..., 0] + 0.587 * rgb[..., 1] + 0.114 * rgb[..., 2]


def psnr(a, b):
    mse = np.mean((a.astype(float) - b.astype(float)) ** 2)
    return float("inf") if mse == 0 else 10 * np.log10(255.0 ** 2 / mse)


def main():
    work, rates = sys.argv[1], [float(r) for r in sys.argv[2].split(",")]
    split = sys.argv.index("--")
    args = sys.argv[3:split]
    crop = None
    if args and args[0] == "--crop":
        crop = [int(v) for v in args[1].split(",")]
        args = args[2:]
    binaries = dict(a.split("=", 1) for a in args)
    images = sys.argv[split + 1:]
    os.makedirs(work, exist_ok=True)
    rows = {}
    first = next(iter(binaries.values()))
    for image in images:
        name = os.path.splitext(os.path.basename(image))[0]
        orig = Image.open(image).convert("RGB")
        small = orig.reduce(2)
        sp = os.path.join(work, name + "_small.png")
        small.save(sp)
        o = np.asarray(orig, dtype=np.float64)
        for rate in rates:
            s = os.path.join(work, f"{name}_{rate}.pifs")
            subprocess.run([first, "encode", sp, "-o", s, "--bpp", str(rate)], check=True,
                           capture_output=True)
            one = os.path.join(work, f"{name}_{rate}_x1.png")
            subprocess.run([first, "decode", s, "-o", one], check=True, capture_output=True)
            bic = np.asarray(Image.open(one).resize(orig.size, Image.BICUBIC), dtype=np.float64)
            results = {"bicubic": bic}
            for label, pifs in binaries.items():
                out = os.path.join(work, f"{name}_{rate}_{label}.png")
                subprocess.run([pifs, "decode", s, "--scale", "2", "-o", out], check=True,
                               capture_output=True)
                results[label] = np.asarray(Image.open(out).convert("RGB"), dtype=np.float64)
            results["original"] = o
            if crop:
                x, y, w, h = crop
                order = ["original"] + list(binaries) + ["bicubic"]
                sheet = Image.new("RGB", (len(order) * 2 * w, 2 * h))
                for k, label in enumerate(order):
                    part = Image.fromarray(np.clip(results[label], 0, 255).astype(np.uint8))
                    part = part.crop((x, y, x + w, y + h)).resize((2 * w, 2 * h), Image.NEAREST)
                    sheet.paste(part, (k * 2 * w, 0))
                sheet.save(os.path.join(work, f"crop_{name}_{rate}.png"))
            for label, img in results.items():
                y = luma(img)
                r = rows.setdefault((rate, label), [])
                r.append((psnr(img, o), b_g(y, 16), b_g(y, 32)))
    for (rate, label), r in sorted(rows.items()):
        m = np.mean(r, axis=0)
        print(f"{rate} bpp {label:10s} PSNR-RGB {m[0]:.3f}  B_16 {m[1]:.3f}  B_32 {m[2]:.3f}  ({len(r)})")


if __name__ == "__main__":
    main()
