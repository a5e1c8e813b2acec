//! The messages of the Foxglove WebSocket protocol that the server speaks (docs/gateway.md,
//! "Foxglove"): JSON text frames with an `op` each way, and binary frames with a one-byte
//! opcode and little-endian integers. Only what the server uses is here; a client message it
//! does not know is answered with a status, never a panic.

use serde::{Deserialize, Serialize};

/// The subprotocol names the handshake accepts: the protocol's first name (Lichtblick, the
/// npm client `@foxglove/ws-protocol`) and its current one (the Foxglove SDKs and app). Both
/// name the same messages.
pub const SUBPROTOCOLS: [&str; 2] = ["foxglove.websocket.v1", "foxglove.sdk.v1"];

/// Server binary opcodes.
const MESSAGE_DATA: u8 = 0x01;
const TIME: u8 = 0x02;
const SERVICE_CALL_RESPONSE: u8 = 0x03;
const PLAYBACK_STATE: u8 = 0x05;

/// Client binary opcodes.
const CLIENT_MESSAGE_DATA: u8 = 0x01;
const SERVICE_CALL_REQUEST: u8 = 0x02;
const PLAYBACK_CONTROL_REQUEST: u8 = 0x03;

/// Status levels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    Info = 0,
    Warning = 1,
    Error = 2,
}

/// A channel the server advertises.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "camelCase")]
pub struct Channel {
    pub id: u32,
    pub topic: String,
    pub encoding: String,
    pub schema_name: String,
    pub schema: String,
    pub schema_encoding: String,
}

/// A service's request or response definition.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "camelCase")]
pub struct MessageDef {
    pub encoding: String,
    pub schema_name: String,
    pub schema_encoding: String,
    pub schema: String,
}

/// A service the server advertises.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "camelCase")]
pub struct Service {
    pub id: u32,
    pub name: String,
    #[serde(rename = "type")]
    pub ty: String,
    pub request: MessageDef,
    pub response: MessageDef,
    /// The schemas again under their older keys, for clients that read only those.
    pub request_schema: String,
    pub response_schema: String,
}

/// One topic of the connection graph and who publishes or subscribes it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(rename_all = "camelCase")]
pub struct GraphTopic {
    pub name: String,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub publisher_ids: Vec<String>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub subscriber_ids: Vec<String>,
}

/// One service of the connection graph and who provides it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(rename_all = "camelCase")]
pub struct GraphService {
    pub name: String,
    pub provider_ids: Vec<String>,
}

/// JSON messages of the server.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "op", rename_all = "camelCase")]
pub enum ServerMessage<'a> {
    #[serde(rename_all = "camelCase")]
    ServerInfo {
        name: &'a str,
        capabilities: &'a [&'a str],
        supported_encodings: &'a [&'a str],
        metadata: &'a std::collections::BTreeMap<String, String>,
        session_id: &'a str,
        /// The range of data (playback control): from the run's start to its end.
        #[serde(skip_serializing_if = "Option::is_none")]
        data_start_time: Option<Stamp>,
        #[serde(skip_serializing_if = "Option::is_none")]
        data_end_time: Option<Stamp>,
    },
    Status {
        level: u8,
        message: &'a str,
    },
    Advertise {
        channels: &'a [Channel],
    },
    AdvertiseServices {
        services: &'a [Service],
    },
    #[serde(rename_all = "camelCase")]
    ServiceCallFailure {
        service_id: u32,
        call_id: u32,
        message: &'a str,
    },
    #[serde(rename_all = "camelCase")]
    ConnectionGraphUpdate {
        published_topics: Vec<GraphTopic>,
        subscribed_topics: Vec<GraphTopic>,
        advertised_services: Vec<GraphService>,
        removed_topics: Vec<String>,
        removed_services: Vec<String>,
    },
}

impl ServerMessage<'_> {
    pub fn to_text(&self) -> String {
        // A value of these types always serialises.
        serde_json::to_string(self).unwrap_or_default()
    }
}

/// A status message of `level`.
pub fn status(level: Level, message: &str) -> String {
    ServerMessage::Status { level: level as u8, message }.to_text()
}

/// One subscription in a `subscribe`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Subscription {
    pub id: u32,
    pub channel_id: u32,
}

/// A channel a client advertises.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct ClientChannel {
    pub id: u32,
    pub topic: String,
    pub encoding: String,
    #[serde(default)]
    pub schema_name: String,
}

/// JSON messages of a client; `Other` is any op the server does not serve.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(tag = "op", rename_all = "camelCase")]
pub enum ClientMessage {
    Subscribe {
        subscriptions: Vec<Subscription>,
    },
    #[serde(rename_all = "camelCase")]
    Unsubscribe {
        subscription_ids: Vec<u32>,
    },
    Advertise {
        channels: Vec<ClientChannel>,
    },
    #[serde(rename_all = "camelCase")]
    Unadvertise {
        channel_ids: Vec<u32>,
    },
    SubscribeConnectionGraph,
    UnsubscribeConnectionGraph,
    #[serde(other)]
    Other,
}

/// Binary messages of a client.
#[derive(Debug, Clone, PartialEq)]
pub enum ClientBinary<'a> {
    /// Data on a channel the client advertised.
    MessageData { channel_id: u32, data: &'a [u8] },
    /// A service call.
    ServiceCall { service_id: u32, call_id: u32, encoding: &'a str, data: &'a [u8] },
    /// Foxglove's playback controls.
    Playback(PlaybackControl<'a>),
}

/// A time as the protocol's JSON has it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Stamp {
    pub sec: u64,
    pub nsec: u32,
}

impl Stamp {
    pub fn of_ns(ns: u64) -> Stamp {
        Stamp { sec: ns / 1_000_000_000, nsec: (ns % 1_000_000_000) as u32 }
    }
}

/// A playback command (Foxglove's playback control).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlaybackCommand {
    Play,
    Pause,
}

/// What Foxglove's playback controls ask.
#[derive(Debug, Clone, PartialEq)]
pub struct PlaybackControl<'a> {
    pub command: PlaybackCommand,
    pub speed: f32,
    /// Where to go, in nanoseconds, if the client sought.
    pub seek: Option<u64>,
    pub request_id: &'a str,
}

/// The server's playback status.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlaybackStatus {
    Playing = 0,
    Paused = 1,
    Ended = 3,
}

/// A `Playback State` frame: the status, the time now (ns), the speed, whether a seek moved
/// it, and the request it answers.
pub fn playback_state(status: PlaybackStatus, time_ns: u64, speed: f32, did_seek: bool, request_id: &str) -> Vec<u8> {
    let mut out = Vec::with_capacity(19 + request_id.len());
    out.push(PLAYBACK_STATE);
    out.push(status as u8);
    out.extend_from_slice(&time_ns.to_le_bytes());
    out.extend_from_slice(&speed.to_le_bytes());
    out.push(u8::from(did_seek));
    out.extend_from_slice(&(request_id.len() as u32).to_le_bytes());
    out.extend_from_slice(request_id.as_bytes());
    out
}

/// Why a client's binary message cannot be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BinaryError {
    #[error("an empty binary message")]
    Empty,
    #[error("binary opcode {0:#04x} is not one a client sends")]
    Opcode(u8),
    #[error("a binary message of opcode {op:#04x} cut short at {len} bytes")]
    Short { op: u8, len: usize },
    #[error("a service call's encoding is not UTF-8")]
    Encoding,
    #[error("playback command {0} is neither play (0) nor pause (1)")]
    PlaybackCommand(u8),
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

/// Reads a client's binary message; every length is checked against the frame.
pub fn parse_binary(b: &[u8]) -> Result<ClientBinary<'_>, BinaryError> {
    let op = *b.first().ok_or(BinaryError::Empty)?;
    let short = || BinaryError::Short { op, len: b.len() };
    match op {
        CLIENT_MESSAGE_DATA => {
            Ok(ClientBinary::MessageData { channel_id: u32_at(b, 1).ok_or_else(short)?, data: &b[5..] })
        }
        SERVICE_CALL_REQUEST => {
            let service_id = u32_at(b, 1).ok_or_else(short)?;
            let call_id = u32_at(b, 5).ok_or_else(short)?;
            let len = u32_at(b, 9).ok_or_else(short)? as usize;
            let encoding = b.get(13..13usize.saturating_add(len)).ok_or_else(short)?;
            let encoding = std::str::from_utf8(encoding).map_err(|_| BinaryError::Encoding)?;
            Ok(ClientBinary::ServiceCall { service_id, call_id, encoding, data: &b[13 + len..] })
        }
        // command u8, speed f32, had_seek u8, seek u64, request id (u32 length, UTF-8).
        PLAYBACK_CONTROL_REQUEST => {
            let command = match *b.get(1).ok_or_else(short)? {
                0 => PlaybackCommand::Play,
                1 => PlaybackCommand::Pause,
                c => return Err(BinaryError::PlaybackCommand(c)),
            };
            let speed = f32::from_le_bytes(b.get(2..6).ok_or_else(short)?.try_into().map_err(|_| short())?);
            let had_seek = *b.get(6).ok_or_else(short)? != 0;
            let seek = u64::from_le_bytes(b.get(7..15).ok_or_else(short)?.try_into().map_err(|_| short())?);
            let len = u32_at(b, 15).ok_or_else(short)? as usize;
            let id = b.get(19..19usize.saturating_add(len)).ok_or_else(short)?;
            let request_id = std::str::from_utf8(id).map_err(|_| BinaryError::Encoding)?;
            Ok(ClientBinary::Playback(PlaybackControl { command, speed, seek: had_seek.then_some(seek), request_id }))
        }
        op => Err(BinaryError::Opcode(op)),
    }
}

/// A `Message Data` frame: subscription `subscription`, timestamp `time_ns`, `data`.
pub fn message_data(subscription: u32, time_ns: u64, data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(13 + data.len());
    out.push(MESSAGE_DATA);
    out.extend_from_slice(&subscription.to_le_bytes());
    out.extend_from_slice(&time_ns.to_le_bytes());
    out.extend_from_slice(data);
    out
}

/// A `Time` frame.
pub fn time(time_ns: u64) -> Vec<u8> {
    let mut out = Vec::with_capacity(9);
    out.push(TIME);
    out.extend_from_slice(&time_ns.to_le_bytes());
    out
}

/// A `Service Call Response` frame.
pub fn service_response(service_id: u32, call_id: u32, encoding: &str, data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(13 + encoding.len() + data.len());
    out.push(SERVICE_CALL_RESPONSE);
    out.extend_from_slice(&service_id.to_le_bytes());
    out.extend_from_slice(&call_id.to_le_bytes());
    out.extend_from_slice(&(encoding.len() as u32).to_le_bytes());
    out.extend_from_slice(encoding.as_bytes());
    out.extend_from_slice(data);
    out
}

/// Simulated time (seconds) as the protocol's nanosecond timestamp (negative and
/// non-finite times as 0).
pub fn sim_ns(t: f64) -> u64 {
    if t.is_finite() && t > 0.0 {
        (t * 1e9).round() as u64
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binary_messages_are_read_with_every_length_checked() {
        let mut call = vec![SERVICE_CALL_REQUEST];
        call.extend_from_slice(&3u32.to_le_bytes());
        call.extend_from_slice(&9u32.to_le_bytes());
        call.extend_from_slice(&4u32.to_le_bytes());
        call.extend_from_slice(b"json{\"n\":2}");
        assert_eq!(
            parse_binary(&call),
            Ok(ClientBinary::ServiceCall { service_id: 3, call_id: 9, encoding: "json", data: b"{\"n\":2}" })
        );
        // An encoding length past the end of the frame.
        let mut bad = call[..9].to_vec();
        bad.extend_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(parse_binary(&bad), Err(BinaryError::Short { .. })));
        assert_eq!(
            parse_binary(&[CLIENT_MESSAGE_DATA, 2, 0, 0, 0, 7]),
            Ok(ClientBinary::MessageData { channel_id: 2, data: &[7] })
        );
        assert!(matches!(parse_binary(&[CLIENT_MESSAGE_DATA, 2]), Err(BinaryError::Short { .. })));
        assert_eq!(parse_binary(&[]), Err(BinaryError::Empty));
        assert_eq!(parse_binary(&[9]), Err(BinaryError::Opcode(9)));
        // Playback control, laid out as the Foxglove SDK writes it.
        let mut play = vec![PLAYBACK_CONTROL_REQUEST, 1];
        play.extend_from_slice(&2.5f32.to_le_bytes());
        play.push(1);
        play.extend_from_slice(&1_500_000_000u64.to_le_bytes());
        play.extend_from_slice(&2u32.to_le_bytes());
        play.extend_from_slice(b"r7");
        let want = PlaybackControl {
            command: PlaybackCommand::Pause,
            speed: 2.5,
            seek: Some(1_500_000_000),
            request_id: "r7",
        };
        assert_eq!(parse_binary(&play), Ok(ClientBinary::Playback(want)));
        assert!(matches!(parse_binary(&play[..play.len() - 1]), Err(BinaryError::Short { .. })));
        play[1] = 4;
        assert_eq!(parse_binary(&play), Err(BinaryError::PlaybackCommand(4)));
    }

    #[test]
    fn client_json_messages_and_unknown_ops() {
        let m: ClientMessage =
            serde_json::from_str(r#"{"op":"subscribe","subscriptions":[{"id":0,"channelId":3}]}"#).unwrap();
        assert_eq!(m, ClientMessage::Subscribe { subscriptions: vec![Subscription { id: 0, channel_id: 3 }] });
        let m: ClientMessage = serde_json::from_str(r#"{"op":"getParameters","parameterNames":[]}"#).unwrap();
        assert_eq!(m, ClientMessage::Other);
        let adv = r#"{"op":"advertise","channels":[{"id":1,"topic":"/a","encoding":"cdr","schemaName":"p/msg/A"}]}"#;
        assert!(matches!(serde_json::from_str::<ClientMessage>(adv).unwrap(), ClientMessage::Advertise { .. }));
    }

    #[test]
    fn frames_and_times() {
        assert_eq!(message_data(1, 2, &[9]), [1, 1, 0, 0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 9]);
        assert_eq!(time(5), [2, 5, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(service_response(1, 2, "json", b"{}")[..13], [3, 1, 0, 0, 0, 2, 0, 0, 0, 4, 0, 0, 0]);
        assert_eq!(sim_ns(0.005), 5_000_000);
        let state = playback_state(PlaybackStatus::Paused, 7, 0.5, true, "ab");
        assert_eq!(state, [5, 1, 7, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0x3f, 1, 2, 0, 0, 0, b'a', b'b']);
        assert_eq!(sim_ns(f64::NAN), 0);
        let info = ServerMessage::Status { level: 2, message: "x" }.to_text();
        assert_eq!(info, r#"{"op":"status","level":2,"message":"x"}"#);
    }
}
