//! How rmw_zenoh maps a ROS 2 QoS onto Zenoh, as plain data for an engine to apply.
//!
//! Each function takes the profile as rmw_zenoh adapts it ([`QosProfile::adapted`]), which is
//! what publishers and subscriptions use
//! (`rmw_zenoh_cpp/src/detail/rmw_publisher_data.cpp:63-68`,
//! `rmw_zenoh_cpp/src/detail/rmw_subscription_data.cpp:66-71`):
//!
//! * reliable: a reliable Zenoh publisher, dropping under congestion; reliable with KEEP_ALL:
//!   blocking under congestion; best effort (or anything else): best-effort, dropping
//!   (`rmw_zenoh_cpp/src/detail/rmw_publisher_data.cpp:135-146`). History depth is not a Zenoh
//!   setting otherwise.
//! * TRANSIENT_LOCAL: the publisher is an advanced publisher with a cache of `depth` samples and
//!   publisher detection, plus sample-miss detection with a sporadic heartbeat of 500 ms when
//!   reliable (`rmw_zenoh_cpp/src/detail/rmw_publisher_data.cpp:114-132`,
//!   `rmw_zenoh_cpp/src/detail/rmw_publisher_data.cpp:49`); the subscriber is an advanced
//!   subscriber with subscriber detection, an unbounded query timeout, history of `depth` samples
//!   with detection of late publishers, and recovery by heartbeat when reliable
//!   (`rmw_zenoh_cpp/src/detail/rmw_subscription_data.cpp:192-207`). Volatile endpoints use none
//!   of these.
//! * services: the server's queryable is `complete`
//!   (`rmw_zenoh_cpp/src/detail/rmw_service_data.cpp:151-153`); the client's querier targets all
//!   complete queryables, without consolidation, with Zenoh's default timeout except for actions'
//!   `get_result`, whose timeout is `u64::MAX` ms
//!   (`rmw_zenoh_cpp/src/detail/rmw_client_data.cpp:132-149`).

use super::keyexpr::DataKey;
use super::qos::{Durability, History, QosProfile, Reliability};

/// Zenoh's `z_reliability_t`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ZenohReliability {
    Reliable,
    BestEffort,
}

/// Zenoh's `z_congestion_control_t`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CongestionControl {
    Drop,
    Block,
}

/// The cache of a TRANSIENT_LOCAL publisher.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct PublisherCache {
    pub max_samples: u64,
    /// Sample-miss detection's sporadic heartbeat period (ms), for reliable publishers.
    pub miss_detection_heartbeat_ms: Option<u64>,
}

/// A publisher's Zenoh options (`rmw_zenoh_cpp/src/detail/rmw_publisher_data.cpp:114-146`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct PublisherOptions {
    pub reliability: ZenohReliability,
    pub congestion_control: CongestionControl,
    /// An advanced publisher's cache and publisher detection; None for volatile publishers.
    pub cache: Option<PublisherCache>,
}

/// A TRANSIENT_LOCAL subscriber's history and recovery.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SubscriberHistory {
    pub max_samples: u64,
    /// Always true: late-joining publishers are queried for their cache.
    pub detect_late_publishers: bool,
    /// Recovery of missed samples by the publisher's heartbeat, for reliable subscriptions.
    pub recovery_by_heartbeat: bool,
    /// The history query's timeout: `u64::MAX` ms.
    pub query_timeout_ms: u64,
}

/// A subscriber's Zenoh options (`rmw_zenoh_cpp/src/detail/rmw_subscription_data.cpp:178-207`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SubscriberOptions {
    /// Only samples of other sessions (`ignore_local_publications`,
    /// `rmw_zenoh_cpp/src/detail/rmw_subscription_data.cpp:186-188`).
    pub remote_only: bool,
    /// History and subscriber detection; None for volatile subscriptions.
    pub history: Option<SubscriberHistory>,
}

/// Zenoh's `z_query_target_t`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum QueryTarget {
    BestMatching,
    All,
    AllComplete,
}

/// Zenoh's `z_consolidation_mode_t`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ConsolidationMode {
    Auto,
    None,
    Monotonic,
    Latest,
}

/// A client's querier options (`rmw_zenoh_cpp/src/detail/rmw_client_data.cpp:132-149`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct QuerierOptions {
    pub target: QueryTarget,
    pub consolidation: ConsolidationMode,
    /// None: Zenoh's default (10 s).
    pub timeout_ms: Option<u64>,
}

/// A server's queryable is complete (`rmw_zenoh_cpp/src/detail/rmw_service_data.cpp:151-153`).
pub const QUERYABLE_COMPLETE: bool = true;

/// The sporadic heartbeat of a reliable TRANSIENT_LOCAL publisher, in ms
/// (`SAMPLE_MISS_DETECTION_HEARTBEAT_PERIOD`,
/// `rmw_zenoh_cpp/src/detail/rmw_publisher_data.cpp:49`).
pub const MISS_DETECTION_HEARTBEAT_MS: u64 = 500;

/// A publisher's options for an adapted profile.
pub fn publisher_options(qos: &QosProfile) -> PublisherOptions {
    let reliable = qos.reliability == Reliability::Reliable;
    let congestion_control =
        if reliable && qos.history == History::KeepAll { CongestionControl::Block } else { CongestionControl::Drop };
    let cache = (qos.durability == Durability::TransientLocal).then(|| PublisherCache {
        max_samples: qos.depth,
        miss_detection_heartbeat_ms: reliable.then_some(MISS_DETECTION_HEARTBEAT_MS),
    });
    PublisherOptions {
        reliability: if reliable { ZenohReliability::Reliable } else { ZenohReliability::BestEffort },
        congestion_control,
        cache,
    }
}

/// A subscriber's options for an adapted profile.
pub fn subscriber_options(qos: &QosProfile, ignore_local_publications: bool) -> SubscriberOptions {
    let history = (qos.durability == Durability::TransientLocal).then(|| SubscriberHistory {
        max_samples: qos.depth,
        detect_late_publishers: true,
        recovery_by_heartbeat: qos.reliability == Reliability::Reliable,
        query_timeout_ms: u64::MAX,
    });
    SubscriberOptions { remote_only: ignore_local_publications, history }
}

/// A client's querier options for its service's key: a key intersecting
/// `**/_action/get_result/**` (a plain key: one with the chunks `_action` then `get_result`)
/// waits forever.
pub fn querier_options(key: &DataKey) -> QuerierOptions {
    let domain = key.domain_id.to_string();
    let mut chunks: Vec<&str> = vec![&domain];
    chunks.extend(key.name.split('/').filter(|c| !c.is_empty()));
    chunks.extend([key.type_name.as_str(), key.type_hash.as_str()]);
    let get_result = chunks.windows(2).any(|w| w == ["_action", "get_result"]);
    QuerierOptions {
        target: QueryTarget::AllComplete,
        consolidation: ConsolidationMode::None,
        timeout_ms: get_result.then_some(u64::MAX),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reliability_congestion_and_cache() {
        let d = QosProfile::ZENOH_DEFAULT;
        let p = publisher_options(&d);
        assert_eq!(
            (p.reliability, p.congestion_control, p.cache),
            (ZenohReliability::Reliable, CongestionControl::Drop, None)
        );
        let keep_all = QosProfile { history: History::KeepAll, ..d };
        assert_eq!(publisher_options(&keep_all).congestion_control, CongestionControl::Block);
        let best_effort_all = QosProfile { reliability: Reliability::BestEffort, ..keep_all };
        let p = publisher_options(&best_effort_all);
        assert_eq!((p.reliability, p.congestion_control), (ZenohReliability::BestEffort, CongestionControl::Drop));
        let latched = QosProfile { durability: Durability::TransientLocal, depth: 5, ..d };
        let cache = PublisherCache { max_samples: 5, miss_detection_heartbeat_ms: Some(500) };
        assert_eq!(publisher_options(&latched).cache, Some(cache));
        let s = subscriber_options(&latched, true);
        assert!(s.remote_only);
        assert_eq!(s.history.map(|h| (h.max_samples, h.recovery_by_heartbeat)), Some((5, true)));
        assert_eq!(subscriber_options(&d, false).history, None);
    }

    #[test]
    fn get_result_waits_forever() {
        let key =
            |name: &str| DataKey { domain_id: 0, name: name.into(), type_name: "T_".into(), type_hash: "H".into() };
        assert_eq!(querier_options(&key("/fib/_action/get_result")).timeout_ms, Some(u64::MAX));
        assert_eq!(querier_options(&key("/fib/_action/send_goal")).timeout_ms, None);
        assert_eq!(querier_options(&key("/add")).target, QueryTarget::AllComplete);
    }
}
