//! The parts of an FMU's `modelDescription.xml` that tutti uses, for FMI 2.0 and 3.0: the
//! model's identity, its co-simulation capabilities, the default experiment and the
//! variables. Read with the core's positioned XML reader, so that every error names a line.
//!
//! Only what tutti needs is validated, and what it would be unsafe to take as written (a
//! `modelIdentifier` that is not a plain name, since it names the library file to load; a
//! start value that is not a finite value of its variable's type). Every command that opens
//! an FMU (`tutti fmu inspect`, `ddf`, `run`) goes through [`ModelDescription::parse`], so
//! they refuse the same files with the same message. Anything else in the file is ignored
//! (FMUs carry many vendor annotations). See docs/fmu.md, "Loading".

use serde::Serialize;
use tutti_core::ddf::raw::{self, RawElement};
use tutti_core::ddf::ScalarType;

/// The FMI major version of an FMU.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum FmiVersion {
    #[serde(rename = "2.0")]
    Fmi2,
    #[serde(rename = "3.0")]
    Fmi3,
}

impl FmiVersion {
    pub fn as_str(self) -> &'static str {
        match self {
            FmiVersion::Fmi2 => "2.0",
            FmiVersion::Fmi3 => "3.0",
        }
    }

    /// The folder of `binaries/` that holds the Linux x86_64 shared library.
    pub fn platform_folder(self) -> &'static str {
        match self {
            FmiVersion::Fmi2 => "linux64",
            FmiVersion::Fmi3 => "x86_64-linux",
        }
    }
}

/// The `<CoSimulation>` element: the model identifier and the capabilities tutti shows.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CoSimulation {
    pub model_identifier: String,
    pub can_handle_variable_communication_step_size: bool,
    /// `canGetAndSetFMUstate` (FMI 3.0 `canGetAndSetFMUState`): the FMU copies its state and
    /// takes a copy back.
    pub can_get_and_set_fmu_state: bool,
    /// `canSerializeFMUstate` (FMI 3.0 `canSerializeFMUState`): the FMU turns such a copy into
    /// bytes and back.
    pub can_serialize_fmu_state: bool,
    pub needs_execution_tool: bool,
    pub can_be_instantiated_only_once_per_process: bool,
    /// Every capability attribute as written (name, value), for `inspect`.
    pub attributes: Vec<(String, String)>,
}

impl CoSimulation {
    /// The capability attributes that saving and restoring the FMU's state (a checkpoint:
    /// docs/fmu.md, "Checkpoints") needs and this FMU does not declare, spelt as FMI `version`
    /// spells them; empty when it can.
    pub fn missing_state_capabilities(&self, version: FmiVersion) -> Vec<&'static str> {
        let (get_set, serialize) = match version {
            FmiVersion::Fmi2 => ("canGetAndSetFMUstate", "canSerializeFMUstate"),
            FmiVersion::Fmi3 => ("canGetAndSetFMUState", "canSerializeFMUState"),
        };
        [(self.can_get_and_set_fmu_state, get_set), (self.can_serialize_fmu_state, serialize)]
            .into_iter()
            .filter(|(declared, _)| !declared)
            .map(|(_, name)| name)
            .collect()
    }
}

/// `<DefaultExperiment>`.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct DefaultExperiment {
    pub start_time: Option<f64>,
    pub stop_time: Option<f64>,
    pub tolerance: Option<f64>,
    pub step_size: Option<f64>,
}

/// The causality of a variable (FMI 2.0 and 3.0 share these names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "camelCase")]
pub enum Causality {
    Parameter,
    CalculatedParameter,
    Input,
    Output,
    Local,
    Independent,
    StructuralParameter,
}

impl Causality {
    fn parse(text: &str) -> Option<Causality> {
        Some(match text {
            "parameter" => Causality::Parameter,
            "calculatedParameter" => Causality::CalculatedParameter,
            "input" => Causality::Input,
            "output" => Causality::Output,
            "local" => Causality::Local,
            "independent" => Causality::Independent,
            "structuralParameter" => Causality::StructuralParameter,
            _ => return None,
        })
    }

    pub fn as_str(self) -> &'static str {
        match self {
            Causality::Parameter => "parameter",
            Causality::CalculatedParameter => "calculatedParameter",
            Causality::Input => "input",
            Causality::Output => "output",
            Causality::Local => "local",
            Causality::Independent => "independent",
            Causality::StructuralParameter => "structuralParameter",
        }
    }
}

/// The type of a variable, with FMI 2.0's types folded into FMI 3.0's names
/// (`Real` = `Float64`, `Integer` = `Int32`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum VarType {
    Float32,
    Float64,
    Int8,
    Int16,
    Int32,
    Int64,
    UInt8,
    UInt16,
    UInt32,
    UInt64,
    Boolean,
    /// FMI 2.0 `Enumeration` (an `Integer`), FMI 3.0 `Enumeration` (an `Int64`).
    Enumeration,
    String,
    Binary,
    Clock,
}

impl VarType {
    /// The element name in `modelDescription.xml` of `version`.
    pub fn fmi_name(self, version: FmiVersion) -> &'static str {
        match (self, version) {
            (VarType::Float64, FmiVersion::Fmi2) => "Real",
            (VarType::Int32, FmiVersion::Fmi2) => "Integer",
            (VarType::Float32, _) => "Float32",
            (VarType::Float64, _) => "Float64",
            (VarType::Int8, _) => "Int8",
            (VarType::Int16, _) => "Int16",
            (VarType::Int32, _) => "Int32",
            (VarType::Int64, _) => "Int64",
            (VarType::UInt8, _) => "UInt8",
            (VarType::UInt16, _) => "UInt16",
            (VarType::UInt32, _) => "UInt32",
            (VarType::UInt64, _) => "UInt64",
            (VarType::Boolean, _) => "Boolean",
            (VarType::Enumeration, _) => "Enumeration",
            (VarType::String, _) => "String",
            (VarType::Binary, _) => "Binary",
            (VarType::Clock, _) => "Clock",
        }
    }

    /// The DDF type a variable of this type maps to, or `None` when tutti cannot exchange it
    /// (strings, binaries, clocks).
    pub fn ddf_type(self, version: FmiVersion) -> Option<ScalarType> {
        Some(match self {
            VarType::Float32 => ScalarType::Float32,
            VarType::Float64 => ScalarType::Float64,
            VarType::Int8 => ScalarType::Int8,
            VarType::Int16 => ScalarType::Int16,
            VarType::Int32 => ScalarType::Int32,
            VarType::Int64 => ScalarType::Int64,
            VarType::UInt8 => ScalarType::UInt8,
            VarType::UInt16 => ScalarType::UInt16,
            VarType::UInt32 => ScalarType::UInt32,
            VarType::UInt64 => ScalarType::UInt64,
            VarType::Boolean => ScalarType::Boolean,
            VarType::Enumeration if version == FmiVersion::Fmi2 => ScalarType::Int32,
            VarType::Enumeration => ScalarType::Int64,
            VarType::String | VarType::Binary | VarType::Clock => return None,
        })
    }

    fn parse(name: &str, version: FmiVersion) -> Option<VarType> {
        Some(match (name, version) {
            ("Real", FmiVersion::Fmi2) => VarType::Float64,
            ("Integer", FmiVersion::Fmi2) => VarType::Int32,
            ("Boolean", _) => VarType::Boolean,
            ("String", _) => VarType::String,
            ("Enumeration", _) => VarType::Enumeration,
            ("Float32", FmiVersion::Fmi3) => VarType::Float32,
            ("Float64", FmiVersion::Fmi3) => VarType::Float64,
            ("Int8", FmiVersion::Fmi3) => VarType::Int8,
            ("Int16", FmiVersion::Fmi3) => VarType::Int16,
            ("Int32", FmiVersion::Fmi3) => VarType::Int32,
            ("Int64", FmiVersion::Fmi3) => VarType::Int64,
            ("UInt8", FmiVersion::Fmi3) => VarType::UInt8,
            ("UInt16", FmiVersion::Fmi3) => VarType::UInt16,
            ("UInt32", FmiVersion::Fmi3) => VarType::UInt32,
            ("UInt64", FmiVersion::Fmi3) => VarType::UInt64,
            ("Binary", FmiVersion::Fmi3) => VarType::Binary,
            ("Clock", FmiVersion::Fmi3) => VarType::Clock,
            _ => return None,
        })
    }
}

/// One model variable.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Variable {
    pub name: String,
    pub value_reference: u32,
    pub causality: Causality,
    /// `constant`, `fixed`, `tunable`, `discrete` or `continuous` (the default filled in).
    pub variability: String,
    #[serde(rename = "type")]
    pub ty: VarType,
    /// The start value as written, if any.
    pub start: Option<String>,
    pub unit: Option<String>,
    pub description: Option<String>,
    /// FMI 3.0 arrays (`<Dimension>`): tutti exchanges scalars only.
    pub is_array: bool,
    /// Line of the variable in `modelDescription.xml`.
    pub line: u32,
}

/// What tutti reads of `modelDescription.xml`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelDescription {
    pub fmi_version: FmiVersion,
    /// The `fmiVersion` attribute as written.
    pub fmi_version_text: String,
    pub model_name: String,
    /// FMI 2.0 `guid`, FMI 3.0 `instantiationToken`.
    pub token: String,
    pub description: Option<String>,
    pub generation_tool: Option<String>,
    pub co_simulation: Option<CoSimulation>,
    pub model_exchange: bool,
    pub default_experiment: Option<DefaultExperiment>,
    pub variables: Vec<Variable>,
}

/// A problem in `modelDescription.xml`, with its line and column.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("modelDescription.xml:{line}:{col}: {message}")]
pub struct ModelError {
    pub line: u32,
    pub col: u32,
    pub message: String,
}

fn err(pos: tutti_core::ddf::Pos, message: impl Into<String>) -> ModelError {
    ModelError { line: pos.line, col: pos.col, message: message.into() }
}

impl ModelDescription {
    /// Parses the text of a `modelDescription.xml`.
    pub fn parse(text: &str) -> Result<ModelDescription, ModelError> {
        if text.trim().is_empty() {
            return Err(ModelError { line: 1, col: 1, message: "the file is empty".into() });
        }
        let doc = raw::parse(text).map_err(|e| err(e.pos, e.message))?;
        let root = doc.root();
        if root.name() != "fmiModelDescription" {
            return Err(err(root.pos(), format!("the root element is <{}>, not <fmiModelDescription>", root.name())));
        }
        let version_text = required(root, "fmiVersion")?.to_string();
        let fmi_version = if version_text.starts_with("2.") {
            FmiVersion::Fmi2
        } else if version_text.starts_with("3.") {
            FmiVersion::Fmi3
        } else {
            return Err(err(root.pos(), format!("fmiVersion=\"{version_text}\": only FMI 2.0 and 3.0 are supported")));
        };
        let token_attr = match fmi_version {
            FmiVersion::Fmi2 => "guid",
            FmiVersion::Fmi3 => "instantiationToken",
        };
        let mut md = ModelDescription {
            fmi_version,
            fmi_version_text: version_text,
            model_name: required(root, "modelName")?.to_string(),
            token: required(root, token_attr)?.to_string(),
            description: root.attr("description").map(str::to_string),
            generation_tool: root.attr("generationTool").map(str::to_string),
            co_simulation: None,
            model_exchange: false,
            default_experiment: None,
            variables: Vec::new(),
        };
        let mut saw_variables = false;
        for child in root.children() {
            match child.name() {
                "CoSimulation" => md.co_simulation = Some(co_simulation(child)?),
                "ModelExchange" => md.model_exchange = true,
                "DefaultExperiment" => md.default_experiment = Some(default_experiment(child)?),
                "ModelVariables" => {
                    saw_variables = true;
                    for v in child.children() {
                        md.variables.push(variable(v, fmi_version)?);
                    }
                }
                _ => {}
            }
        }
        if !saw_variables {
            return Err(err(root.pos(), "no <ModelVariables> element"));
        }
        let mut seen = std::collections::HashSet::new();
        for v in &md.variables {
            if !seen.insert(v.name.as_str()) {
                return Err(ModelError {
                    line: v.line,
                    col: 1,
                    message: format!("variable '{}' is declared twice", v.name),
                });
            }
        }
        Ok(md)
    }

    /// The variable named `name`.
    pub fn variable(&self, name: &str) -> Option<&Variable> {
        self.variables.iter().find(|v| v.name == name)
    }
}

fn required<'a>(e: RawElement<'a>, attr: &str) -> Result<&'a str, ModelError> {
    e.attr(attr).ok_or_else(|| err(e.pos(), format!("<{}> has no {attr} attribute", e.name())))
}

fn flag(e: RawElement<'_>, attr: &str) -> Result<bool, ModelError> {
    match e.attr(attr) {
        None | Some("false") => Ok(false),
        Some("true") => Ok(true),
        Some(other) => Err(err(e.pos(), format!("<{}> {attr}=\"{other}\": expected true or false", e.name()))),
    }
}

fn number(e: RawElement<'_>, attr: &str) -> Result<Option<f64>, ModelError> {
    e.attr(attr)
        .map(|t| match t.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(_) => Err(err(e.pos(), format!("<{}> {attr}=\"{t}\" is not a finite number", e.name()))),
            Err(_) => Err(err(e.pos(), format!("<{}> {attr}=\"{t}\" is not a number", e.name()))),
        })
        .transpose()
}

/// The `modelIdentifier` of `e`, which must be a C identifier (ASCII letters, digits and
/// `_`, not starting with a digit): it prefixes the FMU's functions and names its library,
/// `binaries/PLATFORM/ID.so`, so a `/`, a `..` or a NUL would make it a path.
fn model_identifier(e: RawElement<'_>) -> Result<String, ModelError> {
    let id = required(e, "modelIdentifier")?;
    let ok = id.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_')
        && id.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    if !ok {
        return Err(err(
            e.pos(),
            format!(
                "<{}> modelIdentifier=\"{}\" is not a C identifier (ASCII letters, digits and _, not starting with a \
                 digit): it names the FMU's library file, so it may not be a path",
                e.name(),
                id.escape_debug()
            ),
        ));
    }
    Ok(id.to_string())
}

/// Checks a variable's start value against its type: every element (an FMI 3.0 array's
/// start holds several, space-separated) a finite number of a float type, a whole number in
/// the range of an integer type, `true`, `false`, `1` or `0` for a boolean. Strings,
/// binaries and clocks are not checked.
fn check_start(e: RawElement<'_>, name: &str, ty: VarType, version: FmiVersion, text: &str) -> Result<(), ModelError> {
    let type_name = ty.fmi_name(version);
    let what = match ty {
        VarType::Float32 | VarType::Float64 => format!("a finite {type_name} number"),
        VarType::Boolean => "true, false, 1 or 0".to_string(),
        VarType::String | VarType::Binary | VarType::Clock => return Ok(()),
        _ => format!("a whole number in the range of {type_name}"),
    };
    let fits = |t: &str| match ty {
        VarType::Float32 => t.parse::<f32>().is_ok_and(f32::is_finite),
        VarType::Float64 => t.parse::<f64>().is_ok_and(f64::is_finite),
        VarType::Boolean => matches!(t, "true" | "false" | "1" | "0"),
        // An enumeration's start is an Integer (FMI 2.0) or an Int64 (FMI 3.0).
        _ => match ty.ddf_type(version) {
            Some(scalar) => scalar.parse_value(t).is_some(),
            None => true,
        },
    };
    let mut tokens = text.split_ascii_whitespace().peekable();
    if tokens.peek().is_none() {
        return Err(err(e.pos(), format!("variable '{name}': start=\"\" is empty, not {what}")));
    }
    match tokens.find(|t| !fits(t)) {
        None => Ok(()),
        Some(bad) => {
            let value = if bad == text.trim() { String::new() } else { format!(" (its value \"{bad}\")") };
            Err(err(e.pos(), format!("variable '{name}': start=\"{}\"{value} is not {what}", text.escape_debug())))
        }
    }
}

fn co_simulation(e: RawElement<'_>) -> Result<CoSimulation, ModelError> {
    Ok(CoSimulation {
        model_identifier: model_identifier(e)?,
        can_handle_variable_communication_step_size: flag(e, "canHandleVariableCommunicationStepSize")?,
        // FMI 2.0 spells them `FMUstate`, FMI 3.0 `FMUState`; either is taken.
        can_get_and_set_fmu_state: flag(e, "canGetAndSetFMUstate")? || flag(e, "canGetAndSetFMUState")?,
        can_serialize_fmu_state: flag(e, "canSerializeFMUstate")? || flag(e, "canSerializeFMUState")?,
        needs_execution_tool: flag(e, "needsExecutionTool")?,
        can_be_instantiated_only_once_per_process: flag(e, "canBeInstantiatedOnlyOncePerProcess")?,
        attributes: e
            .attrs()
            .iter()
            .filter(|a| a.name != "modelIdentifier")
            .map(|a| (a.name.to_string(), a.value.to_string()))
            .collect(),
    })
}

fn default_experiment(e: RawElement<'_>) -> Result<DefaultExperiment, ModelError> {
    Ok(DefaultExperiment {
        start_time: number(e, "startTime")?,
        stop_time: number(e, "stopTime")?,
        tolerance: number(e, "tolerance")?,
        step_size: number(e, "stepSize")?,
    })
}

fn variable(e: RawElement<'_>, version: FmiVersion) -> Result<Variable, ModelError> {
    // FMI 2.0: <ScalarVariable ...><Real start=".."/></ScalarVariable>; FMI 3.0: <Float64 ...>.
    let (ty, typed): (VarType, RawElement<'_>) = match version {
        FmiVersion::Fmi2 => {
            if e.name() != "ScalarVariable" {
                return Err(err(e.pos(), format!("<{}> in <ModelVariables>: expected <ScalarVariable>", e.name())));
            }
            let name = e.attr("name").unwrap_or("?");
            let t = e
                .children()
                .find_map(|c| VarType::parse(c.name(), version).map(|ty| (ty, c)))
                .ok_or_else(|| err(e.pos(), format!("variable '{name}' has no type element (Real, Integer, ...)")))?;
            (t.0, t.1)
        }
        FmiVersion::Fmi3 => {
            let ty = VarType::parse(e.name(), version).ok_or_else(|| {
                err(e.pos(), format!("<{}> in <ModelVariables> is not an FMI 3.0 variable type", e.name()))
            })?;
            (ty, e)
        }
    };
    let name = required(e, "name")?.to_string();
    let vr_text = required(e, "valueReference")?;
    let value_reference = vr_text.trim().parse::<u32>().map_err(|_| {
        err(e.pos(), format!("variable '{name}': valueReference=\"{vr_text}\" is not an unsigned 32-bit number"))
    })?;
    let causality = match e.attr("causality") {
        None => Causality::Local,
        Some(c) => {
            Causality::parse(c).ok_or_else(|| err(e.pos(), format!("variable '{name}': unknown causality \"{c}\"")))?
        }
    };
    let default_variability = match ty {
        VarType::Float32 | VarType::Float64 => "continuous",
        _ => "discrete",
    };
    let variability = e.attr("variability").unwrap_or(default_variability).to_string();
    if !["constant", "fixed", "tunable", "discrete", "continuous"].contains(&variability.as_str()) {
        return Err(err(e.pos(), format!("variable '{name}': unknown variability \"{variability}\"")));
    }
    let start = typed.attr("start");
    if let Some(text) = start {
        check_start(typed, &name, ty, version, text)?;
    }
    Ok(Variable {
        name,
        value_reference,
        causality,
        variability,
        ty,
        start: start.map(str::to_string),
        unit: typed.attr("unit").map(str::to_string),
        description: e.attr("description").map(str::to_string),
        is_array: version == FmiVersion::Fmi3 && e.children().any(|c| c.name() == "Dimension"),
        line: e.pos().line,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const FMI2: &str = r#"<?xml version="1.0"?>
<fmiModelDescription fmiVersion="2.0" modelName="M" guid="{1}">
  <CoSimulation modelIdentifier="m" canHandleVariableCommunicationStepSize="true"/>
  <DefaultExperiment startTime="0" stopTime="2" stepSize="0.01"/>
  <ModelVariables>
    <ScalarVariable name="u" valueReference="0" causality="input"><Real start="1" unit="m"/></ScalarVariable>
    <ScalarVariable name="n" valueReference="1" causality="output"><Integer/></ScalarVariable>
  </ModelVariables>
</fmiModelDescription>"#;

    #[test]
    fn an_fmi2_description_reads_with_types_units_and_defaults() {
        let md = ModelDescription::parse(FMI2).unwrap();
        assert_eq!(md.fmi_version, FmiVersion::Fmi2);
        assert_eq!(md.co_simulation.as_ref().unwrap().model_identifier, "m");
        assert_eq!(md.default_experiment.as_ref().unwrap().step_size, Some(0.01));
        let u = md.variable("u").unwrap();
        assert_eq!(
            (u.ty, u.causality, u.unit.as_deref(), u.start.as_deref()),
            (VarType::Float64, Causality::Input, Some("m"), Some("1"))
        );
        assert_eq!(u.variability, "continuous");
        let n = md.variable("n").unwrap();
        assert_eq!((n.ty, n.variability.as_str()), (VarType::Int32, "discrete"));
    }

    #[test]
    fn an_fmi3_description_reads_its_typed_variables() {
        let md = ModelDescription::parse(
            r#"<fmiModelDescription fmiVersion="3.0" modelName="M" instantiationToken="t">
                <CoSimulation modelIdentifier="m"/><ModelVariables>
                <Float64 name="time" valueReference="0" causality="independent"/>
                <UInt16 name="k" valueReference="1" causality="output"/>
                <Float32 name="a" valueReference="2" causality="input" start="1 2"><Dimension start="2"/></Float32>
                </ModelVariables></fmiModelDescription>"#,
        )
        .unwrap();
        assert_eq!(md.fmi_version, FmiVersion::Fmi3);
        assert_eq!(md.variable("k").unwrap().ty.ddf_type(md.fmi_version), Some(ScalarType::UInt16));
        assert!(md.variable("a").unwrap().is_array);
    }

    #[test]
    fn the_state_capabilities_read_in_either_spelling_and_name_what_is_missing() {
        let cs = |attrs: &str, version: &str| {
            let token = if version == "2.0" { "guid" } else { "instantiationToken" };
            let md = ModelDescription::parse(&format!(
                r#"<fmiModelDescription fmiVersion="{version}" modelName="M" {token}="t">
                <CoSimulation modelIdentifier="m" {attrs}/><ModelVariables/></fmiModelDescription>"#
            ))
            .unwrap();
            md.co_simulation.unwrap()
        };
        let both = cs(r#"canGetAndSetFMUstate="true" canSerializeFMUstate="true""#, "2.0");
        assert!(both.can_get_and_set_fmu_state && both.can_serialize_fmu_state);
        assert!(both.missing_state_capabilities(FmiVersion::Fmi2).is_empty());
        let fmi3 = cs(r#"canGetAndSetFMUState="true" canSerializeFMUState="true""#, "3.0");
        assert!(fmi3.missing_state_capabilities(FmiVersion::Fmi3).is_empty());
        let get_set_only = cs(r#"canGetAndSetFMUState="true""#, "3.0");
        assert_eq!(get_set_only.missing_state_capabilities(FmiVersion::Fmi3), ["canSerializeFMUState"]);
        let none = cs("", "2.0");
        assert_eq!(none.missing_state_capabilities(FmiVersion::Fmi2), ["canGetAndSetFMUstate", "canSerializeFMUstate"]);
        let e = ModelDescription::parse(
            &FMI2.replace("modelIdentifier=\"m\"", "modelIdentifier=\"m\" canSerializeFMUstate=\"yes\""),
        )
        .unwrap_err();
        assert!(e.message.contains("canSerializeFMUstate=\"yes\": expected true or false"), "{e}");
    }

    #[test]
    fn broken_descriptions_are_errors_with_a_line() {
        let e = ModelDescription::parse("<fmiModelDescription fmiVersion=\"2.0\"><oops></fmiModelDescription>")
            .unwrap_err();
        assert!(e.message.contains("malformed"), "{e}");
        let e = ModelDescription::parse(&FMI2.replace("valueReference=\"1\"", "valueReference=\"x\"")).unwrap_err();
        assert_eq!(e.line, 7, "{e}");
        let e = ModelDescription::parse(&FMI2.replace("fmiVersion=\"2.0\"", "fmiVersion=\"1.0\"")).unwrap_err();
        assert!(e.message.contains("only FMI 2.0 and 3.0"), "{e}");
    }

    #[test]
    fn a_model_identifier_that_is_a_path_is_refused_at_its_line() {
        for bad in ["../../evil", "a/b", "..", "", "9lives", "a b", "lib.so", "a\\b"] {
            let text = FMI2.replace("modelIdentifier=\"m\"", &format!("modelIdentifier=\"{bad}\""));
            let e = ModelDescription::parse(&text).unwrap_err();
            assert_eq!(e.line, 3, "{bad}: {e}");
            assert!(e.message.contains("modelIdentifier") && e.message.contains("not a C identifier"), "{bad}: {e}");
        }
        for good in ["m", "_m", "Lag2", "Bouncing_Ball"] {
            let text = FMI2.replace("modelIdentifier=\"m\"", &format!("modelIdentifier=\"{good}\""));
            assert!(ModelDescription::parse(&text).is_ok(), "{good}");
        }
    }

    #[test]
    fn start_values_must_be_finite_values_of_their_type() {
        let fmi3 = |ty: &str, start: &str| {
            format!(
                r#"<fmiModelDescription fmiVersion="3.0" modelName="M" instantiationToken="t">
                <CoSimulation modelIdentifier="m"/><ModelVariables>
                <{ty} name="v" valueReference="1" causality="input" start="{start}"/>
                </ModelVariables></fmiModelDescription>"#
            )
        };
        for (ty, bad) in [
            ("Float64", "NaN"),
            ("Float64", "1e999"),
            ("Float64", "-inf"),
            ("Float64", "x"),
            ("Float32", "1e39"),
            ("Float32", "1 NaN"),
            ("Int8", "128"),
            ("UInt16", "-1"),
            ("Int32", "1.5"),
            ("Boolean", "yes"),
            ("Enumeration", "1e3"),
            ("Float64", " "),
        ] {
            let e = ModelDescription::parse(&fmi3(ty, bad)).unwrap_err();
            assert_eq!(e.line, 3, "{ty} {bad}: {e}");
            assert!(e.message.contains("variable 'v'") && e.message.contains("start="), "{ty} {bad}: {e}");
        }
        for (ty, good) in [
            ("Float64", "-1.5e300"),
            ("Float32", "1 2"),
            ("Int8", "-128"),
            ("UInt64", "18446744073709551615"),
            ("Boolean", "false"),
            ("String", "NaN"),
        ] {
            assert!(ModelDescription::parse(&fmi3(ty, good)).is_ok(), "{ty} {good}");
        }
        // FMI 2.0: the start is on the type element, the message names the variable.
        let e = ModelDescription::parse(&FMI2.replace("start=\"1\"", "start=\"NaN\"")).unwrap_err();
        assert!(e.message.contains("variable 'u': start=\"NaN\" is not a finite Real number"), "{e}");
        let e = ModelDescription::parse(&FMI2.replace("stepSize=\"0.01\"", "stepSize=\"1e999\"")).unwrap_err();
        assert!(e.message.contains("stepSize=\"1e999\" is not a finite number"), "{e}");
    }
}
