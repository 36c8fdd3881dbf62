"""Which plane makes the squares of a colour decode (issue 21): crops of the original, the
decode, the decoded luma with the original chroma, and the original luma with the decoded
chroma, at 2x, side by side (BT.601 full range both ways); then the decode with Gaussian grain
of deviation 1 and 2 grey levels added to its luma (a fixed seed), with PSNR-RGB. Prints, in
the crop, the mean absolute step of each plane (Y, Cb, Cr) across the vertical lines of the
64-pixel grid, decoded and original.

    python3 bench/experiments/plane_swap.py DECODED.png ORIGINAL.png X0 Y0 X1 Y1 OUT_PREFIX

docs/decisions.md ("Leaf edges: what did not work", where the squares are by plane) runs it on
`pifs encode kodim23.png --bpp 0.05` (box 0 300 200 512) and `pifs encode kodim03.png --bpp
0.1` (box 150 0 450 150), each decoded by `pifs decode`. Needs numpy and Pillow.
"""
import math
import os
import sys

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.dirname(__file__))
from chroma_seams import ycc  # noqa: E402


def rgb(y, cb, cr):
    return np.clip(np.rint(np.stack([y + 1.402 * (cr - 128),
                                     y - 0.344136 * (cb - 128) - 0.714136 * (cr - 128),
                                     y + 1.772 * (cb - 128)], -1)), 0, 255)


def psnr(a, b):
    return 10 * math.log10(255 ** 2 / max(np.mean((a - b) ** 2), 1e-12))


def sheet(images, box, path, columns=2, zoom=2):
    x0, y0, x1, y1 = box
    w, h = (x1 - x0) * zoom, (y1 - y0) * zoom
    rows = (len(images) + columns - 1) // columns
    out = Image.new("RGB", (columns * (w + 4), rows * (h + 4)), "white")
    for i, image in enumerate(images):
        crop = Image.fromarray(image[y0:y1, x0:x1].astype(np.uint8)).resize((w, h), Image.NEAREST)
        out.paste(crop, ((i % columns) * (w + 4), (i // columns) * (h + 4)))
    out.save(path)


def main():
    decoded_path, original_path = sys.argv[1], sys.argv[2]
    box = tuple(int(v) for v in sys.argv[3:7])
    prefix = sys.argv[7]
    decoded = np.asarray(Image.open(decoded_path).convert("RGB")).astype(np.float64)
    original = np.asarray(Image.open(original_path).convert("RGB")).astype(np.float64)
    yd, cbd, crd = ycc(decoded)
    yo, cbo, cro = ycc(original)
    sheet([original, decoded, rgb(yd, cbo, cro), rgb(yo, cbd, crd)], box, prefix + "_planes.png")
    x0, y0, x1, y1 = box
    for name, d, o in (("Y", yd, yo), ("Cb", cbd, cbo), ("Cr", crd, cro)):
        lines = [x for x in range(x0 + 1, x1) if x % 64 == 0]
        step = lambda p: np.mean([np.abs(p[y0:y1, x] - p[y0:y1, x - 1]).mean() for x in lines])
        print(f"{name}: mean |step| across the 64-px lines of the box, decoded {step(d):.2f}, "
              f"original {step(o):.2f}")
    rng = np.random.default_rng(1)
    grained = [decoded]
    for sigma in (1.0, 2.0):
        grain = rng.normal(0.0, sigma, decoded.shape[:2])[..., None]
        grained.append(np.clip(np.rint(decoded + grain), 0, 255))
    for sigma, image in zip((0.0, 1.0, 2.0), grained):
        print(f"grain {sigma}: PSNR-RGB {psnr(image, original):.3f} dB")
    sheet([original] + grained, box, prefix + "_grain.png")


if __name__ == "__main__":
    main()
