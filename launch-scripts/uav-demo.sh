#!/usr/bin/env bash
# The main job: the UAV formation co-simulation demo (see docs/uav-demo.md).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --locked --quiet
./target/release/tutti check ddf/multiuav.ddf
./target/release/tutti show ddf/multiuav.ddf
