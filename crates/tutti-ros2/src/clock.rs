//! ROS 2's `/clock`: the simulated time a ROS 2 node on `use_sim_time` follows
//! (`rosgraph_msgs/msg/Clock`), its QoS, and the message made of a time in seconds.

use tutti_core::mapping::{Durability, History, Ownership, Qos, Reliability};

use crate::simulation::Stamp;
use crate::{registry, Message, Struct};

/// The topic's relative name.
pub const TOPIC: &str = "clock";
/// Its interface.
pub const MESSAGE: &str = "rosgraph_msgs/msg/Clock";

/// The message, from the registry.
pub fn message() -> Message<'static> {
    match registry().message(MESSAGE) {
        Some(m) => m,
        None => unreachable!("{MESSAGE} is an embedded interface"),
    }
}

/// The writer's QoS: reliable, volatile, keep last 1.
pub fn qos() -> Qos {
    Qos {
        reliability: Reliability::Reliable,
        history: History::KeepLast(1),
        durability: Durability::Volatile,
        ownership: Ownership::Shared,
        lifespan: None,
    }
}

/// `sim_time` (seconds) as a `builtin_interfaces/Time`, rounded to the nanosecond; a negative
/// time (or one that is no number) is zero.
pub fn stamp(sim_time: f64) -> Stamp {
    let ns = (sim_time.max(0.0) * 1e9).round();
    let ns = if ns.is_finite() { ns as u128 } else { 0 };
    Stamp { sec: i32::try_from(ns / 1_000_000_000).unwrap_or(i32::MAX), nanosec: (ns % 1_000_000_000) as u32 }
}

/// The CDR body of the `Clock` of `sim_time` (little-endian, no encapsulation header).
pub fn encode(message: &Message<'_>, sim_time: f64) -> Vec<u8> {
    let clock = Struct::new().with("clock", stamp(sim_time).value());
    // Two fixed-size fields of the right types: nothing in it can fail to encode.
    message.encode(&clock.into()).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_become_seconds_and_nanoseconds() {
        let m = message();
        let decode = |b: Vec<u8>| {
            assert_eq!(b.len(), 8, "int32 sec, uint32 nanosec");
            (i32::from_le_bytes(b[..4].try_into().unwrap()), u32::from_le_bytes(b[4..].try_into().unwrap()))
        };
        assert_eq!(decode(encode(&m, 12.25)), (12, 250_000_000));
        assert_eq!(decode(encode(&m, 0.01 * 3.0)), (0, 30_000_000), "rounded to the nanosecond");
        assert_eq!(decode(encode(&m, -1.0)), (0, 0));
        assert_eq!(decode(encode(&m, f64::NAN)), (0, 0));
    }
}
