"""Real curves from the two DEMs matplotlib ships (its sample data), for bench/curves.sh.

Writes into OUT_DIR, coordinates in metres:
  jacksboro-profile.csv   the elevation along the DEM's middle row (x along the row, y the
                          elevation): a terrain profile at true scale;
  jacksboro-contour.csv   the longest 600 m contour line of the same DEM;
  topobathy-coast.csv     the longest 0 m contour (a coastline) of the topography/bathymetry
                          grid.
Needs numpy and matplotlib (a venv is enough):  python3 extract.py OUT_DIR
"""
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib import cbook  # noqa: E402

EARTH = 6371008.8 * math.pi / 180  # metres per degree of latitude


def longest_contour(x, y, z, level):
    cs = plt.contour(x, y, z, levels=[level])
    paths = [p for p in cs.get_paths()]
    # A path may hold several pieces (MOVETO codes): split them.
    pieces = []
    for p in paths:
        start = 0
        codes = p.codes if p.codes is not None else [1] + [2] * (len(p.vertices) - 1)
        for i, c in enumerate(codes):
            if c == 1 and i > start:
                pieces.append(p.vertices[start:i])
                start = i
        pieces.append(p.vertices[start:])
    plt.close("all")
    return max(pieces, key=len)


def write(path, pts):
    with open(path, "w") as f:
        f.write("x,y\n")
        for x, y in pts:
            f.write(f"{x:.2f},{y:.2f}\n")
    print(f"{path}: {len(pts)} points")


def main(out):
    dem = cbook.get_sample_data("jacksboro_fault_dem.npz")
    z = dem["elevation"].astype(float)
    lat = (float(dem["ymin"]) + float(dem["ymax"])) / 2
    dx = float(dem["dx"]) * EARTH * math.cos(math.radians(lat))
    dy = float(dem["dy"]) * EARTH
    row = z[z.shape[0] // 2]
    write(f"{out}/jacksboro-profile.csv", [(i * dx, v) for i, v in enumerate(row)])
    xs = np.arange(z.shape[1]) * dx
    ys = np.arange(z.shape[0]) * dy
    write(f"{out}/jacksboro-contour.csv", longest_contour(xs, ys, z, 600.0))
    topo = cbook.get_sample_data("topobathy.npz")
    lon, lat = topo["longitude"].astype(float), topo["latitude"].astype(float)
    mx = (lon - lon[0]) * EARTH * math.cos(math.radians(lat.mean()))
    my = (lat - lat[0]) * EARTH
    write(f"{out}/topobathy-coast.csv", longest_contour(mx, my, topo["topo"].astype(float), 0.0))


if __name__ == "__main__":
    main(sys.argv[1])
