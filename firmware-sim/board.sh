#!/usr/bin/env bash
# The firmware on an STM32F405 under QEMU (issue 22): builds the board image if needed
# (firmware-sim/boards/stm32f405, the entity model chosen at build time), starts it under
# `qemu-system-arm -machine netduinoplus2` with USART1 on a pty, runs `mema device` against it
# with CAPTURE (or a cloud, bag or .conf, encoded as scanner-sim encodes them), writes the map
# the board sent to OUT_MAP, and prints as its last line the summary: the board's layout (model,
# k, working, as the board says them) and `mema device --json`'s counts. The same capture replays to the same bytes with
#   mema replay CAPTURE -k K --working W --model MODEL
#
#   firmware-sim/board.sh CAPTURE OUT_MAP [--model shells|paper] [--queries N]
#
# --queries N: after the map, N questions of it (nearest surface and ray cast) answered on the
# board, checked against the host's answers, with the instructions one took.
# MEMA=path/to/mema uses that build of the host's command instead of building one.
# Needs: the thumbv7em-none-eabihf target and qemu-system-arm (scripts/test.sh installs both).
set -euo pipefail
usage() { echo "usage: firmware-sim/board.sh CAPTURE OUT_MAP [--model shells|paper] [--queries N]" >&2; exit 2; }
[ $# -ge 2 ] || usage
input=$(realpath "$1")
out=$(realpath -m "$2")
shift 2
model=shells
queries=0
while [ $# -gt 0 ]; do
  case "$1" in
    --model) [ $# -ge 2 ] || usage; model=$2; shift 2 ;;
    --queries) [ $# -ge 2 ] || usage; queries=$2; shift 2 ;;
    *) usage ;;
  esac
done
case "$model" in
  shells) features=() ;;
  paper) features=(--features paper) ;;
  *) echo "board.sh: --model is shells or paper, not $model" >&2; exit 2 ;;
esac
cd "$(dirname "$0")/.."

# The host's command: $MEMA if set (a mema already built), else built here.
if [ -z "${MEMA:-}" ]; then
  cargo build -q --release -p mema
  MEMA="${CARGO_TARGET_DIR:-target}/release/mema"
fi
board=firmware-sim/boards/stm32f405
# One target directory per model: both images stay built.
(cd "$board" && cargo fmt --check && cargo clippy -q --release --target-dir "target/$model" "${features[@]}" -- -D warnings \
  && cargo build -q --release --target-dir "target/$model" "${features[@]}")
image="$board/target/$model/thumbv7em-none-eabihf/release/mema-board-stm32f405"

work=$(mktemp -d)
qemu_pid=
cleanup() {
  [ -n "$qemu_pid" ] && kill "$qemu_pid" 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT
qemu-system-arm -machine netduinoplus2 -nographic -monitor none -serial pty -icount shift=0 \
  -kernel "$image" > "$work/qemu.txt" 2>&1 &
qemu_pid=$!
pty=
for _ in $(seq 100); do
  pty=$(grep -o '/dev/pts/[0-9]*' "$work/qemu.txt" | head -1 || true)
  [ -n "$pty" ] && break
  kill -0 "$qemu_pid" 2>/dev/null || { echo "board.sh: QEMU did not start:" >&2; cat "$work/qemu.txt" >&2; exit 1; }
  sleep 0.1
done
[ -n "$pty" ] || { echo "board.sh: QEMU gave no pty" >&2; exit 1; }
summary=$("$MEMA" device --port "$pty" "$input" -o "$out" --queries "$queries" --json)
# The layout the image was built with, as the board itself says it when the session begins.
k=$(printf '%s' "$summary" | grep -o '"capacity":[0-9]*' | cut -d: -f2)
working=$(printf '%s' "$summary" | grep -o '"working":[0-9]*' | head -1 | cut -d: -f2)
echo "{\"board\":\"stm32f405\",\"model\":\"$model\",\"k\":$k,\"working\":$working,\"device\":$summary}"
