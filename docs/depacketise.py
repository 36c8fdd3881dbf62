#!/usr/bin/env python3
"""A gateway's depacketiser for PIFS packets, written from docs/bitstream.md alone.

Section 9 of the specification says it describes packets precisely enough for a gateway
author to write a depacketiser; this is one, in plain Python 3 (no third-party module), kept
as an independent reading of that section: it shares no code with the reference decoder, and
`host-encoder/tests/depacketise.rs` checks that it reads the reference encoder's packets as
`pifs info --json` does. A gateway can use it to sort the packets it hears by image, drop the
damaged and the duplicated ones, and see which to ask for again, before handing a set to
`pifs decode` (or to a device).

    python3 docs/depacketise.py FILE_OR_DIR...            one line per image
    python3 docs/depacketise.py --json FILE_OR_DIR...     the same as JSON, one object per image

A directory is read as one file per packet; a file ending in .pifsp (or standard input, "-")
as framed packets (each behind its length, two bytes little-endian); any other file as one
packet. It reads headers and checksums only: it does not decode pictures or rebuild packets
from parity (that is `pifs decode`'s work).
"""

import json
import os
import sys

FORMAT_VERSION = 22
KIND_PARITY, KIND_STREAM, KIND_PACKET = 1, 2, 3


class Refused(Exception):
    """A packet this reader does not accept, with the reason (section 9's rejections)."""


def crc16(data):
    """CRC-16/IBM-3740: polynomial 0x1021, not reflected, initial 0xFFFF, no final XOR."""
    reg = 0xFFFF
    for byte in data:
        reg ^= byte << 8
        for _ in range(8):
            reg = ((reg << 1) ^ 0x1021) if reg & 0x8000 else (reg << 1)
            reg &= 0xFFFF
    return reg


assert crc16(b"123456789") == 0x29B1


class Reader:
    """The fields of a packet, read in order."""

    def __init__(self, data, at):
        self.data = data
        self.at = at

    def byte(self):
        if self.at >= len(self.data):
            raise Refused("a field cut short")
        value = self.data[self.at]
        self.at += 1
        return value

    def u16(self):
        return self.byte() | self.byte() << 8

    def varint(self):
        """Unsigned LEB128 of at most 16 bits in at most three bytes, no redundant zero group."""
        value, shift = 0, 0
        for count in range(1, 4):
            byte = self.byte()
            value |= (byte & 0x7F) << shift
            shift += 7
            if not byte & 0x80:
                if count > 1 and byte == 0:
                    raise Refused("a varint with a redundant zero group")
                if value > 0xFFFF:
                    raise Refused("a varint above 16 bits")
                return value
        raise Refused("a varint longer than three bytes")


def parse(data):
    """One packet's fields as a dict; raises Refused for what section 9 rejects."""
    if not data:
        raise Refused("empty")
    kind, version = data[0] >> 6, data[0] & 0x3F
    if kind == KIND_STREAM:
        raise Refused("a stream, not a packet")
    if kind not in (KIND_PACKET, KIND_PARITY) or version < FORMAT_VERSION:
        raise Refused("not a packet (bad magic)")
    if version > FORMAT_VERSION:
        raise Refused(f"a packet of a later format version ({version})")
    if len(data) < 3 or crc16(data[:-2]) != data[-2] | data[-1] << 8:
        raise Refused("checksum mismatch")
    body = Reader(data[:-2], 1)
    image_id = body.u16()
    if kind == KIND_PARITY:
        k, parity, data_count, shard = (body.varint() for _ in range(4))
        if not (k < parity and data_count >= 1 and data_count + parity <= 256):
            raise Refused("parity fields out of range")
        if len(data) - 2 - body.at != shard:
            raise Refused("a parity shard of the wrong length")
        return {"kind": "parity", "image_id": image_id, "parity_index": k,
                "parity_count": parity, "count": data_count, "shard_length": shard}
    flags = body.byte()
    colour, preview, coding = bool(flags & 1), bool(flags & 2), bool(flags & 4)
    smoothing = flags >> 3
    index, count = body.varint(), body.varint()
    width, height = body.varint() + 1, body.varint() + 1
    if index >= count:
        raise Refused("an index not below the count")
    if width > 65535 or height > 65535:
        raise Refused("a side above 65535")
    if preview:
        region = (0, 0, width, height)
    else:
        x, y, w, h = (body.varint() for _ in range(4))
        inside = (w >= 1 and h >= 1 and 8 * x < width and 8 * (x + w) < width + 8
                  and 8 * y < height and 8 * (y + h) < height + 8)
        if not inside:
            raise Refused("a region outside the image")
        region = (8 * x, 8 * y, min(8 * (x + w), width) - 8 * x,
                  min(8 * (y + h), height) - 8 * y)
    leaves, stripe = 0x72, 4
    if coding:
        leaves, stripe = body.byte(), body.byte()
        if (leaves, stripe) == (0x72, 4):
            raise Refused("coding fields written though they are the defaults")
    low, high = leaves & 0x0F, leaves >> 4
    if not 1 <= low <= high <= 7:
        raise Refused("leaf sizes out of range")
    if smoothing > 16:
        raise Refused("a smoothing strength above 16")
    return {"kind": "preview" if preview else "region", "image_id": image_id,
            "index": index, "count": count, "width": width, "height": height,
            "channels": 3 if colour else 1, "region": region, "smoothing": smoothing,
            "leaf_log2": (low, high), "stripe_tiles": stripe,
            "header_bytes": body.at, "payload_bytes": len(data) - 2 - body.at}


def frames(data):
    """The packets of a framed file: each behind its length, two bytes little-endian."""
    at = 0
    while at + 2 <= len(data):
        length = data[at] | data[at + 1] << 8
        yield data[at + 2:at + 2 + length]
        at += 2 + length


def packets_of(path):
    """Every packet's bytes at `path` (a directory, a framed file, "-" or one packet)."""
    if path == "-":
        yield from frames(sys.stdin.buffer.read())
    elif os.path.isdir(path):
        for name in sorted(os.listdir(path)):
            with open(os.path.join(path, name), "rb") as f:
                yield f.read()
    else:
        with open(path, "rb") as f:
            data = f.read()
        yield from (frames(data) if path.endswith(".pifsp") else [data])


def gather(paths):
    """Packets sorted by image (id, count and geometry): what each image holds and lacks."""
    images, damaged = {}, 0
    for path in paths:
        for data in packets_of(path):
            try:
                packet = parse(data)
            except Refused:
                damaged += 1
                continue
            if packet["kind"] == "parity":
                key = (packet["image_id"], packet["count"])
                images.setdefault(key, {"packets": {}, "parity": {}, "duplicates": 0})
                image = images[key]
                if packet["parity_index"] in image["parity"]:
                    image["duplicates"] += 1
                image["parity"][packet["parity_index"]] = packet
                continue
            key = (packet["image_id"], packet["count"])
            image = images.setdefault(key, {"packets": {}, "parity": {}, "duplicates": 0})
            shape = (packet["width"], packet["height"], packet["channels"])
            if image.setdefault("shape", shape) != shape:
                damaged += 1  # the same id and count but another picture: not this image's
                continue
            if packet["index"] in image["packets"]:
                image["duplicates"] += 1
                continue
            image["packets"][packet["index"]] = packet
    return images, damaged


def summary(key, image):
    """One image's summary, named as `pifs info --json` names the same things."""
    image_id, count = key
    held = image["packets"]
    width, height, channels = image.get("shape", (0, 0, 0))
    covered = sum(p["region"][2] * p["region"][3] for p in held.values()
                  if p["kind"] == "region")
    return {
        "image_id": image_id, "count": count, "width": width, "height": height,
        "channels": channels, "received": sorted(held),
        "missing": [i for i in range(count) if i not in held],
        "previews": sum(p["kind"] == "preview" for p in held.values()),
        "parity": sorted(image["parity"]),
        "region_coverage": covered / (width * height) if width * height else 0.0,
        "duplicates": image["duplicates"],
    }


def main(argv):
    as_json = "--json" in argv
    paths = [a for a in argv if a != "--json"]
    if not paths:
        print(__doc__.strip().splitlines()[0], file=sys.stderr)
        print("usage: depacketise.py [--json] FILE_OR_DIR...", file=sys.stderr)
        return 2
    images, damaged = gather(paths)
    rows = [summary(key, image) for key, image in sorted(images.items())]
    if as_json:
        print(json.dumps({"images": rows, "damaged": damaged}, sort_keys=True))
        return 0
    for row in rows:
        missing = row["missing"]
        print(f"image {row['image_id']}: {row['width']}x{row['height']}, "
              f"{len(row['received'])} of {row['count']} packets, "
              f"{len(row['parity'])} parity, regions cover {100 * row['region_coverage']:.1f}%, "
              f"missing {','.join(map(str, missing)) if missing else 'none'}")
    if damaged:
        print(f"{damaged} packets refused (damaged, or not packets of this format)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
