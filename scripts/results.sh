#!/usr/bin/env bash
# Regenerates every figure the README quotes, with the commands behind them.
# Usage: scripts/results.sh > /tmp/results.md   (release build; reads ../shared/data)
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -q -p mema
mema=target/release/mema
data=../shared/data
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

echo "## mema map (Tables 2 and 4)"
for run in "car6.pcd 150" "bun_zipper.ply 100" "bun_zipper.ply 350" "five_people.pcd 350"; do
  set -- $run
  echo "### \$ mema map $data/$1 -k $2 -o m.mema"
  /usr/bin/time -f "wall %e s, peak RSS %M KB" "$mema" map "$data/$1" -k "$2" -o "$tmp/m.mema" 2>&1
done

echo "## mema ablation"
for run in "car6.pcd 150" "bun_zipper.ply 100" "bun_zipper.ply 350" "five_people.pcd 350" "cturtle.pcd 400" "milk.pcd 150"; do
  set -- $run
  echo "### \$ mema ablation $data/$1 -k $2"
  "$mema" ablation "$data/$1" -k "$2"
done

echo "## mema stream-bench"
for run in "car6.pcd 150" "bun_zipper.ply 350" "five_people.pcd 350" "cturtle.pcd 400"; do
  set -- $run
  echo "### \$ mema stream-bench $data/$1 -k $2"
  "$mema" stream-bench "$data/$1" -k "$2"
done

echo "## mema query-bench"
echo "### \$ mema query-bench"
"$mema" query-bench
