#!/usr/bin/env python3
"""The monitoring script of the UAV demo (`tutti demo uav`, docs/uav-demo.md).

As in the paper's case study, a Python script sends connection and disconnection requests
to the UAV components at scripted times, and retrieves the number of connections of every
domain from the co-simulation layer (RTGetConnectionCount through python/tutti_rtapi.py)
as the run goes on. A disconnection request is SIGUSR1 to the UAV component, a connection
request SIGUSR2; the component then calls disconnect / connect itself.

    monitor.py --t0 UNIX_TIME|stdin --speed 4 --duration 120 \\
        --events 30:3:disconnect,50:3:connect --pids 1:1234,2:1235,3:1236,4:1237 \\
        --domains multiuav_uav1,multiuav_uav2,multiuav_uav3,multiuav_uav4 \\
        --out connections.csv --events-out events.csv

Simulated time is (now - t0) * speed: the framework steps on absolute deadlines from t0.
With --t0 stdin the script loads, prints "ready" on stdout and then reads t0 from its
standard input, so that the framework can start its clock once the script is ready.
Output: connections.csv (sim_time,wall_s,uav1..uavN) and events.csv
(sim_time,uav,connect,scheduled; connect = 1 for a connection request, 0 for a
disconnection). Progress goes to stderr. Stops at --duration, on SIGTERM / SIGINT, or when
the domains are gone (the framework stopped).
"""

import argparse
import os
import signal
import sys
import time

import tutti_rtapi as rt

ACTIONS = {"disconnect": (signal.SIGUSR1, 0), "connect": (signal.SIGUSR2, 1)}


def parse_events(text):
    """'30:3:disconnect,50:3:connect' -> [(30.0, 3, 'disconnect'), ...], sorted by time."""
    events = []
    for part in filter(None, (p.strip() for p in text.split(","))):
        t, uav, action = part.split(":")
        if action not in ACTIONS:
            raise ValueError(f"unknown action {action!r} in {part!r}")
        events.append((float(t), int(uav), action))
    return sorted(events)


def parse_pids(text):
    """'1:1234,2:1235' -> {1: 1234, 2: 1235}."""
    return {int(k): int(v) for k, v in (p.split(":") for p in text.split(",") if p)}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--t0", required=True, help="wall-clock (Unix) time of simulated time 0, or 'stdin'")
    ap.add_argument("--speed", type=float, default=1.0, help="simulated seconds per wall second")
    ap.add_argument("--duration", type=float, required=True, help="simulated seconds to monitor")
    ap.add_argument("--events", default="", help="T:UAV:disconnect|connect, comma-separated")
    ap.add_argument("--pids", default="", help="UAV:PID of each UAV component, comma-separated")
    ap.add_argument("--domains", required=True, help="domains whose connections to count, comma-separated")
    ap.add_argument("--every", type=float, default=0.25, help="simulated seconds between samples")
    ap.add_argument("--out", required=True, help="CSV of the connection counts")
    ap.add_argument("--events-out", required=True, help="CSV of the requests sent")
    args = ap.parse_args()

    rt.error_message(0)  # loads librtapi now, not at the first sample
    if args.t0 == "stdin":
        print("ready", flush=True)
        line = sys.stdin.readline()
        if not line.strip():
            return 0  # the framework did not start
        args.t0 = float(line)
    else:
        args.t0 = float(args.t0)
    events = parse_events(args.events)
    pids = parse_pids(args.pids)
    domains = args.domains.split(",")
    stop = []
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.append(True))

    def sim_now():
        return (time.time() - args.t0) * args.speed

    with open(args.out, "w") as counts, open(args.events_out, "w") as sent:
        counts.write("sim_time,wall_s," + ",".join(f"uav{i + 1}" for i in range(len(domains))) + "\n")
        sent.write("sim_time,uav,connect,scheduled\n")
        next_sample = 0.0
        while not stop:
            now = sim_now()
            if now > args.duration:
                break
            while events and events[0][0] <= now:
                at, uav, action = events.pop(0)
                sig, code = ACTIONS[action]
                try:
                    os.kill(pids[uav], sig)
                except (KeyError, ProcessLookupError) as e:
                    print(f"monitor: t={now:.1f}s cannot reach UAV {uav}: {e!r}", file=sys.stderr)
                    continue
                sent.write(f"{now:.4f},{uav},{code},{at}\n")
                sent.flush()
                print(f"monitor: t={now:.1f}s {action} request to UAV {uav}", file=sys.stderr)
            if now >= next_sample:
                try:
                    row = [rt.connection_count(d) for d in domains]
                except rt.RTAPIError as e:
                    print(f"monitor: t={now:.1f}s domains gone ({e.name}): stopping", file=sys.stderr)
                    break
                counts.write(f"{now:.4f},{time.time() - args.t0:.4f}," + ",".join(map(str, row)) + "\n")
                counts.flush()
                next_sample = now + args.every
            # Wake for whatever comes first: the next sample or the next event.
            due = min([next_sample] + [e[0] for e in events[:1]])
            time.sleep(max(0.0, min((due - sim_now()) / args.speed, 0.05)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
