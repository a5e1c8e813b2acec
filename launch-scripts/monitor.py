#!/usr/bin/env python3
"""The monitoring script of the UAV demo (`tutti-demo uav`, docs/uav-demo.md).

As in the paper's case study, a Python script sends connection and disconnection requests
to the UAV components at scripted times, and retrieves the number of connections of every
domain from the co-simulation layer (RTGetConnectionCount through python/tutti_rtapi.py)
as the run goes on. A disconnection request is SIGUSR1 to the UAV component, a connection
request SIGUSR2; the component then calls disconnect / connect itself.

    monitor.py --clock stdin --duration 120 \\
        --events 30:3:disconnect,50:3:connect --pids 1:1234,2:1235,3:1236,4:1237 \\
        --domains multiuav_uav1,multiuav_uav2,multiuav_uav3,multiuav_uav4 \\
        --out connections.csv --events-out events.csv

The clock: with --clock stdin (as `tutti-demo uav` runs it) the script loads, prints "ready"
on stdout, then reads the framework's simulated time, one number per line, from its standard
input: the script follows the co-simulation's own clock, also when a loaded machine slows it
down. With --clock wall --t0 UNIX_TIME --speed X, simulated time is (now - t0) * X.
Output: connections.csv (sim_time,wall_s,uav1..uavN; wall_s from the script's start) and events.csv
(sim_time,uav,connect,scheduled; connect = 1 for a connection request, 0 for a
disconnection). Progress goes to stderr. Stops at --duration, on SIGTERM / SIGINT, or when
the domains are gone (the framework stopped).
"""

import argparse
import os
import signal
import sys
import threading
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
    ap.add_argument("--clock", choices=["stdin", "wall"], default="stdin", help="where simulated time comes from")
    ap.add_argument("--t0", type=float, default=None, help="--clock wall: Unix time of simulated time 0")
    ap.add_argument("--speed", type=float, default=1.0, help="--clock wall: simulated seconds per wall second")
    ap.add_argument("--duration", type=float, required=True, help="simulated seconds to monitor")
    ap.add_argument("--events", default="", help="T:UAV:disconnect|connect, comma-separated")
    ap.add_argument("--pids", default="", help="UAV:PID of each UAV component, comma-separated")
    ap.add_argument("--domains", required=True, help="domains whose connections to count, comma-separated")
    ap.add_argument("--every", type=float, default=0.25, help="simulated seconds between samples")
    ap.add_argument("--out", required=True, help="CSV of the connection counts")
    ap.add_argument("--events-out", required=True, help="CSV of the requests sent")
    args = ap.parse_args()

    rt.error_message(0)  # loads librtapi now, not at the first sample
    events = parse_events(args.events)
    pids = parse_pids(args.pids)
    domains = args.domains.split(",")
    stop = []
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.append(True))

    clock = {"sim": None, "ended": False}
    if args.clock == "stdin":
        print("ready", flush=True)

        def follow():
            for line in sys.stdin:
                try:
                    clock["sim"] = float(line)
                except ValueError:
                    pass
            clock["ended"] = True  # the framework stopped stepping

        threading.Thread(target=follow, daemon=True).start()
    else:
        if args.t0 is None:
            ap.error("--clock wall needs --t0")
        clock["sim"] = 0.0

    def sim_now():
        if args.clock == "wall":
            return (time.time() - args.t0) * args.speed
        return clock["sim"]

    with open(args.out, "w") as counts, open(args.events_out, "w") as sent:
        counts.write("sim_time,wall_s," + ",".join(f"uav{i + 1}" for i in range(len(domains))) + "\n")
        sent.write("sim_time,uav,connect,scheduled\n")
        next_sample = 0.0
        start = time.time()
        while not stop and not clock["ended"]:
            now = sim_now()
            if now is None:  # the first step has not come yet
                time.sleep(0.002)
                continue
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
                counts.write(f"{now:.4f},{time.time() - start:.4f}," + ",".join(map(str, row)) + "\n")
                counts.flush()
                next_sample = now + args.every
            # Simulated time moves in steps of tens of milliseconds of wall time at most.
            time.sleep(0.002)
    return 0


if __name__ == "__main__":
    sys.exit(main())
