#!/usr/bin/env bash
# The main job: the UAV formation co-simulation demo (see docs/uav-demo.md), from a fresh
# Debian machine with the Rust toolchain, Python 3 and apt.
#
#   ./launch-scripts/uav-demo.sh                      # the paper's run: 120 s simulated, ~30 s wall
#   ./launch-scripts/uav-demo.sh --scenario short     # any option of `tutti demo uav`
#
# Installs what it needs (gcc for the C components, the DejaVu font for the figures, Python 3),
# builds tutti and librtapi in release, then runs `tutti demo uav --out out/uav`. Results:
# out/uav/figure5.png, out/uav/figure6.png, the CSV files and summary.txt. The exit status is
# the demo's: non-zero when a check fails.
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n== %s\n' "$*" >&2; }

# --- Debian packages: C compiler, the font plotters renders text with, Python 3.
packages=(gcc libc6-dev fonts-dejavu-core python3)
missing=()
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ] && command -v apt-get >/dev/null; then
    step "installing Debian packages: ${missing[*]}"
    sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
fi

# --- Python: the monitoring script needs only the standard library and python/tutti_rtapi.py.
if [ -z "${TUTTI_PYTHON:-}" ]; then
    if [ -x .venv/bin/python ]; then
        export TUTTI_PYTHON="$PWD/.venv/bin/python"
    else
        export TUTTI_PYTHON="$(command -v python3)"
    fi
fi

step "building tutti and librtapi (release)"
cargo build --release --locked --quiet -p tutti -p tutti-rtapi

step "tutti demo uav --out out/uav $*"
exec ./target/release/tutti demo uav --out out/uav "$@"
