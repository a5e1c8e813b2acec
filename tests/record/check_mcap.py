#!/usr/bin/env python3
"""Checks an MCAP recording of `tutti host` against the CSV recording of the same run, with
the MCAP libraries of the ROS ecosystem (`mcap`, `mcap-ros2-support`), not tutti's code.

Usage: check_mcap.py [--subset] RUN.mcap CSV_BASE DOMAIN [DOMAIN...]
       check_mcap.py --demo RUN.mcap FRAMEWORK.csv   (tutti-demo uav's run.mcap)
CSV_BASE is the path given to `--record` for the CSV (STEM-DOMAIN.csv per domain when there
are several). Every schema must parse; every message must decode; each step's message on
/DOMAIN/publish and /DOMAIN/subscribe must equal that step's CSV row, element by element (in
DDF order, buses depth first). With --subset (a recording that started after the run and
stopped before its end: `tutti record`), CSV rows without messages are allowed. With --demo, the UAV demo's recording is compared with its
framework.csv: each step's Elevation and Time read back (SUBSCRIBE) and Altitude published
(the FMU component's domain, recorded too, is not in framework.csv).
Prints one JSON line with the counts; exit 0 when all is equal.
"""
import csv
import json
import math
import os
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def flatten(msg):
    """The values of a decoded message in field order, buses depth first."""
    out = []
    for name in msg.__slots__:
        v = getattr(msg, name)
        if hasattr(v, "__slots__"):
            out.extend(flatten(v))
        elif isinstance(v, (list, tuple)):
            out.extend(v)
        else:
            out.append(v)
    return out


def value(text):
    if text in ("true", "false", "yes", "no"):
        return text in ("true", "yes")
    return float(text)


def same(a, b):
    a, b = float(a), float(b)
    return a == b or math.isclose(a, b, rel_tol=1e-6, abs_tol=1e-9)


def read_decoded(path):
    """(topic, log_time, publish_time, decoded or JSON) of every message; every schema parsed."""
    factory = DecoderFactory()
    out = []
    with open(path, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[factory])
        decoders = {}
        for schema in reader.get_summary().schemas.values():
            if schema.encoding == "ros2msg":
                decoders[schema.id] = factory.decoder_for("cdr", schema)
        for schema, channel, message in reader.iter_messages():
            if channel.message_encoding == "json":
                out.append((channel.topic, message.log_time, message.publish_time, json.loads(message.data)))
            else:
                out.append((channel.topic, message.log_time, message.publish_time, decoders[schema.id](message.data)))
    return decoders, out


def demo(path, framework_csv):
    with open(framework_csv, newline="") as fh:
        rows = {int(r["step"]): r for r in csv.DictReader(fh)}
    decoders, messages = read_decoded(path)
    checked = 0
    for topic, _, _, m in messages:
        if topic == "/tutti/events":
            continue
        _, domain, role = topic.split("/")
        if not domain.startswith("multiuav_"):
            continue  # the FMU component's domain, recorded with the UAVs' but not in framework.csv
        uav = domain.rsplit("_", 1)[1]
        row = rows.get(m.step)
        if row is None:
            print(f"{topic} step {m.step} is not in framework.csv", file=sys.stderr)
            return 1
        pairs = [(m.elevation, f"{uav}_elevation"), (m.time, f"{uav}_time")] if role == "subscribe" else \
            [(m.altitude, f"{uav}_altitude_pub")]
        for got, col in pairs:
            if not same(got, float(row[col])):
                print(f"{topic} step {m.step}: {got} vs framework.csv {col}={row[col]}", file=sys.stderr)
                return 1
        checked += 1
    print(json.dumps({"schemas": len(decoders), "messages": checked, "rows": len(rows)}))
    return 0


def main():
    if sys.argv[1] == "--demo":
        return demo(sys.argv[2], sys.argv[3])
    argv = sys.argv[1:]
    subset = argv[0] == "--subset"
    if subset:
        argv = argv[1:]
    path, base, domains = argv[0], argv[1], argv[2:]
    stem, _ = os.path.splitext(base)
    rows = {}
    for d in domains:
        f = base if len(domains) == 1 else f"{stem}-{d}.csv"
        with open(f, newline="") as fh:
            r = csv.reader(fh)
            header = next(r)
            pub = [i for i, h in enumerate(header) if h.startswith("publish.")]
            sub = [i for i, h in enumerate(header) if h.startswith("subscribe.")]
            for row in r:
                rows[(d, int(row[0]))] = (float(row[1]), [row[i] for i in pub], [row[i] for i in sub])
    factory = DecoderFactory()
    with open(path, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[factory])
        summary = reader.get_summary()
        decoders = {}
        for schema in summary.schemas.values():
            if schema.encoding == "ros2msg":
                decoders[schema.id] = factory.decoder_for("cdr", schema)
                if decoders[schema.id] is None:
                    print(f"schema {schema.name} does not parse", file=sys.stderr)
                    return 1
        checked, events, missing = 0, {}, set(rows)
        for schema, channel, message in reader.iter_messages():
            if channel.topic == "/tutti/events":
                event = json.loads(message.data)
                assert event["kind"] in ("start", "connect", "disconnect", "owner"), event
                key = f'{event["domain"]}/{event["kind"]}'
                events[key] = events.get(key, 0) + 1
                continue
            decoded = decoders[schema.id](message.data)
            _, domain, role = channel.topic.split("/")
            key = (domain, decoded.step)
            if key not in rows:
                print(f"{channel.topic} step {decoded.step} has no CSV row", file=sys.stderr)
                return 1
            sim_time, pub, sub = rows[key]
            if not same(decoded.sim_time, sim_time) or message.publish_time != round(decoded.sim_time * 1e9):
                print(f"{channel.topic} step {decoded.step}: time {decoded.sim_time} vs {sim_time}", file=sys.stderr)
                return 1
            want = pub if role == "publish" else sub
            got = flatten(decoded)[2:]
            if len(got) != len(want) or not all(same(g, value(w)) for g, w in zip(got, want)):
                print(f"{channel.topic} step {decoded.step}: {got} vs CSV {want}", file=sys.stderr)
                return 1
            checked += 1
            if role == "subscribe":
                missing.discard(key)
        if missing and not subset:
            print(f"{len(missing)} CSV rows have no message, e.g. {sorted(missing)[:3]}", file=sys.stderr)
            return 1
    print(json.dumps({"schemas": len(decoders), "messages": checked, "events": events, "rows": len(rows)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
