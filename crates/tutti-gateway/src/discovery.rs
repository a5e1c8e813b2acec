//! Matching bookkeeping: which remote (not our participant's) DDS writers and readers are
//! on which topic, from rustdds' discovery database.
//!
//! rustdds 0.15 has no working matched-endpoint queries (`get_matched_publications` is
//! always empty, `get_matched_subscriptions` panics), so the manager polls the discovered
//! endpoints and compares them with the connections it holds.

use std::collections::{BTreeSet, HashMap};

use ros2_client::dds::rustdds::DomainParticipant;
use ros2_client::Gid;

use crate::node::{prefix, PREFIX_LEN};

/// Remote endpoints per topic name.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct Remote {
    pub writers: HashMap<String, BTreeSet<Gid>>,
    pub readers: HashMap<String, BTreeSet<Gid>>,
}

impl Remote {
    /// The remote endpoints discovered by `dp`, leaving out those of prefix `own`.
    pub fn discover(dp: &DomainParticipant, own: &[u8; PREFIX_LEN]) -> Remote {
        let mut r = Remote::default();
        for w in dp.discovered_writers() {
            let gid = Gid::from(w.writer_proxy.remote_writer_guid);
            if prefix(&gid) != *own {
                r.writers.entry(w.publication_topic_data.topic_name.clone()).or_default().insert(gid);
            }
        }
        for rd in dp.discovered_readers() {
            let gid = Gid::from(rd.reader_proxy.remote_reader_guid);
            if prefix(&gid) != *own {
                r.readers.entry(rd.subscription_topic_data.topic_name().clone()).or_default().insert(gid);
            }
        }
        r
    }

    /// Remote writers on `topic`.
    pub fn writers_on<'a>(&'a self, topic: &str) -> impl Iterator<Item = Gid> + 'a {
        self.writers.get(topic).into_iter().flatten().copied()
    }

    /// Remote readers on any of `topics` (each once).
    pub fn readers_on(&self, topics: &[String]) -> BTreeSet<Gid> {
        topics.iter().filter_map(|t| self.readers.get(t)).flatten().copied().collect()
    }
}
