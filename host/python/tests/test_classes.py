"""LAS/LAZ classes in the package (issue 23): `read_cloud` leaves out noise (ASPRS 7, 18) and
withheld points as `mema map` does, counts them in `Cloud.left_out`, and `classes=` chooses,
against laspy's reading of a file laspy wrote (tests/las/noisy_laz.py)."""

import subprocess
import sys

import numpy as np
import pytest

import mema
from conftest import ROOT, cloud
from mema import tiles


@pytest.fixture(scope="module")
def noisy(tmp_path_factory):
    out = tmp_path_factory.mktemp("classes") / "noisy.laz"
    said = subprocess.run(
        [sys.executable, str(ROOT / "tests" / "las" / "noisy_laz.py"), cloud("autzen_trim.laz"), str(out)],
        check=True, capture_output=True, text=True,
    ).stdout.split()
    counts = {said[i]: float(said[i + 1]) for i in range(0, len(said), 2)}
    return out, counts


def test_read_cloud_leaves_out_noise_and_withheld_points(noisy):
    path, counts = noisy
    kept = mema.read_cloud(path)
    assert kept.left_out == {
        "noise": counts["noise"], "withheld": counts["withheld"], "other_classes": 0, "outliers": 0,
    }
    assert len(kept) == counts["points"] - counts["noise"] - counts["withheld"]
    # US feet in the file, metres here: the clean points' top, not the noise 5,000 ft up.
    # (within the f32 offsets' 0.1 mm)
    assert np.max(np.asarray(kept)[:, 2]) == pytest.approx(counts["zmax"] * 0.3048, abs=1e-4)
    # The noise 5,000 ft off is sparse enough that a few of its points are isolated: all of
    # them come back with the outlier filter off too.
    everything = mema.read_cloud(path, classes="all", outliers="off")
    assert len(everything) == counts["points"]
    assert everything.left_out == {"noise": 0, "withheld": 0, "other_classes": 0, "outliers": 0}
    with pytest.raises(ValueError, match="classes"):
        mema.read_cloud(path, classes="noise")


def test_tiles_read_with_the_same_choice(noisy):
    path, counts = noisy
    assert len(tiles._points(str(path), None)) == len(mema.read_cloud(path))
    assert len(tiles._points(str(path), None, "all", "off")) == counts["points"]
