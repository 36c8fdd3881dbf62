#!/usr/bin/env python3
"""seam_crops.py - side-by-side crops for judging leaf edges by eye: the original, PIFS before
and after a change, and JPEG 2000 at the same bytes as the PIFS stream after it, each crop
enlarged (nearest neighbour) and labelled above the panels.

    python3 bench/seam_crops.py --before OLD_PIFS --after NEW_PIFS --bpp 0.05 \
        --box X,Y,W,H [--zoom 2] [--before-args "ARGS"] [--after-args "ARGS"] IMAGE OUT.png

--before-args / --after-args: more options for that side's `pifs encode` (one binary can be
both sides: `--before-args "--stripe-width 512"`).

The image is taken as grayscale, or with --colour in colour (PPM in, PPM out; JPEG 2000 on
the RGB image). Needs numpy, Pillow and opj_compress / opj_decompress.
"""

import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np
from PIL import Image, ImageDraw

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from seams import j2k_at_bytes, psnr, read_gray  # noqa: E402


def read_rgb(path):
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.uint8)


def pifs(binary, pgm, bpp, tdir, tag, extra=(), read=read_gray):
    stream = os.path.join(tdir, tag + ".pifs")
    dec = os.path.join(tdir, tag + os.path.splitext(pgm)[1])
    subprocess.run([binary, "encode", pgm, "-o", stream, "--bpp", str(bpp), *extra], check=True,
                   stdout=subprocess.DEVNULL)
    subprocess.run([binary, "decode", stream, "-o", dec], check=True, stdout=subprocess.DEVNULL)
    return os.path.getsize(stream), read(dec)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("image")
    ap.add_argument("out")
    ap.add_argument("--before", required=True)
    ap.add_argument("--after", required=True)
    ap.add_argument("--bpp", type=float, required=True)
    ap.add_argument("--box", required=True, help="X,Y,W,H")
    ap.add_argument("--zoom", type=int, default=2)
    ap.add_argument("--before-args", default="")
    ap.add_argument("--after-args", default="")
    ap.add_argument("--colour", action="store_true")
    args = ap.parse_args()
    x, y, w, h = (int(v) for v in args.box.split(","))
    with tempfile.TemporaryDirectory() as tdir:
        read, mode, ext = (read_rgb, "RGB", ".ppm") if args.colour else (read_gray, "L", ".pgm")
        orig = read(args.image)
        pgm = os.path.join(tdir, "orig" + ext)
        Image.fromarray(orig, mode).save(pgm)
        b_bytes, before = pifs(args.before, pgm, args.bpp, tdir, "before",
                               args.before_args.split(), read)
        a_bytes, after = pifs(args.after, pgm, args.bpp, tdir, "after",
                              args.after_args.split(), read)
        j_bytes, j2k = j2k_at_bytes(pgm, a_bytes, tdir, read)
    panels = [("original", orig, None), ("PIFS before, %d B" % b_bytes, before, psnr(orig, before)),
              ("PIFS after, %d B" % a_bytes, after, psnr(orig, after)),
              ("JPEG 2000, %d B" % j_bytes, j2k, psnr(orig, j2k))]
    z, label_h, gap = args.zoom, 16, 4
    canvas = Image.new(mode, (len(panels) * (w * z + gap) - gap, h * z + label_h), "white")
    draw = ImageDraw.Draw(canvas)
    for k, (name, img, db) in enumerate(panels):
        crop = Image.fromarray(img[y:y + h, x:x + w], mode).resize((w * z, h * z), Image.NEAREST)
        left = k * (w * z + gap)
        canvas.paste(crop, (left, label_h))
        text = name if db is None else "%s, %.2f dB" % (name, db)
        draw.text((left + 2, 2), text, fill="black")
    canvas.save(args.out)
    print("%s: before %d B %.2f dB, after %d B %.2f dB, JPEG 2000 %d B %.2f dB" % (
        args.out, b_bytes, panels[1][2], a_bytes, panels[2][2], j_bytes, panels[3][2]))


if __name__ == "__main__":
    main()
