#!/usr/bin/env bash
# Regenerates the figures the guides quote, from one run, into one file: docs/results.md.
# Usage: scripts/results.sh [OUT]   (release build; reads ../shared/data; OUT defaults to
# docs/results.md)
#
# Each figure sits in a block between `<!-- result NAME -->` and `<!-- /result -->`. A guide
# quotes a table by copying its block, markers and all; tests/tests/results.rs checks that every
# copy equals this file's block, that the figures quoted in prose are the blocks' cells, and
# recomputes the cheap rows (car6's, the pacing model's) from the code, so neither a guide nor
# the results file can drift unnoticed. Figures that vary by machine (times, rates, memory) are
# kept apart, in blocks named `times-*` that say which machine and load they were measured
# under: the guides copy them like any block, and no test asserts them.
#
# Every benchmark writes a log; scripts/results/render.py turns the logs into the file. The
# slow ones: firmware-sim/check.sh (QEMU, minutes), `scripts/bench.sh --only python` (about a
# quarter of an hour) and `--only fidelity` (hours of Gaussian-mixture EM on two cores, unless
# its fit cache, target/gmm-cache, already holds the fits). Environment:
#
#   MEMA_RESULTS_LOGS=DIR   keep every log in DIR and reuse a log already there instead of
#                           running its benchmark again (delete DIR/NAME.log to rerun one); each
#                           log's commit, time and load are in DIR/NAME.meta, and results.md
#                           names the commit every section came from
#   MEMA_RESULTS_KEEP=A,B   copy these sections (paper, clouds, fidelity, surface, tolerance,
#                           ablation, queries, free-space, streaming, board-fidelity, firmware,
#                           pacing, reference, python, bench, draw) from the current OUT instead
#                           of running
#                           them; the copied section keeps the commit it names
#   MEMA_CHECK_LOG=FILE     the output of a firmware-sim/check.sh run of this checkout
#   MEMA_GMM_CACHE=DIR      the fidelity benchmark's fit cache (default target/gmm-cache)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-docs/results.md}
target=${CARGO_TARGET_DIR:-$PWD/target}
cargo build --release -q -p mema -p mema-firmware-sim
mema=$target/release/mema
data=../shared/data
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
logs=${MEMA_RESULTS_LOGS:-$tmp/logs}
mkdir -p "$logs"
logs=$(cd "$logs" && pwd)
keep=",${MEMA_RESULTS_KEEP:-},"
export MEMA="$mema"

commit=$(git rev-parse --short HEAD)
git diff --quiet HEAD -- . ':!docs' 2>/dev/null || commit="$commit+changes"

# run NAME COMMAND...: COMMAND's stdout to $logs/NAME.log (stderr to NAME.err), with its
# commit, wall time and load in NAME.meta; a log already there is reused, a kept section skipped.
run() {
  local name=$1 section=$2
  shift 2
  if [[ $keep == *",$section,"* ]]; then
    return
  fi
  if [ -e "$logs/$name.log" ]; then
    echo "results: $name: reusing $logs/$name.log ($(tr -d '\n' < "$logs/$name.meta"))" >&2
    return
  fi
  echo "results: $name: $*" >&2
  local start load
  start=$(date +%s.%N)
  load=$(cut -d' ' -f1 /proc/loadavg)
  if ! "$@" > "$logs/$name.part" 2> "$logs/$name.err"; then
    echo "results: $name failed; its output is in $logs/$name.part and $name.err" >&2
    exit 1
  fi
  mv "$logs/$name.part" "$logs/$name.log"
  python3 - "$name" "$*" "$commit" "$start" "$load" > "$logs/$name.meta" <<'EOF'
import json, os, platform, sys, time
name, command, commit, start, load = sys.argv[1:]
model = platform.machine()
for line in open("/proc/cpuinfo"):
    if line.startswith("model name"):
        model = line.split(":", 1)[1].strip()
        break
print(json.dumps({"command": command, "commit": commit, "date": time.strftime("%Y-%m-%d"),
                  "seconds": round(time.time() - float(start), 1),
                  "machine": f"{model}, {os.cpu_count()} cores",
                  "load": [float(load), os.getloadavg()[0]]}))
EOF
}

# The paper's Tables 2 and 4 (`mema map --paper`), and each run's time, as JSON lines.
paper() {
  for run in "car6.pcd 150" "bun_zipper.ply 100" "bun_zipper.ply 350" "five_people.pcd 350"; do
    set -- $run
    /usr/bin/time -f '{"wall": %e, "rss_kb": %M}' -o "$tmp/time" \
      "$mema" map "$data/$1" -k "$2" --paper -o "$tmp/m.mema" --json 2>/dev/null > "$tmp/map.json"
    jq_line cloud "$1" k "$2" report "@$tmp/map.json" time "@$tmp/time"
  done
  # One figure per name (docs/command-line.md): the bunny's default map at k = 150.
  "$mema" map "$data/bun_zipper.ply" -k 150 -o "$tmp/b.mema" --json 2>/dev/null > "$tmp/map.json"
  "$mema" eval "$data/bun_zipper.ply" "$tmp/b.mema" --json 2>/dev/null > "$tmp/eval.json"
  "$mema" info "$tmp/b.mema" --json > "$tmp/info.json"
  jq_line names bun_zipper.ply k 150 report "@$tmp/map.json" eval "@$tmp/eval.json" info "@$tmp/info.json"
}

# One JSON line of KEY VALUE pairs; a value `@FILE` is that file's JSON, a number stays one.
jq_line() {
  python3 - "$@" <<'EOF'
import json, sys
args, line = sys.argv[1:], {}
for key, value in zip(args[::2], args[1::2]):
    if value.startswith("@"):
        line[key] = json.load(open(value[1:]))
    else:
        try:
            line[key] = json.loads(value)
        except ValueError:
            line[key] = value
print(json.dumps(line))
EOF
}

# Every shared cloud read as `mema map` reads it: its slots, what was dropped, what was mapped;
# and the default map at 2,400 bytes (entities and file bytes).
clouds() {
  for path in "$data"/*.{ply,pcd,las,laz}; do
    "$mema" map "$path" --bytes 2400 -o "$tmp/b.mema" --json 2>/dev/null > "$tmp/b.json"
    "$mema" info "$tmp/b.mema" --json > "$tmp/info.json"
    jq_line cloud "$(basename "$path")" report "@$tmp/b.json" info "@$tmp/info.json"
  done
}

# The firmware's figures: firmware-sim/check.sh builds the 64 KiB image and the STM32F405 board,
# runs both under QEMU (-icount shift=0: instructions, not time) and prints their memory and
# instructions.
check() {
  if [ -n "${MEMA_CHECK_LOG:-}" ]; then
    cat "$MEMA_CHECK_LOG"
  else
    firmware-sim/check.sh 2>&1
  fi
}

# The core against the independent f64 reference (docs/firmware.md): every shared input at
# k = 150, the image's K = 400 (all working, and 150 working + 250 frozen), and the moment sums
# rounded to fewer bits. A run over tolerance exits 1: that is what it measures.
reference() {
  local sim=$target/release/mema-firmware-sim
  for args in "" "-k 400" "-k 400 --working 150" "--sum-bits 24" "--sum-bits 32" \
      "--sum-bits 40" "--sum-bits 48" "--sum-bits 52" "--sum-bits 53"; do
    echo "== reference $args"
    "$sim" reference $args 2>&1 || true
  done
}

# The link model's pacing table: the test that checks it prints it (tests/tests/pacing.rs).
pacing() {
  MEMA_RESULTS_REGENERATING=1 cargo test -q --release -p mema-tests --test integration -- \
    --exact pacing::the_ring_keeps_up_with_the_link_on_a_168_mhz_part --nocapture 2>&1
}

# Streamed maps: the bunny's registered scans streamed with their poses against the batch map of
# as many entities, and the demo drive re-cast at its streamed map.
streaming() {
  "$mema" map "$data/bun.conf" --stream -k 400 -o "$tmp/s.mema" 2>/dev/null > /dev/null
  "$mema" info "$tmp/s.mema" --json > "$tmp/s.json"
  local k
  k=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["entities"])' "$tmp/s.json")
  "$mema" map "$data/bun.conf" -k "$k" -o "$tmp/b.mema" 2>/dev/null > /dev/null
  "$mema" eval "$data/bun_zipper.ply" "$tmp/s.mema" --json 2>/dev/null > "$tmp/se.json"
  "$mema" eval "$data/bun_zipper.ply" "$tmp/b.mema" --json 2>/dev/null > "$tmp/be.json"
  jq_line run multiview k "$k" stream "@$tmp/se.json" batch "@$tmp/be.json"
  "$mema" demo --moving --out-dir "$tmp/drive" --json 2>/dev/null > "$tmp/drive.json"
  jq_line run drive demo "@$tmp/drive.json"
  "$mema" query-bench --json 2>/dev/null > "$tmp/static.json"
  jq_line run static bench "@$tmp/static.json"
}

stream_vs_batch() {
  scripts/stream_vs_batch.sh "$1" "$mema"
}

# Automatic k (docs/tolerance.md): T is the largest per-cluster error of the paper's map at
# the cloud's fixed k; then the tolerance maps in both models, eval of each, the paper's with
# four Voronoi rounds, and the streaming mapper with the same T.
tolerance() {
  for run in "car6.pcd 150" "bun_zipper.ply 350" "five_people.pcd 350" "cturtle.pcd 400"; do
    set -- $run
    local cloud=$data/$1 t
    "$mema" map "$cloud" -k "$2" --paper -o "$tmp/f.mema" --json 2>/dev/null > "$tmp/f.json"
    t=$(python3 -c 'import json, sys; print("%.6f" % json.load(open(sys.argv[1]))["ellipsoidal"]["max"])' "$tmp/f.json")
    for model in paper shells voronoi; do
      local flags=(--model shells)
      [ "$model" = shells ] || flags=(--paper)
      [ "$model" = voronoi ] && flags+=(--voronoi-rounds 4)
      /usr/bin/time -f '{"wall": %e}' -o "$tmp/time" \
        "$mema" map "$cloud" --tolerance "$t" "${flags[@]}" --json -o "$tmp/t.mema" 2>/dev/null > "$tmp/t.json"
      "$mema" eval "$cloud" "$tmp/t.mema" --json 2>/dev/null > "$tmp/e.json"
      jq_line cloud "$1" k "$2" tolerance "$t" model "$model" map "@$tmp/t.json" eval "@$tmp/e.json" time "@$tmp/time"
    done
    "$mema" stream-bench "$cloud" -k 2048 --tolerance "$t" --model paper --json 2>/dev/null > "$tmp/s.json"
    jq_line cloud "$1" k "$2" tolerance "$t" model stream bench "@$tmp/s.json"
  done
}

# Surface following (docs/fidelity.md): the default map at 9,600 bytes with and without it.
surface() {
  for cloud in car6.pcd bun_zipper.ply five_people.pcd office1.pcd; do
    for rounds in 30 0; do
      /usr/bin/time -f '{"wall": %e, "rss_kb": %M}' -o "$tmp/time" \
        "$mema" map "$data/$cloud" --bytes 9600 --surface-rounds "$rounds" -o "$tmp/s.mema" 2>/dev/null > /dev/null
      "$mema" eval "$data/$cloud" "$tmp/s.mema" --json 2>/dev/null > "$tmp/e.json"
      jq_line cloud "$cloud" rounds "$rounds" eval "@$tmp/e.json" time "@$tmp/time"
    done
  done
}

# Queries (docs/queries.md): the index against the brute-force scan on three maps, then the demo
# scene's map with its scan re-cast against it.
queries() {
  for run in "car6.pcd 150" "five_people.pcd 350" "cturtle.pcd 2000"; do
    set -- $run
    "$mema" map "$data/$1" -k "$2" -o "$tmp/q.mema" 2>/dev/null > /dev/null
    "$mema" query-bench "$tmp/q.mema" --json 2>/dev/null > "$tmp/q.json"
    jq_line cloud "$1" k "$2" bench "@$tmp/q.json"
  done
  "$mema" query-bench --json 2>/dev/null > "$tmp/q.json"
  jq_line cloud demo k 250 bench "@$tmp/q.json"
}

# The choices the paper leaves open (docs/design.md), on six clouds.
ablation() {
  for run in "car6.pcd 150" "bun_zipper.ply 100" "bun_zipper.ply 350" "five_people.pcd 350" \
      "cturtle.pcd 400" "milk.pcd 150"; do
    set -- $run
    "$mema" ablation "$data/$1" -k "$2" --json 2>/dev/null > "$tmp/a.json"
    jq_line cloud "$1" k "$2" ablation "@$tmp/a.json"
  done
}

# Pictures and meshes (docs/performance.md): draw office1 and its maps, export the bunny's.
draw() {
  "$mema" map "$data/office1.pcd" -k 16384 -o "$tmp/o16k.mema" > /dev/null 2>&1
  "$mema" map "$data/office1.pcd" -k 500 -o "$tmp/o500.mema" > /dev/null 2>&1
  "$mema" map "$data/bun_zipper.ply" -k 4000 -o "$tmp/b4k.mema" > /dev/null 2>&1
  for map in o16k o500; do
    /usr/bin/time -f '{"wall": %e, "user": %U, "rss_kb": %M}' -o "$tmp/time" \
      "$mema" draw "$data/office1.pcd" "$tmp/$map.mema" -o "$tmp/$map.png" --json 2>/dev/null > "$tmp/d.json"
    jq_line run "draw $map" report "@$tmp/d.json" time "@$tmp/time"
  done
  /usr/bin/time -f '{"wall": %e, "user": %U, "rss_kb": %M}' -o "$tmp/time" \
    "$mema" export "$tmp/b4k.mema" -o "$tmp/b4k.glb" --json 2>/dev/null > "$tmp/x.json"
  jq_line run "export b4k" report "@$tmp/x.json" time "@$tmp/time"
}

run paper paper paper
run clouds clouds clouds
run streaming streaming streaming
run stream-vs-batch-400 streaming stream_vs_batch 400
run stream-vs-batch-150 streaming stream_vs_batch 150
run board-fidelity board-fidelity scripts/board-fidelity.sh
run tolerance tolerance tolerance
run surface surface surface
run queries queries queries
run ablation ablation ablation
run draw draw draw
run bench bench "$mema" bench --data "$data"
run pacing pacing pacing
run reference reference reference
run check firmware check
run python python scripts/bench.sh --only python
run free-space free-space scripts/bench.sh --only free-space
run fidelity fidelity scripts/bench.sh --only fidelity --gmm-cache "${MEMA_GMM_CACHE:-target/gmm-cache}" --json

previous=$tmp/previous.md
if [ -e "$out" ]; then cp "$out" "$previous"; else : > "$previous"; fi
python3 scripts/results/render.py "$logs" "$previous" "${MEMA_RESULTS_KEEP:-}" > "$tmp/results.md"
mv "$tmp/results.md" "$out"
echo "wrote $out" >&2
