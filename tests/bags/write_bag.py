"""Writes the ROS 2 bags mema's bag tests read, with `rosbags` (no ROS, no code shared with mema).

    python write_bag.py --data ../shared/data OUT_DIR

makes two bags (rosbag2 directories, MCAP storage) and what the tests compare them with:

* OUT_DIR/bunny/bunny.mcap: the scans of bun.conf, one sensor_msgs/msg/PointCloud2 per scan on
  /points in frame scanner_N (FLOAT64 x, y, z: the numbers Python's float() reads from the
  ASCII PLY text), and each scan's pose, sensor to world (the .conf's t and conj(q)), on the
  transform topics: scanners 0, 1 and 4 on /tf_static; scanner 3 on /tf, stamped at its scan
  and again before and after with wrong poses; scanner 2 through a chain, world -> robot on /tf
  (a pure translation w, wrong again later) and robot -> scanner_2 on /tf_static (t - w and
  conj(q), with (t - w) + w == t checked here, so the chain composes back to the .conf's
  numbers exactly). The transforms are written after the clouds.
* OUT_DIR/messy/messy.mcap (zstd-compressed chunks): on /cloud in frame lidar, three clouds of
  awkward layouts: big-endian CDR and data, FLOAT32 fields in the order intensity, z, y, x,
  ring with padding (point_step 20, rows padded), 3 x 50 points with NaN and inf ones; a
  little-endian FLOAT64 cloud with a UINT32 field first (point_step 32); and one of NaN
  points only. /other holds one more PointCloud2, so the bag has two such topics.
* OUT_DIR/messy/expected.txt: numpy's decoding of /cloud (structured dtypes over the same
  bytes), finite points only, as mema documents it keeps them: each cloud centred on its
  bounding box's centre (each bound halved, then added) into float32 offsets, written back as
  origin + offset in float64. One `scan N` line per non-empty cloud, then `x y z` lines
  (repr), and a last line `dropped D empty E`.
"""

import argparse
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

STORE = get_typestore(Stores.ROS2_HUMBLE)
T = STORE.types
PointCloud2 = T["sensor_msgs/msg/PointCloud2"]
PointField = T["sensor_msgs/msg/PointField"]
Header = T["std_msgs/msg/Header"]
Time = T["builtin_interfaces/msg/Time"]
TFMessage = T["tf2_msgs/msg/TFMessage"]
TransformStamped = T["geometry_msgs/msg/TransformStamped"]
Transform = T["geometry_msgs/msg/Transform"]
Vector3 = T["geometry_msgs/msg/Vector3"]
Quaternion = T["geometry_msgs/msg/Quaternion"]

INT8, UINT8, INT16, UINT16, INT32, UINT32, FLOAT32, FLOAT64 = range(1, 9)


def read_conf(path):
    """(ply path, t, q) of each bmesh line, as mema's .conf reader reads them."""
    scans = []
    for line in path.read_text().splitlines():
        words = line.split()
        if not words or words[0] != "bmesh":
            continue
        numbers = [float(w) for w in words[2:9]]
        scans.append((path.parent / words[1], numbers[:3], numbers[3:]))
    return scans


def read_ascii_ply(path):
    """The vertex x, y, z of an ASCII PLY, as float() parses the text: an (N, 3) float64 array."""
    lines = path.read_text().splitlines()
    end = lines.index("end_header")
    header = lines[:end]
    count = next(int(l.split()[2]) for l in header if l.startswith("element vertex"))
    props = []
    in_vertex = False
    for l in header:
        if l.startswith("element"):
            in_vertex = l.startswith("element vertex")
        elif l.startswith("property") and in_vertex:
            props.append(l.split()[-1])
    ix = [props.index(a) for a in "xyz"]
    rows = []
    for l in lines[end + 1 : end + 1 + count]:
        w = l.split()
        rows.append([float(w[i]) for i in ix])
    return np.array(rows, dtype=np.float64)


def stamp(sec, nanosec=0):
    return Time(sec=sec, nanosec=nanosec)


def cloud_msg(points, frame, sec, fields, point_step, height, width, row_step, big):
    """A PointCloud2 whose data is `points` (a structured array of height x width items)
    laid out by `fields` [(name, offset, datatype)], rows `row_step` apart."""
    data = np.zeros(height * row_step, dtype=np.uint8)
    flat = points.reshape(height, width)
    for r in range(height):
        row = np.frombuffer(flat[r].tobytes(), dtype=np.uint8)
        data[r * row_step : r * row_step + row.size] = row
    return PointCloud2(
        header=Header(stamp=stamp(sec), frame_id=frame),
        height=height,
        width=width,
        fields=[PointField(name=n, offset=o, datatype=d, count=1) for n, o, d in fields],
        is_bigendian=big,
        point_step=point_step,
        row_step=row_step,
        data=data,
        is_dense=False,
    )


def transform(parent, child, sec, t, q, nanosec=0):
    return TransformStamped(
        header=Header(stamp=stamp(sec, nanosec), frame_id=parent),
        child_frame_id=child,
        transform=Transform(
            translation=Vector3(x=t[0], y=t[1], z=t[2]),
            rotation=Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]),
        ),
    )


def write(writer, conn, msg, msgtype, time_ns, little=True):
    writer.write(conn, time_ns, STORE.serialize_cdr(msg, msgtype, little_endian=little))


def bunny(conf, out):
    scans = read_conf(conf)
    names = PointCloud2.__msgtype__, TFMessage.__msgtype__
    xyz64 = np.dtype({"names": ["x", "y", "z"], "formats": ["<f8"] * 3, "offsets": [0, 8, 16]})
    fields = [("x", 0, FLOAT64), ("y", 8, FLOAT64), ("z", 16, FLOAT64)]
    statics, dynamic = [], []
    with Writer(out, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        points = w.add_connection("/points", names[0], typestore=STORE)
        tf = w.add_connection("/tf", names[1], typestore=STORE)
        tf_static = w.add_connection("/tf_static", names[1], typestore=STORE)
        for i, (ply, t, q) in enumerate(scans):
            xyz = read_ascii_ply(ply)
            items = np.zeros(len(xyz), dtype=xyz64)
            items["x"], items["y"], items["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
            sec = 100 + i
            msg = cloud_msg(items, f"scanner_{i}", sec, fields, 24, 1, len(xyz), 24 * len(xyz), False)
            write(w, points, msg, names[0], sec * 10**9)
            pose = [-q[0], -q[1], -q[2], q[3]]  # sensor to world: conj(q)
            frame = f"scanner_{i}"
            if i == 2:
                # A chain: world -> robot (a translation only) -> scanner_2.
                wr = [round(v, 2) for v in t]
                rs = [a - b for a, b in zip(t, wr)]
                assert all(a + b == c for a, b, c in zip(rs, wr, t)), (rs, wr, t)
                dynamic.append(transform("world", "robot", 95, wr, [0.0, 0.0, 0.0, 1.0]))
                dynamic.append(transform("world", "robot", sec, [9.0, 9.0, 9.0], [0.0, 0.0, 0.0, 1.0], 5 * 10**8))
                statics.append(transform("robot", frame, 0, rs, pose))
            elif i == 3:
                dynamic.append(transform("world", frame, sec - 1, [1.0, 2.0, 3.0], [0.0, 0.0, 0.0, 1.0]))
                dynamic.append(transform("world", frame, sec, t, pose))
                dynamic.append(transform("world", frame, sec, t, pose, 1))
                dynamic.append(transform("world", frame, sec + 1, [1.0, 2.0, 3.0], pose))
            else:
                statics.append(transform("world", frame, 0, t, pose))
        # The transforms after the clouds: a reader must gather them first.
        write(w, tf_static, TFMessage(transforms=statics), names[1], 200 * 10**9)
        for k, ts in enumerate(dynamic):
            write(w, tf, TFMessage(transforms=[ts]), names[1], (200 + k) * 10**9)
    return len(scans)


def centred(xyz):
    """mema's rule for a cloud's points: f32 offsets from the box centre, back in f64."""
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    origin = lo / 2.0 + hi / 2.0
    local = (xyz - origin).astype(np.float32)
    return origin + local.astype(np.float64)


def messy(out, expected):
    rng = np.random.default_rng(14)
    names = PointCloud2.__msgtype__
    clouds = []
    # 1. Big-endian, FLOAT32, intensity z y x ring, point_step 20, rows padded by 8 bytes.
    h, wd = 3, 50
    dt = np.dtype({
        "names": ["intensity", "z", "y", "x", "ring"],
        "formats": [">f4", ">f4", ">f4", ">f4", ">u2"],
        "offsets": [0, 4, 8, 12, 16],
        "itemsize": 20,
    })
    a = np.zeros(h * wd, dtype=dt)
    for axis, shift in zip("xyz", (10.0, -3.0, 1.5)):
        a[axis] = rng.normal(shift, 2.0, h * wd)
    a["intensity"] = rng.uniform(0, 100, h * wd)
    a["ring"] = np.arange(h * wd) % 16
    a["y"][::9] = np.nan
    a["x"][5] = np.inf
    a["z"][7] = -np.nan
    fields = [("intensity", 0, FLOAT32), ("z", 4, FLOAT32), ("y", 8, FLOAT32), ("x", 12, FLOAT32), ("ring", 16, UINT16)]
    clouds.append((cloud_msg(a, "lidar", 1, fields, 20, h, wd, wd * 20 + 8, True), False))
    # 2. Little-endian FLOAT64 after a UINT32, point_step 32.
    dt = np.dtype({
        "names": ["t", "x", "y", "z"],
        "formats": ["<u4", "<f8", "<f8", "<f8"],
        "offsets": [0, 8, 16, 24],
        "itemsize": 32,
    })
    b = np.zeros(100, dtype=dt)
    for axis in "xyz":
        b[axis] = rng.uniform(-50.0, 50.0, 100)
    b["t"] = np.arange(100)
    b["z"][[3, 50, 99]] = np.nan
    fields = [("t", 0, UINT32), ("x", 8, FLOAT64), ("y", 16, FLOAT64), ("z", 24, FLOAT64)]
    clouds.append((cloud_msg(b, "lidar", 2, fields, 32, 1, 100, 3200, False), True))
    # 3. Nothing finite.
    c = np.full(5, np.nan, dtype=np.dtype({"names": ["x", "y", "z"], "formats": ["<f4"] * 3, "offsets": [0, 4, 8]}))
    fields = [("x", 0, FLOAT32), ("y", 4, FLOAT32), ("z", 8, FLOAT32)]
    clouds.append((cloud_msg(c, "lidar", 3, fields, 12, 1, 5, 60, False), True))

    w = Writer(out, version=8, storage_plugin=StoragePlugin.MCAP)
    w.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    with w:
        conn = w.add_connection("/cloud", names, typestore=STORE)
        other = w.add_connection("/other", names, typestore=STORE)
        for k, (msg, little) in enumerate(clouds):
            write(w, conn, msg, names, (k + 1) * 10**9, little)
        write(w, other, clouds[2][0], names, 5 * 10**9)

    # numpy's own decoding of the same bytes.
    lines, dropped, empty = [], 0, 0
    for k, (msg, _) in enumerate(clouds):
        order = ">" if msg.is_bigendian else "<"
        kinds = {FLOAT32: "f4", FLOAT64: "f8"}
        by_name = {f.name: f for f in msg.fields}
        dt = np.dtype({
            "names": list("xyz"),
            "formats": [order + kinds[by_name[a].datatype] for a in "xyz"],
            "offsets": [by_name[a].offset for a in "xyz"],
            "itemsize": msg.point_step,
        })
        data = bytes(msg.data)
        rows = [np.frombuffer(data, dtype=dt, count=msg.width, offset=r * msg.row_step) for r in range(msg.height)]
        items = np.concatenate(rows)
        xyz = np.stack([items[a].astype(np.float64) for a in "xyz"], axis=1)
        finite = np.isfinite(xyz).all(axis=1)
        dropped += int((~finite).sum())
        if not finite.any():
            empty += 1
            continue
        lines.append(f"scan {k}")
        lines.extend(" ".join(repr(float(v)) for v in p) for p in centred(xyz[finite]))
    lines.append(f"dropped {dropped} empty {empty}")
    expected.write_text("\n".join(lines) + "\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, required=True, help="the shared data (bun.conf, the scans)")
    ap.add_argument("out", type=Path, help="directory to write the bags in (made; must not hold them)")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    n = bunny(args.data / "bun.conf", args.out / "bunny")
    messy(args.out / "messy", args.out / "messy" / "expected.txt")
    print(f"wrote {args.out / 'bunny' / 'bunny.mcap'} ({n} scans) and {args.out / 'messy' / 'messy.mcap'}")


if __name__ == "__main__":
    main()
