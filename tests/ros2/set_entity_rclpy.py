"""rclpy's own client of the gateway's set_entity_state and get_entity_state (docs/ros2.md,
"Entities").

Usage: set_entity_rclpy.py ENTITY X Y Z YAW [--timeout S]

Sets ENTITY's pose (position X Y Z, yaw YAW radians about z) and prints
{"call": "set_entity_state", "result": CODE, "error_message": TEXT}; when that succeeded, reads the
entity with get_entity_state until its position is X Y Z (at most 20 s) and prints
{"call": "get_entity_state", "result": CODE, "p": [x, y, z], "q": [x, y, z, w]}.
Exits 1 when a service does not show up or a call gets no answer.
"""
import argparse
import json
import math
import sys
import time

import rclpy
import rclpy_end
from rclpy.node import Node
from simulation_interfaces.srv import GetEntityState, SetEntityState


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('entity')
    ap.add_argument('xyz_yaw', type=float, nargs=4)
    ap.add_argument('--timeout', type=float, default=60.0)
    a = ap.parse_args()
    x, y, z, yaw = a.xyz_yaw
    rclpy.init()
    node = Node('tutti_set_entity_rclpy')
    try:
        def call(srv, name, req):
            c = node.create_client(srv, name)
            if not c.wait_for_service(timeout_sec=a.timeout):
                raise SystemExit(f'service {name} not found')
            f = c.call_async(req)
            rclpy.spin_until_future_complete(node, f, timeout_sec=a.timeout)
            if not f.done():
                raise SystemExit(f'{name}: no answer within {a.timeout} s')
            return f.result()

        req = SetEntityState.Request(entity=a.entity)
        req.state.header.frame_id = 'world'
        p, q = req.state.pose.position, req.state.pose.orientation
        p.x, p.y, p.z = x, y, z
        q.z, q.w = math.sin(yaw / 2), math.cos(yaw / 2)
        r = call(SetEntityState, '/set_entity_state', req)
        print(json.dumps({'call': 'set_entity_state', 'result': r.result.result,
                          'error_message': r.result.error_message}), flush=True)
        if r.result.result != 1:
            return 0
        end = time.monotonic() + 20.0
        while True:
            s = call(GetEntityState, '/get_entity_state', GetEntityState.Request(entity=a.entity))
            pos, o = s.state.pose.position, s.state.pose.orientation
            if [pos.x, pos.y, pos.z] == [x, y, z] or time.monotonic() > end:
                break
            time.sleep(0.05)
        print(json.dumps({'call': 'get_entity_state', 'result': s.result.result, 'p': [pos.x, pos.y, pos.z],
                          'q': [o.x, o.y, o.z, o.w]}), flush=True)
    finally:
        node.destroy_node()
        rclpy_end.shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
