//! The QoS string of a liveliness token (`qos_to_keyexpr` / `keyexpr_to_qos`,
//! `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:290-425`) and rmw_zenoh's QoS defaults
//! (`rmw_zenoh_cpp/src/detail/qos.cpp:17-151`).
//!
//! The string is six `:`-separated fields, some of them `,`-separated:
//! `RELIABILITY:DURABILITY:HISTORY,DEPTH:DEADLINE_S,DEADLINE_NS:LIFESPAN_S,LIFESPAN_NS:LIVELINESS,LEASE_S,LEASE_NS`.
//! Policies are rmw's enum numbers (`rmw/types.h`), times are `rmw_time_t` seconds and
//! nanoseconds in decimal. A part equal to rmw_zenoh's default ([`QosProfile::ZENOH_DEFAULT`]) is
//! left empty, and an empty part reads back as that default; so ROS 2's default profile, adapted
//! by rmw_zenoh (reliable, volatile, keep last 10, infinite times, automatic liveliness), is
//! `::,10:,:,:,,`. "Infinite" is `rmw_time_t {9223372036, 854775807}` (`RMW_DURATION_INFINITE`),
//! the default of the three times, so it too is written empty.

/// One of rmw's QoS policy enums, with rmw's numbers as written in the QoS string.
macro_rules! policy {
    ($(#[$m:meta])* $name:ident { $($(#[$vm:meta])* $v:ident = $code:literal),+ $(,)? }) => {
        $(#[$m])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum $name { $($(#[$vm])* $v),+ }

        impl $name {
            /// Every value, in rmw's order.
            pub const ALL: &'static [$name] = &[$($name::$v),+];

            /// rmw's number for it (`rmw/types.h`), as the QoS string writes it.
            pub fn code(self) -> u8 {
                match self { $($name::$v => $code),+ }
            }

            /// The policy for its number as written: rmw_zenoh looks the text up in a table of
            /// `std::to_string` of each value
            /// (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:149-188`), so `"01"` and `" 1"`
            /// are not numbers here.
            pub fn from_code(text: &str) -> Option<$name> {
                match text { $(stringify!($code) => Some($name::$v),)+ _ => None }
            }
        }
    };
}

policy! {
    /// `rmw_qos_reliability_policy_e`.
    Reliability { SystemDefault = 0, Reliable = 1, BestEffort = 2, Unknown = 3, BestAvailable = 4 }
}
policy! {
    /// `rmw_qos_durability_policy_e`.
    Durability { SystemDefault = 0, TransientLocal = 1, Volatile = 2, Unknown = 3, BestAvailable = 4 }
}
policy! {
    /// `rmw_qos_history_policy_e`.
    History { SystemDefault = 0, KeepLast = 1, KeepAll = 2, Unknown = 3 }
}
policy! {
    /// `rmw_qos_liveliness_policy_e`. The deprecated `MANUAL_BY_NODE` (2) is in neither of
    /// rmw_zenoh's tables (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:178-188`, `219-229`):
    /// it can be neither written nor read.
    Liveliness { SystemDefault = 0, Automatic = 1, ManualByTopic = 3, Unknown = 4, BestAvailable = 5 }
}

/// `rmw_time_t`: seconds and nanoseconds, both unsigned 64-bit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct RmwDuration {
    pub sec: u64,
    pub nsec: u64,
}

impl RmwDuration {
    /// `RMW_DURATION_INFINITE`: rmw_zenoh's default deadline, lifespan and lease
    /// (`rmw_zenoh_cpp/src/detail/qos.cpp:30-33`).
    pub const INFINITE: RmwDuration = RmwDuration { sec: 9_223_372_036, nsec: 854_775_807 };
    /// `RMW_DURATION_UNSPECIFIED` (`RMW_QOS_*_DEFAULT`), which rmw_zenoh replaces by
    /// [`RmwDuration::INFINITE`] (`rmw_zenoh_cpp/src/detail/qos.cpp:127-140`).
    pub const UNSPECIFIED: RmwDuration = RmwDuration { sec: 0, nsec: 0 };
}

/// The fields of `rmw_qos_profile_t` that a liveliness token carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct QosProfile {
    pub reliability: Reliability,
    pub durability: Durability,
    pub history: History,
    pub depth: u64,
    pub deadline: RmwDuration,
    pub lifespan: RmwDuration,
    pub liveliness: Liveliness,
    pub liveliness_lease_duration: RmwDuration,
}

/// Why a QoS string is not one rmw_zenoh reads.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum QosError {
    #[error("a QoS string has 6 ':'-separated fields, this one has {found}")]
    TooFewFields { found: usize },
    #[error("the QoS {field} has {expected} ','-separated parts, this one has {found}")]
    TooFewParts { field: &'static str, expected: usize, found: usize },
    #[error("unknown QoS {policy} {value:?}")]
    BadPolicy { policy: &'static str, value: String },
    #[error("the QoS {field} is not a decimal number: {value:?}")]
    BadNumber { field: &'static str, value: String },
    #[error("rmw_zenoh supports no UNKNOWN QoS {0} policy")]
    Unsupported(&'static str),
}

impl QosProfile {
    /// rmw_zenoh's defaults (`rmw_zenoh_cpp/src/detail/qos.cpp:17-48`): keep last 42, reliable,
    /// volatile, infinite deadline, lifespan and lease, automatic liveliness. The QoS string
    /// leaves each part equal to these empty.
    pub const ZENOH_DEFAULT: QosProfile = QosProfile {
        reliability: Reliability::Reliable,
        durability: Durability::Volatile,
        history: History::KeepLast,
        depth: 42,
        deadline: RmwDuration::INFINITE,
        lifespan: RmwDuration::INFINITE,
        liveliness: Liveliness::Automatic,
        liveliness_lease_duration: RmwDuration::INFINITE,
    };

    /// The profile as rmw_zenoh adapts it before it makes an entity and its token
    /// (`QoS::best_available_qos`, `rmw_zenoh_cpp/src/detail/qos.cpp:64-151`): an UNKNOWN policy
    /// is refused; SYSTEM_DEFAULT policies, depth 0 and unspecified (zero) times take rmw_zenoh's
    /// defaults. BEST_AVAILABLE is left as it is (written `4`/`4`/`5` in the token).
    pub fn adapted(self) -> Result<QosProfile, QosError> {
        let d = QosProfile::ZENOH_DEFAULT;
        if self.history == History::Unknown {
            return Err(QosError::Unsupported("history"));
        }
        if self.reliability == Reliability::Unknown {
            return Err(QosError::Unsupported("reliability"));
        }
        if self.durability == Durability::Unknown {
            return Err(QosError::Unsupported("durability"));
        }
        if self.liveliness == Liveliness::Unknown {
            return Err(QosError::Unsupported("liveliness"));
        }
        let time = |t: RmwDuration, default| if t == RmwDuration::UNSPECIFIED { default } else { t };
        Ok(QosProfile {
            history: if self.history == History::SystemDefault { d.history } else { self.history },
            depth: if self.depth == 0 { d.depth } else { self.depth },
            reliability: match self.reliability {
                Reliability::SystemDefault => d.reliability,
                r => r,
            },
            durability: match self.durability {
                Durability::SystemDefault => d.durability,
                r => r,
            },
            deadline: time(self.deadline, d.deadline),
            lifespan: time(self.lifespan, d.lifespan),
            liveliness_lease_duration: time(self.liveliness_lease_duration, d.liveliness_lease_duration),
            liveliness: match self.liveliness {
                Liveliness::SystemDefault => d.liveliness,
                l => l,
            },
        })
    }

    /// The QoS string (`qos_to_keyexpr`,
    /// `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:290-351`).
    pub fn to_keyexpr(&self) -> String {
        let d = QosProfile::ZENOH_DEFAULT;
        let code = |differs: bool, code: u8| if differs { code.to_string() } else { String::new() };
        let num = |v: u64, default: u64| if v != default { v.to_string() } else { String::new() };
        format!(
            "{}:{}:{},{}:{},{}:{},{}:{},{},{}",
            code(self.reliability != d.reliability, self.reliability.code()),
            code(self.durability != d.durability, self.durability.code()),
            code(self.history != d.history, self.history.code()),
            num(self.depth, d.depth),
            num(self.deadline.sec, d.deadline.sec),
            num(self.deadline.nsec, d.deadline.nsec),
            num(self.lifespan.sec, d.lifespan.sec),
            num(self.lifespan.nsec, d.lifespan.nsec),
            code(self.liveliness != d.liveliness, self.liveliness.code()),
            num(self.liveliness_lease_duration.sec, d.liveliness_lease_duration.sec),
            num(self.liveliness_lease_duration.nsec, d.liveliness_lease_duration.nsec),
        )
    }

    /// The profile a QoS string stands for (`keyexpr_to_qos`,
    /// `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:354-425`). As there, fields and parts
    /// beyond those it reads are ignored.
    pub fn from_keyexpr(text: &str) -> Result<QosProfile, QosError> {
        let d = QosProfile::ZENOH_DEFAULT;
        let fields: Vec<&str> = text.split(':').collect();
        if fields.len() < 6 {
            return Err(QosError::TooFewFields { found: fields.len() });
        }
        let history = parts(fields[2], "history", 2)?;
        let deadline = parts(fields[3], "deadline", 2)?;
        let lifespan = parts(fields[4], "lifespan", 2)?;
        let liveliness = parts(fields[5], "liveliness", 3)?;
        Ok(QosProfile {
            history: policy_or(history[0], "history", d.history, History::from_code)?,
            reliability: policy_or(fields[0], "reliability", d.reliability, Reliability::from_code)?,
            durability: policy_or(fields[1], "durability", d.durability, Durability::from_code)?,
            liveliness: policy_or(liveliness[0], "liveliness", d.liveliness, Liveliness::from_code)?,
            depth: number_or(history[1], "depth", d.depth)?,
            deadline: RmwDuration {
                sec: number_or(deadline[0], "deadline seconds", d.deadline.sec)?,
                nsec: number_or(deadline[1], "deadline nanoseconds", d.deadline.nsec)?,
            },
            lifespan: RmwDuration {
                sec: number_or(lifespan[0], "lifespan seconds", d.lifespan.sec)?,
                nsec: number_or(lifespan[1], "lifespan nanoseconds", d.lifespan.nsec)?,
            },
            liveliness_lease_duration: RmwDuration {
                sec: number_or(liveliness[1], "lease seconds", d.liveliness_lease_duration.sec)?,
                nsec: number_or(liveliness[2], "lease nanoseconds", d.liveliness_lease_duration.nsec)?,
            },
        })
    }
}

impl Default for QosProfile {
    fn default() -> QosProfile {
        QosProfile::ZENOH_DEFAULT
    }
}

/// A field's `,`-separated parts, at least `expected` of them
/// (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:363-379`).
fn parts<'a>(field: &'a str, name: &'static str, expected: usize) -> Result<Vec<&'a str>, QosError> {
    let parts: Vec<&str> = field.split(',').collect();
    if parts.len() < expected {
        return Err(QosError::TooFewParts { field: name, expected, found: parts.len() });
    }
    Ok(parts)
}

/// A policy's number, or the default where the part is empty
/// (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:381-393`).
fn policy_or<T>(text: &str, policy: &'static str, default: T, from: fn(&str) -> Option<T>) -> Result<T, QosError> {
    if text.is_empty() {
        return Ok(default);
    }
    from(text).ok_or_else(|| QosError::BadPolicy { policy, value: text.to_owned() })
}

/// A number, or the default where the part is empty (`str_to_size_t`,
/// `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:252-286`).
fn number_or(text: &str, field: &'static str, default: u64) -> Result<u64, QosError> {
    if text.is_empty() {
        return Ok(default);
    }
    super::parse_decimal(text).ok_or_else(|| QosError::BadNumber { field, value: text.to_owned() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ros2_default_profile_is_written_as_rmw_zenoh_writes_it() {
        // rclcpp's default (reliable, volatile, keep last 10, unspecified times, system default
        // liveliness), adapted as rmw_zenoh_cpp/src/detail/qos.cpp:78-151 does, then written as
        // rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:290-351 does.
        let ros_default = QosProfile {
            reliability: Reliability::Reliable,
            durability: Durability::Volatile,
            history: History::KeepLast,
            depth: 10,
            deadline: RmwDuration::UNSPECIFIED,
            lifespan: RmwDuration::UNSPECIFIED,
            liveliness: Liveliness::SystemDefault,
            liveliness_lease_duration: RmwDuration::UNSPECIFIED,
        };
        let adapted = ros_default.adapted().expect("supported");
        assert_eq!(adapted.to_keyexpr(), "::,10:,:,:,,");
        assert_eq!(QosProfile::from_keyexpr("::,10:,:,:,,"), Ok(adapted));
        assert_eq!(QosProfile::ZENOH_DEFAULT.to_keyexpr(), "::,:,:,:,,");
    }

    #[test]
    fn every_part_is_written_where_it_differs() {
        let qos = QosProfile {
            reliability: Reliability::BestEffort,
            durability: Durability::TransientLocal,
            history: History::KeepAll,
            depth: 1,
            deadline: RmwDuration { sec: 2, nsec: 3 },
            lifespan: RmwDuration { sec: 4, nsec: 5 },
            liveliness: Liveliness::ManualByTopic,
            liveliness_lease_duration: RmwDuration { sec: 6, nsec: 7 },
        };
        assert_eq!(qos.to_keyexpr(), "2:1:2,1:2,3:4,5:3,6,7");
        assert_eq!(QosProfile::from_keyexpr("2:1:2,1:2,3:4,5:3,6,7"), Ok(qos));
    }

    #[test]
    fn malformed_strings_are_refused() {
        let e = |s: &str| QosProfile::from_keyexpr(s).expect_err(s);
        assert_eq!(e("::,10:,:,"), QosError::TooFewFields { found: 5 });
        assert_eq!(e("::10:,:,:,,"), QosError::TooFewParts { field: "history", expected: 2, found: 1 });
        assert_eq!(e("::,10:,:,:,"), QosError::TooFewParts { field: "liveliness", expected: 3, found: 2 });
        assert!(matches!(e("9::,10:,:,:,,"), QosError::BadPolicy { policy: "reliability", .. }));
        assert!(matches!(e("::,10:,:,:2,,"), QosError::BadPolicy { policy: "liveliness", .. }));
        assert!(matches!(e("01::,10:,:,:,,"), QosError::BadPolicy { .. }));
        assert!(matches!(e("::,-1:,:,:,,"), QosError::BadNumber { field: "depth", .. }));
        assert!(matches!(e("::,10:x,:,:,,"), QosError::BadNumber { field: "deadline seconds", .. }));
        assert!(matches!(e("::,18446744073709551616:,:,:,,"), QosError::BadNumber { .. }));
    }

    #[test]
    fn extra_fields_are_ignored_as_rmw_zenoh_does() {
        assert_eq!(QosProfile::from_keyexpr("::,10,x:,,y:,:,,,:extra"), QosProfile::from_keyexpr("::,10:,:,:,,"));
    }

    #[test]
    fn unknown_policies_are_not_adapted() {
        let qos = QosProfile { durability: Durability::Unknown, ..QosProfile::ZENOH_DEFAULT };
        assert_eq!(qos.adapted(), Err(QosError::Unsupported("durability")));
    }
}
