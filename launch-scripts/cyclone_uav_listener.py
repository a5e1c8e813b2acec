#!/usr/bin/env python3
"""Print the UAV states of ddf/multiuav.ddf as the tutti gateway publishes them, with the
Cyclone DDS Python binding (pip install cyclonedds==11.0.1): no ROS 2 installation needed.

Each UAV's SUBSCRIBE set (what the UAV model writes: its state) is the DDS topic
rt/multiuav_uavN/subscribe, type multiuav_msgs::msg::dds_::MultiuavUavNSubscribe_ (the
struct `tutti idl ddf/multiuav.ddf` writes); with --publish it also reads each PUBLISH set
(what the framework sends the UAV: autopilot, formation offset, commands), rt/multiuav_uavN/
publish. Reading changes nothing in the co-simulation: a DDS reader is no participant.
Usage:

    tutti host ddf/multiuav.ddf &  tutti gateway ddf/multiuav.ddf --interface 127.0.0.1 &
    python3 launch-scripts/cyclone_uav_listener.py [--domain N] [--uavs 1,2] [--count K] [--publish]

The DDS domain is --domain, else ROS_DOMAIN_ID, else 0. Unless CYCLONEDDS_URI is set, DDS
runs on loopback only (127.0.0.1, no multicast); use --any-interface for a real network.
Prints one JSON line per sample; exits after --count samples (default: run until Ctrl-C).
"""
import argparse
import json
import os
import sys
import time
import types
from dataclasses import dataclass

LOOPBACK = (
    '<CycloneDDS xmlns="https://cdds.io/config"><Domain id="any"><General><Interfaces>'
    '<NetworkInterface name="lo"/></Interfaces><AllowMulticast>false</AllowMulticast></General>'
    '<Discovery><Peers><Peer address="127.0.0.1"/></Peers><ParticipantIndex>auto</ParticipantIndex>'
    '<MaxAutoParticipantIndex>20</MaxAutoParticipantIndex></Discovery></Domain></CycloneDDS>'
)

FIELDS = ["latitude", "longitude", "elevation", "airspeed", "heading", "time"]
PUBLISH_FIELDS = ["autopilot", "x", "y", "z", "airspeed", "altitude", "time"]


def set_type(n, role, fields):
    """multiuav_msgs/msg/MultiuavUavN<Role> as an IdlStruct with its ROS 2 DDS type name."""
    from cyclonedds.idl import IdlStruct
    from cyclonedds.idl.types import float64, uint64

    def body(ns):
        ns["__annotations__"] = dict([("step", uint64), ("sim_time", float64)] + [(f, float64) for f in fields])
    name = f"MultiuavUav{n}{role}"
    cls = types.new_class(name, (IdlStruct,), {"typename": f"multiuav_msgs::msg::dds_::{name}_"}, body)
    return dataclass(cls)


def state_type(n):
    return set_type(n, "Subscribe", FIELDS)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--domain", type=int, default=int(os.environ.get("ROS_DOMAIN_ID", "0") or 0))
    p.add_argument("--uavs", nargs="+", default=["1,2,3,4"], help="UAV numbers: 1,2,3,4 or 1 2 3 4")
    p.add_argument("--count", type=int, default=0, help="stop after this many samples (0: never)")
    p.add_argument("--timeout", type=float, default=0, help="give up after this many seconds (0: never)")
    p.add_argument("--any-interface", action="store_true", help="do not restrict DDS to loopback")
    p.add_argument("--publish", action="store_true", help="also read each UAV's PUBLISH set")
    a = p.parse_args()
    if not a.any_interface:
        os.environ.setdefault("CYCLONEDDS_URI", LOOPBACK)

    from cyclonedds.domain import DomainParticipant
    from cyclonedds.qos import Policy, Qos
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from cyclonedds.util import duration

    dp = DomainParticipant(a.domain)
    # Reliable reader: matches the gateway's RELIABLE (KEEP_ALL in these synchronous domains) writers.
    qos = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(10),
              Policy.Durability.Volatile)
    readers = {}
    for n in (int(x) for x in ",".join(a.uavs).split(",") if x.strip()):
        readers[(n, "subscribe")] = DataReader(dp, Topic(dp, f"rt/multiuav_uav{n}/subscribe", state_type(n)), qos=qos)
        if a.publish:
            t = Topic(dp, f"rt/multiuav_uav{n}/publish", set_type(n, "Publish", PUBLISH_FIELDS))
            readers[(n, "publish")] = DataReader(dp, t, qos=qos)
    got, end = 0, (time.time() + a.timeout if a.timeout else None)
    try:
        while (not a.count or got < a.count) and (end is None or time.time() < end):
            for (n, role), rd in readers.items():
                for s in rd.take(N=64):
                    if not s.sample_info.valid_data:
                        continue
                    fields = FIELDS if role == "subscribe" else PUBLISH_FIELDS
                    extra = {} if role == "subscribe" else {"set": "publish"}
                    print(json.dumps({"uav": n, **extra, "step": s.step, "sim_time": s.sim_time,
                                      **{f: getattr(s, f) for f in fields}}), flush=True)
                    got += 1
            time.sleep(0.005)
    except KeyboardInterrupt:
        pass
    return 0 if (not a.count or got >= a.count) else 3


if __name__ == "__main__":
    sys.exit(main())
