"""Outliers in files in the package (issue 23): `read_cloud` drops an isolated point as `mema
map` does, so the cloud and its map are the clean scan's; `outliers="off"` keeps it and the
precision check refuses the cloud."""

import numpy as np
import pytest

import mema
from conftest import cloud


def scan_with(tmp_path, name, extra):
    """bun000's points (its ASCII PLY, read here) with `extra` after them, as XYZ text."""
    text = open(cloud("bun000.ply")).read()
    header, body = text.split("end_header\n", 1)
    vertices = int(next(l for l in header.splitlines() if l.startswith("element vertex")).split()[2])
    lines = body.splitlines()[:vertices] + [" ".join(map(str, p)) for p in extra]
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def test_an_isolated_point_is_dropped_and_the_map_is_the_clean_scans(tmp_path):
    clean = mema.read_cloud(scan_with(tmp_path, "clean.xyz", []))
    far = mema.read_cloud(scan_with(tmp_path, "far.xyz", [(1e9, 0.0, 0.0)]))
    assert far.left_out["outliers"] == 1 and clean.left_out["outliers"] == 0
    assert np.array_equal(np.asarray(far), np.asarray(clean))
    assert mema.map(far, bytes=9600).to_bytes() == mema.map(clean, bytes=9600).to_bytes()


def test_with_the_filter_off_the_precision_check_refuses(tmp_path):
    path = scan_with(tmp_path, "far.xyz", [(1e5, 0.0, 0.0)])
    with pytest.raises(ValueError, match="f32 about its centre"):
        mema.read_cloud(path, outliers="off")
    with pytest.raises(ValueError, match="outliers"):
        mema.read_cloud(path, outliers="20")
    kept = mema.read_cloud(scan_with(tmp_path, "near.xyz", [(1.0, 0.0, 0.0)]), outliers="off")
    assert kept.left_out["outliers"] == 0 and len(kept) == 40257
