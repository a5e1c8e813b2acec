#!/usr/bin/env python3
"""A Zenoh router of eclipse-zenoh's own (the `zenoh` Python package's, as `zenohd` and
rmw_zenoh's `rmw_zenohd` run one): the router of one site in the tests of sites joined by
Zenoh. Each site's gateway connects to its site's router, and the second router connects to the
first, so that the sites meet router to router, as rmw_zenoh graphs on two networks do.

Usage: zenoh_router.py --listen ENDPOINT [--connect ENDPOINT]...
Prints "up" once it listens, and runs until SIGINT or SIGTERM.
"""
import argparse
import json
import signal
import threading

import zenoh


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--listen", required=True)
    ap.add_argument("--connect", action="append", default=[])
    a = ap.parse_args()
    c = zenoh.Config()
    c.insert_json5("mode", '"router"')
    c.insert_json5("listen/endpoints", json.dumps([a.listen]))
    c.insert_json5("connect/endpoints", json.dumps(a.connect))
    c.insert_json5("scouting/multicast/enabled", "false")
    # No shared-memory segments left behind (the gateways have no shared-memory transport).
    c.insert_json5("transport/shared_memory/enabled", "false")
    done = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: done.set())
    session = zenoh.open(c)
    print("up", flush=True)
    while not done.wait(0.2):
        pass
    session.close()


if __name__ == "__main__":
    main()
