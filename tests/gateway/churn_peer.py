#!/usr/bin/env python3
"""Churn for the gateway's tests: N DDS participants, each with a writer and a reader,
join and leave together, round after round, paced by the test.

Usage: churn_peer.py --domain N --writer-topic T --writer-type TN --writer-fields F
                     --reader-topic T --reader-type TN --reader-fields F
                     [--participants 20] [--rounds R] [--hold]

Each round creates the participants (a reliable, volatile writer and reader each), prints
{"joined": r}, waits for SIGUSR1, deletes them (a clean leave: DDS says goodbye), prints
{"left": r} and waits for SIGUSR1 again. With --hold: one join, then it waits to be killed
(the peers vanish without goodbye). Types are JSON field lists as in dds_peer.py.

The participants announce a lease of 2 s (Discovery/LeaseDuration), so that a killed one is
dropped by everybody's discovery within a few seconds instead of DDS's default 10 s.
"""
import argparse
import json
import os
import signal
import sys

CONFIG = (
    '<CycloneDDS xmlns="https://cdds.io/config"><Domain id="any"><General><Interfaces>'
    '<NetworkInterface name="lo"/></Interfaces><AllowMulticast>false</AllowMulticast></General>'
    '<Discovery><Peers><Peer address="127.0.0.1"/></Peers><ParticipantIndex>auto</ParticipantIndex>'
    '<MaxAutoParticipantIndex>60</MaxAutoParticipantIndex><LeaseDuration>2 s</LeaseDuration>'
    '</Discovery></Domain></CycloneDDS>'
)
os.environ["CYCLONEDDS_URI"] = CONFIG
# Blocked before Cyclone starts a thread, so that every thread inherits the mask and the
# signal stays pending for sigwait (no race between the test's signal and our wait).
signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGUSR1})

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from dds_peer import make_type  # noqa: E402
from cyclonedds.domain import DomainParticipant  # noqa: E402
from cyclonedds.pub import DataWriter  # noqa: E402
from cyclonedds.qos import Policy, Qos  # noqa: E402
from cyclonedds.sub import DataReader  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402
from cyclonedds.util import duration  # noqa: E402


def emit(obj):
    print(json.dumps(obj), flush=True)


def join(a, wcls, rcls):
    qos = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(1),
              Policy.Durability.Volatile)
    peers = []
    for _ in range(a.participants):
        dp = DomainParticipant(a.domain)
        w = DataWriter(dp, Topic(dp, a.writer_topic, wcls), qos=qos)
        r = DataReader(dp, Topic(dp, a.reader_topic, rcls), qos=qos)
        peers.append((dp, w, r))
    return peers


def leave(peers):
    # Deleting a participant deletes its endpoints (and says goodbye on the wire).
    for dp, _, _ in peers:
        dp.__del__()
    peers.clear()


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--domain", type=int, required=True)
    for end in ("writer", "reader"):
        for what in ("topic", "type", "fields"):
            p.add_argument(f"--{end}-{what}", required=True)
    p.add_argument("--participants", type=int, default=20)
    p.add_argument("--rounds", type=int, default=1)
    p.add_argument("--hold", action="store_true")
    a = p.parse_args()
    wcls = make_type(a.writer_type, json.loads(a.writer_fields))
    rcls = make_type(a.reader_type, json.loads(a.reader_fields))
    for r in range(1, a.rounds + 1):
        peers = join(a, wcls, rcls)
        emit({"joined": r})
        if a.hold:
            while True:
                signal.sigwait({signal.SIGUSR1})
        signal.sigwait({signal.SIGUSR1})
        leave(peers)
        emit({"left": r})
        signal.sigwait({signal.SIGUSR1})
    return 0


if __name__ == "__main__":
    sys.exit(main())
