#!/usr/bin/env python3
"""Upscaling by the patches' own fractal detail, measured honestly (issue 24).

For every Kodak image (grayscale, BT.601 luma as `pifs` reads it): downscale it by 2 and by 4,
encode the small image with `pifs rd` at the given rates (bits per pixel of the small image),
then rebuild the full-size image three ways and measure PSNR against the full-size original:

- `pifs decode --scale 2|4` (the subdivision continued below the pixel);
- bicubic (Keys, a = -0.5) and Lanczos-3 upscaling of the normal decode (`--scale 1`).

The decoder treats a pixel as a sample at its grid point (the patch passes through it), so two
downscaling geometries are measured:

- `box`: each small pixel is the mean of its 2x2 (4x4) block, the usual thumbnail; its sample
  sits at the block's centre, half a small pixel from the decoder's grid point; bicubic and
  Lanczos use the same centre alignment (as image libraries do);
- `point`: each small pixel is a binomial low-pass of the full image centred on full pixel
  (2X, 2Y) ((1, 2, 1)/4 per axis and factor 2, applied twice for 4): the grid the decoder
  assumes; bicubic and Lanczos use the same point alignment.

    python3 bench/upscale.py [--rates 0.5,2] [--factors 2,4] [--pifs target/release/pifs]
                             [--out bench/results/upscale.csv] [IMAGES...]

Needs numpy and Pillow. Prints a markdown table of mean PSNR and, per setting, on how many
images the fractal upscale beats each interpolation; writes one CSV row per image and setting.
"""
import argparse
import csv
import glob
import os
import subprocess
import sys
import tempfile

import numpy as np
from PIL import Image


def luma(path):
    rgb = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0
    y = 0.299 * rgb[..., 0] + 0.587 * rgb[..., 1] + 0.114 * rgb[..., 2]
    return np.clip(np.round(y * 255.0), 0, 255)


def write_pgm(path, img):
    h, w = img.shape
    with open(path, "wb") as f:
        f.write(b"P5\n%d %d\n255\n" % (w, h))
        f.write(np.clip(np.round(img), 0, 255).astype(np.uint8).tobytes())


def read_pgm(path):
    with open(path, "rb") as f:
        data = f.read()
    # Four whitespace-separated fields (magic, width, height, maxval), then one whitespace byte.
    fields, pos = [], 0
    while len(fields) < 4:
        while data[pos:pos + 1].isspace():
            pos += 1
        start = pos
        while not data[pos:pos + 1].isspace():
            pos += 1
        fields.append(data[start:pos])
    w, h = int(fields[1]), int(fields[2])
    pixels = data[pos + 1:pos + 1 + w * h]
    return np.frombuffer(pixels, dtype=np.uint8).reshape(h, w).astype(np.float64)


def downscale(img, factor, geometry):
    if geometry == "box":
        h, w = img.shape
        return img[: h - h % factor, : w - w % factor].reshape(
            h // factor, factor, w // factor, factor).mean(axis=(1, 3))
    # point: binomial low-pass centred on even pixels, then decimation, per halving.
    out = img
    while factor > 1:
        padded = np.pad(out, 1, mode="reflect")
        rows = (padded[:-2] + 2 * padded[1:-1] + padded[2:]) / 4
        both = (rows[:, :-2] + 2 * rows[:, 1:-1] + rows[:, 2:]) / 4
        out = both[::2, ::2]
        factor //= 2
    return out


def kernel(name, x):
    x = np.abs(x)
    if name == "bicubic":
        a = -0.5
        return np.where(x < 1, (a + 2) * x**3 - (a + 3) * x**2 + 1,
                        np.where(x < 2, a * x**3 - 5 * a * x**2 + 8 * a * x - 4 * a, 0.0))
    # lanczos3
    return np.where(x < 3, np.sinc(x) * np.sinc(x / 3), 0.0)


def resample_axis(img, n_out, factor, name, geometry, axis):
    """Upsamples along `axis` to `n_out` samples: output i sits at input position
    (i + 0.5) / factor - 0.5 (centre alignment, box) or i / factor (point alignment)."""
    img = np.moveaxis(img, axis, 0)
    n_in = img.shape[0]
    i = np.arange(n_out)
    pos = (i + 0.5) / factor - 0.5 if geometry == "box" else i / factor
    radius = 2 if name == "bicubic" else 3
    base = np.floor(pos).astype(int)
    out = np.zeros((n_out,) + img.shape[1:])
    total = np.zeros(n_out)
    for k in range(-radius + 1, radius + 1):
        j = base + k
        wgt = kernel(name, pos - j)
        j = np.clip(j, 0, n_in - 1)  # edges: repeat the last sample
        out += wgt[:, None] * img[j]
        total += wgt
    out /= total[:, None]
    return np.moveaxis(out, 0, axis)


def upscale(img, factor, shape, name, geometry):
    rows = resample_axis(img, shape[0], factor, name, geometry, 0)
    return np.clip(np.round(resample_axis(rows, shape[1], factor, name, geometry, 1)), 0, 255)


def psnr(a, b):
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rates", default="0.5,2")
    ap.add_argument("--factors", default="2,4")
    ap.add_argument("--geometries", default="box,point")
    ap.add_argument("--pifs", default="target/release/pifs")
    ap.add_argument("--out", default="bench/results/upscale.csv")
    ap.add_argument("images", nargs="*")
    args = ap.parse_args()
    images = args.images or sorted(glob.glob("../shared/images/kodak/kodim*.png"))
    rates = [float(r) for r in args.rates.split(",")]
    factors = [int(f) for f in args.factors.split(",")]
    geometries = args.geometries.split(",")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for path in images:
            name = os.path.splitext(os.path.basename(path))[0]
            full = luma(path)
            for geometry in geometries:
                for factor in factors:
                    small = downscale(full, factor, geometry)
                    shape = (small.shape[0] * factor, small.shape[1] * factor)
                    ref = full[: shape[0], : shape[1]]
                    stem = f"{name}-{geometry}-{factor}"
                    pgm = os.path.join(tmp, stem + ".pgm")
                    write_pgm(pgm, small)
                    subprocess.run([args.pifs, "rd", pgm, "--rates", ",".join(map(str, rates)),
                                    "--out-dir", tmp], check=True, capture_output=True)
                    for rate in rates:
                        stream = os.path.join(tmp, f"{stem}-{rate:g}bpp.pifs")
                        if not os.path.exists(stream):
                            cands = glob.glob(os.path.join(tmp, f"{stem}-*{rate:g}*bpp.pifs"))
                            stream = cands[0]
                        results = {}
                        out = os.path.join(tmp, "out.pgm")
                        subprocess.run([args.pifs, "decode", stream, "-o", out, "--scale",
                                        str(factor)], check=True, capture_output=True)
                        results["pifs"] = psnr(read_pgm(out), ref)
                        subprocess.run([args.pifs, "decode", stream, "-o", out], check=True,
                                       capture_output=True)
                        decoded = read_pgm(out)
                        results["small"] = psnr(decoded, small)
                        for kname in ["bicubic", "lanczos3"]:
                            results[kname] = psnr(upscale(decoded, factor, shape, kname, geometry), ref)
                        results["bicubic_of_original"] = psnr(
                            upscale(small, factor, shape, "bicubic", geometry), ref)
                        row = dict(image=name, geometry=geometry, factor=factor, rate=rate,
                                   bytes=os.path.getsize(stream), **{k: round(v, 3) for k, v in results.items()})
                        rows.append(row)
                        print(row, file=sys.stderr)
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    print("| geometry | factor | bpp (small image) | PSNR of the small decode | PIFS x{f} | bicubic | Lanczos-3 | PIFS beats bicubic | PIFS beats Lanczos | bicubic of the uncoded small image |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for geometry in geometries:
        for factor in factors:
            for rate in rates:
                sel = [r for r in rows if r["geometry"] == geometry and r["factor"] == factor and r["rate"] == rate]
                mean = lambda k: sum(r[k] for r in sel) / len(sel)
                win_b = sum(r["pifs"] > r["bicubic"] for r in sel)
                win_l = sum(r["pifs"] > r["lanczos3"] for r in sel)
                print(f"| {geometry} | {factor} | {rate:g} | {mean('small'):.2f} | {mean('pifs'):.2f} | "
                      f"{mean('bicubic'):.2f} | {mean('lanczos3'):.2f} | {win_b}/{len(sel)} | {win_l}/{len(sel)} | "
                      f"{mean('bicubic_of_original'):.2f} |")


if __name__ == "__main__":
    main()
