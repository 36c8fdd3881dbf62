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
    python3 docs/depacketise.py --write DIR FILE_OR_DIR... also each image's data packets,
                                                            rebuilt from parity where they can be,
                                                            to DIR/ID/NNNN.pkt

A directory is read as one file per packet; a file ending in .pifsp (or standard input, "-")
as framed packets (each behind its length, two bytes little-endian); any other file as one
packet. It reads headers and checksums and rebuilds lost packets from parity packets (the
Reed-Solomon erasure code of section 9); it does not decode pictures (that is `pifs decode`'s
work, or a device's).
"""

import json
import os
import sys

FORMAT_VERSION = 23
FIRST_TAGGED_VERSION = 22
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

# GF(2^8) with the field polynomial x^8 + x^4 + x^3 + x^2 + 1 (0x11D); x (2) generates it.
EXP, LOG = [0] * 510, [0] * 256
_value = 1
for _power in range(255):
    EXP[_power] = EXP[_power + 255] = _value
    LOG[_value] = _power
    _value <<= 1
    if _value & 0x100:
        _value ^= 0x11D


def gf_mul(a, b):
    return 0 if a == 0 or b == 0 else EXP[LOG[a] + LOG[b]]


def gf_pow(a, n):
    if n == 0:
        return 1
    return 0 if a == 0 else EXP[(LOG[a] * n) % 255]


def gf_inverse(matrix):
    """The inverse of a square matrix over GF(2^8) (Gauss-Jordan); None if it is singular."""
    n = len(matrix)
    rows = [list(row) + [int(i == j) for j in range(n)] for i, row in enumerate(matrix)]
    for col in range(n):
        pivot = next((r for r in range(col, n) if rows[r][col]), None)
        if pivot is None:
            return None
        rows[col], rows[pivot] = rows[pivot], rows[col]
        scale = EXP[255 - LOG[rows[col][col]]]
        rows[col] = [gf_mul(v, scale) for v in rows[col]]
        for r in range(n):
            factor = rows[r][col]
            if r != col and factor:
                rows[r] = [v ^ gf_mul(factor, p) for v, p in zip(rows[r], rows[col])]
    return [row[n:] for row in rows]


def gf_product(a, b):
    return [[_dot(row, [b[k][j] for k in range(len(b))]) for j in range(len(b[0]))] for row in a]


def _dot(u, v):
    total = 0
    for x, y in zip(u, v):
        total ^= gf_mul(x, y)
    return total


def encoding_matrix(data_count, parity_count):
    """Section 9's systematic code: V T^-1, V[r][c] = r^c over N + K rows, T its top N rows."""
    v = [[gf_pow(r, c) for c in range(data_count)] for r in range(data_count + parity_count)]
    return gf_product(v, gf_inverse(v[:data_count]))


def rebuild(shards, data_count, parity_count):
    """The N data shards from any N of the N + K (`shards`: index -> bytes), or None."""
    if len(shards) < data_count:
        return None
    rows = sorted(shards)[:data_count]
    code = encoding_matrix(data_count, parity_count)
    decode = gf_inverse([code[r] for r in rows])
    length = len(shards[rows[0]])
    data = []
    for i in range(data_count):
        coefficients = [(c, shards[r]) for c, r in zip(decode[i], rows) if c]
        shard = bytearray(length)
        for c, source in coefficients:
            for at, byte in enumerate(source):
                if byte:
                    shard[at] ^= gf_mul(c, byte)
        data.append(bytes(shard))
    return data


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
    if kind not in (KIND_PACKET, KIND_PARITY) or version < FIRST_TAGGED_VERSION:
        raise Refused("not a packet (bad magic)")
    if version != FORMAT_VERSION:
        raise Refused(f"a packet of another format version ({version})")
    if len(data) < 3 or crc16(data[:-2]) != data[-2] | data[-1] << 8:
        raise Refused("checksum mismatch")
    body = Reader(data[:-2], 1)
    image_id = body.u16()
    if kind == KIND_PARITY:
        k, data_count = body.varint(), body.varint()
        if not (data_count >= 1 and data_count + k < 256):
            raise Refused("parity fields out of range")
        if len(data) - 2 - body.at < 1:
            raise Refused("an empty parity shard")
        return {"kind": "parity", "image_id": image_id, "parity_index": k,
                "count": data_count, "shard": bytes(data[body.at:-2])}
    flags = body.byte()
    colour, preview, coding = bool(flags & 1), bool(flags & 2), bool(flags & 4)
    smoothing = flags >> 3
    index, count = body.varint(), body.varint()
    after_count = body.at
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
            "header_bytes": body.at, "payload_bytes": len(data) - 2 - body.at,
            "bytes": bytes(data), "content": bytes([flags]) + bytes(data[after_count:-2])}


def varint(value):
    """Unsigned LEB128: seven bits a byte, least significant group first."""
    out = bytearray()
    while True:
        byte, value = value & 0x7F, value >> 7
        out.append(byte | (0x80 if value else 0))
        if not value:
            return bytes(out)


def unshard(shard, image_id, index, count):
    """A data packet from its shard (section 9): the content before the end byte 0x80 and the
    zeros, with the tag, image id, index and count put back and the checksum computed."""
    content = shard.rstrip(b"\0")
    if len(content) < 2 or content[-1] != 0x80:
        return None
    content = content[:-1]
    body = (bytes([KIND_PACKET << 6 | FORMAT_VERSION, image_id & 0xFF, image_id >> 8,
                   content[0]]) + varint(index) + varint(count) + content[1:])
    crc = crc16(body)
    return body + bytes([crc & 0xFF, crc >> 8])


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


def new_image(image_id, count):
    return {"image_id": image_id, "count": count, "packets": {}, "parity": {}, "duplicates": 0}


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
                image = images.setdefault(key, new_image(*key))
                if packet["parity_index"] in image["parity"]:
                    image["duplicates"] += 1
                image["parity"][packet["parity_index"]] = packet
                continue
            key = (packet["image_id"], packet["count"])
            image = images.setdefault(key, new_image(*key))
            shape = (packet["width"], packet["height"], packet["channels"])
            if image.setdefault("shape", shape) != shape:
                damaged += 1  # the same id and count but another picture: not this image's
                continue
            if packet["index"] in image["packets"]:
                image["duplicates"] += 1
                continue
            image["packets"][packet["index"]] = packet
    return images, damaged


def complete(image):
    """Rebuilds the image's missing data packets from its parity packets where any N of its
    N + K shards are held (section 9); returns the indices rebuilt."""
    parity = list(image["parity"].values())
    missing = [i for i in range(image["count"]) if i not in image["packets"]]
    if not parity or not missing:
        return []
    length = len(parity[0]["shard"])
    if any(len(p["shard"]) != length for p in parity):
        return []
    shards = {}
    for index, packet in image["packets"].items():
        content = packet["content"]
        if len(content) + 1 > length:
            return []
        shards[index] = content + b"\x80" + bytes(length - len(content) - 1)
    for k, p in image["parity"].items():
        shards[image["count"] + k] = p["shard"]
    # The code's rows do not depend on how many parity packets were sent.
    data = rebuild(shards, image["count"], 1 + max(image["parity"]))
    if data is None:
        return []
    rebuilt = []
    for index in missing:
        data_packet = unshard(data[index], image["image_id"], index, image["count"])
        if data_packet is None:
            continue
        try:
            packet = parse(data_packet)
        except Refused:
            continue
        if packet["kind"] != "parity" and packet["index"] == index:
            image["packets"][index] = packet
            rebuilt.append(index)
    return rebuilt


def summary(key, image, rebuilt):
    """One image's summary, named as `pifs info --json` names the same things."""
    image_id, count = key
    held = image["packets"]
    width, height, channels = image.get("shape", (0, 0, 0))
    covered = sum(p["region"][2] * p["region"][3] for p in held.values()
                  if p["kind"] == "region")
    return {
        "image_id": image_id, "count": count, "width": width, "height": height,
        "channels": channels, "received": sorted(held), "rebuilt_from_parity": rebuilt,
        "missing": [i for i in range(count) if i not in held],
        "previews": sum(p["kind"] == "preview" for p in held.values()),
        "parity": sorted(image["parity"]),
        "region_coverage": covered / (width * height) if width * height else 0.0,
        "duplicates": image["duplicates"],
    }


def write(directory, key, image):
    """The image's data packets, as held or rebuilt, to DIRECTORY/ID/NNNN.pkt."""
    folder = os.path.join(directory, str(key[0]))
    os.makedirs(folder, exist_ok=True)
    for index, packet in image["packets"].items():
        with open(os.path.join(folder, f"{index:04}.pkt"), "wb") as f:
            f.write(packet["bytes"])


def main(argv):
    as_json = "--json" in argv
    argv = [a for a in argv if a != "--json"]
    out = None
    if "--write" in argv:
        at = argv.index("--write")
        out = argv[at + 1] if at + 1 < len(argv) else None
        argv = argv[:at] + argv[at + 2:]
        if out is None:
            argv = []
    paths = argv
    if not paths:
        print(__doc__.strip().splitlines()[0], file=sys.stderr)
        print("usage: depacketise.py [--json] [--write DIR] FILE_OR_DIR...", file=sys.stderr)
        return 2
    try:
        images, damaged = gather(paths)
    except OSError as e:
        print(f"depacketise.py: {e.filename}: {e.strerror}", file=sys.stderr)
        return 1
    rows = []
    for key, image in sorted(images.items()):
        rows.append(summary(key, image, complete(image)))
        if out is not None:
            write(out, key, image)
    if as_json:
        print(json.dumps({"images": rows, "damaged": damaged}, sort_keys=True))
        return 0
    for row in rows:
        missing = row["missing"]
        print(f"image {row['image_id']}: {row['width']}x{row['height']}, "
              f"{len(row['received'])} of {row['count']} packets, "
              f"{len(row['parity'])} parity, {len(row['rebuilt_from_parity'])} rebuilt, "
              f"regions cover {100 * row['region_coverage']:.1f}%, "
              f"missing {','.join(map(str, missing)) if missing else 'none'}")
    if damaged:
        print(f"{damaged} packets refused (damaged, or not packets of this format)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
