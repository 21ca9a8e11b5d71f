#!/usr/bin/env bash
# The board's map against the host's batch map at the same bytes (issues 22 and 31, docs/board.md,
# "The board's layout"): each shared cloud and registered set encoded as `mema scanner-sim` sends it, mapped as the
# board maps it (`mema replay -k K --working 150`, carving at K = 700 as the board does, which the board equals byte for byte) at each
# K given, then `mema map --bytes` of the same cloud at that map's size; both scored by
# `mema eval` (two-way Chamfer distance, mm, 50,000 surface samples).
#
#   scripts/board-fidelity.sh [K ...]        (default: 400 700, today's image and the board)
#
# The last line is the geometric mean of the ratios: one cloud's ratio moves by a tenth with
# small changes to the stream (docs/design.md, "A device's layout"), so levers are judged on it.
#
# MEMA=path/to/mema uses that build; the clouds are read from ../shared/data in place.
set -euo pipefail
cd "$(dirname "$0")/.."
ks=("$@")
[ ${#ks[@]} -gt 0 ] || ks=(400 700)
if [ -z "${MEMA:-}" ]; then
  cargo build -q --release -p mema
  MEMA="${CARGO_TARGET_DIR:-target}/release/mema"
fi
data=../shared/data
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
chamfer() { "$MEMA" eval "$1" "$2" --json --samples 50000 | python3 -c 'import json, sys; print("%.4f" % (1000 * json.load(sys.stdin)["chamfer"]))'; }
printf '%-18s %6s %8s %9s %15s %15s %6s\n' cloud K bytes entities "board (mm)" "batch (mm)" ratio
ratios=()
# Every shared cloud, then the registered sets, each sent as scanner-sim sends it (a .conf's
# scans after their poses).
clouds=(car6.pcd bun000.ply lamppost.pcd milk.pcd cturtle.pcd office1.pcd five_people.pcd)
shopt -s nullglob
for path in "$data"/*.ply "$data"/*.pcd "$data"/*.las "$data"/*.laz; do
  name=$(basename "$path")
  [[ " ${clouds[*]} " == *" $name "* ]] || clouds+=("$name")
done
clouds+=(bun.conf ouster_os1.conf)
for cloud in "${clouds[@]}"; do
  conf=()
  [[ $cloud == *.conf ]] && conf=(--conf)
  "$MEMA" scanner-sim --port "$work/$cloud.bin" "${conf[@]}" "$data/$cloud" 2>/dev/null
  for k in "${ks[@]}"; do
    board="$work/$cloud.$k.board.mema"
    batch="$work/$cloud.$k.batch.mema"
    # The board (K = 700) carves as `--carve 124x512 --carve-every 2`; the 64 KiB image does not.
    carve=()
    [ "$k" = 700 ] && carve=(--carve 124x512 --carve-every 2)
    "$MEMA" replay "$work/$cloud.bin" -k "$k" --working 150 "${carve[@]}" -o "$board" >/dev/null 2>&1
    bytes=$(stat -c %s "$board")
    "$MEMA" map "$data/$cloud" --bytes "$bytes" -o "$batch" >/dev/null 2>&1
    entities=$("$MEMA" info "$board" --json | python3 -c 'import json, sys; print(json.load(sys.stdin)["entities"])')
    b=$(chamfer "$data/$cloud" "$board")
    h=$(chamfer "$data/$cloud" "$batch")
    printf '%-18s %6s %8s %9s %15s %15s %6.2f\n' "$cloud" "$k" "$bytes" "$entities" "$b" "$h" "$(python3 -c "print($b / $h)")"
    ratios+=("$b/$h")
  done
done
python3 -c "import math, sys; r = [float(x.split('/')[0]) / float(x.split('/')[1]) for x in sys.argv[1:]]; print('geometric mean of %d ratios: %.3f' % (len(r), math.exp(sum(map(math.log, r)) / len(r))))" "${ratios[@]}"
