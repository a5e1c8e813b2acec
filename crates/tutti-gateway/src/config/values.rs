//! The values the gateway's keys and flags take, each parser shared by the CLI's flags and
//! the file's keys (serde's `deserialize_with` functions wrap them, so a bad value is refused
//! where it stands in the file).

use std::time::Duration;

use serde::Deserializer;
use tutti_config::de::{Number, Parsed};
use tutti_core::mapping::Profile;
use tutti_core::parse::{parse_duration, parse_wait};
use tutti_core::shm::WaitMode;

use super::{ConfigError, TypeMode};

/// The longest duration a key or flag takes: 365 days. Longer ones are refused, since a
/// deadline is the time now plus the duration, and that sum overflows the clock for
/// durations of some hundred billion years (a panic, not an error).
pub const MAX_DURATION: Duration = Duration::from_secs(365 * 24 * 3600);

/// The lowest rate a key or flag takes: one sample in [`MAX_DURATION`] (the interval between
/// samples is 1 / rate, which must be a duration).
pub const MIN_RATE: f64 = 1.0 / (365.0 * 24.0 * 3600.0);

/// A rate in Hz (`100`, `100Hz`), at least [`MIN_RATE`].
pub fn parse_rate(s: &str) -> Result<f64, ConfigError> {
    match s.trim().trim_end_matches("Hz").trim_end_matches("hz").parse::<f64>() {
        Ok(r) if r.is_finite() && r >= MIN_RATE => Ok(r),
        _ => Err(ConfigError::Rate { value: s.to_string() }),
    }
}

/// A duration from zero to [`MAX_DURATION`] (`poll`, where 0 means keep polling;
/// `duration`).
pub fn parse_span(s: &str) -> Result<Duration, ConfigError> {
    let d = parse_duration(s)?;
    if d > MAX_DURATION {
        return Err(ConfigError::Duration { value: s.to_string(), why: "longer than 365 days" });
    }
    Ok(d)
}

/// A period above zero, at most [`MAX_DURATION`]: `timeout`, `status_every`, `lease` (a
/// period of zero would time out every wait, or tick without end).
pub fn parse_period(s: &str) -> Result<Duration, ConfigError> {
    let d = parse_span(s)?;
    if d.is_zero() {
        return Err(ConfigError::Duration { value: s.to_string(), why: "it must be longer than zero" });
    }
    Ok(d)
}

/// A wait mode (`block`, `spin`, `poll:DURATION`) whose poll interval is at most
/// [`MAX_DURATION`].
pub fn parse_wait_mode(s: &str) -> Result<WaitMode, ConfigError> {
    match parse_wait(s)? {
        WaitMode::Poll(d) if d > MAX_DURATION => {
            Err(ConfigError::Duration { value: s.to_string(), why: "longer than 365 days" })
        }
        w => Ok(w),
    }
}

fn parse_types(s: &str) -> Result<TypeMode, ConfigError> {
    match s {
        "typed" => Ok(TypeMode::Typed),
        "per-item" | "per_item" => Ok(TypeMode::PerItem),
        _ => Err(ConfigError::Types { value: s.to_string() }),
    }
}

/// A QoS profile: `ros2` or `dds`.
pub fn parse_profile(s: &str) -> Result<Profile, ConfigError> {
    match s {
        "ros2" => Ok(Profile::Ros2),
        "dds" => Ok(Profile::Dds),
        _ => Err(ConfigError::Profile { value: s.to_string() }),
    }
}

/// A ROS namespace in canonical form (`tutti_ros2::names::namespace`).
pub fn parse_namespace(s: &str) -> Result<String, ConfigError> {
    Ok(tutti_ros2::names::namespace(s)?)
}

/// A ROS topic name (`tutti_ros2::names::topic_name`).
pub fn parse_topic_name(s: &str) -> Result<String, ConfigError> {
    Ok(tutti_ros2::names::topic_name(s)?)
}

/// `deserialize_with` functions of the form `fn(D) -> Result<Option<T>, D::Error>` over a
/// parser of text.
macro_rules! parsed {
    ($($name:ident -> $ty:ty = $parse:path, $what:literal;)*) => {$(
        pub(crate) fn $name<'de, D: Deserializer<'de>>(d: D) -> Result<Option<$ty>, D::Error> {
            d.deserialize_any(Parsed { expecting: $what, parse: $parse }).map(Some)
        }
    )*};
}

parsed! {
    de_period -> Duration = parse_period, "a duration above zero like \"10ms\", \"2s\" or \"1min\"";
    de_span -> Duration = parse_span, "a duration like \"10ms\", \"2s\" or \"1min\"";
    de_wait -> WaitMode = parse_wait_mode, "\"block\", \"spin\" or \"poll:DURATION\"";
    de_types -> TypeMode = parse_types, "\"typed\" or \"per-item\"";
    de_profile -> Profile = parse_profile, "\"ros2\" or \"dds\"";
    de_namespace -> String = parse_namespace, "a ROS namespace like \"sim1\"";
    de_remap -> String = parse_topic_name, "a ROS topic name like \"uav1/cmd\" or \"/fleet/uav1/cmd\"";
}

/// A rate in Hz (a number), at least [`MIN_RATE`].
pub(crate) fn de_rate<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    let expecting = "a rate in Hz above 0 (at least one sample in 365 days)";
    d.deserialize_any(Number { expecting, ok: |v| v >= MIN_RATE }).map(Some)
}
