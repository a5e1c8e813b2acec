"""rclpy's own clients of the gateway's entity services, and tf2_ros's listener of /tf
(docs/ros2.md, "Entities"), during a run.

Usage: entities_rclpy.py --states N [--every S] [--frame FRAME] [--pose NAME] [--timeout S]

Waits for the services; prints one JSON line per call:
  {"call": "get_simulator_features", "features": [...]};
  {"call": "get_entities", "filter": ..., "result": CODE, "entities": [...]} for no filter, a name
  filter, a category filter and a tags filter;
  {"call": "get_entity_info", "entity": NAME, "result": CODE, "category": C, "description": ..., "tags": [...]};
  S seconds apart, until N of them had every entity written (a stamp after 0):
  {"call": "get_entities_states", "result": CODE, "entities": [...],
  "states": [STATE, ...]}, STATE = {"frame": ..., "stamp": SECONDS, "p": [x, y, z], "q": [x, y, z, w],
  "v": [x, y, z]};
  {"call": "get_entity_state", "entity": NAME, "result": CODE, "error_message": ..., "state": STATE} for
  the first entity and for one that does not exist;
  {"call": "set_entity_state", "entity": NAME, "result": CODE, "error_message": ...} for the first;
  then, from a tf2_ros Buffer and TransformListener that listened all along, for each entity
  {"call": "tf", "child": NAME, "stamp": SECONDS, "t": [x, y, z], "q": [x, y, z, w]} (the latest
  transform from FRAME), or {"call": "tf", "child": NAME, "error": TEXT}; and with --pose, the last
  geometry_msgs/PoseStamped heard on /NAME/pose: {"call": "pose", "frame": ..., "stamp": SECONDS,
  "p": [x, y, z], "q": [x, y, z, w]} (or {"call": "pose", "error": "none heard"}).
Exits 1 when a service does not show up or a call gets no answer.
"""
import argparse
import json
import sys
import time

import rclpy
import rclpy_end
import rclpy.time
import tf2_ros
from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from simulation_interfaces.msg import EntityCategory
from simulation_interfaces.srv import (GetEntities, GetEntitiesStates, GetEntityInfo, GetEntityState,
                                       GetSimulatorFeatures, SetEntityState)


class Failed(Exception):
    pass


def spin_until(node, future, timeout, what):
    rclpy.spin_until_future_complete(node, future, timeout_sec=timeout)
    if not future.done():
        raise Failed(f'{what}: no answer within {timeout} s')
    return future.result()


def seconds(stamp):
    return stamp.sec + stamp.nanosec * 1e-9


def state(s):
    p, q, v = s.pose.position, s.pose.orientation, s.twist.linear
    return {'frame': s.header.frame_id, 'stamp': seconds(s.header.stamp), 'p': [p.x, p.y, p.z],
            'q': [q.x, q.y, q.z, q.w], 'v': [v.x, v.y, v.z]}


class Calls:
    def __init__(self, node, timeout):
        self.node, self.timeout, self.clients = node, timeout, {}

    def call(self, srv, name, req):
        if name not in self.clients:
            c = self.node.create_client(srv, name)
            if not c.wait_for_service(timeout_sec=self.timeout):
                raise Failed(f'service {name} not found')
            self.clients[name] = c
        return spin_until(self.node, self.clients[name].call_async(req), self.timeout, name)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--states', type=int, default=10)
    ap.add_argument('--every', type=float, default=0.5)
    ap.add_argument('--frame', default='map')
    ap.add_argument('--pose')
    ap.add_argument('--timeout', type=float, default=60.0)
    a = ap.parse_args()
    rclpy.init()
    node = Node('tutti_entities_rclpy')
    buffer = tf2_ros.Buffer()
    tf2_ros.TransformListener(buffer, node)
    calls = Calls(node, a.timeout)
    poses = []
    if a.pose:
        node.create_subscription(PoseStamped, f'/{a.pose}/pose', poses.append, 10)
    out = lambda v: print(json.dumps(v), flush=True)  # noqa: E731
    code = 0
    try:
        r = calls.call(GetSimulatorFeatures, '/get_simulator_features', GetSimulatorFeatures.Request())
        out({'call': 'get_simulator_features', 'features': list(r.features.features)})
        names = []
        for label, fill in [
                ('', lambda f: None),
                ('uav[12]$', lambda f: setattr(f, 'filter', 'uav[12]$')),
                ('robots', lambda f: f.categories.append(EntityCategory(category=EntityCategory.CATEGORY_ROBOT))),
                ('human', lambda f: f.categories.append(EntityCategory(category=EntityCategory.CATEGORY_HUMAN))),
                ('tag leader', lambda f: f.tags.tags.append('leader'))]:
            req = GetEntities.Request()
            fill(req.filters)
            r = calls.call(GetEntities, '/get_entities', req)
            out({'call': 'get_entities', 'filter': label, 'result': r.result.result, 'entities': list(r.entities)})
            names = names or list(r.entities)
        if not names:
            raise Failed('get_entities listed no entity')
        r = calls.call(GetEntityInfo, '/get_entity_info', GetEntityInfo.Request(entity=names[0]))
        out({'call': 'get_entity_info', 'entity': names[0], 'result': r.result.result,
             'category': r.info.category.category, 'description': r.info.description, 'tags': list(r.info.tags)})
        flying, give_up = 0, time.monotonic() + a.timeout
        while flying < a.states:
            if time.monotonic() > give_up:
                raise Failed(f'only {flying} of {a.states} answers of get_entities_states had every entity written')
            r = calls.call(GetEntitiesStates, '/get_entities_states', GetEntitiesStates.Request())
            states = [state(s) for s in r.states]
            out({'call': 'get_entities_states', 'result': r.result.result, 'entities': list(r.entities),
                 'states': states})
            # Before the first step nothing is written yet: those answers do not count.
            flying += bool(states) and all(s['stamp'] > 0 for s in states)
            end = time.monotonic() + a.every
            while time.monotonic() < end:
                rclpy.spin_once(node, timeout_sec=0.05)
        for name in [names[0], 'no_such_entity']:
            r = calls.call(GetEntityState, '/get_entity_state', GetEntityState.Request(entity=name))
            out({'call': 'get_entity_state', 'entity': name, 'result': r.result.result,
                 'error_message': r.result.error_message, 'state': state(r.state)})
        req = SetEntityState.Request(entity=names[0])
        req.state.pose.orientation.w = 1.0
        r = calls.call(SetEntityState, '/set_entity_state', req)
        out({'call': 'set_entity_state', 'entity': names[0], 'result': r.result.result,
             'error_message': r.result.error_message})
        for name in names:
            try:
                t = buffer.lookup_transform(a.frame, name, rclpy.time.Time())
                tr, q = t.transform.translation, t.transform.rotation
                out({'call': 'tf', 'child': name, 'stamp': seconds(t.header.stamp), 't': [tr.x, tr.y, tr.z],
                     'q': [q.x, q.y, q.z, q.w]})
            except tf2_ros.TransformException as e:
                out({'call': 'tf', 'child': name, 'error': str(e)})
        if a.pose:
            if poses:
                m = poses[-1]
                p, q = m.pose.position, m.pose.orientation
                out({'call': 'pose', 'frame': m.header.frame_id, 'stamp': seconds(m.header.stamp),
                     'p': [p.x, p.y, p.z], 'q': [q.x, q.y, q.z, q.w]})
            else:
                out({'call': 'pose', 'error': 'none heard'})
    except Failed as e:
        print(f'entities_rclpy: {e}', file=sys.stderr, flush=True)
        code = 1
    finally:
        node.destroy_node()
        rclpy_end.shutdown()
    return code


if __name__ == '__main__':
    sys.exit(main())
