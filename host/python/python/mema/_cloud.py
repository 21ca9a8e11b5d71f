"""`mema.Cloud` and `mema.read_cloud`: a cloud as numpy users hold it, world coordinates in
metres, that remembers the frame its reader put it in so that mapping it gives the command
line's map bit for bit."""

import numpy as np

from mema import _mema


class Cloud(np.ndarray):
    """An ``(N, 3)`` float64 array of a cloud's points, in world coordinates and metres, as
    ``read_cloud`` reads it; a plain ndarray in every other way.

    It also keeps what the reader made of the file, because the world coordinates alone cannot
    give it back (``origin + local`` rounds in float64): ``origin`` ``(3,)``, the local frame's
    origin; ``local`` ``(N, 3)`` float32, each point's offset from it; ``unit``, the unit the
    file was read in (as ``mema eval --json`` gives it); ``dropped_non_finite``, the points
    skipped for a NaN or infinite coordinate; ``left_out``, the points of a classified file
    (LAS/LAZ) its ``classes`` left out and the isolated points its ``outliers`` dropped, as
    ``{"noise", "withheld", "other_classes", "outliers"}``. ``mema.map`` and ``Map.eval`` use that frame as
    long as the array still holds exactly ``origin + local`` (so the map is ``mema map``'s,
    byte for byte), and otherwise (a slice, an edited or computed array) centre the values as
    for any array. ``np.asarray(cloud)`` is the plain array.
    """

    def __new__(
        cls, points, origin=None, local=None, unit=None, dropped_non_finite=0, left_out=None,
        sensors=None, no_returns=0,
    ):
        cloud = np.asarray(points, dtype=np.float64).view(cls)
        cloud.origin = origin
        cloud.local = local
        cloud.unit = unit
        cloud.dropped_non_finite = dropped_non_finite
        cloud.left_out = left_out
        cloud.sensors = sensors
        cloud.no_returns = no_returns
        return cloud

    def __array_finalize__(self, obj):
        # Views and results of arithmetic carry the frame along; mapping checks it still fits.
        self.origin = getattr(obj, "origin", None)
        self.local = getattr(obj, "local", None)
        self.unit = getattr(obj, "unit", None)
        self.dropped_non_finite = getattr(obj, "dropped_non_finite", 0)
        self.left_out = getattr(obj, "left_out", None)
        self.sensors = getattr(obj, "sensors", None)
        self.no_returns = getattr(obj, "no_returns", 0)

    def __reduce__(self):
        state = (
            self.origin, self.local, self.unit, self.dropped_non_finite, self.left_out,
            self.sensors, self.no_returns,
        )
        return (_rebuild, (np.asarray(self), *state))


def _rebuild(
    points, origin, local, unit, dropped_non_finite, left_out=None, sensors=None, no_returns=0
):
    return Cloud(
        points, origin, local, unit, dropped_non_finite, left_out, sensors, no_returns
    )


def read_cloud(
    path, units=None, topic=None, frame=None, classes=None, outliers=None, min_range=None
):
    """Reads a point cloud file (PLY, PCD, LAS/LAZ, XYZ/CSV, KITTI ``.bin``: whatever ``mema
    map`` reads) as a ``Cloud``: an ``(N, 3)`` float64 array of its finite points in world
    coordinates, in metres. ``units`` (``m``, ``mm``, ``cm``, ``km``, ``in``, ``ft``,
    ``us-ft``) scales them as ``--units`` does; without it the unit the file says (a LAS
    file's CRS) is used, else metres, as the command line reads it. A ROS 2 bag's PointCloud2
    messages are read from ``topic`` (the bag's only one by default), each put in ``frame``
    through the bag's transforms when it is given, as ``--topic`` and ``--frame`` read them.
    ``classes`` chooses a LAS/LAZ file's points as ``--classes`` does: ``"not-noise"`` (the
    default: every point but ASPRS classes 7 and 18 and withheld points), ``"all"``, or
    classes like ``"2,6"``. ``outliers`` drops isolated points of a cloud file as ``mema map
    --outliers`` does, with its default (``"20,30"``: a point whose mean distance to its 20
    nearest neighbours is over 30 times that distance's median); ``"off"`` keeps them, and
    either refuses a cloud too wide for float32 at its point spacing. ``Cloud.left_out``
    counts the points the read left out.
    ``min_range`` (metres, default 1 cm, as ``--min-range``): points that close to the sensor
    origin they were seen from are no-returns, left out and counted in ``no_returns``; the
    cloud's ``sensors`` are the runs of points seen from each origin, ``(origins, ends)``.
"""
    import json

    world, local, origin, unit, dropped, left, sensors, no_returns = _mema._read_cloud(
        path, units, topic, frame, classes, outliers, min_range
    )
    left_out = dict(zip(("noise", "withheld", "other_classes", "outliers"), left))
    return Cloud(
        world, origin, local, json.loads(unit), dropped, left_out, sensors, no_returns
    )
