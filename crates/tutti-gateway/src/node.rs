//! The gateway's DDS participant and ROS 2 node, and the factory of its endpoints.
//!
//! Every endpoint is created through ros2-client's `Node`, so that ros_discovery_info
//! lists it under the gateway's node (plain rustdds endpoints work on the wire but are not
//! attributed to any node). Topics are created with rustdds directly, because only the
//! topic can carry OWNERSHIP (ros2-client's `QosProfile` has none).

use std::collections::HashMap;

use ros2_client::dds::rustdds::{DomainParticipant, DomainParticipantBuilder, RTPSEntity, Topic, TopicKind};
use ros2_client::dds::{Publisher, Subscription};
use ros2_client::{Context, Gid, Node, NodeName, NodeOptions};
use serde::Serialize;
use tutti_core::mapping::Qos;

use crate::{qos, GatewayError, GatewayOptions};

/// Bytes of a GUID prefix (the participant part of an endpoint GUID).
pub const PREFIX_LEN: usize = 12;

/// The participant, the node and the topics created so far.
pub struct Dds {
    pub participant: DomainParticipant,
    pub context: Context,
    pub node: Node,
    /// GUID prefix of our participant: samples from it are our own.
    pub own_prefix: [u8; PREFIX_LEN],
    topics: HashMap<String, Topic>,
}

impl std::fmt::Debug for Dds {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Dds").field("own_prefix", &self.own_prefix).field("topics", &self.topics.len()).finish()
    }
}

/// The GUID prefix of an endpoint gid.
pub fn prefix(gid: &Gid) -> [u8; PREFIX_LEN] {
    let mut p = [0u8; PREFIX_LEN];
    p.copy_from_slice(&gid.as_bytes()[..PREFIX_LEN]);
    p
}

/// A short printable form of a gid, for connection names and logs.
pub fn short(gid: &Gid) -> String {
    gid.as_bytes()[..16].iter().map(|b| format!("{b:02x}")).collect()
}

impl Dds {
    /// Joins DDS domain `opts.ros_domain_id` (restricted to `opts.interfaces` when given)
    /// and announces the node `opts.node_name`.
    pub fn open(opts: &GatewayOptions) -> Result<Dds, GatewayError> {
        let node_name = NodeName::new("/", &opts.node_name)
            .map_err(|e| GatewayError::Invalid(format!("invalid ROS 2 node name '{}': {e:?}", opts.node_name)))?;
        let mut b = DomainParticipantBuilder::new(opts.ros_domain_id);
        if !opts.interfaces.is_empty() {
            b = b.with_only_networks(opts.interfaces.clone());
        }
        let participant = b
            .build()
            .map_err(|e| GatewayError::dds(format!("a participant in DDS domain {}", opts.ros_domain_id), e))?;
        let context = Context::from_domain_participant(participant.clone())
            .map_err(|e| GatewayError::dds("the ROS 2 context", e))?;
        let node = context
            .new_node(node_name, NodeOptions::new().enable_rosout(false))
            .map_err(|e| GatewayError::dds(format!("the ROS 2 node '{}'", opts.node_name), format!("{e:?}")))?;
        let own_prefix = prefix(&Gid::from(participant.guid()));
        Ok(Dds { participant, context, node, own_prefix, topics: HashMap::new() })
    }

    fn topic(&mut self, name: &str, type_name: &str, q: &Qos) -> Result<Topic, GatewayError> {
        if let Some(t) = self.topics.get(name) {
            return Ok(t.clone());
        }
        let t = self
            .participant
            .create_topic(name.to_string(), type_name.to_string(), &qos::topic_qos(q), TopicKind::NoKey)
            .map_err(|e| GatewayError::dds(format!("topic {name}"), e))?;
        self.topics.insert(name.to_string(), t.clone());
        Ok(t)
    }

    /// A node publisher on `topic` (type `type_name`) with the writer QoS `q`.
    pub fn publisher<M: Serialize>(
        &mut self,
        topic: &str,
        type_name: &str,
        q: &Qos,
    ) -> Result<Publisher<M>, GatewayError> {
        let t = self.topic(topic, type_name, q)?;
        self.node
            .create_publisher::<M>(&t, Some(qos::profile(q)))
            .map_err(|e| GatewayError::dds(format!("a writer on {topic}"), e))
    }

    /// A node subscription on `topic` (type `type_name`) with the reader QoS `q`.
    pub fn subscription<M: 'static>(
        &mut self,
        topic: &str,
        type_name: &str,
        q: &Qos,
    ) -> Result<Subscription<M>, GatewayError> {
        let t = self.topic(topic, type_name, q)?;
        self.node
            .create_subscription::<M>(&t, Some(qos::profile(q)))
            .map_err(|e| GatewayError::dds(format!("a reader on {topic}"), e))
    }
}
