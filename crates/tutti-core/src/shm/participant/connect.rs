//! Joining a domain and leaving it: the connection's slot, the checks that it still
//! stands, and the wait for the framework's wait-to-go.

use std::sync::Arc;
use std::time::{Duration, Instant};

use super::due::Due;
use super::gate::GateFor;
use super::{ConnectOptions, Participant};
use crate::ddf::{Domain, Leaf, Role};
use crate::shm::segment::{DomainInfo, Segment, Waited, Waiter};
use crate::shm::{os, ShmError};
use crate::sync::Ordering;

impl Participant {
    /// Connects to domain `domain`: waits (up to `connect_timeout`) for its framework, then
    /// for wait-to-go unless skipped.
    pub fn connect(domain: &str, opts: ConnectOptions) -> Result<Participant, ShmError> {
        let deadline = Instant::now() + opts.connect_timeout;
        let seg = loop {
            let err = match Segment::open(&opts.namespace, domain) {
                Ok(seg) if seg.framework_alive() => break seg,
                Ok(_) => ShmError::FrameworkStopped { domain: domain.to_string() },
                Err(e @ (ShmError::NoSuchDomain { .. } | ShmError::NotReady { .. })) => e,
                Err(e) => return Err(e),
            };
            if Instant::now() >= deadline {
                return Err(err);
            }
            std::thread::sleep(Duration::from_millis(5));
        };
        let me = os::current_process();
        let slot = seg.claim_slot(me, &opts.name, opts.kind, opts.state.is_some())?;
        let id = seg.conn_id(slot);
        let (pub_size, sub_size) = (seg.info.publish.size as usize, seg.info.subscribe.size as usize);
        let mut p = Participant {
            snapshot: vec![0; pub_size],
            staging: vec![0; sub_size],
            shadow: vec![0; sub_size],
            marked: vec![false; seg.info.subscribe.leaves.len()],
            changed: Vec::with_capacity(seg.info.subscribe.leaves.len()),
            last_read: 0,
            last_commit: 0,
            locked_step: 0,
            has_read: false,
            // Start from the SUBSCRIBE values as they are: a commit changes only what we change.
            stale_staging: true,
            framework_seen: std::cell::Cell::new(Instant::now()),
            read_sim: 0.0,
            read_index: 0,
            due: Due::default(),
            seg: Arc::new(seg),
            slot,
            id,
            me,
            opts,
        };
        if let Some(c) = p.seg.conn(slot) {
            p.last_read = c.last_read.load(Ordering::Relaxed);
            p.last_commit = p.last_read;
        }
        p.refresh_staging()?;
        p.seg.read_set(Role::Publish, &mut p.snapshot)?;
        if !p.opts.skip_wait_to_go {
            p.wait_ready_to_go_until(deadline)?;
        }
        p.join_lock_step();
        Ok(p)
    }

    /// A connection claimed while the framework held wait-to-go (its first step deferred, see
    /// `Segment::claim_slot`) takes part in lock-step from the framework's next step on.
    fn join_lock_step(&mut self) {
        let Some(c) = self.seg.conn(self.slot) else { return };
        if c.first_step.load(Ordering::Acquire) == u64::MAX {
            let k = self.seg.step();
            c.last_read.store(k, Ordering::Relaxed);
            c.last_commit.store(k, Ordering::Relaxed);
            c.answered.store(k, Ordering::Relaxed);
            // The framework's release (`DomainHost::set_hold`) may set it first.
            let _ = c.first_step.compare_exchange(u64::MAX, k + 1, Ordering::AcqRel, Ordering::Acquire);
        }
        (self.last_read, self.last_commit) =
            (c.last_read.load(Ordering::Acquire), c.last_commit.load(Ordering::Acquire));
    }

    /// Connects and checks that `domain` (from a DDF) describes the running domain: the same
    /// flags and, in each set, the same items (paths, types, lengths). The items may be listed
    /// in another order (the product's tools do not agree on one): every access goes through
    /// the running domain's layout, by path or item key.
    pub fn connect_checked(domain: &Domain, opts: ConnectOptions) -> Result<Participant, ShmError> {
        let p = Participant::connect(&domain.name, opts)?;
        if p.seg.info.layout_hash != domain.layout_hash {
            if let Some(difference) = describe_difference(domain, &p.seg.info) {
                return Err(ShmError::LayoutMismatch {
                    domain: domain.name.clone(),
                    expected: domain.layout_hash,
                    found: p.seg.info.layout_hash,
                    difference,
                });
            }
        }
        Ok(p)
    }

    /// Whether the connection is still in place (the framework removes connections it
    /// judges dead) and the framework runs.
    pub fn check(&self) -> Result<(), ShmError> {
        // A framework killed outright cannot mark its segment stopped: look at its process
        // now and then (a /proc read costs microseconds; every call would be too many).
        let look = self.framework_seen.get().elapsed() >= Duration::from_millis(50);
        let r = self.waiting(GateFor::Nothing).check(&self.seg, look);
        if look && r.is_ok() {
            self.framework_seen.set(Instant::now());
        }
        r
    }

    /// [`check`](Self::check), looking at the framework's process every time (a wait's
    /// periodic check).
    pub(super) fn check_alive(&self) -> Result<(), ShmError> {
        self.waiting(GateFor::Nothing).check(&self.seg, true)
    }

    pub(super) fn timeout(&self, what: &'static str, after: Duration) -> ShmError {
        ShmError::Timeout { domain: self.seg.info.name.clone(), what, ms: after.as_millis() as u64 }
    }

    fn waiter(&self, futex: &'static str) -> Waiter<'_> {
        let h = self.seg.header();
        let (futex, waiters) = match futex {
            "hold" => (&h.hold, &h.go_waiters),
            _ => (&h.step_seq, &h.step_waiters),
        };
        Waiter { mode: self.opts.wait, futex, waiters, check_every: Duration::from_millis(20) }
    }

    /// Blocks while the framework holds its wait-to-go signal (at most the connect timeout).
    pub fn wait_ready_to_go(&self) -> Result<(), ShmError> {
        self.wait_ready_to_go_until(Instant::now() + self.opts.connect_timeout)
    }

    /// A state request made while it holds (the framework's checkpoint of step 0) is answered
    /// here: the connection has not started, so its state is the boundary's.
    fn wait_ready_to_go_until(&self, deadline: Instant) -> Result<(), ShmError> {
        let h = self.seg.header();
        let w = self.waiter("hold");
        let released_or_asked = || Ok(h.hold.load(Ordering::Acquire) == 0 || self.seg.state_pending(self.slot));
        loop {
            match w.wait(deadline, released_or_asked, || self.check_alive())? {
                Waited::Ready if self.serve_state() => {}
                Waited::Ready => return Ok(()),
                Waited::TimedOut => return Err(self.timeout("wait-to-go", self.opts.connect_timeout)),
            }
        }
    }

    /// Leaves the domain: releases the slot, ownership and pending handshakes.
    pub fn disconnect(mut self) {
        self.release();
    }

    /// Releases the slot unless it is no longer this connection's (released already, or
    /// removed by the framework: either bumps the slot's generation, so the id differs).
    fn release(&mut self) {
        if self.seg.conn_id(self.slot) == self.id {
            self.seg.release_slot(self.slot, self.me.pid);
        }
    }
}

impl Drop for Participant {
    fn drop(&mut self) {
        self.release();
    }
}

/// The first way `domain` (from a DDF) differs from the running domain `live`, ignoring the
/// order of the items; `None` when they have the same flags and items.
pub fn describe_difference(domain: &Domain, live: &DomainInfo) -> Option<String> {
    let yn = |b: bool| if b { "yes" } else { "no" };
    for (name, ddf, running) in [
        ("synchronous", domain.flags.synchronous, live.flags.synchronous),
        ("multiplePublishAllowed", domain.flags.multiple_publish_allowed, live.flags.multiple_publish_allowed),
        ("states", domain.flags.states, live.flags.states),
    ] {
        if ddf != running {
            return Some(format!("<{name}> is {} in the DDF, {} in the running domain", yn(ddf), yn(running)));
        }
    }
    for role in Role::ALL {
        let ddf = &domain.set(role).layout.leaves;
        let running = &live.set(role).leaves;
        let describe = |l: &Leaf| format!("{} {}[{}]", l.path, l.ty.canonical(), l.length);
        for l in ddf {
            match running.iter().find(|r| r.path == l.path) {
                None => return Some(format!("{role} item '{}' is not in the running domain", l.path)),
                Some(r) if r.ty != l.ty || r.length != l.length => {
                    return Some(format!(
                        "{role} item: the DDF has {}, the running domain {}",
                        describe(l),
                        describe(r)
                    ))
                }
                Some(_) => {}
            }
        }
        if let Some(r) = running.iter().find(|r| !ddf.iter().any(|l| l.path == r.path)) {
            return Some(format!("{role} item '{}' of the running domain is not in the DDF", r.path));
        }
    }
    None
}
