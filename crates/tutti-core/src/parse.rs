//! Parsers of the values that every command and configuration file takes the same way:
//! durations (`10ms`, `500us`, `2s`, `1min`) and the framework's wait modes (`block`, `spin`,
//! `poll:DURATION`). The CLI's flags, the gateway's configuration file and the runner share
//! them, so a value means the same wherever it is written.

use std::time::Duration;

use crate::shm::WaitMode;

/// A value that does not parse, with the text given.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ParseError {
    #[error("'{0}' is not a duration: a number and a unit, like 10ms, 500us, 2s or 1min")]
    Duration(String),
    #[error("'{0}': use adaptive[:DURATION], block, spin or poll:DURATION (e.g. poll:50us)")]
    Wait(String),
}

/// A duration: a number and a unit (`10ms`, `500us`, `2s`, `1min`).
pub fn parse_duration(s: &str) -> Result<Duration, ParseError> {
    humantime::parse_duration(s.trim()).map_err(|_| ParseError::Duration(s.to_string()))
}

/// A wait mode: `adaptive` (yield up to 50 µs, then block: the default), `block`, `spin`,
/// `adaptive:DURATION` or `poll:DURATION`.
pub fn parse_wait(s: &str) -> Result<WaitMode, ParseError> {
    match s {
        "block" => Ok(WaitMode::Block),
        "spin" => Ok(WaitMode::Spin),
        "adaptive" => Ok(WaitMode::adaptive()),
        _ => match (s.strip_prefix("poll:"), s.strip_prefix("adaptive:")) {
            (Some(d), _) => parse_duration(d).map(WaitMode::Poll),
            (_, Some(d)) => parse_duration(d).map(WaitMode::Adaptive),
            _ => Err(ParseError::Wait(s.to_string())),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_and_wait_modes_parse_or_say_what_is_expected() {
        assert_eq!(parse_duration(" 10ms"), Ok(Duration::from_millis(10)));
        assert_eq!(parse_duration("1min"), Ok(Duration::from_secs(60)));
        assert!(parse_duration("10").unwrap_err().to_string().contains("a number and a unit"));
        assert_eq!(parse_wait("poll:50us"), Ok(WaitMode::Poll(Duration::from_micros(50))));
        assert_eq!(parse_wait("spin"), Ok(WaitMode::Spin));
        assert_eq!(parse_wait("adaptive:20us"), Ok(WaitMode::Adaptive(Duration::from_micros(20))));
        // The default: a yield of 50 µs, then a block.
        assert_eq!(parse_wait("adaptive"), Ok(WaitMode::Adaptive(Duration::from_micros(50))));
        assert_eq!(WaitMode::default(), WaitMode::adaptive());
        assert_eq!(parse_wait("poll:x"), Err(ParseError::Duration("x".into())));
        assert!(parse_wait("sleep").unwrap_err().to_string().contains("adaptive[:DURATION], block, spin or poll"));
    }
}
