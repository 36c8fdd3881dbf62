#!/usr/bin/env python3
"""Makes the grayscale test images of bench/embedded.sh from one 8-bit PNG, with the standard
library only (no Pillow): decodes the PNG, converts to BT.601 luma like `pifs` does, and writes
binary PGM files that `pifs encode` reads.

    python3 bench/crop_png.py [--colour] IN.png OUT_DIR NAME WxH[/F] ...

Each `WxH/F` is: downscale by the integer factor F (box filter, default 1), then take the centred
W x H crop. Writes OUT_DIR/NAME_WxH.pgm, or with --colour OUT_DIR/NAME_WxH.ppm in RGB (each
channel downscaled alike).
"""
import struct
import sys
import zlib
from pathlib import Path


def read_png(path, colour=False):
    data = Path(path).read_bytes()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise SystemExit(f"{path}: not a PNG")
    pos, idat, ihdr = 8, [], None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
    width, height, depth, color, _, _, interlace = ihdr
    channels = {0: 1, 2: 3, 4: 2, 6: 4}.get(color)
    if depth != 8 or channels is None or interlace:
        raise SystemExit(f"{path}: only 8-bit, non-interlaced gray/RGB(A) PNGs are supported")
    raw = zlib.decompress(b"".join(idat))
    stride = width * channels
    rows, prev = [], bytearray(stride)
    for y in range(height):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        bpp = channels
        if f == 1:
            for i in range(bpp, stride):
                line[i] = (line[i] + line[i - bpp]) & 255
        elif f == 2:
            for i in range(stride):
                line[i] = (line[i] + prev[i]) & 255
        elif f == 3:
            for i in range(stride):
                left = line[i - bpp] if i >= bpp else 0
                line[i] = (line[i] + ((left + prev[i]) >> 1)) & 255
        elif f == 4:
            for i in range(stride):
                a = line[i - bpp] if i >= bpp else 0
                b = prev[i]
                c = prev[i - bpp] if i >= bpp else 0
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[i] = (line[i] + pred) & 255
        rows.append(line)
        prev = line
    if colour:
        if channels < 3:
            raise SystemExit(f"{path}: not a colour PNG")
        return width, height, [
            [[line[i + c] for i in range(0, stride, channels)] for line in rows] for c in range(3)
        ]
    luma = []
    for line in rows:
        if channels >= 3:
            luma.append([
                min(255, max(0, round(0.299 * line[i] + 0.587 * line[i + 1] + 0.114 * line[i + 2])))
                for i in range(0, stride, channels)
            ])
        else:
            luma.append([line[i] for i in range(0, stride, channels)])
    return width, height, luma


def main():
    args = sys.argv[1:]
    colour = bool(args) and args[0] == "--colour"
    if colour:
        args = args[1:]
    if len(args) < 4:
        raise SystemExit(__doc__)
    src, out_dir, name = args[0], Path(args[1]), args[2]
    width, height, planes = read_png(src, colour)
    if not colour:
        planes = [planes]
    out_dir.mkdir(parents=True, exist_ok=True)
    for spec in args[3:]:
        size, _, factor = spec.partition("/")
        w, h = (int(v) for v in size.split("x"))
        f = int(factor or 1)
        sw, sh = width // f, height // f
        if w > sw or h > sh:
            raise SystemExit(f"{spec}: larger than the {sw}x{sh} downscaled image")
        x0, y0 = (sw - w) // 2, (sh - h) // 2
        crops = []
        for plane in planes:
            small = [[(sum(plane[y * f + j][x * f + i] for j in range(f) for i in range(f))
                       + f * f // 2) // (f * f) for x in range(sw)] for y in range(sh)]
            crops.append([row[x0:x0 + w] for row in small[y0:y0 + h]])
        if colour:
            pixels = bytes(crops[c][y][x] for y in range(h) for x in range(w) for c in range(3))
            out = out_dir / f"{name}_{w}x{h}.ppm"
            out.write_bytes(b"P6\n%d %d\n255\n" % (w, h) + pixels)
        else:
            pixels = bytes(v for row in crops[0] for v in row)
            out = out_dir / f"{name}_{w}x{h}.pgm"
            out.write_bytes(b"P5\n%d %d\n255\n" % (w, h) + pixels)
        print(out)


if __name__ == "__main__":
    main()
