#!/usr/bin/env python3
"""display.py - how a decoded picture looks on a panel of fewer levels, dithered or not.

For each image: `pifs encode IMAGE --bpp R` (colour as colour), `pifs decode` (the picture),
then `pifs decode --display PANEL --dither ordered|nearest` (the picture as decoder-core's
embedded-graphics adapter draws it on an RGB565, 16-grey, 4-grey or 1-bit panel, written back
as 8 bits). Against the picture: the plain PSNR (pixel by pixel) and the PSNR of both blurred by
a Gaussian of deviation SIGMA pixels (what an eye a little way off sees: shades, not pixels;
dithering trades the one for the other). RGB panels in PSNR-RGB of the colour decode, gray
panels against its luma. Prints a markdown table of the means.

    python3 bench/display.py [--pifs target/release/pifs] [--bpp 0.25] [--sigma 1.5]
        --work DIR IMAGE...

Needs numpy and Pillow.
"""

import argparse
import math
import os
import subprocess

import numpy as np
from PIL import Image

PANELS = ("rgb565", "gray4", "gray2", "mono")


def blur(a, sigma):
    """Separable Gaussian blur of a 2-D array (radius 3 sigma, edges repeated)."""
    r = max(1, int(math.ceil(3 * sigma)))
    k = np.exp(-(np.arange(-r, r + 1) ** 2) / (2 * sigma * sigma))
    k /= k.sum()
    p = np.pad(a.astype(np.float64), r, mode="edge")
    p = sum(k[i] * p[i:i + p.shape[0] - 2 * r, :] for i in range(2 * r + 1))
    return sum(k[i] * p[:, i:i + p.shape[1] - 2 * r] for i in range(2 * r + 1))


def psnr(a, b):
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10 * math.log10(255.0 ** 2 / mse)


def planes(img):
    a = np.asarray(img, dtype=np.float64)
    return [a] if a.ndim == 2 else [a[..., c] for c in range(a.shape[2])]


def run(cmd):
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--pifs", default="target/release/pifs")
    ap.add_argument("--bpp", default="0.25")
    ap.add_argument("--sigma", type=float, default=1.5)
    ap.add_argument("--work", required=True)
    ap.add_argument("images", nargs="+")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    rows = {}
    for path in a.images:
        name = os.path.splitext(os.path.basename(path))[0]
        stream = os.path.join(a.work, name + ".pifs")
        picture = os.path.join(a.work, name + ".png")
        run([a.pifs, "encode", path, "-o", stream, "--bpp", a.bpp])
        run([a.pifs, "decode", stream, "-o", picture])
        for panel in PANELS:
            mode = "RGB" if panel.startswith("rgb") else "L"
            ref = planes(Image.open(picture).convert(mode))
            for dither in ("nearest", "ordered"):
                out = os.path.join(a.work, "%s_%s_%s.png" % (name, panel, dither))
                run([a.pifs, "decode", stream, "-o", out, "--display", panel, "--dither", dither])
                shown = planes(Image.open(out).convert(mode))
                plain = psnr(np.stack(ref), np.stack(shown))
                seen = psnr(np.stack([blur(p, a.sigma) for p in ref]),
                            np.stack([blur(p, a.sigma) for p in shown]))
                rows.setdefault((panel, dither), []).append((plain, seen))
    print("| panel | levels | PSNR, pixel by pixel (dB) | PSNR, both blurred (sigma %g) (dB) |"
          % a.sigma)
    print("|---|---|---:|---:|")
    for (panel, dither), v in rows.items():
        v = np.array(v)
        print("| %s | %s | %.2f | %.2f |" % (panel, dither, v[:, 0].mean(), v[:, 1].mean()))


if __name__ == "__main__":
    main()
