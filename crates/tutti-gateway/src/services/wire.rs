//! How a ROS 2 service travels over DDS in rmw_cyclonedds's layout (docs/ros2.md, "Wire
//! forms"): service `NAME` under namespace `NS` is the request topic `rq/NS/NAMERequest` and
//! the reply topic `rr/NS/NAMEReply`, with the types `PKG::srv::dds_::SRV_Request_` and
//! `…_Response_`, and the QoS of rmw's services default. Each sample's body starts with
//! the request header: the client's 64-bit writer id and the request's sequence number,
//! which the reply echoes and by which the client pairs the reply with its request.
//!
//! The same services in Fast DDS's form (rmw_fastrtps, ros2-client's `Enhanced` mapping) have
//! the same names, types and QoS, but no header: the request is named by its own sample
//! identity and the reply carries it as its related sample identity. [`ReplyTo::of`] tells
//! the forms apart, request by request.

use tutti_core::cdr::CdrError;
use tutti_core::mapping::{Durability, History, Ownership, Qos, Reliability};

use super::messages::{Body, Out};
use crate::engine::{Guid, Identified, SampleIdentity, TopicType};

/// What a service does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    GetFeatures,
    GetState,
    SetState,
    Step,
    Reset,
    /// The action `simulate_steps`'s three services.
    SendGoal,
    GetResult,
    CancelGoal,
}

/// A service: its relative ROS name and its DDS types (the package's type, `::dds_::`, the
/// `_Request_` or `_Response_` suffix).
#[derive(Debug)]
pub struct Service {
    pub name: &'static str,
    /// `PKG::srv::dds_::SRV` (or `PKG::action::dds_::ACTION_SendGoal`, …).
    pub dds_type: &'static str,
    pub kind: Kind,
}

impl Service {
    pub fn request_type(&self) -> String {
        format!("{}_Request_", self.dds_type)
    }

    pub fn response_type(&self) -> String {
        format!("{}_Response_", self.dds_type)
    }

    /// The type of the request topic's endpoints: the request message, with its ROS 2 type
    /// hash (`PKG/srv/SRV_Request`'s, as rmw_cyclonedds announces it; docs/gateway.md, "Type
    /// hashes").
    pub fn request_topic_type(&self) -> TopicType {
        TopicType::stock(&self.request_type())
    }

    /// The type of the reply topic's endpoints: the response message, with its hash.
    pub fn response_topic_type(&self) -> TopicType {
        TopicType::stock(&self.response_type())
    }
}

/// The type of a topic of the action ([`FEEDBACK`], [`STATUS`]), with its hash.
pub fn action_topic_type((_, dds_type): (&str, &str)) -> TopicType {
    TopicType::stock(dds_type)
}

/// The action's relative name; its services and topics are under `NAME/_action/`.
pub const ACTION: &str = "simulate_steps";

/// The services, in the order the gateway creates them: the five, then the action's.
pub const SERVICES: &[Service] = &[
    Service {
        name: "get_simulator_features",
        dds_type: "simulation_interfaces::srv::dds_::GetSimulatorFeatures",
        kind: Kind::GetFeatures,
    },
    Service {
        name: "get_simulation_state",
        dds_type: "simulation_interfaces::srv::dds_::GetSimulationState",
        kind: Kind::GetState,
    },
    Service {
        name: "set_simulation_state",
        dds_type: "simulation_interfaces::srv::dds_::SetSimulationState",
        kind: Kind::SetState,
    },
    Service { name: "step_simulation", dds_type: "simulation_interfaces::srv::dds_::StepSimulation", kind: Kind::Step },
    Service {
        name: "reset_simulation",
        dds_type: "simulation_interfaces::srv::dds_::ResetSimulation",
        kind: Kind::Reset,
    },
    Service {
        name: "simulate_steps/_action/send_goal",
        dds_type: "simulation_interfaces::action::dds_::SimulateSteps_SendGoal",
        kind: Kind::SendGoal,
    },
    Service {
        name: "simulate_steps/_action/get_result",
        dds_type: "simulation_interfaces::action::dds_::SimulateSteps_GetResult",
        kind: Kind::GetResult,
    },
    Service {
        name: "simulate_steps/_action/cancel_goal",
        dds_type: "action_msgs::srv::dds_::CancelGoal",
        kind: Kind::CancelGoal,
    },
];

/// The action's feedback topic and type.
pub const FEEDBACK: (&str, &str) =
    ("simulate_steps/_action/feedback", "simulation_interfaces::action::dds_::SimulateSteps_FeedbackMessage_");
/// The action's status topic and type.
pub const STATUS: (&str, &str) = ("simulate_steps/_action/status", "action_msgs::msg::dds_::GoalStatusArray_");

/// rcl_action's status QoS: reliable, transient local, keep last 1 (a late client gets the
/// goals' last statuses).
pub fn status_qos() -> Qos {
    Qos {
        reliability: Reliability::Reliable,
        history: History::KeepLast(1),
        durability: Durability::TransientLocal { depth: 1 },
        ownership: Ownership::Shared,
    }
}

fn topic(prefix: &str, ns: &str, name: &str, suffix: &str) -> String {
    if ns.is_empty() {
        format!("{prefix}/{name}{suffix}")
    } else {
        format!("{prefix}/{ns}/{name}{suffix}")
    }
}

/// `rq/NS/NAMERequest` (`rq/NAMERequest` without a namespace).
pub fn request_topic(ns: &str, name: &str) -> String {
    topic("rq", ns, name, "Request")
}

/// `rr/NS/NAMEReply`.
pub fn reply_topic(ns: &str, name: &str) -> String {
    topic("rr", ns, name, "Reply")
}

/// rmw's services default: reliable, volatile, keep last 10.
pub fn qos() -> Qos {
    Qos {
        reliability: Reliability::Reliable,
        history: History::KeepLast(10),
        durability: Durability::Volatile,
        ownership: Ownership::Shared,
    }
}

/// The request header at the start of a body.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RequestHeader {
    /// The client's request writer, as rmw_cyclonedds names it (its instance handle).
    pub client: u64,
    pub sequence: i64,
}

impl RequestHeader {
    /// Its size: the request's own fields start here.
    pub const LEN: usize = 16;

    pub fn read(b: Body<'_>) -> Result<RequestHeader, CdrError> {
        Ok(RequestHeader { client: b.u64(0)?, sequence: b.u64(8)? as i64 })
    }

    pub fn write(&self, out: &mut Out) {
        out.u64(self.client).i64(self.sequence);
    }
}

/// The vendor id Cyclone DDS puts at the head of its GUID prefixes (as Fast DDS and rustdds put
/// theirs).
pub const CYCLONE_VENDOR: [u8; 2] = [0x01, 0x10];

/// How a request names itself, and so how its reply names it back: the two wire forms
/// (docs/ros2.md, "Wire forms").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReplyTo {
    /// rmw_cyclonedds's: the request header at the start of the body, echoed by the reply.
    Header(RequestHeader),
    /// Fast DDS's: no header; the reply carries this as its related sample identity.
    Related(SampleIdentity),
}

impl ReplyTo {
    /// The form of `sample` (whose body, after the encapsulation header, is `body`):
    /// * an engine that reads no sample identity (Cyclone) serves rmw_cyclonedds's form only;
    /// * a request that carries a related sample identity is in Fast DDS's form (rmw_fastrtps
    ///   sets one on every request: the GUID of its reply reader), and its reply goes to that
    ///   GUID (its own writer's if the identity names none) with the request's sequence number;
    /// * otherwise a request written by a Cyclone DDS participant (its GUID prefix starts with
    ///   Cyclone's vendor id) is in rmw_cyclonedds's form, and any other (ros2-client's
    ///   `Enhanced` clients write no related identity) in Fast DDS's.
    pub fn of(sample: &Identified<'_>, body: Body<'_>) -> Result<ReplyTo, CdrError> {
        let Some(sequence) = sample.sequence else { return RequestHeader::read(body).map(ReplyTo::Header) };
        match sample.related {
            Some(r) => {
                let writer = if r.writer == Guid::default() { sample.writer } else { r.writer };
                Ok(ReplyTo::Related(SampleIdentity { writer, sequence }))
            }
            None if sample.writer.0[..2] == CYCLONE_VENDOR => RequestHeader::read(body).map(ReplyTo::Header),
            None => Ok(ReplyTo::Related(SampleIdentity { writer: sample.writer, sequence })),
        }
    }

    /// Where the request's own fields start in its body.
    pub fn fields_at(&self) -> usize {
        match self {
            ReplyTo::Header(_) => RequestHeader::LEN,
            ReplyTo::Related(_) => 0,
        }
    }

    /// Starts a reply's body: the echoed header, or nothing.
    pub fn start(&self, out: &mut Out) {
        if let ReplyTo::Header(h) = self {
            h.write(out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_as_rmw_cyclonedds_makes_them() {
        assert_eq!(request_topic("", "get_simulation_state"), "rq/get_simulation_stateRequest");
        assert_eq!(reply_topic("sim/a", "step_simulation"), "rr/sim/a/step_simulationReply");
        assert_eq!(SERVICES[2].request_type(), "simulation_interfaces::srv::dds_::SetSimulationState_Request_");
        assert_eq!(SERVICES[3].response_type(), "simulation_interfaces::srv::dds_::StepSimulation_Response_");
        assert_eq!(request_topic("", SERVICES[5].name), "rq/simulate_steps/_action/send_goalRequest");
        assert_eq!(SERVICES[7].request_type(), "action_msgs::srv::dds_::CancelGoal_Request_");
    }

    #[test]
    fn every_endpoint_announces_its_messages_type_hash() {
        for s in SERVICES {
            for ty in [s.request_topic_type(), s.response_topic_type()] {
                assert!(ty.hash.is_some(), "{} has no type hash", ty.name);
            }
        }
        for topic in [FEEDBACK, STATUS] {
            assert!(action_topic_type(topic).hash.is_some(), "{} has no type hash", topic.1);
        }
        // As rosidl's generator hashes it (the tests of tutti-ros2 pin more).
        assert_eq!(
            SERVICES[3].request_topic_type().user_data().as_deref(),
            Some("typehash=RIHS01_cda33f6887815f3dce0f90e61fd8efd39bda13ae264ddede15c33fbad890630e;")
        );
    }

    #[test]
    fn the_header_is_echoed_in_little_endian_whatever_the_request_order() {
        let mut be = Vec::new();
        be.extend_from_slice(&0x0102_0304_0506_0708u64.to_be_bytes());
        be.extend_from_slice(&9i64.to_be_bytes());
        let h = RequestHeader::read(Body { le: false, bytes: &be }).unwrap();
        assert_eq!(h, RequestHeader { client: 0x0102_0304_0506_0708, sequence: 9 });
        let mut out = Out::default();
        h.write(&mut out);
        assert_eq!(&out.0[..8], &0x0102_0304_0506_0708u64.to_le_bytes());
        assert_eq!(&out.0[8..], &9i64.to_le_bytes());
        assert!(RequestHeader::read(Body { le: true, bytes: &be[..12] }).is_err());
    }

    fn sample(writer: [u8; 2], sequence: Option<i64>, related: Option<SampleIdentity>) -> Identified<'static> {
        let mut g = [7u8; 16];
        g[..2].copy_from_slice(&writer);
        Identified { writer: Guid(g), sequence, related, raw: &[] }
    }

    #[test]
    fn each_request_is_answered_in_its_own_form() {
        let mut header = Vec::new();
        header.extend_from_slice(&0x0102_0304_0506_0708u64.to_le_bytes());
        header.extend_from_slice(&9i64.to_le_bytes());
        let body = Body { le: true, bytes: &header };
        let cyclone_header = ReplyTo::Header(RequestHeader { client: 0x0102_0304_0506_0708, sequence: 9 });
        // The Cyclone engine reads no identity: rmw_cyclonedds's form whoever writes.
        assert_eq!(ReplyTo::of(&sample([0x01, 0x0f], None, None), body).unwrap(), cyclone_header);
        // A Cyclone DDS client, no related identity: rmw_cyclonedds's form.
        assert_eq!(ReplyTo::of(&sample(CYCLONE_VENDOR, Some(3), None), body).unwrap(), cyclone_header);
        assert_eq!(cyclone_header.fields_at(), 16);
        // ros2-client's Enhanced client (rustdds): its own identity.
        let s = sample([0x01, 0x12], Some(3), None);
        assert_eq!(ReplyTo::of(&s, body).unwrap(), ReplyTo::Related(SampleIdentity { writer: s.writer, sequence: 3 }));
        // rmw_fastrtps: the reply reader's GUID in the related identity, the sequence number unknown.
        let reader = Guid([9; 16]);
        let unknown = SampleIdentity { writer: reader, sequence: -(1 << 32) };
        let s = sample([0x01, 0x0f], Some(5), Some(unknown));
        let to = ReplyTo::of(&s, body).unwrap();
        assert_eq!(to, ReplyTo::Related(SampleIdentity { writer: reader, sequence: 5 }));
        assert_eq!(to.fields_at(), 0);
        let mut out = Out::default();
        to.start(&mut out);
        assert!(out.0.is_empty(), "no header in Fast DDS's form");
        // A related identity wins over the vendor; one that names no writer names the request's.
        let none = SampleIdentity { writer: Guid::default(), sequence: 0 };
        let s = sample(CYCLONE_VENDOR, Some(6), Some(none));
        assert_eq!(ReplyTo::of(&s, body).unwrap(), ReplyTo::Related(SampleIdentity { writer: s.writer, sequence: 6 }));
        // rmw_cyclonedds's form without its header is refused.
        let short = Body { le: true, bytes: &header[..8] };
        assert!(ReplyTo::of(&sample(CYCLONE_VENDOR, Some(1), None), short).is_err());
    }
}
