//! The values the gateway's keys and flags take, each parser shared by the CLI's flags and
//! the file's keys (serde's `deserialize_with` functions wrap them, so a bad value is refused
//! where it stands in the file).

use std::time::Duration;

use serde::Deserializer;
use tutti_config::de::{Number, Parsed};
use tutti_core::mapping::Profile;
use tutti_core::parse::{parse_duration, parse_wait};
use tutti_core::shm::WaitMode;

use super::{ConfigError, Lookahead, TypeMode};

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

/// A wait mode (`block`, `spin`, `adaptive[:DURATION]`, `poll:DURATION`) whose time is at most
/// [`MAX_DURATION`].
pub fn parse_wait_mode(s: &str) -> Result<WaitMode, ConfigError> {
    match parse_wait(s)? {
        WaitMode::Poll(d) | WaitMode::Adaptive(d) if d > MAX_DURATION => {
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
    de_wait -> WaitMode = parse_wait_mode, "\"block\", \"spin\", \"adaptive[:DURATION]\" or \"poll:DURATION\"";
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

/// The most steps of lookahead a domain takes: the home side keeps up to that many answers,
/// and a larger one is no lookahead but a mistake.
pub const MAX_LOOKAHEAD: u32 = 100_000;

/// One `--lookahead` flag: `K` (every synchronous domain) or `DOMAIN=K`.
pub fn parse_lookahead(s: &str) -> Result<Lookahead, ConfigError> {
    let (domain, k) = match s.split_once('=') {
        Some((d, k)) => (Some(d.trim()), k),
        None => (None, s),
    };
    let k = match k.trim().parse::<u32>() {
        Ok(k) if k <= MAX_LOOKAHEAD => k,
        _ => return Err(ConfigError::Lookahead { value: s.to_string() }),
    };
    Ok(match domain {
        None => Lookahead { all: Some(k), domains: Vec::new() },
        Some("") => return Err(ConfigError::Lookahead { value: s.to_string() }),
        Some(d) => Lookahead { all: None, domains: vec![(d.to_string(), k)] },
    })
}

/// `lookahead`: a number of steps (every synchronous domain), or a map of domain names to
/// numbers of steps.
pub(crate) fn de_lookahead<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Lookahead>, D::Error> {
    struct V;
    const WHAT: &str = "a number of steps from 0 to 100000, or a map of domain names to numbers of steps";
    fn steps<E: serde::de::Error>(v: f64) -> Result<u32, E> {
        if v.fract() == 0.0 && (0.0..=f64::from(MAX_LOOKAHEAD)).contains(&v) {
            Ok(v as u32)
        } else {
            Err(E::custom(format!("{v} is not {WHAT}")))
        }
    }
    /// A map's value: a number, refused with [`WHAT`] otherwise.
    struct Steps;
    impl<'de> serde::de::DeserializeSeed<'de> for Steps {
        type Value = f64;
        fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<f64, D::Error> {
            d.deserialize_any(Number { expecting: WHAT, ok: |_| true })
        }
    }
    impl<'de> serde::de::Visitor<'de> for V {
        type Value = Lookahead;
        fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str(WHAT)
        }
        fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Lookahead, E> {
            Ok(Lookahead { all: Some(steps(v)?), domains: Vec::new() })
        }
        fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<Lookahead, E> {
            self.visit_f64(v as f64)
        }
        fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<Lookahead, E> {
            self.visit_f64(v as f64)
        }
        fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<Lookahead, A::Error> {
            let mut l = Lookahead::default();
            while let Some(domain) = map.next_key::<String>()? {
                let k = steps(map.next_value_seed(Steps)?)?;
                if l.domains.iter().any(|(d, _)| *d == domain) {
                    return Err(serde::de::Error::custom(format!("domain '{domain}' is given twice")));
                }
                l.domains.push((domain, k));
            }
            Ok(l)
        }
    }
    d.deserialize_any(V).map(Some)
}
