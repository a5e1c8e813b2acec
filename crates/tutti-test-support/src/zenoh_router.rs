//! A Zenoh router of the test's own (the `zenoh` crate's, as `zenohd` and rmw_zenoh's
//! `rmw_zenohd` run it), listening on a port of loopback that the system picked: where a
//! test's Zenoh sessions meet, as rmw_zenoh's nodes meet at `rmw_zenohd`.

use zenoh::Wait;

/// A router, closed when dropped.
#[derive(Debug)]
pub struct ZenohRouter {
    _session: zenoh::Session,
    endpoint: String,
}

impl ZenohRouter {
    /// Starts one on `tcp/127.0.0.1:0`, without multicast scouting.
    pub fn start() -> ZenohRouter {
        let mut c = zenoh::Config::default();
        for (key, value) in [
            ("mode", r#""router""#),
            ("listen/endpoints", r#"["tcp/127.0.0.1:0"]"#),
            ("scouting/multicast/enabled", "false"),
        ] {
            c.insert_json5(key, value).expect("a router setting");
        }
        let session = zenoh::open(c).wait().expect("a Zenoh router on loopback");
        let endpoint = session
            .info()
            .locators()
            .wait()
            .into_iter()
            .map(|l| l.to_string())
            .find(|l| l.starts_with("tcp/127.0.0.1:"))
            .expect("the router's TCP endpoint");
        ZenohRouter { _session: session, endpoint }
    }

    /// Its endpoint, `tcp/127.0.0.1:PORT`.
    pub fn endpoint(&self) -> &str {
        &self.endpoint
    }

    /// A Zenoh session (a peer, with Zenoh's own API) connected to it.
    pub fn session(&self) -> zenoh::Session {
        let mut c = zenoh::Config::default();
        c.insert_json5("mode", r#""peer""#).expect("mode");
        c.insert_json5("connect/endpoints", &format!(r#"["{}"]"#, self.endpoint)).expect("connect");
        c.insert_json5("listen/endpoints", r#"["tcp/127.0.0.1:0"]"#).expect("listen");
        c.insert_json5("scouting/multicast/enabled", "false").expect("scouting");
        zenoh::open(c).wait().expect("a Zenoh session")
    }
}
