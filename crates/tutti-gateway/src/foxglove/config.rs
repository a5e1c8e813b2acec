//! The Foxglove server's key of the gateway's config file (`foxglove`, as `--foxglove`),
//! parsed here as a section of its own (`crate::config::file`).

use std::net::SocketAddr;

use serde::Deserialize;
use tutti_config::sections::Section;

/// `foxglove: "127.0.0.1:8765"`: the address the Foxglove WebSocket server listens on.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FoxgloveKeys {
    pub foxglove: Option<SocketAddr>,
}

impl Section for FoxgloveKeys {
    const KEYS: &'static [&'static str] = &["foxglove"];

    fn over(self, lower: Self) -> Self {
        FoxgloveKeys { foxglove: self.foxglove.or(lower.foxglove) }
    }
}
