#!/usr/bin/env python3
"""chroma_tools.py - issue 22 exploration: which chroma tools could close the gap to JPEG 2000
in colour? Two measurements on colour decodes, neither part of the codec (the findings are in
docs/decisions.md, "Colour: chroma tools measured").

    python3 bench/experiments/chroma_tools.py cfl DIR IMAGE_NUMBERS... [--rates 0.25,1.0]
        Chroma from luma, as an upper bound: for each B x B block (8, 16, 32) of a decode and
        each chroma plane, add alpha (Y - mean Y) of the decoded luma, alpha fitted by least
        squares against the original chroma (unquantised: no rate), or quantised in steps of
        1/8 (|alpha| <= 1) with the order-0 entropy of the indices as its side cost. Prints the
        PSNR-RGB gain and the side cost in % of the stream. DIR holds kNN_R.pifs and kNN_R.png
        (`pifs encode kodimNN.png --bpp R -o DIR/kNN_R.pifs`, then `pifs decode`).

    python3 bench/experiments/chroma_tools.py planes DIR IMAGE_NUMBERS... [--rates 1.0]
        4:4:4 against 4:2:0, and both against the codec's one-cut bilinear chroma: Y, Cb and
        Cr written as grayscale images (Cb, Cr at full size or box-averaged to half size),
        each coded alone with `pifs encode --gray --bytes N` at a grid of budgets, the best
        PSNR-RGB over the combinations whose three streams fit R bpp (three headers counted),
        half-size chroma upsampled bilinearly at centred sites. Work files go to DIR/planes.

Both read ../shared/images/kodak/kodimNN.png and the `pifs` of target/release.
"""
import argparse, os, subprocess, sys
from concurrent.futures import ThreadPoolExecutor
import numpy as np
from PIL import Image

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..')
PIFS = os.path.join(ROOT, 'target', 'release', 'pifs')
KODAK = os.path.join(ROOT, '..', 'shared', 'images', 'kodak')


def ycc(rgb):
    r, g, b = [rgb[..., i].astype(float) for i in range(3)]
    y = 0.299 * r + 0.587 * g + 0.114 * b
    cb = -0.168736 * r - 0.331264 * g + 0.5 * b + 128
    cr = 0.5 * r - 0.418688 * g - 0.081312 * b + 128
    return y, cb, cr


def to_rgb(y, cb, cr):
    r = y + 1.402 * (cr - 128)
    g = y - 0.344136 * (cb - 128) - 0.714136 * (cr - 128)
    b = y + 1.772 * (cb - 128)
    return np.clip(np.round(np.stack([r, g, b], -1)), 0, 255)


def psnr(a, b):
    return 10 * np.log10(255 ** 2 / np.mean((a.astype(float) - b.astype(float)) ** 2))


def entropy_bits(ix):
    _, c = np.unique(ix, return_counts=True)
    return -(c * np.log2(c / c.sum())).sum()


def original(n):
    return np.array(Image.open(os.path.join(KODAK, f'kodim{n}.png')).convert('RGB'))


def upsample(s):
    """Bilinear 2x upsampling at centred sites (a pixel's centre is (x / 2 - 1/4) chroma px)."""
    h, w = s.shape
    ys = (np.arange(2 * h) + 0.5) / 2 - 0.5
    xs = (np.arange(2 * w) + 0.5) / 2 - 0.5
    y0, x0 = np.floor(ys).astype(int), np.floor(xs).astype(int)
    fy, fx = (ys - y0)[:, None], xs - x0
    a, b = np.clip(y0, 0, h - 1), np.clip(y0 + 1, 0, h - 1)
    c, d = np.clip(x0, 0, w - 1), np.clip(x0 + 1, 0, w - 1)
    return (s[a][:, c] * (1 - fy) * (1 - fx) + s[a][:, d] * (1 - fy) * fx
            + s[b][:, c] * fy * (1 - fx) + s[b][:, d] * fy * fx)


def cfl(args):
    for rate in args.rates:
        for size in (8, 16, 32):
            for step in (0, 1 / 8):
                gains, side = [], []
                for n in args.images:
                    o = original(n)
                    d = np.array(Image.open(os.path.join(args.dir, f'k{n}_{rate}.png')).convert('RGB'))
                    _, cbo, cro = ycc(o)
                    yd, cbd, crd = ycc(d)
                    out, indices = [cbd.copy(), crd.copy()], []
                    for y0 in range(0, yd.shape[0], size):
                        for x0 in range(0, yd.shape[1], size):
                            sl = (slice(y0, y0 + size), slice(x0, x0 + size))
                            x = yd[sl] - yd[sl].mean()
                            xx = (x * x).sum()
                            for k, (co, cd) in enumerate(((cbo, cbd), (cro, crd))):
                                alpha = ((co[sl] - cd[sl]) * x).sum() / xx if xx > 0 else 0
                                if step:
                                    alpha = np.clip(np.round(alpha / step), -8, 8)
                                    indices.append(alpha)
                                    alpha *= step
                                out[k][sl] = cd[sl] + alpha * x
                    gains.append(psnr(o, to_rgb(yd, *out)) - psnr(o, d))
                    bits = os.path.getsize(os.path.join(args.dir, f'k{n}_{rate}.pifs')) * 8
                    side.append(entropy_bits(np.array(indices)) / bits if step else 0)
                label = 'unquantised' if not step else 'steps of 1/8'
                print(f'{rate} bpp, {size} px blocks, {label}: gain {np.mean(gains):.3f} dB '
                      f'({" ".join(f"{g:.2f}" for g in gains)}), side {100 * np.mean(side):.1f}%')


def encode_plane(work, plane, name, budget):
    pgm = os.path.join(work, f'{name}.pgm')
    if not os.path.exists(pgm):
        Image.fromarray(np.clip(np.round(plane), 0, 255).astype(np.uint8)).save(pgm)
    out = os.path.join(work, f'{name}_{budget}')
    if not os.path.exists(out + '.png'):
        subprocess.run([PIFS, 'encode', '--gray', pgm, '--bytes', str(budget), '-o', out + '.pifs'],
                       check=True, capture_output=True)
        subprocess.run([PIFS, 'decode', out + '.pifs', '-o', out + '.png'], check=True, capture_output=True)
    return np.array(Image.open(out + '.png')).astype(float), os.path.getsize(out + '.pifs')


def planes(args):
    work = os.path.join(args.dir, 'planes')
    os.makedirs(work, exist_ok=True)
    for n in args.images:
        o = original(n)
        y, cb, cr = ycc(o)
        h, w = y.shape
        half = lambda c: c.reshape(h // 2, 2, w // 2, 2).mean((1, 3))
        for rate in args.rates:
            total = int(float(rate) * h * w / 8)
            # Budgets as fractions of the whole, so that every rate gets a comparable grid.
            luma = [int(total * f) for f in (0.6, 0.67, 0.73, 0.78, 0.83, 0.88, 0.92, 0.95)]
            full = [int(total * f) for f in (0.01, 0.02, 0.03, 0.05, 0.08, 0.12, 0.16, 0.22)]
            halfb = [int(total * f) for f in (0.005, 0.01, 0.015, 0.025, 0.04, 0.06, 0.09, 0.13)]
            with ThreadPoolExecutor(os.cpu_count()) as ex:
                fy = {b: ex.submit(encode_plane, work, y, f'{n}Y', b) for b in luma}
                f444 = {(c, b): ex.submit(encode_plane, work, p, f'{n}{c}f', b)
                        for b in full for c, p in (('b', cb), ('r', cr))}
                f420 = {(c, b): ex.submit(encode_plane, work, half(p), f'{n}{c}h', b)
                        for b in halfb for c, p in (('b', cb), ('r', cr))}
            for tag, planes_, budgets, up in (('4:4:4', f444, full, lambda x: x),
                                               ('4:2:0', f420, halfb, upsample)):
                best = None
                for by in luma:
                    yd, sy = fy[by].result()
                    for bb in budgets:
                        for br in budgets:
                            cbd, sb = planes_[('b', bb)].result()
                            crd, sr = planes_[('r', br)].result()
                            if sy + sb + sr > total:
                                continue
                            p = psnr(o, to_rgb(yd, up(cbd), up(crd)))
                            if best is None or p > best[0]:
                                best = (p, sy, sb, sr)
                print(f'kodim{n} {rate} bpp {tag} planes: PSNR-RGB {best[0]:.2f} dB '
                      f'(Y {best[1]} B, Cb {best[2]} B, Cr {best[3]} B)', flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('what', choices=('cfl', 'planes'))
    ap.add_argument('dir')
    ap.add_argument('images', nargs='+', help='Kodak numbers, e.g. 03 23')
    ap.add_argument('--rates', default=None, help='comma-separated bpp')
    args = ap.parse_args()
    args.rates = (args.rates or ('0.25,1.0' if args.what == 'cfl' else '1.0')).split(',')
    (cfl if args.what == 'cfl' else planes)(args)


if __name__ == '__main__':
    sys.exit(main())
