"""The package's own contract: what it accepts, what it returns, its exceptions, the GIL."""

import pickle
import threading
import time

import numpy as np
import pytest

import mema
from conftest import cloud


@pytest.fixture(scope="module")
def milk():
    return mema.read_cloud(cloud("milk.pcd"))


def test_float32_float64_and_views_map_alike(milk):
    # float32 widens exactly, so a float32 array maps as its float64 copy; so does a strided view.
    as32 = milk.astype(np.float32)
    want = mema.map(as32.astype(np.float64), k=20).to_bytes()
    assert mema.map(as32, k=20).to_bytes() == want
    fortran = np.asfortranarray(as32.astype(np.float64))
    assert mema.map(fortran, k=20).to_bytes() == want
    padded = np.zeros((len(milk), 5))
    padded[:, 1:4] = as32
    assert mema.map(padded[:, 1:4], k=20).to_bytes() == want


def test_non_finite_rows_are_dropped_and_counted(milk):
    dirty = milk.copy()
    dirty[::100, 1] = np.nan
    dirty[1::100, 2] = np.inf
    made = mema.map(dirty, k=20)
    dropped = len(milk[::100]) + len(milk[1::100])
    assert made.report["dropped_non_finite"] == dropped
    assert len(made.labels) == len(milk) - dropped
    clean = mema.map(dirty[np.all(np.isfinite(dirty), axis=1)], k=20)
    assert made.to_bytes() == clean.to_bytes()


def test_entities_are_the_csvs_columns(milk, tmp_path):
    made = mema.map(milk, k=25)
    made.save(tmp_path / "m.csv")
    csv = np.genfromtxt(tmp_path / "m.csv", delimiter=",", names=True, dtype=None, encoding=None)
    e = made.entities
    assert len(e) == len(made) == 25
    assert e.centres.shape == e.semi_axes.shape == e.weights.shape == (25, 3)
    assert e.rotations.shape == (25, 3, 3) and e.quaternions.shape == (25, 4)
    assert np.array_equal(e.centres, np.column_stack([csv["cx"], csv["cy"], csv["cz"]]))
    radii = np.column_stack([csv["rx"], csv["ry"], csv["rz"]])
    assert np.allclose(e.semi_axes, radii, rtol=1e-6)
    quaternions = np.column_stack([csv[c] for c in ("qx", "qy", "qz", "qw")])
    assert np.array_equal(e.quaternions.astype(np.float32), quaternions.astype(np.float32))
    assert e.kinds.tolist() == csv["kind"].tolist()
    # The rotations are orthonormal, and x_world = c + R x_local puts (r, 0, 0) on the surface.
    assert np.allclose(e.rotations @ e.rotations.transpose(0, 2, 1), np.eye(3), atol=1e-6)
    on_surface = e.centres + e.rotations[:, :, 0] * e.semi_axes[:, :1]
    distance, _ = made.nearest(on_surface)
    assert np.allclose(distance, 0.0, atol=1e-5)


def test_maps_survive_files_bytes_and_pickle(milk, tmp_path):
    made = mema.map(milk, k=25, seed=7)
    made.save(tmp_path / "m.mema")
    loaded = mema.load(tmp_path / "m.mema")
    assert loaded.to_bytes() == made.to_bytes() == (tmp_path / "m.mema").read_bytes()
    assert pickle.loads(pickle.dumps(loaded)) == loaded
    assert mema.from_bytes(made.to_bytes()) == loaded
    assert loaded.quantized and loaded.report is None and loaded.labels is None
    assert made.report["memory"]["entities"] == 25
    # JSON keeps every bit of the entities (not the grid, which only .mema files use).
    made.save(tmp_path / "m.json")
    from_json = mema.load(tmp_path / "m.json")
    assert from_json.to_bytes("json") == made.to_bytes("json")
    assert not from_json.quantized
    for name in ("centres", "weights", "quaternions"):
        assert np.array_equal(getattr(from_json.entities, name), getattr(loaded.entities, name))


def test_errors_are_exceptions_that_say_what(milk, tmp_path):
    cases = [
        (FileNotFoundError, "no-such.pcd", lambda: mema.read_cloud(tmp_path / "no-such.pcd")),
        (FileNotFoundError, "no-such.mema", lambda: mema.load(tmp_path / "no-such.mema")),
        (ValueError, "exactly one", lambda: mema.map(milk)),
        (ValueError, "exactly one", lambda: mema.map(milk, k=5, bytes=2400)),
        (ValueError, "k must be at least 1", lambda: mema.map(milk, k=0)),
        (ValueError, "k: -1 is not a count", lambda: mema.map(milk, k=-1)),
        (ValueError, "generations: -5", lambda: mema.map(milk, k=5, generations=-5)),
        (mema.MemaError, "consider k=1", lambda: mema.map(milk[:3], k=10)),
        (ValueError, "alpha 1.5", lambda: mema.map(milk, k=5, alpha=1.5, paper=True)),
        (ValueError, "'cubes' is not one of", lambda: mema.map(milk, k=5, model="cubes")),
        (ValueError, "paper=True", lambda: mema.map(milk, k=5, entity="sphere")),
        (ValueError, "shape [13704, 2]", lambda: mema.map(milk[:, :2], k=5)),
        (ValueError, "crop", lambda: mema.map(milk, k=5, crop=(1, 1, 1, 0, 0, 0))),
        (mema.MemaError, "crop box", lambda: mema.map(milk, k=5, crop=(9, 9, 9, 10, 10, 10))),
        (mema.MemaError, "no finite points", lambda: mema.map(np.full((4, 3), np.nan), k=1)),
        (TypeError, "points", lambda: mema.map("milk.pcd", k=5)),
        (ValueError, "units", lambda: mema.read_cloud(cloud("milk.pcd"), units="furlong")),
        (ValueError, "unknown map extension", lambda: mema.map(milk, k=5).save(tmp_path / "m.txt")),
    ]
    for kind, words, call in cases:
        with pytest.raises(kind) as raised:
            call()
        assert words in str(raised.value), f"{kind.__name__}: {raised.value}"
    (tmp_path / "junk.ply").write_bytes(b"\x00\x01 not a cloud")
    with pytest.raises(mema.MemaError, match="junk.ply: not a point cloud"):
        mema.read_cloud(tmp_path / "junk.ply")
    m = mema.map(milk, k=5)
    with pytest.raises(ValueError, match="row 1 is zero"):
        m.ray_cast([0, 0, 0], [[1, 0, 0], [0, 0, 0]], 1.0)
    with pytest.raises(ValueError, match="not a rotation"):
        m.transform(np.diag([1.0, 1.0, 2.0]))
    with pytest.raises(ValueError, match="row 0"):
        m.nearest([[np.nan, 0, 0]])
    with pytest.raises(ValueError, match="translation: expected three"):
        m.transform(None, [1.0, 2.0])
    with pytest.raises(ValueError, match="samples: -1"):
        m.eval(milk, samples=-1)


def test_a_byte_budget_past_the_points_warns_and_maps_fewer(milk):
    few = milk[:40]
    with pytest.warns(UserWarning, match="mapping with k = 10"):
        made = mema.map(few, bytes=2400)
    assert len(made) == 10


def test_the_gil_is_released_while_mapping():
    # A Python thread keeps counting while the map is made: with the GIL held for the whole
    # call, it could not run at all between its start and end.
    # office1's 254,456 points take about a second to map; a bunny scan is done too soon to
    # tell on an idle machine.
    points = mema.read_cloud(cloud("office1.pcd"))
    ticks, stop = [], threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    thread = threading.Thread(target=count)
    thread.start()
    try:
        start = time.perf_counter()
        mema.map(points, bytes=9600)
        end = time.perf_counter()
    finally:
        stop.set()
        thread.join()
    inner = [t for t in ticks if start + 0.1 * (end - start) < t < end - 0.1 * (end - start)]
    assert end - start > 0.2, "the map is too quick to tell"
    assert len(inner) >= 10, f"{len(inner)} ticks in {end - start:.2f} s of mapping"


def test_read_cloud_reads_a_ros2_bag_in_a_frame(tmp_path):
    # The bunny bag the Rust tests use (tests/bags/write_bag.py, written by rosbags), read in
    # frame world: the same points, bit for bit, as the registration file it was made from.
    import subprocess
    import sys

    from conftest import DATA, ROOT

    subprocess.run(
        [sys.executable, str(ROOT / "tests" / "bags" / "write_bag.py"), "--data", str(DATA),
         str(tmp_path / "bags")],
        check=True,
    )
    bag = tmp_path / "bags" / "bunny" / "bunny.mcap"
    in_world = mema.read_cloud(bag, topic="/points", frame="world")
    conf = mema.read_cloud(DATA / "bun.conf")
    # Each scan is screened as its file alone is (issue 33): the .conf holds what they hold.
    scans = [line.split()[1] for line in (DATA / "bun.conf").read_text().splitlines()
             if line.startswith("bmesh ")]
    alone = sum(len(mema.read_cloud(DATA / scan)) for scan in scans)
    assert in_world.shape == conf.shape == (alone, 3)
    assert np.array_equal(in_world, conf)
    # Without a frame each scan stays in its sensor's frame: other points.
    assert not np.array_equal(mema.read_cloud(bag), conf)
    with pytest.raises(ValueError, match="not a bag"):
        mema.read_cloud(DATA / "car6.pcd", frame="world")
