//! ROS 2's `simulation_interfaces` services and the action `simulate_steps` as a tutti run
//! serves them (docs/ros2.md): under the gateway's ROS namespace, `get_simulator_features`,
//! `get_simulation_state`, `set_simulation_state`, `step_simulation` and `reset_simulation`,
//! and the action's `send_goal`, `get_result` and `cancel_goal`, each call carried out on the
//! run's control plane ([`lifecycle`]) as `tutti ctl` would, the goals on threads of their own
//! ([`action`]).
//!
//! Everything here is ROS 2's messages as [`Value`]s of their interface files: a request is
//! read by its fields' names, a response built by them, and the codec of the registry turns
//! either into CDR. How a request and its response travel is the engine's
//! (`tutti_engine::Engine::serve`); the gateway only wires the two together.

pub mod action;
pub mod entities;
pub mod lifecycle;

use tutti_core::ddf::Model;
use tutti_core::mapping::{Durability, History, Ownership, Qos, Reliability};

pub use self::action::{GoalId, Goals, Publisher, Stamp};
pub use self::entities::{Body, Entities, EntityCall, EntityInfo, Pose, SourceError};
pub use self::lifecycle::{Control, Lifecycle, Outcome, RunControl};
use crate::{registry, Message, Struct, Value};

/// `simulation_interfaces/msg/Result` codes.
pub mod result {
    pub const FEATURE_UNSUPPORTED: u8 = 0;
    pub const OK: u8 = 1;
    pub const NOT_FOUND: u8 = 2;
    pub const INCORRECT_STATE: u8 = 3;
    pub const OPERATION_FAILED: u8 = 4;
    /// `SetSimulationState`'s own codes.
    pub const ALREADY_IN_TARGET_STATE: u8 = 101;
    pub const STATE_TRANSITION_ERROR: u8 = 102;
    pub const INCORRECT_TRANSITION: u8 = 103;
}

/// `simulation_interfaces/msg/SimulationState` values.
pub mod state {
    pub const STOPPED: u8 = 0;
    pub const PLAYING: u8 = 1;
    pub const PAUSED: u8 = 2;
    pub const QUITTING: u8 = 3;
    pub const NO_WORLD: u8 = 4;
    pub const LOADING_WORLD: u8 = 5;
}

/// `simulation_interfaces/msg/SimulatorFeatures` values (those tutti names).
pub mod feature {
    pub const SIMULATION_RESET: u16 = 20;
    pub const SIMULATION_RESET_TIME: u16 = 21;
    pub const SIMULATION_RESET_STATE: u16 = 22;
    pub const SIMULATION_STATE_GETTING: u16 = 24;
    pub const SIMULATION_STATE_SETTING: u16 = 25;
    pub const SIMULATION_STATE_PAUSE: u16 = 26;
    pub const STEP_SIMULATION_SINGLE: u16 = 31;
    pub const STEP_SIMULATION_MULTIPLE: u16 = 32;
    pub const STEP_SIMULATION_ACTION: u16 = 33;
}

/// `simulation_interfaces/srv/ResetSimulation` scopes.
pub mod scope {
    pub const DEFAULT: u8 = 0;
    pub const TIME: u8 = 1;
    pub const STATE: u8 = 2;
    pub const SPAWNED: u8 = 4;
    pub const ALL: u8 = 255;
}

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
    /// The entity services ([`entities`]).
    Entity(EntityCall),
}

/// A service: its relative ROS name and its interface.
#[derive(Debug)]
pub struct ServiceDef {
    pub name: &'static str,
    /// The service's interface (`PKG/srv/NAME`, or an action's `PKG/action/NAME_SendGoal`).
    pub interface: &'static str,
    pub kind: Kind,
}

impl ServiceDef {
    /// Its request and response messages, from the registry.
    pub fn service(&self) -> crate::Service<'static> {
        match registry().service(self.interface) {
            Some(s) => s,
            // The table names embedded interfaces only (a unit test checks every one).
            None => unreachable!("{} is not an embedded interface", self.interface),
        }
    }
}

/// The action's relative name; its services and topics are under `NAME/_action/`.
pub const ACTION: &str = "simulate_steps";

/// The services, in the order the gateway creates them: the five, the action's, then the
/// entity services.
pub const SERVICES: &[ServiceDef] = &[
    ServiceDef {
        name: "get_simulator_features",
        interface: "simulation_interfaces/srv/GetSimulatorFeatures",
        kind: Kind::GetFeatures,
    },
    ServiceDef {
        name: "get_simulation_state",
        interface: "simulation_interfaces/srv/GetSimulationState",
        kind: Kind::GetState,
    },
    ServiceDef {
        name: "set_simulation_state",
        interface: "simulation_interfaces/srv/SetSimulationState",
        kind: Kind::SetState,
    },
    ServiceDef { name: "step_simulation", interface: "simulation_interfaces/srv/StepSimulation", kind: Kind::Step },
    ServiceDef { name: "reset_simulation", interface: "simulation_interfaces/srv/ResetSimulation", kind: Kind::Reset },
    ServiceDef {
        name: "simulate_steps/_action/send_goal",
        interface: "simulation_interfaces/action/SimulateSteps_SendGoal",
        kind: Kind::SendGoal,
    },
    ServiceDef {
        name: "simulate_steps/_action/get_result",
        interface: "simulation_interfaces/action/SimulateSteps_GetResult",
        kind: Kind::GetResult,
    },
    ServiceDef {
        name: "simulate_steps/_action/cancel_goal",
        interface: "action_msgs/srv/CancelGoal",
        kind: Kind::CancelGoal,
    },
    ServiceDef {
        name: "get_entities",
        interface: "simulation_interfaces/srv/GetEntities",
        kind: Kind::Entity(EntityCall::List),
    },
    ServiceDef {
        name: "get_entity_state",
        interface: "simulation_interfaces/srv/GetEntityState",
        kind: Kind::Entity(EntityCall::State),
    },
    ServiceDef {
        name: "get_entities_states",
        interface: "simulation_interfaces/srv/GetEntitiesStates",
        kind: Kind::Entity(EntityCall::States),
    },
    ServiceDef {
        name: "get_entity_info",
        interface: "simulation_interfaces/srv/GetEntityInfo",
        kind: Kind::Entity(EntityCall::Info),
    },
    ServiceDef {
        name: "set_entity_state",
        interface: "simulation_interfaces/srv/SetEntityState",
        kind: Kind::Entity(EntityCall::Set),
    },
];

/// A topic of the action: its relative ROS name and its message.
#[derive(Debug, Clone, Copy)]
pub struct TopicDef {
    pub name: &'static str,
    pub message: &'static str,
}

impl TopicDef {
    /// Its message, from the registry.
    pub fn message(&self) -> Message<'static> {
        match registry().message(self.message) {
            Some(m) => m,
            None => unreachable!("{} is not an embedded interface", self.message),
        }
    }
}

/// The action's feedback topic.
pub const FEEDBACK: TopicDef = TopicDef {
    name: "simulate_steps/_action/feedback",
    message: "simulation_interfaces/action/SimulateSteps_FeedbackMessage",
};
/// The action's status topic.
pub const STATUS: TopicDef =
    TopicDef { name: "simulate_steps/_action/status", message: "action_msgs/msg/GoalStatusArray" };

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

/// rmw's default QoS, as rcl_action's feedback topic has it: reliable, volatile, keep last 10
/// (the same terms as rmw's services default, [`services_qos`]).
pub fn feedback_qos() -> Qos {
    services_qos()
}

/// rmw's services default, which every service's request and reply topics have: reliable,
/// volatile, keep last 10.
pub fn services_qos() -> Qos {
    Qos {
        reliability: Reliability::Reliable,
        history: History::KeepLast(10),
        durability: Durability::Volatile,
        ownership: Ownership::Shared,
        lifespan: None,
    }
}

/// Why stepping cannot apply to a run of `model`: every domain is asynchronous.
pub fn no_stepping(model: &Model) -> Option<String> {
    if model.domains.iter().any(|d| d.flags.synchronous) {
        return None;
    }
    let names: Vec<&str> = model.domains.iter().map(|d| d.name.as_str()).collect();
    Some(format!(
        "every domain of this run is asynchronous ({}): their participants do not step with the framework, so \
         there is no step to count; set the state PLAYING and PAUSED instead",
        names.join(", ")
    ))
}

/// A request that does not have the fields of its message.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("a {service} request without its field {field}")]
pub struct BadRequest {
    pub service: &'static str,
    pub field: &'static str,
}

/// What a request gets.
#[derive(Debug, Clone, PartialEq)]
pub enum Answer {
    /// The response.
    Reply(Value),
    /// None yet: a `get_result` of a goal that runs; answered when [`Goals::ended`] says so.
    Wait(GoalId),
    /// The response of an accepted goal, which is now to be carried out ([`action::spawn`]).
    Accepted { reply: Value, goal: GoalId, steps: u64 },
}

/// `get_simulator_features`'s `custom_info`.
fn custom_info() -> String {
    format!("tutti {}: docs/ros2.md", env!("CARGO_PKG_VERSION"))
}

/// The services of one run: the answer to each request.
pub struct Simulation {
    pub life: Lifecycle,
    pub goals: std::sync::Arc<Goals>,
    /// The run's entities (none: [`NoEntities`]).
    pub entities: Box<dyn Entities>,
}

impl std::fmt::Debug for Simulation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Simulation").field("life", &self.life).field("entities", &self.entities.list()).finish()
    }
}

/// A run without entities: the entity services list none.
#[derive(Debug, Default)]
pub struct NoEntities;

impl Entities for NoEntities {
    fn list(&self) -> &[EntityInfo] {
        &[]
    }
    fn read(&mut self, _: &[usize]) -> Result<Vec<Body>, SourceError> {
        Ok(Vec::new())
    }
    fn write(&mut self, _: usize, _: &Pose, _: [f64; 3]) -> Result<(), SourceError> {
        Err("this run has no entities".into())
    }
}

impl Simulation {
    /// The answer to a request (its message as a [`Value`]) of service `SERVICES[service]`,
    /// made on the run's control plane `ctl`.
    pub fn answer(&mut self, service: usize, req: &Value, ctl: &mut dyn Control) -> Result<Answer, BadRequest> {
        let def = &SERVICES[service];
        let field = |name: &'static str| req.get(name).ok_or(BadRequest { service: def.name, field: name });
        let reply = |fields: Struct| Ok(Answer::Reply(fields.into()));
        match def.kind {
            Kind::GetFeatures => {
                // SCOPE_STATE only where the run holds its checkpoint of step 0.
                let state_reset = ctl.call(&tutti_host::control::Request::State).is_ok_and(|s| s.state_reset);
                let mut features = self.life.features(true, state_reset);
                features.extend(entities::features(self.entities.list()));
                features.sort_unstable();
                let features: Vec<Value> = features.into_iter().map(Value::from).collect();
                let f = Struct::new().with("features", features).with("custom_info", custom_info());
                reply(Struct::new().with("features", f))
            }
            Kind::GetState => {
                let (s, o) = self.life.get_state(ctl);
                reply(Struct::new().with("state", Struct::new().with("state", s)).with("result", o.value()))
            }
            Kind::SetState => {
                let target = field("state")?.get("state").and_then(Value::as_u64);
                let target = target.ok_or(BadRequest { service: def.name, field: "state.state" })?;
                let o = self.life.set_state(ctl, u8::try_from(target).unwrap_or(u8::MAX));
                reply(Struct::new().with("result", o.value()))
            }
            Kind::Step => {
                let steps = field("steps")?.as_u64().unwrap_or(0);
                reply(Struct::new().with("result", self.life.step(ctl, steps).value()))
            }
            Kind::Reset => {
                let s = field("scope")?.as_u64().and_then(|s| u8::try_from(s).ok()).unwrap_or(u8::MAX);
                reply(Struct::new().with("result", self.life.reset(ctl, s).value()))
            }
            Kind::SendGoal => {
                let goal = action::uuid(field("goal_id")?).ok_or(BadRequest { service: def.name, field: "goal_id" })?;
                let steps = field("goal")?.get("steps").and_then(Value::as_u64).unwrap_or(0);
                let (accepted, stamp) = self.goals.send_goal(goal);
                let reply = Struct::new().with("accepted", accepted).with("stamp", stamp.value()).into();
                Ok(if accepted { Answer::Accepted { reply, goal, steps } } else { Answer::Reply(reply) })
            }
            Kind::GetResult => {
                let goal = action::uuid(field("goal_id")?).ok_or(BadRequest { service: def.name, field: "goal_id" })?;
                Ok(self.goals.get_result(&goal).map_or(Answer::Wait(goal), Answer::Reply))
            }
            Kind::CancelGoal => {
                let info = field("goal_info")?;
                let goal = info.get("goal_id").and_then(action::uuid);
                let goal = goal.ok_or(BadRequest { service: def.name, field: "goal_info.goal_id" })?;
                let stamp = info.get("stamp").map(Stamp::of).unwrap_or_default();
                Ok(Answer::Reply(self.goals.cancel_goal(&goal, stamp)))
            }
            Kind::Entity(call) => Ok(Answer::Reply(entities::answer(call, def.name, req, self.entities.as_mut())?)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn constant(message: &str, name: &str) -> u64 {
        let m = registry().message(message).unwrap_or_else(|| panic!("{message}"));
        m.constant(name).and_then(Value::as_u64).unwrap_or_else(|| panic!("{message} has no {name}"))
    }

    /// The names the code uses for the interfaces' constants are their files' values.
    #[test]
    fn the_constants_are_the_interfaces_own() {
        let r = "simulation_interfaces/msg/Result";
        for (name, v) in [
            ("RESULT_FEATURE_UNSUPPORTED", result::FEATURE_UNSUPPORTED),
            ("RESULT_OK", result::OK),
            ("RESULT_NOT_FOUND", result::NOT_FOUND),
            ("RESULT_INCORRECT_STATE", result::INCORRECT_STATE),
            ("RESULT_OPERATION_FAILED", result::OPERATION_FAILED),
        ] {
            assert_eq!(constant(r, name), u64::from(v), "{name}");
        }
        let s = "simulation_interfaces/srv/SetSimulationState_Response";
        for (name, v) in [
            ("ALREADY_IN_TARGET_STATE", result::ALREADY_IN_TARGET_STATE),
            ("STATE_TRANSITION_ERROR", result::STATE_TRANSITION_ERROR),
            ("INCORRECT_TRANSITION", result::INCORRECT_TRANSITION),
        ] {
            assert_eq!(constant(s, name), u64::from(v), "{name}");
        }
        let st = "simulation_interfaces/msg/SimulationState";
        for (name, v) in [
            ("STATE_STOPPED", state::STOPPED),
            ("STATE_PLAYING", state::PLAYING),
            ("STATE_PAUSED", state::PAUSED),
            ("STATE_QUITTING", state::QUITTING),
            ("STATE_NO_WORLD", state::NO_WORLD),
            ("STATE_LOADING_WORLD", state::LOADING_WORLD),
        ] {
            assert_eq!(constant(st, name), u64::from(v), "{name}");
        }
        let f = "simulation_interfaces/msg/SimulatorFeatures";
        for (name, v) in [
            ("SIMULATION_RESET", feature::SIMULATION_RESET),
            ("SIMULATION_RESET_TIME", feature::SIMULATION_RESET_TIME),
            ("SIMULATION_STATE_GETTING", feature::SIMULATION_STATE_GETTING),
            ("SIMULATION_STATE_SETTING", feature::SIMULATION_STATE_SETTING),
            ("SIMULATION_STATE_PAUSE", feature::SIMULATION_STATE_PAUSE),
            ("STEP_SIMULATION_SINGLE", feature::STEP_SIMULATION_SINGLE),
            ("STEP_SIMULATION_MULTIPLE", feature::STEP_SIMULATION_MULTIPLE),
            ("STEP_SIMULATION_ACTION", feature::STEP_SIMULATION_ACTION),
        ] {
            assert_eq!(constant(f, name), u64::from(v), "{name}");
        }
        let sc = "simulation_interfaces/srv/ResetSimulation_Request";
        for (name, v) in [
            ("SCOPE_DEFAULT", scope::DEFAULT),
            ("SCOPE_TIME", scope::TIME),
            ("SCOPE_STATE", scope::STATE),
            ("SCOPE_SPAWNED", scope::SPAWNED),
            ("SCOPE_ALL", scope::ALL),
        ] {
            assert_eq!(constant(sc, name), u64::from(v), "{name}");
        }
        action::tests::the_action_constants_are_the_interfaces_own(constant);
    }

    #[test]
    fn every_service_and_topic_is_an_embedded_interface() {
        for s in SERVICES {
            let svc = s.service();
            assert!(svc.request().hash().to_string().starts_with("RIHS01_"), "{}", s.interface);
        }
        for t in [FEEDBACK, STATUS] {
            t.message();
        }
        // As rosidl's generator hashes it (tutti-ros2's tests pin more).
        assert_eq!(
            SERVICES[3].service().request().hash().to_string(),
            "RIHS01_cda33f6887815f3dce0f90e61fd8efd39bda13ae264ddede15c33fbad890630e"
        );
        assert_eq!(SERVICES[7].service().request().name().dds(), "action_msgs::srv::dds_::CancelGoal_Request_");
    }

    /// Requests and responses as a client of rmw_cyclonedds encodes and reads them (the byte
    /// layouts the hand-written codec had, now those of the interface files).
    #[test]
    fn responses_encode_as_their_messages() {
        let rsp = |kind: usize, v: &Value| SERVICES[kind].service().response().encode(v).unwrap();
        let o = Outcome::new(result::INCORRECT_STATE, "ab");
        let body = rsp(4, &Struct::new().with("result", o.value()).into());
        assert_eq!(body, [3, 0, 0, 0, 3, 0, 0, 0, b'a', b'b', 0]);
        let f = Struct::new().with("features", vec![Value::from(20u16), Value::from(21u16)]).with("custom_info", "x");
        let body = rsp(0, &Struct::new().with("features", f).into());
        assert_eq!(body, [2, 0, 0, 0, 20, 0, 21, 0, 0, 0, 0, 0, 2, 0, 0, 0, b'x', 0]);
        let req = SERVICES[3].service().request().decode(&9u64.to_be_bytes(), false).unwrap();
        assert_eq!(req.get("steps"), Some(&Value::UInt(9)));
    }
}
