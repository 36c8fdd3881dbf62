"""Chroma as one bilinear lattice over the whole picture, continuous by construction (issue 21):
an emulation against the codec's colour streams at the same bytes. Each chroma plane (BT.601
full range, at full resolution) becomes the bilinear interpolation of a lattice of points F
luma pixels apart, their values fitted by least squares (separably), quantised with step Q in
raster order against the median predictor of the values already quantised; its bytes are the
ideal adaptive code length of the quantised residuals (an order-0 model with counts starting
at 1/2 over 64 symbols). The luma is `pifs encode --gray --bytes B - lattice bytes`, decoded. Prints the mean
PSNR-RGB of lattice + luma against `pifs encode --bytes B` (colour), per rate and setting, and
each image's difference.

    python3 bench/experiments/chroma_lattice.py PIFS WORKDIR BPPS F/Q[,F/Q...] IMAGES...

With HYBRID=1 in the environment it also prints a bound of the lattice as a base that chroma
nodes may keep: the colour stream made at the budget less the lattice's bytes, and each of its
chroma nodes (`cargo run --release -p host-encoder --example chroma_nodes`, run from the
repository) given the lattice's chroma or its own, whichever is nearer the original (chosen
by an oracle, no flag paid), with how many nodes took the lattice.

docs/decisions.md ("Leaf edges: what did not work", chroma lattice) quotes it with BPPS
0.05,0.1 and settings 16/4,32/4,32/8 on kodim01, 03, 05, 13, 19 and 23. Needs numpy and
Pillow.
"""
import math
import os
import subprocess
import sys

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.dirname(__file__))
from chroma_seams import ycc  # noqa: E402
from plane_swap import psnr, rgb as rgb_of  # noqa: E402

P = 'pifs'


def interp_matrix(n, f):
    """n pixels, lattice points at 0, f, 2f, ... covering n-1 (pixel centres at integer positions)."""
    m = int(math.ceil((n - 1) / f)) + 1
    A = np.zeros((n, m))
    for i in range(n):
        t = i / f; k = min(int(t), m - 2); u = t - k
        A[i, k] += 1 - u; A[i, k + 1] += u
    return A

def ideal_bits(sym):
    # adaptive order-0 code length (Krichevsky-Trofimov-like), per symbol alphabet grown on the fly
    counts = {}; total = 0; bits = 0.0
    for s in sym:
        c = counts.get(s, 0)
        bits += -math.log2((c + 0.5) / (total + 0.5 * 64))
        counts[s] = c + 1; total += 1
    return bits

def lattice(plane, f, q):
    H, W = plane.shape
    Ay, Ax = interp_matrix(H, f), interp_matrix(W, f)
    C = np.linalg.pinv(Ay) @ plane @ np.linalg.pinv(Ax).T
    h, w = C.shape
    R = np.zeros_like(C); syms = []
    for i in range(h):
        for j in range(w):
            if i and j:
                a, b, c = R[i, j-1], R[i-1, j], R[i-1, j-1]
                pred = min(a, b) if c >= max(a, b) else max(a, b) if c <= min(a, b) else a + b - c
            elif i: pred = R[i-1, j]
            elif j: pred = R[i, j-1]
            else: pred = 128
            k = int(round((C[i, j] - pred) / q)); syms.append(k)
            R[i, j] = pred + k * q
    return Ay @ R @ Ax.T, ideal_bits(syms)

def hybrid(img, o, budget, cbytes, lattice_planes, work, tag):
    """The bound of the docstring: (PSNR-RGB, nodes that took the lattice, nodes)."""
    c = f'{work}/{tag}_h'
    subprocess.run([P, 'encode', img, '-o', c + '.pifs', '--bytes', str(budget - cbytes)], check=True, capture_output=True)
    subprocess.run([P, 'decode', c + '.pifs', '-o', c + '.png'], check=True, capture_output=True)
    nodes = subprocess.run(['cargo', 'run', '-q', '--release', '-p', 'host-encoder', '--example', 'chroma_nodes', '--',
                            os.path.abspath(c + '.pifs')], check=True, capture_output=True, text=True).stdout
    H, W = o.shape[:2]
    _, cb, cr = ycc(o)
    yd, cbd, crd = ycc(np.asarray(Image.open(c + '.png').convert('RGB')))
    cbh, crh = cbd.copy(), crd.copy()
    taken = total = 0
    for line in nodes.splitlines():
        if not line.startswith('C'):
            continue
        x, y, s = (2 * int(v) for v in line.split()[1:])
        at = (slice(y, min(y + s, H)), slice(x, min(x + s, W)))
        own = np.sum((cbd[at] - cb[at]) ** 2) + np.sum((crd[at] - cr[at]) ** 2)
        base = np.sum((lattice_planes[0][at] - cb[at]) ** 2) + np.sum((lattice_planes[1][at] - cr[at]) ** 2)
        total += 1
        if base < own:
            cbh[at], crh[at] = lattice_planes[0][at], lattice_planes[1][at]
            taken += 1
    return psnr(o, rgb_of(yd, cbh, crh)), taken, total


def run(img, bpp, f, q, work):
    o = np.asarray(Image.open(img).convert('RGB')).astype(np.float64)
    H, W = o.shape[:2]
    budget = int(bpp * H * W / 8)
    y, cb, cr = ycc(o)
    cbr, bcb = lattice(cb, f, q); crr, bcr = lattice(cr, f, q)
    cbytes = int(math.ceil((bcb + bcr) / 8))
    name = os.path.basename(img)[:-4]
    g = f'{work}/{name}_{bpp}_{f}_{q}_g'
    subprocess.run([P, 'encode', img, '--gray', '-o', g + '.pifs', '--bytes', str(budget - cbytes)], check=True, capture_output=True)
    subprocess.run([P, 'decode', g + '.pifs', '-o', g + '.png'], check=True, capture_output=True)
    yd = np.asarray(Image.open(g + '.png').convert('L')).astype(float)
    out = rgb_of(yd, cbr, crr)
    Image.fromarray(out.astype(np.uint8)).save(g + '_lat.png')
    c = f'{work}/{name}_{bpp}_c'
    if not os.path.exists(c + '.png'):
        subprocess.run([P, 'encode', img, '-o', c + '.pifs', '--bytes', str(budget)], check=True, capture_output=True)
        subprocess.run([P, 'decode', c + '.pifs', '-o', c + '.png'], check=True, capture_output=True)
    cd = np.asarray(Image.open(c + '.png').convert('RGB')).astype(np.float64)
    mixed = hybrid(img, o, budget, cbytes, (cbr, crr), work, f'{name}_{bpp}_{f}_{q}') if os.environ.get('HYBRID') else None
    return psnr(o, out), psnr(o, cd), cbytes, budget, mixed

if __name__ == '__main__':
    P = sys.argv[1]
    work = sys.argv[2]
    os.makedirs(work, exist_ok=True)
    bpps = [float(b) for b in sys.argv[3].split(',')]
    settings = [tuple(map(float, s.split('/'))) for s in sys.argv[4].split(',')]
    imgs = sys.argv[5:]
    for bpp in bpps:
        for f, q in settings:
            rows = [run(i, bpp, int(f), q, work) for i in imgs]
            a = np.mean([r[0] for r in rows]); b = np.mean([r[1] for r in rows]); cb = np.mean([r[2] / r[3] for r in rows])
            print(f'{bpp} bpp lattice {int(f)} px step {q}: PSNR-RGB lattice {a:.3f} codec {b:.3f} ({a-b:+.3f}); chroma {100*cb:.1f}% of bytes; ' +
                  ' '.join(f'{r[0]-r[1]:+.2f}' for r in rows), flush=True)
            if rows[0][4]:
                m = np.mean([r[4][0] for r in rows])
                print(f'  hybrid bound {m:.3f} ({m-b:+.3f}); per image ' +
                      ' '.join(f'{r[4][0]-r[1]:+.2f} ({r[4][1]}/{r[4][2]} nodes)' for r in rows), flush=True)
