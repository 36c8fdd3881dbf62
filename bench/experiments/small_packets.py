"""Packets of small pictures: the 24 Kodak images scaled to 240x160 (portrait ones 160x240,
Pillow's Lanczos filter, as bench/small.sh), sent as packets of at most 255 bytes (or SIZE)
at byte budgets of 0.25, 0.5 and 1.0 bpp by one or more `pifs` binaries. For each: the
packets and bytes sent, mean PSNR-RGB with every packet, with 10% and 20% of them lost (`pifs
packets drop --loss L --seed S`, seeds 1-5, each image's own patterns; a pattern that loses
everything is left out) and from the first packet alone.

    python3 bench/experiments/small_packets.py WORKDIR NAME=PIFS[,SIZE[,ARGS]] [NAME=...]

ARGS: more `pifs encode` options for that binary, separated by spaces (`--expect-loss 0.1`).

docs/decisions.md quotes it with the binaries before and after a change ("Packets": what
whole packets leave of a budget; "Parity shards without the repeated fields"). Needs numpy
and Pillow.
"""
import concurrent.futures as cf
import glob
import math
import os
import shutil
import subprocess
import sys

import numpy as np
from PIL import Image

RATES = (0.25, 0.5, 1.0)
LOSSES = (0.1, 0.2)
SEEDS = range(1, 6)


def psnr(a, b):
    return 10 * math.log10(255 ** 2 / np.mean((a - b) ** 2))


def small_images(work):
    out = os.path.join(work, "images")
    os.makedirs(out, exist_ok=True)
    for path in sorted(glob.glob(os.path.join(os.path.dirname(__file__),
                                              "../../../shared/images/kodak/kodim*.png"))):
        image = Image.open(path).convert("RGB")
        size = (240, 160) if image.width >= image.height else (160, 240)
        image.resize(size, Image.LANCZOS).save(os.path.join(out, os.path.basename(path)))
    return sorted(glob.glob(os.path.join(out, "*.png")))


def one(work, name, pifs, image, rate):
    pifs, _, rest = pifs.partition(",")
    size, _, extra = rest.partition(",")
    original = np.asarray(Image.open(image).convert("RGB")).astype(float)
    w, h = Image.open(image).size
    base = os.path.join(work, f"{name}_{os.path.basename(image)[:-4]}_{rate}")
    run = lambda *args: subprocess.run([pifs, *args], check=True, capture_output=True)
    try:
        run("encode", image, "--bytes", str(int(rate * w * h / 8)), "--packets", base,
            "--packet-size", size or "255", *extra.split())
    except subprocess.CalledProcessError:
        return name, rate, None  # refused (a budget too small for its packets)
    packets = sorted(os.listdir(base))

    def decoded(directory):
        run("decode", directory, "-o", directory + ".png")
        return psnr(original, np.asarray(Image.open(directory + ".png").convert("RGB")).astype(float))

    first = base + "_first"
    os.makedirs(first)
    shutil.copy(os.path.join(base, packets[0]), first)
    row = {"packets": len(packets),
           "bytes": sum(os.path.getsize(os.path.join(base, p)) for p in packets),
           "all": [decoded(base)], "first": [decoded(first)]}
    for loss in LOSSES:
        row[loss] = []
        for seed in SEEDS:
            kept = f"{base}_{loss}_{seed}"
            run("packets", "drop", "--loss", str(loss), "--seed", str(seed), base, kept)
            if os.listdir(kept):
                row[loss].append(decoded(kept))
    return name, rate, row


def main():
    work = sys.argv[1]
    binaries = dict(arg.split("=", 1) for arg in sys.argv[2:])
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    images = small_images(work)
    jobs = [(n, p, i, r) for n, p in binaries.items() for r in RATES for i in images]
    with cf.ThreadPoolExecutor(2) as ex:
        rows = list(ex.map(lambda j: one(work, *j), jobs))
    for rate in RATES:
        for name in binaries:
            rs = [row for n, r, row in rows if n == name and r == rate and row]
            refused = sum(1 for n, r, row in rows if n == name and r == rate and not row)
            if refused:
                print(f"{rate} bpp {name}: {refused} images refused, the means are over the rest")
            if not rs:
                continue
            mean = lambda key: np.mean([v for row in rs for v in (row[key] if isinstance(row[key], list) else [row[key]])])
            print(f"{rate} bpp {name}: {mean('packets'):.1f} packets, {mean('bytes'):.0f} bytes; "
                  f"PSNR-RGB every packet {mean('all'):.2f}, 10% lost {mean(0.1):.2f}, "
                  f"20% lost {mean(0.2):.2f}, first packet {mean('first'):.2f} dB")


if __name__ == "__main__":
    main()
