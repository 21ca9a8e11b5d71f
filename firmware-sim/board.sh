#!/usr/bin/env bash
# The firmware on an STM32F405 under QEMU (issue 22): builds the board image if needed
# (firmware-sim/boards/stm32f405, the entity model chosen at build time), starts it under
# `qemu-system-arm -machine netduinoplus2` with USART1 on a pty, runs `mema device` against it
# with CAPTURE (or a cloud, bag or .conf, encoded as scanner-sim encodes them), writes the map
# the board sent to OUT_MAP, and prints as its last line the summary: the board's layout (model,
# k, working, as the board says them) and `mema device --json`'s counts. The same capture replays to the same bytes with
#   mema replay CAPTURE -k K --working W --model MODEL
#
#   firmware-sim/board.sh CAPTURE OUT_MAP [--model shells|paper] [--queries N] [--sensor]
#
# --queries N: after the map, N questions of it (nearest surface and ray cast) answered on the
# board, checked against the host's answers, with the instructions one took.
# --sensor: a sensor wired to the board instead of a host's session: QEMU gets two ptys, USART1
# and USART2; CAPTURE goes onto the first as a sensor sends it (a capture's bytes as they are,
# a cloud or .conf through `mema scanner-sim`), and `mema device --listen` on the second
# receives the map.
# MEMA=path/to/mema uses that build of the host's command instead of building one.
# Needs: the thumbv7em-none-eabihf target and qemu-system-arm (scripts/test.sh installs both).
set -euo pipefail
usage() { echo "usage: firmware-sim/board.sh CAPTURE OUT_MAP [--model shells|paper] [--queries N] [--sensor]" >&2; exit 2; }
[ $# -ge 2 ] || usage
input=$(realpath "$1")
out=$(realpath -m "$2")
shift 2
model=shells
queries=0
sensor=0
while [ $# -gt 0 ]; do
  case "$1" in
    --model) [ $# -ge 2 ] || usage; model=$2; shift 2 ;;
    --queries) [ $# -ge 2 ] || usage; queries=$2; shift 2 ;;
    --sensor) sensor=1; shift ;;
    *) usage ;;
  esac
done
case "$model" in
  shells) features=(--features qemu) ;;
  paper) features=(--features qemu,paper) ;;
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
# QEMU's netduinoplus2 puts its serial ports on the USARTs in order: the first on USART1, the
# second on USART2.
serials=(-serial pty)
[ "$sensor" = 1 ] && serials+=(-serial pty)
ports=$(( ${#serials[@]} / 2 ))
qemu-system-arm -machine netduinoplus2 -nographic -monitor none "${serials[@]}" -icount shift=0 \
  ${MEMA_QEMU_LOG:+-d guest_errors,int -D "$MEMA_QEMU_LOG"} -kernel "$image" > "$work/qemu.txt" 2>&1 &
qemu_pid=$!
ptys=()
for _ in $(seq 100); do
  mapfile -t ptys < <(grep -o '/dev/pts/[0-9]*' "$work/qemu.txt" || true)
  [ "${#ptys[@]}" -ge "$ports" ] && break
  kill -0 "$qemu_pid" 2>/dev/null || { echo "board.sh: QEMU did not start:" >&2; cat "$work/qemu.txt" >&2; exit 1; }
  sleep 0.1
done
[ "${#ptys[@]}" -ge "$ports" ] || { echo "board.sh: QEMU gave no pty" >&2; exit 1; }
if [ "$sensor" = 1 ]; then
  # Held open here: the sensor's end closing it would hang up QEMU's side before the board
  # had read all it wrote.
  exec 3<>"${ptys[0]}"
  "$MEMA" device --listen "${ptys[1]}" -o "$out" --queries "$queries" --json > "$work/summary.json" &
  listener=$!
  if [ "$(head -c 1 "$input" | od -An -tu1 | tr -d ' ')" = 0 ]; then
    cat "$input" > "${ptys[0]}"
  elif [[ "$input" == *.conf ]]; then
    "$MEMA" scanner-sim --port "${ptys[0]}" --conf "$input"
  else
    "$MEMA" scanner-sim --port "${ptys[0]}" "$input"
  fi
  wait "$listener" || { echo "board.sh: mema device --listen failed" >&2; exit 1; }
  summary=$(cat "$work/summary.json")
else
  summary=$("$MEMA" device --port "${ptys[0]}" "$input" -o "$out" --queries "$queries" --json)
fi
# The layout the image was built with, as the board itself says it.
k=$(printf '%s' "$summary" | grep -o '"capacity":[0-9]*' | cut -d: -f2)
working=$(printf '%s' "$summary" | grep -o '"working":[0-9]*' | head -1 | cut -d: -f2)
link=host; [ "$sensor" = 1 ] && link=sensor
echo "{\"board\":\"stm32f405\",\"model\":\"$model\",\"link\":\"$link\",\"k\":$k,\"working\":$working,\"device\":$summary}"
