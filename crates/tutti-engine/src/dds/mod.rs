//! What the two DDS engines share: how ROS 2 names become DDS topics, how a DDS GUID
//! becomes an [`EndpointId`], and ROS 2 services over DDS ([`rpc`]).

use crate::{EndpointId, PeerId};

pub(crate) mod rpc;

pub(crate) use rpc::ReplyTo;

/// Bytes of a GUID prefix (the participant part of an endpoint GUID).
pub(crate) const PREFIX_LEN: usize = 12;

/// The vendor id Cyclone DDS puts at the head of its GUID prefixes (as Fast DDS and rustdds put
/// theirs).
pub(crate) const CYCLONE_VENDOR: [u8; 2] = [0x01, 0x10];

/// The peer of a DDS endpoint: its participant's GUID prefix, zero-padded.
pub(crate) fn peer_of(guid: &[u8; 16]) -> PeerId {
    let mut p = [0u8; 16];
    p[..PREFIX_LEN].copy_from_slice(&guid[..PREFIX_LEN]);
    PeerId(p)
}

/// The id of the DDS endpoint whose GUID is `guid`: the GUID is its GID.
pub(crate) fn endpoint(guid: [u8; 16]) -> EndpointId {
    EndpointId { gid: guid, peer: peer_of(&guid) }
}

/// The DDS topic of ROS 2 topic `ros` (`/a/b` → `rt/a/b`, as rmw names it).
pub(crate) fn data_topic(ros: &str) -> String {
    format!("rt/{}", ros.trim_start_matches('/'))
}

/// The ROS 2 topic of a DDS data topic (`rt/a/b` → `/a/b`); None for the other DDS topics
/// (services' `rq/`/`rr/`, `ros_discovery_info`, plain DDS).
pub(crate) fn ros_topic(dds: &str) -> Option<String> {
    dds.strip_prefix("rt/").map(|t| format!("/{t}"))
}

/// The request topic of ROS 2 service `ros` (`/a/b` → `rq/a/bRequest`).
pub(crate) fn request_topic(ros: &str) -> String {
    format!("rq/{}Request", ros.trim_start_matches('/'))
}

/// The reply topic of ROS 2 service `ros` (`/a/b` → `rr/a/bReply`).
pub(crate) fn reply_topic(ros: &str) -> String {
    format!("rr/{}Reply", ros.trim_start_matches('/'))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_as_rmw_makes_them() {
        assert_eq!(data_topic("/sim/d/publish"), "rt/sim/d/publish");
        assert_eq!(ros_topic("rt/clock").as_deref(), Some("/clock"));
        assert_eq!(ros_topic("rq/get_simulation_stateRequest"), None);
        assert_eq!(request_topic("/get_simulation_state"), "rq/get_simulation_stateRequest");
        assert_eq!(reply_topic("/sim/a/step_simulation"), "rr/sim/a/step_simulationReply");
        assert_eq!(request_topic("/simulate_steps/_action/send_goal"), "rq/simulate_steps/_action/send_goalRequest");
    }

    #[test]
    fn a_guid_is_its_own_gid_and_its_prefix_the_peer() {
        let mut g = [7u8; 16];
        g[12..].copy_from_slice(&[1, 2, 3, 4]);
        let id = endpoint(g);
        assert_eq!(id.gid, g);
        assert_eq!(&id.peer.0[..12], &g[..12]);
        assert_eq!(&id.peer.0[12..], &[0; 4]);
        assert_eq!(id.short(), format!("{}01020304", "07".repeat(12)));
    }
}
