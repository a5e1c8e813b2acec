//! The system an SSD describes, validated: what the run is made of, each part with the
//! `FILE:LINE:COL` it came from. Step two of reading an archive ([`crate::xml`] is step one):
//! every rule of docs/ssp.md is checked here, and what tutti does not support (a nested
//! system, SSM parameter mappings, SSB signal dictionaries, enumerations, mapping
//! transformations, …) is refused where it stands.

use tutti_core::ddf::Pos;
use tutti_host::connect::{Unit, BASE_UNITS};

use crate::archive::{resolve_source, Archive, SSD};
use crate::xml::{self, Node, Ns};
use crate::SspError;

/// SSP 1.0 or 2.0 (by the SSD's namespace).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SspVersion {
    V1,
    V2,
}

/// A connector's or a parameter's type: SSP 1.0's `Real`, `Integer`, `Boolean` (2.0's
/// `Float64`, `Int32`, `Boolean`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Type {
    Real,
    Integer,
    Boolean,
}

impl Type {
    pub fn as_str(self) -> &'static str {
        match self {
            Type::Real => "Real",
            Type::Integer => "Integer",
            Type::Boolean => "Boolean",
        }
    }
}

/// A connector's kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Causality {
    Input,
    Output,
    Parameter,
    CalculatedParameter,
}

impl Causality {
    pub fn as_str(self) -> &'static str {
        match self {
            Causality::Input => "input",
            Causality::Output => "output",
            Causality::Parameter => "parameter",
            Causality::CalculatedParameter => "calculatedParameter",
        }
    }
}

/// Where something was written: the file (`SYSTEM.ssp!SystemStructure.ssd`) and position.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct At {
    pub file: String,
    pub pos: Pos,
}

impl At {
    /// An error at this place.
    pub fn error(&self, message: impl Into<String>) -> SspError {
        SspError::At { file: self.file.clone(), line: self.pos.line, col: self.pos.col, message: message.into() }
    }
}

impl std::fmt::Display for At {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}:{}", self.file, self.pos.line, self.pos.col)
    }
}

#[derive(Debug, Clone)]
pub struct Connector {
    pub name: String,
    pub kind: Causality,
    /// None: the type is the FMU variable's.
    pub ty: Option<Type>,
    pub unit: Option<String>,
    pub at: At,
}

/// One parameter value of an SSV parameter set (inline or a file).
#[derive(Debug, Clone)]
pub struct ParamValue {
    /// The variable's name (component level), or `COMPONENT.VARIABLE` (system level).
    pub name: String,
    pub ty: Type,
    /// The value as FMI writes it (`1.5`, `3`, `true`).
    pub value: String,
    pub at: At,
}

#[derive(Debug, Clone)]
pub struct Component {
    pub name: String,
    /// The FMU's path inside the archive.
    pub source: String,
    pub connectors: Vec<Connector>,
    /// Its own parameter bindings' values, in binding order.
    pub params: Vec<ParamValue>,
    pub at: At,
}

impl Component {
    pub fn connector(&self, name: &str) -> Option<&Connector> {
        self.connectors.iter().find(|c| c.name == name)
    }
}

/// A connection between two components' connectors.
#[derive(Debug, Clone)]
pub struct Connection {
    /// (component, connector)
    pub from: (String, String),
    pub to: (String, String),
    /// `ssc:LinearTransformation`: factor and offset (1 and 0 without).
    pub factor: f64,
    pub offset: f64,
    /// `suppressUnitConversion="true"`.
    pub suppress_unit_conversion: bool,
    pub at: At,
}

/// A flat system of FMUs, checked.
#[derive(Debug, Clone)]
pub struct System {
    /// The SSD, as messages name it.
    pub file: String,
    pub version: SspVersion,
    pub name: String,
    pub components: Vec<Component>,
    pub connections: Vec<Connection>,
    /// `ssd:Units`.
    pub units: Vec<(Unit, At)>,
    /// The system's own parameter bindings, names `COMPONENT.VARIABLE`.
    pub system_params: Vec<ParamValue>,
    /// `ssd:DefaultExperiment`'s `stopTime` (its `startTime` must be 0).
    pub stop_time: Option<f64>,
}

impl System {
    pub fn component(&self, name: &str) -> Option<&Component> {
        self.components.iter().find(|c| c.name == name)
    }

    /// The unit named `name`: one of `ssd:Units`, else an SI base unit.
    pub fn unit(&self, name: &str) -> Option<Unit> {
        self.units.iter().find(|(u, _)| u.name == name).map(|(u, _)| u.clone()).or_else(|| Unit::base(name))
    }

    /// Reads and checks the archive's `SystemStructure.ssd` (and the SSV files it binds).
    pub fn load(archive: &mut Archive) -> Result<System, SspError> {
        let file = archive.label(SSD);
        let text = archive.read_text(SSD)?;
        let root = xml::parse(&text, &file)?;
        let mut r = Reader { archive, file: file.clone() };
        r.system_description(&root)
    }
}

struct Reader<'a> {
    archive: &'a mut Archive,
    file: String,
}

fn at(file: &str, n: &Node) -> At {
    At { file: file.to_string(), pos: n.pos }
}

fn unsupported(file: &str, n: &Node, what: impl Into<String>) -> SspError {
    SspError::Unsupported { file: file.to_string(), line: n.pos.line, col: n.pos.col, what: what.into() }
}

fn number(file: &str, n: &Node, attr: &str) -> Result<Option<f64>, SspError> {
    match n.attr(attr) {
        None => Ok(None),
        Some(v) => v
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .map(Some)
            .ok_or_else(|| at(file, n).error(format!("<{}> {attr}=\"{v}\" is not a finite number", n.qname))),
    }
}

fn required<'n>(file: &str, n: &'n Node, attr: &str) -> Result<&'n str, SspError> {
    n.attr(attr).ok_or_else(|| at(file, n).error(format!("<{}> has no {attr}=\"…\"", n.qname)))
}

/// The type element of a connector (`ssc:Real`, …) or a parameter (`ssv:Real`, …).
fn type_of(name: &str) -> Option<Type> {
    match name {
        "Real" | "Float64" => Some(Type::Real),
        "Integer" | "Int32" => Some(Type::Integer),
        "Boolean" => Some(Type::Boolean),
        _ => None,
    }
}

/// Elements that describe looks or carry a tool's notes: never part of the run.
fn cosmetic(n: &Node) -> bool {
    matches!(
        n.name.as_str(),
        "Annotations"
            | "ElementGeometry"
            | "ConnectorGeometry"
            | "ConnectionGeometry"
            | "SystemGeometry"
            | "GraphicalElements"
            | "MetaData"
            | "Signature"
    ) || n.ns == Ns::Other
}

/// `<ssd:DefaultExperiment>`: its `stopTime`, if it has one (its `startTime` must be 0).
fn default_experiment(file: &str, n: &Node) -> Result<Option<f64>, SspError> {
    let start = number(file, n, "startTime")?.unwrap_or(0.0);
    if start != 0.0 {
        return Err(at(file, n).error(format!(
            "startTime=\"{start}\": a run starts at time 0 (docs/ssp.md); shift the system's time to 0"
        )));
    }
    number(file, n, "stopTime")
}

/// Every system-level parameter names a component's variable, `COMPONENT.VARIABLE`.
fn check_system_params(system: &System) -> Result<(), SspError> {
    for p in &system.system_params {
        let Some((comp, var)) = p.name.split_once('.') else {
            return Err(p.at.error(format!(
                "system-level parameter '{}': name a component's variable as COMPONENT.VARIABLE",
                p.name
            )));
        };
        if system.component(comp).is_none() || var.is_empty() {
            return Err(p.at.error(format!("system-level parameter '{}': no component '{comp}'", p.name)));
        }
    }
    Ok(())
}

impl Reader<'_> {
    fn system_description(&mut self, root: &Node) -> Result<System, SspError> {
        let f = self.file.clone();
        if !root.is(Ns::Ssd, "SystemStructureDescription") {
            return Err(at(&f, root).error(format!(
                "the root element is <{}> ({}), not an SSD's <ssd:SystemStructureDescription> of SSP 1.0 or 2.0",
                root.qname,
                if root.uri.is_empty() { "no namespace".to_string() } else { root.uri.clone() }
            )));
        }
        let version = if root.uri == xml::SSD2 { SspVersion::V2 } else { SspVersion::V1 };
        let mut system = None;
        let mut units = Vec::new();
        let mut stop_time = None;
        for c in &root.children {
            match (c.ns, c.name.as_str()) {
                (Ns::Ssd, "System") => system = Some(c),
                (Ns::Ssd, "Units") => units = self.units(c)?,
                (Ns::Ssd, "Enumerations") => return Err(unsupported(&f, c, "enumerations (<ssd:Enumerations>)")),
                (Ns::Ssd, "DefaultExperiment") => stop_time = default_experiment(&f, c)?,
                _ if cosmetic(c) => {}
                _ => return Err(at(&f, c).error(format!("unknown element <{}> in an SSD", c.qname))),
            }
        }
        let Some(sys) = system else {
            return Err(at(&f, root).error("the SSD has no <ssd:System>"));
        };
        let mut out = System {
            file: f.clone(),
            version,
            name: sys.attr("name").or(root.attr("name")).unwrap_or("system").to_string(),
            components: Vec::new(),
            connections: Vec::new(),
            units,
            system_params: Vec::new(),
            stop_time,
        };
        let connections = self.system(sys, &mut out)?;
        if out.components.is_empty() {
            return Err(at(&f, sys).error("the system has no component"));
        }
        if let Some(c) = connections {
            self.connections(c, &mut out)?;
        }
        check_system_params(&out)?;
        Ok(out)
    }

    /// The children of `<ssd:System>`: its components and its parameter bindings, into
    /// `out`. Its `<ssd:Connections>` is returned, to be read once every component is known.
    fn system<'n>(&mut self, sys: &'n Node, out: &mut System) -> Result<Option<&'n Node>, SspError> {
        let f = self.file.clone();
        let mut connections = None;
        for c in &sys.children {
            match (c.ns, c.name.as_str()) {
                (Ns::Ssd, "Elements") => self.elements(c, out)?,
                (Ns::Ssd, "Connections") => connections = Some(c),
                (Ns::Ssd, "ParameterBindings") => out.system_params = self.bindings(c)?,
                (Ns::Ssd, "SignalDictionaries") => {
                    return Err(unsupported(&f, c, "signal dictionaries (<ssd:SignalDictionaries>, SSB)"))
                }
                // The system's own connectors may be declared; a connection to one is refused.
                (Ns::Ssd, "Connectors") => {}
                _ if cosmetic(c) => {}
                _ => return Err(at(&f, c).error(format!("unknown element <{}> in <ssd:System>", c.qname))),
            }
        }
        Ok(connections)
    }

    /// `<ssd:Elements>`: the components, into `out`.
    fn elements(&mut self, n: &Node, out: &mut System) -> Result<(), SspError> {
        let f = self.file.clone();
        for e in &n.children {
            match (e.ns, e.name.as_str()) {
                (Ns::Ssd, "Component") => {
                    let comp = self.component(e)?;
                    if out.component(&comp.name).is_some() {
                        return Err(at(&f, e).error(format!("two components are named '{}'", comp.name)));
                    }
                    out.components.push(comp);
                }
                (Ns::Ssd, "System") => {
                    return Err(unsupported(&f, e, "a nested system (<ssd:System> inside <ssd:Elements>)"))
                }
                (Ns::Ssd, "SignalDictionaryReference") => {
                    return Err(unsupported(&f, e, "a signal dictionary reference (SSB)"))
                }
                _ if cosmetic(e) => {}
                _ => return Err(at(&f, e).error(format!("unknown element <{}> in <ssd:Elements>", e.qname))),
            }
        }
        Ok(())
    }

    /// `<ssd:Connections>`, into `out` (whose components are all known).
    fn connections(&mut self, n: &Node, out: &mut System) -> Result<(), SspError> {
        for c in &n.children {
            if c.is(Ns::Ssd, "Connection") {
                let conn = self.connection(c, out)?;
                out.connections.push(conn);
            } else if !cosmetic(c) {
                return Err(at(&self.file, c).error(format!("unknown element <{}> in <ssd:Connections>", c.qname)));
            }
        }
        Ok(())
    }

    fn units(&mut self, n: &Node) -> Result<Vec<(Unit, At)>, SspError> {
        let f = self.file.clone();
        let mut out: Vec<(Unit, At)> = Vec::new();
        for u in &n.children {
            if !u.is(Ns::Ssc, "Unit") {
                if cosmetic(u) {
                    continue;
                }
                return Err(at(&f, u).error(format!("unknown element <{}> in <ssd:Units>", u.qname)));
            }
            let name = required(&f, u, "name")?.to_string();
            let Some(base) = u.children.iter().find(|b| b.is(Ns::Ssc, "BaseUnit")) else {
                return Err(at(&f, u).error(format!("unit '{name}' has no <ssc:BaseUnit>")));
            };
            let mut unit = Unit { name: name.clone(), exponents: [0; 8], factor: 1.0, offset: 0.0 };
            for (i, b) in BASE_UNITS.iter().enumerate() {
                if let Some(e) = base.attr(b) {
                    unit.exponents[i] = e.trim().parse().map_err(|_| {
                        at(&f, base).error(format!("unit '{name}': {b}=\"{e}\" is not a whole exponent"))
                    })?;
                }
            }
            unit.factor = number(&f, base, "factor")?.unwrap_or(1.0);
            unit.offset = number(&f, base, "offset")?.unwrap_or(0.0);
            if unit.factor == 0.0 {
                return Err(at(&f, base).error(format!("unit '{name}': factor=\"0\" converts nothing")));
            }
            if out.iter().any(|(o, _)| o.name == name) {
                return Err(at(&f, u).error(format!("unit '{name}' is defined twice")));
            }
            out.push((unit, at(&f, u)));
        }
        Ok(out)
    }

    fn component(&mut self, n: &Node) -> Result<Component, SspError> {
        let f = self.file.clone();
        let name = required(&f, n, "name")?.to_string();
        let ty = n.attr("type").unwrap_or("application/x-fmu-sharedlibrary");
        if ty != "application/x-fmu-sharedlibrary" {
            return Err(unsupported(&f, n, format!("component '{name}' of type '{ty}' (only FMUs)")));
        }
        if n.attr("implementation") == Some("ModelExchange") {
            return Err(unsupported(&f, n, format!("component '{name}' with implementation=\"ModelExchange\"")));
        }
        let source_text = required(&f, n, "source")?;
        let source = resolve_source(source_text).ok_or_else(|| {
            at(&f, n).error(format!("component '{name}': source=\"{source_text}\" is not a path inside the archive"))
        })?;
        if !self.archive.has(&source) {
            return Err(at(&f, n).error(format!("component '{name}': the archive has no {source}")));
        }
        let mut comp = Component { name, source, connectors: Vec::new(), params: Vec::new(), at: at(&f, n) };
        for c in &n.children {
            match (c.ns, c.name.as_str()) {
                (Ns::Ssd, "Connectors") => {
                    for k in &c.children {
                        if k.is(Ns::Ssd, "Connector") {
                            let conn = self.connector(k, &comp.name)?;
                            if comp.connector(&conn.name).is_some() {
                                return Err(at(&f, k).error(format!(
                                    "component '{}' declares connector '{}' twice",
                                    comp.name, conn.name
                                )));
                            }
                            comp.connectors.push(conn);
                        } else if !cosmetic(k) {
                            return Err(at(&f, k).error(format!("unknown element <{}> in <ssd:Connectors>", k.qname)));
                        }
                    }
                }
                (Ns::Ssd, "ParameterBindings") => comp.params = self.bindings(c)?,
                _ if cosmetic(c) => {}
                _ => return Err(at(&f, c).error(format!("unknown element <{}> in <ssd:Component>", c.qname))),
            }
        }
        Ok(comp)
    }

    fn connector(&mut self, n: &Node, component: &str) -> Result<Connector, SspError> {
        let f = self.file.clone();
        let name = required(&f, n, "name")?.to_string();
        let kind = match required(&f, n, "kind")? {
            "input" => Causality::Input,
            "output" => Causality::Output,
            "parameter" => Causality::Parameter,
            "calculatedParameter" => Causality::CalculatedParameter,
            k => return Err(unsupported(&f, n, format!("connector '{component}.{name}' of kind '{k}'"))),
        };
        let mut ty = None;
        let mut unit = None;
        for c in &n.children {
            if c.ns == Ns::Ssc && !cosmetic(c) {
                match type_of(&c.name) {
                    Some(t) => {
                        ty = Some(t);
                        unit = c.attr("unit").map(str::to_string);
                    }
                    None => {
                        return Err(unsupported(
                            &f,
                            c,
                            format!("connector '{component}.{name}' of type <{}> (Real, Integer, Boolean; 2.0's Float64, Int32, Boolean)", c.qname),
                        ))
                    }
                }
            } else if !cosmetic(c) {
                return Err(at(&f, c).error(format!("unknown element <{}> in <ssd:Connector>", c.qname)));
            }
        }
        Ok(Connector { name, kind, ty, unit, at: at(&f, n) })
    }

    /// `ssd:ParameterBindings`: each binding's values, inline or from its SSV file, in order.
    fn bindings(&mut self, n: &Node) -> Result<Vec<ParamValue>, SspError> {
        let f = self.file.clone();
        let mut out = Vec::new();
        for b in &n.children {
            if !b.is(Ns::Ssd, "ParameterBinding") {
                if cosmetic(b) {
                    continue;
                }
                return Err(at(&f, b).error(format!("unknown element <{}> in <ssd:ParameterBindings>", b.qname)));
            }
            let ty = b.attr("type").unwrap_or("application/x-ssp-parameter-set");
            if ty != "application/x-ssp-parameter-set" {
                return Err(unsupported(&f, b, format!("a parameter binding of type '{ty}'")));
            }
            let prefix = b.attr("prefix").unwrap_or("");
            if let Some(m) = b.children.iter().find(|c| c.is(Ns::Ssd, "ParameterMapping")) {
                return Err(unsupported(&f, m, "a parameter mapping (<ssd:ParameterMapping>, SSM)"));
            }
            let mut values = Vec::new();
            match (b.attr("source"), b.children.iter().find(|c| c.is(Ns::Ssd, "ParameterValues"))) {
                (Some(_), Some(_)) => {
                    return Err(at(&f, b).error("a parameter binding with both source=\"…\" and <ssd:ParameterValues>"))
                }
                (Some(src), None) => {
                    let path = resolve_source(src)
                        .ok_or_else(|| at(&f, b).error(format!("source=\"{src}\" is not a path inside the archive")))?;
                    if !self.archive.has(&path) {
                        return Err(at(&f, b).error(format!("the archive has no {path}")));
                    }
                    let file = self.archive.label(&path);
                    let text = self.archive.read_text(&path)?;
                    let root = xml::parse(&text, &file)?;
                    parameter_set(&file, &root, &mut values)?;
                }
                (None, Some(inline)) => {
                    let Some(set) = inline.children.iter().find(|c| !cosmetic(c)) else {
                        return Err(at(&f, inline).error("<ssd:ParameterValues> holds no <ssv:ParameterSet>"));
                    };
                    parameter_set(&f, set, &mut values)?;
                }
                (None, None) => return Err(at(&f, b).error("a parameter binding with neither source=\"…\" nor values")),
            }
            for v in &mut values {
                match v.name.strip_prefix(prefix) {
                    Some(rest) if !prefix.is_empty() => v.name = rest.to_string(),
                    _ => {}
                }
            }
            out.extend(values);
        }
        Ok(out)
    }

    fn connection(&mut self, n: &Node, sys: &System) -> Result<Connection, SspError> {
        let f = self.file.clone();
        let here = at(&f, n);
        let end = |elem: &str, conn: &str| -> Result<(String, String), SspError> {
            let Some(e) = n.attr(elem) else {
                return Err(unsupported(
                    &f,
                    n,
                    format!("a connection to the system's own connector '{}'", n.attr(conn).unwrap_or("?")),
                ));
            };
            let c = required(&f, n, conn)?;
            Ok((e.to_string(), c.to_string()))
        };
        let from = end("startElement", "startConnector")?;
        let to = end("endElement", "endConnector")?;
        let mut factor = 1.0;
        let mut offset = 0.0;
        for c in &n.children {
            match (c.ns, c.name.as_str()) {
                (Ns::Ssc, "LinearTransformation") => {
                    factor = number(&f, c, "factor")?.unwrap_or(1.0);
                    offset = number(&f, c, "offset")?.unwrap_or(0.0);
                }
                (Ns::Ssc, t) if t.ends_with("Transformation") => {
                    return Err(unsupported(
                        &f,
                        c,
                        format!("a <{}> on a connection (only ssc:LinearTransformation)", c.qname),
                    ))
                }
                _ if cosmetic(c) => {}
                _ => return Err(at(&f, c).error(format!("unknown element <{}> in <ssd:Connection>", c.qname))),
            }
        }
        let suppress = n.attr("suppressUnitConversion") == Some("true");
        let conn = Connection { from, to, factor, offset, suppress_unit_conversion: suppress, at: here.clone() };
        // Both ends: a component's declared connector of the right kind.
        let mut tys = Vec::new();
        for ((elem, name), want) in [(&conn.from, Causality::Output), (&conn.to, Causality::Input)] {
            let comp = sys.component(elem).ok_or_else(|| here.error(format!("no component '{elem}' in the system")))?;
            let k = comp.connector(name).ok_or_else(|| {
                let known: Vec<&str> = comp.connectors.iter().map(|c| c.name.as_str()).collect();
                here.error(format!(
                    "unknown connector '{elem}.{name}': component '{elem}' declares {}",
                    if known.is_empty() { "none".to_string() } else { known.join(", ") }
                ))
            })?;
            let ok = match want {
                Causality::Output => matches!(k.kind, Causality::Output | Causality::CalculatedParameter),
                _ => matches!(k.kind, Causality::Input | Causality::Parameter),
            };
            if !ok {
                let role = if want == Causality::Output { "start" } else { "end" };
                return Err(here.error(format!(
                    "connector '{elem}.{name}' is an {} and cannot be a connection's {role}",
                    k.kind.as_str()
                )));
            }
            tys.push(k);
        }
        let (a, b) = (tys[0], tys[1]);
        if let (Some(ta), Some(tb)) = (a.ty, b.ty) {
            let fits = ta == tb || (ta == Type::Integer && tb == Type::Real);
            let scaled = factor != 1.0 || offset != 0.0;
            if !fits || (scaled && (ta == Type::Boolean || tb == Type::Boolean)) {
                return Err(here.error(format!(
                    "type mismatch: {}.{} is {}, {}.{} is {}",
                    conn.from.0,
                    conn.from.1,
                    ta.as_str(),
                    conn.to.0,
                    conn.to.1,
                    tb.as_str()
                )));
            }
        }
        if !suppress {
            if let (Some(ua), Some(ub)) = (&a.unit, &b.unit) {
                for u in [ua, ub] {
                    if sys.unit(u).is_none() {
                        return Err(
                            here.error(format!("unit '{u}' is not defined in <ssd:Units> (nor an SI base unit)"))
                        );
                    }
                }
            }
        }
        Ok(conn)
    }
}

/// The values of an `ssv:ParameterSet` element into `out`.
fn parameter_set(file: &str, set: &Node, out: &mut Vec<ParamValue>) -> Result<(), SspError> {
    if !set.is(Ns::Ssv, "ParameterSet") {
        return Err(
            at(file, set).error(format!("expected an <ssv:ParameterSet> of SSP 1.0 or 2.0, found <{}>", set.qname))
        );
    }
    for c in &set.children {
        match (c.ns, c.name.as_str()) {
            (Ns::Ssv, "Parameters") => {
                for p in &c.children {
                    if !p.is(Ns::Ssv, "Parameter") {
                        if cosmetic(p) {
                            continue;
                        }
                        return Err(at(file, p).error(format!("unknown element <{}> in <ssv:Parameters>", p.qname)));
                    }
                    out.push(parameter(file, p)?);
                }
            }
            (Ns::Ssv, "Units") => return Err(unsupported(file, c, "units in a parameter set (<ssv:Units>)")),
            (Ns::Ssv, "Enumerations") => return Err(unsupported(file, c, "enumerations (<ssv:Enumerations>)")),
            _ if cosmetic(c) => {}
            _ => return Err(at(file, c).error(format!("unknown element <{}> in <ssv:ParameterSet>", c.qname))),
        }
    }
    Ok(())
}

fn parameter(file: &str, p: &Node) -> Result<ParamValue, SspError> {
    let name = required(file, p, "name")?.to_string();
    let Some(v) = p.children.iter().find(|c| !cosmetic(c)) else {
        return Err(at(file, p).error(format!("parameter '{name}' has no value")));
    };
    let ty = type_of(&v.name).filter(|_| v.ns == Ns::Ssv).ok_or_else(|| {
        unsupported(
            file,
            v,
            format!("parameter '{name}' of type <{}> (Real, Integer, Boolean; 2.0's Float64, Int32, Boolean)", v.qname),
        )
    })?;
    if v.attr("unit").is_some() {
        return Err(unsupported(
            file,
            v,
            format!("parameter '{name}' with a unit (values are taken in the variable's unit)"),
        ));
    }
    let text = required(file, v, "value")?.trim().to_string();
    let ok = match ty {
        Type::Real => text.parse::<f64>().is_ok_and(f64::is_finite),
        Type::Integer => text.parse::<i32>().is_ok(),
        Type::Boolean => matches!(text.as_str(), "true" | "false" | "1" | "0"),
    };
    if !ok {
        return Err(at(file, v).error(format!("parameter '{name}': value=\"{text}\" is not a {}", ty.as_str())));
    }
    Ok(ParamValue { name, ty, value: text, at: at(file, v) })
}
