#!/usr/bin/env python3
"""seam_crops.py - side-by-side crops for judging leaf edges by eye: the original, PIFS before
and after a change, and JPEG 2000 at the same bytes as the PIFS stream after it, each crop
enlarged (nearest neighbour) and labelled above the panels.

    python3 bench/seam_crops.py --before OLD_PIFS --after NEW_PIFS --bpp 0.05 \
        --box X,Y,W,H [--zoom 2] [--before-decoder OLD_PIFS] IMAGE OUT.png

The image is taken as grayscale. Needs numpy, Pillow and opj_compress / opj_decompress.
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


def pifs(binary, pgm, bpp, tdir, tag):
    stream = os.path.join(tdir, tag + ".pifs")
    dec = os.path.join(tdir, tag + ".pgm")
    subprocess.run([binary, "encode", pgm, "-o", stream, "--bpp", str(bpp)], check=True,
                   stdout=subprocess.DEVNULL)
    subprocess.run([binary, "decode", stream, "-o", dec], check=True, stdout=subprocess.DEVNULL)
    return os.path.getsize(stream), read_gray(dec)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("image")
    ap.add_argument("out")
    ap.add_argument("--before", required=True)
    ap.add_argument("--after", required=True)
    ap.add_argument("--bpp", type=float, required=True)
    ap.add_argument("--box", required=True, help="X,Y,W,H")
    ap.add_argument("--zoom", type=int, default=2)
    args = ap.parse_args()
    x, y, w, h = (int(v) for v in args.box.split(","))
    with tempfile.TemporaryDirectory() as tdir:
        orig = read_gray(args.image)
        pgm = os.path.join(tdir, "orig.pgm")
        Image.fromarray(orig, "L").save(pgm)
        b_bytes, before = pifs(args.before, pgm, args.bpp, tdir, "before")
        a_bytes, after = pifs(args.after, pgm, args.bpp, tdir, "after")
        j_bytes, j2k = j2k_at_bytes(pgm, a_bytes, tdir)
    panels = [("original", orig, None), ("PIFS before, %d B" % b_bytes, before, psnr(orig, before)),
              ("PIFS after, %d B" % a_bytes, after, psnr(orig, after)),
              ("JPEG 2000, %d B" % j_bytes, j2k, psnr(orig, j2k))]
    z, label_h, gap = args.zoom, 16, 4
    canvas = Image.new("L", (len(panels) * (w * z + gap) - gap, h * z + label_h), 255)
    draw = ImageDraw.Draw(canvas)
    for k, (name, img, db) in enumerate(panels):
        crop = Image.fromarray(img[y:y + h, x:x + w], "L").resize((w * z, h * z), Image.NEAREST)
        left = k * (w * z + gap)
        canvas.paste(crop, (left, label_h))
        text = name if db is None else "%s, %.2f dB" % (name, db)
        draw.text((left + 2, 2), text, fill=0)
    canvas.save(args.out)
    print("%s: before %d B %.2f dB, after %d B %.2f dB, JPEG 2000 %d B %.2f dB" % (
        args.out, b_bytes, panels[1][2], a_bytes, panels[2][2], j_bytes, panels[3][2]))


if __name__ == "__main__":
    main()
