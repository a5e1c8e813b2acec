//! The `simulation_interfaces` client in Fast DDS's wire form: ros2-client's own `Client` and
//! `ActionClient` with `ServiceMapping::Enhanced` (no request header; the reply is paired by
//! its related sample identity, docs/ros2.md "Wire forms"), run in the test's process on a
//! runtime of its own, under a watchdog. Its output has the shapes `dds_peer.py service` and
//! `dds_peer.py action` print, so that one suite checks both clients.

use std::future::Future;
use std::net::IpAddr;
use std::time::Duration;

use futures::StreamExt;
use ros2_client::action::ActionClientQosPolicies;
use ros2_client::builtin_interfaces::Time;
use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::message::Message;
use ros2_client::qos::{Durability, History, QosProfile, Reliability, WhenFull};
use ros2_client::{
    ActionTypeName, Client, Context, Name, Node, NodeName, NodeOptions, ServiceMapping, ServiceTypeName,
};
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

/// The longest a client waits for the services, and for all its calls.
const WATCHDOG: Duration = Duration::from_secs(100);

#[derive(Debug, Clone, Serialize, Deserialize)]
struct Empty {
    structure_needs_at_least_one_member: u8,
}
impl Message for Empty {}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct SimResult {
    result: u8,
    error_message: String,
}
impl Message for SimResult {}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct SimulationState {
    state: u8,
}
impl Message for SimulationState {}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct SimulatorFeatures {
    features: Vec<u16>,
    spawn_formats: Vec<String>,
    custom_info: String,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct FeaturesResponse {
    features: SimulatorFeatures,
}
impl Message for FeaturesResponse {}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct StateResponse {
    state: SimulationState,
    result: SimResult,
}
impl Message for StateResponse {}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct ResultResponse {
    result: SimResult,
}
impl Message for ResultResponse {}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct Steps {
    steps: u64,
}
impl Message for Steps {}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct Scope {
    scope: u8,
}
impl Message for Scope {}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct StepsFeedback {
    completed_steps: u64,
    remaining_steps: u64,
}
impl Message for StepsFeedback {}

/// rmw's services default, as rclcpp's clients use it.
fn service_qos() -> QosProfile {
    QosProfile::publisher_default()
        .reliability(Reliability::Reliable { when_full: WhenFull::Wait(Duration::from_millis(100)) })
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 10 })
}

/// A node of its own in DDS domain `dom`, on loopback as the tests' gateways are, with its
/// spinner running (discovery events: `wait_for_service`).
fn node(dom: u16) -> Result<Node, String> {
    let lo: IpAddr = [127, 0, 0, 1].into();
    let dp = DomainParticipantBuilder::new(dom).with_only_networks(vec![lo]).build().map_err(|e| format!("{e:?}"))?;
    let ctx = Context::from_domain_participant(dp).map_err(|e| format!("{e:?}"))?;
    let name = NodeName::new("/", "simif_enhanced_client").map_err(|e| format!("{e:?}"))?;
    let mut node = ctx.new_node(name, NodeOptions::new().enable_rosout(false)).map_err(|e| format!("{e:?}"))?;
    let spinner = node.spinner().map_err(|e| format!("{e:?}"))?;
    tokio::spawn(spinner.spin());
    Ok(node)
}

/// Runs `f` on a runtime of its own, for at most [`WATCHDOG`].
fn run<T>(f: impl Future<Output = Result<T, String>>) -> Result<T, String> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| e.to_string())?;
    let r = rt.block_on(async { tokio::time::timeout(WATCHDOG, f).await.unwrap_or_else(|_| Err("timed out".into())) });
    rt.shutdown_timeout(Duration::from_secs(5));
    r
}

fn client<Q: Message + Clone + 'static, R: Message + 'static>(node: &mut Node, name: &str, ty: &str) -> Client<Q, R> {
    let service = Name::new("/", name).expect("a service name");
    node.create_client::<Q, R>(
        ServiceMapping::Enhanced,
        &service,
        &ServiceTypeName::new("simulation_interfaces", ty),
        service_qos(),
        service_qos(),
    )
    .expect("a client")
}

/// One client per service, made once.
struct Clients {
    features: Client<Empty, FeaturesResponse>,
    get: Client<Empty, StateResponse>,
    set: Client<SimulationState, ResultResponse>,
    step: Client<Steps, ResultResponse>,
    reset: Client<Scope, ResultResponse>,
}

impl Clients {
    fn new(node: &mut Node) -> Clients {
        Clients {
            features: client(node, "get_simulator_features", "GetSimulatorFeatures"),
            get: client(node, "get_simulation_state", "GetSimulationState"),
            set: client(node, "set_simulation_state", "SetSimulationState"),
            step: client(node, "step_simulation", "StepSimulation"),
            reset: client(node, "reset_simulation", "ResetSimulation"),
        }
    }

    /// Whether every service is there within `wait`.
    async fn wait(&self, node: &Node, wait: Duration) -> bool {
        let all = async {
            matched(|| self.features.wait_for_service(node)).await;
            matched(|| self.get.wait_for_service(node)).await;
            matched(|| self.set.wait_for_service(node)).await;
            matched(|| self.step.wait_for_service(node)).await;
            matched(|| self.reset.wait_for_service(node)).await;
        };
        tokio::time::timeout(wait, all).await.is_ok()
    }

    async fn call(&self, name: &str, arg: Option<u64>) -> Result<Value, String> {
        let e = |e: ros2_client::service::CallServiceError<()>| format!("{name}: {e}");
        let arg8 = arg.map(|a| u8::try_from(a).unwrap_or(u8::MAX)).unwrap_or(0);
        let response = match name {
            "get_simulator_features" => {
                json!(self
                    .features
                    .async_call_service(Empty { structure_needs_at_least_one_member: 0 })
                    .await
                    .map_err(e)?)
            }
            "get_simulation_state" => {
                json!(self.get.async_call_service(Empty { structure_needs_at_least_one_member: 0 }).await.map_err(e)?)
            }
            "set_simulation_state" => {
                json!(self.set.async_call_service(SimulationState { state: arg8 }).await.map_err(e)?)
            }
            "step_simulation" => {
                json!(self.step.async_call_service(Steps { steps: arg.unwrap_or(0) }).await.map_err(e)?)
            }
            "reset_simulation" => json!(self.reset.async_call_service(Scope { scope: arg8 }).await.map_err(e)?),
            other => return Err(format!("no service {other}")),
        };
        let mut line = json!({ "call": name, "arg": arg });
        if let (Some(l), Value::Object(r)) = (line.as_object_mut(), response) {
            l.extend(r);
        }
        Ok(line)
    }
}

/// Waits for what one of ros2-client's `wait_for_*` futures waits for, made afresh every
/// second. A new future first reads the node's matches, which the node's spinner keeps; one
/// future alone hears of a later match only through an event, and ros2-client 0.12 queues at
/// most 8 events per listener (`Node::status_receiver`) and drops the rest. Under load, a
/// burst of discovery events (the gateway's node has dozens of endpoints) overflowed that
/// queue, the one event that mattered was dropped, and the client waited 60 s for services
/// that had been there all along.
async fn matched<F: Future<Output = ()>>(mut wait: impl FnMut() -> F) {
    while tokio::time::timeout(Duration::from_secs(1), wait()).await.is_err() {}
}

/// Makes `calls` (JSON: `[["NAME", ARG], ...]`) in DDS domain `dom`: each call's response, as
/// `dds_peer.py service` prints it.
pub fn calls(dom: u16, calls: &str) -> Result<Vec<Value>, String> {
    let calls: Vec<Vec<Value>> = serde_json::from_str(calls).map_err(|e| format!("{e}: {calls}"))?;
    run(async move {
        let mut node = node(dom)?;
        let clients = Clients::new(&mut node);
        if !clients.wait(&node, Duration::from_secs(60)).await {
            return Err("no service".into());
        }
        let mut out = Vec::new();
        for c in &calls {
            let name = c.first().and_then(Value::as_str).unwrap_or("");
            out.push(clients.call(name, c.get(1).and_then(Value::as_u64)).await?);
        }
        Ok(out)
    })
}

/// Whether the services appear in DDS domain `dom` within `wait`.
pub fn finds_services(dom: u16, wait: Duration) -> Result<bool, String> {
    run(async move {
        let mut node = node(dom)?;
        let clients = Clients::new(&mut node);
        Ok(clients.wait(&node, wait).await)
    })
}

/// A goal of `steps` steps of the action `simulate_steps`, canceled after `cancel_after`
/// feedback samples (0: never), as `dds_peer.py action` does it: its output lines.
pub fn simulate_steps(dom: u16, steps: u64, cancel_after: u64) -> Result<Vec<Value>, String> {
    run(async move {
        let mut node = node(dom)?;
        let reliable = Reliability::Reliable { when_full: WhenFull::Wait(Duration::from_millis(100)) };
        let qos = ActionClientQosPolicies {
            goal_service: service_qos(),
            result_service: service_qos(),
            cancel_service: service_qos(),
            // Keep-all, so that every feedback sample is seen.
            feedback_subscription: QosProfile::subscription_default()
                .reliability(reliable)
                .durability(Durability::Volatile)
                .history(History::KeepAll),
            status_subscription: QosProfile::subscription_default()
                .reliability(reliable)
                .durability(Durability::TransientLocal)
                .history(History::KeepLast { depth: 1 }),
        };
        let action = node
            .create_action_client::<Steps, ResultResponse, StepsFeedback>(
                ServiceMapping::Enhanced,
                &Name::new("/", "simulate_steps").map_err(|e| format!("{e:?}"))?,
                &ActionTypeName::new("simulation_interfaces", "SimulateSteps"),
                qos,
            )
            .map_err(|e| format!("{e:?}"))?;
        let ready = async {
            matched(|| action.goal_client().wait_for_service(&node)).await;
            matched(|| action.result_client().wait_for_service(&node)).await;
            matched(|| action.cancel_client().wait_for_service(&node)).await;
            matched(|| action.feedback_subscription().wait_for_publisher(&node)).await;
        };
        if tokio::time::timeout(Duration::from_secs(60), ready).await.is_err() {
            return Err("no action server".into());
        }
        let mut lines = Vec::new();
        let (goal, sent) = action.async_send_goal(Steps { steps }).await.map_err(|e| format!("send_goal: {e}"))?;
        lines.push(json!({ "accepted": sent.accepted }));
        if !sent.accepted {
            return Ok(lines);
        }
        let result = action.async_request_result(goal);
        futures::pin_mut!(result);
        let feedback = action.feedback_stream(goal);
        futures::pin_mut!(feedback);
        let mut seen = 0;
        let (status, got) = loop {
            tokio::select! {
                r = &mut result => break r.map_err(|e| format!("get_result: {e}"))?,
                Some(f) = feedback.next() => {
                    let f = f.map_err(|e| format!("feedback: {e:?}"))?;
                    lines.push(json!({ "feedback": [f.completed_steps, f.remaining_steps] }));
                    seen += 1;
                    if cancel_after != 0 && seen == cancel_after {
                        let c = action.async_cancel_goal(goal, Time::ZERO).await.map_err(|e| format!("cancel_goal: {e}"))?;
                        lines.push(json!({ "cancel": c.return_code as i8, "canceling": c.goals_canceling.len() }));
                    }
                }
            }
        };
        // Feedback written before the result may arrive after it (another writer).
        let late = tokio::time::sleep(Duration::from_millis(300));
        futures::pin_mut!(late);
        loop {
            tokio::select! {
                () = &mut late => break,
                Some(Ok(f)) = feedback.next() => lines.push(json!({ "feedback": [f.completed_steps, f.remaining_steps] })),
            }
        }
        // The goal's last status on the status topic.
        let mut last = None;
        let statuses = action.status_stream(goal);
        futures::pin_mut!(statuses);
        let end = tokio::time::sleep(Duration::from_secs(2));
        futures::pin_mut!(end);
        while !matches!(last, Some(s) if s >= 4) {
            tokio::select! {
                () = &mut end => break,
                Some(Ok(s)) = statuses.next() => last = Some(s.status as i8),
            }
        }
        lines.push(json!({ "status": status as i8, "result": got.result, "last_status": last }));
        Ok(lines)
    })
}
