#!/usr/bin/env python3
"""Summarises an rd_sweep CSV: per target rate, mean PSNR and mean actual bpp of PIFS beside the
anchor codecs' means from ../shared/bench/kodak-anchors.md (when present), and encode/decode
times.

    python3 bench/summarise.py bench/results/kodak-pifs.csv [anchors.md]
"""
import csv
import os
import re
import statistics
import sys
from collections import defaultdict

rows = [r for r in csv.DictReader(open(sys.argv[1])) if r.get("target_bpp") and r.get("rate_gap_pct") is not None]
anchors_path = sys.argv[2] if len(sys.argv) > 2 else os.path.join(
    os.path.dirname(__file__), "..", "..", "shared", "bench", "kodak-anchors.md")

# First table of the anchors file: "| target bpp | jpeg | jpeg2000 | webp | avif |".
anchors = {}
codecs = []
if os.path.exists(anchors_path):
    lines = open(anchors_path).read().splitlines()
    for i, line in enumerate(lines):
        if line.startswith("| target bpp |"):
            codecs = [c.strip() for c in line.strip("|").split("|")[1:]]
            for row in lines[i + 2:]:
                if not row.startswith("|"):
                    break
                cells = [c.strip() for c in row.strip("|").split("|")]
                anchors[float(cells[0])] = [re.sub(r"\s*\(.*", "", c) + (" " + re.search(r"\[.*\]", c).group(0) if "[" in c else "") for c in cells[1:]]
            break

by_rate = defaultdict(list)
for r in rows:
    by_rate[float(r["target_bpp"])].append(r)
images = {r["image"] for r in rows}
# One analysis per image and leaf depth (rd_sweep analyses the rates that want 2 px leaves apart).
analysis = defaultdict(dict)
for r in rows:
    analysis[r.get("min_leaf_px", "?")][r["image"]] = float(r["analysis_s"])
print(f"\n{len(images)} images")
for leaf, times in sorted(analysis.items()):
    rates = sorted({float(r["target_bpp"]) for r in rows if r.get("min_leaf_px", "?") == leaf})
    print(f"analysis with leaves from {leaf} px (for {', '.join(map(str, rates))} bpp): median "
          f"{statistics.median(times.values()):.2f} s (min {min(times.values()):.2f}, max {max(times.values()):.2f})")
print()
head = "| target bpp | PIFS mean PSNR (dB) | PIFS mean bpp | reached |" + "".join(f" {c} |" for c in codecs)
print(head)
print("|---:" * (4 + len(codecs)) + "|")
for rate in sorted(by_rate):
    ok = [r for r in by_rate[rate] if r["psnr_db"]]
    extra = "".join(f" {a} |" for a in anchors.get(rate, ["-"] * len(codecs)))
    if not ok:
        print(f"| {rate} | - | - | 0/{len(by_rate[rate])} |{extra}")
        continue
    mp = statistics.mean(float(r["psnr_db"]) for r in ok)
    mb = statistics.mean(float(r["bpp"]) for r in ok)
    print(f"| {rate} | {mp:.2f} | {mb:.4f} | {len(ok)}/{len(by_rate[rate])} |{extra}")
print()
print("| target bpp | median encode per extra target (s) | median decode (ms) | mean rate-estimate gap (%) |")
print("|---:|---:|---:|---:|")
for rate in sorted(by_rate):
    ok = [r for r in by_rate[rate] if r["psnr_db"]]
    if ok:
        me = statistics.median(float(r["encode_s"]) for r in ok)
        md = statistics.median(float(r["decode_ms"]) for r in ok)
        gap = statistics.mean(float(r["rate_gap_pct"]) for r in ok)
        print(f"| {rate} | {me:.2f} | {md:.1f} | {gap:+.2f} |")
