//! The engine's keys of the gateway's config file (docs/gateway.md, "Config file"), parsed
//! here, where they are used: `engine` (`dds` is its old name), `ros_domain_id`, `interface`
//! and `peer`, each checked where it stands; and the engine's environment variables
//! (`TUTTI_DDS`, `TUTTI_GATEWAY_INTERFACE`), each read here and nowhere else.

use std::fmt;
use std::net::IpAddr;
use std::path::PathBuf;

use serde::de::{Deserializer, SeqAccess, Visitor};
use serde::Deserialize;
use tutti_config::de::{Number, Parsed};
use tutti_config::sections::Section;

use crate::security::{SecurityError, SecuritySettings, Strategy};
use crate::{EngineKind, UnknownEngine};

/// The engine's keys; each None where the file (or the flags) say nothing.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EngineKeys {
    /// The ROS domain (DDS domain id), 0-232.
    #[serde(default, deserialize_with = "de_domain_id")]
    pub ros_domain_id: Option<u16>,
    /// The engine (`--engine`; `dds`, the key's old name, is taken too).
    #[serde(default, alias = "dds", deserialize_with = "de_engine")]
    pub engine: Option<EngineKind>,
    /// Addresses the engine may use.
    pub interface: Option<Vec<IpAddr>>,
    /// Unicast discovery peers, checked where each stands ([`parse_peer`]).
    #[serde(default, deserialize_with = "de_peers")]
    pub peer: Option<Vec<String>>,
    /// Zenoh: the endpoints to connect to (`tcp/127.0.0.1:7447`), checked when the session
    /// opens.
    pub zenoh_connect: Option<Vec<String>>,
    /// Zenoh: the endpoints to listen on.
    pub zenoh_listen: Option<Vec<String>>,
    /// DDS Security on (`ROS_SECURITY_ENABLE`, `--security`).
    pub security_enable: Option<bool>,
    /// The SROS2 keystore (`ROS_SECURITY_KEYSTORE`, `--security-keystore`).
    pub security_keystore: Option<PathBuf>,
    /// The gateway's enclave (`ROS_SECURITY_ENCLAVE_OVERRIDE`, `--enclave`).
    pub enclave: Option<String>,
    /// `Enforce` or `Permissive` (`ROS_SECURITY_STRATEGY`, `--security-strategy`).
    #[serde(default, deserialize_with = "de_strategy")]
    pub security_strategy: Option<Strategy>,
}

impl Section for EngineKeys {
    const KEYS: &'static [&'static str] = &[
        "ros_domain_id",
        "engine",
        "dds",
        "interface",
        "peer",
        "zenoh_connect",
        "zenoh_listen",
        "security_enable",
        "security_keystore",
        "enclave",
        "security_strategy",
    ];

    fn over(self, lower: Self) -> Self {
        EngineKeys {
            ros_domain_id: self.ros_domain_id.or(lower.ros_domain_id),
            engine: self.engine.or(lower.engine),
            interface: self.interface.or(lower.interface),
            peer: self.peer.or(lower.peer),
            zenoh_connect: self.zenoh_connect.or(lower.zenoh_connect),
            zenoh_listen: self.zenoh_listen.or(lower.zenoh_listen),
            security_enable: self.security_enable.or(lower.security_enable),
            security_keystore: self.security_keystore.or(lower.security_keystore),
            enclave: self.enclave.or(lower.enclave),
            security_strategy: self.security_strategy.or(lower.security_strategy),
        }
    }
}

impl EngineKeys {
    /// The DDS Security settings: the environment's (as rcl reads it), where these keys say
    /// nothing.
    pub fn security(&self) -> Result<SecuritySettings, SecurityError> {
        let env = SecuritySettings::from_env()?;
        Ok(SecuritySettings {
            enable: self.security_enable.unwrap_or(env.enable),
            keystore: self.security_keystore.clone().or(env.keystore),
            enclave: self.enclave.clone().or(env.enclave),
            strategy: self.security_strategy.unwrap_or(env.strategy),
        })
    }
}

fn de_strategy<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Strategy>, D::Error> {
    let parse = std::str::FromStr::from_str;
    d.deserialize_any(Parsed { expecting: "\"Enforce\" or \"Permissive\"", parse }).map(Some)
}

/// A peer or a variable the engine cannot take.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum KeysError {
    /// A discovery peer Cyclone DDS would not take.
    #[error("peer '{value}': {why}")]
    Peer { value: String, why: String },
    /// A bad `TUTTI_DDS`.
    #[error("TUTTI_DDS='{value}': {error}")]
    EngineVar { value: String, error: UnknownEngine },
    /// A bad address in `TUTTI_GATEWAY_INTERFACE`.
    #[error("TUTTI_GATEWAY_INTERFACE: '{value}': {error}")]
    InterfaceVar { value: String, error: std::net::AddrParseError },
}

/// The port Cyclone assumes for a peer given without one does not matter here: host names
/// are resolved only to check that they resolve.
const ANY_PORT: u16 = 7400;

/// A unicast discovery peer as Cyclone DDS takes it in `<Peer address="...">` on its default
/// UDP/IPv4 transport: an IPv4 address or a host name, with an optional `:PORT` (1-65535).
/// A host name must resolve to an IPv4 address now: Cyclone aborts the process on a peer it
/// cannot resolve, and on an IPv6 one. The value comes back as given (trimmed).
pub fn parse_peer(s: &str) -> Result<String, KeysError> {
    let t = s.trim();
    // Shown escaped: the value may hold control characters.
    let bad = |why: String| KeysError::Peer { value: s.escape_debug().to_string(), why };
    let (host, port) = match t.rsplit_once(':') {
        Some((h, p)) if !h.contains(':') => {
            let port = p.parse::<u16>().ok().filter(|&p| p > 0);
            (h, Some(port.ok_or_else(|| bad(format!("'{p}' is not a port (1-65535)")))?))
        }
        _ => (t, None),
    };
    if host.parse::<std::net::Ipv4Addr>().is_ok() {
        return Ok(t.to_string());
    }
    if t.trim_start_matches('[').split(']').next().is_some_and(|h| h.parse::<std::net::Ipv6Addr>().is_ok()) {
        return Err(bad("IPv6 peers are not supported: the gateway's Cyclone DDS talks UDP over IPv4".into()));
    }
    if !host_name(host) {
        return Err(bad("not an IPv4 address or a host name (letters, digits, '-' and '.', like 192.0.2.1, \
             site-b.example or site-b:7410)"
            .into()));
    }
    use std::net::ToSocketAddrs;
    match (host, port.unwrap_or(ANY_PORT)).to_socket_addrs() {
        Ok(mut addrs) => match addrs.any(|a| a.is_ipv4()) {
            true => Ok(t.to_string()),
            false => Err(bad(format!("host name '{host}' has no IPv4 address"))),
        },
        Err(e) => Err(bad(format!("host name '{host}' does not resolve: {e}"))),
    }
}

/// A host name as RFC 1123 has it: dot-separated labels of 1-63 letters, digits and `-`, not
/// starting or ending with `-`; 253 characters at most (a final `.` allowed).
fn host_name(h: &str) -> bool {
    let h = h.strip_suffix('.').unwrap_or(h);
    !h.is_empty()
        && h.len() <= 253
        && h.split('.').all(|l| {
            (1..=63).contains(&l.len())
                && l.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
                && !l.starts_with('-')
                && !l.ends_with('-')
        })
}

fn de_engine<'de, D: Deserializer<'de>>(d: D) -> Result<Option<EngineKind>, D::Error> {
    let parse = std::str::FromStr::from_str;
    d.deserialize_any(Parsed { expecting: "\"cyclone\", \"rustdds\" or \"zenoh\"", parse }).map(Some)
}

/// The highest ROS domain id, as the numbers of the file are read.
const DOMAIN_MAX: f64 = *tutti_ros2::names::DOMAIN_IDS.end() as f64;

fn de_domain_id<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u16>, D::Error> {
    let ok = |v: f64| v.fract() == 0.0 && (0.0..=DOMAIN_MAX).contains(&v);
    d.deserialize_any(Number { expecting: "a DDS domain id (0-232)", ok }).map(|v| Some(v as u16))
}

fn de_peers<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Vec<String>>, D::Error> {
    struct Peers;
    impl<'de> Visitor<'de> for Peers {
        type Value = Vec<String>;
        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str("a list of peers, like [\"192.0.2.1\", \"site-b:7410\"]")
        }
        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<String>, A::Error> {
            let mut out = Vec::new();
            while let Some(p) =
                seq.next_element_seed(Parsed { expecting: "an IPv4 address or host name", parse: parse_peer })?
            {
                out.push(p);
            }
            Ok(out)
        }
    }
    d.deserialize_any(Peers).map(Some)
}

/// The engine's environment variables. A variable set to nothing counts as unset; a bad value
/// is an error naming the variable.
pub mod env {
    use std::net::IpAddr;

    use super::KeysError;
    use crate::EngineKind;

    /// `TUTTI_DDS`, else the default engine (cyclone).
    pub fn engine() -> Result<EngineKind, KeysError> {
        match tutti_ros2::env::var("TUTTI_DDS") {
            Some(s) => s.parse().map_err(|error| KeysError::EngineVar { value: s, error }),
            None => Ok(EngineKind::default()),
        }
    }

    /// `TUTTI_GATEWAY_INTERFACE` (comma-separated addresses), if set.
    pub fn interfaces() -> Result<Option<Vec<IpAddr>>, KeysError> {
        let Some(s) = tutti_ros2::env::var("TUTTI_GATEWAY_INTERFACE") else { return Ok(None) };
        s.split(',')
            .map(|a| {
                a.trim().parse::<IpAddr>().map_err(|error| KeysError::InterfaceVar { value: a.to_string(), error })
            })
            .collect::<Result<Vec<_>, _>>()
            .map(Some)
    }
}
