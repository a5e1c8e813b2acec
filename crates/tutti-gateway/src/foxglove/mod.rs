//! The Foxglove WebSocket server (`--foxglove ADDR`, docs/gateway.md "Foxglove"): the same
//! bridged sets as on DDS, live, for Foxglove, Lichtblick and any client of the Foxglove
//! WebSocket protocol.
//!
//! * one channel per bridged set, on its ROS 2 topic name, `cdr` encoding, with the
//!   `ros2msg` schema of the MCAP recordings (`tutti_ros2::idl::ros2msg`); messages and the
//!   server's `time` carry simulated time;
//! * the connection graph lists each domain's framework and participants;
//! * a client that advertises a SUBSCRIBE set's topic writes it through a shared-memory
//!   connection of its own, as a DDS writer does (`routes::from_dds::RemoteWriter`), so the
//!   core's rules (exclusivity, seeding, lock-step) apply to it unchanged;
//! * services `/tutti/pause`, `/tutti/resume`, `/tutti/step` and `/tutti/state` call the
//!   run's control plane (`tutti_host::control`).
//!
//! The handshake accepts the protocol under both its names ([`protocol::SUBPROTOCOLS`]) and
//! refuses any other request with 400. The server runs on the manager's runtime (each
//! client a task: `session`); shared memory is read by the follower's thread ([`follow`]),
//! a control call runs on the runtime's blocking pool, and a client's sample is committed
//! as a DDS writer's is (where that could wait, by its connection's own thread).

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, AtomicUsize};
use std::sync::Arc;
use std::thread::JoinHandle;

use axum::extract::ws::WebSocketUpgrade;
use axum::extract::State;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::routing::any;
use tokio::sync::{broadcast, watch};
use tracing::warn;
use tutti_core::cdr::SetCodec;
use tutti_core::ddf::Role;
use tutti_core::mapping;
use tutti_ros2::idl::ros2msg;

pub use self::config::FoxgloveKeys;
use crate::config::PlannedSet;
use crate::routes::{Counters, ShmConfig};
use crate::{GatewayError, GatewayOptions};

mod config;
pub mod follow;
pub mod protocol;
mod session;

/// The default address of `--foxglove` given without one.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8765";

/// What a channel carries: a bridged set, or the entities' poses (`/tf`).
#[derive(Debug)]
pub(crate) enum Source {
    Set { domain: usize, role: Role, codec: Arc<SetCodec> },
    Poses,
}

/// One channel: a bridged set, or `/tf`.
#[derive(Debug)]
pub(crate) struct ChannelInfo {
    /// Its id on the protocol (its index in [`Shared::channels`] plus 1).
    pub id: u32,
    pub source: Source,
    /// The ROS 2 topic name, as on DDS.
    pub topic: String,
    pub schema_name: String,
    /// Subscriptions to it now, over all clients: the follower reads only subscribed sets.
    pub subscribers: AtomicUsize,
    /// Bumped by each new subscription: the follower then sends the current value again, so
    /// that a new subscriber of a set that does not change gets it.
    pub epoch: AtomicU64,
    /// The set's counters (client samples count as DDS samples do).
    pub counters: Counters,
}

/// A domain as the server needs it.
#[derive(Debug)]
pub(crate) struct DomainInfo {
    pub name: String,
    pub synchronous: bool,
}

/// What the sessions and the follower share.
#[derive(Debug)]
pub(crate) struct Shared {
    pub channels: Vec<ChannelInfo>,
    pub domains: Vec<DomainInfo>,
    /// The entities (their poses go out on `/tf`) and the DDF they are of.
    pub entities: Vec<crate::config::Entity>,
    pub model: tutti_core::ddf::Model,
    pub cfg: ShmConfig,
    /// The messages every session sends first.
    pub advertise: String,
    pub services: String,
    pub server_name: String,
    pub metadata: BTreeMap<String, String>,
    /// Numbers the clients (their connections' names).
    pub next_client: AtomicU64,
    /// The gateway's node, which provides the services in the graph.
    pub node: String,
    pub out: broadcast::Sender<follow::Out>,
    pub graph: watch::Receiver<follow::Graph>,
}

/// The services, by id: name, type, request schema (JSON schema).
pub(crate) const SERVICES: [(u32, &str, &str, &str); 4] = [
    (1, "/tutti/pause", "tutti/Pause", r#"{"type":"object","properties":{}}"#),
    (2, "/tutti/resume", "tutti/Resume", r#"{"type":"object","properties":{}}"#),
    (
        3,
        "/tutti/step",
        "tutti/Step",
        r#"{"type":"object","properties":{"n":{"type":"integer","minimum":1,"description":"steps to make (default 1)"}}}"#,
    ),
    (4, "/tutti/state", "tutti/State", r#"{"type":"object","properties":{}}"#),
];

/// The schema of every service's response: the run's state after the call.
const RESPONSE_SCHEMA: &str = r#"{"type":"object","properties":{"state":{"type":"string","enum":["ready","playing","paused","stopped"]},"step":{"type":"integer"},"sim_time":{"type":"number"},"namespace":{"type":"string"},"pid":{"type":"integer"}}}"#;

fn services() -> Vec<protocol::Service> {
    let def = |name: &str, schema: &str| protocol::MessageDef {
        encoding: "json".into(),
        schema_name: name.into(),
        schema_encoding: "jsonschema".into(),
        schema: schema.into(),
    };
    SERVICES
        .iter()
        .map(|&(id, name, ty, request)| protocol::Service {
            id,
            name: name.into(),
            ty: ty.into(),
            request: def(&format!("{ty}_Request"), request),
            response: def(&format!("{ty}_Response"), RESPONSE_SCHEMA),
            request_schema: request.into(),
            response_schema: RESPONSE_SCHEMA.into(),
        })
        .collect()
}

/// How many messages a slow client may fall behind before it misses some.
const BACKLOG: usize = 4096;

/// Starts the server on `addr` for the sets `plan` of `opts` (each with its counters in
/// `counters`, then those of the entities' `/tf`), on runtime `rt`; the follower's thread ends with the gateway (`cfg.stop`),
/// the sessions with the runtime. Returns the follower's thread and the address bound
/// (port 0: one the system chose).
pub(crate) fn serve(
    addr: SocketAddr,
    rt: &tokio::runtime::Runtime,
    opts: &GatewayOptions,
    plan: &[PlannedSet],
    counters: Vec<Counters>,
    cfg: ShmConfig,
    time_domain: Option<usize>,
) -> Result<(JoinHandle<()>, SocketAddr), GatewayError> {
    let package = mapping::package_name(&opts.ddf_path);
    let defs = ros2msg::message_definitions(&opts.model, &package)?;
    let mut channels = Vec::with_capacity(plan.len());
    let mut advertised = Vec::with_capacity(plan.len());
    let mut counters = counters.into_iter();
    for (i, (p, counters)) in plan.iter().zip(counters.by_ref()).enumerate() {
        let d = &opts.model.domains[p.domain];
        let schema = ros2msg::set_schema(&defs, &package, &d.name, p.role)?;
        let id = i as u32 + 1;
        advertised.push(protocol::Channel {
            id,
            topic: p.ros2_topic.clone(),
            encoding: "cdr".into(),
            schema_name: schema.name.clone(),
            schema: schema.text,
            schema_encoding: "ros2msg".into(),
        });
        channels.push(ChannelInfo {
            id,
            source: Source::Set {
                domain: p.domain,
                role: p.role,
                codec: Arc::new(SetCodec::new(&d.set(p.role).layout)),
            },
            topic: p.ros2_topic.clone(),
            schema_name: schema.name,
            subscribers: AtomicUsize::new(0),
            epoch: AtomicU64::new(0),
            counters,
        });
    }
    // The entities' poses: `/tf`, for the 3D panel.
    if let (false, Some(counters)) = (opts.entities.is_empty(), counters.next()) {
        let id = channels.len() as u32 + 1;
        let tf = tutti_ros2::simulation::entities::tf_message();
        let topic = tutti_ros2::names::under(&opts.ros_namespace, tutti_ros2::simulation::entities::TF_TOPIC);
        advertised.push(protocol::Channel {
            id,
            topic: topic.clone(),
            encoding: "cdr".into(),
            schema_name: tf.name().to_string(),
            schema: ros2msg::message_schema(tf),
            schema_encoding: "ros2msg".into(),
        });
        channels.push(ChannelInfo {
            id,
            source: Source::Poses,
            topic,
            schema_name: tf.name().to_string(),
            subscribers: AtomicUsize::new(0),
            epoch: AtomicU64::new(0),
            counters,
        });
    }
    let domains = opts
        .model
        .domains
        .iter()
        .map(|d| DomainInfo { name: d.name.clone(), synchronous: d.flags.synchronous })
        .collect();
    let listener = std::net::TcpListener::bind(addr)
        .and_then(|l| l.set_nonblocking(true).map(|()| l))
        .map_err(|error| GatewayError::FoxgloveListen { addr, error })?;
    let bound = listener.local_addr().map_err(|error| GatewayError::FoxgloveListen { addr, error })?;
    let listener = {
        let _in_rt = rt.enter();
        tokio::net::TcpListener::from_std(listener).map_err(|error| GatewayError::FoxgloveListen { addr, error })?
    };
    let (out, _) = broadcast::channel(BACKLOG);
    let (graph_tx, graph) = watch::channel(follow::Graph::default());
    let metadata = BTreeMap::from([
        ("namespace".to_string(), opts.namespace.clone()),
        ("ros_namespace".to_string(), opts.ros_namespace.clone()),
        ("package".to_string(), package),
    ]);
    let shared = Arc::new(Shared {
        channels,
        domains,
        entities: opts.entities.clone(),
        model: opts.model.clone(),
        cfg,
        advertise: protocol::ServerMessage::Advertise { channels: &advertised }.to_text(),
        services: protocol::ServerMessage::AdvertiseServices { services: &services() }.to_text(),
        server_name: format!("tutti gateway ({})", opts.node_name),
        metadata,
        next_client: AtomicU64::new(1),
        node: config_node(opts),
        out: out.clone(),
        graph,
    });
    let thread =
        follow::spawn(shared.clone(), out, graph_tx, time_domain).map_err(|e| GatewayError::Thread("a thread", e))?;
    let app = axum::Router::new().route("/", any(upgrade)).with_state(shared);
    rt.spawn(async move {
        if let Err(e) = axum::serve(listener, app).await {
            warn!("the Foxglove server stopped: {e}");
        }
    });
    Ok((thread, bound))
}

fn config_node(opts: &GatewayOptions) -> String {
    tutti_ros2::names::under(&opts.ros_namespace, &opts.node_name)
}

/// The subprotocol of ours that a client offered (the first of ours, in our order).
pub fn chosen_subprotocol<'a>(offered: impl IntoIterator<Item = &'a str>) -> Option<&'static str> {
    let offered: Vec<&str> = offered.into_iter().flat_map(|h| h.split(',')).map(str::trim).collect();
    protocol::SUBPROTOCOLS.into_iter().find(|p| offered.contains(p))
}

/// The WebSocket handshake: upgraded with one of the protocol's names, else 400.
async fn upgrade(State(shared): State<Arc<Shared>>, ws: WebSocketUpgrade) -> Response {
    let chosen = chosen_subprotocol(ws.requested_protocols().filter_map(|h| h.to_str().ok()));
    let Some(chosen) = chosen else {
        let msg = format!("offer the WebSocket subprotocol {}", protocol::SUBPROTOCOLS.join(" or "));
        return (StatusCode::BAD_REQUEST, msg).into_response();
    };
    ws.protocols([chosen]).on_upgrade(move |socket| session::run(socket, shared))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_names_of_the_protocol_and_no_other() {
        assert_eq!(chosen_subprotocol(["foxglove.websocket.v1"]), Some("foxglove.websocket.v1"));
        assert_eq!(chosen_subprotocol(["foxglove.sdk.v1"]), Some("foxglove.sdk.v1"));
        assert_eq!(chosen_subprotocol(["x, foxglove.sdk.v1"]), Some("foxglove.sdk.v1"));
        assert_eq!(chosen_subprotocol(["foxglove.sdk.v1.1"]), None);
        assert_eq!(chosen_subprotocol(["foxglove.sdk.v2", "graphql-ws"]), None);
        assert_eq!(chosen_subprotocol([]), None);
    }
}
