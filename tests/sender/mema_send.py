#!/usr/bin/env python3
"""An independent sender of mema's wire protocol, version 2, written from PROTOCOL.md alone.

It shares no code with mema (standard library only: struct, zlib, json), so a test that feeds
its bytes to `mema replay` or `mema stream` checks that the document is enough to write a
sender. Two inputs:

  mema_send.py --conf bun.conf --unit -4 OUT
      the scans of a Stanford registration file (`bmesh FILE tx ty tz qx qy qz qw`; ASCII PLY
      scans), each in its own sensor frame after a pose frame. Stanford's convention takes a
      scan's point to the world as x_world = R(q)^T x + t, so the pose sent (sensor to world,
      x_world = R(q') x + t) has q' = conj(q).

  mema_send.py --ints SCANS.json OUT
      scans already in wire integers: {"unit_exponent": e, "scans": [{"pose_exponent": pe,
      "translation": [3 ints], "rotation": [4 ints, units of 2^-30], "points": [[3 ints], ...]},
      ...]}; a scan without "rotation" is sent without a pose frame (pose 0, the identity).

OUT is a file (a capture) or a serial device / pty path, written in one go. Frames hold
--points-per-frame points (at most 128); sequence numbers start at --first-sequence; the first
frame carries the session-start flag and the last the end-of-stream flag; poses are numbered
1, 2, ... in order.
"""

import argparse
import json
import math
import os
import struct
import sys
import zlib

VERSION = 2
FLAG_END = 0x01
FLAG_SESSION = 0x02
KIND_POINTS = 0
KIND_POSE = 1
ONE = 1 << 30  # a quaternion component of 1 on the wire
MAX_POINTS = 128


def raw_frame(flags, sequence, unit, kind, pose_number, body, count):
    header = struct.pack("<BBIHbBI", VERSION, flags, sequence, count, unit, kind, pose_number)
    raw = header + body
    return raw + struct.pack("<I", zlib.crc32(raw) & 0xFFFFFFFF)


def cobs(raw):
    out = bytearray([0])
    code_at, code = 0, 1
    for byte in raw:
        if byte != 0:
            out.append(byte)
            code += 1
            if code == 0xFF:
                out[code_at] = code
                code_at, code = len(out), 1
                out.append(0)
        else:
            out[code_at] = code
            code_at, code = len(out), 1
            out.append(0)
    out[code_at] = code
    return bytes(out) + b"\x00"


def wire_round(v):
    """Nearest integer, halves away from zero (Python's round() goes to even)."""
    return int(math.floor(abs(v) + 0.5)) * (1 if v >= 0 else -1)


def quaternion_on_wire(q):
    """(x, y, z, w) normalised, w >= 0, in units of 2^-30."""
    n = math.sqrt(sum(c * c for c in q))
    sign = -1.0 if q[3] < 0 else 1.0
    return [wire_round(sign * c / n * ONE) for c in q]


def read_ascii_ply(path):
    """The x, y, z of every vertex of an ASCII PLY file."""
    with open(path, "rb") as f:
        lines = f.read().decode("ascii").split("\n")
    if lines[0].strip() != "ply":
        sys.exit(f"{path}: not a PLY file")
    count, props, in_vertex, body = 0, [], False, 0
    for i, line in enumerate(lines[1:], start=1):
        words = line.split()
        if not words:
            continue
        if words[0] == "format" and words[1] != "ascii":
            sys.exit(f"{path}: only ASCII PLY is read here")
        if words[0] == "element":
            in_vertex = words[1] == "vertex"
            if in_vertex:
                count = int(words[2])
        elif words[0] == "property" and in_vertex:
            props.append(words[-1])
        elif words[0] == "end_header":
            body = i + 1
            break
    ix = [props.index(a) for a in ("x", "y", "z")]
    points = []
    for line in lines[body : body + count]:
        v = line.split()
        points.append([float(v[j]) for j in ix])
    return points


def scans_of_conf(path, unit):
    """The registration file's scans in wire integers, each with its pose (translation in the
    points' unit)."""
    scale = 10.0 ** unit
    scans = []
    base = os.path.dirname(path)
    with open(path) as f:
        for line in f:
            w = line.split()
            if not w or w[0] != "bmesh":
                continue
            t = [float(v) for v in w[2:5]]
            qx, qy, qz, qw = (float(v) for v in w[5:9])
            points = read_ascii_ply(os.path.join(base, w[1]))
            scans.append(
                {
                    "pose_exponent": unit,
                    "translation": [wire_round(v / scale) for v in t],
                    "rotation": quaternion_on_wire([-qx, -qy, -qz, qw]),
                    "points": [[wire_round(v / scale) for v in p] for p in points],
                }
            )
    return scans


def encode(scans, unit, per_frame, first_sequence):
    frames = []  # (unit, kind, pose number, body, count)
    for number, scan in enumerate(scans, start=1):
        pose = 0
        if "rotation" in scan:
            pose = number
            body = struct.pack("<3i", *scan["translation"]) + struct.pack("<4i", *scan["rotation"])
            frames.append((scan["pose_exponent"], KIND_POSE, pose, body, 0))
        pts = scan["points"]
        for at in range(0, len(pts), per_frame):
            chunk = pts[at : at + per_frame]
            body = b"".join(struct.pack("<3i", *p) for p in chunk)
            frames.append((unit, KIND_POINTS, pose, body, len(chunk)))
    out = bytearray(b"\x00")
    for i, (u, kind, pose, body, count) in enumerate(frames):
        flags = (FLAG_SESSION if i == 0 else 0) | (FLAG_END if i == len(frames) - 1 else 0)
        sequence = (first_sequence + i) & 0xFFFFFFFF
        out += cobs(raw_frame(flags, sequence, u, kind, pose, body, count))
    return bytes(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--conf")
    src.add_argument("--ints")
    ap.add_argument("--unit", type=int, default=-4, help="with --conf: 10^UNIT m")
    ap.add_argument("--points-per-frame", type=int, default=100)
    ap.add_argument("--first-sequence", type=int, default=0)
    ap.add_argument("out")
    a = ap.parse_args()
    if not 1 <= a.points_per_frame <= MAX_POINTS:
        sys.exit("--points-per-frame is 1..=128")
    if a.conf:
        unit, scans = a.unit, scans_of_conf(a.conf, a.unit)
    else:
        with open(a.ints) as f:
            doc = json.load(f)
        unit, scans = doc["unit_exponent"], doc["scans"]
    data = encode(scans, unit, a.points_per_frame, a.first_sequence)
    with open(a.out, "wb") as f:
        f.write(data)
    points = sum(len(s["points"]) for s in scans)
    print(f"mema_send.py: {len(scans)} scans, {points} points, {len(data)} bytes", file=sys.stderr)


if __name__ == "__main__":
    main()
