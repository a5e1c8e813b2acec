//! The types tutti knows: every message, service and action of the interface files embedded
//! from `interfaces/` ([`registry`], parsed once, at first use), or of any other set of specs
//! (a DDF's sets: `crate::idl`), with the messages rosidl makes of each service and action.
//!
//! A service `PKG/srv/NAME` is the messages `NAME_Request` and `NAME_Response` of its file and
//! `NAME_Event` (`service_msgs/msg/ServiceEventInfo info`, `NAME_Request[<=1] request`,
//! `NAME_Response[<=1] response`). An action `PKG/action/NAME` is the messages `NAME_Goal`,
//! `NAME_Result` and `NAME_Feedback` of its file, the services `NAME_SendGoal` (request
//! `unique_identifier_msgs/UUID goal_id`, `NAME_Goal goal`; response `bool accepted`,
//! `builtin_interfaces/Time stamp`) and `NAME_GetResult` (request `goal_id`; response `int8
//! status`, `NAME_Result result`), and the message `NAME_FeedbackMessage` (`goal_id`,
//! `NAME_Feedback feedback`). Each is a message of the registry like any other, looked up by
//! its ROS 2 name (`simulation_interfaces/action/SimulateSteps_SendGoal_Request`) or its DDS
//! name (`simulation_interfaces::action::dds_::SimulateSteps_SendGoal_Request_`).

use std::collections::BTreeMap;
use std::sync::OnceLock;

use crate::cdr::{self, CdrError};
use crate::parse::{self, ParseError};
use crate::spec::{ActionSpec, BaseType, Field, FieldType, Kind, MessageSpec, Primitive, ServiceSpec, Shape, TypeName};
use crate::typehash::{self, IndividualType, MissingType, TypeDescription, TypeHash};
use crate::value::Value;

mod embedded {
    include!(concat!(env!("OUT_DIR"), "/interfaces.rs"));
}

/// Why a set of interfaces is not a registry.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RegistryError {
    #[error(transparent)]
    Parse(#[from] ParseError),
    #[error("{0} is defined twice")]
    Duplicate(String),
    #[error(transparent)]
    Missing(#[from] MissingType),
    #[error("type {0} contains itself")]
    Cycle(String),
    #[error("{0}: an interface file is PKG/msg/NAME.msg, PKG/srv/NAME.srv or PKG/action/NAME.action")]
    Kind(String),
}

/// One message and where its nested types are.
#[derive(Debug, Clone)]
pub(crate) struct Entry {
    pub(crate) spec: MessageSpec,
    /// For each field, the index of its nested type's entry (None: not nested).
    pub(crate) nested: Vec<Option<usize>>,
}

#[derive(Debug, Clone)]
struct ServiceEntry {
    spec: ServiceSpec,
    /// Request, response, event.
    messages: [usize; 3],
}

#[derive(Debug, Clone)]
struct ActionEntry {
    spec: ActionSpec,
    /// Goal, result, feedback, feedback message.
    messages: [usize; 4],
    /// Send goal, get result.
    services: [usize; 2],
}

/// Messages, services and actions by name.
#[derive(Debug, Clone, Default)]
pub struct Registry {
    pub(crate) entries: Vec<Entry>,
    by_name: BTreeMap<String, usize>,
    services: Vec<ServiceEntry>,
    service_names: BTreeMap<String, usize>,
    actions: Vec<ActionEntry>,
    action_names: BTreeMap<String, usize>,
}

/// The registry of the interface files embedded from `interfaces/`, parsed at first use.
pub fn registry() -> &'static Registry {
    static REGISTRY: OnceLock<Registry> = OnceLock::new();
    REGISTRY.get_or_init(|| {
        // The files are fixed at build time and the crate's tests parse every one of them.
        Registry::embedded().expect("the embedded interface files are valid")
    })
}

/// `PKG/KIND/NAME` of a ROS 2 name (`PKG/KIND/NAME`, or `PKG/NAME` for a message) or a DDS
/// name (`PKG::KIND::dds_::NAME_`).
fn key(name: &str) -> Option<String> {
    let n = if name.contains("::") { TypeName::from_dds(name) } else { TypeName::parse(name) };
    n.map(|n| n.to_string())
}

impl Registry {
    /// Collects specs and interface files into a registry.
    pub fn builder() -> RegistryBuilder {
        RegistryBuilder::default()
    }

    /// Every interface file embedded from `interfaces/`, parsed.
    pub fn embedded() -> Result<Registry, RegistryError> {
        let mut b = Registry::builder();
        for (package, kind, name, text) in embedded::FILES {
            let kind = Kind::parse(kind).ok_or_else(|| RegistryError::Kind(format!("{package}/{kind}/{name}")))?;
            b.file(package, kind, name, text)?;
        }
        b.build()
    }

    /// The text of the embedded `.msg` file of message `package/msg/name`, as ROS 2 ships it.
    pub fn message_file(package: &str, name: &str) -> Option<&'static str> {
        embedded::FILES.iter().find(|(p, k, n, _)| *p == package && *k == "msg" && *n == name).map(|f| f.3)
    }

    /// The message named `name` (`std_msgs/msg/Float64`, `std_msgs::msg::dds_::Float64_`).
    pub fn message(&self, name: &str) -> Option<Message<'_>> {
        self.by_name.get(&key(name)?).map(|&i| self.at(i))
    }

    pub(crate) fn at(&self, i: usize) -> Message<'_> {
        Message { registry: self, index: i }
    }

    /// The service named `name` (`simulation_interfaces/srv/StepSimulation`).
    pub fn service(&self, name: &str) -> Option<Service<'_>> {
        self.service_names.get(&key(name)?).map(|&i| Service { registry: self, entry: &self.services[i] })
    }

    /// The action named `name` (`simulation_interfaces/action/SimulateSteps`).
    pub fn action(&self, name: &str) -> Option<Action<'_>> {
        self.action_names.get(&key(name)?).map(|&i| Action { registry: self, entry: &self.actions[i] })
    }

    /// Every message, by name.
    pub fn messages(&self) -> impl Iterator<Item = Message<'_>> {
        self.by_name.values().map(|&i| self.at(i))
    }

    /// Every service, by name.
    pub fn services(&self) -> impl Iterator<Item = Service<'_>> {
        self.service_names.values().map(|&i| Service { registry: self, entry: &self.services[i] })
    }

    /// Every action, by name.
    pub fn actions(&self) -> impl Iterator<Item = Action<'_>> {
        self.action_names.values().map(|&i| Action { registry: self, entry: &self.actions[i] })
    }

    /// The name of every type it describes (messages, services and actions), sorted.
    pub fn type_names(&self) -> Vec<&str> {
        let mut names: Vec<&str> = self
            .by_name
            .keys()
            .chain(self.service_names.keys())
            .chain(self.action_names.keys())
            .map(String::as_str)
            .collect();
        names.sort_unstable();
        names
    }

    /// A type as rosidl describes it on its own: a message's fields; a service's
    /// `request_message`, `response_message` and `event_message`; an action's `goal`,
    /// `result`, `feedback`, `send_goal_service`, `get_result_service` and `feedback_message`.
    fn individual(&self, name: &str) -> Option<IndividualType> {
        let key = key(name)?;
        let nested = |n: &str, t: &TypeName| typehash::Field::new(n, typehash::FieldType::nested(&t.to_string(), 0, 0));
        if let Some(&i) = self.by_name.get(&key) {
            return Some(IndividualType::of_message(&self.entries[i].spec));
        }
        if let Some(&i) = self.service_names.get(&key) {
            let s = &self.services[i].spec;
            let fields = vec![
                nested("request_message", &s.request),
                nested("response_message", &s.response),
                nested("event_message", &s.event),
            ];
            return Some(IndividualType { type_name: key, fields });
        }
        let a = &self.actions[*self.action_names.get(&key)?].spec;
        let fields = vec![
            nested("goal", &a.goal),
            nested("result", &a.result),
            nested("feedback", &a.feedback),
            nested("send_goal_service", &a.send_goal.name),
            nested("get_result_service", &a.get_result.name),
            nested("feedback_message", &a.feedback_message),
        ];
        Some(IndividualType { type_name: key, fields })
    }

    /// The description of type `name` (a message, a service or an action), with every type it
    /// refers to: what its hash is computed from.
    pub fn description(&self, name: &str) -> Option<TypeDescription> {
        // Every nested type of a built registry is in it.
        TypeDescription::resolve(self.individual(name)?, |n| self.individual(n)).ok()
    }

    /// The RIHS01 hash of type `name` (a message, a service or an action).
    pub fn hash(&self, name: &str) -> Option<TypeHash> {
        self.description(name).map(|d| d.hash())
    }

    /// The hash of the message whose DDS name is `dds_type` (`std_msgs::msg::dds_::Float64_`).
    pub fn hash_of_dds_type(&self, dds_type: &str) -> Option<TypeHash> {
        TypeName::from_dds(dds_type).and_then(|n| self.hash(&n.to_string()))
    }
}

/// A message of a registry: its spec, its description and hash, and its CDR codec.
#[derive(Debug, Clone, Copy)]
pub struct Message<'r> {
    registry: &'r Registry,
    index: usize,
}

impl<'r> Message<'r> {
    pub fn spec(&self) -> &'r MessageSpec {
        &self.registry.entries[self.index].spec
    }

    pub(crate) fn entry(&self) -> &'r Entry {
        &self.registry.entries[self.index]
    }

    pub fn registry(&self) -> &'r Registry {
        self.registry
    }

    /// `PKG/KIND/NAME`.
    pub fn name(&self) -> &'r TypeName {
        &self.spec().name
    }

    /// The value of its constant `name` (`RESULT_OK` of `simulation_interfaces/msg/Result`).
    pub fn constant(&self, name: &str) -> Option<&'r Value> {
        self.spec().constant(name)
    }

    /// The message type of field `field`, when it is a nested message.
    pub fn nested(&self, field: &str) -> Option<Message<'r>> {
        let e = self.entry();
        let i = e.spec.fields.iter().position(|f| f.name == field)?;
        e.nested[i].map(|n| self.registry.at(n))
    }

    /// Its description, with every type it refers to.
    pub fn description(&self) -> TypeDescription {
        let top = IndividualType::of_message(self.spec());
        TypeDescription::resolve(top.clone(), |n| self.registry.individual(n))
            .unwrap_or(TypeDescription { type_description: top, referenced_type_descriptions: Vec::new() })
    }

    /// Its RIHS01 hash.
    pub fn hash(&self) -> TypeHash {
        self.description().hash()
    }

    /// Its value when nothing is given: every field's `.msg` default, else zero or empty.
    pub fn default_value(&self) -> Value {
        cdr::default_value(*self)
    }

    /// `value` as a little-endian plain CDR body (no encapsulation header). A field the
    /// value leaves out takes its default (`default_value`).
    pub fn encode(&self, value: &Value) -> Result<Vec<u8>, CdrError> {
        let mut out = Vec::new();
        self.encode_into(value, &mut out)?;
        Ok(out)
    }

    /// `value` appended to `out`, aligned as if `out` started the body (after a request
    /// header, say).
    pub fn encode_into(&self, value: &Value, out: &mut Vec<u8>) -> Result<(), CdrError> {
        cdr::encode(*self, value, out)
    }

    /// The message a plain CDR body holds, in either byte order.
    pub fn decode(&self, body: &[u8], little_endian: bool) -> Result<Value, CdrError> {
        self.decode_at(body, 0, little_endian).map(|(v, _)| v)
    }

    /// The message at offset `start` of `body` (alignment counted from the body's start),
    /// and the offset after it.
    pub fn decode_at(&self, body: &[u8], start: usize, little_endian: bool) -> Result<(Value, usize), CdrError> {
        cdr::decode(*self, body, start, little_endian)
    }
}

/// A service of a registry and its messages.
#[derive(Debug, Clone, Copy)]
pub struct Service<'r> {
    registry: &'r Registry,
    entry: &'r ServiceEntry,
}

impl<'r> Service<'r> {
    pub fn spec(&self) -> &'r ServiceSpec {
        &self.entry.spec
    }

    pub fn name(&self) -> &'r TypeName {
        &self.entry.spec.name
    }

    /// `NAME_Request`.
    pub fn request(&self) -> Message<'r> {
        self.registry.at(self.entry.messages[0])
    }

    /// `NAME_Response`.
    pub fn response(&self) -> Message<'r> {
        self.registry.at(self.entry.messages[1])
    }

    /// `NAME_Event`.
    pub fn event(&self) -> Message<'r> {
        self.registry.at(self.entry.messages[2])
    }
}

/// An action of a registry, its messages and services.
#[derive(Debug, Clone, Copy)]
pub struct Action<'r> {
    registry: &'r Registry,
    entry: &'r ActionEntry,
}

impl<'r> Action<'r> {
    pub fn spec(&self) -> &'r ActionSpec {
        &self.entry.spec
    }

    pub fn name(&self) -> &'r TypeName {
        &self.entry.spec.name
    }

    pub fn goal(&self) -> Message<'r> {
        self.registry.at(self.entry.messages[0])
    }

    pub fn result(&self) -> Message<'r> {
        self.registry.at(self.entry.messages[1])
    }

    pub fn feedback(&self) -> Message<'r> {
        self.registry.at(self.entry.messages[2])
    }

    /// `NAME_FeedbackMessage`: `goal_id` and `feedback`.
    pub fn feedback_message(&self) -> Message<'r> {
        self.registry.at(self.entry.messages[3])
    }

    /// `NAME_SendGoal`.
    pub fn send_goal(&self) -> Service<'r> {
        Service { registry: self.registry, entry: &self.registry.services[self.entry.services[0]] }
    }

    /// `NAME_GetResult`.
    pub fn get_result(&self) -> Service<'r> {
        Service { registry: self.registry, entry: &self.registry.services[self.entry.services[1]] }
    }
}

/// Specs and interface files being collected into a [`Registry`].
#[derive(Debug, Default)]
pub struct RegistryBuilder {
    messages: Vec<MessageSpec>,
    services: Vec<ServiceSpec>,
    actions: Vec<ActionSpec>,
}

fn nested(name: &str, ty: &TypeName) -> Field {
    Field::new(name, FieldType::nested(ty.clone()))
}

fn msg_type(package: &str, name: &str) -> TypeName {
    TypeName::new(package, Kind::Msg, name)
}

impl RegistryBuilder {
    /// Adds a message.
    pub fn message(&mut self, spec: MessageSpec) -> &mut Self {
        self.messages.push(spec);
        self
    }

    /// Adds the interface file `PKG/KIND/NAME.KIND` of text `text`: a message, or a service
    /// or an action with every message rosidl makes of it.
    pub fn file(&mut self, package: &str, kind: Kind, name: &str, text: &str) -> Result<&mut Self, ParseError> {
        let file = format!("{package}/{kind}/{name}.{kind}");
        match kind {
            Kind::Msg => {
                self.message(parse::parse_message(&file, package, name, text)?);
            }
            Kind::Srv => {
                let (request, response) = parse::parse_service(&file, package, name, text)?;
                self.service(ServiceSpec::named(TypeName::new(package, kind, name)), request, response);
            }
            Kind::Action => {
                let [goal, result, feedback] = parse::parse_action(&file, package, name, text)?;
                self.action(goal, result, feedback);
            }
        }
        Ok(self)
    }

    /// Adds a service, its request and response and the event rosidl makes of them.
    fn service(&mut self, spec: ServiceSpec, request: MessageSpec, response: MessageSpec) {
        let bounded = |name: &str, ty: &TypeName| Field {
            ty: FieldType { base: BaseType::Nested(ty.clone()), shape: Shape::Bounded(1) },
            ..Field::new(name, FieldType::nested(ty.clone()))
        };
        let event = vec![
            nested("info", &msg_type("service_msgs", "ServiceEventInfo")),
            bounded("request", &spec.request),
            bounded("response", &spec.response),
        ];
        self.message(request).message(response).message(MessageSpec::new(spec.event.clone(), event, Vec::new()));
        self.services.push(spec);
    }

    /// Adds an action: its goal, result and feedback, and the services and message rosidl
    /// makes of them.
    fn action(&mut self, goal: MessageSpec, result: MessageSpec, feedback: MessageSpec) {
        let short = goal.name.name.strip_suffix("_Goal").unwrap_or(&goal.name.name);
        let name = TypeName { name: short.to_string(), ..goal.name.clone() };
        let spec = ActionSpec::named(name);
        let goal_id = nested("goal_id", &msg_type("unique_identifier_msgs", "UUID"));
        let m = |name: &TypeName, fields: Vec<Field>| MessageSpec::new(name.clone(), fields, Vec::new());
        let primitive = |name: &str, p: Primitive| Field::new(name, FieldType::primitive(p));
        let send_goal = (
            m(&spec.send_goal.request, vec![goal_id.clone(), nested("goal", &spec.goal)]),
            m(
                &spec.send_goal.response,
                vec![primitive("accepted", Primitive::Bool), nested("stamp", &msg_type("builtin_interfaces", "Time"))],
            ),
        );
        let get_result = (
            m(&spec.get_result.request, vec![goal_id.clone()]),
            m(&spec.get_result.response, vec![primitive("status", Primitive::Int8), nested("result", &spec.result)]),
        );
        let feedback_message = m(&spec.feedback_message, vec![goal_id, nested("feedback", &spec.feedback)]);
        self.message(goal).message(result).message(feedback).message(feedback_message);
        self.service(spec.send_goal.clone(), send_goal.0, send_goal.1);
        self.service(spec.get_result.clone(), get_result.0, get_result.1);
        self.actions.push(spec);
    }

    /// The registry, once every nested type is found and none contains itself.
    pub fn build(self) -> Result<Registry, RegistryError> {
        let mut by_name = BTreeMap::new();
        for (i, m) in self.messages.iter().enumerate() {
            if by_name.insert(m.name.to_string(), i).is_some() {
                return Err(RegistryError::Duplicate(m.name.to_string()));
            }
        }
        let mut entries = Vec::with_capacity(self.messages.len());
        for spec in self.messages {
            let nested = spec
                .fields
                .iter()
                .map(|f| match &f.ty.base {
                    BaseType::Nested(n) => find(&by_name, &spec.name, n).map(Some),
                    _ => Ok(None),
                })
                .collect::<Result<Vec<_>, _>>()?;
            entries.push(Entry { spec, nested });
        }
        no_cycles(&entries)?;
        let mut r = Registry { entries, by_name, ..Registry::default() };
        for spec in self.services {
            let messages = [
                find(&r.by_name, &spec.name, &spec.request)?,
                find(&r.by_name, &spec.name, &spec.response)?,
                find(&r.by_name, &spec.name, &spec.event)?,
            ];
            if r.service_names.insert(spec.name.to_string(), r.services.len()).is_some() {
                return Err(RegistryError::Duplicate(spec.name.to_string()));
            }
            r.services.push(ServiceEntry { spec, messages });
        }
        for spec in self.actions {
            let messages = [
                find(&r.by_name, &spec.name, &spec.goal)?,
                find(&r.by_name, &spec.name, &spec.result)?,
                find(&r.by_name, &spec.name, &spec.feedback)?,
                find(&r.by_name, &spec.name, &spec.feedback_message)?,
            ];
            let services = [
                find(&r.service_names, &spec.name, &spec.send_goal.name)?,
                find(&r.service_names, &spec.name, &spec.get_result.name)?,
            ];
            if r.action_names.insert(spec.name.to_string(), r.actions.len()).is_some() {
                return Err(RegistryError::Duplicate(spec.name.to_string()));
            }
            r.actions.push(ActionEntry { spec, messages, services });
        }
        Ok(r)
    }
}

/// The index of `name`, which `referrer` refers to.
fn find(names: &BTreeMap<String, usize>, referrer: &TypeName, name: &TypeName) -> Result<usize, MissingType> {
    names
        .get(&name.to_string())
        .copied()
        .ok_or_else(|| MissingType { referrer: referrer.to_string(), missing: name.to_string() })
}

/// Refuses a message that contains itself, directly or not (it would have no end in CDR).
fn no_cycles(entries: &[Entry]) -> Result<(), RegistryError> {
    // 0: not seen, 1: on the current path, 2: done.
    let mut state = vec![0u8; entries.len()];
    for start in 0..entries.len() {
        if state[start] != 0 {
            continue;
        }
        let mut stack = vec![(start, 0usize)];
        state[start] = 1;
        while let Some((i, field)) = stack.pop() {
            match entries[i].nested.iter().skip(field).position(Option::is_some).map(|p| field + p) {
                Some(f) => {
                    stack.push((i, f + 1));
                    let n = entries[i].nested[f].unwrap_or(i);
                    match state[n] {
                        1 => return Err(RegistryError::Cycle(entries[n].spec.name.to_string())),
                        0 => {
                            state[n] = 1;
                            stack.push((n, 0));
                        }
                        _ => {}
                    }
                }
                None => state[i] = 2,
            }
        }
    }
    Ok(())
}
