"""The package against the command line: the same cloud and options give the same map bytes, the
same labels and the same report; every option of `mema map` is a keyword with its default."""

import inspect
import re

import numpy as np
import pytest

import mema
from conftest import CLOUDS, cloud


def same_bytes(a, b):
    with open(a, "rb") as fa, open(b, "rb") as fb:
        return fa.read() == fb.read()


def test_the_issues_example_gives_the_clis_bytes(cli, tmp_path):
    # mema.map(mema.read_cloud(p), k=150, seed=1).save(out) == mema map p -k 150 --seed 1 -o out
    p = cloud("car6.pcd")
    cli.run("map", p, "-k", 150, "--seed", 1, "-o", tmp_path / "cli.mema")
    mema.map(mema.read_cloud(p), k=150, seed=1).save(tmp_path / "py.mema")
    assert same_bytes(tmp_path / "cli.mema", tmp_path / "py.mema")


def test_stream_maps_as_the_clis_map_stream(cli, tmp_path):
    # The streaming mapper fed what scanner-sim would send: the CLI's bytes, and a map unlike
    # the batch one (so the keyword is not ignored).
    p = cloud("car6.pcd")
    cli.run("map", p, "--stream", "-k", 150, "--working", 100, "-o", tmp_path / "cli.mema")
    made = mema.map(mema.read_cloud(p), k=150, stream=True, working=100)
    made.save(tmp_path / "py.mema")
    assert same_bytes(tmp_path / "cli.mema", tmp_path / "py.mema")
    mema.map(mema.read_cloud(p), k=150).save(tmp_path / "batch.mema")
    assert not same_bytes(tmp_path / "batch.mema", tmp_path / "py.mema")
    with pytest.raises(ValueError, match="working"):
        mema.map(mema.read_cloud(p), k=150, working=100)


@pytest.mark.parametrize("name", CLOUDS)
def test_every_shared_cloud_maps_as_the_cli_maps_it(cli, tmp_path, name):
    # A one-entity map holds the cloud's origin and mean, so it sees every point's bits.
    p = cloud(name)
    cli.run("map", p, "-k", 1, "--surface-rounds", 0, "-o", tmp_path / "cli.mema")
    points = mema.read_cloud(p)
    assert isinstance(points, np.ndarray) and isinstance(points, mema.Cloud)
    assert points.dtype == np.float64 and points.ndim == 2 and points.shape[1] == 3
    made = mema.map(points, k=1, surface_rounds=0)
    made.save(tmp_path / "py.mema")
    assert same_bytes(tmp_path / "cli.mema", tmp_path / "py.mema")
    # The cloud is its reader's frame, to f64 rounding of origin + offset.
    assert np.array_equal(points.origin, mema.load(tmp_path / "cli.mema").origin)
    assert np.array_equal(points, points.origin + points.local.astype(np.float64))
    # As a plain array it is centred as a file is: the same map where origin + offset is
    # exact in f64 (binary clouds), within that rounding elsewhere. A plain array says nowhere
    # where its sensor was, so its shells are not shaped to rays: the read cloud's map
    # without shaping is the one to match.
    plain = mema.map(np.array(points), k=1, surface_rounds=0)
    unshaped = mema.map(points, k=1, surface_rounds=0, no_ray_shaping=True)
    assert np.allclose(plain.origin, made.origin, rtol=0, atol=1e-12 * (1 + np.abs(made.origin)))
    assert np.allclose(plain.entities.centres, unshaped.entities.centres, rtol=0, atol=1e-6)


def test_a_changed_cloud_maps_as_a_plain_array():
    points = mema.read_cloud(cloud("top3.ply"))
    for changed in (points[::2], points * 1.0 + [0.0, 0.0, 0.001], points[:, [1, 0, 2]]):
        assert isinstance(changed, mema.Cloud)
        want = mema.map(np.array(changed), k=10).to_bytes()
        assert mema.map(changed, k=10).to_bytes() == want
    edited = points.copy()
    edited[7, 2] += 0.01
    assert mema.map(edited, k=10).to_bytes() == mema.map(np.array(edited), k=10).to_bytes()


@pytest.mark.parametrize(
    "name, args, keywords",
    [
        # feet read through the LAS GeoKeys, a byte budget
        ("autzen_trim.laz", ["--bytes", 2400], dict(bytes=2400)),
        # the paper's model with the sphere written, and non-default fit options
        (
            "milk.pcd",
            ["-k", 40, "--paper", "--entity", "sphere", "--alpha", 0.7, "--generations", 20,
             "--bounds", "threshold", "--init", "random", "--seed", 3],
            dict(k=40, paper=True, entity="sphere", alpha=0.7, generations=20,
                 bounds="threshold", init="random", seed=3),
        ),
        # shells' own options, the crop and the voxel grid
        (
            "bun000.ply",
            ["-k", 60, "--tangent-scale", 1.5, "--normal-scale", 0.5, "--surface-rounds", 5,
             "--crop=-0.1,0.05,-0.1,0.1,0.2,0.1", "--voxel", 0.002],
            dict(k=60, tangent_scale=1.5, normal_scale=0.5, surface_rounds=5,
                 crop=(-0.1, 0.05, -0.1, 0.1, 0.2, 0.1), voxel=0.002),
        ),
        # the rest of the fit options, through --model
        (
            "lamppost.pcd",
            ["-k", 25, "--model", "paper", "--out-of-bounds", "reflect", "--volume", "spread",
             "--threshold", 0.5, "--sphere-tolerance", 0.05, "--max-iterations", 7],
            dict(k=25, model="paper", out_of_bounds="reflect", volume="spread", threshold=0.5,
                 sphere_tolerance=0.05, max_iterations=7),
        ),
        # the tolerance mode
        ("lamppost.pcd", ["--tolerance", 0.05, "--voronoi-rounds", 1],
         dict(tolerance=0.05, voronoi_rounds=1)),
        ("car6.pcd", ["--tolerance", 0.01, "--capacity", 30, "--paper"],
         dict(tolerance=0.01, capacity=30, paper=True)),
    ],
    ids=["bytes-feet", "paper-sphere", "shells-crop-voxel", "paper-options", "tolerance",
         "tolerance-capacity"],
)
def test_options_give_the_clis_map_labels_and_report(cli, tmp_path, name, args, keywords):
    p = cloud(name)
    report = cli.json(
        "map", p, *args, "-o", tmp_path / "cli.mema", "--labels", tmp_path / "labels.txt"
    )
    made = mema.map(mema.read_cloud(p), **keywords)
    made.save(tmp_path / "py.mema")
    assert same_bytes(tmp_path / "cli.mema", tmp_path / "py.mema")
    assert np.array_equal(made.labels, np.loadtxt(tmp_path / "labels.txt", dtype=np.int64))
    report.pop("output")
    assert made.report == report


@pytest.mark.parametrize("extension", ["csv", "json"])
def test_text_maps_are_the_clis(cli, tmp_path, extension):
    p = cloud("lamppost.pcd")
    cli.run("map", p, "-k", 30, "-o", tmp_path / f"cli.{extension}")
    made = mema.map(mema.read_cloud(p), k=30)
    made.save(tmp_path / f"py.{extension}")
    assert same_bytes(tmp_path / f"cli.{extension}", tmp_path / f"py.{extension}")
    assert made.to_bytes(extension) == (tmp_path / f"py.{extension}").read_bytes()


def help_defaults(cli):
    """Each long option of `mema map --help` and its default (None where it has none)."""
    text = cli.run("map", "--help")
    options = {}
    for block in re.split(r"\n(?=\s+(?:-\w, )?--)", text):
        found = re.match(r"\s+(?:-\w, )?--([\w-]+)", block)
        if found:
            default = re.search(r"\[default: ([^\]]+)\]", block)
            options[found.group(1).replace("-", "_")] = default and default.group(1)
    return options


def test_every_map_option_is_a_keyword_with_the_clis_default(cli):
    # Files and printing are the package's own: the points, Map.save, Map.labels, Map.report,
    # and read_cloud(units=).
    # How the input is read is `read_cloud`'s keywords; the rest is what the command line writes.
    reading = {"units", "topic", "frame", "classes", "outliers", "min_range"}
    not_keywords = {"output", "labels", "json", "help", "version"}
    signature = inspect.signature(mema.map)
    read_signature = inspect.signature(mema.read_cloud)
    for option, default in help_defaults(cli).items():
        if option in reading:
            assert option in read_signature.parameters, f"--{option} is no read_cloud keyword"
            continue
        if option in not_keywords:
            continue
        assert option in signature.parameters, f"--{option} has no keyword"
        given = signature.parameters[option].default
        if default is None:
            assert given in (None, False), f"{option}: {given!r}"
        elif isinstance(given, str):
            assert given == default, f"{option}: {given!r} vs the CLI's {default}"
        else:
            assert float(given) == float(default), f"{option}: {given!r} vs the CLI's {default}"
    assert "k" in signature.parameters
