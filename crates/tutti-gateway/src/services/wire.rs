//! How a ROS 2 service travels over DDS in rmw_cyclonedds's layout (docs/ros2.md, "Wire
//! forms"): service `NAME` under namespace `NS` is the request topic `rq/NS/NAMERequest` and
//! the reply topic `rr/NS/NAMEReply`, with the types `PKG::srv::dds_::SRV_Request_` and
//! `…_Response_`, and the QoS of rmw's services default. Each sample's body starts with
//! the request header: the client's 64-bit writer id and the request's sequence number,
//! which the reply echoes and by which the client pairs the reply with its request.

use tutti_core::cdr::CdrError;
use tutti_core::mapping::{Durability, History, Ownership, Qos, Reliability};

use super::messages::{Body, Out};

/// What a service does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    GetFeatures,
    GetState,
    SetState,
    Step,
    Reset,
}

/// A service: its relative ROS name and its type.
#[derive(Debug)]
pub struct Service {
    pub name: &'static str,
    /// `simulation_interfaces/srv/NAME`'s last part.
    pub srv: &'static str,
    pub kind: Kind,
}

impl Service {
    pub fn request_type(&self) -> String {
        format!("simulation_interfaces::srv::dds_::{}_Request_", self.srv)
    }

    pub fn response_type(&self) -> String {
        format!("simulation_interfaces::srv::dds_::{}_Response_", self.srv)
    }
}

/// The services, in the order the gateway creates them.
pub const SERVICES: &[Service] = &[
    Service { name: "get_simulator_features", srv: "GetSimulatorFeatures", kind: Kind::GetFeatures },
    Service { name: "get_simulation_state", srv: "GetSimulationState", kind: Kind::GetState },
    Service { name: "set_simulation_state", srv: "SetSimulationState", kind: Kind::SetState },
    Service { name: "step_simulation", srv: "StepSimulation", kind: Kind::Step },
    Service { name: "reset_simulation", srv: "ResetSimulation", kind: Kind::Reset },
];

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_as_rmw_cyclonedds_makes_them() {
        assert_eq!(request_topic("", "get_simulation_state"), "rq/get_simulation_stateRequest");
        assert_eq!(reply_topic("sim/a", "step_simulation"), "rr/sim/a/step_simulationReply");
        assert_eq!(SERVICES[2].request_type(), "simulation_interfaces::srv::dds_::SetSimulationState_Request_");
        assert_eq!(SERVICES[3].response_type(), "simulation_interfaces::srv::dds_::StepSimulation_Response_");
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
}
