#!/usr/bin/env python3
"""Per-rate means of an rd_sweep CSV: mean PSNR, mean actual bpp, images reaching the rate,
median analysis and per-target encode times."""
import csv
import statistics
import sys
from collections import defaultdict

rows = list(csv.DictReader(open(sys.argv[1])))
by_rate = defaultdict(list)
for r in rows:
    by_rate[float(r["target_bpp"])].append(r)
images = {r["image"] for r in rows}
analysis = {r["image"]: float(r["analysis_s"]) for r in rows}
print(f"\n{len(images)} images; median analysis {statistics.median(analysis.values()):.2f} s")
print("| target bpp | mean PSNR (dB) | mean bpp | reached | median encode per target (s) | median decode (ms) |")
print("|---:|---:|---:|---:|---:|---:|")
for rate in sorted(by_rate):
    ok = [r for r in by_rate[rate] if r["psnr_db"]]
    if not ok:
        print(f"| {rate} | - | - | 0/{len(by_rate[rate])} | - | - |")
        continue
    mp = statistics.mean(float(r["psnr_db"]) for r in ok)
    mb = statistics.mean(float(r["bpp"]) for r in ok)
    me = statistics.median(float(r["encode_s"]) for r in ok)
    md = statistics.median(float(r["decode_ms"]) for r in ok)
    print(f"| {rate} | {mp:.2f} | {mb:.4f} | {len(ok)}/{len(by_rate[rate])} | {me:.2f} | {md:.1f} |")
