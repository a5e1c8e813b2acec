//! The scripted events of the UAV demo: when the monitoring script disconnects and
//! reconnects which UAV component, and when the C components connect. All times are
//! simulated seconds.

use std::fmt;

/// The FMU's time constant (s), given to the demo's FMU component with `--param tau=`; the
/// checks recompute the filter with it.
pub const FMU_TAU: f64 = 2.0;

/// What the monitoring script asks a UAV component to do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    /// Leave the domain (the UAV keeps flying on its own clock).
    Disconnect,
    /// Connect again.
    Connect,
}

impl Action {
    pub fn name(self) -> &'static str {
        match self {
            Action::Disconnect => "disconnect",
            Action::Connect => "connect",
        }
    }
}

/// One scripted request to UAV `uav` (1-based) at simulated time `t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Event {
    pub t: f64,
    pub uav: usize,
    pub action: Action,
}

impl fmt::Display for Event {
    /// The monitoring script's notation: `T:UAV:ACTION`, e.g. `30:3:disconnect`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}", self.t, self.uav, self.action.name())
    }
}

/// A whole run.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    pub name: &'static str,
    /// Simulated length, s.
    pub duration: f64,
    /// UAV requests of the monitoring script, in time order.
    pub events: Vec<Event>,
    /// Simulated times at which a C component connects to `c_domain_uav`, in order.
    pub c_readers: Vec<f64>,
    /// The UAV (1-based) whose domain the C components read.
    pub c_domain_uav: usize,
}

/// Number of UAVs (and domains) of the demo.
pub const UAVS: usize = 4;

impl Scenario {
    /// The paper's run (section 7, Figures 5 and 6): 120 s; UAV3 disconnected 30–50 s, UAV4
    /// 40–70 s; C components connect to UAV2's domain at 60 s and 80 s.
    pub fn paper() -> Scenario {
        Scenario {
            name: "paper",
            duration: 120.0,
            events: sorted(vec![
                Event { t: 30.0, uav: 3, action: Action::Disconnect },
                Event { t: 40.0, uav: 4, action: Action::Disconnect },
                Event { t: 50.0, uav: 3, action: Action::Connect },
                Event { t: 70.0, uav: 4, action: Action::Connect },
            ]),
            c_readers: vec![60.0, 80.0],
            c_domain_uav: 2,
        }
    }

    /// The same story in 40 s (the test suite's run): UAV3 disconnected 10–20 s, UAV4 12–22 s;
    /// C components at 25 s and 30 s.
    pub fn short() -> Scenario {
        Scenario {
            name: "short",
            duration: 40.0,
            events: sorted(vec![
                Event { t: 10.0, uav: 3, action: Action::Disconnect },
                Event { t: 12.0, uav: 4, action: Action::Disconnect },
                Event { t: 20.0, uav: 3, action: Action::Connect },
                Event { t: 22.0, uav: 4, action: Action::Connect },
            ]),
            c_readers: vec![25.0, 30.0],
            c_domain_uav: 2,
        }
    }

    pub fn by_name(name: &str) -> Option<Scenario> {
        match name {
            "paper" => Some(Scenario::paper()),
            "short" => Some(Scenario::short()),
            _ => None,
        }
    }

    /// The scripted disconnection windows of `uav`: `(from, to)`, `to` = infinity when it
    /// never reconnects.
    pub fn windows(&self, uav: usize) -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        let mut open: Option<f64> = None;
        for e in self.events.iter().filter(|e| e.uav == uav) {
            match (e.action, open) {
                (Action::Disconnect, None) => open = Some(e.t),
                (Action::Connect, Some(from)) => {
                    out.push((from, e.t));
                    open = None;
                }
                _ => {}
            }
        }
        if let Some(from) = open {
            out.push((from, f64::INFINITY));
        }
        out
    }

    /// Connections the domain of `uav` should have at `t`: its UAV component unless it is
    /// disconnected, plus the C components already started when it is the C domain.
    pub fn expected_connections(&self, uav: usize, t: f64) -> u32 {
        let away = self.windows(uav).iter().any(|&(a, b)| t >= a && t < b);
        let c = if uav == self.c_domain_uav { self.c_readers.iter().filter(|&&s| t >= s).count() } else { 0 };
        u32::from(!away) + c as u32
    }

    /// The times at which the connection count of `uav`'s domain is scripted to change.
    pub fn change_times(&self, uav: usize) -> Vec<f64> {
        let mut out: Vec<f64> = self.events.iter().filter(|e| e.uav == uav).map(|e| e.t).collect();
        if uav == self.c_domain_uav {
            out.extend(&self.c_readers);
        }
        out.sort_by(f64::total_cmp);
        out
    }

    /// The events in the monitoring script's notation, comma-separated.
    pub fn events_arg(&self) -> String {
        self.events.iter().map(|e| e.to_string()).collect::<Vec<_>>().join(",")
    }

    /// A scenario shortened to `duration`: events after the end are dropped.
    pub fn with_duration(mut self, duration: f64) -> Scenario {
        self.duration = duration;
        self.events.retain(|e| e.t < duration);
        self.c_readers.retain(|&t| t < duration);
        self
    }
}

fn sorted(mut events: Vec<Event>) -> Vec<Event> {
    events.sort_by(|a, b| a.t.total_cmp(&b.t));
    events
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_paper_schedule_has_the_papers_windows_and_readers() {
        let s = Scenario::paper();
        assert_eq!(s.windows(3), vec![(30.0, 50.0)]);
        assert_eq!(s.windows(4), vec![(40.0, 70.0)]);
        assert!(s.windows(1).is_empty() && s.windows(2).is_empty());
        assert_eq!(s.c_readers, vec![60.0, 80.0]);
        assert_eq!(s.events_arg(), "30:3:disconnect,40:4:disconnect,50:3:connect,70:4:connect");
    }

    #[test]
    fn expected_connections_follow_the_script() {
        let s = Scenario::paper();
        assert_eq!(s.expected_connections(3, 29.9), 1);
        assert_eq!(s.expected_connections(3, 30.0), 0);
        assert_eq!(s.expected_connections(3, 49.9), 0);
        assert_eq!(s.expected_connections(3, 50.0), 1);
        assert_eq!(s.expected_connections(2, 59.0), 1);
        assert_eq!(s.expected_connections(2, 60.0), 2);
        assert_eq!(s.expected_connections(2, 100.0), 3);
        assert_eq!(s.expected_connections(1, 100.0), 1);
        assert_eq!(s.change_times(2), vec![60.0, 80.0]);
        assert_eq!(s.change_times(4), vec![40.0, 70.0]);
    }

    #[test]
    fn an_open_window_lasts_to_the_end_and_shortening_drops_late_events() {
        let s = Scenario::paper().with_duration(60.0);
        assert_eq!(s.windows(4), vec![(40.0, f64::INFINITY)]);
        assert_eq!(s.expected_connections(4, 59.0), 0);
        assert!(s.c_readers.is_empty());
        assert_eq!(s.events.len(), 3);
        assert!(Scenario::by_name("short").is_some() && Scenario::by_name("nope").is_none());
    }
}
