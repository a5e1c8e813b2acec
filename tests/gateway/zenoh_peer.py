#!/usr/bin/env python3
"""A ROS 2 node in rmw_zenoh's wire format, written with Zenoh's own Python binding
(eclipse-zenoh): the stand-in for an rclpy node on rmw_zenoh_cpp in the gateway's Zenoh tests.

Usage: zenoh_peer.py MODE --router tcp/127.0.0.1:PORT --domain N [options]. Every mode prints JSON
lines on stdout and exits 0 on success, 3 on timeout. Each rule cites rmw_zenoh_cpp 0.2.10:

* liveliness tokens `@ros2_lv/<domain>/<zid>/<node id>/<entity id>/<kind>/<enclave>/<namespace>/
  <node name>[/<topic>/<type>/<type hash>/<qos>]`, names with `/` as `%`
  (src/detail/liveliness_utils.cpp:435-619, 697-708);
* data keys `<domain>/<name without its leading />/<type>/<type hash>`
  (src/detail/liveliness_utils.cpp:87-93);
* the attachment: z_serialize of (int64 sequence number, int64 source timestamp, 16 bytes GID)
  (src/detail/attachment_helpers.cpp);
* the payload: the CDR encapsulation header, then the body (src/detail/type_support.cpp:97-98);
* a service call: a query on the service's key whose payload is the request and whose attachment
  names the client; the reply carries the request's sequence number and the client's GID
  (src/detail/rmw_client_data.cpp:380-400, src/detail/rmw_service_data.cpp:440-454).

  sub  --topic T [--count N] [--timeout S]: waits for the gateway's publisher token on ROS 2 topic T,
       declares a subscription token for it (rmw_zenoh's default QoS), subscribes to its data key;
       prints {"token": KEY} for the publisher's token, then one line per sample:
       {"seq", "ts", "gid", "header", "step", "body"} (body in hex, after the header)
  pub  --topic T --body HEX [--count N] [--bad] [--timeout S]: waits for the gateway's subscription
       token on T, declares a publisher token, then writes the sample (header + body) N times, 50 ms
       apart, with rmw_zenoh's attachment (with --bad, each time after one without it: bad input);
       prints {"token": KEY, "written": N}
  call --service S --request HEX [--timeout S]: waits for the service's token (SS) on S, declares a
       client token, sends the request as a query; prints {"token": KEY, "seq", "gid", "reply": HEX
       (after the header), "header", "reply_seq", "reply_gid"}
  late --topic T [--count N] [--timeout S]: a late-joining TRANSIENT_LOCAL subscription, as
       rmw_zenoh makes one (src/detail/rmw_subscription_data.cpp:192-207): its token with
       TRANSIENT_LOCAL, keep last 1, and an advanced subscriber that queries late publishers'
       caches; prints {"declared_at": ns} just before it subscribes, then the samples it got (as
       sub) once N came or the timeout passed
  graph [--timeout S] [--count N]: every token of the domain once N are known and none came for a
       second: one {"token": KEY} line each
"""
import argparse
import json
import sys
import time

import zenoh
import zenoh.ext
from zenoh.ext import Int64, z_deserialize, z_serialize

HEADER_LE = bytes([0, 1, 0, 0])
DEFAULT_QOS = "::,10:,:,:,,"  # reliable, volatile, keep last 10 (ROS 2's default, as rmw_zenoh writes it)
LATCHED_QOS = ":1:,1:,:,:,,"  # reliable, TRANSIENT_LOCAL, keep last 1


def mangle(name):
    return name.replace("/", "%")


def open_session(router):
    c = zenoh.Config()
    c.insert_json5("mode", '"peer"')
    c.insert_json5("connect/endpoints", json.dumps([router]))
    c.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
    c.insert_json5("scouting/multicast/enabled", "false")
    # No shared-memory transport: the gateway has none, and a session with it makes segments in
    # /dev/shm (*.zenoh) that a test must not leave behind.
    c.insert_json5("transport/shared_memory/enabled", "false")
    return zenoh.open(c)


def tokens(s, domain):
    out = []
    for r in s.liveliness().get(f"@ros2_lv/{domain}/**"):
        if r.ok is not None:
            out.append(str(r.ok.key_expr))
    return out


def wait_token(s, domain, kind, name, deadline):
    """The first token of `kind` (MP, MS, SS) on ROS 2 name `name` of another session."""
    while time.time() < deadline:
        for k in tokens(s, domain):
            f = k.split("/")
            if len(f) >= 13 and f[5] == kind and f[9] == mangle(name) and f[2] != str(s.zid()):
                return k, f
        time.sleep(0.2)
    return None, None


def need_token(s, a, kind, name, what, deadline):
    """`wait_token`, printing {"error": "no WHAT token"} when none came."""
    key, f = wait_token(s, a.domain, kind, name, deadline)
    if key is None:
        print(json.dumps({"error": f"no {what} token", "name": name}), flush=True)
    return key, f


def own_token(s, domain, entity_id, kind, f, qos=DEFAULT_QOS):
    """A token of this node for the same topic, type and hash as the token fields `f`."""
    key = "/".join(["@ros2_lv", str(domain), str(s.zid()), "0", str(entity_id), kind, "%", "%", "zenoh_peer",
                    f[9], f[10], f[11], qos])
    return key, s.liveliness().declare_token(key)


def data_key(domain, f):
    return "/".join([str(domain), f[9].replace("%", "/").strip("/"), f[10], f[11]])


def attachment(seq, gid):
    return z_serialize((Int64(seq), Int64(time.time_ns()), gid))


def read_attachment(a):
    seq, ts, gid = z_deserialize(tuple[Int64, Int64, bytes], a)
    return int(seq), int(ts), gid.hex()


GID = bytes(range(16))  # the GID this node's client and publisher use (rmw_zenoh hashes its token key)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("mode", choices=["sub", "pub", "call", "graph", "late"])
    p.add_argument("--router", required=True)
    p.add_argument("--domain", type=int, required=True)
    p.add_argument("--topic")
    p.add_argument("--service")
    p.add_argument("--body", default="")
    p.add_argument("--request", default="")
    p.add_argument("--count", type=int, default=1)
    p.add_argument("--bad", action="store_true")
    p.add_argument("--timeout", type=float, default=60.0)
    a = p.parse_args()
    deadline = time.time() + a.timeout
    s = open_session(a.router)
    try:
        return serve(a, s, deadline)
    finally:
        s.close()


def serve(a, s, deadline):
    if a.mode == "graph":
        seen, quiet_since = set(), time.time()
        while time.time() < deadline:
            now = set(tokens(s, a.domain))
            if now - seen:
                seen |= now
                quiet_since = time.time()
            if len(seen) >= a.count and time.time() - quiet_since > 1.0:
                for k in sorted(seen):
                    print(json.dumps({"token": k}), flush=True)
                return 0
            time.sleep(0.2)
        print(json.dumps({"error": "timeout", "tokens": sorted(seen)}), flush=True)
        return 3

    if a.mode in ("sub", "late"):
        key, f = need_token(s, a, "MP", a.topic, "publisher", deadline)
        if key is None:
            return 3
        print(json.dumps({"token": key}), flush=True)
        got = []

        def on_sample(sample):
            raw = sample.payload.to_bytes()
            att = sample.attachment
            seq, ts, gid = read_attachment(att) if att is not None else (None, None, None)
            body = raw[4:]
            step = int.from_bytes(body[:8], "little") if len(body) >= 8 else None
            got.append({"seq": seq, "ts": ts, "gid": gid, "header": raw[:4].hex(), "step": step, "body": body.hex()})

        if a.mode == "sub":
            _tok = own_token(s, a.domain, 1, "MS", f)
            _sub = s.declare_subscriber(data_key(a.domain, f), on_sample)
        else:
            _tok = own_token(s, a.domain, 1, "MS", f, qos=LATCHED_QOS)
            # A sample written before this moment can only come from the publisher's cache.
            print(json.dumps({"declared_at": time.time_ns()}), flush=True)
            history = zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=1)
            _sub = zenoh.ext.declare_advanced_subscriber(s, data_key(a.domain, f), on_sample, history=history,
                                                         subscriber_detection=True)
        while time.time() < deadline and len(got) < a.count:
            time.sleep(0.05)
        for g in list(got)[:a.count]:
            print(json.dumps(g), flush=True)
        return 0 if len(got) >= a.count else 3

    if a.mode == "pub":
        key, f = need_token(s, a, "MS", a.topic, "subscription", deadline)
        if key is None:
            return 3
        _tok = own_token(s, a.domain, 2, "MP", f)
        pub = s.declare_publisher(data_key(a.domain, f))
        time.sleep(0.5)  # the gateway's subscriber learns of the token, then of the samples
        for seq in range(1, a.count + 1):
            if a.bad:
                pub.put(HEADER_LE + bytes.fromhex(a.body))
            pub.put(HEADER_LE + bytes.fromhex(a.body), attachment=attachment(seq, GID))
            time.sleep(0.05)
        print(json.dumps({"token": key, "written": a.count}), flush=True)
        return 0

    if a.mode == "call":
        key, f = need_token(s, a, "SS", a.service, "service", deadline)
        if key is None:
            return 3
        _tok = own_token(s, a.domain, 3, "SC", f)
        time.sleep(0.3)  # the server learns of the client (its node) before the call
        seq = 1
        while time.time() < deadline:
            replies = s.get(data_key(a.domain, f), payload=HEADER_LE + bytes.fromhex(a.request),
                            attachment=attachment(seq, GID), timeout=5.0)
            for r in replies:
                if r.ok is None:
                    continue
                raw = r.ok.payload.to_bytes()
                rseq, _, rgid = read_attachment(r.ok.attachment)
                print(json.dumps({"token": key, "seq": seq, "gid": GID.hex(), "header": raw[:4].hex(),
                                  "reply": raw[4:].hex(), "reply_seq": rseq, "reply_gid": rgid}), flush=True)
                return 0
            seq += 1
        print(json.dumps({"error": "no reply", "service": a.service}), flush=True)
        return 3
    return 2


if __name__ == "__main__":
    sys.exit(main())
