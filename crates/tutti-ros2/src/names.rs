//! ROS 2 names as tutti makes and checks them: namespaces, topic names (as rcl validates
//! them), a node's full name, and the range of ROS domain ids.

use std::ops::RangeInclusive;

/// The ROS domain ids (`ROS_DOMAIN_ID`): what fits DDS's port mapping (and rmw_zenoh's keys).
pub const DOMAIN_IDS: RangeInclusive<u16> = 0..=232;

/// Why a name is no ROS 2 name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum NameError {
    /// An invalid ROS namespace.
    #[error("ROS namespace '{given}': each part must be letters, digits and '_' and not start with a digit (e.g. sim1 or site_a/sim1)")]
    Namespace { given: String },
    /// An invalid ROS topic name.
    #[error("'{name}' is not a ROS topic name: {why} (e.g. uav1/cmd, or /fleet/uav1/cmd)")]
    TopicName { name: String, why: &'static str },
}

/// A ROS namespace as given (`sim1`, `/sim1/`, `a/b`) in canonical form without slashes
/// around it (`sim1`, `a/b`; empty for none); an invalid one is an error naming it.
pub fn namespace(ns: &str) -> Result<String, NameError> {
    let t = ns.trim().trim_matches('/');
    for tok in t.split('/').filter(|_| !t.is_empty()) {
        if !token(tok) {
            return Err(NameError::Namespace { given: ns.to_string() });
        }
    }
    Ok(t.to_string())
}

/// One token of a ROS name: `[A-Za-z_][A-Za-z0-9_]*`.
fn token(tok: &str) -> bool {
    !tok.is_empty()
        && !tok.starts_with(|c: char| c.is_ascii_digit())
        && tok.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// A topic name: relative (`uav1/cmd`) or absolute (`/fleet/uav1/cmd`), tokens of letters,
/// digits and `_` not starting with a digit, as rcl validates topic names; ROS's `~` and `{}`
/// substitutions are refused (tutti's node name is no help in a topic name).
pub fn topic_name(name: &str) -> Result<String, NameError> {
    let body = name.strip_prefix('/').unwrap_or(name);
    let why = if body.is_empty() {
        Some("it is empty")
    } else if name.contains('~') || name.contains('{') || name.contains('}') {
        Some("ROS substitutions (~, {}) are not supported")
    } else if body.ends_with('/') {
        Some("it ends with '/'")
    } else if body.contains("//") {
        Some("it contains '//'")
    } else if !body.split('/').all(token) {
        Some("each part must be letters, digits and '_' and not start with a digit")
    } else {
        None
    };
    match why {
        None => Ok(name.to_string()),
        Some(why) => Err(NameError::TopicName { name: name.to_string(), why }),
    }
}

/// The ROS node namespace of a canonical ROS namespace (`/` for none).
pub fn node_namespace(ns: &str) -> String {
    format!("/{ns}")
}

/// The ROS 2 name of `name` (relative) under the canonical namespace `ns`: `/NS/NAME`, or
/// `/NAME` without a namespace. A node's full name is one (`/NS/NODE`).
pub fn under(ns: &str, name: &str) -> String {
    if ns.is_empty() {
        format!("/{name}")
    } else {
        format!("/{ns}/{name}")
    }
}

/// `rt/NS/NAME` (`rt/NAME` without a namespace): the DDS topic rmw makes of the relative ROS
/// name `name` under `ns` (what `tutti show` and the stats print beside the ROS 2 name).
pub fn dds_topic(ns: &str, name: &str) -> String {
    if ns.is_empty() {
        format!("rt/{name}")
    } else {
        format!("rt/{ns}/{name}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_as_ros2_makes_and_checks_them() {
        assert_eq!(namespace("/sim1/").unwrap(), "sim1");
        assert_eq!(namespace("").unwrap(), "");
        assert!(namespace("1x").is_err());
        assert!(topic_name("/a//b").is_err() && topic_name("~/x").is_err() && topic_name("a/").is_err());
        assert_eq!(topic_name("/fleet/uav1/cmd").unwrap(), "/fleet/uav1/cmd");
        assert_eq!(under("", "clock"), "/clock");
        assert_eq!(under("a/b", "n"), "/a/b/n");
        assert_eq!(dds_topic("a", "d/publish"), "rt/a/d/publish");
        assert_eq!(node_namespace(""), "/");
    }
}
