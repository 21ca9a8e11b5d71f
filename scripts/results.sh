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

echo "## mema stream-bench (the paper's model)"
for run in "car6.pcd 150" "bun_zipper.ply 350" "five_people.pcd 350" "cturtle.pcd 400"; do
  set -- $run
  echo "### \$ mema stream-bench $data/$1 -k $2 --model paper"
  "$mema" stream-bench "$data/$1" -k "$2" --model paper
done

echo "## mema stream-bench: shells against the paper's fits, K = 400 (all working, and 150 working)"
for cloud in car6.pcd bun000.ply five_people.pcd cturtle.pcd; do
  for model in paper shells; do
    for working in 400 150; do
      echo "### \$ mema stream-bench $data/$cloud -k 400 --working $working --model $model --repetitions 1 --json"
      "$mema" stream-bench "$data/$cloud" -k 400 --working "$working" --model "$model" --repetitions 1 --json
    done
  done
done

echo "## mema query-bench"
echo "### \$ mema query-bench"
"$mema" query-bench

echo "## mema map --tolerance (T = the fixed-k map's largest e_i)"
for run in "car6.pcd 150" "bun_zipper.ply 350" "five_people.pcd 350" "cturtle.pcd 400"; do
  set -- $run
  t=$("$mema" map "$data/$1" -k "$2" -o "$tmp/f.mema" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["ellipsoidal"]["max"])')
  for rounds in 0 4; do
    echo "### \$ mema map $data/$1 --tolerance $t --voronoi-rounds $rounds -o t.mema"
    /usr/bin/time -f "wall %e s" "$mema" map "$data/$1" --tolerance "$t" --voronoi-rounds "$rounds" -o "$tmp/t.mema" 2>&1
    echo "### \$ mema eval $data/$1 t.mema --json"
    "$mema" eval "$data/$1" "$tmp/t.mema" --json
  done
  echo "### \$ mema stream-bench $data/$1 -k 2048 --tolerance $t --model paper --repetitions 1"
  "$mema" stream-bench "$data/$1" -k 2048 --tolerance "$t" --model paper --repetitions 1
done

echo "## mema query-bench on a real map"
"$mema" map "$data/car6.pcd" -k 150 -o "$tmp/car.mema" > /dev/null
echo "### \$ mema query-bench car6-k150.mema"
"$mema" query-bench "$tmp/car.mema"
"$mema" map "$data/five_people.pcd" -k 350 -o "$tmp/people.mema" > /dev/null
echo "### \$ mema query-bench five_people-k350.mema"
"$mema" query-bench "$tmp/people.mema"
