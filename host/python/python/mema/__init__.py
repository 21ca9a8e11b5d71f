"""mema: multiellipsoidal maps of 3D point clouds, from numpy.

Read a cloud, map it into a few hundred ellipsoids, save the map, score it and ask it questions::

    import mema
    points = mema.read_cloud("scan.pcd")          # (N, 3) float64 (a mema.Cloud), metres
    m = mema.map(points, k=150, seed=1)           # every option of `mema map`
    m.save("scan.mema")                           # .mema, .csv or .json by extension
    score = m.eval(points)                        # the keys of `mema eval --json`
    distance, entity = m.nearest(points[:10])     # vectorised queries

Everything here is the Rust library the `mema` command line runs, so the same points and seed
give the same map bytes as `mema map`. See the README's "Python" section.
"""

from mema._cloud import Cloud, read_cloud
from mema._mema import (
    Entities,
    Map,
    MemaError,
    __version__,
    from_bytes,
    load,
    map,
    rotation_degrees,
)

__all__ = [
    "Cloud",
    "Entities",
    "Map",
    "MemaError",
    "__version__",
    "from_bytes",
    "load",
    "map",
    "read_cloud",
    "rotation_degrees",
]
