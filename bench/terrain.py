"""Terrain heightmaps (issue 26): bits per sample against the error in the data's units, PIFS
beside OpenJPEG (JPEG 2000, 16-bit lossy) at the same bytes, on the two real DEMs matplotlib
ships and on fBm terrain from midpoint displacement.

PIFS gets the DEM as a 16-bit PGM (`round(z - min)`, maxval 65535) and codes it as a 16-bit
stream (format 19: the range in the header, values decoded from the synthesis's 1/16 grey
level): `pifs encode --tune psnr --bytes N`, `pifs decode` to a 16-bit PGM. Beside it, the
8-bit path of format 18 (column "8-bit dB"): the range mapped linearly onto 0..255
(`round((z - min) * 255 / (max - min))`), coded with `--gray --depth 8`, decoded to 8 bits and
mapped back, the range's 4 bytes counted. OpenJPEG gets the same 16-bit PGM as PIFS (maxval
the range), `opj_compress -I -r R` (9/7 irreversible wavelet), R bisected for the largest
codestream within the budget.

Errors against the original values: RMSE and largest absolute error in the data's units
(metres for the DEMs), and PSNR relative to the data's range, `20 log10(range / RMSE)` (the
thesis's measure for surfaces). Writes a markdown table to stdout, rows to CSV, and
hillshaded views (original / PIFS / JPEG 2000) of each DEM at one rate.

    python3 bench/terrain.py [--pifs target/release/pifs] [--rates 0.1,0.25,0.5,1,2]
        [--out target/bench-terrain] [--csv bench/results/terrain.csv]

Needs numpy, matplotlib (for its sample data only) and pillow, plus opj_compress and
opj_decompress.
"""
import argparse
import math
import os
import subprocess
import sys

import numpy as np
from PIL import Image


def dems():
    """The real DEMs matplotlib ships, as float arrays in metres."""
    from matplotlib import cbook

    jacksboro = cbook.get_sample_data("jacksboro_fault_dem.npz")["elevation"]
    topobathy = cbook.get_sample_data("topobathy.npz")["topo"]
    return [
        ("jacksboro", "Jacksboro fault DEM (3 arc-seconds), metres",
         np.asarray(jacksboro, dtype=np.float64)),
        ("topobathy", "topography and bathymetry, Strait of Georgia, metres",
         np.asarray(topobathy, dtype=np.float64)),
        ("fbm", "fBm by midpoint displacement, 257x257, H = 0.8, seed 7, 16-bit units",
         midpoint_displacement(8, 0.8, 7)),
    ]


def midpoint_displacement(levels, hurst, seed):
    """Fractional Brownian surface of side 2^levels + 1 by the diamond-square midpoint
    displacement (random additions halved in amplitude by 2^-H per level), scaled to 0..65535.
    """
    rng = np.random.default_rng(seed)
    n = 2 ** levels
    z = np.zeros((n + 1, n + 1))
    z[0, 0], z[0, n], z[n, 0], z[n, n] = rng.normal(size=4)
    step, scale = n, 1.0
    while step > 1:
        half = step // 2
        scale *= 0.5 ** hurst
        # Diamond: the centre of each square.
        for y in range(half, n, step):
            for x in range(half, n, step):
                mean = (z[y - half, x - half] + z[y - half, x + half]
                        + z[y + half, x - half] + z[y + half, x + half]) / 4
                z[y, x] = mean + scale * rng.normal()
        # Square: the midpoints of the edges.
        for y in range(0, n + 1, half):
            for x in range((y + half) % step, n + 1, step):
                around = [z[y + dy, x + dx] for dy, dx in ((-half, 0), (half, 0), (0, -half), (0, half))
                          if 0 <= y + dy <= n and 0 <= x + dx <= n]
                z[y, x] = sum(around) / len(around) + scale * rng.normal()
        step = half
    z -= z.min()
    return np.round(z * 65535 / z.max())


def write_pgm(path, a, maxval):
    h, w = a.shape
    with open(path, "wb") as f:
        f.write(b"P5\n%d %d\n%d\n" % (w, h, maxval))
        if maxval < 256:
            f.write(a.astype(np.uint8).tobytes())
        else:
            f.write(a.astype(">u2").tobytes())


def read_pnm(path):
    """An 8- or 16-bit PGM as floats, samples as written: pillow rescales a 16-bit PGM whose
    maxval is below 65535, as OpenJPEG writes them."""
    with open(path, "rb") as f:
        data = f.read()
    fields, pos = [], 0
    while len(fields) < 4:
        while data[pos:pos + 1].isspace():
            pos += 1
        if data[pos:pos + 1] == b"#":
            pos = data.index(b"\n", pos)
            continue
        end = pos
        while not data[end:end + 1].isspace():
            end += 1
        fields.append(data[pos:end])
        pos = end
    pos += 1
    w, h, maxval = int(fields[1]), int(fields[2]), int(fields[3])
    dtype = np.uint8 if maxval < 256 else np.dtype(">u2")
    return np.frombuffer(data[pos:], dtype=dtype, count=w * h).reshape(h, w).astype(np.float64)


def run(cmd):
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def errors(z, rec):
    e = rec - z
    rmse = math.sqrt(float(np.mean(e * e)))
    span = float(z.max() - z.min())
    psnr = math.inf if rmse == 0 else 20 * math.log10(span / rmse)
    return rmse, float(np.abs(e).max()), psnr


def pifs_at(pifs, z, budget, work):
    """PIFS's 16-bit stream of the DEM within `budget` bytes."""
    lo = float(z.min())
    src, stream, dec = (os.path.join(work, n) for n in ("pifs16-in.pgm", "x16.pifs", "x16.pgm"))
    write_pgm(src, np.round(z - lo), 65535)
    run([pifs, "encode", src, "--tune", "psnr", "--bytes", str(budget), "-o", stream])
    run([pifs, "decode", stream, "-o", dec])
    return os.path.getsize(stream), lo + read_pnm(dec)


def pifs8_at(pifs, z, budget, work):
    """PIFS on the 8-bit range-mapped DEM within `budget` bytes (4 of them the range)."""
    lo, hi = float(z.min()), float(z.max())
    mapped = np.round((z - lo) * 255 / (hi - lo))
    src, stream, dec = (os.path.join(work, n) for n in ("pifs-in.pgm", "x.pifs", "x.pgm"))
    write_pgm(src, mapped, 255)
    run([pifs, "encode", src, "--gray", "--depth", "8", "--tune", "psnr", "--bytes", str(budget - 4),
         "-o", stream])
    run([pifs, "decode", stream, "-o", dec])
    rec = lo + read_pnm(dec) * (hi - lo) / 255
    return os.path.getsize(stream) + 4, rec


def j2k_at(z, budget, work):
    """OpenJPEG (9/7, 16-bit PGM in) with the largest codestream within `budget` bytes."""
    lo = float(z.min())
    ints = np.round(z - lo)
    span = int(ints.max())
    src, stream, dec = (os.path.join(work, n) for n in ("j2k-in.pgm", "x.j2k", "x-j2k.pgm"))
    write_pgm(src, ints, max(span, 256))
    best = None
    a, b = 1.0, 4000.0  # compression ratios: a is too large a stream, b small enough
    for _ in range(40):
        r = math.sqrt(a * b)
        run(["opj_compress", "-i", src, "-o", stream, "-I", "-r", "%.6f" % r])
        size = os.path.getsize(stream)
        if size <= budget:
            b = r
            if best is None or size > best[0]:
                run(["opj_decompress", "-i", stream, "-o", dec])
                best = (size, lo + read_pnm(dec))
        else:
            a = r
        if b / a < 1.0005:
            break
    return best  # None: OpenJPEG's smallest codestream is larger than the budget


def relief_scale(z):
    """The vertical scale that gives the original's median slope 20 degrees: one scale for
    every view of a surface, so that they compare."""
    gy, gx = np.gradient(z)
    return math.tan(math.radians(20)) / max(float(np.median(np.hypot(gx, gy))), 1e-9)


def hillshade(z, scale, azimuth=315.0, altitude=45.0):
    """Lambertian hillshade (light from the north-west, 45 degrees up) of `z` times `scale`,
    8-bit."""
    gy, gx = np.gradient(z * scale)
    slope = np.pi / 2 - np.arctan(np.hypot(gx, gy))
    aspect = np.arctan2(-gx, gy)
    az, alt = math.radians(azimuth), math.radians(altitude)
    shade = np.sin(alt) * np.sin(slope) + np.cos(alt) * np.cos(slope) * np.cos(az - aspect)
    return np.clip(255 * shade, 0, 255).astype(np.uint8)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pifs", default="target/release/pifs")
    ap.add_argument("--rates", default="0.1,0.25,0.5,1,2")
    ap.add_argument("--out", default="target/bench-terrain")
    ap.add_argument("--csv", default="bench/results/terrain.csv")
    ap.add_argument("--views", default="0.25", help="the rate of the hillshaded views")
    args = ap.parse_args()
    rates = [float(r) for r in args.rates.split(",")]
    os.makedirs(args.out, exist_ok=True)
    rows = []
    print("| surface | size | range | bits/sample | PIFS bytes | PIFS RMSE | PIFS max | PIFS dB "
          "| 8-bit dB | J2K bytes | J2K RMSE | J2K max | J2K dB |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name, what, z in dems():
        h, w = z.shape
        span = z.max() - z.min()
        mapped = z.min() + np.round((z - z.min()) * 255 / span) * span / 255
        q = errors(z, mapped)
        print(f"{name}: {what}; {w}x{h}, {z.min():.0f} to {z.max():.0f}; the 8-bit mapping alone: "
              f"RMSE {q[0]:.2f}, max {q[1]:.1f}, {q[2]:.2f} dB", file=sys.stderr)
        for rate in rates:
            budget = int(rate * w * h / 8)
            pb, prec = pifs_at(args.pifs, z, budget, args.out)
            p8 = errors(z, pifs8_at(args.pifs, z, budget, args.out)[1])
            j2k = j2k_at(z, budget, args.out)
            p = errors(z, prec)
            if j2k is None:
                jb, j, jcells = "", ("", "", ""), "| - | - | - | - |"
            else:
                jb, jrec = j2k
                j = errors(z, jrec)
                jcells = f"| {jb} ({8 * jb / (w * h):.3f}) | {j[0]:.2f} | {j[1]:.1f} | {j[2]:.2f} |"
            rows.append((name, w, h, span, rate, pb, *p, p8[2], jb, *j))
            print(f"| {name} | {w}x{h} | {span:.0f} | {rate:g} | {pb} ({8 * pb / (w * h):.3f}) "
                  f"| {p[0]:.2f} | {p[1]:.1f} | {p[2]:.2f} | {p8[2]:.2f} {jcells}", flush=True)
            if f"{rate:g}" == args.views and j2k is not None:
                scale = relief_scale(z)
                views = [hillshade(a, scale) for a in (z, prec, jrec)]
                Image.fromarray(np.hstack(views)).save(os.path.join(args.out, f"{name}-{rate:g}-hillshade.png"))
    with open(args.csv, "w") as f:
        f.write("surface,width,height,range,rate,pifs_bytes,pifs_rmse,pifs_max,pifs_psnr,"
                "pifs8_psnr,j2k_bytes,j2k_rmse,j2k_max,j2k_psnr\n")
        for r in rows:
            f.write(",".join(f"{v:.4f}" if isinstance(v, float) else str(v) for v in r) + "\n")
    print(f"views (original / PIFS / JPEG 2000, hillshaded): {args.out}/*-hillshade.png", file=sys.stderr)


if __name__ == "__main__":
    main()
