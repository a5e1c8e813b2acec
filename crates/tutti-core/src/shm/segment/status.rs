//! What `tutti status` shows of a domain and its connections, and of every domain of a
//! namespace.

use serde::Serialize;

use super::conns::conn_name;
use super::format::PAUSED;
use super::names::check_namespace;
use super::Segment;
use crate::ddf::{Flags, Role};
use crate::shm::handshake::{CONN_OBSERVER, CONN_REMOTE, CONN_SYNC_READER, CONN_WRITER};
use crate::shm::os::{self, ProcessId};
use crate::shm::ShmError;
use crate::sync::Ordering;

impl Segment {
    /// Status of the domain and its connections, for `tutti status`.
    pub fn status(&self) -> DomainStatus {
        let h = self.header();
        let mut connections = Vec::new();
        for i in 0..self.scan_len() {
            let Some(c) = self.conn(i) else { break };
            let pid = c.active.load(Ordering::Acquire);
            if pid == 0 || c.ready.load(Ordering::Acquire) == 0 {
                continue;
            }
            let flags = c.flags.load(Ordering::Relaxed);
            connections.push(ConnectionInfo {
                slot: i as u32,
                pid,
                name: conn_name(c),
                writer: flags & CONN_WRITER != 0,
                sync_reader: flags & CONN_SYNC_READER != 0,
                remote: flags & CONN_REMOTE != 0,
                observer: flags & CONN_OBSERVER != 0,
                dds_readers: c.peers.load(Ordering::Relaxed),
                since_ns: c.since_ns.load(Ordering::Relaxed),
                reads: c.reads.load(Ordering::Relaxed),
                commits: c.commits.load(Ordering::Relaxed),
                missed_steps: c.missed.load(Ordering::Relaxed),
                link: LinkInfo::of(c),
                alive: os::is_alive(ProcessId { pid, start_time: c.start_time.load(Ordering::Relaxed) }),
            });
        }
        let owner_pid = self.exclusive_owner_pid();
        DomainStatus {
            domain: self.info.name.clone(),
            segment: format!("{}/{}", os::SHM_DIR, self.shm_name),
            flags: self.info.flags,
            framework_pid: h.owner_pid.load(Ordering::Relaxed),
            framework_alive: self.framework_alive(),
            step: h.pub_step.load(Ordering::Acquire),
            sim_time: f64::from_bits(h.sim_time_bits.load(Ordering::Relaxed)),
            period_ns: h.period_ns.load(Ordering::Relaxed),
            steps: h.steps.load(Ordering::Relaxed),
            overruns: h.overruns.load(Ordering::Relaxed),
            step_timeouts: h.timeouts.load(Ordering::Relaxed),
            max_late_ns: h.max_late_ns.load(Ordering::Relaxed),
            last_late_ns: h.last_late_ns.load(Ordering::Relaxed),
            publish_commits: self.generation(Role::Publish),
            subscribe_commits: self.generation(Role::Subscribe),
            rejected: h.rejected.load(Ordering::Relaxed),
            seeded: h.seeded.load(Ordering::Relaxed) != 0,
            waiting_to_go: h.hold.load(Ordering::Relaxed) != 0,
            paused: h.paused.load(Ordering::Relaxed) == PAUSED,
            connection_count: h.conn_count.load(Ordering::Relaxed),
            dds_writers: h.remote_count.load(Ordering::Relaxed),
            // DDS readers of the domain's topics, as the live gateways attached to it count them.
            dds_readers: connections.iter().filter(|c| c.observer).map(|c| c.dds_readers).sum(),
            owner_pid,
            connections,
        }
    }
}

/// A remote writer's link to another site with a lookahead (docs/run.md, "Sites and
/// lookahead"), as the gateway last wrote it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct LinkInfo {
    /// Steps of lookahead.
    pub lookahead: u64,
    /// Steps the framework is ahead of the newest answer received.
    pub ahead: u64,
    /// The latest round trip from a step's publication to its answer's arrival, µs.
    pub rtt_us: u64,
    /// Steps that waited for the link.
    pub link_waits: u64,
}

impl LinkInfo {
    /// The slot's link figures; None for a connection without a lookahead.
    fn of(c: &super::format::ConnSlot) -> Option<LinkInfo> {
        let [lookahead, ahead, rtt_us, link_waits] = c.link.each_ref().map(|v| v.load(Ordering::Relaxed));
        (lookahead > 0).then_some(LinkInfo { lookahead, ahead, rtt_us, link_waits })
    }
}

/// One connection, as `tutti status` shows it.
#[derive(Debug, Clone, Serialize)]
pub struct ConnectionInfo {
    pub slot: u32,
    pub pid: u32,
    pub name: String,
    pub writer: bool,
    pub sync_reader: bool,
    /// Stands for a DDS-side writer bridged by the gateway.
    pub remote: bool,
    /// A passive observer (a gateway bridging the domain): never waited for, not a
    /// participant.
    pub observer: bool,
    /// An observer's count of the DDS readers of the domain's topics.
    pub dds_readers: u64,
    pub since_ns: u64,
    pub reads: u64,
    pub commits: u64,
    pub missed_steps: u64,
    /// A remote writer across a link with a lookahead: its figures (absent otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub link: Option<LinkInfo>,
    pub alive: bool,
}

/// A live domain, as `tutti status` shows it.
#[derive(Debug, Clone, Serialize)]
pub struct DomainStatus {
    pub domain: String,
    pub segment: String,
    pub flags: Flags,
    pub framework_pid: u32,
    pub framework_alive: bool,
    pub step: u64,
    pub sim_time: f64,
    pub period_ns: u64,
    pub steps: u64,
    pub overruns: u64,
    pub step_timeouts: u64,
    pub max_late_ns: u64,
    pub last_late_ns: u64,
    pub publish_commits: u64,
    pub subscribe_commits: u64,
    pub rejected: u64,
    pub seeded: bool,
    pub waiting_to_go: bool,
    /// The framework's run is paused (`tutti ctl pause`).
    pub paused: bool,
    /// Participants (components), not counting DDS writers or observers.
    pub connection_count: u32,
    /// Connections standing for DDS writers, through the gateway.
    pub dds_writers: u32,
    /// DDS readers of the domain's topics, as the gateways bridging it count them.
    pub dds_readers: u64,
    pub owner_pid: Option<u32>,
    pub connections: Vec<ConnectionInfo>,
}

/// Every domain segment of namespace `ns`, opened and checked (a segment that fails its
/// checks is reported as an error, not skipped).
pub fn list_domains(ns: &str) -> Result<Vec<Result<DomainStatus, ShmError>>, ShmError> {
    check_namespace(ns)?;
    let prefix = format!("tutti.{ns}.");
    let names = os::list_shm(&prefix).map_err(|e| ShmError::io(format!("listing {}", os::SHM_DIR), e))?;
    Ok(names.iter().map(|n| Segment::open(ns, &n[prefix.len()..]).map(|s| s.status())).collect())
}
