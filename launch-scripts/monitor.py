#!/usr/bin/env python3
"""The monitoring script of the UAV demo (`tutti-demo uav`, docs/uav-demo.md).

As in the paper's case study, a Python script sends connection and disconnection requests
to the UAV components at scripted times, and retrieves the number of connections of every
domain from the co-simulation layer (RTGetConnectionCount through python/tutti_rtapi.py)
as the run goes on. It is a component of the demo's launch file (examples/uav/uav-demo.json5)
and acts through the run's control plane (python/tutti_ctl.py, what `tutti ctl` uses): a
disconnection request is `signal uavN USR1`, a connection request `signal uavN USR2` (the UAV
component then disconnects / connects itself), and the C components, declared in the launch
file with `autostart: false`, are started with `start NAME` at their times.

    monitor.py --duration 120 \\
        --events 30:3:disconnect,50:3:connect --starts 60:c_reader1,80:c_reader2 \\
        --domains multiuav_uav1,multiuav_uav2,multiuav_uav3,multiuav_uav4 \\
        --out connections.csv --events-out events.csv

The clock: the run's simulated time, the `sim_time` of its state (that of the last step
made), asked of the control plane every few milliseconds: the script follows the
co-simulation's own clock, also when a loaded machine slows it down. The run is the one of
TUTTI_NAMESPACE, which `tutti run` gives every component.
Output: connections.csv (sim_time,wall_s,uav1..uavN; wall_s from the script's start) and events.csv
(sim_time,uav,connect,scheduled; connect = 1 for a connection request, 0 for a
disconnection). Progress goes to stderr. Stops at --duration, on SIGTERM / SIGINT, or when
the run is gone.
"""

import argparse
import signal
import sys
import time

import tutti_ctl
import tutti_rtapi as rt

ACTIONS = {"disconnect": ("USR1", 0), "connect": ("USR2", 1)}


def parse_events(text):
    """'30:3:disconnect,50:3:connect' -> [(30.0, 3, 'disconnect'), ...], sorted by time."""
    events = []
    for part in filter(None, (p.strip() for p in text.split(","))):
        t, uav, action = part.split(":")
        if action not in ACTIONS:
            raise ValueError(f"unknown action {action!r} in {part!r}")
        events.append((float(t), int(uav), action))
    return sorted(events)


def parse_starts(text):
    """'60:c_reader1,80:c_reader2' -> [(60.0, 'c_reader1'), ...], sorted by time."""
    starts = []
    for part in filter(None, (p.strip() for p in text.split(","))):
        t, name = part.split(":", 1)
        starts.append((float(t), name))
    return sorted(starts)


def connect_run(stop, timeout=30.0):
    """The run's control plane; `tutti run` may serve it a moment after starting us."""
    end = time.time() + timeout
    while True:
        try:
            return tutti_ctl.connect(timeout=30.0)
        except tutti_ctl.NoRun:
            if stop or time.time() > end:
                raise
            time.sleep(0.02)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, required=True, help="simulated seconds to monitor")
    ap.add_argument("--events", default="", help="T:UAV:disconnect|connect, comma-separated")
    ap.add_argument("--starts", default="", help="T:COMPONENT to start, comma-separated")
    ap.add_argument("--uav-component", default="uav{}", help="the name of UAV N's component (default uav{})")
    ap.add_argument("--domains", required=True, help="domains whose connections to count, comma-separated")
    ap.add_argument("--every", type=float, default=0.25, help="simulated seconds between samples")
    ap.add_argument("--out", required=True, help="CSV of the connection counts")
    ap.add_argument("--events-out", required=True, help="CSV of the requests sent")
    args = ap.parse_args()

    rt.error_message(0)  # loads librtapi now, not at the first sample
    events = parse_events(args.events)
    starts = parse_starts(args.starts)
    domains = args.domains.split(",")
    stop = []
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.append(True))
    run = connect_run(stop)

    def sim_now():
        """The simulated time of the last step, None before the first, False once the run is gone."""
        try:
            state = run.state()
        except (tutti_ctl.ControlError, OSError, ValueError):
            return False
        if state["state"] == "stopped":
            return False
        return state["sim_time"] if state["step"] > 0 else None

    with open(args.out, "w") as counts, open(args.events_out, "w") as sent:
        counts.write("sim_time,wall_s," + ",".join(f"uav{i + 1}" for i in range(len(domains))) + "\n")
        sent.write("sim_time,uav,connect,scheduled\n")
        next_sample = 0.0
        start = time.time()
        while not stop:
            now = sim_now()
            if now is False:
                print("monitor: the run is gone: stopping", file=sys.stderr)
                break
            if now is None:  # the first step has not come yet
                time.sleep(0.002)
                continue
            while events and events[0][0] <= now:
                at, uav, action = events.pop(0)
                sig, code = ACTIONS[action]
                name = args.uav_component.format(uav)
                try:
                    run.signal(name, sig)
                except tutti_ctl.ControlError as e:
                    print(f"monitor: t={now:.1f}s cannot reach UAV {uav}: {e}", file=sys.stderr)
                    continue
                sent.write(f"{now:.4f},{uav},{code},{at}\n")
                sent.flush()
                print(f"monitor: t={now:.1f}s {action} request to UAV {uav} (signal {name} {sig})", file=sys.stderr)
            while starts and starts[0][0] <= now:
                at, name = starts.pop(0)
                try:
                    run.start_component(name)  # answered once it has connected
                    print(f"monitor: t={now:.1f}s started {name}", file=sys.stderr)
                except tutti_ctl.ControlError as e:
                    print(f"monitor: t={now:.1f}s cannot start {name}: {e}", file=sys.stderr)
            if now >= next_sample or now >= args.duration:
                try:
                    row = [rt.connection_count(d) for d in domains]
                except rt.RTAPIError as e:
                    print(f"monitor: t={now:.1f}s domains gone ({e.name}): stopping", file=sys.stderr)
                    break
                counts.write(f"{now:.4f},{time.time() - start:.4f}," + ",".join(map(str, row)) + "\n")
                counts.flush()
                next_sample = now + args.every
            if now >= args.duration:
                break
            # Simulated time moves in steps of tens of milliseconds of wall time at most.
            time.sleep(0.002)
    run.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
