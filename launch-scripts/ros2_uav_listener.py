#!/usr/bin/env python3
"""An rclpy node printing the UAV states of ddf/multiuav.ddf as the tutti gateway publishes
them on /multiuav_uavN/subscribe (type multiuav_msgs/msg/MultiuavUavNSubscribe).

Build the interface package first (ROS 2 Humble or later sourced):

    tutti idl ddf/multiuav.ddf --out idl        # or use the committed idl/multiuav_msgs
    mkdir -p ~/ws/src && cp -r idl/multiuav_msgs ~/ws/src/
    cd ~/ws && colcon build --packages-select multiuav_msgs && source install/setup.bash
    python3 launch-scripts/ros2_uav_listener.py --ros-args -p uavs:=[1,2]

The gateway must run in the same ROS_DOMAIN_ID. Its writers are RELIABLE (KEEP_ALL in these
synchronous domains) and SHARED in the default ros2 QoS profile, so the default subscription
profile below matches.
"""
import importlib
import sys

import rclpy
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy, HistoryPolicy, DurabilityPolicy


class UavListener(Node):
    def __init__(self):
        super().__init__("uav_listener")
        self.declare_parameter("uavs", [1, 2, 3, 4])
        msgs = importlib.import_module("multiuav_msgs.msg")
        qos = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=10,
                         durability=DurabilityPolicy.VOLATILE)
        self.subs = []
        for n in self.get_parameter("uavs").value:
            msg_type = getattr(msgs, f"MultiuavUav{n}Subscribe")
            self.subs.append(self.create_subscription(
                msg_type, f"/multiuav_uav{n}/subscribe", lambda m, n=n: self.on_state(n, m), qos))

    def on_state(self, n, m):
        self.get_logger().info(
            f"uav{n} step {m.step} t={m.sim_time:.3f}s lat={m.latitude:.6f} lon={m.longitude:.6f} "
            f"elev={m.elevation:.1f} m airspeed={m.airspeed:.1f} m/s heading={m.heading:.1f} deg")

RCLError = rclpy_implementation.RCLError


def main():
    rclpy.init(args=sys.argv)
    node = UavListener()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        # Ctrl-C: rclpy's own SIGINT handler shuts the context down under the spin.
        pass
    finally:
        node.destroy_node()
        try:
            rclpy.try_shutdown()
        except RCLError:
            # Ctrl-C: rclpy's SIGINT handler may be shutting the context down at this moment
            # (on rmw_zenoh, closing the session takes a while), which try_shutdown misses.
            pass


if __name__ == "__main__":
    main()
