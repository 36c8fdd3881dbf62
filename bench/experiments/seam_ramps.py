#!/usr/bin/env python3
"""seam_ramps.py - issue 21 exploration: would spreading the step across a leaf edge over more
of the later leaf's rows (a ramp whose length grows with the leaf) hide the leaf grid better
than format 12's three-way split of one pixel each side, at the same PSNR? A post-filter on
decodes made without smoothing, judged by PSNR, SSIM and the grid measure B_g of
bench/seams.py. Not part of the codec (see docs/decisions.md, "Leaf edges: what did not work").

Inputs, with any build of `pifs`:

    pifs encode IMAGE --gray --bpp R --deblock 0 -o S.pifs
    pifs decode S.pifs -o S.png
    pifs info S.pifs --svg S.svg            (the leaves, in coding order)
    python3 bench/experiments/seam_ramps.py ORIGINAL S.png S.svg one,s8,hs8,hs4 8,16,32,64 [OUT]

Rules (comma-separated), for each leaf's top and left edge, each pixel pair (p beside the
leaf, q0 its first row or column, q1... the next) with step D = q0 - p, |D| <= T grey levels:
  one  p += D/3, q0 -= D/3 (format 12's rule, with a fixed threshold instead of the stream's);
  s8   a linear ramp over L = max(1, size/8) rows of the leaf: p += D/(L+2),
       q_j -= D (L-j)/(L+2);
  s4   the same with L = max(1, min(8, size/4));
  s8c  as s8 with L at most 8 (a ramp inside the leaf's first tile row or column);
  s4u  as s4 without the cap of 8;
  h... (hs8, hs4) p and q0 move by D/3 as in `one`, then q_j by D/3 (L-j)/L for j < L.
Prints PSNR, SSIM, [B_4, B_8, B_16] and B_16s (bench/seams.py: B_16 over the original's smooth
parts) per rule and threshold T (second list); with OUT, writes OUT_<rule>_<T>.png.
"""
import os, sys, re, numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..'))
from seams import ssim, grid_measure, psnr, smooth_grid_measure
from PIL import Image

def leaves(svg):
    out = []
    for m in re.finditer(r'<rect class="leaf"[^>]* x="([\d.]+)" y="([\d.]+)" width="(\d+)"', open(svg).read()):
        out.append((int(float(m.group(1))), int(float(m.group(2))), int(m.group(3)) + 1))
    return out

def rampfn(rule, s):
    if rule == 'one': return 1
    if rule == 's8': return max(1, s // 8)
    if rule == 's4': return max(1, min(8, s // 4))
    if rule == 's4u': return max(1, s // 4)
    if rule == 's8c': return max(1, min(8, s // 8))

def filt(rec, lv, T, rule):
    HYB = rule.startswith('h')
    rule = rule.lstrip('h')
    out = rec.copy()
    H, W = out.shape
    for (x, y, s) in lv:
        L = rampfn(rule, s)
        w_, h_ = min(s, W - x), min(s, H - y)
        for axis in (0, 1):
            if axis == 0:
                if y == 0: continue
                p = out[y - 1, x:x + w_]; q = out[y:y + h_, x:x + w_]
            else:
                if x == 0 or x % 512 == 0: continue
                p = out[y:y + h_, x - 1]; q = out[y:y + h_, x:x + w_].T
            D = q[0] - p
            m = np.abs(D) <= T
            Dm = np.where(m, D, 0)
            if HYB:
                p += np.round(Dm / 3)
                for j in range(min(L, q.shape[0])):
                    q[j] -= np.round(Dm * (L - j) / (3 * L))
            else:
                p += np.round(Dm / (L + 2))
                for j in range(min(L, q.shape[0])):
                    q[j] -= np.round(Dm * (L - j) / (L + 2))
    return np.clip(out, 0, 255)

if __name__ == '__main__':
    orig = np.asarray(Image.open(sys.argv[1]).convert('L')).astype(float)
    rec = np.asarray(Image.open(sys.argv[2]).convert('L')).astype(float)
    lv = leaves(sys.argv[3])
    print('none', round(psnr(orig, rec), 3), round(ssim(orig, rec), 4), [round(grid_measure(rec, g), 3) for g in (4, 8, 16)],
          round(smooth_grid_measure(orig, rec), 3))
    for rule in sys.argv[4].split(','):
        for T in [float(t) for t in sys.argv[5].split(',')]:
            f = filt(rec, lv, T, rule)
            print(rule, T, round(psnr(orig, f), 3), round(ssim(orig, f), 4), [round(grid_measure(f, g), 3) for g in (4, 8, 16)],
                  round(smooth_grid_measure(orig, f), 3))
            if len(sys.argv) > 6:
                Image.fromarray(f.astype(np.uint8)).save(f'{sys.argv[6]}_{rule}_{T}.png')
