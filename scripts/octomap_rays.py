"""OctoMap beside mema on held-out rays (`mema bench --only free-space`, issue 29).

Reads what the benchmark wrote in DIR (manifest.json; little-endian f64 arrays: each mapped
frame's world points, the held-out rays as origin and end, the sample points), builds an
OcTree with insertPointCloud (every ray cast: free voxels along it, its end occupied) at the
finest resolution whose binary tree (writeBinary) fits BYTES, then answers for each held-out
ray its first occupied voxel (castRay; the range is where the ray enters that voxel) and for
each sample its state. Prints one JSON object; mema scores it with the same function as its
own maps.
"""

import json
import os
import sys
import tempfile
import time

import numpy as np
import pyoctomap


def load(path, width):
    return np.fromfile(path, dtype="<f8").reshape(-1, width)


def build(frames, resolution):
    tree = pyoctomap.OcTree(resolution)
    start = time.perf_counter()
    for points, origin in frames:
        tree.insertPointCloud(points, origin)
    elapsed = time.perf_counter() - start
    return tree, elapsed


def binary_bytes(tree):
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "t.bt")
        tree.writeBinary(path)
        return os.path.getsize(path)


def entry_range(origin, direction, centre, half):
    """Where the ray enters the voxel's box (slab test); 0 if it starts inside."""
    lo, hi = centre - half, centre + half
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo - origin) / direction
        t2 = (hi - origin) / direction
    near = np.nanmax(np.minimum(t1, t2))
    return max(float(near), 0.0)


def main():
    directory, budget = sys.argv[1], int(sys.argv[2])
    manifest = json.load(open(os.path.join(directory, "manifest.json")))
    tol = manifest["tolerance"]
    frames = [
        (load(os.path.join(directory, f["points"]), 3), np.array(f["origin"], dtype=np.float64))
        for f in manifest["frames"]
    ]
    # The finest resolution whose tree fits the budget: the size falls as voxels grow, so a
    # bisection on the logarithm of the resolution, between 1 cm and 50 m.
    lo, hi = np.log(0.01), np.log(50.0)
    best = None
    for _ in range(14):
        mid = 0.5 * (lo + hi)
        tree, _ = build(frames, float(np.exp(mid)))
        size = binary_bytes(tree)
        if size <= budget:
            best = float(np.exp(mid))
            hi = mid
        else:
            lo = mid
    if best is None:
        best = float(np.exp(hi))
    tree, insert_s = build(frames, best)
    size = binary_bytes(tree)
    rays = load(os.path.join(directory, "rays.f64"), 6)
    samples = load(os.path.join(directory, "samples.f64"), 3)
    hits = []
    half = 0.5 * best
    end = np.zeros(3, dtype=np.float64)
    start = time.perf_counter()
    for ray in rays:
        origin, stop = ray[:3], ray[3:]
        span = stop - origin
        rng = float(np.linalg.norm(span))
        direction = span / rng
        hit = tree.castRay(origin, direction, end, True, rng + tol)
        if hit:
            t = entry_range(origin, direction, np.array(end), half)
            hits.append(t if t <= rng + tol else None)
        else:
            hits.append(None)
    states = []
    for p in samples:
        node = tree.search(p)
        if node is None:
            states.append(2)
        else:
            states.append(1 if tree.isNodeOccupied(node) else 0)
    query_s = time.perf_counter() - start
    print(
        json.dumps(
            {
                "pyoctomap": getattr(pyoctomap, "__version__", None),
                "resolution": best,
                "bytes": size,
                "insert_s": insert_s,
                "points": int(sum(len(f[0]) for f in frames)),
                "query_s": query_s,
                "hits": hits,
                "states": states,
            }
        )
    )


if __name__ == "__main__":
    main()
