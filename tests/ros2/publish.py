"""An rclpy publisher writing one message again and again (a SUBSCRIBE set of the gateway).

Usage: publish.py TOPIC TYPE FIELDS [--every SECONDS] [--timeout SECONDS]

TYPE is a ROS 2 message type (`pkg/msg/Name`), FIELDS a JSON object of its fields. Waits for
a subscription to match (the gateway's), then publishes every SECONDS (default 0.1), RELIABLE
and VOLATILE with a depth of 10, until interrupted (exit 0) or TIMEOUT (default 120) passes
(exit 1). Prints `matched N` once a subscription matches and `published K` every tenth message.
"""
import argparse
import importlib
import json
import time

import rclpy
import rclpy_end
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy


def message_class(type_name):
    pkg, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{pkg}.{kind}'), name)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('topic')
    ap.add_argument('type')
    ap.add_argument('fields')
    ap.add_argument('--every', type=float, default=0.1)
    ap.add_argument('--timeout', type=float, default=120)
    a = ap.parse_args()
    rclpy.init()
    node = Node('tutti_test_publisher')
    cls = message_class(a.type)
    msg = cls()
    for k, v in json.loads(a.fields).items():
        setattr(msg, k, v)
    pub = node.create_publisher(cls, a.topic, QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    end = time.monotonic() + a.timeout
    sent, matched = 0, False
    try:
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=a.every)
            if not matched:
                n = pub.get_subscription_count()
                if n == 0:
                    continue
                print(f'matched {n}', flush=True)
                matched = True
            pub.publish(msg)
            sent += 1
            if sent % 10 == 0:
                print(f'published {sent}', flush=True)
        print(f'timeout after {sent} messages', flush=True)
        return 1
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        node.destroy_node()
        rclpy_end.shutdown()


if __name__ == '__main__':
    raise SystemExit(main())
