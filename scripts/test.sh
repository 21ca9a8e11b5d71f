#!/usr/bin/env bash
# The test command (README, .ci/run): installs what the tests need, then runs every check.
# Real-data tests run in the release profile; the shared clouds are read from ../shared/data.
set -euo pipefail
cd "$(dirname "$0")/.."

if [ ! -d ../shared/data ]; then
  echo "test.sh: ../shared/data is missing; the tests read the shared real clouds from there" >&2
  exit 1
fi
rustup component add rustfmt clippy >/dev/null 2>&1 || true
# The serial tests drive the real binaries over a pseudo-terminal pair made by socat.
if ! command -v socat >/dev/null 2>&1; then
  echo "== installing socat"
  if [ "$(id -u)" = 0 ]; then apt-get update -qq && apt-get install -y -qq socat; else sudo apt-get update -qq && sudo apt-get install -y -qq socat; fi
fi

# The firmware check builds a Cortex-M4F image and runs it under QEMU (firmware-sim/check.sh).
rustup target add thumbv7em-none-eabihf >/dev/null 2>&1 || true
if ! command -v qemu-system-arm >/dev/null 2>&1 || ! command -v llvm-size >/dev/null 2>&1; then
  echo "== installing qemu-system-arm and llvm"
  sudo_=""; [ "$(id -u)" = 0 ] || sudo_=sudo
  $sudo_ apt-get update -qq && $sudo_ apt-get install -y -qq --no-install-recommends qemu-system-arm llvm
fi

echo "== cargo fmt --check"
cargo fmt --all --check
echo "== cargo clippy"
cargo clippy --workspace --all-targets -- -D warnings
echo "== core builds without std"
cargo build -p mema-core --no-default-features
echo "== fuzz targets build (campaigns: scripts/fuzz.sh; their properties are tested below)"
(cd core/fuzz && cargo fmt --check && cargo clippy -q -- -D warnings)
(cd host/fuzz && cargo fmt --check && cargo clippy -q -- -D warnings)
(cd firmware-sim/fuzz && cargo fmt --check && cargo clippy -q -- -D warnings)
echo "== the host library builds without the command line (no clap)"
cargo check -p mema --lib --no-default-features
echo "== the library's documentation builds without warnings"
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --quiet
# A virtual environment for the Python package's tests (below) and the bag tests' independent
# writer (tests/bags/write_bag.py: rosbags, pure Python, writes ROS 2 bags without ROS).
if ! python3 -c 'import venv, ensurepip' >/dev/null 2>&1; then
  echo "== installing python3-venv"
  sudo_=""; [ "$(id -u)" = 0 ] || sudo_=sudo
  $sudo_ apt-get update -qq && $sudo_ apt-get install -y -qq python3-venv
fi
[ -x target/py-venv/bin/python ] || python3 -m venv target/py-venv
target/py-venv/bin/python -m pip install --quiet rosbags==0.11.9 numpy "laspy[lazrs]==2.7.0" pyoctomap==1.2.2
# The Python package goes in before the tests: the guides' commands (tests/tests/docs.rs) run
# `python -m mema.tiles` from this environment. Its own workspace, built into the main target/.
echo "== the Python package: pip install into the virtual environment"
CARGO_TARGET_DIR="$PWD/target" target/py-venv/bin/python -m pip install --quiet ./host/python pytest numpy "dask==2026.8.0" "distributed==2026.8.0"
echo "== tests (release profile: real clouds)"
MEMA_PY="$PWD/target/py-venv/bin/python" cargo test --workspace --release
echo "== firmware: bit for bit across builds and targets, and the budget"
firmware-sim/check.sh | tee target/check.log
echo "== docs/results.md's firmware figures are this build's (scripts/results/held.py)"
python3 scripts/results/held.py target/check.log
echo "== the Python package: lint and pytest (installed above)"
# Its own workspace (host/python), built into the main target directory.
(cd host/python && cargo fmt --check)
CARGO_TARGET_DIR="$PWD/target" cargo clippy --manifest-path host/python/Cargo.toml --all-targets -- -D warnings
# The tests compare the package with the command line built above by `cargo test --release`.
cargo build --release -p mema --quiet
MEMA_BIN="$PWD/target/release/mema" target/py-venv/bin/python -m pytest -q host/python/tests
