//! A domain's segment as a passive observer holds it: no connection, so the observer is
//! never counted as a participant and never paces a step (the gateway's poller and
//! `/clock`, `tutti record`). The segment is opened while a framework is there, let go when
//! it stops, and looked for again every 200 ms; whether the framework's process still lives
//! (a `/proc` read, microseconds) is checked at most every 50 ms, so a look is cheap enough
//! for a loop that spins.

use std::time::{Duration, Instant};

use super::segment::{ConnKind, Segment};
use super::ShmError;

/// How often a missing domain is looked for.
const REOPEN: Duration = Duration::from_millis(200);
/// How often the framework's process is checked.
const ALIVE_CHECK: Duration = Duration::from_millis(50);

/// One domain, followed from outside.
#[derive(Debug)]
pub struct Observer {
    pub domain: String,
    seg: Option<Segment>,
    /// The observer connection held while the segment is open, if asked for
    /// ([`Observer::with_presence`]).
    presence: Option<Presence>,
    next_open: Instant,
    next_alive_check: Instant,
}

/// An observer's connection: listed by `tutti status`, never waited for.
#[derive(Debug)]
struct Presence {
    /// The name the connection shows.
    name: String,
    /// Its connection slot while the segment is open and one was free.
    slot: Option<usize>,
}

/// What [`Observer::look`] found ([`Observer::segment`] is the segment after `Fresh` and
/// `Same`).
#[derive(Debug)]
pub enum Look {
    /// No running framework (not yet, or still not).
    Gone,
    /// The framework stopped since the last look; its segment was let go.
    Stopped,
    /// The segment is there but refused (corrupted, another format): the error, at most
    /// every 200 ms.
    Refused(ShmError),
    /// Opened just now (a new framework, or the first look).
    Fresh,
    /// Open, as at the last look.
    Same,
}

impl Observer {
    pub fn new(domain: String) -> Self {
        Observer { domain, seg: None, presence: None, next_open: Instant::now(), next_alive_check: Instant::now() }
    }

    /// An observer that also holds an observer connection named `name` while the framework
    /// runs: listed by `tutti status` (with the DDS reader count set by
    /// [`set_dds_readers`](Self::set_dds_readers)), never waited for, not a participant.
    pub fn with_presence(domain: String, name: &str) -> Self {
        let mut o = Observer::new(domain);
        o.presence = Some(Presence { name: name.to_string(), slot: None });
        o
    }

    /// Shows `n` DDS readers in the presence connection.
    pub fn set_dds_readers(&self, n: u64) {
        if let (Some(seg), Some(Presence { slot: Some(slot), .. })) = (&self.seg, &self.presence) {
            seg.set_peers(*slot, n);
        }
    }

    /// Lets the segment go (it is opened again at the next look).
    pub fn close(&mut self) {
        self.leave();
        self.seg = None;
    }

    /// Releases the presence connection (the segment stays open).
    fn leave(&mut self) {
        if let (Some(seg), Some(presence)) = (&self.seg, &mut self.presence) {
            if let Some(i) = presence.slot.take() {
                seg.release_slot(i, super::os::current_process().pid);
            }
        }
    }

    /// Looks at the domain of namespace `namespace`.
    pub fn look(&mut self, namespace: &str) -> Look {
        let now = Instant::now();
        if let Some(seg) = &self.seg {
            if let Err(e) = seg.intact() {
                self.close();
                return Look::Refused(e);
            }
            if now >= self.next_alive_check {
                self.next_alive_check = now + ALIVE_CHECK;
                if !seg.framework_alive() {
                    // A header shrunk away reads as zeros, a framework gone: say which.
                    let truncated = seg.intact_checked().err();
                    // The presence connection is released, not just forgotten: were the
                    // framework seen gone while its segment lives on, a forgotten slot would
                    // stay claimed beside the one taken at the next open, and `tutti status`
                    // would count this gateway's DDS readers twice.
                    self.close();
                    return truncated.map_or(Look::Stopped, Look::Refused);
                }
            }
        }
        let mut fresh = false;
        if self.seg.is_none() {
            if now < self.next_open {
                return Look::Gone;
            }
            self.next_open = now + REOPEN;
            match Segment::open(namespace, &self.domain) {
                Ok(s) if s.framework_alive() => {
                    if let Some(presence) = &mut self.presence {
                        // A full connection table leaves the observer without its presence;
                        // it still observes.
                        presence.slot =
                            s.claim_slot(super::os::current_process(), &presence.name, ConnKind::Observer, false).ok();
                    }
                    self.seg = Some(s);
                    fresh = true;
                }
                Ok(_) | Err(ShmError::NoSuchDomain { .. } | ShmError::NotReady { .. }) => {}
                Err(e) => return Look::Refused(e),
            }
        }
        match (&self.seg, fresh) {
            (Some(_), true) => Look::Fresh,
            (Some(_), false) => Look::Same,
            (None, _) => Look::Gone,
        }
    }

    /// The segment, while a framework is there.
    pub fn segment(&self) -> Option<&Segment> {
        self.seg.as_ref()
    }
}

impl Drop for Observer {
    fn drop(&mut self) {
        self.leave();
    }
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::Ordering;

    use super::*;
    use crate::shm::segment::{STATE_RUNNING, STATE_STOPPED};
    use crate::shm::{Framework, FrameworkOptions};

    const DDF: &str = r#"<?xml version="1.0"?>
<orchestra>
  <domain name="seen">
    <synchronous>no</synchronous><multiplePublishAllowed>yes</multiplePublishAllowed><states>no</states>
    <set name="PUBLISH"><item name="x"><type>float64</type><length>1</length></item></set>
    <set name="SUBSCRIBE"><item name="y"><type>float64</type><length>1</length></item></set>
  </domain>
</orchestra>"#;

    /// A framework seen gone while its segment lives on (here: its state word flips and
    /// back) costs the observer its presence connection, which it takes again at the next
    /// open: one connection, never two, so `tutti status` does not count its DDS readers twice.
    #[test]
    fn a_framework_seen_gone_and_back_leaves_one_presence_connection() {
        let model = crate::ddf::parse_str(DDF, "seen.ddf").unwrap();
        let ns = format!("observer{}", std::process::id());
        let fw = Framework::create(&model, &FrameworkOptions { namespace: ns.clone(), ..Default::default() }).unwrap();
        let observers = || fw.domains[0].status().connections.iter().filter(|c| c.observer).count();
        let mut watcher = Observer::with_presence("seen".into(), "tutti_gateway");
        assert!(matches!(watcher.look(&ns), Look::Fresh));
        watcher.set_dds_readers(1);
        assert_eq!(observers(), 1);

        let seg = Segment::open(&ns, "seen").unwrap();
        let state = &seg.header().state;
        state.store(STATE_STOPPED, Ordering::Release);
        watcher.next_alive_check = Instant::now();
        assert!(matches!(watcher.look(&ns), Look::Stopped));
        assert_eq!(observers(), 0, "the presence connection is released when the framework reads as gone");

        state.store(STATE_RUNNING, Ordering::Release);
        watcher.next_open = Instant::now();
        assert!(matches!(watcher.look(&ns), Look::Fresh));
        watcher.set_dds_readers(1);
        let s = fw.domains[0].status();
        assert_eq!((s.connections.iter().filter(|c| c.observer).count(), s.dds_readers), (1, 1), "{:?}", s.connections);
    }

    /// Only the framework's own pause (its pattern in the word) and a resume that is not in the
    /// future hold a participant's timeout back: a segment written over cannot make a wait
    /// last for ever.
    #[test]
    fn only_a_real_pause_holds_a_wait_back() {
        let model = crate::ddf::parse_str(DDF, "seen.ddf").unwrap();
        let ns = format!("pauseword{}", std::process::id());
        let fw = Framework::create(&model, &FrameworkOptions { namespace: ns.clone(), ..Default::default() }).unwrap();
        let seg = Segment::open(&ns, "seen").unwrap();
        let timeout = Duration::from_millis(100);
        let h = seg.header();
        assert!(seg.step_wait_may_time_out(timeout), "never paused");
        fw.domains[0].set_paused(true);
        assert!(!seg.step_wait_may_time_out(timeout) && seg.paused());
        fw.domains[0].set_paused(false);
        assert!(!seg.step_wait_may_time_out(timeout), "just resumed: a whole timeout from the resume");
        h.resumed_ns.store(0, Ordering::Release);
        assert!(seg.step_wait_may_time_out(timeout));
        for garbage in [1u32, 2, 0xdead_beef, u32::MAX] {
            h.paused.store(garbage, Ordering::Release);
            assert!(seg.step_wait_may_time_out(timeout) && !seg.paused(), "paused word {garbage:#x}");
        }
        h.paused.store(0, Ordering::Release);
        h.resumed_ns.store(u64::MAX, Ordering::Release);
        assert!(seg.step_wait_may_time_out(timeout), "a resume in the future is garbage");
    }
}
