#!/usr/bin/env bash
# The board's image as a raw binary for a flasher that takes one (dfu-util through the
# STM32's ROM bootloader, the Crazyflie's cfloader), with the address it goes to:
#
#   firmware-sim/boards/stm32f405/flash-image.sh OUT.bin [--model shells|paper] [--crazyflie]
#
# --crazyflie links the image above the Crazyflie 2.x's bootloader (at 0x08004000), which it
# then keeps. Needs the thumbv7em-none-eabihf target and llvm-objcopy (scripts/test.sh installs
# both).
set -euo pipefail
usage() { echo "usage: flash-image.sh OUT.bin [--model shells|paper] [--crazyflie]" >&2; exit 2; }
[ $# -ge 1 ] || usage
out=$(realpath -m "$1")
shift
model=shells
features=()
while [ $# -gt 0 ]; do
  case "$1" in
    --model) [ $# -ge 2 ] || usage; model=$2; shift 2 ;;
    --crazyflie) features+=(crazyflie); shift ;;
    *) usage ;;
  esac
done
case "$model" in
  shells) ;;
  paper) features+=(paper) ;;
  *) echo "flash-image.sh: --model is shells or paper, not $model" >&2; exit 2 ;;
esac
cd "$(dirname "$0")"
variant="$model${features:+-$(IFS=-; echo "${features[*]}")}"
feature_args=()
[ ${#features[@]} -eq 0 ] || feature_args=(--features "$(IFS=,; echo "${features[*]}")")
cargo build -q --release --target-dir "target/$variant" "${feature_args[@]}"
elf="target/$variant/thumbv7em-none-eabihf/release/mema-board-stm32f405"
llvm-objcopy -O binary "$elf" "$out"
# The address of the first byte: where the vector table, the image's start, was linked.
at=$(llvm-readelf -S "$elf" | awk '{ for (i = 1; i < NF; i++) if ($i == ".vector_table") print $(i + 2) }')
echo "$(basename "$out"): $(stat -c %s "$out") bytes to write at 0x$at"
