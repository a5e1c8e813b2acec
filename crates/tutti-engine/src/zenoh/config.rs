//! The Zenoh session's configuration, as rmw_zenoh makes a node's: the file that
//! `ZENOH_SESSION_CONFIG_URI` names, else rmw_zenoh's defaults
//! (`rmw_zenoh_cpp/config/DEFAULT_RMW_ZENOH_SESSION_CONFIG.json5`: a peer that connects to the
//! router at `tcp/localhost:7447`, listens on a port of its own on loopback, and scouts by
//! gossip through the router, not by multicast); then `--zenoh-connect` and `--zenoh-listen`
//! replace the endpoints.

use ::zenoh::Config;

use crate::{EngineConfig, EngineError};

/// The environment variable naming a Zenoh session config file, as rmw_zenoh reads it
/// (`rmw_zenoh_cpp/src/detail/zenoh_config.cpp`).
pub const CONFIG_ENV: &str = "ZENOH_SESSION_CONFIG_URI";

/// Where the session looks for its router unless told otherwise: rmw_zenohd's port.
pub const DEFAULT_CONNECT: &str = "tcp/localhost:7447";

/// rmw_zenoh's session defaults that differ from Zenoh's own.
const RMW_ZENOH_DEFAULTS: &[(&str, &str)] = &[
    ("mode", r#""peer""#),
    ("connect/endpoints", r#"["tcp/localhost:7447"]"#),
    ("listen/endpoints", r#"["tcp/localhost:0"]"#),
    ("scouting/multicast/enabled", "false"),
    ("timestamping/enabled", r#"{ router: true, peer: true, client: true }"#),
    ("queries_default_timeout", "600000"),
];

fn invalid(detail: impl std::fmt::Display) -> EngineError {
    EngineError::ZenohConfig { detail: detail.to_string() }
}

/// The configuration of the engine's session.
pub fn session_config(cfg: &EngineConfig) -> Result<Config, EngineError> {
    let file = std::env::var(CONFIG_ENV).ok().filter(|f| !f.trim().is_empty());
    let mut c = match &file {
        Some(path) => Config::from_file(path).map_err(|e| invalid(format!("{CONFIG_ENV}={path}: {e}")))?,
        None => {
            let mut c = Config::default();
            for (key, value) in RMW_ZENOH_DEFAULTS {
                c.insert_json5(key, value).map_err(|e| invalid(format!("{key}: {e}")))?;
            }
            c
        }
    };
    for (key, endpoints, flag) in [
        ("connect/endpoints", &cfg.zenoh_connect, "--zenoh-connect"),
        ("listen/endpoints", &cfg.zenoh_listen, "--zenoh-listen"),
    ] {
        if endpoints.is_empty() {
            continue;
        }
        let list = serde_json::to_string(endpoints).map_err(invalid)?;
        c.insert_json5(key, &list).map_err(|e| invalid(format!("{flag} {}: {e}", endpoints.join(" "))))?;
    }
    Ok(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endpoints_replace_the_defaults_and_bad_ones_are_refused_with_the_flag() {
        let cfg = EngineConfig { zenoh_connect: vec!["tcp/127.0.0.1:7500".into()], ..EngineConfig::default() };
        let c = session_config(&cfg).unwrap();
        let connect = c.get_json("connect/endpoints").unwrap();
        assert!(connect.contains("tcp/127.0.0.1:7500") && !connect.contains("7447"), "{connect}");
        assert!(c.get_json("listen/endpoints").unwrap().contains("tcp/localhost:0"));
        assert_eq!(c.get_json("scouting/multicast/enabled").unwrap(), "false");
        let bad = EngineConfig { zenoh_listen: vec!["not an endpoint".into()], ..EngineConfig::default() };
        let e = session_config(&bad).unwrap_err().to_string();
        assert!(e.contains("--zenoh-listen not an endpoint"), "{e}");
    }
}
