//! Names that keep the tests apart: each test uses a shared-memory namespace and a DDS domain
//! of its own, so that the tests of one binary (and of two checkouts) run in parallel.
//!
//! DDS domain ids in use (ROS 2 allows 0..=232): the two-site example 47, the Foxglove server 61..=76, the gateway
//! scenarios 101..=125 with Cyclone DDS and 151..=175 with rustdds (50 above), the gateway's
//! DDS writers in an event-driven domain 136..=141 (each test's two engines side by side),
//! the UAV demo 180..=198, the gateway that `tutti show` plans against 199, the
//! hostile-settings gateway tests 200..=209, the reliable synchronous sets 220..=229, the
//! gateway under churn and restarts 230..=232 (ids above 232 do not fit DDS's port mapping).

use std::ops::RangeInclusive;

/// A shared-memory namespace of test `tag` in this process: `tag` followed by the process id.
pub fn namespace(tag: &str) -> String {
    format!("{tag}{}", std::process::id())
}

/// A DDS domain id from `range`, chosen by the process id, so that the same test run by two
/// processes at once (two checkouts on one machine) most likely uses two domains.
pub fn dds_domain_in(range: RangeInclusive<u16>) -> u16 {
    let (lo, hi) = (*range.start(), *range.end());
    assert!(lo <= hi && hi <= 232, "DDS domain ids go up to 232");
    let span = u32::from(hi - lo) + 1;
    // The remainder is below `span`, which fits a u16.
    lo + u16::try_from(std::process::id() % span).unwrap_or(0)
}
