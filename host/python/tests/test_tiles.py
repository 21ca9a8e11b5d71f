"""`mema.tiles` on a local Dask cluster of two worker processes, on the shared LAZ cloud."""

import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import mema
from mema import tiles
from conftest import ROOT, cloud, guide_says

distributed = pytest.importorskip("distributed")

AUTZEN = cloud("autzen_trim.laz")
# autzen_trim is about 359 m by 172 m: 100 m tiles make 4 by 2 tiles and 10 seams.
TILE = 100.0
BUDGET = 9600
# The merged map's Chamfer distance against one process's, at most.
RATIO = 1.1


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        env={"RAYON_NUM_THREADS": "1"},
        dashboard_address=None,
    )
    with distributed.Client(cluster) as c:
        yield c
    cluster.close()


@pytest.fixture(scope="module")
def merged(client):
    return tiles.map_tiles([AUTZEN], TILE, bytes=BUDGET, client=client)


def test_tiles_scan_counts_every_point_once():
    points = np.asarray(mema.read_cloud(AUTZEN))
    counts = tiles.scan(AUTZEN, TILE, TILE / 10)
    assert sum(counts.values()) == len(points)
    # Independently: a tile's count is its square's points.
    i, j = np.floor(points[:, 0] / TILE), np.floor(points[:, 1] / TILE)
    for (ti, tj) in {key[:2] for key in counts}:
        expected = int(np.sum((i == ti) & (j == tj)))
        assert sum(n for key, n in counts.items() if key[:2] == (ti, tj)) == expected


def test_tiles_share_is_proportional_and_sums_to_the_budget():
    counts = {"a": 5000, "b": 3000, "c": 1999, "d": 1}
    k = tiles.share(100, counts)
    assert k["d"] == 0  # one point has no shape
    assert sum(k.values()) <= 100 and sum(k.values()) >= 99
    for key in "abc":
        assert abs(k[key] - 100 * counts[key] / 10000) <= 1


def test_tiles_merged_map_scores_within_a_tenth_of_one_process(merged):
    points = mema.read_cloud(AUTZEN)
    single = mema.map(points, bytes=BUDGET)
    # The same budget: no more entities than one process's map holds.
    assert len(merged) <= BUDGET // tiles.BYTES_PER_ENTITY[False]
    assert len(merged.to_bytes()) <= len(single.to_bytes())
    ours, theirs = merged.eval(points)["chamfer"], single.eval(points)["chamfer"]
    assert ours <= RATIO * theirs, (ours, theirs)
    guide_says(
        "docs/python.md",
        f"On autzen_trim at {BUDGET:,} bytes in {TILE:.0f} m tiles the merged map's Chamfer is "
        f"within {RATIO}x the one-process map's",
    )


def test_tiles_merged_map_covers_the_whole_cloud(merged):
    # Every entity centre lies within the cloud's box; every tile holding a fiftieth of the
    # points has entities of its own (a corner tile of a few points may be all seam).
    points = np.asarray(mema.read_cloud(AUTZEN))
    centres = merged.entities.centres
    assert np.all(centres[:, :2] >= points[:, :2].min(0) - 1.0)
    assert np.all(centres[:, :2] <= points[:, :2].max(0) + 1.0)
    cells = {tuple(c) for c in np.floor(centres[:, :2] / TILE).astype(int)}
    tile_of = np.floor(points[:, :2] / TILE).astype(int)
    found, counts = np.unique(tile_of, axis=0, return_counts=True)
    big = {tuple(c) for c, n in zip(found, counts) if n >= len(points) / 50}
    assert big and big <= cells


def test_tiles_survive_a_worker_killed_mid_run(client, merged):
    pids = client.run(os.getpid)
    killed = []

    def kill_one_busy_worker():
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not killed:
            busy = [w for w, tasks in client.processing().items() if tasks]
            if any("map_tile" in t for w in busy for t in client.processing()[w]):
                worker = next(w for w in busy if any("map_tile" in t for t in
                                                     client.processing()[w]))
                os.kill(pids[worker], signal.SIGKILL)
                killed.append(worker)
            time.sleep(0.01)

    killer = threading.Thread(target=kill_one_busy_worker)
    killer.start()
    again = tiles.map_tiles([AUTZEN], TILE, bytes=BUDGET, client=client)
    killer.join()
    assert killed, "no worker was busy with a tile to kill"
    assert again.to_bytes() == merged.to_bytes()


def test_tiles_command_line_writes_the_functions_map(client, merged, tmp_path):
    out = tmp_path / "autzen.mema"
    done = subprocess.run(
        [sys.executable, "-m", "mema.tiles", AUTZEN, "--tile", str(TILE),
         "--bytes", str(BUDGET), "-o", str(out), "--scheduler", client.scheduler.address],
        capture_output=True, text=True,
    )
    assert done.returncode == 0, done.stderr
    assert out.read_bytes() == merged.to_bytes()


def test_tiles_refuse_a_missing_budget_clearly():
    with pytest.raises(ValueError, match="exactly one"):
        tiles.map_tiles([AUTZEN], TILE)
    done = subprocess.run(
        [sys.executable, "-m", "mema.tiles", AUTZEN, "--tile", "0", "-k", "10", "-o", "x.mema"],
        capture_output=True, text=True,
    )
    assert done.returncode == 2 and "tile: 0.0 is no positive size" in done.stderr


def test_the_guide_describes_the_tiles_benchmarks_archive():
    sys.path.insert(0, str(ROOT / "scripts"))
    import bench_tiles

    copies = bench_tiles.archive(np.asarray(mema.read_cloud(AUTZEN)))
    points = np.concatenate(copies)
    across = points.max(0) - points.min(0)
    guide_says(
        "docs/python.md",
        f"lays autzen_trim out 3 by 3 ({len(points):,} points over {across[0]:,.0f} m by "
        f"{across[1]:,.0f} m, {len(copies)} XYZ files as an archive of flight lines is kept) and "
        f"maps it in {bench_tiles.TILE:.0f} m tiles at {bench_tiles.BYTES:,} bytes",
    )
