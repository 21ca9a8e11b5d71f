"""Map.eval against `mema eval --json` on the same files: the same keys and the same values."""

import numpy as np
import pytest

import mema
from conftest import cloud

SAMPLES = 20_000


@pytest.fixture(scope="module")
def car_map(cli, tmp_path_factory):
    out = tmp_path_factory.mktemp("eval") / "car.mema"
    cli.run("map", cloud("car6.pcd"), "-k", 120, "-o", out)
    return out


def test_eval_of_files_is_the_clis(cli, car_map):
    want = cli.json("eval", cloud("car6.pcd"), car_map, "--samples", SAMPLES, "--seed", 2)
    got = mema.load(car_map).eval(cloud("car6.pcd"), samples=SAMPLES, seed=2)
    assert got == want


def test_eval_of_the_cloud_read_is_the_clis(cli, car_map):
    # A mema.Cloud scores in the frame and unit it was read in; a plain array in metres
    # assumed (car6 is binary, so its points are the same bits either way).
    want = cli.json("eval", cloud("car6.pcd"), car_map, "--samples", SAMPLES)
    points = mema.read_cloud(cloud("car6.pcd"))
    assert mema.load(car_map).eval(points, samples=SAMPLES) == want
    plain = mema.load(car_map).eval(points.view(np.ndarray), samples=SAMPLES)
    assert plain.pop("unit") == {"unit": {"name": "metre", "metres": 1.0}, "source": "assumed"}
    want.pop("unit")
    assert plain == want


def test_a_map_in_memory_measures_its_mema_encoding(cli, tmp_path):
    # Not saved: the bytes of the .mema file it would be; saved as CSV: that file's bytes
    # (the scores then differ in the last digits: the CSV's entities are the map's around an
    # origin of their own, which `mema eval` reads back).
    p = cloud("milk.pcd")
    made = mema.map(mema.read_cloud(p), k=50)
    in_memory = made.eval(p, samples=SAMPLES)
    made.save(tmp_path / "milk.mema")
    assert in_memory == cli.json("eval", p, tmp_path / "milk.mema", "--samples", SAMPLES)
    made.save(tmp_path / "milk.csv")
    want = cli.json("eval", p, tmp_path / "milk.csv", "--samples", SAMPLES)
    got = made.eval(p, samples=SAMPLES)
    for key in ("file_bytes", "header_bytes", "bytes_per_entity"):
        assert got[key] == want[key], key
    assert mema.load(tmp_path / "milk.csv").eval(p, samples=SAMPLES) == want


def test_eval_reads_a_clouds_unit_and_takes_units(cli, tmp_path):
    # autzen_trim.laz is in feet (its GeoKeys); --units overrides it (with the US survey foot,
    # 2 ppm longer, so the points stay near the map and the score quick).
    p = cloud("autzen_trim.laz")
    cli.run("map", p, "--bytes", 1400, "-o", tmp_path / "autzen.mema")
    m = mema.load(tmp_path / "autzen.mema")
    want = cli.json("eval", p, tmp_path / "autzen.mema", "--samples", SAMPLES)
    got = m.eval(p, samples=SAMPLES)
    assert got == want and got["unit"]["unit"]["name"] == "foot"
    assert m.eval(mema.read_cloud(p), samples=SAMPLES) == want
    want = cli.json(
        "eval", p, tmp_path / "autzen.mema", "--samples", SAMPLES, "--units", "us-ft"
    )
    assert want["unit"]["overrides"] == "foot (LAS GeoKeys)"
    assert m.eval(p, samples=SAMPLES, units="us-ft") == want
    assert m.eval(mema.read_cloud(p, units="us-ft"), samples=SAMPLES) == want
