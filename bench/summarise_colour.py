#!/usr/bin/env python3
"""Per-rate means of a colour sweep (bench/kodak-colour.sh's CSV) beside the anchors' means of
PSNR-RGB (and PSNR-YCbCr 6:1:1) over the same images, from the per-image tables of
kodak-colour-anchors.md (`### Per image: PSNR-RGB`; PSNR-YCbCr is only available as the
anchors' mean over all images, shown when the sweep covers all of them).

    python3 bench/summarise_colour.py SWEEP.csv [ANCHORS.md]
"""
import csv
import re
import sys
from collections import defaultdict


def anchors_per_image(path):
    """{codec: {image: {rate: (psnr, bpp)}}} from the per-image PSNR-RGB tables."""
    out = defaultdict(dict)
    try:
        text = open(path).read()
    except OSError:
        return out
    part = text.split("### Per image: PSNR-RGB", 1)
    if len(part) < 2:
        return out
    codec = None
    rates = []
    for line in part[1].splitlines():
        if line.startswith("### "):
            break
        m = re.match(r"#### (\S+)", line)
        if m:
            codec = m.group(1)
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if codec and cells and cells[0] == "image":
            rates = [float(c) for c in cells[1:]]
            continue
        if codec and cells and cells[0].endswith(".png"):
            row = {}
            for r, c in zip(rates, cells[1:]):
                m = re.match(r"([\d.]+) \(([\d.]+)\)", c)
                if m:
                    row[r] = (float(m.group(1)), float(m.group(2)))
            out[codec][cells[0]] = row
    return out


def main():
    rows = [r for r in csv.DictReader(open(sys.argv[1])) if r["psnr_rgb"]]
    anchors = anchors_per_image(sys.argv[2]) if len(sys.argv) > 2 else {}
    by_rate = defaultdict(list)
    for r in rows:
        by_rate[float(r["target_bpp"])].append(r)
    codecs = sorted(anchors)
    head = "| bpp | images | PIFS PSNR-RGB | PIFS bpp | PIFS PSNR-YCbCr 6:1:1 | chroma share |"
    head += "".join(f" {c} PSNR-RGB |" for c in codecs)
    print(head)
    print("|" + "---:|" * (6 + len(codecs)))
    for rate in sorted(by_rate):
        rs = by_rate[rate]
        n = len(rs)
        mean = lambda k: sum(float(r[k]) for r in rs) / n
        line = f"| {rate} | {n} | {mean('psnr_rgb'):.2f} | {mean('bpp'):.3f} | {mean('psnr_ycbcr611'):.2f} | {100 * mean('chroma_share'):.1f}% |"
        for c in codecs:
            vals = [anchors[c].get(r["image"], {}).get(rate) for r in rs]
            got = [v[0] for v in vals if v]
            line += f" {sum(got) / len(got):.2f} [{len(got)}/{n}] |" if got else " - |"
        print(line)


if __name__ == "__main__":
    main()
