//! The Zenoh session's configuration, as rmw_zenoh makes a node's: the file that
//! `ZENOH_SESSION_CONFIG_URI` names, else rmw_zenoh's defaults
//! (`rmw_zenoh_cpp/config/DEFAULT_RMW_ZENOH_SESSION_CONFIG.json5`: a peer that connects to the
//! router at `tcp/localhost:7447`, listens on a port of its own on loopback, and scouts by
//! gossip through the router, not by multicast); then the `key=value;…` pairs of
//! `ZENOH_CONFIG_OVERRIDE`, as rmw_zenoh applies them (a pair Zenoh refuses is skipped with a
//! warning, as rmw_zenoh skips it); then `--zenoh-connect` and `--zenoh-listen` replace the
//! endpoints (`--interface ADDR`, without `--zenoh-listen`, listens on `tcp/ADDR:0`).

use ::zenoh::Config;

use crate::{EngineConfig, EngineError};

/// The environment variable naming a Zenoh session config file, as rmw_zenoh reads it
/// (`rmw_zenoh_cpp/src/detail/zenoh_config.cpp`).
pub const CONFIG_ENV: &str = "ZENOH_SESSION_CONFIG_URI";

/// The environment variable of `key=value` pairs laid over the configuration, `;`-separated
/// (`rmw_zenoh_cpp/src/detail/zenoh_config.cpp:48-100`).
pub const OVERRIDE_ENV: &str = "ZENOH_CONFIG_OVERRIDE";

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
    if let Ok(pairs) = std::env::var(OVERRIDE_ENV) {
        apply_overrides(&mut c, &pairs);
    }
    // The addresses the gateway may use (`--interface`) are where it listens, on a port of
    // the system's choosing, unless its listening endpoints are given.
    let listen_on_interfaces: Vec<String> = match cfg.zenoh_listen.is_empty() {
        true => cfg.interfaces.iter().map(|ip| format!("tcp/{}", std::net::SocketAddr::new(*ip, 0))).collect(),
        false => Vec::new(),
    };
    for (key, endpoints, flag) in [
        ("connect/endpoints", &cfg.zenoh_connect, "--zenoh-connect"),
        ("listen/endpoints", &cfg.zenoh_listen, "--zenoh-listen"),
        ("listen/endpoints", &listen_on_interfaces, "--interface"),
    ] {
        if endpoints.is_empty() {
            continue;
        }
        let list = serde_json::to_string(endpoints).map_err(invalid)?;
        c.insert_json5(key, &list).map_err(|e| invalid(format!("{flag} {}: {e}", endpoints.join(" "))))?;
    }
    Ok(c)
}

/// Lays `key=value;…` over `c` as rmw_zenoh does: each pair split at its first `=`, a pair
/// without one ignored, one that Zenoh refuses skipped with a warning.
fn apply_overrides(c: &mut Config, pairs: &str) {
    for pair in pairs.split(';') {
        let Some((key, value)) = pair.split_once('=') else { continue };
        if let Err(e) = c.insert_json5(key, value) {
            tracing::warn!("{OVERRIDE_ENV}: the pair {key}={value} is not taken ({e}); skipped, as rmw_zenoh skips it");
        }
    }
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

    #[test]
    fn interfaces_are_where_it_listens_unless_told() {
        let on_lo = EngineConfig { interfaces: vec![[127, 0, 0, 1].into()], ..EngineConfig::default() };
        let c = session_config(&on_lo).unwrap();
        assert_eq!(c.get_json("listen/endpoints").unwrap(), r#"["tcp/127.0.0.1:0"]"#);
        let told = EngineConfig { zenoh_listen: vec!["tcp/127.0.0.1:7449".into()], ..on_lo };
        assert!(session_config(&told).unwrap().get_json("listen/endpoints").unwrap().contains("7449"));
    }

    #[test]
    fn overrides_are_laid_over_as_rmw_zenoh_lays_them() {
        let mut c = session_config(&EngineConfig::default()).unwrap();
        apply_overrides(
            &mut c,
            r#"listen/endpoints=["tcp/127.0.0.1:7448"];no_equals;scouting/multicast/enabled=true;mode=42"#,
        );
        assert!(c.get_json("listen/endpoints").unwrap().contains("tcp/127.0.0.1:7448"));
        assert_eq!(c.get_json("scouting/multicast/enabled").unwrap(), "true");
        assert_eq!(c.get_json("mode").unwrap(), r#""peer""#, "a refused pair is skipped");
    }
}
