//! The services and the action the gateway offers (docs/ros2.md): their ROS 2 names under the
//! gateway's namespace, their message types, and the QoS of the action's topics. How a
//! service travels on the wire is the engine's (`tutti_engine::Engine::serve`).

use tutti_core::mapping::{Durability, History, Ownership, Qos, Reliability};
use tutti_engine::TopicType;

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
        lifespan: None,
    }
}

/// rmw's services default: reliable, volatile, keep last 10.
pub fn qos() -> Qos {
    Qos {
        reliability: Reliability::Reliable,
        history: History::KeepLast(10),
        durability: Durability::Volatile,
        ownership: Ownership::Shared,
        lifespan: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::ros_name;

    #[test]
    fn names_as_rmw_cyclonedds_makes_them() {
        assert_eq!(ros_name("", "get_simulation_state"), "/get_simulation_state");
        assert_eq!(ros_name("sim/a", "step_simulation"), "/sim/a/step_simulation");
        assert_eq!(SERVICES[2].request_type(), "simulation_interfaces::srv::dds_::SetSimulationState_Request_");
        assert_eq!(SERVICES[3].response_type(), "simulation_interfaces::srv::dds_::StepSimulation_Response_");
        assert_eq!(ros_name("", SERVICES[5].name), "/simulate_steps/_action/send_goal");
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
}
