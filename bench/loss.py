#!/usr/bin/env python3
"""Packets under loss on the Kodak set: what a receiver shows when packets are lost.

    python3 bench/loss.py [--colour] [--size 255] [--rates 0.1 0.25 0.5] [--work DIR]
                          [--pifs target/release/pifs] [--encode-args "..."] [--csv FILE]
                          [IMAGES...]

For each image and rate: `pifs encode --packets` (whole packet bytes counted against the
rate), then the receiver (`pifs decode` of a packet directory) after i.i.d. losses of 1, 5, 10
and 20 % (five seeds each, `pifs packets drop --loss P --seed S`, S drawn from the image's
name and the seed's number so that images cut into as many packets lose different packets) and
after bursty losses (10 %, mean burst 4: `--burst 4`), and after the first 1, 2, 4, 8 packets and the first 10 / 25 / 50 %
of them (the rest missing). PSNR against the original (gray: luma; --colour: RGB). Writes
bench/results/loss[-colour].csv and prints the means, the cost of packetisation in BD-rate
against the single stream of the same encoder (gray: its points in bench/results/kodak-pifs.csv,
colour: kodak-colour-pifs.csv, at the same rates), and SSDV's figures from
../shared/bench/ssdv/results-kodak24/summary.md beside ours.
"""
import argparse
import csv
import glob
import math
import os
import shutil
import statistics
import subprocess
import sys
import zlib

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.dirname(__file__))
from bd import bd  # noqa: E402

LOSSES = [0.01, 0.05, 0.1, 0.2]
SEEDS = [1, 2, 3, 4, 5]
BURST = (0.1, 4.0)
PREFIX_COUNTS = [1, 2, 4, 8]
PREFIX_SHARES = [0.1, 0.25, 0.5]


def image_seed(name, seed):
    """The loss pattern's seed for `name`'s `seed`-th draw: one pattern per image and draw (with
    the same seed for every image, images cut into as many packets would all lose the same
    ones, and five draws would stand for the whole image set)."""
    return zlib.crc32(name.encode()) % 1_000_000 * 10 + seed


def run(pifs, *args):
    out = subprocess.run([pifs, *args], capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"pifs {' '.join(args)}: {out.stderr.strip()}")
    return out.stdout


def load(path, colour):
    im = Image.open(path)
    im = im.convert("RGB" if colour else "L")
    return np.asarray(im, dtype=np.float64)


def psnr(a, b):
    mse = float(np.mean((a - b) ** 2))
    return float("inf") if mse == 0 else 10 * math.log10(255 * 255 / mse)


def decoded_psnr(pifs, packets_dir, original, colour, work):
    out = os.path.join(work, "decoded.png")
    run(pifs, "decode", packets_dir, "-o", out)
    return psnr(load(out, colour), original)


def subset(src, names, dst):
    shutil.rmtree(dst, ignore_errors=True)
    os.makedirs(dst)
    for n in names:
        shutil.copy(os.path.join(src, n), os.path.join(dst, n))


def measure(pifs, image, rate, args, work):
    colour = args.colour
    original = load(image, colour)
    name = os.path.splitext(os.path.basename(image))[0]
    packets = os.path.join(work, f"{name}-{rate}")
    shutil.rmtree(packets, ignore_errors=True)
    encode = ["encode", image, "--bpp", str(rate), "--packets", packets,
              "--packet-size", str(args.size)]
    if not colour:
        encode.append("--gray")
    encode += args.encode_args.split()
    run(pifs, *encode)
    names = sorted(os.listdir(packets))
    total = sum(os.path.getsize(os.path.join(packets, n)) for n in names)
    h, w = original.shape[:2]
    row = {"image": name, "rate": rate, "packets": len(names), "bytes": total,
           "bpp": total * 8 / (w * h)}
    row["psnr_0"] = decoded_psnr(pifs, packets, original, colour, work)
    lossy = os.path.join(work, "lossy")
    patterns = [(p, 1.0) for p in LOSSES] + [BURST]
    for loss, burst in patterns:
        values = []
        for seed in SEEDS:
            shutil.rmtree(lossy, ignore_errors=True)
            run(pifs, "packets", "drop", "--loss", str(loss), "--seed", str(image_seed(name, seed)),
                "--burst", str(burst), packets, lossy)
            if not os.listdir(lossy):
                values.append(float("nan"))
                continue
            values.append(decoded_psnr(pifs, lossy, original, colour, work))
        key = f"psnr_{loss}" + ("" if burst == 1.0 else f"_burst{burst:g}")
        row[key] = statistics.fmean(v for v in values if not math.isnan(v))
    prefix = os.path.join(work, "prefix")
    for k in PREFIX_COUNTS:
        subset(packets, names[:k], prefix)
        row[f"first_{k}"] = decoded_psnr(pifs, prefix, original, colour, work)
    for share in PREFIX_SHARES:
        k = max(1, math.ceil(share * len(names)))
        subset(packets, names[:k], prefix)
        row[f"first_{share:g}"] = decoded_psnr(pifs, prefix, original, colour, work)
    shutil.rmtree(packets, ignore_errors=True)
    return row


def single_stream_points(colour):
    path = os.path.join(os.path.dirname(__file__), "results",
                        "kodak-colour-pifs.csv" if colour else "kodak-pifs.csv")
    points = {}
    for r in csv.DictReader(open(path)):
        name = os.path.splitext(r["image"])[0]
        psnr_col = "psnr_rgb" if "psnr_rgb" in r else "psnr_db"
        if r.get(psnr_col):
            points.setdefault(name, {})[float(r["target_bpp"])] = (
                float(r["bpp"]), float(r[psnr_col]))
    return path, points


def ssdv_rows(colour):
    path = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "bench", "ssdv",
                        "results-kodak24", "summary.md")
    if not os.path.exists(path):
        return path, []
    lines = open(path).read().splitlines()
    title = "## colour, nofec packets" if colour else "## grey, nofec packets"
    start = next(i for i, l in enumerate(lines) if l.startswith(title))
    table = [l for l in lines[start + 2:] if l.startswith("|")]
    rows = []
    for line in table[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        if len(cells) < 11:
            break
        rows.append({"q": cells[0], "bpp": float(cells[4]), "psnr_0": float(cells[6]),
                     "drops": [float(c) for c in cells[7:11]]})
    prefix = next(i for i, l in enumerate(lines[start:], start) if l.startswith("Prefix"))
    ptable = [l for l in lines[prefix + 2:] if l.startswith("|")]
    for row, line in zip(rows, ptable[2:]):
        cells = [c.strip() for c in line.strip("|").split("|")]
        row["prefix"] = [float(c) for c in cells[1:4]]
    return path, rows


def packet_arguments(ap):
    """The options this script shares with packet_costs.py: colour, packet size, rates, the
    working directory and the `pifs` binary."""
    ap.add_argument("--colour", action="store_true")
    ap.add_argument("--size", type=int, default=255)
    ap.add_argument("--rates", type=float, nargs="+", default=[0.1, 0.25, 0.5])
    ap.add_argument("--work", default=None)
    ap.add_argument("--pifs", default="target/release/pifs")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    packet_arguments(ap)
    ap.add_argument("--encode-args", default="",
                    help="more options for `pifs encode` (such as --repeat-preview)")
    ap.add_argument("--csv", default=None, help="where the per-image rows go")
    ap.add_argument("images", nargs="*")
    args = ap.parse_args()
    images = args.images or sorted(glob.glob("../shared/images/kodak/kodim*.png"))
    work = args.work or os.path.join("target", "loss-bench")
    os.makedirs(work, exist_ok=True)
    rows = []
    for image in images:
        for rate in args.rates:
            row = measure(args.pifs, image, rate, args, work)
            rows.append(row)
            print(f"{row['image']} {rate}: {row['packets']} packets, {row['bpp']:.4f} bpp, "
                  f"{row['psnr_0']:.2f} dB, 10% loss {row['psnr_0.1']:.2f} dB, "
                  f"first 10% {row['first_0.1']:.2f} dB", file=sys.stderr, flush=True)
    out = args.csv or os.path.join("bench", "results",
                                   "loss-colour.csv" if args.colour else "loss.csv")
    with open(out, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        writer.writeheader()
        for r in rows:
            writer.writerow({k: (f"{v:.4f}" if isinstance(v, float) else v) for k, v in r.items()})
    report(rows, args, out)


def report(rows, args, out):
    kind = "colour, PSNR-RGB" if args.colour else "gray, PSNR of luma"
    n_images = len({r["image"] for r in rows})
    print(f"\nPackets of at most {args.size} bytes, {n_images} images ({kind}); "
          f"{out}. Drops are from each image's own loss-free PSNR, means over images and "
          f"{len(SEEDS)} seeds.\n")
    print("| codec | rate | packets | bpp | PSNR | drop 1% | drop 5% | drop 10% | drop 20% | "
          "drop 10% bursty | first 10% | first 25% | first 50% |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for rate in args.rates:
        rs = [r for r in rows if r["rate"] == rate]
        m = lambda k: statistics.fmean(r[k] for r in rs)  # noqa: E731
        drops = [m("psnr_0") - m(f"psnr_{p}") for p in LOSSES]
        burst = m("psnr_0") - m(f"psnr_{BURST[0]}_burst{BURST[1]:g}")
        print(f"| PIFS | {rate} | {m('packets'):.1f} | {m('bpp'):.3f} | {m('psnr_0'):.2f} | "
              + " | ".join(f"{d:.2f}" for d in drops)
              + f" | {burst:.2f} | "
              + " | ".join(f"{m(f'first_{s:g}'):.2f}" for s in PREFIX_SHARES) + " |")
    path, ssdv = ssdv_rows(args.colour)
    for s in ssdv[:3]:
        print(f"| SSDV q{s['q']} (no FEC) | | | {s['bpp']:.3f} | {s['psnr_0']:.2f} | "
              + " | ".join(f"{d:.2f}" for d in s["drops"]) + " | | "
              + " | ".join(f"{p:.2f}" for p in s.get("prefix", [])) + " |")
    if ssdv:
        print(f"\nSSDV: {os.path.normpath(path)} (its stored run; 256-byte packets).")
    print("\nFirst packets (in PIFS's sending order), mean PSNR:\n")
    print("| rate | " + " | ".join(f"first {k}" for k in PREFIX_COUNTS) + " |")
    print("|---|" + "---:|" * len(PREFIX_COUNTS))
    for rate in args.rates:
        rs = [r for r in rows if r["rate"] == rate]
        print(f"| {rate} | " + " | ".join(
            f"{statistics.fmean(r[f'first_{k}'] for r in rs):.2f}" for k in PREFIX_COUNTS) + " |")
    single_path, single = single_stream_points(args.colour)
    deltas = []
    for name in sorted({r["image"] for r in rows}):
        ours = [(r["bpp"], r["psnr_0"]) for r in rows if r["image"] == name]
        theirs = [single[name][rate] for rate in args.rates if rate in single.get(name, {})]
        if len(ours) >= 3 and len(theirs) >= 3:
            deltas.append(bd(ours, theirs))
    if deltas:
        rate_d = statistics.fmean(d[0] for d in deltas)
        psnr_d = statistics.fmean(d[1] for d in deltas)
        print(f"\nCost of packetisation against the single stream ({single_path}, same rates), "
              f"mean over {len(deltas)} images: BD-rate {rate_d:+.1f}%, BD-PSNR {psnr_d:+.2f} dB.")


if __name__ == "__main__":
    main()
