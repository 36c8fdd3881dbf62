#!/usr/bin/env python3
"""seam_filters.py - the exploration behind format version 12's edge smoothing (see
docs/decisions.md, "Leaf edges"): post-filters on format-11 decodes, judged by PSNR, SSIM and the
grid measure B_g of bench/seams.py.

Not part of the codec. It needs, per image and rate, the format-11 decode and the stream's
leaves in coding order (x y size model cquant transform per line), which a build of commit
74fd1f3 produces: `pifs encode` / `pifs decode`, and an example printing
`Decoder::observe`'s leaves. Layout: DIR/<image>/{orig.pgm, pifs_<rate>.pgm, leaves_<rate>.txt}.

    python3 bench/experiments/seam_filters.py DIR
"""
import sys, os, collections, math
import numpy as np
from PIL import Image
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..'))
from seams import ssim, grid_measure, psnr

STEPS = [24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024, 1536, 2048]
IMAGES = ['kodim01', 'kodim03', 'kodim05', 'kodim08', 'kodim13', 'kodim19', 'kodim23']
RATES = ['0.05', '0.1', '0.25', '0.5']


def load(root, img, r):
    d = os.path.join(root, img)
    rec = np.asarray(Image.open(f'{d}/pifs_{r}.pgm')).astype(np.float64)
    orig = np.asarray(Image.open(f'{d}/orig.pgm')).astype(np.float64)
    leaves = [tuple(int(v) if v not in ('true', 'false') else v == 'true' for v in l.split())
              for l in open(f'{d}/leaves_{r}.txt')]
    return orig, rec, leaves


def edge(out, rec, orig, x, y, s, axis):
    """The pixels beside a leaf's top (axis 0) or left (axis 1) edge and its first rows."""
    H, W = rec.shape
    if axis == 0:
        if y == 0:
            return None
        xs = slice(x, min(x + s, W))
        return (out[y - 1, xs].copy(), out[y:min(y + s, H), xs].copy(),
                orig[y - 1, xs], orig[y:min(y + s, H), xs])
    if x == 0:
        return None
    ys = slice(y, min(y + s, H))
    return (out[ys, x - 1].copy(), out[ys, x:min(x + s, W)].T.copy(),
            orig[ys, x - 1], orig[ys, x:min(x + s, W)].T)


def put(out, x, y, axis, p0, q):
    if axis == 0:
        out[y - 1, x:x + p0.shape[0]] = p0
        out[y:y + q.shape[0], x:x + q.shape[1]] = q
    else:
        out[y:y + p0.shape[0], x - 1] = p0
        out[y:y + q.shape[1], x:x + q.shape[0]] = q.T


def spread(p0, q, d, n):
    """Step d spread over the n + 2 gaps from the pixel before p0 to q[n]: p0 and q[0..n) move."""
    tot = n + 2
    q2 = q.copy()
    for j in range(n):
        q2[j] = q[j] + d * ((j + 2) / tot) - d
    return p0 + d / tot, q2


def two_sided(rec, orig, leaves, choose):
    """Each leaf's top and left edges, in coding order: `choose(s, cq, p0, q, op, oq)` gives the
    filter length (0: none) and the step to spread."""
    out = rec.copy()
    choices = []
    for (x, y, s, model, cq, tr) in leaves:
        for axis in (0, 1):
            e = edge(out, rec, orig, x, y, s, axis)
            if e is None or e[1].shape[0] < 2:
                continue
            p0, q, op, oq = e
            n, d = choose(s, cq, p0, q, op, oq)
            choices.append((s, n))
            if n > 0:
                p0, q = spread(p0, q, d, min(n, q.shape[0] - 1))
                put(out, x, y, axis, p0, q)
    return np.clip(np.round(out), 0, 255), choices


def fixed(n, tstep):
    def choose(s, cq, p0, q, op, oq):
        d = q[0] - p0
        return n, np.where(np.abs(d) > tstep * STEPS[cq] / 16, 0, d)
    return choose


def greedy(lengths):
    """The length that minimises the squared error (what an encoder signalling it would do)."""
    def choose(s, cq, p0, q, op, oq):
        d = q[0] - p0
        best = (np.sum((p0 - op) ** 2) + np.sum((q - oq) ** 2), 0)
        for n in lengths:
            n = min(n, q.shape[0] - 1)
            np0, nq = spread(p0, q, d, n)
            e = np.sum((np0 - op) ** 2) + np.sum((nq - oq) ** 2)
            if e < best[0]:
                best = (e, n)
        return best[1], d
    return choose


def report(name, root, choose_for_image):
    for r in RATES:
        acc, side = [], collections.Counter()
        for img in IMAGES:
            orig, rec, leaves = load(root, img, r)
            out = choose_for_image(orig, rec, leaves)
            acc.append((psnr(orig, out), ssim(orig, out), grid_measure(out, 4),
                        grid_measure(out, 8), grid_measure(out, 16)))
        print(name, r, 'PSNR %.3f SSIM %.4f B4 %.3f B8 %.3f B16 %.3f' % tuple(np.mean(acc, axis=0)),
              flush=True)


def main():
    root = sys.argv[1]
    report('none', root, lambda o, rec, l: rec)
    report('two-sided, 1 px, at most 2 steps', root,
           lambda o, rec, l: two_sided(rec, o, l, fixed(1, 2.0))[0])
    report('two-sided, per-edge length by squared error (signalling not counted)', root,
           lambda o, rec, l: two_sided(rec, o, l, greedy((1, 2, 4, 8)))[0])

    def per_image(o, rec, l):
        # The strongest threshold that does not lower the PSNR: the chosen rule.
        base = psnr(o, rec)
        best = rec
        for t in (0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0):
            out = two_sided(rec, o, l, fixed(1, t))[0]
            if psnr(o, out) >= base:
                best = out
        return best
    report('two-sided, 1 px, strongest threshold that keeps the PSNR', root, per_image)


if __name__ == '__main__':
    main()
