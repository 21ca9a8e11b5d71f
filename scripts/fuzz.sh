#!/usr/bin/env bash
# Fuzz campaigns under cargo-fuzz, each for SECONDS (default 60), from seed corpora made of the
# shared clouds: the core's decoders (core/fuzz: the .mema map decoder, seeded with the clouds'
# maps in every layout, and the wire decoder, with their captures) and the host's cloud readers
# (host/fuzz: PLY, PCD, LAS/LAZ, XYZ and KITTI, seeded with the clouds themselves). The test
# suite checks the same properties on mutations of the same seeds on stable
# (tests/tests/fuzzing.rs); this is the long campaign.
# Installs the nightly toolchain and cargo-fuzz when missing. Usage: scripts/fuzz.sh [SECONDS]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"

rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --version 0.13.2 --locked

cargo build -q --release -p mema
corpus="$PWD/target/fuzz-corpus"
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

cd core/fuzz
for target in map_decoder wire_decoder; do
  echo "== fuzz $target for $seconds s"
  cargo +nightly fuzz run "$target" "$corpus/$target" -- -max_total_time="$seconds" -max_len=262144
done
cd ../../host/fuzz
# Built as the binary ships (-O: no debug assertions). With them, the laz crate's decoder stops
# the campaign within seconds at its own debug_assert!(sym < 1 << 16) (decoders.rs:284) on
# corrupt arithmetic-coded data, where a release build reads on and the reader returns its
# one-line error (the first 3-minute campaign found that and nothing else).
echo "== fuzz cloud_readers for $seconds s"
cargo +nightly fuzz run -O cloud_readers "$readers" -- -max_total_time="$seconds" -max_len=1048576
