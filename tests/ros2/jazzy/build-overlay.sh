#!/usr/bin/env bash
# build-overlay.sh SRC WS: tf2_msgs, tf2 (C++), tf2_py and tf2_ros_py (ros2/geometry2, jazzy) built over the
# workspace build-ws.sh made, into the same merged install prefix WS/install. Called by build.sh.
#
# SRC: geometry2-jazzy-src.tar.xz beside this script, unpacked (SRC/ros2/geometry2/{tf2,tf2_msgs,tf2_py,tf2_ros_py};
#      SOURCES-geometry2.txt names the commit). build.sh unpacks it afresh before each call: it is patched in place.
# WS:  a workspace build-ws.sh built (WS/venv, WS/deps, WS/install). This adds WS/build-geometry2 and installs into
#      WS/install. JOBS (default 2): compile jobs. Reaches no network.
set -euo pipefail
SRC=$(cd "${1:?usage: build-overlay.sh SRC WS}" && pwd)
WS=$(cd "${2:?usage: build-overlay.sh SRC WS}" && pwd)
JOBS=${JOBS:-2}
t0=$(date +%s)
say() { echo "[ros2 overlay $(( $(date +%s) - t0 ))s] $*"; }
[ -x "$WS/venv/bin/colcon" ] && [ -f "$WS/install/setup.bash" ] || { echo "no base workspace in $WS (build.sh builds it)"; exit 1; }

# 1. patches
# tf2_ros_py imports sensor_msgs.msg.PointCloud2 at module level, only to name it in a type hint (MsgStamped), and
# the base workspace has no sensor_msgs: import it when there is one, else let the hint name PointStamped instead.
BI="$SRC/ros2/geometry2/tf2_ros_py/tf2_ros/buffer_interface.py"
sed -i 's/^from sensor_msgs\.msg import PointCloud2$/try:\n    from sensor_msgs.msg import PointCloud2\nexcept ImportError:  # no sensor_msgs here (patched by build-overlay.sh)\n    PointCloud2 = PointStamped/' "$BI"
grep -q '^    PointCloud2 = PointStamped$' "$BI" || { echo "$BI is not the one this patch knows"; exit 1; }

# 2. the environment build-ws.sh builds in, over the base workspace
# shellcheck disable=SC1091
. "$WS/venv/bin/activate"
set +u
# shellcheck disable=SC1091
. "$WS/install/setup.bash"
set -u
DEPS=$WS/deps/usr
export RMW_IMPLEMENTATION=rmw_cyclonedds_cpp
DISTRO=$(sed -n 's/^# distro: *//p' "$WS/sources/DISTRO" 2>/dev/null || true)
[ -n "$DISTRO" ] && export ROS_DISTRO_OVERRIDE=$DISTRO
export CMAKE_PREFIX_PATH="$DEPS${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}"
export LD_LIBRARY_PATH="$DEPS/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export CPATH="$DEPS/include/x86_64-linux-gnu${CPATH:+:$CPATH}"
export MAKEFLAGS="-j$JOBS"

# 3. build
say "colcon build tf2_msgs tf2 tf2_py tf2_ros_py ($JOBS jobs)"
cd "$WS"
colcon build --merge-install --base-paths "$SRC" --build-base "$WS/build-geometry2" --install-base "$WS/install" \
  --executor sequential \
  --packages-select tf2_msgs tf2 tf2_py tf2_ros_py \
  --cmake-args -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release \
     -DPython3_EXECUTABLE="$WS/venv/bin/python3" -DPYTHON_EXECUTABLE="$WS/venv/bin/python3" \
  --event-handlers console_cohesion+ summary+ status-
say "done"
