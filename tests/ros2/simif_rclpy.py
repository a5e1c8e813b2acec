"""rclpy's own clients of the gateway's simulation services and action (docs/ros2.md).

Usage: simif_rclpy.py CALLS [--namespace NS] [--timeout S]

CALLS is JSON, a list of calls made in order:
  ["get_simulator_features"], ["get_simulation_state"], ["set_simulation_state", STATE],
  ["step_simulation", STEPS], ["reset_simulation", SCOPE],
  ["simulate_steps", STEPS, CANCEL_AFTER]  (the action; CANCEL_AFTER feedbacks, 0: never cancel),
  ["clock", SECONDS]  (waits, at most 20 s, for /clock to say SECONDS; its subscription is made
  before the first call, so a time published while the run is paused reaches it)
Prints one JSON line per call: {"call": NAME, "result": CODE, "error_message": TEXT, ...} with
"state" (get_simulation_state), "features" (get_simulator_features), and for the action
"accepted", "feedback" ([[completed, remaining], ...]) and "status" (the goal's final status);
for "clock", "time" (the last time /clock said, or null) and "heard" (every time it said since
the last "clock" call).
Exits 1 when a service or the action server does not show up or a call gets no answer.

Runs with the ROS 2 workspace's environment (install/setup.bash) and RMW_IMPLEMENTATION.
"""
import argparse
import json
import sys

import time

import rclpy
import rclpy_end
from rclpy.action import ActionClient
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.srv import (GetSimulationState, GetSimulatorFeatures, ResetSimulation,
                                       SetSimulationState, StepSimulation)

SERVICES = {
    'get_simulator_features': GetSimulatorFeatures,
    'get_simulation_state': GetSimulationState,
    'set_simulation_state': SetSimulationState,
    'step_simulation': StepSimulation,
    'reset_simulation': ResetSimulation,
}


class Failed(Exception):
    pass


def spin_until(node, future, timeout, what):
    rclpy.spin_until_future_complete(node, future, timeout_sec=timeout)
    if not future.done():
        raise Failed(f'{what}: no answer within {timeout} s')
    return future.result()


def call_service(node, ns, name, args, timeout):
    srv = SERVICES[name]
    client = node.create_client(srv, f'{ns}/{name}')
    if not client.wait_for_service(timeout_sec=timeout):
        raise Failed(f'service {ns}/{name} not found')
    req = srv.Request()
    if name == 'set_simulation_state':
        req.state.state = args[0]
    elif name == 'step_simulation':
        req.steps = args[0]
    elif name == 'reset_simulation':
        req.scope = args[0]
    resp = spin_until(node, client.call_async(req), timeout, name)
    out = {'call': name}
    if name == 'get_simulator_features':
        out['features'] = list(resp.features.features)
        out['custom_info'] = resp.features.custom_info
        return out
    out['result'] = resp.result.result
    out['error_message'] = resp.result.error_message
    if name == 'get_simulation_state':
        out['state'] = resp.state.state
    return out


def simulate_steps(node, ns, steps, cancel_after, timeout):
    client = ActionClient(node, SimulateSteps, f'{ns}/simulate_steps')
    if not client.wait_for_server(timeout_sec=timeout):
        raise Failed(f'action {ns}/simulate_steps not found')
    feedback = []
    out = {'call': 'simulate_steps', 'feedback': feedback}
    goal = SimulateSteps.Goal()
    goal.steps = steps
    sent = client.send_goal_async(goal, feedback_callback=lambda m: feedback.append(
        [m.feedback.completed_steps, m.feedback.remaining_steps]))
    handle = spin_until(node, sent, timeout, 'send_goal')
    out['accepted'] = handle.accepted
    if not handle.accepted:
        return out
    result = handle.get_result_async()
    if cancel_after:
        while len(feedback) < cancel_after and not result.done():
            rclpy.spin_once(node, timeout_sec=0.1)
        if not result.done():
            cancel = spin_until(node, handle.cancel_goal_async(), timeout, 'cancel_goal')
            out['cancel_return_code'] = cancel.return_code
    res = spin_until(node, result, timeout, 'get_result')
    # Feedback that raced the result in: let it arrive.
    for _ in range(5):
        rclpy.spin_once(node, timeout_sec=0.05)
    out['status'] = res.status
    out['result'] = res.result.result.result
    out['error_message'] = res.result.result.error_message
    return out


class ClockWatch:
    """/clock as a use_sim_time node hears it (reliable, keep last 10)."""

    def __init__(self, node):
        self.last = None
        self.since = []
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        node.create_subscription(Clock, '/clock', self.heard, qos)

    def heard(self, m):
        self.last = m.clock.sec + m.clock.nanosec * 1e-9
        self.since.append(self.last)

    def wait_for(self, node, seconds):
        """Until /clock says SECONDS and nothing more comes for 0.5 s (the samples of earlier
        steps drained); "heard" is every time heard since the last such call."""
        end = time.monotonic() + 20.0
        quiet_since = time.monotonic()
        while time.monotonic() < end:
            n = len(self.since)
            rclpy.spin_once(node, timeout_sec=0.05)
            if len(self.since) != n:
                quiet_since = time.monotonic()
            elif (self.last is not None and abs(self.last - seconds) <= 1e-9
                  and time.monotonic() - quiet_since >= 0.5):
                break
        out = {'call': 'clock', 'time': self.last, 'heard': self.since}
        self.since = []
        return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('calls')
    ap.add_argument('--namespace', default='')
    ap.add_argument('--timeout', type=float, default=60.0)
    a = ap.parse_args()
    rclpy.init()
    node = Node('tutti_simif_rclpy')
    code = 0
    calls = json.loads(a.calls)
    clock = ClockWatch(node) if any(c[0] == 'clock' for c in calls) else None
    try:
        for c in calls:
            name, args = c[0], c[1:]
            if name == 'clock':
                out = clock.wait_for(node, args[0])
            elif name == 'simulate_steps':
                out = simulate_steps(node, a.namespace, args[0], args[1] if len(args) > 1 else 0, a.timeout)
            else:
                out = call_service(node, a.namespace, name, args, a.timeout)
            print(json.dumps(out), flush=True)
    except Failed as e:
        print(f'simif_rclpy: {e}', file=sys.stderr, flush=True)
        code = 1
    finally:
        node.destroy_node()
        rclpy_end.shutdown()
    return code


if __name__ == '__main__':
    sys.exit(main())
