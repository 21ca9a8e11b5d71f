"""Wall time of `mema.tiles` on one Dask worker against two, on a cloud large enough to matter.

The cloud: autzen_trim.laz (110,000 points) laid out 3 by 3, each copy shifted by the cloud's
own extent, written once as nine XYZ text files in a scratch directory, as an archive of flight
lines is kept (990,000 points over 1,077 m by 515 m; each tile reads only the files with
points in it), mapped in 100 m tiles at 96,000 bytes (docs/python.md, whose figures
host/python/tests/test_tiles.py computes from `archive`). Each run gets a fresh LocalCluster
of one-thread workers (one rayon thread each, so a worker is a core), started before the clock
starts. A measurement, not a test: the machine's other load moves it.

    target/py-venv/bin/python scripts/bench_tiles.py [DATA_DIR]
"""

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import mema
from mema import tiles

TILE = 100.0
BYTES = 96000


def archive(points):
    """The cloud laid out 3 by 3, each copy shifted by the cloud's own extent."""
    extent = points.max(0) - points.min(0)
    return [points + [extent[0] * i, extent[1] * j, 0] for i in range(3) for j in range(3)]


if __name__ == "__main__":
    import distributed

    data = Path(sys.argv[1] if len(sys.argv) > 1 else "../shared/data")
    copies = archive(np.asarray(mema.read_cloud(data / "autzen_trim.laz")))
    with tempfile.TemporaryDirectory() as scratch:
        files = []
        for n, copy in enumerate(copies):
            files.append(str(Path(scratch) / f"autzen_{n}.xyz"))
            np.savetxt(files[-1], copy, fmt="%.3f")
        seconds = {}
        for workers in (1, 2):
            cluster = distributed.LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True,
                env={"RAYON_NUM_THREADS": "1"}, dashboard_address=None,
            )
            with distributed.Client(cluster) as client:
                start = time.perf_counter()
                merged = tiles.map_tiles(files, TILE, bytes=BYTES, client=client)
                seconds[workers] = time.perf_counter() - start
            cluster.close()
            print(f"{workers} worker(s): {seconds[workers]:.1f} s, {len(merged)} entities",
                  flush=True)
        print(f"speed-up with two workers: {seconds[1] / seconds[2]:.2f}x")
