#!/usr/bin/env bash
# Fuzz campaigns under cargo-fuzz, every target for SECONDS each (default 60), from seed corpora
# made of the shared data: the core's decoders (core/fuzz: `map_decoder`, seeded with the
# clouds' maps in every layout; `wire_decoder`, with their captures) and the host's readers
# (host/fuzz: `cloud_readers`, PLY, PCD, LAS/LAZ, XYZ and KITTI seeded with the clouds
# themselves; `bag_messages`, the CDR of the PointCloud2 and TFMessage messages of the bags the
# bag tests write with rosbags) and the link's frames (core/fuzz: `uplink_decoder` and
# `downlink_decoder`; firmware-sim/fuzz: `carrier`, the board's receiver of the host's frames;
# host/fuzz: `map_frames`, the host's assembler of the device's), seeded with a tiny session
# between a host and the board's loop (firmware-sim/examples/link_seeds.rs: a few frames each,
# so a campaign makes thousands of runs a second). The test suite checks the same properties on
# mutations of the same seeds on stable (tests/tests/fuzzing.rs); this is the long campaign.
#
# A finding does not end a campaign: each runs in libFuzzer's fork mode and goes on past
# crashes, timeouts and running out of memory, and keeps every input that caused one in
# target/fuzz-findings/TARGET/ (earlier runs' findings stay there too). The last lines are a table of each target's runs and findings;
# the exit status is 1 when any target had a finding.
# Installs the nightly toolchain, cargo-fuzz and the Python environment (rosbags, numpy) when
# missing. Usage: scripts/fuzz.sh [SECONDS]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"

rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --version 0.13.2 --locked
[ -x target/py-venv/bin/python ] || python3 -m venv target/py-venv
target/py-venv/bin/python -m pip install --quiet --disable-pip-version-check rosbags==0.11.9 numpy

cargo build -q --release -p mema
corpus="$PWD/target/fuzz-corpus"
findings="$PWD/target/fuzz-findings"
mkdir -p "$corpus/map_decoder" "$corpus/wire_decoder"
for cloud in car6.pcd lamppost.pcd bun_zipper.ply milk.pcd; do
  maps="$corpus/map_decoder/$cloud"
  target/release/mema map "../shared/data/$cloud" -k 60 --paper -o "$maps.v1.mema" >/dev/null 2>&1
  target/release/mema map "../shared/data/$cloud" --bytes 1400 -o "$maps.quantized.mema" >/dev/null 2>&1
  target/release/mema transform "$maps.v1.mema" --rotate 10,20,30 -o "$maps.oriented.mema" >/dev/null 2>&1
  target/release/mema scanner-sim --port "$corpus/capture.bin" "../shared/data/$cloud" 2>/dev/null
  # The wire target's first byte picks the piece size the input is fed in.
  { printf '\x0c'; cat "$corpus/capture.bin"; } > "$corpus/wire_decoder/$cloud.bin"
done
rm -f "$corpus/capture.bin"
# The link's targets: frames of a tiny session, the carrier's line and the assembler's bytes
# with their headers (mema_firmware_sim::fuzz_checks::link_seeds).
cargo run -q --release -p mema-firmware-sim --example link_seeds -- "$corpus"

# The readers' target reads its input under the name its first byte picks
# (mema::io::read::fuzz_checks::NAMES: 0 .ply, 1 .pcd, 2 .las, 3 .laz, 4 .xyz, 5 .bin), since
# KITTI .bin is told by its name alone.
readers="$corpus/cloud_readers"
mkdir -p "$readers"
for cloud in ../shared/data/*.ply ../shared/data/*.pcd ../shared/data/*.las ../shared/data/*.laz; do
  case "$cloud" in
    *.ply) pick='\x00' ;; *.pcd) pick='\x01' ;; *.las) pick='\x02' ;; *.laz) pick='\x03' ;;
  esac
  { printf "$pick"; cat "$cloud"; } > "$readers/$(basename "$cloud")"
done
# XYZ text and a KITTI scan, from lamppost.pcd's ascii points.
xyz=$(awk 'body { print $1, $2, $3 } /^DATA/ { body = 1 }' ../shared/data/lamppost.pcd)
{ printf '\x04'; echo "$xyz"; } > "$readers/lamppost.xyz"
{ printf '\x05'; echo "$xyz" | perl -ne 'print pack("f<4", split(" "), 0.5)'; } > "$readers/lamppost.bin"

# The bag target's first byte picks the message type (odd: PointCloud2, even: TFMessage): the
# messages of the bags tests/bags/write_bag.py writes, read back by rosbags.
bags="$corpus/bag_messages"
mkdir -p "$bags"
rm -rf target/fuzz-bags
target/py-venv/bin/python tests/bags/write_bag.py --data ../shared/data target/fuzz-bags >/dev/null
target/py-venv/bin/python - target/fuzz-bags "$bags" <<'EOF'
import sys
from pathlib import Path
from rosbags.rosbag2 import Reader

out = Path(sys.argv[2])
for bag in sorted(Path(sys.argv[1]).iterdir()):
    with Reader(bag) as reader:
        for n, (conn, _, raw) in enumerate(reader.messages()):
            pick = b"\x01" if conn.msgtype.endswith("PointCloud2") else b"\x00"
            (out / f"{bag.name}-{n}").write_bytes(pick + bytes(raw))
EOF

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
  # Fork mode's status lines read `#RUNS: cov: ... oom/timeout/crash: O/T/C ...`.
  local runs
  runs=$(grep -oE '^#[0-9]+' "$log" | tail -1 | tr -d '#')
  local found
  found=$(find "$findings/$target" -type f -newer "$started" | wc -l)
  total=$((total + found))
  grep -E '^(#[0-9]+:|INFO: (fuzzed|exiting)|==[0-9]+==ERROR|.*panicked)' "$log" | tail -4 || true
  summary+=("$(printf '%-17s %5s s %12s runs %4s findings' "$target" "$seconds" "${runs:-0}" "$found")")
}

campaign core/fuzz map_decoder 262144
campaign core/fuzz wire_decoder 262144
campaign core/fuzz uplink_decoder 8192
campaign core/fuzz downlink_decoder 8192
campaign firmware-sim/fuzz carrier 8192
# Built as the binary ships (-O: no debug assertions). With them, the laz crate's decoder stops
# a campaign within seconds at its own debug_assert!(sym < 1 << 16) (decoders.rs:284) on corrupt
# arithmetic-coded data, where a release build reads on and the reader returns its one-line
# error.
campaign host/fuzz cloud_readers 1048576 -O
campaign host/fuzz bag_messages 1048576 -O
campaign host/fuzz map_frames 8192 -O

echo "== campaigns (findings kept in $findings/TARGET, logs in target/fuzz-TARGET.log)"
printf '%s\n' "${summary[@]}"
[ "$total" -eq 0 ]
