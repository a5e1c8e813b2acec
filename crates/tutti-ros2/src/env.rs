//! ROS 2's environment, each variable read here and nowhere else: the ROS domain
//! (`ROS_DOMAIN_ID`) and the discovery range (`ROS_LOCALHOST_ONLY`,
//! `ROS_AUTOMATIC_DISCOVERY_RANGE`). A variable set to nothing counts as unset; a bad value is
//! an error naming the variable.

use crate::names::DOMAIN_IDS;

/// A ROS 2 variable with a value it does not take.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum EnvError {
    /// A bad `ROS_DOMAIN_ID`.
    #[error("ROS_DOMAIN_ID='{value}' is not a DDS domain id (0-232)")]
    DomainId { value: String },
    /// An unknown `ROS_AUTOMATIC_DISCOVERY_RANGE`.
    #[error("ROS_AUTOMATIC_DISCOVERY_RANGE='{value}': expected SUBNET, LOCALHOST, OFF or SYSTEM_DEFAULT")]
    DiscoveryRange { value: String },
}

/// The value of `name`, None when unset or blank.
pub fn var(name: &str) -> Option<String> {
    std::env::var(name).ok().filter(|v| !v.trim().is_empty())
}

/// A ROS domain id given as text, if it is one ([`DOMAIN_IDS`]).
pub fn parse_domain_id(s: &str) -> Option<u16> {
    s.trim().parse::<u16>().ok().filter(|d| DOMAIN_IDS.contains(d))
}

/// `ROS_DOMAIN_ID`, if set.
pub fn domain_id() -> Result<Option<u16>, EnvError> {
    let Some(s) = var("ROS_DOMAIN_ID") else { return Ok(None) };
    match parse_domain_id(&s) {
        Some(d) => Ok(Some(d)),
        None => Err(EnvError::DomainId { value: s }),
    }
}

/// What ROS 2's discovery variables ask for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DiscoveryRange {
    /// `SUBNET`, `SYSTEM_DEFAULT` or unset: as configured.
    #[default]
    Default,
    /// This machine only: loopback.
    Localhost,
    /// No automatic discovery: only the peers given.
    Off,
}

/// The discovery range of ROS 2's variables, given their values. `ROS_LOCALHOST_ONLY=1`
/// wins, as in ROS 2 Jazzy (which still honours it, deprecated); an unknown range is an
/// error naming the variable.
pub fn discovery_range(localhost_only: Option<&str>, range: Option<&str>) -> Result<DiscoveryRange, EnvError> {
    if localhost_only.is_some_and(|v| v.trim() == "1") {
        return Ok(DiscoveryRange::Localhost);
    }
    match range.map(|r| r.trim().to_ascii_uppercase()).as_deref() {
        None | Some("" | "SUBNET" | "SYSTEM_DEFAULT") => Ok(DiscoveryRange::Default),
        Some("LOCALHOST") => Ok(DiscoveryRange::Localhost),
        Some("OFF") => Ok(DiscoveryRange::Off),
        Some(_) => Err(EnvError::DiscoveryRange { value: range.unwrap_or_default().to_string() }),
    }
}

/// `ROS_LOCALHOST_ONLY` and `ROS_AUTOMATIC_DISCOVERY_RANGE`.
pub fn discovery() -> Result<DiscoveryRange, EnvError> {
    discovery_range(
        std::env::var("ROS_LOCALHOST_ONLY").ok().as_deref(),
        std::env::var("ROS_AUTOMATIC_DISCOVERY_RANGE").ok().as_deref(),
    )
}
