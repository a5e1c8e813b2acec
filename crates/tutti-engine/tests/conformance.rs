//! The engine conformance suite: every engine this build has ([`tutti_engine::for_each_engine!`],
//! the one list of engines) goes through the same scenarios, written once against the [`Engine`]
//! trait: raw CDR in both byte orders (typed sets and per-item stock messages), the engine's own
//! samples known by their peer and dropped (echo suppression is the engine's), discovery of
//! remote endpoints with the QoS they announced, QoS matching and its refusal, exclusive
//! ownership, the node announcement on `ros_discovery_info`, samples that cannot be decoded
//! reported as such, and a ROS 2 service answering each request in its client's wire form
//! (docs/ros2.md, "Wire forms").
//!
//! Everything runs in this process, on loopback, with no Python and no gateway binary. Each
//! scenario has a DDS domain of its own (60-79 for the first engine of the list, 80-99 for the
//! second: 20 per engine) so that all run in parallel, and a watchdog; waits are for an event, bounded, and nothing asserts a duration.
//! Where a scenario needs what only Cyclone can do (write a big-endian sample, read samples of a
//! type without decoding them), the peer is a Cyclone participant: for the rustdds engine that
//! makes the scenario an interop test between the two engines as well.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use tutti_core::ddf::{parse_str, Leaf, SetLayout};
use tutti_core::mapping::{Durability, History, Ownership, Qos, Reliability};
use tutti_engine::cdr::{split_header, stock, CdrError, Payload, SetCodec, TypedSample, HEADER_LE};
use tutti_engine::cyclone::Cyclone;
use tutti_engine::{
    self as engine, Decode, EndpointId, EndpointQos, Engine, EngineConfig, EngineKind, Request, Service, Sink,
    TopicType, Writer,
};
use tutti_test_support::ZenohRouter;

/// The longest wait for one expected event (discovery, a sample).
const PATIENCE: Duration = Duration::from_secs(30);
/// The longest a whole scenario may take before the test binary is stopped.
const WATCHDOG: Duration = Duration::from_secs(150);

/// The scenarios of one engine: a module named after it (`NAME::cyclone`, `NAME::rustdds`).
macro_rules! scenarios_for {
    ($engine:ident, $kind:ident, [$($n:literal => $name:ident),* $(,)?]) => {
        mod $engine {
            $( #[test] fn $name() { super::run(super::EngineKind::$kind, $n, super::$name) } )*
        }
    };
}

/// Every scenario on every engine of the build, as [`tutti_engine::for_each_engine!`] lists them.
macro_rules! conformance {
    ($scenarios:tt $($engine:ident: $kind:ident),* $(,)?) => {
        $( scenarios_for!($engine, $kind, $scenarios); )*
        const TESTED: &[EngineKind] = &[$(EngineKind::$kind),*];
    };
}

tutti_engine::for_each_engine!(conformance, [
    0 => raw_cdr_round_trips_in_both_byte_orders,
    1 => own_samples_are_known_by_their_peer_and_dropped,
    2 => discovery_lists_remote_endpoints_with_their_qos,
    3 => qos_matching_and_refusal,
    4 => exclusive_ownership_goes_by_strength,
    5 => the_node_is_announced_on_ros_discovery_info,
    6 => a_sample_that_cannot_be_decoded_is_reported,
    7 => a_service_answers_each_request_in_its_clients_form,
]);

#[test]
fn every_engine_of_the_build_is_tested() {
    assert_eq!(TESTED, EngineKind::built());
}

// ---------------------------------------------------------------------------------------
// The scenarios.

/// A typed set written by one participant reaches another's reader unchanged: little-endian
/// from the engine's own writer, big-endian from a Cyclone writer; per-item stock messages
/// likewise. The writer's GUID comes with each sample.
fn raw_cdr_round_trips_in_both_byte_orders(c: &Case) {
    let (codec, layout) = set_codec();
    let reader = c.open("reader");
    let writer = c.open("writer");
    let cyclone = c.peer_raw("be_writer");
    let q = qos(Reliability::Reliable, History::KeepAll, false, Ownership::Shared);

    let topic = c.topic("set");
    let inbox = Inbox::new(Decode::Set(codec.clone()));
    reader.reader(&topic, &TopicType::plain(SET_TYPE), &q, Decode::Set(codec.clone()), inbox.sink()).unwrap();
    let mut le = writer.writer(&topic, &TopicType::plain(SET_TYPE), &q).unwrap();
    let a = sample(&codec, &layout, 1);
    let mut body = Vec::new();
    codec.encode(a.step, a.sim_time, &a.data, &mut body);
    let from = inbox.until_payload("the little-endian sample", &mut *le, &Payload::Set(a.clone()), |w| w.write(&body));
    assert_eq!(from.peer, writer.own_peer(), "the sample comes with its writer's GUID");

    let b = sample(&codec, &layout, 2);
    codec.encode(b.step, b.sim_time, &b.data, &mut body);
    let be = [&[0u8, 0, 0, 0][..], &big_endian(&codec, &body)].concat();
    let mut bw = cyclone.writer(&topic, &TopicType::plain(SET_TYPE), &q).unwrap();
    inbox.until_payload("the big-endian sample", &mut *bw, &Payload::Set(b), |w| w.write_serialized(&be));

    // Per item: a double as std_msgs/Float64, and a double array as Float64MultiArray.
    for (path, value) in [("x", vec![2.5f64]), ("v", vec![1.0f64, -4.0, 0.125])] {
        let leaf = Arc::new(layout.leaf(path).unwrap().clone());
        let topic = c.topic(&format!("item_{path}"));
        let ty = tutti_core::mapping::per_item_type(leaf.ty, leaf.length);
        let decode = Decode::Item(leaf.clone(), Arc::from(path));
        let inbox = Inbox::new(decode.clone());
        reader.reader(&topic, &TopicType::stock(ty), &q, decode, inbox.sink()).unwrap();
        let want = Payload::Item { path: Arc::from(path), bytes: value.iter().flat_map(|v| v.to_ne_bytes()).collect() };
        let mut body = Vec::new();
        match stock::Stock::of(&leaf) {
            stock::Stock::Float64 => stock::encode_float64(value[0], &mut body),
            _ => stock::encode_float64_array(value.iter().copied(), &mut body),
        }
        let mut w = writer.writer(&topic, &TopicType::stock(ty), &q).unwrap();
        inbox.until_payload("a little-endian stock sample", &mut *w, &want, |w| w.write(&body));
        let be = [&[0u8, 0, 0, 0][..], &stock_big_endian(&value, leaf.length > 1)].concat();
        assert_eq!(stock::decode(&leaf, &be).map(|b| b.len()), Ok(8 * value.len()), "the test's own big-endian form");
        let mut w = cyclone.writer(&topic, &TopicType::stock(ty), &q).unwrap();
        inbox.until_payload("a big-endian stock sample", &mut *w, &want, |w| w.write_serialized(&be));
    }
}

/// A participant's own samples never reach its readers' sinks: an engine that hands them
/// to its readers (Cyclone) knows them by its own peer, drops them and counts them; another
/// participant's reach the sink, with its writer's peer. Discovery leaves the participant's
/// own endpoints out.
fn own_samples_are_known_by_their_peer_and_dropped(c: &Case) {
    let (codec, layout) = set_codec();
    let gateway = c.open("gateway");
    let other = c.open("other");
    assert_ne!(gateway.own_peer(), other.own_peer());
    let q = qos(Reliability::Reliable, History::KeepAll, false, Ownership::Shared);
    let topic = c.topic("echo");

    let inbox = Inbox::new(Decode::Set(codec.clone()));
    gateway.reader(&topic, &TopicType::plain(SET_TYPE), &q, Decode::Set(codec.clone()), inbox.sink()).unwrap();
    let mut own = gateway.writer(&topic, &TopicType::plain(SET_TYPE), &q).unwrap();
    let mut theirs = other.writer(&topic, &TopicType::plain(SET_TYPE), &q).unwrap();

    let (mine, their) = (sample(&codec, &layout, 10), sample(&codec, &layout, 20));
    let (mut mine_body, mut their_body) = (Vec::new(), Vec::new());
    codec.encode(mine.step, mine.sim_time, &mine.data, &mut mine_body);
    codec.encode(their.step, their.sim_time, &their.data, &mut their_body);
    until("ten samples of the other participant at the sink", || {
        own.write(&mine_body);
        own.flush();
        theirs.write(&their_body);
        theirs.flush();
        inbox.len() >= 10
    });
    for (writer, payload) in lock(&inbox.got).iter() {
        assert_eq!(writer.peer, other.own_peer(), "only the other participant's samples reach the sink");
        assert_eq!(payload.as_ref(), Ok(&Payload::Set(their.clone())));
    }
    if c.engine == EngineKind::Cyclone {
        // Cyclone hands them over: the drop path ran, and counted what it dropped.
        assert!(gateway.own_samples() > 0, "Cyclone handed over none of the participant's own samples");
    }

    let remote = until_some("the other participant's writer in discovery", || {
        let r = gateway.remote();
        let listed = r.writers_on(&topic).any(|g| g.peer == other.own_peer());
        listed.then_some(r)
    });
    assert!(remote.writers_on(&topic).all(|g| g.peer != gateway.own_peer()), "our own writer is not remote");
    assert!(remote.readers.values().flatten().all(|g| g.peer != gateway.own_peer()));
}

/// A participant lists the other's writer and reader under their topics, each with the QoS
/// it announced.
fn discovery_lists_remote_endpoints_with_their_qos(c: &Case) {
    let (codec, _) = set_codec();
    let announcer = c.open("announcer");
    let observer = c.open("observer");
    let (wt, rt) = (c.topic("offered"), c.topic("requested"));
    let offered = Qos {
        reliability: Reliability::Reliable,
        history: History::KeepLast(1),
        durability: Durability::TransientLocal { depth: 1 },
        ownership: Ownership::Exclusive { strength: 7 },
        lifespan: None,
    };
    let requested = qos(Reliability::BestEffort, History::KeepLast(4), false, Ownership::Shared);
    let _w = announcer.writer(&wt, &TopicType::plain(SET_TYPE), &offered).unwrap();
    announcer.reader(&rt, &TopicType::plain(SET_TYPE), &requested, Decode::Set(codec), Arc::new(|_, _| {})).unwrap();

    let mine = |g: &EndpointId| g.peer == announcer.own_peer();
    let remote = until_some("the writer and the reader in discovery", || {
        let r = observer.remote();
        let listed = r.writers_on(&wt).any(|g| mine(&g)) && r.readers_on(std::slice::from_ref(&rt)).iter().any(mine);
        listed.then_some(r)
    });
    let w = remote.writers_on(&wt).find(|g| mine(g)).unwrap();
    let r = *remote.readers_on(std::slice::from_ref(&rt)).iter().find(|g| mine(g)).unwrap();
    // Zenoh has no ownership: its tokens carry none (docs/gateway.md, "Zenoh").
    let ownership = if c.engine.is_dds() { Ownership::Exclusive { strength: 7 } } else { Ownership::Shared };
    assert_eq!(
        remote.qos.get(&w),
        Some(&EndpointQos { reliability: Reliability::Reliable, transient_local: true, ownership })
    );
    assert_eq!(
        remote.qos.get(&r),
        Some(&EndpointQos {
            reliability: Reliability::BestEffort,
            transient_local: false,
            ownership: Ownership::Shared
        })
    );
    assert!(
        remote.readers_on(std::slice::from_ref(&wt)).iter().all(|g| !mine(g)),
        "no reader of ours on the writer's topic"
    );
}

/// A best-effort volatile writer matches a best-effort volatile reader, and on DDS neither a
/// reliable reader nor a transient-local one (Zenoh delivers to all three); a reliable
/// transient-local writer matches all three.
/// Refusal is seen against a reader that matched: both are in one participant, which learns
/// of the writer once, and the refused readers get nothing while it gets every sample.
fn qos_matching_and_refusal(c: &Case) {
    let (codec, layout) = set_codec();
    let writer = c.open("writer");
    let reader = c.open("reader");
    let requests = [
        ("best effort", qos(Reliability::BestEffort, History::KeepAll, false, Ownership::Shared)),
        ("reliable", qos(Reliability::Reliable, History::KeepAll, false, Ownership::Shared)),
        ("transient local", qos(Reliability::BestEffort, History::KeepAll, true, Ownership::Shared)),
    ];
    // Zenoh refuses no reader for its QoS (docs/gateway.md, "Zenoh"): every reader matches.
    let refuses = c.engine.is_dds();
    for (what, offered, matched) in [
        (
            "weakest",
            qos(Reliability::BestEffort, History::KeepLast(1), false, Ownership::Shared),
            [true, !refuses, !refuses],
        ),
        ("strongest", qos(Reliability::Reliable, History::KeepLast(1), true, Ownership::Shared), [true, true, true]),
    ] {
        let topic = c.topic(what);
        let inboxes: Vec<Arc<Inbox>> = requests
            .iter()
            .map(|(_, rq)| {
                let inbox = Inbox::new(Decode::Set(codec.clone()));
                reader
                    .reader(&topic, &TopicType::plain(SET_TYPE), rq, Decode::Set(codec.clone()), inbox.sink())
                    .unwrap();
                inbox
            })
            .collect();
        let mut w = writer.writer(&topic, &TopicType::plain(SET_TYPE), &offered).unwrap();
        let mut body = Vec::new();
        let mut step = 0;
        let mut write = |w: &mut Box<dyn Writer>| {
            step += 1;
            let s = sample(&codec, &layout, step);
            codec.encode(s.step, s.sim_time, &s.data, &mut body);
            w.write(&body);
            w.flush();
        };
        until(&format!("the {what} writer's samples at every matching reader"), || {
            write(&mut w);
            inboxes.iter().zip(matched).all(|(i, m)| !m || i.len() >= 3)
        });
        // Ten more at the reader that matches first, once every match is settled: the other
        // matched readers get theirs too, the refused ones none.
        let before = inboxes[0].len();
        until(&format!("ten more of the {what} writer's samples"), || {
            write(&mut w);
            inboxes[0].len() >= before + 10
        });
        for ((name, _), (inbox, m)) in requests.iter().zip(inboxes.iter().zip(matched)) {
            assert_eq!(inbox.len() > 0, m, "a {name} reader of the {what} writer: matched {m} expected");
        }
    }
}

/// EXCLUSIVE ownership: on an engine that arbitrates it, a reader takes only the strongest
/// live writer's samples, and the weaker one's again once the stronger has gone; on one that
/// does not (rustdds), the reader takes both and the core's first-writer rule decides above.
fn exclusive_ownership_goes_by_strength(c: &Case) {
    let (codec, layout) = set_codec();
    let reader = c.open("reader");
    let weak_p = c.open("weak");
    let strong_p = c.open("strong");
    let topic = c.topic("owned");
    let exclusive = |strength| qos(Reliability::Reliable, History::KeepAll, false, Ownership::Exclusive { strength });
    let inbox = Inbox::new(Decode::Set(codec.clone()));
    reader
        .reader(&topic, &TopicType::plain(SET_TYPE), &exclusive(0), Decode::Set(codec.clone()), inbox.sink())
        .unwrap();
    let mut weak = weak_p.writer(&topic, &TopicType::plain(SET_TYPE), &exclusive(1)).unwrap();
    let mut strong = strong_p.writer(&topic, &TopicType::plain(SET_TYPE), &exclusive(5)).unwrap();
    let mut body = Vec::new();
    let mut send = |w: &mut Box<dyn Writer>, step: u64| {
        let s = sample(&codec, &layout, step);
        codec.encode(s.step, s.sim_time, &s.data, &mut body);
        w.write(&body);
        w.flush();
    };
    // Steps tell the writers apart: 1000s the weak one, 2000s the strong one.
    let (mut ws, mut ss) = (1000, 2000);
    until("a sample of each writer", || {
        ws += 1;
        ss += 1;
        send(&mut weak, ws);
        send(&mut strong, ss);
        let steps = inbox.steps();
        steps.iter().any(|s| *s < 2000) && steps.iter().any(|s| *s >= 2000)
    });
    until("both writers matched to the reader", || {
        ws += 1;
        ss += 1;
        send(&mut weak, ws);
        send(&mut strong, ss);
        let steps = inbox.steps();
        steps.iter().filter(|s| **s >= 2000).count() >= 5
    });
    let settled = inbox.len();
    let last_strong = ss + 20;
    for _ in 0..20 {
        ws += 1;
        ss += 1;
        send(&mut weak, ws);
        send(&mut strong, ss);
    }
    until("the strong writer's last sample", || inbox.steps().contains(&last_strong));
    let after: Vec<u64> = inbox.steps()[settled..].to_vec();
    let weak_after = after.iter().filter(|s| **s < 2000).count();
    if reader.arbitrates_ownership() {
        assert_eq!(weak_after, 0, "the weaker writer's samples while the stronger lives: {after:?}");
        drop(strong);
        drop(strong_p);
        until("the weaker writer's samples once the stronger has gone", || {
            ws += 1;
            send(&mut weak, ws);
            inbox.steps().contains(&ws)
        });
    } else {
        assert!(weak_after > 0, "an engine that does not arbitrate delivers both writers: {after:?}");
    }
}

/// A typed sample too short for its set, or in another representation than plain CDR, reaches
/// the reader's sink as a decoding error, never as a sample; the good sample after it arrives.
fn a_sample_that_cannot_be_decoded_is_reported(c: &Case) {
    let (codec, layout) = set_codec();
    let reader = c.open("reader");
    let cyclone = c.peer_raw("bad_writer");
    let q = qos(Reliability::Reliable, History::KeepAll, false, Ownership::Shared);
    let topic = c.topic("bad");
    let inbox = Inbox::new(Decode::Set(codec.clone()));
    reader.reader(&topic, &TopicType::plain(SET_TYPE), &q, Decode::Set(codec.clone()), inbox.sink()).unwrap();
    let mut w = cyclone.writer(&topic, &TopicType::plain(SET_TYPE), &q).unwrap();
    let good = sample(&codec, &layout, 3);
    let mut body = Vec::new();
    codec.encode(good.step, good.sim_time, &good.data, &mut body);
    let raw = [&HEADER_LE[..], &body].concat();
    until("a good sample, once the writer is matched", || {
        w.write_serialized(&raw);
        w.flush();
        inbox.len() > 0
    });
    let want = Payload::Set(good);
    for bad in [&raw[..raw.len() / 2], &[&[0u8, 7, 0, 0][..], &body].concat()[..]] {
        let before = inbox.len();
        assert!(w.write_serialized(bad));
        w.write_serialized(&raw);
        w.flush();
        // The error, then the good sample after it (an engine may still deliver a good sample
        // of the wait above first).
        until("the bad sample's error and the good sample after it", || {
            let got = lock(&inbox.got);
            let err = got[before..].iter().position(|(_, p)| p.is_err());
            err.is_some_and(|i| got[before + i..].iter().any(|(_, p)| p.as_ref() == Ok(&want)))
        });
        let got = lock(&inbox.got);
        assert!(got[before..].iter().all(|(_, p)| p.as_ref().map_or(true, |p| p == &want)), "only good samples decode");
    }
}

/// `announce` publishes the node (namespace and name) with the GUIDs of its readers and
/// writers on `ros_discovery_info`, as ROS 2's graph reads it.
fn the_node_is_announced_on_ros_discovery_info(c: &Case) {
    if c.engine == EngineKind::Zenoh {
        return the_node_is_announced_by_its_tokens(c);
    }
    let announced = AnnouncedNode::open(c);
    let observer = c.raw_cyclone("graph");

    let infos = Arc::new(Mutex::new(Vec::<Vec<u8>>::new()));
    let into = infos.clone();
    let latched = Qos {
        reliability: Reliability::Reliable,
        history: History::KeepLast(1),
        durability: Durability::TransientLocal { depth: 1 },
        ownership: Ownership::Shared,
        lifespan: None,
    };
    let sink: Sink = Arc::new(move |_, data| {
        if let engine::Data::Raw(raw) = data {
            lock(&into).push(raw.to_vec());
        }
    });
    observer.raw_reader("ros_discovery_info", &TopicType::stock(DISCOVERY_TYPE), &latched, sink).unwrap();

    let (w, r) = announced.endpoints_seen_by(&observer);
    let node = &announced.node;
    let want = format!("conf_{}_announced_node", c.number);
    let info = until_some("the node on ros_discovery_info", || {
        node.announce().unwrap();
        lock(&infos).iter().filter_map(|raw| ParticipantInfo::parse(raw)).find(|i| {
            i.participant[..12] == node.own_peer().0[..12]
                && i.nodes.iter().any(|n| n.name == want && n.writers.contains(&w.gid) && n.readers.contains(&r.gid))
        })
    });
    let n = info.nodes.iter().find(|n| n.name == want).unwrap();
    assert_eq!(n.namespace, "/conformance");
}

/// A served service answers each request in its client's wire form (docs/ros2.md, "Wire
/// forms"). A client in rmw_cyclonedds's form (a Cyclone participant writing
/// `rq/NAMERequest` with the request header and reading `rr/NAMEReply`) gets the response
/// with its header echoed, whatever the engine; the request reaches the engine's sink past its
/// header, with its client's peer and byte order; and the response, held until the client's
/// reply reader has matched, reaches the client.
fn a_service_answers_each_request_in_its_clients_form(c: &Case) {
    if c.engine == EngineKind::Zenoh {
        return a_service_answers_a_query_in_rmw_zenohs_form(c);
    }
    let server = c.open("server");
    let client = c.raw_cyclone("client");
    let Served { name, seen, rx, mut responder } = Served::on(c, server.as_ref());

    let q = Qos {
        reliability: Reliability::Reliable,
        history: History::KeepLast(10),
        durability: Durability::Volatile,
        ownership: Ownership::Shared,
        lifespan: None,
    };
    let replies = Arc::new(Mutex::new(Vec::<Vec<u8>>::new()));
    let into = replies.clone();
    let on_reply: Sink = Arc::new(move |_, data| {
        if let engine::Data::Raw(raw) = data {
            lock(&into).push(raw.to_vec());
        }
    });
    let relative = name.trim_start_matches('/');
    let (rq_ty, rr_ty) = (TopicType::plain(ECHO_REQUEST), TopicType::plain(ECHO_RESPONSE));
    client.raw_reader(&format!("rr/{relative}Reply"), &rr_ty, &q, on_reply).unwrap();
    let mut w = client.raw_writer(&format!("rq/{relative}Request"), &rq_ty, &q).unwrap();
    let request = |sequence: i64| [&77u64.to_le_bytes()[..], &sequence.to_le_bytes(), &41u64.to_le_bytes()].concat();
    // A request written before the server has matched the client's writer may reach nobody.
    let mut sequence = 0;
    let to = until_some("a request at the server", || {
        sequence += 1;
        assert!(w.write(&request(sequence)), "the client's writer refused a request");
        w.flush();
        rx.try_recv().ok()
    });
    let (from, le, body) = lock(&seen)[0].clone();
    assert_eq!(from.peer, client.own_peer(), "the request comes with its client's peer");
    assert_eq!(from.gid[..2], [0x01, 0x10], "Cyclone's vendor id heads its GUIDs: rmw_cyclonedds's form");
    assert!(le, "the client wrote little-endian");
    assert_eq!(body, 41u64.to_le_bytes(), "the request's body, past its header");

    responder.respond(&to, &42u64.to_le_bytes());
    let reply = until_some("the response at the client", || lock(&replies).first().cloned());
    let (le, body) = split_header(&reply).unwrap();
    assert!(le, "a response is little-endian");
    assert_eq!(body.len(), 24, "the echoed header, then the response's body: {body:?}");
    assert_eq!(body[..8], 77u64.to_le_bytes(), "the client's id echoed");
    let answered = i64::from_le_bytes(body[8..16].try_into().unwrap());
    assert!((1..=sequence).contains(&answered), "the request's sequence number echoed: {answered}");
    assert_eq!(body[16..], 42u64.to_le_bytes());
}

/// On Zenoh the graph is the liveliness tokens (`@ros2_lv/…`): the node's own, and one for
/// each of its endpoints, whose key's hash is the endpoint's GID, as a raw Zenoh session
/// reads them.
fn the_node_is_announced_by_its_tokens(c: &Case) {
    use ::zenoh::Wait;
    use tutti_engine::rmw_zenoh::{gid_of_key, Entity, EntityKind as Kind};
    let announced = AnnouncedNode::open(c);
    let observer = c.open("graph");

    let (w, r) = announced.endpoints_seen_by(observer.as_ref());
    let AnnouncedNode { node, wt, rt, .. } = &announced;
    let raw = c.router.as_ref().expect("a router").session();
    let want = format!("conf_{}_announced_node", c.number);
    until("the node's tokens, read by a raw Zenoh session", || {
        let Ok(replies) = raw.liveliness().get(format!("@ros2_lv/{}/**", c.domain)).wait() else { return false };
        let mut tokens = Vec::new();
        while let Ok(reply) = replies.recv() {
            if let Ok(sample) = reply.result() {
                let key = sample.key_expr().as_str();
                if let Ok(e) = Entity::parse(key) {
                    tokens.push((e, gid_of_key(key)));
                }
            }
        }
        let of_node: Vec<_> = tokens.iter().filter(|(e, _)| e.zid.to_le_bytes() == node.own_peer().0).collect();
        let named = of_node
            .iter()
            .any(|(e, _)| e.kind == Kind::Node && e.node.name == want && e.node.namespace == "/conformance");
        let writer = of_node.iter().any(|(e, g)| matches!(&e.kind, Kind::Publisher(t) if t.name == *wt) && *g == w.gid);
        let reader =
            of_node.iter().any(|(e, g)| matches!(&e.kind, Kind::Subscription(t) if t.name == *rt) && *g == r.gid);
        named && writer && reader
    });
}

/// On Zenoh a client is a querier (a raw Zenoh session here, in rmw_zenoh's form: its
/// client token first, then each request as a query on the service's key with the CDR
/// request and the attachment): the request reaches the sink with the client's GID and peer,
/// past its encapsulation header, and the response comes back as the reply, with the
/// request's sequence number and the client's GID in its attachment.
fn a_service_answers_a_query_in_rmw_zenohs_form(c: &Case) {
    use ::zenoh::Wait;
    use tutti_engine::rmw_zenoh::qos::QosProfile;
    use tutti_engine::rmw_zenoh::{gid_of_key, Attachment, Entity, EntityKind as Kind, NodeInfo, TopicInfo};
    let server = c.open("server");
    let Served { name, seen, rx, mut responder } = Served::on(c, server.as_ref());

    let raw = c.router.as_ref().expect("a router").session();
    let client = Entity {
        zid: raw.zid().to_string().parse().unwrap(),
        node_id: 0,
        entity_id: 1,
        node: NodeInfo {
            domain_id: u64::from(c.domain),
            namespace: "/conformance".into(),
            name: format!("conf_{}_client", c.number),
            enclave: "/".into(),
        },
        kind: Kind::Client(TopicInfo {
            name: name.clone(),
            type_name: "conformance::srv::dds_::Echo_".into(),
            type_hash: format!("RIHS01_{}", "0".repeat(64)),
            qos: QosProfile::ZENOH_DEFAULT,
        }),
    };
    let token_key = client.to_key().unwrap();
    let gid = gid_of_key(&token_key);
    let _token = raw.liveliness().declare_token(&token_key).wait().unwrap();
    let key = client.data_key().unwrap().to_keyexpr().unwrap();
    let request = [&HEADER_LE[..], &41u64.to_le_bytes()].concat();
    // A query sent before the router knows the queryable reaches nobody: ask again.
    let mut sequence = 0;
    let (to, replies) = until_some("a request at the server", || {
        sequence += 1;
        let a = Attachment { sequence_number: sequence, source_timestamp: 1, source_gid: gid };
        let replies = raw.get(&key).payload(request.clone()).attachment(a.encode().to_vec()).wait().unwrap();
        rx.recv_timeout(Duration::from_millis(500)).ok().map(|to| (to, replies))
    });
    let (from, le, body) = lock(&seen).last().cloned().unwrap();
    assert_eq!(from.gid, gid, "the request comes with its client's GID");
    assert_eq!(from.peer.0, raw.zid().to_le_bytes(), "and its client's session");
    assert!(le, "the client wrote little-endian");
    assert_eq!(body, 41u64.to_le_bytes(), "the request's body, past its encapsulation header");

    responder.respond(&to, &42u64.to_le_bytes());
    let reply = replies.recv_timeout(PATIENCE).ok().flatten().expect("a reply to the query");
    let sample = reply.result().expect("a reply, not an error");
    let payload = sample.payload().to_bytes();
    let (le, body) = split_header(&payload).unwrap();
    assert!(le, "a response is little-endian");
    assert_eq!(body, 42u64.to_le_bytes(), "the response's body, no request header on Zenoh");
    let a = Attachment::decode(&sample.attachment().expect("an attachment").to_bytes()).unwrap();
    assert_eq!((a.sequence_number, a.source_gid), (sequence, gid), "the request's sequence number and client");
}

// ---------------------------------------------------------------------------------------
// The test's own means.

/// A node of the engine under test with a writer on `wt` and a reader on `rt`, announced.
struct AnnouncedNode {
    node: Box<dyn Engine>,
    wt: String,
    rt: String,
    _writer: Box<dyn Writer>,
}

impl AnnouncedNode {
    fn open(c: &Case) -> AnnouncedNode {
        let (codec, _) = set_codec();
        let node = c.open("announced_node");
        let (wt, rt) = (c.topic("node_out"), c.topic("node_in"));
        let q = qos(Reliability::Reliable, History::KeepLast(1), false, Ownership::Shared);
        let _writer = node.writer(&wt, &TopicType::plain(SET_TYPE), &q).unwrap();
        node.reader(&rt, &TopicType::plain(SET_TYPE), &q, Decode::Set(codec), Arc::new(|_, _| {})).unwrap();
        node.announce().unwrap();
        AnnouncedNode { node, wt, rt, _writer }
    }

    /// Its writer and reader, once `observer`'s discovery lists them.
    fn endpoints_seen_by(&self, observer: &dyn Engine) -> (EndpointId, EndpointId) {
        let mine = |g: &EndpointId| g.peer == self.node.own_peer();
        until_some("the node's endpoints in discovery", || {
            let rem = observer.remote();
            let w = rem.writers_on(&self.wt).find(mine)?;
            let r = *rem.readers_on(std::slice::from_ref(&self.rt)).iter().find(|g| mine(g))?;
            Some((w, r))
        })
    }
}

/// The scenarios' echo service served by an engine: each request as its sink saw it (client,
/// byte order, body) and its `ReplyTo`, and the responder.
/// A request as a sink saw it: its client, its byte order, its body.
type Seen = (EndpointId, bool, Vec<u8>);

struct Served {
    name: String,
    seen: Arc<Mutex<Vec<Seen>>>,
    rx: std::sync::mpsc::Receiver<engine::ReplyTo>,
    responder: Box<dyn engine::Responder>,
}

impl Served {
    fn on(c: &Case, server: &dyn Engine) -> Served {
        let name = c.topic("echo");
        let (rq_ty, rr_ty) = (TopicType::plain(ECHO_REQUEST), TopicType::plain(ECHO_RESPONSE));
        let seen = Arc::new(Mutex::new(Vec::new()));
        let (tx, rx) = std::sync::mpsc::channel::<engine::ReplyTo>();
        let tap = seen.clone();
        let tx = Mutex::new(tx);
        let sink = Arc::new(move |r: Request<'_>| {
            lock(&tap).push((r.client, r.little_endian, r.body.to_vec()));
            let _ = lock(&tx).send(r.reply_to);
        });
        let service = Service { name: &name, request: &rq_ty, response: &rr_ty };
        let responder = server.serve(&service, sink).unwrap();
        Served { name, seen, rx, responder }
    }
}

const SET_TYPE: &str = "conformance::msg::dds_::Set_";
const DISCOVERY_TYPE: &str = "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_";
const ECHO_REQUEST: &str = "conformance::srv::dds_::Echo_Request_";
const ECHO_RESPONSE: &str = "conformance::srv::dds_::Echo_Response_";

/// One scenario on one engine.
struct Case {
    engine: EngineKind,
    number: u16,
    domain: u16,
    /// The Zenoh router the scenario's Zenoh sessions meet at (Zenoh only).
    router: Option<ZenohRouter>,
}

impl Case {
    /// A participant of the engine under test, on loopback.
    fn open(&self, node: &str) -> Box<dyn Engine> {
        self.open_kind(self.engine, node)
    }

    /// A peer that writes any encapsulation as it is given: a Cyclone participant for a DDS
    /// engine, another session of the engine for Zenoh (which writes serialized samples as
    /// they are).
    fn peer_raw(&self, node: &str) -> Box<dyn Engine> {
        match self.engine {
            EngineKind::Zenoh => self.open(node),
            _ => self.open_kind(EngineKind::Cyclone, node),
        }
    }

    /// A Cyclone participant whose DDS topics the scenario names itself (`ros_discovery_info`,
    /// a service's `rq/` and `rr/` topics).
    fn raw_cyclone(&self, node: &str) -> Cyclone {
        match Cyclone::open(&self.config(node)) {
            Ok(e) => e,
            Err(e) => panic!("cyclone participant in DDS domain {}: {e}", self.domain),
        }
    }

    fn config(&self, node: &str) -> EngineConfig {
        EngineConfig {
            domain_id: self.domain,
            interfaces: vec![[127, 0, 0, 1].into()],
            peers: Vec::new(),
            node_name: format!("conf_{}_{node}", self.number),
            node_namespace: "/conformance".into(),
            participant_lease: None,
            zenoh_connect: self.router.iter().map(|r| r.endpoint().to_string()).collect(),
            zenoh_listen: if self.router.is_some() { vec!["tcp/127.0.0.1:0".into()] } else { Vec::new() },
            security: None,
        }
    }

    fn open_kind(&self, kind: EngineKind, node: &str) -> Box<dyn Engine> {
        match engine::open(kind, &self.config(node)) {
            Ok(e) => e,
            Err(e) => panic!("{kind} participant in DDS domain {}: {e}", self.domain),
        }
    }

    /// A topic of this scenario.
    fn topic(&self, what: &str) -> String {
        format!("/conformance/s{}/{what}", self.number)
    }
}

/// Runs scenario number `n` on `engine` under a watchdog that stops the test binary if the
/// scenario hangs (a hang inside DDS cannot be interrupted from another thread).
fn run(engine: EngineKind, n: u16, scenario: fn(&Case)) {
    struct Done(Arc<AtomicBool>);
    impl Drop for Done {
        fn drop(&mut self) {
            self.0.store(true, Ordering::Release);
        }
    }
    let done = Arc::new(AtomicBool::new(false));
    let flag = done.clone();
    std::thread::spawn(move || {
        if tutti_test_support::poll_for(WATCHDOG, || flag.load(Ordering::Acquire).then_some(())).is_none() {
            eprintln!("watchdog: the {engine} scenario {n} hangs; stopping the conformance suite");
            std::process::abort();
        }
    });
    let _done = Done(done);
    // 20 domains per engine, by its place in the list of engines.
    let base = 60 + 20 * engine.index() as u16;
    let router = (engine == EngineKind::Zenoh).then(ZenohRouter::start);
    scenario(&Case { engine, number: n, domain: base + n, router });
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Calls `f` until it is true; fails naming `what` after [`PATIENCE`].
fn until(what: &str, mut f: impl FnMut() -> bool) {
    until_some(what, || f().then_some(()))
}

fn until_some<T>(what: &str, f: impl FnMut() -> Option<T>) -> T {
    tutti_test_support::wait_for(format_args!("gave up waiting for {what}"), PATIENCE, f)
}

fn qos(reliability: Reliability, history: History, transient_local: bool, ownership: Ownership) -> Qos {
    let durability = if transient_local { Durability::TransientLocal { depth: 1 } } else { Durability::Volatile };
    Qos { reliability, history, durability, ownership, lifespan: None }
}

/// The codec and layout of the scenarios' set: elements of every alignment, an array.
fn set_codec() -> (Arc<SetCodec>, SetLayout) {
    let items = r#"<item name="a"><type>boolean</type></item>
        <item name="s"><type>int16</type></item>
        <item name="x"><type>double</type></item>
        <item name="v"><type>double</type><length>3</length></item>
        <item name="f"><type>float32</type></item>"#;
    let ddf = format!(
        r#"<orchestra><domain name="d"><synchronous>no</synchronous><multiplePublishAllowed>no</multiplePublishAllowed>
           <states>no</states><block name="d/Publish">{items}</block></domain></orchestra>"#
    );
    let model = parse_str(&ddf, "conformance.ddf").unwrap();
    let layout = model.domains[0].publish.layout.clone();
    (Arc::new(SetCodec::new(&layout)), layout)
}

/// A sample of the set for `step`, every leaf set from it.
fn sample(codec: &SetCodec, layout: &SetLayout, step: u64) -> TypedSample {
    let mut data = vec![0u8; codec.shm_size()];
    let mut put = |path: &str, bytes: &[u8]| {
        let leaf: &Leaf = layout.leaf(path).unwrap();
        data[leaf.range()].copy_from_slice(bytes);
    };
    let k = step as f64;
    put("a", &[u8::from(step % 2 == 1)]);
    put("s", &(-(step as i16)).to_ne_bytes());
    put("x", &(k * 0.5).to_ne_bytes());
    put("v", &[k, -k, k / 8.0].iter().flat_map(|v| v.to_ne_bytes()).collect::<Vec<_>>());
    put("f", &(k as f32 * 0.25).to_ne_bytes());
    TypedSample { step, sim_time: k / 100.0, data }
}

/// The little-endian CDR body `le` of the set in big-endian: every element reversed in place.
fn big_endian(codec: &SetCodec, le: &[u8]) -> Vec<u8> {
    let mut be = le.to_vec();
    be[0..8].reverse();
    be[8..16].reverse();
    for f in codec.fields() {
        let size = f.ty.size() as usize;
        be[f.cdr..f.cdr + size * f.count].chunks_exact_mut(size).for_each(<[u8]>::reverse);
    }
    be
}

/// A big-endian `Float64` (one value, `array` false) or `Float64MultiArray` body.
fn stock_big_endian(values: &[f64], array: bool) -> Vec<u8> {
    if !array {
        return values[0].to_be_bytes().to_vec();
    }
    let mut out = Vec::new();
    out.extend_from_slice(&0u32.to_be_bytes()); // no dimensions
    out.extend_from_slice(&0u32.to_be_bytes()); // data_offset
    out.extend_from_slice(&(values.len() as u32).to_be_bytes());
    out.extend_from_slice(&[0; 4]); // the doubles are aligned to 8
    for v in values {
        out.extend_from_slice(&v.to_be_bytes());
    }
    out
}

/// What a reader received, decoded.
struct Inbox {
    decode: Decode,
    got: Mutex<Vec<(EndpointId, Result<Payload, CdrError>)>>,
}

impl Inbox {
    fn new(decode: Decode) -> Arc<Inbox> {
        Arc::new(Inbox { decode, got: Mutex::new(Vec::new()) })
    }

    fn sink(self: &Arc<Self>) -> Sink {
        let me = self.clone();
        Arc::new(move |g, data| {
            let p = data.into_payload(&me.decode);
            lock(&me.got).push((g, p));
        })
    }

    fn len(&self) -> usize {
        lock(&self.got).len()
    }

    /// The steps of the typed samples received, in order.
    fn steps(&self) -> Vec<u64> {
        lock(&self.got)
            .iter()
            .filter_map(|(_, p)| match p {
                Ok(Payload::Set(s)) => Some(s.step),
                _ => None,
            })
            .collect()
    }

    /// Writes with `write` until `want` has arrived, decoded without error; the GUID of its
    /// writer. A sample that fails to decode fails the test.
    fn until_payload(
        &self,
        what: &str,
        w: &mut dyn Writer,
        want: &Payload,
        mut write: impl FnMut(&mut dyn Writer) -> bool,
    ) -> EndpointId {
        until_some(what, || {
            assert!(write(w), "{what}: the writer refused it");
            w.flush();
            let got = lock(&self.got);
            if let Some((_, Err(e))) = got.iter().find(|(_, p)| p.is_err()) {
                panic!("{what}: a sample failed to decode: {e}");
            }
            got.iter().find(|(_, p)| p.as_ref() == Ok(want)).map(|(g, _)| *g)
        })
    }
}

/// `rmw_dds_common::msg::ParticipantEntitiesInfo` as ROS 2 Iron and later write it (16-byte gids).
struct ParticipantInfo {
    participant: [u8; 16],
    nodes: Vec<NodeInfo>,
}

struct NodeInfo {
    namespace: String,
    name: String,
    readers: Vec<[u8; 16]>,
    writers: Vec<[u8; 16]>,
}

/// A cursor over a CDR body.
struct Cursor<'a> {
    b: &'a [u8],
    pos: usize,
    le: bool,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, align: usize) -> Option<&'a [u8]> {
        self.pos = self.pos.next_multiple_of(align);
        let s = self.b.get(self.pos..self.pos + n)?;
        self.pos += n;
        Some(s)
    }

    fn u32(&mut self) -> Option<u32> {
        let a: [u8; 4] = self.take(4, 4)?.try_into().ok()?;
        Some(if self.le { u32::from_le_bytes(a) } else { u32::from_be_bytes(a) })
    }

    fn string(&mut self) -> Option<String> {
        let len = self.u32()? as usize;
        let s = self.take(len, 1)?;
        Some(String::from_utf8_lossy(s.strip_suffix(&[0]).unwrap_or(s)).into_owned())
    }

    fn guid(&mut self) -> Option<[u8; 16]> {
        self.take(16, 1)?.try_into().ok()
    }

    fn guids(&mut self) -> Option<Vec<[u8; 16]>> {
        let n = self.u32()?;
        (0..n.min(4096)).map(|_| self.guid()).collect()
    }
}

impl ParticipantInfo {
    /// Reads a serialized sample (either byte order); None if it is not one.
    fn parse(raw: &[u8]) -> Option<ParticipantInfo> {
        let (le, b) = split_header(raw).ok()?;
        let mut c = Cursor { b, pos: 0, le };
        let participant = c.guid()?;
        let n = c.u32()?;
        let mut nodes = Vec::new();
        for _ in 0..n.min(64) {
            let (namespace, name) = (c.string()?, c.string()?);
            let (readers, writers) = (c.guids()?, c.guids()?);
            nodes.push(NodeInfo { namespace, name, readers, writers });
        }
        Some(ParticipantInfo { participant, nodes })
    }
}
