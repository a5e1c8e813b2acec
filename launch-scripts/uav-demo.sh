#!/usr/bin/env bash
# The main job: the UAV formation co-simulation demo (see docs/uav-demo.md), from a fresh
# Debian machine with the Rust toolchain, Python 3 and apt.
#
#   ./launch-scripts/uav-demo.sh                      # the paper's run: 120 s simulated, ~30 s wall
#   ./launch-scripts/uav-demo.sh --scenario short     # any option of `tutti-demo uav`
#
# Installs what it needs (gcc for the C components, the DejaVu font for the figures, Python 3,
# cmake and libclang for the Cyclone DDS engine),
# builds tutti, librtapi and tutti-demo in release, then runs `tutti-demo uav --out out/uav`, which
# runs the scenario's launch file (examples/uav/uav-demo.json5) with `tutti run`. Results:
# out/uav/figure5.png, out/uav/figure6.png, the CSV files and summary.txt. The exit status is
# the demo's: non-zero when a check fails.
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n== %s\n' "$*" >&2; }
. launch-scripts/lib.sh

# --- Debian packages: C compiler, the font plotters renders text with, Python 3, and what
# the gateway's Cyclone DDS engine builds with (cmake, libclang for bindgen, OpenSSL for its
# DDS Security plugins). Without apt-get the demo goes on: what is missing fails later with its
# own message.
ensure_debian_packages gcc g++ libc6-dev cmake libclang-dev libssl-dev pkgconf fonts-dejavu-core python3 || true

# --- Python: the monitoring script needs only the standard library and python/tutti_rtapi.py.
if [ -z "${TUTTI_PYTHON:-}" ]; then
    if [ -x .venv/bin/python ]; then
        export TUTTI_PYTHON="$PWD/.venv/bin/python"
    else
        export TUTTI_PYTHON="$(command -v python3)"
    fi
fi

step "building tutti, librtapi and tutti-demo (release)"
cargo build --release --locked --quiet -p tutti -p tutti-rtapi -p tutti-uav-demo

step "tutti-demo uav --out out/uav $*"
exec ./target/release/tutti-demo uav --out out/uav "$@"
