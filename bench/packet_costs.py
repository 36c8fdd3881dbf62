#!/usr/bin/env python3
"""Where the cost of packets goes: the BD-rate of a packet set against the single stream, with
its bytes counted whole, without the packets' headers and checksums, and without those nor the
preview packet (what is left is the regions' own coding: fresh contexts, nothing predicted
across a region's edge, leaves cut at its edges).

    python3 bench/packet_costs.py [--colour] [--size 255] [--rates 0.1 0.25 0.5] [--work DIR]
                                  [--pifs target/release/pifs] [IMAGES...]

For each image and rate: `pifs encode --packets DIR --bpp R --packet-size SIZE [--gray]`, every
packet's header and checksum measured by parsing it (docs/bitstream.md, section 9), then the
whole set decoded (`pifs decode DIR`) for its PSNR (gray: luma; --colour: RGB). The single
stream's points are bench/results/kodak-pifs.csv (colour: kodak-colour-pifs.csv) at the same
rates; the Bjontegaard delta is bench/loss.py's. Default images: the 24 of
../shared/images/kodak. Needs numpy and Pillow.
"""

import argparse
import glob
import os
import statistics
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loss  # noqa: E402


def varint(data, at):
    """An unsigned LEB128 value of at most three bytes at `at`: (value, next offset)."""
    value, shift = 0, 0
    for k in range(3):
        b = data[at + k]
        value |= (b & 0x7F) << shift
        shift += 7
        if b < 0x80:
            return value, at + k + 1
    raise ValueError("varint longer than three bytes")


def overhead(packet):
    """Bytes of a packet that are not its payload: header fields and checksum; and whether it is
    the preview."""
    if packet[0] >> 6 != 3:
        raise ValueError("not a packet (its first byte)")
    flags = packet[3]
    preview = bool(flags & 2)
    at = 4
    for _ in range(4 if preview else 8):  # index, count, width - 1, height - 1 [, x, y, w, h]
        _, at = varint(packet, at)
    if flags & 4:
        at += 2
    return at + 2, preview


def measure(pifs, image, rate, args, work):
    name = os.path.splitext(os.path.basename(image))[0]
    packets = os.path.join(work, f"{name}-{rate}")
    encode = ["encode", image, "--bpp", str(rate), "--packets", packets,
              "--packet-size", str(args.size)]
    if not args.colour:
        encode.append("--gray")
    loss.run(pifs, *encode)
    total = headers = preview = 0
    names = sorted(os.listdir(packets))
    for n in names:
        data = open(os.path.join(packets, n), "rb").read()
        head, is_preview = overhead(data)
        total += len(data)
        headers += head
        if is_preview:
            preview += len(data) - head
    original = loss.load(image, args.colour)
    value = loss.decoded_psnr(pifs, packets, original, args.colour, work)
    pixels = original.shape[0] * original.shape[1]
    return {"name": name, "rate": rate, "packets": len(names), "psnr": value,
            "whole": 8 * total / pixels, "payload": 8 * (total - headers) / pixels,
            "regions": 8 * (total - headers - preview) / pixels,
            "header_share": headers / total, "preview_share": preview / total}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    loss.packet_arguments(ap)
    ap.add_argument("images", nargs="*")
    args = ap.parse_args()
    images = args.images or sorted(glob.glob(os.path.join(
        os.path.dirname(__file__), "..", "..", "shared", "images", "kodak", "*.png")))
    work = args.work or tempfile.mkdtemp(prefix="pifs-packet-costs-")
    os.makedirs(work, exist_ok=True)
    rows = [measure(args.pifs, im, r, args, work) for im in images for r in args.rates]
    print(f"{len(images)} images, {args.size}-byte packets, "
          f"{'colour' if args.colour else 'gray'}:\n")
    print("| rate | packets | bpp | PSNR | headers and checksums | preview |")
    print("|---:|---:|---:|---:|---:|---:|")
    for rate in args.rates:
        rs = [r for r in rows if r["rate"] == rate]
        m = lambda k: statistics.fmean(r[k] for r in rs)  # noqa: E731
        print(f"| {rate} | {m('packets'):.1f} | {m('whole'):.4f} | {m('psnr'):.2f} | "
              f"{100 * m('header_share'):.1f}% | {100 * m('preview_share'):.1f}% |")
    path, single = loss.single_stream_points(args.colour)
    print(f"\nBD-rate against the single stream ({os.path.normpath(path)}):\n")
    print("| bytes counted | BD-rate |")
    print("|---|---:|")
    for key, label in [("whole", "whole packets"),
                       ("payload", "payloads (no headers, no checksums)"),
                       ("regions", "the regions' payloads (no preview either)")]:
        deltas = []
        for name in sorted({r["name"] for r in rows}):
            ours = [(r[key], r["psnr"]) for r in rows if r["name"] == name]
            theirs = [single[name][rate] for rate in args.rates if rate in single.get(name, {})]
            if len(ours) >= 3 and len(theirs) >= 3:
                deltas.append(loss.bd(ours, theirs))
        if deltas:
            print(f"| {label} | {statistics.fmean(d[0] for d in deltas):+.1f}% |")


if __name__ == "__main__":
    main()
