"""A symmetric ramp across leaf edges as a post-filter of decoded colour pictures (issue 21),
a bound on what a decoder with a frame buffer could do that decoder-core cannot (it does not
change pixels it has drawn): at every edge between two luma leaves of at least 8 px, the luma
step across it (steps above 6 levels tapering off to none at 18: an edge of the picture) is
spread over a linear ramp of up to 16 px on each side (half the smaller leaf), half of it on
either side; chroma is left alone. Prints PSNR-RGB before and after, and writes crops
(original / decoded / filtered) for judging by eye.

    python3 bench/experiments/leaf_ramps_post.py DIR OUTDIR

DIR as bench/experiments/chroma_ramps.py's: kNN_R.png decodes and kNN_R.nodes (the
`chroma_nodes` example's leaves); it uses kodim03 at 0.1 and 0.25 bpp and kodim23 at 0.05.
Needs numpy and Pillow.
"""
import math
import os
import sys

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.dirname(__file__))
from chroma_seams import ycc  # noqa: E402

TMAX, LIMIT, MIN_SIDE = 16, 6.0, 8


def leaves_of(path):
    return [tuple(map(int, v)) for k, *v in (line.split() for line in open(path)) if k == "L"]


def ramp(plane, leaves):
    h, w = plane.shape
    owner = np.full((h, w), -1, int)
    for i, (x, y, s) in enumerate(leaves):
        owner[y:min(y + s, h), x:min(x + s, w)] = i
    delta = np.zeros_like(plane)

    def spread(step, side_a, side_b, at_after, at_before):
        if side_b < MIN_SIDE:
            return
        n = min(side_a, side_b, 2 * TMAX) // 2
        m = abs(step)
        step *= 1.0 if m <= LIMIT else max(0.0, (3 * LIMIT - m) / (2 * LIMIT))
        for d in range(n):
            f = 0.5 * (1 - (d + 0.5) / n)
            delta[at_after(d)] -= step * f
            delta[at_before(d)] += step * f

    for x, y, s in leaves:
        if s < MIN_SIDE:
            continue
        if x > 0:
            for yy in range(y, min(y + s, h)):
                spread(plane[yy, x] - plane[yy, x - 1], s, leaves[owner[yy, x - 1]][2],
                       lambda d: (yy, x + d), lambda d: (yy, x - 1 - d))
        if y > 0:
            for xx in range(x, min(x + s, w)):
                spread(plane[y, xx] - plane[y - 1, xx], s, leaves[owner[y - 1, xx]][2],
                       lambda d: (y + d, xx), lambda d: (y - 1 - d, xx))
    return plane + delta


def main():
    work, out = sys.argv[1], sys.argv[2]
    os.makedirs(out, exist_ok=True)
    here = os.path.dirname(__file__)
    for name, rate, box in (("k03", 0.1, (150, 0, 400, 130)), ("k03", 0.25, (150, 0, 400, 130)),
                            ("k23", 0.05, (300, 0, 700, 200))):
        base = os.path.join(work, f"{name}_{rate}")
        decoded = np.asarray(Image.open(base + ".png").convert("RGB")).astype(float)
        original = np.asarray(Image.open(os.path.join(
            here, "../../../shared/images/kodak", name.replace("k", "kodim") + ".png")).convert("RGB")).astype(float)
        luma = ycc(decoded)[0]
        filtered = np.clip(np.rint(decoded + (ramp(luma, leaves_of(base + ".nodes")) - luma)[..., None]), 0, 255)
        psnr = lambda a: 10 * math.log10(255 ** 2 / np.mean((original - a) ** 2))
        print(f"{name} {rate} bpp: PSNR-RGB {psnr(decoded):.3f} -> {psnr(filtered):.3f} dB")
        w, h = box[2] - box[0], box[3] - box[1]
        sheet = Image.new("RGB", (6 * w + 8, 2 * h), "white")
        for i, image in enumerate((original, decoded, filtered)):
            crop = Image.fromarray(image[box[1]:box[3], box[0]:box[2]].astype(np.uint8))
            sheet.paste(crop.resize((2 * w, 2 * h), Image.NEAREST), (i * (2 * w + 4), 0))
        sheet.save(os.path.join(out, f"{name}_{rate}.png"))


if __name__ == "__main__":
    main()
