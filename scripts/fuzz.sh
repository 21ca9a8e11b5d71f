#!/usr/bin/env bash
# Fuzz campaigns under cargo-fuzz, every target for SECONDS each (default 60), from small seeds
# made afresh from the shared data on every run (a target explores only while it runs fast: a
# few frames or a few dozen points, not whole captures or clouds): the core's decoders
# (core/fuzz: `map_decoder`, the clouds' maps in every layout; `wire_decoder`, a few frames of
# captures with one pose, a pose per scan and wide poses, and version 1 frames), the host's
# readers (host/fuzz: `cloud_readers`, a few dozen points of every layout of PLY, PCD, LAS/LAZ,
# XYZ/CSV and KITTI; `bag_messages`, the CDR of the PointCloud2 and TFMessage messages of the
# bags the bag tests write with rosbags, the clouds cut to a few dozen points) and the link's
# frames (core/fuzz: `uplink_decoder` and `downlink_decoder`; firmware-sim/fuzz: `carrier`, the
# board's receiver of the host's frames; host/fuzz: `map_frames`, the host's assembler of the
# device's), seeded with a tiny session between a host and the board's loop
# (firmware-sim/examples/link_seeds.rs). The test suite checks the same properties on
# mutations of seeds like these on stable (tests/tests/fuzzing.rs); this is the long campaign.
#
# A finding does not end a campaign: each runs in libFuzzer's fork mode and goes on past
# crashes, timeouts and running out of memory, and keeps every input that caused one in
# target/fuzz-findings/TARGET/ (earlier runs' findings stay there too). The last lines are a
# table of each target's runs, runs a second and findings; the exit status is 1 when any target
# had a finding. Installs the nightly toolchain, cargo-fuzz and the Python environment
# (rosbags, numpy, laspy and lazrs for the LAS/LAZ seeds) when missing.
# Usage: scripts/fuzz.sh [SECONDS]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"

rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --version 0.13.2 --locked
[ -x target/py-venv/bin/python ] || python3 -m venv target/py-venv
target/py-venv/bin/python -m pip install --quiet --disable-pip-version-check rosbags==0.11.9 numpy \
  laspy==2.7.0 lazrs==0.8.2

cargo build -q --release -p mema
# Every run starts from the seeds alone, made afresh: small inputs (a few frames, a few dozen
# points), since a target explores only while it runs fast.
corpus="$PWD/target/fuzz-corpus"
findings="$PWD/target/fuzz-findings"
data=../shared/data
rm -rf "$corpus" target/fuzz-seed-work
mkdir -p "$corpus/map_decoder" "$corpus/wire_decoder" target/fuzz-seed-work
work="$PWD/target/fuzz-seed-work"
for cloud in car6.pcd lamppost.pcd bun_zipper.ply milk.pcd; do
  maps="$corpus/map_decoder/$cloud"
  target/release/mema map "$data/$cloud" -k 60 --paper -o "$maps.v1.mema" >/dev/null 2>&1
  target/release/mema map "$data/$cloud" --bytes 1400 -o "$maps.quantized.mema" >/dev/null 2>&1
  target/release/mema transform "$maps.v1.mema" --rotate 10,20,30 -o "$maps.oriented.mema" >/dev/null 2>&1
done
# Whole captures, cut below to a few of their frames: a cloud's (one pose), the demo drive's
# and bun.conf's (a pose frame per scan), and bun.conf's moved 5,400 km (wide pose frames:
# translations past i32 in its 0.1 mm unit), its scans named by absolute path.
target/release/mema scanner-sim --port "$work/car6.cap" "$data/car6.pcd" 2>/dev/null
target/release/mema scanner-sim --port "$work/demo.cap" 2>/dev/null
target/release/mema scanner-sim --conf "$data/bun.conf" --port "$work/bun.cap" 2>/dev/null
awk -v dir="$(cd "$data" && pwd)" '$1 == "bmesh" {
    $2 = dir "/" $2; for (i = 3; i <= 5; i++) $i = sprintf("%.9f", $i + 5400000)
  } { print }' "$data/bun.conf" > "$work/far.conf"
target/release/mema scanner-sim --conf "$work/far.conf" --port "$work/far.cap" 2>/dev/null
# The link's targets: frames of a tiny session, the carrier's line and the assembler's bytes
# with their headers (mema_firmware_sim::fuzz_checks::link_seeds).
cargo run -q --release -p mema-firmware-sim --example link_seeds -- "$corpus"
# The bag target's messages: those of the bags tests/bags/write_bag.py writes, cut below.
target/py-venv/bin/python tests/bags/write_bag.py --data "$data" "$work/bags" >/dev/null

# The small seeds, each a valid input of its format cut from the shared data:
# - wire_decoder (its first byte picks the piece size the rest is fed in): a few frames of each
#   capture at its 0x00 delimiters (the session-start pose frame, points frames, a later pose,
#   the end-of-stream frame), and version 1 frames (no poses) of car6's first points;
# - cloud_readers (its first byte picks the name read under, mema::io::read::fuzz_checks::NAMES:
#   0 .ply, 1 .pcd, 2 .las, 3 .laz, 4 .xyz, 5 .bin, 6 .txt; KITTI .bin is told by its name): a
#   few dozen points of each layout, their headers' counts made to agree: PCD ascii, binary and
#   binary_compressed (LZF with back-references), organized patches with NaN slots and
#   no-returns, a padding field; PLY ascii with faces and with bun000's range_grid, binary in
#   both byte orders; LAS 1.2, 1.3 and 1.4 and LAZ 1.2 and 1.4 (laspy, lazrs); XYZ, CSV, KITTI;
# - bag_messages (its first byte: odd PointCloud2, even TFMessage): each PointCloud2 cut to a
#   few dozen points in its own layout (endianness, padding, row padding), the TFMessages whole.
target/py-venv/bin/python - "$data" "$work" "$corpus" <<'EOF'
import struct
import sys
import zlib
from pathlib import Path

import laspy
import numpy as np
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

data, work, corpus = (Path(a) for a in sys.argv[1:4])


def put(target, name, pick, body):
    out = corpus / target
    out.mkdir(parents=True, exist_ok=True)
    (out / name).write_bytes(bytes([pick]) + body)


# The wire: captures cut at their delimiters, every block a whole COBS-framed frame.
def cobs(raw):
    out, block = bytearray(), bytearray()
    for b in raw + b"\0":
        if b == 0 or len(block) == 254:
            out += bytes([len(block) + 1]) + block
            block = bytearray()
            if b != 0:
                block.append(b)
        else:
            block.append(b)
    return bytes(out)


def uncobs(block):
    out, i = bytearray(), 0
    while i < len(block):
        code = block[i]
        out += block[i + 1 : i + code]
        i += code
        if code < 0xFF and i < len(block):
            out.append(0)
    return bytes(out)


for name, piece in [("car6", 12), ("demo", 0), ("bun", 3), ("far", 255)]:
    blocks = (work / f"{name}.cap").read_bytes().split(b"\0")[1:-1]
    kinds = [uncobs(b)[9] for b in blocks]
    poses = [i for i, k in enumerate(kinds) if k != 0]
    assert len(poses) >= 1 and poses[0] == 0, name
    # The first pose and two points frames, the last pose (if another) and one, the end.
    keep = [0, 1, 2] + ([poses[-1], poses[-1] + 1] if len(poses) > 1 else []) + [len(blocks) - 1]
    cut = b"".join(b"\0" + blocks[i] for i in keep) + b"\0"
    put("wire_decoder", f"{name}.bin", piece, cut)
    if name == "far":
        assert all(kinds[i] == 2 for i in poses), "far: wide poses"
raw = uncobs((work / "car6.cap").read_bytes().split(b"\0")[2])
count, unit = struct.unpack_from("<Hb", raw, 6)
points = raw[14 : 14 + 12 * count]
v1 = b"\0"
for seq, at in enumerate(range(0, 60, 20)):
    n, flags = 20, 1 if at == 40 else 0
    frame = struct.pack("<BBIHbB", 1, flags, seq, n, unit, 0) + points[12 * at : 12 * (at + n)]
    v1 += cobs(frame + struct.pack("<I", zlib.crc32(frame))) + b"\0"
put("wire_decoder", "car6-v1.bin", 12, v1)


# LZF, as PCL's binary_compressed holds it.
def lzf_decompress(src):
    out, i = bytearray(), 0
    while i < len(src):
        c = src[i]
        i += 1
        if c < 32:
            out += src[i : i + c + 1]
            i += c + 1
            continue
        n = c >> 5
        if n == 7:
            n += src[i]
            i += 1
        ref = len(out) - ((c & 0x1F) << 8) - src[i] - 1
        i += 1
        for _ in range(n + 2):
            out.append(out[ref])
            ref += 1
    return bytes(out)


def lzf_compress(src):
    out, lit, seen, i = bytearray(), bytearray(), {}, 0

    def literals():
        for k in range(0, len(lit), 32):
            out.append(len(lit[k : k + 32]) - 1)
            out.extend(lit[k : k + 32])
        lit.clear()

    while i < len(src):
        key = src[i : i + 3]
        ref = seen.get(key)
        seen[key] = i
        if len(key) == 3 and ref is not None and i - ref <= 8192:
            n = 3
            while i + n < len(src) and n < 264 and src[ref + n] == src[i + n]:
                n += 1
            literals()
            off, m = i - ref - 1, n - 2
            out += bytes([(min(m, 7) << 5) | off >> 8]) + (bytes([m - 7]) if m >= 7 else b"")
            out.append(off & 0xFF)
            i += n
        else:
            lit.append(src[i])
            i += 1
    literals()
    assert lzf_decompress(bytes(out)) == src
    return bytes(out)


# PCD: the header's lines as they are but WIDTH, HEIGHT and POINTS; the body in its own
# DATA layout, of the slots kept.
def read_pcd(path):
    raw = path.read_bytes()
    header, at = [], 0
    while True:
        end = raw.index(b"\n", at) + 1
        line = raw[at:end].decode()
        header.append(line)
        at = end
        if line.startswith("DATA"):
            break
    words = {l.split()[0]: l.split()[1:] for l in header if l.strip() and l[0] != "#"}
    sizes = [int(s) * int(c) for s, c in zip(words["SIZE"], words["COUNT"])]
    width, height = int(words["WIDTH"][0]), int(words["HEIGHT"][0])
    n, kind = width * height, words["DATA"][0]
    if kind == "ascii":
        rows = raw[at:].decode().splitlines()[:n]
    elif kind == "binary":
        step = sum(sizes)
        rows = [raw[at + i * step : at + (i + 1) * step] for i in range(n)]
    else:
        size, _ = struct.unpack_from("<II", raw, at)
        body = lzf_decompress(raw[at + 8 : at + 8 + size])
        columns, off = [], 0
        for name, s in zip(words["FIELDS"], sizes):
            if name != "_":
                columns.append([body[off + i * s : off + (i + 1) * s] for i in range(n)])
                off += n * s
        rows = [b"".join(c[i] for c in columns) for i in range(n)]
    return header, words, width, height, kind, rows


def write_pcd(header, words, kind, rows, width, height, fields=None):
    lines = []
    for line in header:
        key = line.split()[0] if line.strip() else ""
        if key in ("WIDTH", "HEIGHT", "POINTS"):
            line = f"{key} {dict(WIDTH=width, HEIGHT=height, POINTS=width * height)[key]}\n"
        lines.append(line)
    head = "".join(lines).encode()
    if kind == "ascii":
        return head + "".join(r + "\n" for r in rows).encode()
    if kind == "binary":
        return head + b"".join(rows)
    sizes = [int(s) * int(c) for s, c in zip(words["SIZE"], words["COUNT"])]
    names = fields or words["FIELDS"]
    body, off = b"", 0
    for name, s in zip(names, sizes):
        if name != "_":
            body += b"".join(r[off : off + s] for r in rows)
            off += s
    packed = lzf_compress(body)
    return head + struct.pack("<II", len(packed), len(body)) + packed


def x_of(words, kind, row):
    at = words["FIELDS"].index("x")
    if kind == "ascii":
        return float(row.split()[at])
    off = sum(int(s) * int(c) for s, c in zip(words["SIZE"][:at], words["COUNT"][:at]))
    return struct.unpack_from("<f", row, off)[0]


def patch(words, kind, rows, width, height, w, h):
    """A w x h patch of an organized cloud holding both points and empty (NaN) slots."""
    for r0 in range(height // 2, height - h, h):
        for c0 in range(0, width - w, w):
            xs = [x_of(words, kind, rows[(r0 + r) * width + c0 + c]) for r in range(h) for c in range(w)]
            empty = sum(1 for x in xs if x != x)
            if 0 < empty <= len(xs) // 2:
                return [rows[(r0 + r) * width + c0 + c] for r in range(h) for c in range(w)]
    raise SystemExit("no mixed patch")


for name in ["car6", "cturtle", "lamppost", "five_people", "office1", "ouster_os1_0"]:
    header, words, width, height, kind, rows = read_pcd(data / f"{name}.pcd")
    if height > 1:
        kept, w, h = patch(words, kind, rows, width, height, 8, 4), 8, 4
    else:
        kept, w, h = rows[:40], 40, 1
    put("cloud_readers", f"{name}.pcd", 1, write_pcd(header, words, kind, kept, w, h))
# car6's points with a padding field, which binary_compressed leaves out as PCL's writer does.
header, words, _, _, _, rows = read_pcd(data / "car6.pcd")
padded = {"FIELDS": "x y z _", "SIZE": "4 4 4 1", "TYPE": "F F F U", "COUNT": "1 1 1 4"}
header = [f"{l.split()[0]} {padded[l.split()[0]]}\n" if l.split()[0] in padded else l for l in header]
padded = {k: v.split() for k, v in padded.items()}
for kind in ["binary", "binary_compressed"]:
    head = [f"DATA {kind}\n" if l.startswith("DATA") else l for l in header]
    body = [r + b"\xab\xcd\xef\x01" for r in rows[:40]]
    put("cloud_readers", f"car6-padded-{kind}.pcd", 1, write_pcd(head, padded, kind, body, 40, 1))

# PLY: bun_zipper's vertices of its first faces (x y z confidence intensity, and the faces
# renumbered) in ascii and both binary orders (big-endian as doubles with colours), and
# bun000's first vertices with a range_grid of 8 x 6 (obj_info says so).
lines = (data / "bun_zipper.ply").read_text().splitlines()
body = lines[lines.index("end_header") + 1 :]
faces = [list(map(int, l.split()[1:])) for l in body[35947 : 35947 + 12]]
used = sorted({v for f in faces for v in f})
verts = [list(map(float, body[v].split())) for v in used]
faces = [[used.index(v) for v in f] for f in faces]
nv, nf = len(verts), len(faces)


def ply_header(fmt, props):
    props = "".join(f"property {t} {p}\n" for t, p in props)
    return (f"ply\nformat {fmt} 1.0\ncomment zipper output, cut\nelement vertex {nv}\n{props}"
            f"element face {nf}\nproperty list uchar int vertex_indices\nend_header\n").encode()


floats = [("float", p) for p in ["x", "y", "z", "confidence", "intensity"]]
text = "".join(" ".join(f"{c:g}" for c in v) + "\n" for v in verts)
text += "".join(f"{len(f)} " + " ".join(map(str, f)) + "\n" for f in faces)
put("cloud_readers", "bun_zipper.ply", 0, ply_header("ascii", floats) + text.encode())
le = b"".join(struct.pack("<5f", *v) for v in verts)
le += b"".join(struct.pack(f"<B{len(f)}i", len(f), *f) for f in faces)
put("cloud_readers", "bun_zipper-le.ply", 0, ply_header("binary_little_endian", floats) + le)
colours = [("double", p) for p in "xyz"] + [("uchar", c) for c in ["red", "green", "blue"]]
be = b"".join(struct.pack(">3d3B", *v[:3], 200, 100 + i, 50) for i, v in enumerate(verts))
be += b"".join(struct.pack(f">B{len(f)}i", len(f), *f) for f in faces)
put("cloud_readers", "bun_zipper-be.ply", 0, ply_header("binary_big_endian", colours) + be)
lines = (data / "bun000.ply").read_text().splitlines()
end = lines.index("end_header")
head = []
for l in lines[: end + 1]:
    w = l.split()
    if w[:2] == ["element", "vertex"]:
        l = "element vertex 40"
    elif w[:2] == ["element", "range_grid"]:
        l = "element range_grid 48"
    elif w[:2] == ["obj_info", "num_cols"]:
        l = "obj_info num_cols 8"
    elif w[:2] == ["obj_info", "num_rows"]:
        l = "obj_info num_rows 6"
    head.append(l)
grid = ["0"] * 4 + [f"1 {k}" for k in range(40)] + ["0"] * 4
text = "\n".join(head + lines[end + 1 : end + 41] + grid) + "\n"
put("cloud_readers", "bun000.ply", 0, text.encode())

# LAS and LAZ: 40 points of each, their headers rewritten by laspy (counts, bounds), the LAZ
# compressed by lazrs; autzen's also as LAS and LAZ 1.4 (point formats 6 and 7).
for name, pick in [("simple.las", 2), ("vegetation_1_3.las", 2), ("autzen_trim.laz", 3)]:
    las = laspy.read(data / name)
    small = laspy.LasData(las.header)
    small.points = las.points[:40].copy()
    path = work / name
    small.write(path, do_compress=name.endswith(".laz"))
    put("cloud_readers", name, pick, path.read_bytes())
    if name.endswith(".laz"):
        for fmt, suffix, pick in [(6, "las", 2), (7, "laz", 3)]:
            path = work / f"autzen-1.4.{suffix}"
            laspy.convert(small, point_format_id=fmt, file_version="1.4").write(
                path, do_compress=suffix == "laz"
            )
            put("cloud_readers", path.name, pick, path.read_bytes())

# XYZ, CSV with a header line, and a KITTI scan (x y z and a reflectance, f32), of lamppost.
_, words, _, _, _, rows = read_pcd(data / "lamppost.pcd")
xyz = [list(map(float, r.split()[:3])) for r in rows[:40]]
put("cloud_readers", "lamppost.xyz", 4, "".join(f"{x} {y} {z}\n" for x, y, z in xyz).encode())
csv = "x,y,z,intensity\n" + "".join(f"{x},{y},{z},7\n" for x, y, z in xyz)
put("cloud_readers", "lamppost.txt", 6, csv.encode())
put("cloud_readers", "lamppost.bin", 5, b"".join(struct.pack("<4f", *p, 0.5) for p in xyz))

# The bags' messages, each PointCloud2 cut to at most 3 rows of 12 points in its own layout.
store = get_typestore(Stores.ROS2_HUMBLE)
for bag in sorted(p for p in (work / "bags").iterdir() if p.is_dir()):
    with Reader(bag) as reader:
        for n, (conn, _, raw) in enumerate(reader.messages()):
            if not conn.msgtype.endswith("PointCloud2"):
                put("bag_messages", f"{bag.name}-{n}", 0, bytes(raw))
                continue
            msg = store.deserialize_cdr(bytes(raw), conn.msgtype)
            h, w, step = min(msg.height, 3), min(msg.width, 12), msg.point_step
            padding = msg.row_step - msg.width * step
            cut = b"".join(
                bytes(msg.data[r * msg.row_step : r * msg.row_step + w * step]) + b"\0" * padding
                for r in range(h)
            )
            msg.height, msg.width, msg.row_step = h, w, w * step + padding
            msg.data = np.frombuffer(cut, dtype=np.uint8)
            little = raw[1] == 1
            put("bag_messages", f"{bag.name}-{n}", 1, bytes(store.serialize_cdr(msg, conn.msgtype, little_endian=little)))
EOF
rm -rf "$work"

# One campaign: TARGET in the fuzz crate DIR, inputs up to MAX_LEN bytes, cargo-fuzz's flags.
# Its runs and findings are appended to the summary.
summary=()
total=0
started="$PWD/target/fuzz-started"
touch "$started"
campaign() {
  local dir="$1" target="$2" max_len="$3"
  shift 3
  local log="$PWD/target/fuzz-$target.log"
  mkdir -p "$findings/$target"
  echo "== fuzz $target for $seconds s"
  (cd "$dir" && cargo +nightly fuzz run "$@" "$target" "$corpus/$target" -- \
    -max_total_time="$seconds" -max_len="$max_len" \
    -fork=1 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1 \
    -artifact_prefix="$findings/$target/") >"$log" 2>&1 || true
  # Fork mode's status lines read `#RUNS: cov: ... oom/timeout/crash: O/T/C time: Ts ...`; the
  # rate is over the time the last one gives (a little past SECONDS: the last job ends).
  local runs elapsed
  runs=$(grep -oE '^#[0-9]+' "$log" | tail -1 | tr -d '#')
  elapsed=$(grep -E '^#[0-9]+:' "$log" | tail -1 | sed -nE 's/.* time: ([0-9]+)s.*/\1/p')
  local found
  found=$(find "$findings/$target" -type f -newer "$started" | wc -l)
  total=$((total + found))
  grep -E '^(#[0-9]+:|INFO: (fuzzed|exiting)|==[0-9]+==ERROR|.*panicked)' "$log" | tail -4 || true
  summary+=("$(printf '%-17s %5s s %12s runs %8s runs/s %4s findings' "$target" "$seconds" \
    "${runs:-0}" "$(( ${runs:-0} / ${elapsed:-$seconds} ))" "$found")")
}

# Inputs may grow to some times the seeds' size (the readers' past their 32 KiB buffer), not to
# whole captures or clouds.
campaign core/fuzz map_decoder 262144
campaign core/fuzz wire_decoder 16384
campaign core/fuzz uplink_decoder 8192
campaign core/fuzz downlink_decoder 8192
campaign firmware-sim/fuzz carrier 8192
# Built as the binary ships (-O: no debug assertions). With them, the laz crate's decoder stops
# a campaign within seconds at its own debug_assert!(sym < 1 << 16) (decoders.rs:284) on corrupt
# arithmetic-coded data, where a release build reads on and the reader returns its one-line
# error.
campaign host/fuzz cloud_readers 131072 -O
campaign host/fuzz bag_messages 65536 -O
campaign host/fuzz map_frames 8192 -O

echo "== campaigns (findings kept in $findings/TARGET, logs in target/fuzz-TARGET.log)"
printf '%s\n' "${summary[@]}"
[ "$total" -eq 0 ]
