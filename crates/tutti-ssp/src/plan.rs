//! The system against its FMUs, and what a run of it is: the DDF (a domain per component,
//! made by `tutti_fmu::ddf` as `tutti fmu ddf` makes one), the framework connections
//! (`tutti_host::connect`), the start values and the launch file (`tutti_launch`'s keys).
//! docs/ssp.md has the mapping.

use std::path::{Path, PathBuf};
use std::time::Duration;

use tutti_fmu::ddf::{domain_name, generate_domain, item_names, DdfOptions};
use tutti_fmu::{Causality as FmiCausality, ModelDescription, VarType};
use tutti_host::connect::{ConnectionSpec, Connections, ItemRef, Source, StepOrder};
use tutti_launch::{ComponentKeys, FrameworkKeys, LaunchKeys};

use crate::model::{At, Causality, Component, System, Type};
use crate::{Archive, SspError};

/// How the run steps.
#[derive(Debug, Clone)]
pub struct PlanOptions {
    /// The communication step (the framework's step).
    pub step: Duration,
    /// How many steps (default: the DefaultExperiment's stopTime over the step, if it has one).
    pub steps: Option<u64>,
    /// Recordings of every step (`framework.record`), as written into the launch file.
    pub record: Vec<PathBuf>,
    /// The framework's wait for a step's answers and for the seeds.
    pub timeout: Duration,
    /// How the connections are applied within a step (`framework.ordering`).
    pub ordering: StepOrder,
}

impl Default for PlanOptions {
    fn default() -> Self {
        PlanOptions {
            step: Duration::from_millis(10),
            steps: None,
            record: Vec::new(),
            timeout: tutti_core::defaults::SSP_STEP_TIMEOUT,
            ordering: StepOrder::Delayed,
        }
    }
}

/// One component as it runs.
#[derive(Debug, Clone)]
pub struct Member {
    pub component: String,
    /// Its domain (and its name in the launch file).
    pub domain: String,
    /// The FMU, relative to the output directory.
    pub fmu: String,
    /// `--param NAME=VALUE`: component-level values, then system-level ones (which win).
    pub params: Vec<String>,
}

/// A system made into a run.
#[derive(Debug, Clone)]
pub struct Plan {
    pub system: System,
    pub members: Vec<Member>,
    pub connections: Vec<ConnectionSpec>,
    /// `framework.set`: the start values of inputs no connection feeds.
    pub sets: Vec<String>,
    pub steps: Option<u64>,
    pub ddf: String,
    pub launch: String,
    /// The file names of both, in the output directory.
    pub ddf_file: String,
    pub launch_file: String,
}

/// An SSP archive made ready to run: its launch file, and the temporary directory that
/// holds it (removed when this is dropped) when no directory was given.
#[derive(Debug)]
pub struct Prepared {
    /// The launch file written, and what `tutti_launch` makes of it.
    pub launch_file: PathBuf,
    pub launch: tutti_launch::Launch,
    pub plan: Plan,
    pub temp: Option<tempfile::TempDir>,
}

/// Extracts `ssp` into `out` (a new temporary directory when None), checks it, and writes
/// the DDF and the launch file there.
pub fn prepare(ssp: &Path, out: Option<&Path>, opts: &PlanOptions) -> Result<Prepared, SspError> {
    let mut archive = Archive::open(ssp)?;
    let system = System::load(&mut archive)?;
    let (dir, temp) = match out {
        Some(d) => {
            std::fs::create_dir_all(d).map_err(|e| SspError::io(d, e))?;
            (d.to_path_buf(), None)
        }
        None => {
            let t = tempfile::Builder::new()
                .prefix("tutti-ssp-")
                .tempdir()
                .map_err(|e| SspError::io(Path::new("TMPDIR"), e))?;
            (t.path().to_path_buf(), Some(t))
        }
    };
    archive.extract(&dir)?;
    let plan = Plan::build(system, &dir, opts)?;
    let ddf = dir.join(&plan.ddf_file);
    std::fs::write(&ddf, &plan.ddf).map_err(|e| SspError::io(&ddf, e))?;
    let launch_file = dir.join(&plan.launch_file);
    std::fs::write(&launch_file, &plan.launch).map_err(|e| SspError::io(&launch_file, e))?;
    // Read back as `tutti run` reads it: what is written is a launch file it accepts.
    let launch = tutti_launch::load(&launch_file).map_err(|e| SspError::Archive {
        file: ssp.display().to_string(),
        reason: format!("the generated launch file is refused: {e}"),
    })?;
    Ok(Prepared { launch_file, launch, plan, temp })
}

/// The DDF type a connector's SSP type goes with, for the check against the FMU.
fn fits(ty: Type, v: VarType) -> bool {
    match ty {
        Type::Real => matches!(v, VarType::Float64 | VarType::Float32),
        Type::Integer => {
            matches!(v, VarType::Int32 | VarType::Int64 | VarType::Int16 | VarType::Int8 | VarType::Enumeration)
        }
        Type::Boolean => v == VarType::Boolean,
    }
}

struct Fmu {
    md: ModelDescription,
    names: std::collections::BTreeMap<String, String>,
}

fn file_stem(name: &str) -> String {
    let s = domain_name(name);
    if s.is_empty() {
        "system".into()
    } else {
        s
    }
}

impl Plan {
    /// Checks `system` against its FMUs, extracted into `dir`, and makes the run.
    pub fn build(system: System, dir: &Path, opts: &PlanOptions) -> Result<Plan, SspError> {
        let (fmus, mut members, ddf) = domains(&system, dir)?;
        let model = tutti_core::ddf::parse_str(&ddf, "generated DDF").map_err(|e| SspError::Archive {
            file: system.file.clone(),
            reason: format!("the generated DDF is not valid: {e}"),
        })?;
        let connections = connections(&system, &members, &fmus, &model)?;
        let sets = start_values(&system, &mut members, &fmus, &connections)?;
        tutti_host::Host::check_sets(&model, &sets).map_err(|e| SspError::Archive {
            file: system.file.clone(),
            reason: format!("a start value does not fit: {e}"),
        })?;
        let steps = opts.steps.or_else(|| {
            let stop = system.stop_time?;
            let h = opts.step.as_secs_f64();
            (stop > 0.0 && h > 0.0).then(|| (stop / h).round() as u64)
        });
        let stem = file_stem(&system.name);
        let ddf_file = format!("{stem}.ddf");
        let launch_file = format!("{stem}.json5");
        let mut plan =
            Plan { system, members, connections, sets, steps, ddf, launch: String::new(), ddf_file, launch_file };
        plan.launch = plan.launch_text(opts)?;
        Ok(plan)
    }

    /// The launch file: the framework as `opts` and the system say, a component per member,
    /// the connections.
    fn launch_text(&self, opts: &PlanOptions) -> Result<String, SspError> {
        let framework = FrameworkKeys {
            step: Some(opts.step),
            timeout: Some(opts.timeout),
            hold: Some(true),
            catch_up: Some(true),
            steps: self.steps,
            ordering: (opts.ordering != StepOrder::Delayed).then_some(opts.ordering),
            record: opts.record.clone(),
            set: self.sets.clone(),
            ..Default::default()
        };
        let components = self
            .members
            .iter()
            .map(|m| ComponentKeys {
                name: m.domain.clone(),
                fmu: Some(m.fmu.clone().into()),
                domain: Some(m.domain.clone()),
                params: (!m.params.is_empty()).then(|| m.params.clone()),
                ..Default::default()
            })
            .collect();
        let keys = LaunchKeys {
            ddf: self.ddf_file.clone().into(),
            framework: Some(framework),
            components,
            gateway: None,
            connections: self.connections.clone(),
        };
        let json = serde_json::to_string_pretty(&keys).map_err(|e| SspError::Archive {
            file: self.system.file.clone(),
            reason: format!("the launch file cannot be written: {e}"),
        })?;
        Ok(format!(
            "// Generated by `tutti ssp ddf` from {} (docs/ssp.md): run it with `tutti run`.\n{json}\n",
            self.system.file
        ))
    }
}

/// A domain per component, each made by `tutti_fmu::ddf` from its FMU (opened, its
/// connectors checked): the FMUs, the members and the DDF's text.
fn domains(system: &System, dir: &Path) -> Result<(Vec<Fmu>, Vec<Member>, String), SspError> {
    let mut fmus = Vec::new();
    let mut members: Vec<Member> = Vec::new();
    let mut ddf = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    ddf.push_str(&format!(
        "<!-- Generated by `tutti ssp ddf` from {}: a domain per component, made as `tutti fmu ddf` makes one. -->\n<orchestra>\n",
        system.file.replace("--", "- -")
    ));
    for comp in &system.components {
        let fmu = open_fmu(comp, dir)?;
        check_connectors(comp, &fmu)?;
        let mut domain = domain_name(&comp.name);
        let mut n = 2;
        while members.iter().any(|m| m.domain == domain) {
            domain = format!("{}_{n}", domain_name(&comp.name));
            n += 1;
        }
        let outputs =
            fmu.md.variables.iter().any(|v| {
                v.causality == FmiCausality::Output && tutti_fmu::ddf::unsupported_reason(&fmu.md, v).is_none()
            });
        // A domain with outputs waits for the FMU's initial outputs before its first step.
        let opts = DdfOptions { domain: domain.clone(), synchronous: true, states: outputs };
        ddf.push_str(&format!("  <!-- component '{}': {} -->\n", comp.name.replace("--", "- -"), comp.source));
        ddf.push_str(&generate_domain(&fmu.md, &opts));
        members.push(Member { component: comp.name.clone(), domain, fmu: comp.source.clone(), params: Vec::new() });
        fmus.push(fmu);
    }
    ddf.push_str("</orchestra>\n");
    Ok((fmus, members, ddf))
}

/// The system's connections as framework connections, each checked against `model` as it
/// is added, so that a refusal points at its own.
fn connections(
    system: &System,
    members: &[Member],
    fmus: &[Fmu],
    model: &tutti_core::ddf::Model,
) -> Result<Vec<ConnectionSpec>, SspError> {
    let index = |name: &str| system.components.iter().position(|c| c.name == name);
    let mut connections: Vec<ConnectionSpec> = Vec::new();
    for c in &system.connections {
        let (Some(a), Some(b)) = (index(&c.from.0), index(&c.to.0)) else { continue };
        let unit = |comp: usize, conn: &str| system.components[comp].connector(conn).and_then(|k| k.unit.clone());
        let units = match (unit(a, &c.from.1), unit(b, &c.to.1)) {
            (Some(ua), Some(ub)) if ua != ub && !c.suppress_unit_conversion => {
                match (system.unit(&ua), system.unit(&ub)) {
                    (Some(x), Some(y)) => Some((x, y)),
                    _ => None,
                }
            }
            _ => None,
        };
        let spec = ConnectionSpec {
            from: Source::Item(ItemRef {
                domain: members[a].domain.clone(),
                role: tutti_core::ddf::Role::Subscribe,
                item: fmus[a].names.get(&c.from.1).cloned().unwrap_or_default(),
            }),
            to: ItemRef {
                domain: members[b].domain.clone(),
                role: tutti_core::ddf::Role::Publish,
                item: fmus[b].names.get(&c.to.1).cloned().unwrap_or_default(),
            },
            gain: c.factor,
            offset: c.offset,
            units,
        };
        connections.push(spec);
        Connections::resolve(model, &connections, &[]).map_err(|e| c.at.error(format!("{e}")))?;
    }
    Ok(connections)
}

/// The start values: each member's `params`, the component's own values, then the
/// system's (which win); and, for an input no connection feeds, its framework `set` (the
/// framework's sets, returned).
fn start_values(
    system: &System,
    members: &mut [Member],
    fmus: &[Fmu],
    connections: &[ConnectionSpec],
) -> Result<Vec<String>, SspError> {
    let mut sets = Vec::new();
    for (i, comp) in system.components.iter().enumerate() {
        let prefix = format!("{}.", comp.name);
        let system_level =
            system.system_params.iter().filter_map(|p| p.name.strip_prefix(&prefix).map(|n| (n.to_string(), p)));
        let all: Vec<(String, &crate::ParamValue)> =
            comp.params.iter().map(|p| (p.name.clone(), p)).chain(system_level).collect();
        for (name, p) in all {
            let var = check_param(comp, &fmus[i].md, &name, p.ty, &p.at)?;
            members[i].params.push(format!("{name}={}", p.value));
            if var.causality != FmiCausality::Input {
                continue;
            }
            let item = &fmus[i].names[&name];
            let fed = connections.iter().any(|c| c.to.domain == members[i].domain && &c.to.item == item);
            if !fed {
                let value = match p.value.as_str() {
                    "true" | "1" if p.ty == Type::Boolean => "yes",
                    "false" | "0" if p.ty == Type::Boolean => "no",
                    v => v,
                };
                let set = format!("{}/{item}={value}", members[i].domain);
                sets.retain(|s: &String| s.split_once('=').map(|(t, _)| t) != set.split_once('=').map(|(t, _)| t));
                sets.push(set);
            }
        }
    }
    Ok(sets)
}

fn open_fmu(comp: &Component, dir: &Path) -> Result<Fmu, SspError> {
    let path = dir.join(&comp.source);
    let fmu = tutti_fmu::Fmu::open(&path).map_err(|e| comp.at.error(format!("component '{}': {e}", comp.name)))?;
    if fmu.model.co_simulation.is_none() {
        return Err(comp.at.error(format!(
            "component '{}': {} is not a co-simulation FMU (docs/fmu.md, Limits)",
            comp.name, comp.source
        )));
    }
    let names = item_names(&fmu.model);
    Ok(Fmu { md: fmu.model, names })
}

/// Every declared connector is a variable of the FMU, of its kind and type.
fn check_connectors(comp: &Component, fmu: &Fmu) -> Result<(), SspError> {
    for k in &comp.connectors {
        let var = fmu.md.variable(&k.name).ok_or_else(|| {
            k.at.error(format!(
                "connector '{}.{}': the FMU {} has no variable '{}'",
                comp.name, k.name, comp.source, k.name
            ))
        })?;
        let want = match k.kind {
            Causality::Input => FmiCausality::Input,
            Causality::Output => FmiCausality::Output,
            Causality::Parameter => FmiCausality::Parameter,
            Causality::CalculatedParameter => FmiCausality::CalculatedParameter,
        };
        if var.causality != want {
            return Err(k.at.error(format!(
                "connector '{}.{}' is an {}, the FMU's variable is {}",
                comp.name,
                k.name,
                k.kind.as_str(),
                var.causality.as_str()
            )));
        }
        if let Some(ty) = k.ty {
            if !fits(ty, var.ty) {
                return Err(k.at.error(format!(
                    "type mismatch: connector '{}.{}' is {}, the FMU's variable is {}",
                    comp.name,
                    k.name,
                    ty.as_str(),
                    var.ty.fmi_name(fmu.md.fmi_version)
                )));
            }
        }
        if matches!(k.kind, Causality::Input | Causality::Output) {
            if let Some(why) = tutti_fmu::ddf::unsupported_reason(&fmu.md, var) {
                return Err(k.at.error(format!("connector '{}.{}': the FMU's variable is {why}", comp.name, k.name)));
            }
        }
    }
    Ok(())
}

fn check_param<'m>(
    comp: &Component,
    md: &'m ModelDescription,
    name: &str,
    ty: Type,
    at: &At,
) -> Result<&'m tutti_fmu::Variable, SspError> {
    let var = md.variable(name).ok_or_else(|| {
        at.error(format!("parameter '{name}' of component '{}': its FMU has no such variable", comp.name))
    })?;
    let settable =
        matches!(var.causality, FmiCausality::Parameter | FmiCausality::Input | FmiCausality::StructuralParameter)
            && var.variability != "constant";
    if !settable {
        return Err(at.error(format!(
            "parameter '{name}' of component '{}': the variable is {} {}, not a parameter or an input",
            comp.name,
            var.variability,
            var.causality.as_str()
        )));
    }
    if !fits(ty, var.ty) {
        return Err(at.error(format!(
            "type mismatch: parameter '{name}' of component '{}' is {}, the variable is {}",
            comp.name,
            ty.as_str(),
            var.ty.fmi_name(md.fmi_version)
        )));
    }
    Ok(var)
}
