"""The PSNR-RGB ceiling of 4:2:0 chroma with exact luma, on a set of images, for two ways of
making the half-size chroma planes: the means of 2 x 2 blocks (what the encoder does) and
the least-squares planes for the decoder's drawing (linear interpolation at the centred
siting, luma x at chroma x / 2 - 1/4, clamped at the edges); and a third: the 2 x 2 means with
each pixel's luma the one whose RGB, with the chroma drawn there, is nearest the pixel's (what
the encoder codes since "Luma that makes up for the chroma drawn"). Conversions are
decoder-core's integer BT.601 ones (docs/bitstream.md, "Drawing in RGB"). docs/decisions.md,
"Colour: chroma tools measured" and "Luma that makes up for the chroma drawn", quote its means
on Kodak.

    python3 bench/experiments/chroma_ceiling.py ../shared/images/kodak/*.png

With `--repeated` first, the same two 2 x 2 means ceilings (plain luma, luma made up) with the
chroma drawn as the decoder draws it and repeated over each 2 x 2 block instead (what JPEG
decoders' plain upsampling does; docs/decisions.md, "Chroma repeated over 2 x 2 pixels").

Needs numpy and Pillow. Images of even sizes.
"""
import sys

import numpy as np
from PIL import Image


def to_ycbcr(rgb):
    r, g, b = (rgb[..., i].astype(np.int64) for i in range(3))
    y = (19595 * r + 38470 * g + 7471 * b + 32768) >> 16
    cb = np.clip(128 + ((-11059 * r - 21709 * g + 32768 * b + 32768) >> 16), 0, 255)
    cr = np.clip(128 + ((32768 * r - 27439 * g - 5329 * b + 32768) >> 16), 0, 255)
    return y, cb, cr


def to_rgb(y, cb, cr):
    cb, cr = cb - 128, cr - 128
    r = np.clip(y + ((91881 * cr + 32768) >> 16), 0, 255)
    g = np.clip(y + ((-22554 * cb - 46802 * cr + 32768) >> 16), 0, 255)
    b = np.clip(y + ((116130 * cb + 32768) >> 16), 0, 255)
    return np.stack([r, g, b], -1)


def interpolation(n):
    """The n x n/2 matrix of the drawing's linear interpolation along one axis."""
    nc = n // 2
    u = np.zeros((n, nc))
    for x in range(n):
        s = min(max(x / 2 - 0.25, 0), nc - 1)
        i = int(np.floor(s))
        f = s - i
        u[x, i] += 1 - f
        u[x, min(i + 1, nc - 1)] += f
    return u


def psnr(a, b):
    return 10 * np.log10(255**2 / np.mean((a.astype(float) - b) ** 2))


def made_up_luma(rgb, cb, cr):
    """Each pixel's 8-bit luma nearest its RGB with chroma (cb, cr), clamping included."""
    best_error = np.full(cb.shape, np.iinfo(np.int64).max)
    best = np.zeros(cb.shape, dtype=np.int64)
    for level in range(256):
        got = to_rgb(np.full(cb.shape, level, dtype=np.int64), cb, cr)
        error = ((got - rgb.astype(np.int64)) ** 2).sum(axis=-1)
        better = error < best_error
        best_error[better], best[better] = error[better], level
    return best


def repeated(paths):
    """The 2 x 2 means ceilings, chroma drawn (as `main`) and chroma repeated."""
    rows = []
    for path in paths:
        rgb = np.asarray(Image.open(path).convert("RGB"))
        h, w, _ = rgb.shape
        y, cb, cr = to_ycbcr(rgb)
        uy, ux = interpolation(h), interpolation(w)
        means = [np.round(c.reshape(h // 2, 2, w // 2, 2).mean(axis=(1, 3))) for c in (cb, cr)]
        drawn = [np.round(uy @ c @ ux.T).astype(np.int64) for c in means]
        repeat = [np.repeat(np.repeat(c, 2, 0), 2, 1).astype(np.int64) for c in means]
        row = [
            psnr(rgb, to_rgb(y, *drawn)),
            psnr(rgb, to_rgb(y, *repeat)),
            psnr(rgb, to_rgb(made_up_luma(rgb, *drawn), *drawn)),
            psnr(rgb, to_rgb(made_up_luma(rgb, *repeat), *repeat)),
        ]
        rows.append(row)
        print(
            f"{path}: drawn {row[0]:.2f} dB, repeated {row[1]:.2f} dB; with the luma made up: "
            f"drawn {row[2]:.2f} dB, repeated {row[3]:.2f} dB"
        )
    m = np.mean(rows, axis=0)
    print(
        f"mean over {len(paths)}: drawn {m[0]:.2f} dB, repeated {m[1]:.2f} dB; with the luma "
        f"made up: drawn {m[2]:.2f} dB, repeated {m[3]:.2f} dB"
    )


def main(paths):
    means, least, made_up = [], [], []
    for path in paths:
        rgb = np.asarray(Image.open(path).convert("RGB"))
        h, w, _ = rgb.shape
        y, cb, cr = to_ycbcr(rgb)
        uy, ux = interpolation(h), interpolation(w)

        def draw(c):
            return np.round(uy @ c @ ux.T).astype(np.int64)

        def mean2x2(c):
            return np.round(c.reshape(h // 2, 2, w // 2, 2).mean(axis=(1, 3)))

        def least_squares(c):
            return np.clip(np.round(np.linalg.pinv(uy) @ c @ np.linalg.pinv(ux).T), 0, 255)

        means.append(psnr(rgb, to_rgb(y, draw(mean2x2(cb)), draw(mean2x2(cr)))))
        least.append(psnr(rgb, to_rgb(y, draw(least_squares(cb)), draw(least_squares(cr)))))
        drawn = draw(mean2x2(cb)), draw(mean2x2(cr))
        made_up.append(psnr(rgb, to_rgb(made_up_luma(rgb, *drawn), *drawn)))
        print(
            f"{path}: 2x2 means {means[-1]:.2f} dB, least squares {least[-1]:.2f} dB, "
            f"2x2 means with the luma made up {made_up[-1]:.2f} dB"
        )
    print(
        f"mean over {len(paths)}: 2x2 means {np.mean(means):.2f} dB, least squares "
        f"{np.mean(least):.2f} dB, 2x2 means with the luma made up {np.mean(made_up):.2f} dB"
    )


if __name__ == "__main__":
    if sys.argv[1:2] == ["--repeated"]:
        repeated(sys.argv[2:])
    else:
        main(sys.argv[1:])
