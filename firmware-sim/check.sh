#!/usr/bin/env bash
# Issue 4, bit for bit across builds and targets: the same capture mapped by
#   - `mema replay` (host, release),
#   - `mema-firmware-sim run` built in release, in debug, and in release with -C target-cpu=native
#     (each with different UART chunkings), and
#   - the Cortex-M4F image under qemu-system-arm (mps2-an386, semihosting),
# must give identical map bytes, in both entity models (`--model paper` and `--model shells`; the
# image reads its model from model.txt). Everything is built and compared in this run; no stored
# hash. Then `mema-firmware-sim budget` prints the memory and cycle figures from the image's runs.
# Needs: the thumbv7em-none-eabihf target, qemu-system-arm, llvm-size (scripts/test.sh installs).
set -euo pipefail
cd "$(dirname "$0")/.."

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
minimal=(--no-default-features --features std -p mema-firmware-sim)

echo "== firmware: building release, debug, target-cpu=native and the thumbv7em image"
cargo build -q --release -p mema -p mema-firmware-sim
cargo build -q "${minimal[@]}" --target-dir target/fw-debug
RUSTFLAGS="-C target-cpu=native" cargo build -q --release "${minimal[@]}" --target-dir target/fw-native
# The image is its own workspace: its target dir is pinned so a caller's CARGO_TARGET_DIR cannot move it.
(cd firmware-sim/image && cargo fmt --check && cargo clippy -q --release --target-dir target -- -D warnings && cargo build -q --release --target-dir target)
image=firmware-sim/image/target/thumbv7em-none-eabihf/release/mema-firmware-image

# The image's layout: K = 400 ellipsoids, 150 of them in working memory (IMAGE_WORKING/FROZEN).
shape=(-k 400 --working 150)
status=0
for cloud in car6.pcd demo; do
  dir="$work/$cloud"
  mkdir -p "$dir"
  if [ "$cloud" = demo ]; then
    target/release/mema scanner-sim --port "$dir/capture.bin" 2>/dev/null
  else
    target/release/mema scanner-sim --port "$dir/capture.bin" "../shared/data/$cloud" 2>/dev/null
  fi
  for model in paper shells; do
    m="$dir/$model"
    mkdir -p "$m"
    cp "$dir/capture.bin" "$m/capture.bin"
    echo "$model" > "$m/model.txt"
    target/release/mema replay "$m/capture.bin" "${shape[@]}" --model "$model" -o "$m/replay.mema" >/dev/null 2>&1
    target/release/mema-firmware-sim run "$m/capture.bin" "${shape[@]}" --model "$model" -o "$m/release.mema" 2>/dev/null
    target/fw-debug/debug/mema-firmware-sim run "$m/capture.bin" "${shape[@]}" --model "$model" -o "$m/debug.mema" \
      --chunk-seed 7 --max-chunk 13 2>/dev/null
    target/fw-native/release/mema-firmware-sim run "$m/capture.bin" "${shape[@]}" --model "$model" -o "$m/native.mema" \
      --chunk-seed 3 --max-chunk 1000 2>/dev/null
    (cd "$m" && timeout 600 qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic \
      -monitor none -serial none -semihosting-config enable=on,target=native -icount shift=0 \
      -kernel "$OLDPWD/$image" > qemu.txt) || { echo "firmware: QEMU run failed"; cat "$m/qemu.txt"; exit 1; }
    mv "$m/map.mema" "$m/qemu.mema"
    for variant in release debug native qemu; do
      if cmp -s "$m/replay.mema" "$m/$variant.mema"; then
        echo "   $cloud, $model: $variant = mema replay ($(stat -c %s "$m/replay.mema") bytes)"
      else
        echo "firmware: $cloud, $model: $variant differs from mema replay:"
        cmp "$m/replay.mema" "$m/$variant.mema" || true
        status=1
      fi
    done
  done
done
# A line idling at zero: 100,000 zeros in one chunk, decoded at opt-level 0 on a 256 KiB stack
# (the decoder once recursed per idle byte: 512 zeros overflowed it; the test profile's
# optimiser hides that, so this runs in the dev profile).
cargo test -q -p mema-core --profile dev --target-dir target/fw-debug --test idle_line >/dev/null
echo "   100,000 idle zeros in one chunk: decoded on a 256 KiB stack at opt-level 0"
# And 1 MiB of zeros before car6's capture changes nothing in the map of the debug build.
idle="$work/idle"
mkdir -p "$idle"
{ head -c 1048576 /dev/zero; cat "$work/car6.pcd/capture.bin"; } > "$idle/capture.bin"
target/fw-debug/debug/mema-firmware-sim run "$idle/capture.bin" "${shape[@]}" --model shells -o "$idle/debug.mema" \
  --chunk-seed 5 --max-chunk 2000000 2>/dev/null
if cmp -s "$work/car6.pcd/shells/replay.mema" "$idle/debug.mema"; then
  echo "   car6 after 1 MiB of idle zeros, shells: debug = mema replay"
else
  echo "firmware: car6 after 1 MiB of idle zeros: the debug build's map differs"
  status=1
fi
# The board (issue 22): the STM32F405 image under QEMU's netduinoplus2, fed over its USART by
# `mema device` on a pty, sends its map back as downlink frames; the map `mema device` rebuilds
# from them must be `mema replay`'s at the board's layout (the k and working its summary line
# names: BOARD_WORKING + BOARD_FROZEN), byte for byte. And (issue 30) the same capture from a
# sensor wired to USART1, its map to `mema device --listen` on USART2 (board.sh --sensor).
for cloud in car6.pcd demo; do
  for model in paper shells; do
    for link in host sensor; do
      m="$work/$cloud/$model"
      # On car6 the board also answers 32 queries of its map (checked against the host's).
      queries=0; [ "$cloud" = car6.pcd ] && [ "$link" = host ] && queries=32
      flags=(--model "$model" --queries "$queries")
      [ "$link" = sensor ] && flags+=(--sensor)
      MEMA=target/release/mema firmware-sim/board.sh "$m/capture.bin" "$m/$link.mema" "${flags[@]}" > "$m/$link.txt" 2>&1 \
        || { echo "firmware: board.sh failed on $cloud, $model, $link:"; cat "$m/$link.txt"; status=1; continue; }
      k=$(tail -1 "$m/$link.txt" | grep -o '"k":[0-9]*' | head -1 | cut -d: -f2)
      working=$(tail -1 "$m/$link.txt" | grep -o '"working":[0-9]*' | head -1 | cut -d: -f2)
      # The board carves as `--carve 124x512 --carve-every 2` (BOARD_CARVE_IMAGE, BOARD_CARVE_EVERY).
      target/release/mema replay "$m/capture.bin" -k "$k" --working "$working" --model "$model" \
        --carve 124x512 --carve-every 2 -o "$m/board-replay.mema" >/dev/null 2>&1
      if cmp -s "$m/board-replay.mema" "$m/$link.mema"; then
        if [ "$link" = host ]; then
          echo "   $cloud, $model: the STM32F405 board's map over its USART = mema replay"
        else
          echo "   $cloud, $model: a sensor on USART1, the board's map on USART2 = mema replay"
        fi
        # Instructions a point (QEMU -icount; the receive interrupt and the downlink included)
        # and the longest tick, from the board's own timing frame.
        per_point=$(tail -1 "$m/$link.txt" | grep -o '"per_point":[0-9.]*' | cut -d: -f2)
        longest=$(tail -1 "$m/$link.txt" | grep -o '"longest_tick":[0-9.]*' | cut -d: -f2)
        printf '   %s, %s, %s: %.0f instructions a point on the board, longest tick %.0f\n' "$cloud" "$model" "$link" "$per_point" "$longest"
        if [ "$queries" -gt 0 ]; then
          q=$(tail -1 "$m/$link.txt" | grep -o '"queries":{[^}]*}')
          echo "   $cloud, $model: queries on the board, each answer the host's: $q"
        fi
        if ! awk -v p="$per_point" 'BEGIN { exit !(p > 0 && p < 10000) }'; then
          echo "firmware: $cloud, $model, $link: $per_point instructions a point on the board, not under 10,000"
          status=1
        fi
      else
        echo "firmware: $cloud, $model, $link: the board's map differs from mema replay:"
        cmp "$m/board-replay.mema" "$m/$link.mema" || true
        tail -1 "$m/$link.txt"
        status=1
      fi
    done
  done
done
for model in paper shells; do
  echo "== firmware budget (image mapping car6, K = 400: 150 working + 250 frozen; the board, K = 700: 150 + 550; model $model)"
  target/release/mema-firmware-sim budget --image "$image" --qemu-report "$work/car6.pcd/$model/qemu.txt" \
    --board "firmware-sim/boards/stm32f405/target/$model/thumbv7em-none-eabihf/release/mema-board-stm32f405" \
    --board-run "$work/car6.pcd/$model/host.txt"
done
exit $status
