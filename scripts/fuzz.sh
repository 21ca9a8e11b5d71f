#!/usr/bin/env bash
# Fuzz campaigns of the core's decoders (core/fuzz: the .mema map decoder and the wire decoder)
# under cargo-fuzz, each for SECONDS (default 60), from a seed corpus made of the shared clouds:
# their maps in every layout and their captures. The test suite checks the same properties on
# mutations of the same seeds on stable (tests/tests/fuzzing.rs); this is the long campaign.
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

cd core/fuzz
for target in map_decoder wire_decoder; do
  echo "== fuzz $target for $seconds s"
  cargo +nightly fuzz run "$target" "$corpus/$target" -- -max_total_time="$seconds" -max_len=262144
done
