//! The one place where the QoS table of `docs/gateway.md` (`tutti_core::mapping::qos`) becomes
//! rustdds / ros2-client QoS.
//!
//! ros2-client creates node endpoints from a [`QosProfile`] (reliability, durability,
//! history) laid over the QoS of the topic, and `QosProfile` has no ownership. So the
//! ownership goes on the topic ([`topic_qos`]) and the rest in the endpoint's profile
//! ([`profile`]); the tests check that the two halves together give the table's terms.

use ros2_client::dds::rustdds::{policy, QosPolicies, QosPolicyBuilder};
use ros2_client::qos::{Durability, History, Reliability, WhenFull};
use ros2_client::QosProfile;
use tutti_core::mapping::{self, Qos};

/// How long a reliable write waits for room in a full send window.
const MAX_BLOCKING: std::time::Duration = std::time::Duration::from_millis(100);

/// The topic-level part of `q`: its ownership.
pub fn topic_qos(q: &Qos) -> QosPolicies {
    QosPolicyBuilder::new().ownership(ownership(q)).build()
}

/// The endpoint-level part of `q`, for ros2-client's `create_publisher/create_subscription`.
pub fn profile(q: &Qos) -> QosProfile {
    let mut p = QosProfile::publisher_default();
    p.reliability = match q.reliability {
        mapping::Reliability::Reliable => Reliability::Reliable { when_full: WhenFull::Wait(MAX_BLOCKING) },
        mapping::Reliability::BestEffort => Reliability::BestEffort,
    };
    p.durability = match q.durability {
        mapping::Durability::Volatile => Durability::Volatile,
        mapping::Durability::TransientLocal { .. } => Durability::TransientLocal,
    };
    p.history = match (q.history, q.durability) {
        // A transient-local writer keeps `depth` samples for late joiners.
        (mapping::History::KeepLast(_), mapping::Durability::TransientLocal { depth }) => {
            History::KeepLast { depth: depth.max(1) as usize }
        }
        (mapping::History::KeepLast(n), _) => History::KeepLast { depth: n.max(1) as usize },
        (mapping::History::KeepAll, _) => History::KeepAll,
    };
    p.lifespan = q.lifespan;
    p
}

fn ownership(q: &Qos) -> policy::Ownership {
    match q.ownership {
        mapping::Ownership::Shared => policy::Ownership::Shared,
        mapping::Ownership::Exclusive { strength } => policy::Ownership::Exclusive { strength },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tutti_core::ddf::Flags;
    use tutti_core::mapping::{Endpoint, Profile};

    /// All of `q` as one rustdds `QosPolicies`: the profile laid over the topic's part.
    fn policies(q: &Qos) -> QosPolicies {
        QosPolicies::from(&profile(q)).modify_by(&topic_qos(q))
    }

    #[test]
    fn table_rows_become_rustdds_policies() {
        let f = |s, m, st| Flags { synchronous: s, event: false, multiple_publish_allowed: m, states: st };
        let w = policies(&mapping::qos(f(false, false, true), Profile::Ros2, Endpoint::Writer, 0));
        assert!(matches!(w.reliability(), Some(policy::Reliability::Reliable { .. })));
        assert_eq!(w.history(), Some(policy::History::KeepLast { depth: 1 }));
        assert_eq!(w.durability(), Some(policy::Durability::TransientLocal));
        assert_eq!(w.ownership(), Some(policy::Ownership::Shared));
        let r = policies(&mapping::qos(f(false, false, true), Profile::Dds, Endpoint::Reader, 3));
        assert_eq!(r.reliability(), Some(policy::Reliability::BestEffort));
        assert_eq!(r.durability(), Some(policy::Durability::Volatile));
        assert_eq!(r.ownership(), Some(policy::Ownership::Exclusive { strength: 3 }));
        let s = policies(&mapping::qos(f(true, true, false), Profile::Dds, Endpoint::Writer, 0));
        assert_eq!(s.history(), Some(policy::History::KeepAll));
        assert_eq!(s.ownership(), Some(policy::Ownership::Shared));
    }

    /// What rustdds announces of an endpoint in discovery keeps its history (the vendored
    /// rustdds' patch, vendor/rustdds/TUTTI-PATCHES.md): a synchronous set's writer and reader
    /// KEEP_ALL, an asynchronous set's KEEP_LAST 1. Without the patch both are `None`, which
    /// a Cyclone peer shows as KEEP_LAST 1 (docs/gateway.md, "The history a ROS 2 tool shows").
    #[test]
    fn discovery_data_carries_the_history() {
        use ros2_client::dds::rustdds::discovery::{PublicationBuiltinTopicData, SubscriptionBuiltinTopicData};
        use ros2_client::dds::rustdds::GUID;
        let f = |s| Flags { synchronous: s, event: false, multiple_publish_allowed: true, states: false };
        let announced = |sync, end| {
            let q = policies(&mapping::qos(f(sync), Profile::Ros2, end, 0));
            let (topic, ty) = ("rt/d/publish".to_string(), "d::Set".to_string());
            match end {
                Endpoint::Writer => {
                    PublicationBuiltinTopicData::new_with_qos(GUID::GUID_UNKNOWN, None, topic, ty, &q, None)
                        .qos()
                        .history()
                }
                Endpoint::Reader => {
                    SubscriptionBuiltinTopicData::new(GUID::GUID_UNKNOWN, None, topic, ty, &q, None).qos().history()
                }
            }
        };
        assert_eq!(announced(true, Endpoint::Writer), Some(policy::History::KeepAll));
        assert_eq!(announced(true, Endpoint::Reader), Some(policy::History::KeepAll));
        assert_eq!(announced(false, Endpoint::Writer), Some(policy::History::KeepLast { depth: 1 }));
        assert_eq!(announced(false, Endpoint::Reader), Some(policy::History::KeepLast { depth: 1 }));
    }
}
