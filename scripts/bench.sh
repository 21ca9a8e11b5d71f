#!/usr/bin/env bash
# Runs `mema bench` with every benchmark, including the Python comparison (benchmark 4).
# Installs numpy and scikit-learn into a private virtualenv first: only benchmarking needs them,
# so scripts/test.sh never does. Extra arguments go to `mema bench` (e.g. --only kmeans).
set -euo pipefail
cd "$(dirname "$0")/.."

venv="${MEMA_BENCH_VENV:-target/bench-venv}"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check numpy scikit-learn pyoctomap==1.2.2

cargo build --release -p mema
"${CARGO_TARGET_DIR:-target}/release/mema" bench --data ../shared/data --python "$venv/bin/python" "$@"
