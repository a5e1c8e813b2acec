"""An rclpy node on simulated time (use_sim_time) beside the gateway's /clock (docs/gateway.md).

Usage: sim_time.py SAMPLES

Subscribes to /clock itself, and reads the node's clock (which rclpy's time source sets from
/clock when use_sim_time is true) after each spin. Prints `clock NS SOURCE RECEIVED` for
each /clock message (its time, the writer's source timestamp and the reception time, in ns),
`now NS` for each distinct reading of the node's clock, and once `active BOOL` (whether ROS
time is overridden by /clock), `publishers N` (the /clock writers it sees) and `wall NS`;
exits after SAMPLES /clock messages, or with 1 when they do not come within 60 s.
"""
import sys
import time

import rclpy
import rclpy_end
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock


def main():
    samples = int(sys.argv[1])
    rclpy.init()
    node = Node('tutti_sim_time', parameter_overrides=[Parameter('use_sim_time', Parameter.Type.BOOL, True)])
    clocks = []
    node.create_subscription(
        Clock, '/clock',
        lambda m, info: clocks.append(
            f'{m.clock.sec * 10**9 + m.clock.nanosec} {info["source_timestamp"]} {info["received_timestamp"]}'),
        QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
    print(f'wall {time.time_ns()}', flush=True)
    seen, last = 0, None
    end = time.monotonic() + 60
    try:
        while len(clocks) < samples and time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.1)
            for c in clocks[seen:]:
                print(f'clock {c}', flush=True)
            seen = len(clocks)
            now = node.get_clock().now().nanoseconds
            if now != last:
                print(f'now {now}', flush=True)
                last = now
        print(f'active {str(node.get_clock().ros_time_is_active).lower()}', flush=True)
        print(f'publishers {node.count_publishers("/clock")}', flush=True)
        # The /clock messages the time source had and this subscription not yet.
        end = time.monotonic() + 0.5
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
        for c in clocks[seen:]:
            print(f'clock {c}', flush=True)
    finally:
        node.destroy_node()
        rclpy_end.shutdown()
    return 0 if len(clocks) >= samples else 1


if __name__ == '__main__':
    sys.exit(main())
