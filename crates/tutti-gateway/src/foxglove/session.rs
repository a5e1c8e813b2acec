//! One client of the Foxglove server: a task on the manager's runtime that sends the
//! follower's messages for the client's subscriptions, the simulated time and the
//! connection graph, commits what the client publishes through a connection per
//! advertised channel, and answers service calls and playback requests from the control plane
//! (called on the runtime's blocking pool, so that a `step N` does not hold up the session).

use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use axum::extract::ws::{Message, WebSocket};
use tokio::sync::{broadcast, mpsc};
use tracing::{debug, info};
use tutti_core::ddf::Role;
use tutti_host::control::{ControlClient, ControlError, Request, RunState, RunStatus};

use super::follow::{Graph, Out};
use super::protocol::{
    self, ClientBinary, ClientMessage, GraphService, GraphTopic, Level, PlaybackCommand, PlaybackStatus, ServerMessage,
    Stamp,
};
use super::{Shared, Source, SERVICES};
use crate::routes::from_dds::{RemoteWriter, Sample};

/// How long a service call waits for the run's answer (a `step N` is answered after N steps).
const CONTROL_TIMEOUT: Duration = Duration::from_secs(60);

/// A channel the client advertised: the set it writes and its connection.
struct Publishing {
    channel: usize,
    codec: Arc<tutti_core::cdr::SetCodec>,
    writer: RemoteWriter,
}

/// A service call's outcome: service, call, and the JSON answer or why there is none.
type CallResult = (u32, u32, Result<Vec<u8>, String>);

struct Session {
    sh: Arc<Shared>,
    /// The client's number (its connections' names).
    number: u64,
    /// Subscription id -> channel index.
    subs: HashMap<u32, usize>,
    /// Client channel id -> what it writes.
    publishing: HashMap<u32, Publishing>,
    /// The graph last sent, while the client follows it.
    graph: Option<Graph>,
    /// The playback speed the client asked last (Foxglove's controls start at 1): every
    /// request carries one, and only a change of it changes the run's speed.
    speed: f32,
}

pub(crate) async fn run(mut ws: WebSocket, sh: Arc<Shared>) {
    let number = sh.next_client.fetch_add(1, Ordering::Relaxed);
    info!("Foxglove client {number} connected ({})", ws.protocol().and_then(|p| p.to_str().ok()).unwrap_or("?"));
    let mut s =
        Session { sh: sh.clone(), number, subs: HashMap::new(), publishing: HashMap::new(), graph: None, speed: 1.0 };
    let mut out = sh.out.subscribe();
    let mut graph = sh.graph.clone();
    let (calls_tx, mut calls) = mpsc::unbounded_channel::<CallResult>();
    let (playback_tx, mut playback) = mpsc::unbounded_channel::<Vec<Message>>();
    // Playback control where there is a run to control: its range is the run's, from 0 to its
    // end (or a day of simulated time after now, for a run without an end).
    let ns = sh.cfg.namespace.clone();
    let run = tokio::task::spawn_blocking(move || ControlClient::connect(&ns, PROBE_TIMEOUT)?.state()).await;
    let range = run.ok().and_then(Result::ok).map(|st| {
        let end = st.end_time.unwrap_or(st.sim_time + DAY);
        (Stamp::of_ns(0), Stamp::of_ns(protocol::sim_ns(end)))
    });
    let mut capabilities = vec!["clientPublish", "services", "connectionGraph", "time"];
    if range.is_some() {
        capabilities.push("playbackControl");
    }
    let info = ServerMessage::ServerInfo {
        name: &sh.server_name,
        capabilities: &capabilities,
        supported_encodings: &["cdr", "json"],
        metadata: &sh.metadata,
        session_id: &format!("{}-{number}", std::process::id()),
        data_start_time: range.map(|r| r.0),
        data_end_time: range.map(|r| r.1),
    }
    .to_text();
    let hello = [info, sh.advertise.clone(), sh.services.clone()];
    let mut open = true;
    for text in hello {
        open &= ws.send(Message::Text(text.into())).await.is_ok();
    }
    while open {
        let sent = tokio::select! {
            msg = ws.recv() => match msg {
                Some(Ok(Message::Text(t))) => s.on_text(&mut ws, t.as_str()).await,
                Some(Ok(Message::Binary(b))) => s.on_binary(&mut ws, &b, &calls_tx, &playback_tx).await,
                Some(Ok(Message::Close(_))) | None | Some(Err(_)) => false,
                Some(Ok(_)) => true,
            },
            o = out.recv() => match o {
                Ok(o) => s.on_out(&mut ws, o).await,
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    let msg = format!("{n} messages were not sent: the connection is too slow for the run");
                    send_text(&mut ws, protocol::status(Level::Warning, &msg)).await
                }
                Err(broadcast::error::RecvError::Closed) => false,
            },
            changed = graph.changed() => match changed {
                Ok(()) => {
                    let g = graph.borrow_and_update().clone();
                    s.on_graph(&mut ws, g, false).await
                }
                Err(_) => false,
            },
            Some(frames) = playback.recv() => {
                let mut ok = true;
                for f in frames {
                    ok &= ws.send(f).await.is_ok();
                }
                ok
            }
            Some((service, call, result)) = calls.recv() => {
                let frame = match result {
                    Ok(json) => Message::Binary(protocol::service_response(service, call, "json", &json).into()),
                    Err(message) => Message::Text(ServerMessage::ServiceCallFailure { service_id: service, call_id: call, message: &message }.to_text().into()),
                };
                ws.send(frame).await.is_ok()
            }
        };
        open = sent;
    }
    s.leave();
    info!("Foxglove client {number} left");
}

async fn send_text(ws: &mut WebSocket, text: String) -> bool {
    ws.send(Message::Text(text.into())).await.is_ok()
}

impl Session {
    async fn on_out(&mut self, ws: &mut WebSocket, o: Out) -> bool {
        match o {
            Out::Time(t) => ws.send(Message::Binary(protocol::time(t).into())).await.is_ok(),
            Out::Message { channel, time_ns, data } => {
                let index = channel as usize - 1;
                let subs: Vec<u32> = self.subs.iter().filter(|(_, c)| **c == index).map(|(s, _)| *s).collect();
                for sub in subs {
                    let frame = protocol::message_data(sub, time_ns, &data);
                    if ws.send(Message::Binary(frame.into())).await.is_err() {
                        return false;
                    }
                }
                true
            }
        }
    }

    async fn on_text(&mut self, ws: &mut WebSocket, text: &str) -> bool {
        let msg = match serde_json::from_str::<ClientMessage>(text) {
            Ok(m) => m,
            Err(e) => {
                return send_text(ws, protocol::status(Level::Error, &format!("message not understood: {e}"))).await
            }
        };
        let mut problems = Vec::new();
        match msg {
            ClientMessage::Subscribe { subscriptions } => {
                for sub in subscriptions {
                    let Some(ch) = self.sh.channels.get((sub.channel_id as usize).wrapping_sub(1)) else {
                        problems.push(format!("no channel {}", sub.channel_id));
                        continue;
                    };
                    if let Some(old) = self.subs.insert(sub.id, ch.id as usize - 1) {
                        self.sh.channels[old].subscribers.fetch_sub(1, Ordering::AcqRel);
                    }
                    ch.subscribers.fetch_add(1, Ordering::AcqRel);
                    ch.epoch.fetch_add(1, Ordering::AcqRel);
                }
            }
            ClientMessage::Unsubscribe { subscription_ids } => {
                for id in subscription_ids {
                    if let Some(c) = self.subs.remove(&id) {
                        self.sh.channels[c].subscribers.fetch_sub(1, Ordering::AcqRel);
                    }
                }
            }
            ClientMessage::Advertise { channels } => {
                for c in channels {
                    match self.advertised(&c) {
                        Ok(p) => {
                            self.publishing.insert(c.id, p);
                        }
                        Err(e) => problems.push(e.to_string()),
                    }
                }
            }
            ClientMessage::Unadvertise { channel_ids } => {
                for id in channel_ids {
                    self.publishing.remove(&id);
                }
            }
            ClientMessage::SubscribeConnectionGraph => {
                let g = self.sh.graph.borrow().clone();
                self.graph = Some(Graph::default());
                return self.on_graph(ws, g, true).await;
            }
            ClientMessage::UnsubscribeConnectionGraph => self.graph = None,
            ClientMessage::Other => problems.push(format!("not served: {}", op_of(text))),
        }
        if problems.is_empty() {
            return true;
        }
        send_text(ws, protocol::status(Level::Error, &problems.join("; "))).await
    }

    /// A channel the client advertises: it must be a SUBSCRIBE set's topic, in CDR. It
    /// gets a shared-memory connection of its own, as a DDS writer does.
    fn advertised(&self, c: &protocol::ClientChannel) -> Result<Publishing, Refused> {
        let topic = || c.topic.clone();
        let Some(index) = self.sh.channels.iter().position(|ch| ch.topic == c.topic) else {
            return Err(Refused::NoSuchTopic { topic: topic() });
        };
        let ch = &self.sh.channels[index];
        let codec = match &ch.source {
            Source::Set { role: Role::Subscribe, domain, codec } => (*domain, codec.clone()),
            Source::Set { .. } => return Err(Refused::PublishSet { topic: topic() }),
            Source::Poses => return Err(Refused::Poses { topic: topic() }),
        };
        let (domain, codec) = codec;
        if c.encoding != "cdr" {
            return Err(Refused::Encoding { topic: topic(), given: c.encoding.clone() });
        }
        let d = &self.sh.domains[domain];
        let name = format!("foxglove client {}", self.number);
        let writer = RemoteWriter::spawn(
            d.name.clone(),
            name,
            d.synchronous,
            // A Foxglove client answers the step it is at: no lookahead.
            0,
            self.sh.cfg.clone(),
            ch.counters.clone(),
            // Not the gateway's DDS commits: the set goes on to DDS as a component's would.
            Arc::new(AtomicU64::new(0)),
        )
        .map_err(Refused::Thread)?;
        info!(domain = %d.name, "Foxglove client {} writes {} ({})", self.number, c.topic, ch.schema_name);
        Ok(Publishing { channel: index, codec, writer })
    }

    async fn on_binary(
        &mut self,
        ws: &mut WebSocket,
        b: &[u8],
        calls: &mpsc::UnboundedSender<CallResult>,
        playback: &mpsc::UnboundedSender<Vec<Message>>,
    ) -> bool {
        let problem = match protocol::parse_binary(b) {
            Err(e) => e.to_string(),
            Ok(ClientBinary::MessageData { channel_id, data }) => match self.publishing.get(&channel_id) {
                None => format!("channel {channel_id} was not advertised"),
                Some(p) => {
                    let ch = &self.sh.channels[p.channel];
                    match p.codec.check(data) {
                        Ok((le, body)) => {
                            let _ = p.writer.send(Sample::Encoded { codec: &p.codec, le, body });
                            return true;
                        }
                        Err(e) => {
                            crate::stats::SetStats::add(
                                Some(&ch.counters.set),
                                |s| &s.bad_input,
                                &ch.counters.total.bad_samples,
                                1,
                            );
                            format!("{}: not a {} sample: {e}", ch.topic, ch.schema_name)
                        }
                    }
                }
            },
            Ok(ClientBinary::Playback(req)) => {
                let (tx, ns) = (playback.clone(), self.sh.cfg.namespace.clone());
                let speed = (req.speed != self.speed).then_some(req.speed);
                self.speed = req.speed;
                let req = OwnedPlayback {
                    command: req.command,
                    speed,
                    seek: req.seek,
                    request_id: req.request_id.to_string(),
                };
                tokio::task::spawn_blocking(move || {
                    let _ = tx.send(playback_control(&ns, &req));
                });
                return true;
            }
            Ok(ClientBinary::ServiceCall { service_id, call_id, encoding, data }) => {
                match call(service_id, encoding, data) {
                    Ok(request) => {
                        let (tx, ns) = (calls.clone(), self.sh.cfg.namespace.clone());
                        tokio::task::spawn_blocking(move || {
                            let answer = control(&ns, request).map_err(|e| e.to_string());
                            let _ = tx.send((service_id, call_id, answer));
                        });
                        return true;
                    }
                    Err(refused) => {
                        let message = refused.to_string();
                        let m = ServerMessage::ServiceCallFailure { service_id, call_id, message: &message };
                        return send_text(ws, m.to_text()).await;
                    }
                }
            }
        };
        debug!("Foxglove client {}: {problem}", self.number);
        send_text(ws, protocol::status(Level::Error, &problem)).await
    }

    /// Sends the graph `g` if the client follows it and it changed since the last one sent
    /// (or `first`: the client just asked for it), with the topics gone since then.
    async fn on_graph(&mut self, ws: &mut WebSocket, g: Graph, first: bool) -> bool {
        let Some(last) = self.graph.replace(g.clone()) else { return true };
        if last == g && !first {
            return true;
        }
        let topics = |m: &std::collections::BTreeMap<String, BTreeSet<String>>, publishers: bool| {
            m.iter()
                .map(|(name, ids)| {
                    let ids: Vec<String> = ids.iter().cloned().collect();
                    let (publisher_ids, subscriber_ids) =
                        if publishers { (ids, Vec::new()) } else { (Vec::new(), ids) };
                    GraphTopic { name: name.clone(), publisher_ids, subscriber_ids }
                })
                .collect::<Vec<_>>()
        };
        let now: BTreeSet<&String> = g.published.keys().chain(g.subscribed.keys()).collect();
        let removed_topics = last
            .published
            .keys()
            .chain(last.subscribed.keys())
            .filter(|t| !now.contains(t))
            .cloned()
            .collect::<BTreeSet<_>>();
        let advertised_services = SERVICES
            .iter()
            .map(|s| GraphService { name: s.1.into(), provider_ids: vec![self.sh.node.clone()] })
            .collect();
        let m = ServerMessage::ConnectionGraphUpdate {
            published_topics: topics(&g.published, true),
            subscribed_topics: topics(&g.subscribed, false),
            advertised_services,
            removed_topics: removed_topics.into_iter().collect(),
            removed_services: Vec::new(),
        };
        send_text(ws, m.to_text()).await
    }

    /// Gives back the client's subscriptions (its connections close as they drop).
    fn leave(&mut self) {
        for (_, c) in self.subs.drain() {
            self.sh.channels[c].subscribers.fetch_sub(1, Ordering::AcqRel);
        }
        self.publishing.clear();
    }
}

/// The `op` of a JSON message, for a status.
fn op_of(text: &str) -> String {
    serde_json::from_str::<serde_json::Value>(text)
        .ok()
        .and_then(|v| v.get("op").and_then(|o| o.as_str()).map(str::to_string))
        .unwrap_or_else(|| "?".into())
}

/// Why a client's channel or service call is refused; the text goes back to the client as a
/// status or a call failure.
#[derive(Debug, thiserror::Error)]
pub(crate) enum Refused {
    #[error("'{topic}' is not a topic of the run (see the advertised channels)")]
    NoSuchTopic { topic: String },
    #[error("'{topic}' is a PUBLISH set: only its framework writes it")]
    PublishSet { topic: String },
    #[error("'{topic}' carries the entities' poses, which the gateway reads from their sets: write the sets")]
    Poses { topic: String },
    #[error("'{topic}': publish in cdr encoding (given: {given})")]
    Encoding { topic: String, given: String },
    #[error("cannot start a thread: {0}")]
    Thread(#[source] std::io::Error),
    #[error("the services take json requests (given: {given})")]
    CallEncoding { given: String },
    #[error("the request is not JSON: {0}")]
    NotJson(#[source] serde_json::Error),
    #[error("n must be a whole number of steps, 1 or more (given: {given})")]
    Steps { given: serde_json::Value },
    #[error("no service {0}")]
    NoService(u32),
}

/// What a service call asks the run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Call {
    Pause,
    Resume,
    Step(u64),
    State,
}

/// The call service `service` makes with request `data` (JSON; an empty request is `{}`).
fn call(service: u32, encoding: &str, data: &[u8]) -> Result<Call, Refused> {
    if encoding != "json" {
        return Err(Refused::CallEncoding { given: encoding.to_string() });
    }
    let request: serde_json::Value = if data.iter().all(u8::is_ascii_whitespace) {
        serde_json::Value::Object(Default::default())
    } else {
        serde_json::from_slice(data).map_err(Refused::NotJson)?
    };
    match service {
        1 => Ok(Call::Pause),
        2 => Ok(Call::Resume),
        3 => match request.get("n") {
            None | Some(serde_json::Value::Null) => Ok(Call::Step(1)),
            Some(n) => match n.as_u64() {
                Some(n) if n >= 1 => Ok(Call::Step(n)),
                _ => Err(Refused::Steps { given: n.clone() }),
            },
        },
        4 => Ok(Call::State),
        other => Err(Refused::NoService(other)),
    }
}

/// How long a new session waits to learn whether there is a run to control.
const PROBE_TIMEOUT: Duration = Duration::from_secs(2);
/// The end of the playback range of a run without an end: this long after now (simulated s).
const DAY: f64 = 86_400.0;

/// A playback request, as the blocking pool takes it.
struct OwnedPlayback {
    command: PlaybackCommand,
    /// A new speed, if the client changed it.
    speed: Option<f32>,
    seek: Option<u64>,
    request_id: String,
}

/// Carries out Foxglove's playback request `req` on the run of namespace `ns` (speed, seek,
/// then play or pause), and the frames that answer it: a status where something was refused (a
/// live run's seek: it has no other time to go to), and the playback state after it.
fn playback_control(ns: &str, req: &OwnedPlayback) -> Vec<Message> {
    let mut frames = Vec::new();
    let mut warn = |why: String| frames.push(Message::Text(protocol::status(Level::Warning, &why).into()));
    let mut sought = false;
    let done = (|| -> Result<RunStatus, ControlError> {
        let mut client = ControlClient::connect(ns, CONTROL_TIMEOUT)?;
        if let Some(speed) = req.speed.map(f64::from) {
            if let Err(e) = client.request(&Request::Speed { factor: speed }) {
                warn(format!("speed {speed}: {e}"));
            }
        }
        // A replay goes to the time asked for; a live run refuses, and says why.
        if let Some(ns) = req.seek {
            match client.request(&Request::Seek { time: ns as f64 / 1e9 }) {
                Ok(_) => sought = true,
                Err(e) => warn(e.to_string()),
            }
        }
        let now = client.state()?;
        match (req.command, now.state) {
            (PlaybackCommand::Play, RunState::Paused) => client.resume(),
            (PlaybackCommand::Pause, RunState::Playing) => client.pause(),
            _ => client.state(),
        }
    })();
    let (status, time, speed) = match &done {
        Ok(st) => {
            let status = match st.state {
                RunState::Playing | RunState::Ready => PlaybackStatus::Playing,
                RunState::Paused => PlaybackStatus::Paused,
                RunState::Stopped => PlaybackStatus::Ended,
            };
            (status, protocol::sim_ns(st.sim_time), if st.speed.is_finite() { st.speed as f32 } else { 0.0 })
        }
        Err(e) => {
            warn(format!("playback: {e}"));
            (PlaybackStatus::Ended, 0, req.speed.unwrap_or(1.0))
        }
    };
    let state = protocol::playback_state(status, time, speed, sought, &req.request_id);
    frames.push(Message::Binary(state.into()));
    frames
}

/// Carries out `c` on the run of namespace `ns`; the run's state after it, as JSON.
fn control(ns: &str, c: Call) -> Result<Vec<u8>, ControlError> {
    let mut client = ControlClient::connect(ns, CONTROL_TIMEOUT)?;
    let status = match c {
        Call::Pause => client.pause(),
        Call::Resume => client.resume(),
        Call::Step(n) => client.step(n),
        Call::State => client.state(),
    }?;
    serde_json::to_vec(&status).map_err(|e| ControlError::Protocol(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn service_requests() {
        assert_eq!(call(3, "json", br#"{"n": 4}"#).ok(), Some(Call::Step(4)));
        assert_eq!(call(3, "json", b"").ok(), Some(Call::Step(1)));
        assert!(call(3, "json", br#"{"n": 0}"#).is_err());
        assert!(call(3, "json", br#"{"n": -2}"#).is_err());
        assert!(call(3, "cdr", b"").is_err());
        assert_eq!(call(1, "json", b"{}").ok(), Some(Call::Pause));
        assert_eq!(
            call(3, "json", br#"{"n": 0}"#).unwrap_err().to_string(),
            "n must be a whole number of steps, 1 or more (given: 0)"
        );
        assert!(call(9, "json", b"{}").is_err());
        assert!(call(1, "json", b"{").is_err());
    }
}
