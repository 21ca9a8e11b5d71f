"""`mema.tiles`: an archive of LAS/LAZ files mapped tile by tile on Dask, merged into one map.

    python -m mema.tiles a.laz b.laz --tile 100 --bytes 96000 -o archive.mema [--workers 2]
    python -m mema.tiles a.laz --tile 100 -k 5000 -o archive.mema --scheduler tcp://host:8786

or, from Python, ``mema.tiles.map_tiles([...], tile=100, bytes=96000)`` which gives a ``mema.Map``.

How it goes, each step a Dask task:

1. scan: each file is read once and its points counted per tile (squares of ``tile`` metres in
   x and y, on a grid anchored at 0 so no file needs another's bounds) and, within a tile, per
   band: the points within ``seam / 2`` of a tile edge, by the nearest edge, else the interior.
2. The client shares the whole archive's budget among the tiles' interiors and the seams (the
   bands on both sides of an edge between two tiles that have points) by their point counts.
3. tile: each tile reads only the files that have points in it, keeps that tile's points
   (memory per worker is the tile, plus one file as it is read), maps its interior with its
   share, and hands the seam points on.
4. seam: the points of both sides of each edge are mapped together, so no entity is cut in two
   at a tile boundary: a seam's entities are fitted across it from the points near it.
5. The maps are merged (``mema._mema.merge``) in a fixed order, tiles then seams by position.

Every task is a pure function of its inputs and seed, so a worker lost mid-run has its tasks
rerun by Dask elsewhere and the merged map is the same, byte for byte. Progress is Dask's own
(``distributed.progress``; the dashboard of a running cluster shows the same tasks).
"""

import argparse
import operator
import sys

import numpy as np

import mema

# Bytes of one entity's record in a map file: the quantized records of the shells model, the
# f32 records of the paper's (`mema.map`'s `bytes=` divides by the same, header aside).
BYTES_PER_ENTITY = {False: 14, True: 24}
# `mema.map` fits no more clusters than a quarter of the points: fewer points have no shape.
MIN_POINTS_PER_ENTITY = 4
# Bands of a tile's points: by the edge they are nearest to, within half a seam.
INTERIOR, LEFT, RIGHT, BOTTOM, TOP = range(5)


def _cells(xy, tile):
    """Each point's tile, as integer (i, j): squares of `tile` metres anchored at 0."""
    return np.floor(xy / tile).astype(np.int64)


def _bands(xy, cells, tile, seam):
    """Each point's band in its tile (INTERIOR, or the edge it is within `seam / 2` of)."""
    low = xy - cells * tile
    high = (cells + 1) * tile - xy
    near = np.stack([low[:, 0], high[:, 0], low[:, 1], high[:, 1]], axis=1)
    edge = np.argmin(near, axis=1)
    band = edge + 1
    band[near[np.arange(len(edge)), edge] >= seam / 2] = INTERIOR
    return band


def _points(path, units, classes=None, outliers=None):
    return np.asarray(mema.read_cloud(path, units, classes=classes, outliers=outliers))


def scan(path, tile, seam, units=None, classes=None, outliers=None):
    """Counts a file's points per (tile i, tile j, band): a dict of int counts."""
    points = _points(path, units, classes, outliers)
    xy = points[:, :2]
    cells = _cells(xy, tile)
    bands = _bands(xy, cells, tile, seam)
    keys = np.column_stack([cells, bands])
    unique, counts = np.unique(keys, axis=0, return_counts=True)
    return {tuple(int(v) for v in key): int(n) for key, n in zip(unique, counts)}


def _neighbour(cell, band):
    """The tile across `band`'s edge of `cell`, and the seam's key (axis, i, j): the edge at
    x = i * tile (axis 0) between tiles (i-1, j) and (i, j), or at y = j * tile (axis 1)."""
    i, j = cell
    return {
        LEFT: ((i - 1, j), (0, i, j)),
        RIGHT: ((i + 1, j), (0, i + 1, j)),
        BOTTOM: ((i, j - 1), (1, i, j)),
        TOP: ((i, j + 1), (1, i, j + 1)),
    }[band]


def plan(counts):
    """From the scans' merged counts: each tile's interior count, each seam's count, and each
    tile's open bands (those whose edge borders another tile with points; a band on the
    archive's edge stays in its tile's interior)."""
    tiles = {}
    for (i, j, _), n in counts.items():
        tiles[(i, j)] = tiles.get((i, j), 0) + n
    interior = {cell: 0 for cell in tiles}
    seams, open_bands = {}, {cell: [] for cell in tiles}
    for (i, j, band), n in sorted(counts.items()):
        if band == INTERIOR:
            interior[(i, j)] += n
            continue
        other, key = _neighbour((i, j), band)
        if other in tiles:
            seams[key] = seams.get(key, 0) + n
            open_bands[(i, j)].append(band)
        else:
            interior[(i, j)] += n
    return interior, seams, open_bands


def share(total, counts):
    """`total` entities shared by point counts (largest remainders, ties to the earlier key),
    none past a quarter of a part's points: {key: k}. Keys are sorted, so it is deterministic."""
    keys = sorted(counts)
    points = sum(counts.values())
    if points == 0:
        return {key: 0 for key in keys}
    exact = [total * counts[key] / points for key in keys]
    k = [int(e) for e in exact]
    order = sorted(range(len(keys)), key=lambda a: (-(exact[a] - k[a]), a))
    for a in order[: total - sum(k)]:
        k[a] += 1
    return {key: min(n, counts[key] // MIN_POINTS_PER_ENTITY) for key, n in zip(keys, k)}


def _map_bytes(points, k, options):
    """The `.mema` bytes of `points` mapped into `k` entities, or None for no entity."""
    if k == 0 or len(points) == 0:
        return None
    return mema.map(points, k=k, **options).to_bytes()


def map_tile(
    cell, paths, tile, seam, open_bands, k, options, units=None, classes=None, outliers=None
):
    """Reads the tile's points from `paths`, maps its interior into `k` entities, and gives
    (map bytes or None, {seam key: that side's points})."""
    parts = []
    for path in paths:
        points = _points(path, units, classes, outliers)
        inside = np.all(_cells(points[:, :2], tile) == np.asarray(cell), axis=1)
        parts.append(points[inside])
        del points  # one file at a time, besides the tile
    points = np.concatenate(parts)
    bands = _bands(points[:, :2], _cells(points[:, :2], tile), tile, seam)
    sides = {}
    interior = np.ones(len(points), dtype=bool)
    for band in open_bands:
        mine = bands == band
        sides[_neighbour(cell, band)[1]] = points[mine]
        interior &= ~mine
    return _map_bytes(points[interior], k, options), sides


def map_seam(key, tiles, k, options):
    """Maps the points of both sides of seam `key` (from the two tiles' results) together; a
    side with no point within half a seam of the edge has none to give."""
    points = np.concatenate([t[1][key] for t in tiles if key in t[1]])
    return _map_bytes(points, k, options)


def _tiles_of_seam(key):
    axis, i, j = key
    return [(i - 1, j), (i, j)] if axis == 0 else [(i, j - 1), (i, j)]


def map_tiles(
    paths,
    tile,
    bytes=None,
    k=None,
    seam=None,
    client=None,
    workers=None,
    scheduler=None,
    progress=False,
    seed=0,
    paper=False,
    units=None,
    classes=None,
    outliers=None,
    **options,
):
    """Maps LAS/LAZ files (or any cloud `mema.read_cloud` reads) tile by tile on Dask into one
    `mema.Map`: tiles of `tile` metres, a budget of `bytes` (or `k` entities) for the whole
    archive, seams `seam` metres wide (default a tenth of a tile) mapped across tile edges.
    Runs on `client` (a `distributed.Client`), else on the cluster at `scheduler`, else on a
    new local cluster of `workers` processes (default 2), one thread each. `options` are
    `mema.map`'s keywords. `units`, `classes` and `outliers` read each file as
    `mema.read_cloud` does (`classes`: which LAS/LAZ points to keep, as `--classes`; by default
    all but noise and withheld points; `outliers`: as `mema map --outliers`, by default isolated
    points dropped). `progress=True` shows Dask's progress bar."""
    from distributed import Client, LocalCluster
    from distributed import progress as show_progress

    paths = [str(p) for p in ([paths] if isinstance(paths, str) else paths)]
    if not paths:
        raise ValueError("paths: give at least one file to map")
    if not tile > 0:
        raise ValueError(f"tile: {tile} is no positive size in metres")
    seam = tile / 10 if seam is None else seam
    if not 0 <= seam < tile:
        raise ValueError(f"seam: {seam} must be at least 0 and less than the tile ({tile})")
    if (bytes is None) == (k is None):
        raise ValueError("bytes, k: give exactly one, the budget of the whole archive")
    total = k if bytes is None else bytes // BYTES_PER_ENTITY[bool(paper)]
    if total < 1:
        raise ValueError(f"bytes: {bytes} bytes hold no entity; consider a larger budget")
    options = dict(options, seed=seed, paper=paper)

    own = None
    if client is None:
        if scheduler is not None:
            client = own = Client(scheduler)
        else:
            # One thread a worker, and one for mema's own threads (rayon): a worker is a core.
            cluster = LocalCluster(
                n_workers=workers or 2,
                threads_per_worker=1,
                processes=True,
                env={"RAYON_NUM_THREADS": "1"},
                dashboard_address=None,
            )
            client = own = Client(cluster)
    try:
        reading = (units, classes, outliers)
        return _run(client, paths, tile, seam, total, options, reading, progress, show_progress)
    finally:
        if own is not None:
            cluster = own.cluster
            own.close()
            if cluster is not None and scheduler is None:
                cluster.close()


def _run(client, paths, tile, seam, total, options, reading, progress, show_progress):
    units, classes, outliers = reading

    def wait(futures):
        if progress:
            show_progress(futures)
        return client.gather(futures)

    scans = wait([client.submit(scan, p, tile, seam, units, classes, outliers, pure=True) for p in paths])
    counts = {}
    for file_counts in scans:
        for key, n in file_counts.items():
            counts[key] = counts.get(key, 0) + n
    interior, seams, open_bands = plan(counts)
    ks = share(total, {("tile",) + c: n for c, n in interior.items()}
               | {("seam",) + s: n for s, n in seams.items()})
    tiles = {}
    for cell in sorted(interior):
        files = [p for p, c in zip(paths, scans) if any(key[:2] == cell for key in c)]
        tiles[cell] = client.submit(
            map_tile, cell, files, tile, seam, open_bands[cell], ks[("tile",) + cell],
            options, units, classes, outliers, pure=True,
        )
    seam_maps = [
        client.submit(
            map_seam, key, [tiles[c] for c in _tiles_of_seam(key)], ks[("seam",) + key],
            options, pure=True,
        )
        for key in sorted(seams)
    ]
    tile_maps = [client.submit(operator.getitem, tiles[c], 0, pure=True) for c in sorted(tiles)]
    made = [b for b in wait(tile_maps + seam_maps) if b is not None]
    if not made:
        raise mema.MemaError("no tile had enough points for an entity")
    return mema._mema.merge([mema.from_bytes(b) for b in made])


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python -m mema.tiles",
        description="Map LAS/LAZ files tile by tile on Dask and merge the tiles into one map.",
    )
    parser.add_argument("inputs", nargs="+", metavar="INPUT", help="LAS/LAZ (or any cloud) files")
    parser.add_argument("--tile", type=float, required=True, metavar="SIZE", help="tile size, m")
    size = parser.add_mutually_exclusive_group(required=True)
    size.add_argument("--bytes", type=int, metavar="B", help="map file budget, whole archive")
    size.add_argument("-k", type=int, metavar="K", help="entities, whole archive")
    parser.add_argument("-o", "--output", required=True, metavar="OUT.mema")
    parser.add_argument("--seam", type=float, metavar="M", help="seam width, m (tile / 10)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--paper", action="store_true", help="the paper's model, as mema map")
    parser.add_argument("--units", help="as mema map --units (default: what each file says)")
    parser.add_argument("--classes", help="as mema map --classes (default: not-noise)")
    parser.add_argument("--outliers", help="as mema map --outliers (default: 20,30)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, metavar="N", help="local worker processes (2)")
    where.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler")
    args = parser.parse_args(argv)
    try:
        merged = map_tiles(
            args.inputs, args.tile, bytes=args.bytes, k=args.k, seam=args.seam,
            workers=args.workers, scheduler=args.scheduler, progress=True, seed=args.seed,
            paper=args.paper, units=args.units, classes=args.classes, outliers=args.outliers,
        )
        merged.save(args.output)
    except (OSError, ValueError) as e:
        print(f"\nmema.tiles: {e}", file=sys.stderr)
        return 2
    print(f"\n{args.output}: {len(merged)} entities", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
