//! Connections in the framework: at every step the framework copies an item that
//! participants write (a SUBSCRIBE item) to an item that participants read (a PUBLISH item),
//! within a domain or across domains, with an optional gain and offset.
//!
//! `"plant/subscribe/y -> ctrl/publish/y_meas"`, or with a gain and an offset
//! `"plant/subscribe/y -> ctrl/publish/y_meas * 2 + 0.5"`. Item paths are the DDF's
//! (`gw_async/v`, `Formation/X`, …).
//!
//! **Order within a step.** Step k publishes every domain's PUBLISH set, then waits for the
//! answers and reads every SUBSCRIBE set; then the connections are applied, in the order
//! they are given, to the PUBLISH sets of step k + 1. So a connection carries the value its
//! output had at the end of the previous step (no output is evaluated again within a step),
//! and a chain A -> B -> C of n connections takes n steps from A's output to C's input.
//! That is [`StepOrder::Delayed`], the default (libcosim's ordering).
//!
//! **[`StepOrder::Feedthrough`]** (OMSimulator's ordering) adds, after the step's answers and
//! before the exchange for the next step, one re-evaluation of every synchronous domain that
//! an output of another domain feeds, in the order of the connections' graph
//! ([`Connections::reevaluation_order`]): the connections are applied, the domain is
//! published again with the same simulated time (a repeated step, which a participant
//! answers without advancing: `tutti fmu run` sets the inputs and reads the outputs again),
//! and its new outputs feed the domains after it. So a component with direct feedthrough
//! passes its inputs on within the step. An algebraic loop is not solved: a domain in a
//! cycle is re-evaluated once, where the cycle is entered.
//!
//! **The simulated time as a source.** `"@sim_time -> ctrl/publish/t"` writes, into every
//! step's PUBLISH set, the simulated time of that very step (seconds, the time the framework
//! publishes the step with and participants find in the segment's header), with the gain and
//! offset if given. It is written just before the step is published, so unlike an item's
//! value it is never a step late; the input must be a float (`float32`, `float64`).
//!
//! **Units.** Each end may carry a unit in brackets, `"plant/subscribe/h [km: m=1 factor=1000]
//! -> ctrl/publish/h [m]"`: a unit is a name and its definition against the SI base units
//! (the exponents of `kg m s A K mol cd rad`, and `factor` and `offset`: a value v in the
//! unit is `factor × v + offset` in the base units), as SSP's `ssc:Unit` defines one; a base
//! unit alone (`[m]`, `[K]`) needs no definition. Both ends give a unit or neither; the two
//! must have the same base dimensions. The output is converted into the input's unit first,
//! then the gain and the offset apply (in the input's unit).
//!
//! Checked before anything runs ([`Connections::resolve`]): both items exist and have the
//! roles above, the same length, and types that convert (the same type; or any number into
//! a float; with a gain, an offset or a unit conversion, numbers only); units of the same
//! dimensions; no input has two sources, nor a connection and a `--set` value. Every
//! refusal names both ends.

use std::fmt;

use tutti_core::ddf::{Leaf, Model, Role, ScalarType, Value};

/// How the connections are applied within a step (see the module).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum StepOrder {
    /// Each connection carries its output's value at the end of the previous step.
    #[default]
    Delayed,
    /// Domains fed by other domains are re-evaluated within the step, in graph order.
    Feedthrough,
}

impl StepOrder {
    pub fn as_str(self) -> &'static str {
        match self {
            StepOrder::Delayed => "delayed",
            StepOrder::Feedthrough => "feedthrough",
        }
    }
}

/// A name that is not one of the [`StepOrder`]s.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("'{given}': expected 'delayed' (the default) or 'feedthrough'")]
pub struct UnknownOrder {
    pub given: String,
}

impl std::str::FromStr for StepOrder {
    type Err = UnknownOrder;
    fn from_str(s: &str) -> Result<StepOrder, UnknownOrder> {
        match s {
            "delayed" => Ok(StepOrder::Delayed),
            "feedthrough" => Ok(StepOrder::Feedthrough),
            _ => Err(UnknownOrder { given: s.to_string() }),
        }
    }
}

impl fmt::Display for StepOrder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A connection as written, before it is checked against a model.
#[derive(Debug, Clone, PartialEq)]
pub struct ConnectionSpec {
    pub from: Source,
    pub to: ItemRef,
    pub gain: f64,
    pub offset: f64,
    /// The units of both ends (`[UNIT]` after each), when the value is converted.
    pub units: Option<(Unit, Unit)>,
}

/// The names of the SI base units, in the order of [`Unit::exponents`] (SSP's `ssc:BaseUnit`).
pub const BASE_UNITS: [&str; 8] = ["kg", "m", "s", "A", "K", "mol", "cd", "rad"];

/// A unit: a value v in it is `factor × v + offset` in the base units whose exponents it has.
#[derive(Debug, Clone, PartialEq)]
pub struct Unit {
    pub name: String,
    /// The exponents of `kg m s A K mol cd rad` ([`BASE_UNITS`]).
    pub exponents: [i32; 8],
    pub factor: f64,
    pub offset: f64,
}

impl Unit {
    /// The SI base unit `name` (`m`, `K`, …), if it is one.
    pub fn base(name: &str) -> Option<Unit> {
        let i = BASE_UNITS.iter().position(|b| *b == name)?;
        let mut exponents = [0; 8];
        exponents[i] = 1;
        Some(Unit { name: name.to_string(), exponents, factor: 1.0, offset: 0.0 })
    }

    /// Its base dimensions, as `m s-1` (`1` for none).
    pub fn dimensions(&self) -> String {
        let terms: Vec<String> = BASE_UNITS
            .iter()
            .zip(self.exponents)
            .filter(|(_, e)| *e != 0)
            .map(|(b, e)| if e == 1 { b.to_string() } else { format!("{b}{e}") })
            .collect();
        if terms.is_empty() {
            "1".into()
        } else {
            terms.join(" ")
        }
    }

    /// The gain and offset that take a value in `self` to the same quantity in `to`.
    pub fn conversion_to(&self, to: &Unit) -> (f64, f64) {
        (self.factor / to.factor, (self.offset - to.offset) / to.factor)
    }
}

impl fmt::Display for Unit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if Unit::base(&self.name).as_ref() == Some(self) {
            return write!(f, "[{}]", self.name);
        }
        write!(f, "[{}:", self.name)?;
        for (b, e) in BASE_UNITS.iter().zip(self.exponents) {
            if e != 0 {
                write!(f, " {b}={e}")?;
            }
        }
        if self.factor != 1.0 {
            write!(f, " factor={}", self.factor)?;
        }
        if self.offset != 0.0 {
            write!(f, " offset={}", self.offset)?;
        }
        f.write_str("]")
    }
}

/// Parses the inside of `[NAME]` (a base unit) or `[NAME: kg=E m=E … factor=F offset=O]`.
pub fn parse_unit(s: &str) -> Result<Unit, UnitError> {
    let (name, terms) = match s.split_once(':') {
        Some((n, t)) => (n.trim(), Some(t)),
        None => (s.trim(), None),
    };
    if name.is_empty() || name.contains(char::is_whitespace) {
        return Err(UnitError::Form(s.to_string()));
    }
    let Some(terms) = terms else {
        return Unit::base(name).ok_or_else(|| UnitError::NotBase(name.to_string()));
    };
    let mut unit = Unit { name: name.to_string(), exponents: [0; 8], factor: 1.0, offset: 0.0 };
    for term in terms.split_whitespace() {
        let (key, value) = term.split_once('=').unwrap_or((term, "1"));
        let bad = || UnitError::Term { name: name.to_string(), term: term.to_string() };
        if let Some(i) = BASE_UNITS.iter().position(|b| *b == key) {
            unit.exponents[i] = value.parse().map_err(|_| bad())?;
            continue;
        }
        let v: f64 = value.parse().ok().filter(|v: &f64| v.is_finite()).ok_or_else(bad)?;
        match key {
            "factor" if v != 0.0 => unit.factor = v,
            "factor" => return Err(UnitError::ZeroFactor(name.to_string())),
            "offset" => unit.offset = v,
            _ => return Err(UnitError::UnknownTerm { name: name.to_string(), key: key.to_string() }),
        }
    }
    Ok(unit)
}

/// `DOMAIN/ROLE/ITEM`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ItemRef {
    pub domain: String,
    pub role: Role,
    pub item: String,
}

/// Where a connection's value comes from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Source {
    /// An output: a SUBSCRIBE item, as the framework read it at the end of the previous step.
    Item(ItemRef),
    /// `@sim_time`: the simulated time of the step the value is published in.
    SimTime,
}

/// How the simulated time is written as a source.
pub const SIM_TIME: &str = "@sim_time";

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Source::Item(r) => r.fmt(f),
            Source::SimTime => f.write_str(SIM_TIME),
        }
    }
}

impl fmt::Display for ItemRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let role = match self.role {
            Role::Publish => "publish",
            Role::Subscribe => "subscribe",
        };
        write!(f, "{}/{role}/{}", self.domain, self.item)
    }
}

impl fmt::Display for ConnectionSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.units {
            Some((a, b)) => write!(f, "{} {a} -> {} {b}", self.from, self.to)?,
            None => write!(f, "{} -> {}", self.from, self.to)?,
        }
        if self.gain != 1.0 {
            write!(f, " * {}", self.gain)?;
        }
        if self.offset != 0.0 {
            write!(f, " + {}", self.offset)?;
        }
        Ok(())
    }
}

/// A connection that cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConnectError {
    #[error("'{0}': expected FROM -> TO [* GAIN] [+ OFFSET], each end DOMAIN/ROLE/ITEM (e.g. plant/subscribe/y -> ctrl/publish/y_meas)")]
    Form(String),
    #[error("'{given}': '{end}' is not DOMAIN/ROLE/ITEM with ROLE publish or subscribe")]
    End { given: String, end: String },
    #[error("'{given}': '{source_name}' is not a source: the sources are DOMAIN/subscribe/ITEM and @sim_time")]
    UnknownSource { given: String, source_name: String },
    #[error("'{given}': '{value}' is not a number")]
    Number { given: String, value: String },
    #[error("'{given}': {reason}")]
    Unit { given: String, reason: UnitError },
    #[error("{connection}: {reason}")]
    Refused { connection: String, reason: String },
}

/// A unit that does not parse, or units given at one end only.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum UnitError {
    #[error("'[{0}]' is not a unit: expected [NAME] or [NAME: m=1 s=-1 factor=F offset=O]")]
    Form(String),
    #[error("unit '{0}' is not a base unit ({base}): define it, like [{0}: m=1 factor=1000]", base = BASE_UNITS.join(" "))]
    NotBase(String),
    #[error("unit '{name}': '{term}' is not KEY=NUMBER")]
    Term { name: String, term: String },
    #[error("unit '{0}': factor 0 converts nothing")]
    ZeroFactor(String),
    #[error("unit '{name}': unknown term '{key}' (the base units {base}, factor, offset)", base = BASE_UNITS.join(" "))]
    UnknownTerm { name: String, key: String },
    #[error("a '[' without its ']'")]
    Unclosed,
    #[error("give a unit at both ends or at neither")]
    OneEnd,
}

/// Parses `FROM -> TO [* GAIN] [+ OFFSET]` (`- OFFSET` too); FROM is an item or `@sim_time`.
pub fn parse_connection(s: &str) -> Result<ConnectionSpec, ConnectError> {
    let (from, rest) = split_arrow(s).ok_or_else(|| ConnectError::Form(s.to_string()))?;
    let unit_err = |reason: UnitError| ConnectError::Unit { given: s.to_string(), reason };
    let (from, from_unit) = take_unit(from).map_err(unit_err)?;
    let rest = rest.trim_start();
    let to_end = rest.find(char::is_whitespace).unwrap_or(rest.len());
    let (to, after) = rest.split_at(to_end);
    let (to_unit, after) = match after.trim_start().strip_prefix('[') {
        Some(inner) => {
            let (u, tail) = inner.split_once(']').ok_or_else(|| unit_err(UnitError::Unclosed))?;
            (Some(parse_unit(u).map_err(unit_err)?), tail)
        }
        None => (None, after),
    };
    let units = match (from_unit, to_unit) {
        (Some(a), Some(b)) => Some((a, b)),
        (None, None) => None,
        _ => return Err(unit_err(UnitError::OneEnd)),
    };
    if to.is_empty() {
        return Err(ConnectError::Form(s.to_string()));
    }
    let mut words = after.split_whitespace();
    let (mut gain, mut offset) = (1.0, 0.0);
    let number = |w: Option<&str>| -> Result<f64, ConnectError> {
        let w = w.ok_or_else(|| ConnectError::Form(s.to_string()))?;
        w.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| ConnectError::Number { given: s.to_string(), value: w.to_string() })
    };
    while let Some(op) = words.next() {
        match op {
            "*" => gain = number(words.next())?,
            "+" => offset = number(words.next())?,
            "-" => offset = -number(words.next())?,
            _ => return Err(ConnectError::Form(s.to_string())),
        }
    }
    let end = |e: &str| -> Result<ItemRef, ConnectError> {
        let bad = || ConnectError::End { given: s.to_string(), end: e.to_string() };
        let (domain, rest) = e.split_once('/').ok_or_else(bad)?;
        let (role, item) = rest.split_once('/').ok_or_else(bad)?;
        let role = match role.to_ascii_lowercase().as_str() {
            "publish" => Role::Publish,
            "subscribe" => Role::Subscribe,
            _ => return Err(bad()),
        };
        if domain.is_empty() || item.is_empty() {
            return Err(bad());
        }
        Ok(ItemRef { domain: domain.to_string(), role, item: item.to_string() })
    };
    let from = match from.trim() {
        SIM_TIME => Source::SimTime,
        f if f.starts_with('@') => {
            return Err(ConnectError::UnknownSource { given: s.to_string(), source_name: f.to_string() })
        }
        f => Source::Item(end(f)?),
    };
    Ok(ConnectionSpec { from, to: end(to)?, gain, offset, units })
}

/// `FROM -> REST`, at the first `->` outside brackets.
fn split_arrow(s: &str) -> Option<(&str, &str)> {
    let mut depth = 0i32;
    for (i, c) in s.char_indices() {
        match c {
            '[' => depth += 1,
            ']' => depth -= 1,
            '-' if depth == 0 && s[i..].starts_with("->") => return Some((&s[..i], &s[i + 2..])),
            _ => {}
        }
    }
    None
}

/// `END [UNIT]` → the end and its unit.
fn take_unit(s: &str) -> Result<(&str, Option<Unit>), UnitError> {
    let s = s.trim();
    match s.strip_suffix(']').and_then(|r| r.split_once('[')) {
        Some((end, u)) => Ok((end.trim(), Some(parse_unit(u)?))),
        None => Ok((s, None)),
    }
}

/// One end of a checked connection.
#[derive(Debug, Clone)]
struct End {
    domain: usize,
    leaf: Leaf,
}

/// A checked connection from an item.
#[derive(Debug, Clone)]
struct Connection {
    from: End,
    to: End,
    gain: f64,
    offset: f64,
    /// Same type, no gain, no offset: the bytes are copied.
    raw: bool,
}

/// The connections of a run, checked against its model.
#[derive(Debug, Clone, Default)]
pub struct Connections {
    list: Vec<Connection>,
    /// The `@sim_time` connections: their input, gain and offset.
    clocks: Vec<(End, f64, f64)>,
    specs: Vec<ConnectionSpec>,
}

impl Connections {
    /// Checks `specs` against `model`; `sets` are the run's `DOMAIN/ITEM=VALUE` values, whose
    /// items may not also be a connection's input.
    pub fn resolve(model: &Model, specs: &[ConnectionSpec], sets: &[String]) -> Result<Connections, ConnectError> {
        let mut list: Vec<Connection> = Vec::with_capacity(specs.len());
        let mut clocks = Vec::new();
        // Every input given so far, with the connection that gives it.
        let mut inputs: Vec<(End, &ConnectionSpec)> = Vec::new();
        for spec in specs {
            let refused = |reason: String| ConnectError::Refused { connection: spec.to_string(), reason };
            let to = end(model, &spec.to, Role::Publish).map_err(|e| refused(e.to_string()))?;
            if let Some((_, other)) = inputs.iter().find(|(e, _)| e.domain == to.domain && overlap(&e.leaf, &to.leaf)) {
                return Err(refused(format!("{} already has a source: {other}", spec.to)));
            }
            if let Some(set) = sets.iter().find(|s| s.split_once('=').is_some_and(|(t, _)| set_target(t, &spec.to))) {
                return Err(refused(format!("{} is also given a value by set '{set}'", spec.to)));
            }
            inputs.push((to.clone(), spec));
            let from = match &spec.from {
                Source::SimTime => {
                    if !matches!(to.leaf.ty, ScalarType::Float32 | ScalarType::Float64) {
                        return Err(refused(format!(
                            "type mismatch: {SIM_TIME} is a time in seconds and needs a float input, {} is {}",
                            spec.to,
                            to.leaf.ty.canonical()
                        )));
                    }
                    let (gain, offset) = match &spec.units {
                        Some((ua, ub)) if ua.exponents != ub.exponents || ua.dimensions() != "s" => {
                            return Err(refused(format!(
                                "unit mismatch: {SIM_TIME} is a time ([s]), {} is in {} ({})",
                                spec.to,
                                ub.name,
                                ub.dimensions()
                            )))
                        }
                        Some((ua, ub)) => {
                            let (g, o) = ua.conversion_to(ub);
                            (g * spec.gain, o * spec.gain + spec.offset)
                        }
                        None => (spec.gain, spec.offset),
                    };
                    clocks.push((to, gain, offset));
                    continue;
                }
                Source::Item(r) => end(model, r, Role::Subscribe).map_err(|e| refused(e.to_string()))?,
            };
            let (a, b) = (&from.leaf, &to.leaf);
            if a.length != b.length {
                return Err(refused(format!(
                    "length mismatch: {} has {} element(s), {} has {}",
                    spec.from, a.length, spec.to, b.length
                )));
            }
            let (mut gain, mut offset) = (spec.gain, spec.offset);
            if let Some((ua, ub)) = &spec.units {
                if ua.exponents != ub.exponents {
                    return Err(refused(format!(
                        "unit mismatch: {} is in {} ({}), {} in {} ({}): not the same base dimensions",
                        spec.from,
                        ua.name,
                        ua.dimensions(),
                        spec.to,
                        ub.name,
                        ub.dimensions()
                    )));
                }
                // Into the input's unit first, then the gain and the offset.
                let (g, o) = ua.conversion_to(ub);
                (gain, offset) = (g * spec.gain, o * spec.gain + spec.offset);
            }
            let scaled = gain != 1.0 || offset != 0.0 || spec.units.is_some();
            if !converts(a.ty, b.ty, scaled) {
                return Err(refused(format!(
                    "type mismatch: {} is {}, {} is {}{}",
                    spec.from,
                    a.ty.canonical(),
                    spec.to,
                    b.ty.canonical(),
                    if scaled { " (a gain, an offset or a unit conversion needs numbers)" } else { "" }
                )));
            }
            let raw = !scaled && a.ty == b.ty;
            list.push(Connection { from, to, gain, offset, raw });
        }
        Ok(Connections { list, clocks, specs: specs.to_vec() })
    }

    /// Whether some input is the simulated time (`@sim_time`): it changes at every step.
    pub fn has_clock(&self) -> bool {
        !self.clocks.is_empty()
    }

    pub fn is_empty(&self) -> bool {
        self.list.is_empty() && self.clocks.is_empty()
    }

    /// The connections as given, in order.
    pub fn specs(&self) -> &[ConnectionSpec] {
        &self.specs
    }

    /// Writes `sim`, the simulated time of the step about to be published, into the input
    /// of every `@sim_time` connection in `publish` (each domain's PUBLISH buffer): called
    /// just before each step is published.
    pub fn apply_clock(&self, sim: f64, publish: &mut [Vec<u8>]) {
        for (to, gain, offset) in &self.clocks {
            let Some(dst) = publish.get_mut(to.domain).and_then(|p| p.get_mut(to.leaf.range())) else { continue };
            let v = Value::Float(sim * gain + offset);
            for y in dst.chunks_exact_mut(to.leaf.ty.size() as usize) {
                to.leaf.ty.encode(v, y);
            }
        }
    }

    /// The domains [`StepOrder::Feedthrough`] re-evaluates, in the order it does: every domain
    /// for which `synchronous(i)` holds that an output of another domain feeds, each after
    /// the domains that feed it. Where the graph has a cycle, the first domain of the cycle
    /// to be fed in the connections' order goes first.
    pub fn reevaluation_order(&self, synchronous: impl Fn(usize) -> bool) -> Vec<usize> {
        let edges: Vec<(usize, usize)> =
            self.list.iter().map(|c| (c.from.domain, c.to.domain)).filter(|&(a, b)| a != b && synchronous(b)).collect();
        let mut left: Vec<usize> = Vec::new();
        for &(_, b) in &edges {
            if !left.contains(&b) {
                left.push(b);
            }
        }
        let mut order = Vec::with_capacity(left.len());
        while !left.is_empty() {
            // The first domain none of whose sources is still to come; else (a cycle) the first.
            let ready = left.iter().position(|&d| !edges.iter().any(|&(a, b)| b == d && left.contains(&a)));
            order.push(left.remove(ready.unwrap_or(0)));
        }
        order
    }

    /// Copies each item connection's output in `subscribe(i)` (domain i's SUBSCRIBE set, i in
    /// model order) to its input in `publish` (each domain's PUBLISH buffer), in order:
    /// called after each step, for the next, with nothing allocated.
    pub fn apply<'a>(&self, subscribe: impl Fn(usize) -> Option<&'a [u8]>, publish: &mut [Vec<u8>]) {
        for c in &self.list {
            let (Some(src), Some(dst)) = (subscribe(c.from.domain), publish.get_mut(c.to.domain)) else { continue };
            let (Some(src), Some(dst)) = (src.get(c.from.leaf.range()), dst.get_mut(c.to.leaf.range())) else {
                continue;
            };
            if c.raw {
                dst.copy_from_slice(src);
                continue;
            }
            let (a, b) = (c.from.leaf.ty, c.to.leaf.ty);
            for (x, y) in src.chunks_exact(a.size() as usize).zip(dst.chunks_exact_mut(b.size() as usize)) {
                let v = a.decode(x);
                let v = if c.gain != 1.0 || c.offset != 0.0 { Value::Float(v.as_f64() * c.gain + c.offset) } else { v };
                b.encode(v, y);
            }
        }
    }
}

/// Why an end of a connection names no item of the right role.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
enum EndError {
    #[error("no domain '{0}' in the DDF")]
    NoDomain(String),
    #[error("no item '{item}' in the {set} set of domain '{domain}'", item = .0.item, set = set_name(.0.role), domain = .0.domain)]
    NoItem(ItemRef),
    #[error("{0} must be {what}", what = role_text(*.1))]
    Role(ItemRef, Role),
}

fn set_name(role: Role) -> &'static str {
    match role {
        Role::Publish => "PUBLISH",
        Role::Subscribe => "SUBSCRIBE",
    }
}

/// What an end of role `want` must be.
fn role_text(want: Role) -> &'static str {
    match want {
        Role::Subscribe => "an output: a SUBSCRIBE item (what participants write)",
        Role::Publish => "an input: a PUBLISH item (what participants read)",
    }
}

/// The leaf `r` names, which must have role `want`.
fn end(model: &Model, r: &ItemRef, want: Role) -> Result<End, EndError> {
    let (domain, d) = model
        .domains
        .iter()
        .enumerate()
        .find(|(_, d)| d.name == r.domain)
        .ok_or_else(|| EndError::NoDomain(r.domain.clone()))?;
    let leaf = d.set(r.role).layout.leaf(&r.item).ok_or_else(|| EndError::NoItem(r.clone()))?;
    if r.role != want {
        return Err(EndError::Role(r.clone(), want));
    }
    Ok(End { domain, leaf: leaf.clone() })
}

/// Whether an element of type `a` converts into type `b`.
fn converts(a: ScalarType, b: ScalarType, scaled: bool) -> bool {
    let float = |t: ScalarType| matches!(t, ScalarType::Float32 | ScalarType::Float64);
    let number = |t: ScalarType| t != ScalarType::Boolean;
    if scaled {
        return number(a) && number(b);
    }
    a == b || (float(b) && number(a))
}

fn overlap(a: &Leaf, b: &Leaf) -> bool {
    let (x, y) = (a.range(), b.range());
    x.start < y.end && y.start < x.end
}

/// Whether a `--set` target `DOMAIN/ITEM` is the input `to`.
fn set_target(target: &str, to: &ItemRef) -> bool {
    target.split_once('/').is_some_and(|(d, i)| d == to.domain && i == to.item)
}

#[cfg(test)]
mod tests {
    use super::*;

    const DDF: &str = r#"<?xml version="1.0"?>
<orchestra>
  <domain name="plant">
    <synchronous>yes</synchronous><multiplePublishAllowed>no</multiplePublishAllowed><states>no</states>
    <set name="PUBLISH"><item name="u"><type>float64</type></item><item name="on"><type>boolean</type></item></set>
    <set name="SUBSCRIBE"><item name="y"><type>float64</type></item><item name="n"><type>int32</type></item>
      <item name="v"><type>float32</type><length>3</length></item></set>
  </domain>
  <domain name="ctrl">
    <synchronous>no</synchronous><multiplePublishAllowed>yes</multiplePublishAllowed><states>no</states>
    <set name="PUBLISH"><item name="y_meas"><type>float64</type></item><item name="w"><type>float64</type><length>3</length></item></set>
    <set name="SUBSCRIBE"><item name="u"><type>float64</type></item></set>
  </domain>
</orchestra>"#;

    fn model() -> Model {
        tutti_core::ddf::parse_str(DDF, "c.ddf").unwrap()
    }

    fn resolve(specs: &[&str], sets: &[&str]) -> Result<Connections, ConnectError> {
        let specs: Vec<ConnectionSpec> = specs.iter().map(|s| parse_connection(s).unwrap()).collect();
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        Connections::resolve(&model(), &specs, &sets)
    }

    /// Four synchronous domains a..d and an asynchronous one e, each with inputs x and x2 and an
    /// output y. `"a>b"` connects a's y to b's x, `"a>b2"` to b's x2.
    fn chain_model() -> Model {
        let domain = |name: &str, sync: &str| {
            format!(
                "<domain name=\"{name}\"><synchronous>{sync}</synchronous><multiplePublishAllowed>no</multiplePublishAllowed><states>no</states>\
                 <set name=\"PUBLISH\"><item name=\"x\"><type>float64</type></item><item name=\"x2\"><type>float64</type></item></set>\
                 <set name=\"SUBSCRIBE\"><item name=\"y\"><type>float64</type></item></set></domain>"
            )
        };
        let domains: String = [("a", "yes"), ("b", "yes"), ("c", "yes"), ("d", "yes"), ("e", "no")]
            .iter()
            .map(|(n, s)| domain(n, s))
            .collect();
        tutti_core::ddf::parse_str(&format!("<orchestra>{domains}</orchestra>"), "chain.ddf").unwrap()
    }

    fn order(specs: &[&str]) -> Vec<String> {
        let model = chain_model();
        let specs: Vec<ConnectionSpec> = specs
            .iter()
            .map(|s| {
                let (a, b) = s.split_once('>').unwrap();
                let (b, x) = b.strip_suffix('2').map_or((b, "x"), |b| (b, "x2"));
                parse_connection(&format!("{a}/subscribe/y -> {b}/publish/{x}")).unwrap()
            })
            .collect();
        let c = Connections::resolve(&model, &specs, &[]).unwrap();
        c.reevaluation_order(|i| model.domains[i].flags.synchronous)
            .into_iter()
            .map(|i| model.domains[i].name.clone())
            .collect()
    }

    #[test]
    fn feedthrough_reevaluates_each_fed_domain_after_its_sources() {
        // Given backwards, evaluated forwards; a domain feeding itself and an asynchronous
        // target are not re-evaluated; a source that nothing feeds is not either.
        assert_eq!(order(&["c>d", "b>c", "a>b"]), ["b", "c", "d"]);
        assert_eq!(order(&["a>a", "a>e"]), Vec::<String>::new());
        // Two branches join: d after both.
        assert_eq!(order(&["b>d", "c>d2", "a>b", "a>c"]), ["b", "c", "d"]);
        // A cycle b <-> c fed by a: entered at the first fed domain of the cycle, once each.
        assert_eq!(order(&["c>b", "b>c", "a>b2"]), ["b", "c"]);
        assert_eq!(order(&["c>b", "b>c", "c>d"]), ["b", "c", "d"]);
    }

    #[test]
    fn an_ordering_is_named_and_an_unknown_one_is_refused() {
        assert_eq!("feedthrough".parse::<StepOrder>(), Ok(StepOrder::Feedthrough));
        assert_eq!("delayed".parse::<StepOrder>(), Ok(StepOrder::Delayed));
        assert_eq!(StepOrder::default(), StepOrder::Delayed);
        let e = "gauss-seidel".parse::<StepOrder>().unwrap_err().to_string();
        assert!(e.contains("'gauss-seidel'") && e.contains("feedthrough"), "{e}");
    }

    #[test]
    fn connections_parse_with_gain_and_offset() {
        let c = parse_connection("plant/subscribe/y -> ctrl/publish/y_meas * 2 - 0.5").unwrap();
        assert_eq!((c.gain, c.offset), (2.0, -0.5));
        assert_eq!(c.to, ItemRef { domain: "ctrl".into(), role: Role::Publish, item: "y_meas".into() });
        assert_eq!(c.to_string(), "plant/subscribe/y -> ctrl/publish/y_meas * 2 + -0.5");
        assert!(matches!(parse_connection("plant/y -> ctrl/publish/y"), Err(ConnectError::End { .. })));
        assert!(matches!(parse_connection("a/subscribe/y ctrl/publish/y"), Err(ConnectError::Form(_))));
        assert!(matches!(parse_connection("a/subscribe/y -> b/publish/y * x"), Err(ConnectError::Number { .. })));
    }

    #[test]
    fn refusals_name_both_ends() {
        let refused = |specs: &[&str], sets: &[&str]| resolve(specs, sets).unwrap_err().to_string();
        let e = refused(&["plant/subscribe/nope -> ctrl/publish/y_meas"], &[]);
        assert!(e.starts_with("plant/subscribe/nope -> ctrl/publish/y_meas: no item 'nope'"), "{e}");
        let e = refused(&["ctrl/publish/y_meas -> plant/publish/u"], &[]);
        assert!(e.contains("must be an output"), "{e}");
        let e = refused(&["plant/subscribe/y -> ctrl/publish/w"], &[]);
        assert!(e.contains("length mismatch: plant/subscribe/y has 1 element(s), ctrl/publish/w has 3"), "{e}");
        let e = refused(&["plant/subscribe/y -> plant/publish/on"], &[]);
        assert!(e.contains("type mismatch: plant/subscribe/y is float64, plant/publish/on is boolean"), "{e}");
        let e = refused(&["plant/subscribe/y -> ctrl/publish/y_meas", "plant/subscribe/n -> ctrl/publish/y_meas"], &[]);
        assert!(
            e.contains("ctrl/publish/y_meas already has a source: plant/subscribe/y -> ctrl/publish/y_meas"),
            "{e}"
        );
        let e = refused(&["plant/subscribe/y -> ctrl/publish/y_meas"], &["ctrl/y_meas=1"]);
        assert!(e.contains("also given a value by set 'ctrl/y_meas=1'"), "{e}");
        let e = refused(&["plant/subscribe/y -> elsewhere/publish/x"], &[]);
        assert!(e.contains("no domain 'elsewhere'"), "{e}");
    }

    #[test]
    fn outputs_reach_inputs_converted_and_scaled() {
        let m = model();
        let c = resolve(
            &[
                "plant/subscribe/y -> ctrl/publish/y_meas * 2 + 1",
                "ctrl/subscribe/u -> plant/publish/u",
                "plant/subscribe/v -> ctrl/publish/w",
            ],
            &[],
        )
        .unwrap();
        let mut sub: Vec<Vec<u8>> = m.domains.iter().map(|d| d.subscribe.layout.default_bytes()).collect();
        let leaf = |d: usize, role: Role, p: &str| m.domains[d].set(role).layout.leaf(p).unwrap().clone();
        let put = |buf: &mut Vec<u8>, l: &Leaf, vals: &[f64]| {
            for (e, v) in buf[l.range()].chunks_exact_mut(l.ty.size() as usize).zip(vals) {
                l.ty.encode(Value::Float(*v), e);
            }
        };
        put(&mut sub[0], &leaf(0, Role::Subscribe, "y"), &[3.0]);
        put(&mut sub[0], &leaf(0, Role::Subscribe, "v"), &[1.5, 2.5, 3.5]);
        put(&mut sub[1], &leaf(1, Role::Subscribe, "u"), &[-4.0]);
        let mut publish: Vec<Vec<u8>> = m.domains.iter().map(|d| d.publish.layout.default_bytes()).collect();
        let views: Vec<&[u8]> = sub.iter().map(Vec::as_slice).collect();
        c.apply(|i| views.get(i).copied(), &mut publish);
        let get = |buf: &[u8], l: &Leaf| -> Vec<f64> {
            buf[l.range()].chunks_exact(l.ty.size() as usize).map(|e| l.ty.decode(e).as_f64()).collect()
        };
        assert_eq!(get(&publish[1], &leaf(1, Role::Publish, "y_meas")), [7.0], "3 * 2 + 1");
        assert_eq!(get(&publish[0], &leaf(0, Role::Publish, "u")), [-4.0]);
        assert_eq!(get(&publish[1], &leaf(1, Role::Publish, "w")), [1.5, 2.5, 3.5], "float32 into float64");
    }

    #[test]
    fn units_convert_between_the_same_dimensions_before_the_gain_and_offset() {
        let c = parse_connection("plant/subscribe/y [km: m=1 factor=1000] -> ctrl/publish/y_meas [m] * 2 + 1").unwrap();
        let (a, b) = c.units.clone().unwrap();
        assert_eq!((a.factor, a.exponents[1], b.name.as_str()), (1000.0, 1, "m"));
        assert_eq!(c.to_string(), "plant/subscribe/y [km: m=1 factor=1000] -> ctrl/publish/y_meas [m] * 2 + 1");
        assert_eq!(parse_connection(&c.to_string()).unwrap(), c, "the text form reads back");
        let m = model();
        let run = |spec: &str, y: f64| -> f64 {
            let c = resolve(&[spec], &[]).unwrap();
            let mut sub: Vec<Vec<u8>> = m.domains.iter().map(|d| d.subscribe.layout.default_bytes()).collect();
            let l = m.domains[0].subscribe.layout.leaf("y").unwrap().clone();
            l.ty.encode(Value::Float(y), &mut sub[0][l.range()]);
            let mut publish: Vec<Vec<u8>> = m.domains.iter().map(|d| d.publish.layout.default_bytes()).collect();
            let views: Vec<&[u8]> = sub.iter().map(Vec::as_slice).collect();
            c.apply(|i| views.get(i).copied(), &mut publish);
            let l = m.domains[1].publish.layout.leaf("y_meas").unwrap();
            l.ty.decode(&publish[1][l.range()]).as_f64()
        };
        assert_eq!(run("plant/subscribe/y [km: m=1 factor=1000] -> ctrl/publish/y_meas [m] * 2 + 1", 3.0), 6001.0);
        // Celsius to Fahrenheit through kelvin: offsets on both sides.
        let c_to_f = "plant/subscribe/y [degC: K=1 offset=273.15] -> ctrl/publish/y_meas [degF: K=1 factor=0.5555555555555556 offset=255.3722222222222]";
        assert!((run(c_to_f, 100.0) - 212.0).abs() < 1e-9, "{}", run(c_to_f, 100.0));
        assert!((run(c_to_f, -40.0) + 40.0).abs() < 1e-9);
        let e = resolve(&["plant/subscribe/y [km: m=1 factor=1000] -> ctrl/publish/y_meas [s]"], &[]).unwrap_err();
        assert!(
            e.to_string().contains("unit mismatch: plant/subscribe/y is in km (m), ctrl/publish/y_meas in s (s)"),
            "{e}"
        );
        let e = resolve(&["plant/subscribe/n [m] -> plant/publish/on [m]"], &[]).unwrap_err();
        assert!(e.to_string().contains("a unit conversion needs numbers"), "{e}");
        for bad in [
            "plant/subscribe/y [km] -> ctrl/publish/y_meas [m]",
            "plant/subscribe/y [m] -> ctrl/publish/y_meas",
            "plant/subscribe/y [km: m=1 factor=0] -> ctrl/publish/y_meas [m]",
            "plant/subscribe/y [km: m=x] -> ctrl/publish/y_meas [m]",
            "plant/subscribe/y [km: furlong=1] -> ctrl/publish/y_meas [m]",
        ] {
            assert!(matches!(parse_connection(bad), Err(ConnectError::Unit { .. })), "{bad}");
        }
        let c = resolve(&["@sim_time [s] -> plant/publish/u [ms: s=1 factor=0.001]"], &[]).unwrap();
        let mut publish: Vec<Vec<u8>> = m.domains.iter().map(|d| d.publish.layout.default_bytes()).collect();
        c.apply_clock(0.25, &mut publish);
        let l = m.domains[0].publish.layout.leaf("u").unwrap();
        assert_eq!(l.ty.decode(&publish[0][l.range()]).as_f64(), 250.0);
    }

    #[test]
    fn the_simulated_time_is_a_source_written_into_the_step_it_is_published_in() {
        let m = model();
        let c = parse_connection("@sim_time -> ctrl/publish/w * 2 + 1").unwrap();
        assert_eq!(c.from, Source::SimTime);
        assert_eq!(c.to_string(), "@sim_time -> ctrl/publish/w * 2 + 1");
        let c = resolve(&["@sim_time -> plant/publish/u", "@sim_time -> ctrl/publish/w * 2 + 1"], &[]).unwrap();
        let mut publish: Vec<Vec<u8>> = m.domains.iter().map(|d| d.publish.layout.default_bytes()).collect();
        // Item connections (after a step) leave the clock's inputs alone.
        let sub: Vec<Vec<u8>> = m.domains.iter().map(|d| d.subscribe.layout.default_bytes()).collect();
        let views: Vec<&[u8]> = sub.iter().map(Vec::as_slice).collect();
        c.apply(|i| views.get(i).copied(), &mut publish);
        let leaf = |d: usize, p: &str| m.domains[d].publish.layout.leaf(p).unwrap().clone();
        let get = |buf: &[u8], l: &Leaf| -> Vec<f64> {
            buf[l.range()].chunks_exact(l.ty.size() as usize).map(|e| l.ty.decode(e).as_f64()).collect()
        };
        assert_eq!(get(&publish[0], &leaf(0, "u")), [0.0]);
        // Before the step at t = 0.15 s is published: exactly that time, in every element.
        c.apply_clock(0.15, &mut publish);
        assert_eq!(get(&publish[0], &leaf(0, "u")), [0.15]);
        assert_eq!(get(&publish[1], &leaf(1, "w")), [1.3, 1.3, 1.3]);
        c.apply_clock(3.0 * 0.05, &mut publish);
        assert_eq!(get(&publish[0], &leaf(0, "u"))[0].to_bits(), (3.0f64 * 0.05).to_bits(), "not rounded");
    }

    #[test]
    fn the_simulated_time_needs_a_float_input_of_its_own() {
        let refused = |specs: &[&str], sets: &[&str]| resolve(specs, sets).unwrap_err().to_string();
        let e = refused(&["@sim_time -> plant/publish/on"], &[]);
        assert!(
            e.contains("@sim_time is a time in seconds and needs a float input, plant/publish/on is boolean"),
            "{e}"
        );
        let e = refused(&["plant/subscribe/y -> ctrl/publish/y_meas", "@sim_time -> ctrl/publish/y_meas"], &[]);
        assert!(e.contains("already has a source: plant/subscribe/y -> ctrl/publish/y_meas"), "{e}");
        let e = refused(&["@sim_time -> plant/publish/u"], &["plant/u=2"]);
        assert!(e.contains("also given a value by set 'plant/u=2'"), "{e}");
        let e = refused(&["@sim_time -> plant/subscribe/y"], &[]);
        assert!(e.contains("must be an input"), "{e}");
        assert!(matches!(parse_connection("@wall_time -> plant/publish/u"), Err(ConnectError::UnknownSource { .. })));
    }
}
