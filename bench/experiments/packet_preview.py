#!/usr/bin/env python3
"""What one radio packet can carry as a whole picture (issue 23, docs/decisions.md).

    python3 bench/experiments/packet_preview.py kodim01 kodim05 ...

For each Kodak image (grayscale) and each size N of 230, 460 and 920 bytes (one, two and four
packets of 230 bytes), prints the PSNR against the original of: the whole image coded at N
bytes (`pifs encode --bytes N`), and the image shrunk 8 and 4 times (box filter), coded at N
bytes and enlarged again (bicubic). Run from the repository root after
`cargo build --release -p host-encoder`; needs numpy and Pillow.
"""
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

PIFS = "./target/release/pifs"
KODAK = Path("../shared/images/kodak")


def psnr(a, b):
    mse = np.mean((a.astype(float) - b.astype(float)) ** 2)
    return 10 * np.log10(255**2 / mse)


def coded(src, nbytes, work):
    """The pixels of `src` coded at `nbytes` bytes, or None if no stream is that small."""
    stream, out = work / "x.pifs", work / "x.pgm"
    r = subprocess.run([PIFS, "encode", "--gray", str(src), "-o", str(stream),
                        "--bytes", str(nbytes)], capture_output=True, text=True)
    if r.returncode != 0:
        return None
    subprocess.run([PIFS, "decode", str(stream), "-o", str(out)], check=True,
                   capture_output=True)
    return Image.open(out)


def main():
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for name in sys.argv[1:]:
            path = KODAK / f"{name}.png"
            original = Image.open(path).convert("L")
            o = np.asarray(original)
            w, h = original.size
            row = [name]
            for nbytes in (230, 460, 920):
                cells = []
                whole = coded(path, nbytes, work)
                cells.append("n/a" if whole is None else f"{psnr(o, np.asarray(whole)):.2f}")
                for k in (8, 4):
                    small = work / f"small{k}.png"
                    original.resize((w // k, h // k), Image.BOX).save(small)
                    thumb = coded(small, nbytes, work)
                    if thumb is None:
                        cells.append("n/a")
                    else:
                        up = thumb.resize((w, h), Image.BICUBIC)
                        cells.append(f"{psnr(o, np.asarray(up)):.2f}")
                row.append(f"{nbytes} B: " + " / ".join(cells))
            print(" | ".join(row), flush=True)


if __name__ == "__main__":
    main()
