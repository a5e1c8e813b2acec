#!/usr/bin/env python3
"""A Cyclone DDS peer for the gateway's tests: the stand-in for an rclpy node.

Usage: dds_peer.py MODE --domain N [options]; types are given as JSON field lists,
e.g. '[["step","uint64"],["sim_time","float64"],["x","float64"],["v","float64[3]"]]'.
Every mode prints JSON lines on stdout and exits 0 on success, 3 on timeout.
Every mode takes --announce-every S: announce the participant (SPDP) every S seconds, for a network
that loses datagrams (see ANNOUNCE below).

  sub    --topic T --type TN --fields F [--count N] [--timeout S] [--best-effort] [--exclusive]
         [--transient-local]: a late joiner that asks for what writers kept
  pub    --topic T --type TN --fields F --values '[{...}, ...]' [--period-ms P] [--exclusive [--strength S]]
         [--linger S] [--transient-local]: waits for a matched reader, writes each sample (transient
         local: a latched writer, keeping its last sample for late joiners)
  answer --topic T --type TN --fields F --reply-topic T2 --reply-type TN2 --reply-fields F2
         --count N [--reply-depth D] [--read-depth D] [--on-change]: for each sample read on T (a step k) writes one sample on T2
         with step k and every other field of F2 = the first data field of the sample + 1; the
         writer keeps all its samples until acknowledged, or with D the last D (as rclpy's
         default KEEP_LAST 10); with --on-change, only for a sample whose first data field differs
         from the sample before's (the first sample counts as a change): a node that reacts to changes
  steps  --topic T --type TN --fields F [--timeout S] [--max-samples N --pause-ms P]: every step of a
         synchronous PUBLISH set, read with the domain's QoS (reliable, keep-all; a slow reader with
         --max-samples, which holds at most N samples and takes them every P ms, so that its writer
         must wait for it): prints {"first": k} at the first sample,
         and a summary (steps missing, repeated or out of order, data not the step's own) once
         the sample whose first data field is negative (the framework's last step) arrives
  qos    --topic T [--timeout S] [--readers]: the QoS of the first remote writer on T (DCPSPublication;
         with --readers, of the first remote reader: DCPSSubscription)
  endpoints --count N [--timeout S]: every remote writer and reader (DCPSPublication,
         DCPSSubscription) with its topic, type and USER_DATA (as text), one line each, once N
         are known and no more came for a second
  nodes  --name NAME [--timeout S]: waits until ros_discovery_info lists node NAME
  lease  --name NAME --node-namespace NS [--timeout S]: the lease (in s) that the participant
         of node NS/NAME (on ros_discovery_info) announces (DCPSParticipant)
  clock  [--timeout S]: prints every rosgraph_msgs/msg/Clock sample on rt/clock (as rclcpp's
         ClockQoS subscription reads it: best effort, keep last 1) until the timeout
  service --calls '[["get_simulation_state"], ["step_simulation", 3], ...]' [--ros-namespace NS]:
         a simulation_interfaces client in rmw_cyclonedds's layout (rq/NS/NAMERequest and
         rr/NS/NAMEReply, each body starting with the 16-byte request header, rmw's services QoS);
         each request is checked byte for byte against the layout packed by hand before it is
         sent; waits, as rmw_service_server_is_available, for the service's reader and writer,
         then makes the calls in order, printing {"call": NAME, ...the response's fields}
  action --steps N [--cancel-after K] [--ros-namespace NS]: a client of the action simulate_steps in the
         same layout, as rclpy's ActionClient: send_goal, then get_result; prints {"accepted": ...},
         {"feedback": [completed, remaining]} for each feedback sample, with --cancel-after K a cancel_goal
         after the K-th feedback ({"cancel": return_code, "canceling": n}), then {"status": S, "result": ...}
         and the goal's last status seen on the status topic ({"last_status": S})
"""
import argparse
import json
import os
import sys
import time
import types
from dataclasses import dataclass



def announce_every(argv):
    """The value of `--announce-every S` in `argv` (read before Cyclone is loaded), or None."""
    for i, a in enumerate(argv):
        if a == "--announce-every" and i + 1 < len(argv):
            return float(argv[i + 1])
        if a.startswith("--announce-every="):
            return float(a.split("=", 1)[1])
    return None


# Under Cyclone's defaults a participant that finds the others by unicast (Discovery/Peers)
# announces itself (SPDP) to a port where nobody is known yet twice, at start and 100 ms
# later, and then only every 30 s, which is when such a port is dropped
# (Discovery/InitialLocatorPruneDelay, 30 s): on a network that loses datagrams on purpose,
# losing both leaves the others unaware of it. `--announce-every S` announces it every S
# seconds (Discovery/SPDPInterval) instead.
ANNOUNCE = announce_every(sys.argv)
LOOPBACK = (
    '<CycloneDDS xmlns="https://cdds.io/config"><Domain id="any"><General><Interfaces>'
    '<NetworkInterface name="lo"/></Interfaces><AllowMulticast>false</AllowMulticast></General>'
    '<Discovery><Peers><Peer address="127.0.0.1"/></Peers><ParticipantIndex>auto</ParticipantIndex>'
    '<MaxAutoParticipantIndex>20</MaxAutoParticipantIndex>'
    + (f'<SPDPInterval>{ANNOUNCE}s</SPDPInterval>' if ANNOUNCE else '')
    + '</Discovery></Domain></CycloneDDS>'
)
os.environ.setdefault("CYCLONEDDS_URI", LOOPBACK)

from cyclonedds.builtin import (  # noqa: E402
    BuiltinDataReader, BuiltinTopicDcpsParticipant, BuiltinTopicDcpsPublication, BuiltinTopicDcpsSubscription)
from cyclonedds.core import Listener  # noqa: E402
from cyclonedds.domain import DomainParticipant  # noqa: E402
from cyclonedds.idl import IdlStruct  # noqa: E402
from cyclonedds.idl import types as T  # noqa: E402
from cyclonedds.pub import DataWriter  # noqa: E402
from cyclonedds.qos import Policy, Qos  # noqa: E402
from cyclonedds.sub import DataReader  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402
from cyclonedds.util import duration  # noqa: E402

SCALARS = {
    "bool": bool, "boolean": bool, "int8": T.int8, "int16": T.int16, "int32": T.int32, "int64": T.int64,
    "uint8": T.uint8, "uint16": T.uint16, "uint32": T.uint32, "uint64": T.uint64,
    "float32": T.float32, "float64": T.float64, "string": str,
}


def field_type(spec):
    if spec.endswith("]") and "[" in spec:
        base, n = spec[:-1].split("[")
        return T.sequence[SCALARS[base]] if n == "" else T.array[SCALARS[base], int(n)]
    return SCALARS[spec]


def make_type(typename, fields):
    """An IdlStruct class named `typename` (the DDS type name) with `fields`."""
    def body(ns):
        ns["__annotations__"] = {name: field_type(spec) for name, spec in fields}
    cls = types.new_class("T_" + typename.replace(":", "_"), (IdlStruct,), {"typename": typename}, body)
    return dataclass(cls)


def default(spec):
    t = field_type(spec)
    if spec.endswith("]"):
        n = spec[:-1].split("[")[1]
        return [] if n == "" else [0.0 if "float" in spec else 0] * int(n)
    return False if t is bool else ("" if t is str else (0.0 if "float" in spec else 0))


def reader_qos(a):
    pol = [Policy.Reliability.BestEffort if a.best_effort else Policy.Reliability.Reliable(duration(milliseconds=100)),
           Policy.History.KeepLast(100),
           Policy.Durability.TransientLocal if a.transient_local else Policy.Durability.Volatile]
    pol.append(Policy.Ownership.Exclusive if a.exclusive else Policy.Ownership.Shared)
    return Qos(*pol)


def writer_qos(a):
    pol = [Policy.Reliability.Reliable(duration(milliseconds=100))]
    if a.transient_local:
        pol += [Policy.History.KeepLast(1), Policy.Durability.TransientLocal]
    else:
        pol += [Policy.History.KeepLast(100), Policy.Durability.Volatile]
    if a.exclusive:
        pol += [Policy.Ownership.Exclusive, Policy.OwnershipStrength(a.strength)]
    else:
        pol.append(Policy.Ownership.Shared)
    return Qos(*pol)


def plain(v):
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    if hasattr(v, "__dataclass_fields__"):
        return {k: plain(getattr(v, k)) for k in v.__dataclass_fields__}
    return v


def emit(obj):
    print(json.dumps(obj), flush=True)


def wait_matched(w, timeout):
    end = time.time() + timeout
    while time.time() < end:
        if w.get_matched_subscriptions():
            return True
        time.sleep(0.05)
    return False


def cmd_sub(dp, a):
    fields = json.loads(a.fields)
    cls = make_type(a.type, fields)
    rd = DataReader(dp, Topic(dp, a.topic, cls), qos=reader_qos(a))
    end, n = time.time() + a.timeout, 0
    emit({"ready": True})
    while time.time() < end and n < a.count:
        for s in rd.take(N=100):
            if not s.sample_info.valid_data:
                continue
            emit(plain(s))
            n += 1
        time.sleep(0.002)
    return 0 if n >= a.count else 3


def cmd_pub(dp, a):
    fields = json.loads(a.fields)
    cls = make_type(a.type, fields)
    w = DataWriter(dp, Topic(dp, a.topic, cls), qos=writer_qos(a))
    if not wait_matched(w, a.timeout):
        emit({"error": "no matched reader"})
        return 3
    emit({"matched": True})
    time.sleep(0.2)
    for v in json.loads(a.values):
        full = {name: default(spec) for name, spec in fields}
        full.update(v)
        w.write(cls(**full))
        emit({"wrote": v})
        time.sleep(a.period_ms / 1000.0)
    time.sleep(a.linger)
    return 0


def cmd_answer(dp, a):
    f_in, f_out = json.loads(a.fields), json.loads(a.reply_fields)
    cin, cout = make_type(a.type, f_in), make_type(a.reply_type, f_out)
    read_history = Policy.History.KeepLast(a.read_depth) if a.read_depth else Policy.History.KeepAll
    rd = DataReader(dp, Topic(dp, a.topic, cin), qos=Qos(Policy.Reliability.Reliable(duration(milliseconds=100)),
                                                           read_history, Policy.Durability.Volatile))
    history = Policy.History.KeepLast(a.reply_depth) if a.reply_depth else Policy.History.KeepAll
    w = DataWriter(dp, Topic(dp, a.reply_topic, cout), qos=Qos(Policy.Reliability.Reliable(duration(milliseconds=100)),
                                                                 history, Policy.Durability.Volatile))
    emit({"ready": True})
    end, n = time.time() + a.timeout, 0
    first = f_in[2][0]
    previous = None
    while time.time() < end and n < a.count:
        for s in rd.take(N=100):
            if not s.sample_info.valid_data:
                continue
            unchanged = previous is not None and getattr(s, first) == previous
            previous = getattr(s, first)
            if a.on_change and unchanged:
                continue
            out = {name: default(spec) for name, spec in f_out}
            for name, _ in f_out[2:]:
                out[name] = getattr(s, first) + 1
            out["step"], out["sim_time"] = s.step, s.sim_time
            w.write(cout(**out))
            emit({"step": s.step, "in": getattr(s, first)})
            n += 1
        time.sleep(0.001)
    time.sleep(a.linger)
    return 0 if n >= a.count else 3


def cmd_steps(dp, a):
    fields = json.loads(a.fields)
    cls = make_type(a.type, fields)
    pol = [Policy.Reliability.Reliable(duration(seconds=1)), Policy.History.KeepAll, Policy.Durability.Volatile]
    if a.max_samples:
        pol.append(Policy.ResourceLimits(max_samples=a.max_samples, max_instances=1,
                                         max_samples_per_instance=a.max_samples))
    rd = DataReader(dp, Topic(dp, a.topic, cls), qos=Qos(*pol))
    emit({"ready": True})
    data = fields[2][0]
    pause = a.pause_ms / 1000.0 if a.max_samples else 0.001
    end = time.time() + a.timeout
    first = last = None
    received = missing = gaps = misordered = wrong = 0
    ended = False
    while time.time() < end and not ended:
        for s in rd.take(N=256):
            if not s.sample_info.valid_data:
                continue
            k, x = s.step, getattr(s, data)
            if first is None:
                first = k
                emit({"first": k})
            elif k <= last:
                misordered += 1
                continue
            elif k != last + 1:
                gaps += 1
                missing += k - last - 1
            last = k
            received += 1
            if x < 0:
                ended = True
            elif x != float(k):
                wrong += 1
        time.sleep(pause)
    emit({"summary": True, "first": first, "last": last, "received": received, "missing": missing, "gaps": gaps,
          "misordered": misordered, "wrong": wrong, "ended": ended})
    return 0 if ended else 3


def history(q):
    """The HISTORY a discovered endpoint announced; Cyclone fills in the DDS default
    (KEEP_LAST 1) for an endpoint whose discovery data has none."""
    h = q[Policy.History] if Policy.History in q else Policy.History.KeepLast(1)
    return ("KeepAll", None) if "KeepAll" in str(h) else ("KeepLast", h.depth)


def cmd_qos(dp, a):
    rd = BuiltinDataReader(dp, BuiltinTopicDcpsSubscription if a.readers else BuiltinTopicDcpsPublication)
    end = time.time() + a.timeout
    while time.time() < end:
        for s in rd.take(N=200):
            if not s.sample_info.valid_data or s.topic_name != a.topic:
                continue
            q = s.qos
            emit({
                "type_name": s.type_name,
                "reliability": type(q[Policy.Reliability]).__name__.split(".")[-1],
                "durability": str(q[Policy.Durability]).split(".")[-1],
                "ownership": str(q[Policy.Ownership]).split(".")[-1],
                "strength": q[Policy.OwnershipStrength].strength if Policy.OwnershipStrength in q else None,
                "history": history(q)[0],
                "depth": history(q)[1],
            })
            return 0
        time.sleep(0.05)
    return 3


def cmd_endpoints(dp, a):
    readers = [(kind, BuiltinDataReader(dp, t)) for kind, t in
               (("writer", BuiltinTopicDcpsPublication), ("reader", BuiltinTopicDcpsSubscription))]
    seen = {}
    end, quiet_since = time.time() + a.timeout, time.time()
    while time.time() < end:
        for kind, rd in readers:
            for s in rd.take(N=200):
                if not s.sample_info.valid_data or s.key.bytes in seen or s.participant_key == dp.guid:
                    continue
                ud = s.qos[Policy.Userdata].data if Policy.Userdata in s.qos else None
                seen[s.key.bytes] = {"kind": kind, "topic": s.topic_name, "type_name": s.type_name,
                                     "user_data": ud.decode("latin-1") if ud is not None else None}
                quiet_since = time.time()
        if len(seen) >= a.count and time.time() - quiet_since > 1.0:
            break
        time.sleep(0.05)
    for e in seen.values():
        emit(e)
    return 0 if len(seen) >= a.count else 3


@dataclass
class Gid(IdlStruct, typename="rmw_dds_common::msg::dds_::Gid_"):
    data: T.array[T.uint8, 16]


@dataclass
class NodeEntitiesInfo(IdlStruct, typename="rmw_dds_common::msg::dds_::NodeEntitiesInfo_"):
    node_namespace: str
    node_name: str
    reader_gid_seq: T.sequence[Gid]
    writer_gid_seq: T.sequence[Gid]


@dataclass
class ParticipantEntitiesInfo(IdlStruct, typename="rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_"):
    gid: Gid
    node_entities_info_seq: T.sequence[NodeEntitiesInfo]


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: T.int32
    nanosec: T.uint32


@dataclass
class Clock(IdlStruct, typename="rosgraph_msgs::msg::dds_::Clock_"):
    clock: Time


def cmd_clock(dp, a):
    q = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(1), Policy.Durability.Volatile)
    rd = DataReader(dp, Topic(dp, "rt/clock", Clock), qos=q)
    emit({"ready": True})
    end = time.time() + a.timeout
    while time.time() < end:
        for s in rd.take(N=100):
            if s.sample_info.valid_data:
                emit({"clock": s.clock.sec + s.clock.nanosec * 1e-9, "sec": s.clock.sec, "nanosec": s.clock.nanosec})
        time.sleep(0.001)
    return 0


def cmd_nodes(dp, a):
    q = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(1),
            Policy.Durability.TransientLocal)
    rd = DataReader(dp, Topic(dp, "ros_discovery_info", ParticipantEntitiesInfo), qos=q)
    end = time.time() + a.timeout
    while time.time() < end:
        for s in rd.take(N=100):
            if not s.sample_info.valid_data:
                continue
            for n in s.node_entities_info_seq:
                if n.node_name == a.name:
                    emit({"namespace": n.node_namespace, "name": n.node_name,
                          "readers": len(n.reader_gid_seq), "writers": len(n.writer_gid_seq)})
                    return 0
        time.sleep(0.05)
    return 3


def cmd_lease(dp, a):
    # Deep: ros_discovery_info is one keyless topic that every participant writes.
    q = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(100),
            Policy.Durability.TransientLocal)
    rd = DataReader(dp, Topic(dp, "ros_discovery_info", ParticipantEntitiesInfo), qos=q)
    parts = BuiltinDataReader(dp, BuiltinTopicDcpsParticipant)
    end, gid, leases = time.time() + a.timeout, None, {}
    while time.time() < end:
        for s in rd.take(N=100):
            if s.sample_info.valid_data and any(n.node_name == a.name and n.node_namespace == a.node_namespace
                                                for n in s.node_entities_info_seq):
                gid = bytes(s.gid.data)
        for s in parts.take(N=100):
            if s.sample_info.valid_data and Policy.Liveliness in s.qos:
                leases[s.key.bytes] = s.qos[Policy.Liveliness].lease_duration
        if gid is not None and gid in leases:
            emit({"namespace": a.node_namespace, "name": a.name, "lease_s": leases[gid] / 1e9})
            return 0
        time.sleep(0.05)
    return 3


# simulation_interfaces, as rmw_cyclonedds serializes a service's samples: the request header
# (the client's writer id, the sequence number), then the message's fields.
@dataclass
class SimulationState(IdlStruct, typename="simulation_interfaces::msg::dds_::SimulationState_"):
    state: T.uint8


@dataclass
class SimResult(IdlStruct, typename="simulation_interfaces::msg::dds_::Result_"):
    result: T.uint8
    error_message: str


@dataclass
class SimulatorFeatures(IdlStruct, typename="simulation_interfaces::msg::dds_::SimulatorFeatures_"):
    features: T.sequence[T.uint16]
    spawn_formats: T.sequence[str]
    custom_info: str


def srv_types(srv, request_fields, response_fields):
    req = {"client_guid": T.uint64, "sequence_number": T.int64, **request_fields}
    rsp = {"client_guid": T.uint64, "sequence_number": T.int64, **response_fields}

    def make(suffix, ann):
        name = f"simulation_interfaces::srv::dds_::{srv}_{suffix}_"
        cls = types.new_class("S_" + srv + suffix, (IdlStruct,), {"typename": name},
                              lambda ns: ns.__setitem__("__annotations__", ann))
        return dataclass(cls)
    return make("Request", req), make("Response", rsp)


# name: (srv, request fields, response fields, how the request's own fields are packed)
SERVICES = {
    "get_simulator_features": ("GetSimulatorFeatures", {"structure_needs_at_least_one_member": T.uint8},
                               {"features": SimulatorFeatures}, "B"),
    "get_simulation_state": ("GetSimulationState", {"structure_needs_at_least_one_member": T.uint8},
                             {"state": SimulationState, "result": SimResult}, "B"),
    "set_simulation_state": ("SetSimulationState", {"state": SimulationState}, {"result": SimResult}, "B"),
    "step_simulation": ("StepSimulation", {"steps": T.uint64}, {"result": SimResult}, "Q"),
    "reset_simulation": ("ResetSimulation", {"scope": T.uint8}, {"result": SimResult}, "B"),
}


def service_qos():
    # rmw_qos_profile_services_default
    return Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(10),
               Policy.Durability.Volatile)


def ros_topic(prefix, ns, name, suffix):
    return f"{prefix}/{ns + '/' if ns else ''}{name}{suffix}"


class ServiceClient:
    """One service's client: a request writer and a reply reader, as rmw_cyclonedds makes them."""

    def __init__(self, dp, ns, name):
        srv, fields, _, self.pack = SERVICES[name]
        self.name, self.fields = name, fields
        self.req, self.rsp = srv_types(srv, fields, SERVICES[name][2])
        self.w = DataWriter(dp, Topic(dp, ros_topic("rq", ns, name, "Request"), self.req), qos=service_qos())
        self.r = DataReader(dp, Topic(dp, ros_topic("rr", ns, name, "Reply"), self.rsp), qos=service_qos())
        self.guid = int.from_bytes(os.urandom(8), "little") >> 1
        self.seq = 0

    def available(self):
        return bool(self.w.get_matched_subscriptions()) and bool(self.r.get_matched_publications())

    def call(self, arg, timeout):
        import struct
        self.seq += 1
        fields = {}
        if self.name == "set_simulation_state":
            fields["state"], raw_arg = SimulationState(state=arg), arg
        elif self.name == "step_simulation":
            fields["steps"], raw_arg = arg, arg
        elif self.name == "reset_simulation":
            fields["scope"], raw_arg = arg, arg
        else:
            fields["structure_needs_at_least_one_member"], raw_arg = 0, 0
        sample = self.req(client_guid=self.guid, sequence_number=self.seq, **fields)
        by_hand = b"\x00\x01\x00\x00" + struct.pack("<Qq" + self.pack, self.guid, self.seq, raw_arg)
        got = sample.serialize()
        if got[:len(by_hand)] != by_hand or len(got.rstrip(b"\x00")) > len(by_hand):
            emit({"error": "not rmw_cyclonedds's layout", "got": got.hex(), "want": by_hand.hex()})
            return None
        self.w.write(sample)
        end = time.time() + timeout
        while time.time() < end:
            for s in self.r.take(N=10):
                if s.sample_info.valid_data and s.client_guid == self.guid and s.sequence_number == self.seq:
                    return plain(s)
            time.sleep(0.005)
        return None


def action_types():
    """The action's types, as rmw_cyclonedds serializes them (services with the request header)."""
    def struct(name, ann):
        return dataclass(types.new_class("A_" + name.split("::")[-1], (IdlStruct,), {"typename": name},
                                         lambda ns: ns.__setitem__("__annotations__", ann)))
    hdr = {"client_guid": T.uint64, "sequence_number": T.int64}
    uuid = T.array[T.uint8, 16]
    Time = struct("builtin_interfaces::msg::dds_::Time_", {"sec": T.int32, "nanosec": T.uint32})
    GoalInfo = struct("action_msgs::msg::dds_::GoalInfo_", {"goal_id": uuid, "stamp": Time})
    GoalStatus = struct("action_msgs::msg::dds_::GoalStatus_", {"goal_info": GoalInfo, "status": T.int8})
    A = "simulation_interfaces::action::dds_::SimulateSteps_"
    return types.SimpleNamespace(
        Time=Time, GoalInfo=GoalInfo,
        SendReq=struct(A + "SendGoal_Request_", {**hdr, "goal_id": uuid, "steps": T.uint64}),
        SendRsp=struct(A + "SendGoal_Response_", {**hdr, "accepted": bool, "stamp": Time}),
        ResultReq=struct(A + "GetResult_Request_", {**hdr, "goal_id": uuid}),
        ResultRsp=struct(A + "GetResult_Response_", {**hdr, "status": T.int8, "result": SimResult}),
        CancelReq=struct("action_msgs::srv::dds_::CancelGoal_Request_", {**hdr, "goal_info": GoalInfo}),
        CancelRsp=struct("action_msgs::srv::dds_::CancelGoal_Response_",
                         {**hdr, "return_code": T.int8, "goals_canceling": T.sequence[GoalInfo]}),
        Feedback=struct(A + "FeedbackMessage_", {"goal_id": uuid, "completed_steps": T.uint64,
                                                 "remaining_steps": T.uint64}),
        Status=struct("action_msgs::msg::dds_::GoalStatusArray_", {"status_list": T.sequence[GoalStatus]}),
    )


def cmd_action(dp, a):
    import struct as st
    t = action_types()
    base = "simulate_steps/_action/"
    guid, seq = int.from_bytes(os.urandom(8), "little") >> 1, [0]

    def pair(name, req, rsp):
        return (DataWriter(dp, Topic(dp, ros_topic("rq", a.ros_namespace, base + name, "Request"), req), qos=service_qos()),
                DataReader(dp, Topic(dp, ros_topic("rr", a.ros_namespace, base + name, "Reply"), rsp), qos=service_qos()))
    send, result, cancel = pair("send_goal", t.SendReq, t.SendRsp), pair("get_result", t.ResultReq, t.ResultRsp), \
        pair("cancel_goal", t.CancelReq, t.CancelRsp)
    # Keep-all, unlike rclpy's keep-last 10, so that every feedback sample is seen.
    fb = DataReader(dp, Topic(dp, ros_topic("rt", a.ros_namespace, base + "feedback", ""), t.Feedback),
                    qos=Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepAll,
                            Policy.Durability.Volatile))
    status = DataReader(dp, Topic(dp, ros_topic("rt", a.ros_namespace, base + "status", ""), t.Status),
                        qos=Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(1),
                                Policy.Durability.TransientLocal))
    end = time.time() + a.timeout
    while not all(w.get_matched_subscriptions() and r.get_matched_publications() for w, r in (send, result, cancel)) \
            or not fb.get_matched_publications():
        if time.time() > end:
            emit({"error": "no action server"})
            return 3
        time.sleep(0.05)

    def request(p, sample, check=None):
        if check is not None:
            got = sample.serialize()
            if got[:len(check)] != check:
                emit({"error": "not rmw_cyclonedds's layout", "got": got.hex(), "want": check.hex()})
                return False
        p[0].write(sample)
        return True

    def reply(p, s):
        while time.time() < end:
            for r in p[1].take(N=10):
                if r.sample_info.valid_data and r.client_guid == guid and r.sequence_number == s:
                    return r
            time.sleep(0.005)
        return None

    goal = list(os.urandom(16))
    seq[0] += 1
    by_hand = b"\x00\x01\x00\x00" + st.pack("<Qq16BQ", guid, seq[0], *goal, a.steps)
    if not request(send, t.SendReq(client_guid=guid, sequence_number=seq[0], goal_id=goal, steps=a.steps), by_hand):
        return 3
    r = reply(send, seq[0])
    if r is None:
        emit({"error": "no send_goal reply"})
        return 3
    emit({"accepted": r.accepted})
    if not r.accepted:
        return 0
    seq[0] += 1
    result_seq = seq[0]
    request(result, t.ResultReq(client_guid=guid, sequence_number=result_seq, goal_id=goal))
    feedbacks, got = 0, None
    while time.time() < end and got is None:
        for s in fb.take(N=100):
            if s.sample_info.valid_data and list(s.goal_id) == goal:
                feedbacks += 1
                emit({"feedback": [s.completed_steps, s.remaining_steps]})
                if a.cancel_after and feedbacks == a.cancel_after:
                    seq[0] += 1
                    info = t.GoalInfo(goal_id=goal, stamp=t.Time(sec=0, nanosec=0))
                    request(cancel, t.CancelReq(client_guid=guid, sequence_number=seq[0], goal_info=info))
                    c = reply(cancel, seq[0])
                    emit({"cancel": None if c is None else c.return_code,
                          "canceling": None if c is None else len(c.goals_canceling)})
        for r in result[1].take(N=10):
            if r.sample_info.valid_data and r.client_guid == guid and r.sequence_number == result_seq:
                got = r
        time.sleep(0.002)
    if got is None:
        emit({"error": "no result"})
        return 3
    # Feedback written before the result may arrive after it (another writer).
    time.sleep(0.3)
    for s in fb.take(N=100):
        if s.sample_info.valid_data and list(s.goal_id) == goal:
            emit({"feedback": [s.completed_steps, s.remaining_steps]})
    last = None
    for _ in range(100):
        for s in status.take(N=10):
            if s.sample_info.valid_data:
                mine = [g.status for g in s.status_list if list(g.goal_info.goal_id) == goal]
                last = mine[0] if mine else last
        if last is not None and last >= 4:
            break
        time.sleep(0.02)
    emit({"status": got.status, "result": plain(got.result), "last_status": last})
    return 0


def cmd_service(dp, a):
    calls = json.loads(a.calls)
    clients = {name: ServiceClient(dp, a.ros_namespace, name) for name in {c[0] for c in calls}}
    end = time.time() + a.timeout
    while not all(c.available() for c in clients.values()):
        if time.time() > end:
            emit({"error": "no service", "missing": [n for n, c in clients.items() if not c.available()]})
            return 3
        time.sleep(0.05)
    for c in calls:
        reply = clients[c[0]].call(c[1] if len(c) > 1 else None, a.timeout)
        if reply is None:
            emit({"error": "no reply", "call": c[0]})
            return 3
        reply.pop("client_guid")
        reply.pop("sequence_number")
        emit({"call": c[0], "arg": c[1] if len(c) > 1 else None, **reply})
    return 0


def main():
    p = argparse.ArgumentParser()
    p.add_argument("mode", choices=["sub", "pub", "answer", "steps", "qos", "endpoints", "nodes", "clock", "lease",
                                    "service", "action"])
    p.add_argument("--domain", type=int, required=True)
    p.add_argument("--topic")
    p.add_argument("--type")
    p.add_argument("--fields")
    p.add_argument("--values", default="[]")
    p.add_argument("--reply-topic")
    p.add_argument("--reply-type")
    p.add_argument("--reply-fields")
    p.add_argument("--name")
    p.add_argument("--node-namespace", default="/")
    p.add_argument("--count", type=int, default=1)
    p.add_argument("--timeout", type=float, default=60.0)
    p.add_argument("--period-ms", type=float, default=50.0)
    p.add_argument("--linger", type=float, default=0.5)
    p.add_argument("--best-effort", action="store_true")
    p.add_argument("--exclusive", action="store_true")
    p.add_argument("--transient-local", action="store_true")
    p.add_argument("--readers", action="store_true")
    p.add_argument("--on-change", action="store_true")
    p.add_argument("--reply-depth", type=int, default=0)
    p.add_argument("--read-depth", type=int, default=0)
    p.add_argument("--strength", type=int, default=5)
    p.add_argument("--max-samples", type=int, default=0)
    p.add_argument("--pause-ms", type=float, default=1.0)
    p.add_argument("--calls", default="[]")
    p.add_argument("--steps", type=int, default=1)
    p.add_argument("--cancel-after", type=int, default=0)
    p.add_argument("--announce-every", type=float, help="SPDP every S seconds (read before Cyclone is loaded)")
    p.add_argument("--ros-namespace", default="")
    a = p.parse_args()
    dp = DomainParticipant(a.domain)
    sys.exit({"sub": cmd_sub, "pub": cmd_pub, "answer": cmd_answer, "steps": cmd_steps, "qos": cmd_qos,
              "endpoints": cmd_endpoints, "nodes": cmd_nodes, "clock": cmd_clock, "lease": cmd_lease,
              "service": cmd_service, "action": cmd_action}[a.mode](dp, a))


if __name__ == "__main__":
    main()
