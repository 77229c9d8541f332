"""OctoMap side of `ember-bench map`: inserts the same frames into OctoMap and dumps its leaves.

Usage: python octomap_peer.py FRAMES RES MAX_RANGE LEAVES_OUT [--discretize]
FRAMES: little-endian binary, per frame: u32 n, f64 origin[3], f32 points[n][3] (world frame).
Prints one line per frame "ms <float>"; writes every known leaf voxel as
"ix iy iz occupied" lines (keys floor(coord / res), pruned nodes expanded) to LEAVES_OUT.
"""
import struct
import sys
import time

import numpy as np
import octomap


def main():
    path, res, max_range, out = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
    discretize = "--discretize" in sys.argv
    tree = octomap.OcTree(res)
    data = open(path, "rb").read()
    pos = 0
    while pos < len(data):
        (n,) = struct.unpack_from("<I", data, pos)
        origin = np.array(struct.unpack_from("<3d", data, pos + 4), dtype=np.float64)
        pos += 4 + 24
        pts = np.frombuffer(data, dtype="<f4", count=3 * n, offset=pos).reshape(n, 3).astype(np.float64)
        pos += 12 * n
        t = time.perf_counter()
        tree.insertPointCloud(pts, origin, maxrange=max_range, discretize=discretize)
        print("ms %.3f" % ((time.perf_counter() - t) * 1e3), flush=True)
    with open(out, "w") as f:
        for it in tree.begin_leafs():
            size = it.getSize()
            c = it.getCoordinate()
            occ = 1 if tree.isNodeOccupied(it) else 0
            cells = int(round(size / res))
            lo = [int(np.floor((c[a] - size / 2) / res + 0.5)) for a in range(3)]
            for x in range(cells):
                for y in range(cells):
                    for z in range(cells):
                        f.write("%d %d %d %d\n" % (lo[0] + x, lo[1] + y, lo[2] + z, occ))


if __name__ == "__main__":
    main()
