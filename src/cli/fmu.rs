//! `tutti fmu inspect|ddf|run MODEL.fmu`: FMI 2.0 / 3.0 co-simulation FMUs as participants
//! of a domain, with no code written (the work is in the `tutti-fmu` crate; docs/fmu.md).
//!
//! Exit status: 2 for an FMU that cannot be used (not an FMU, broken model description, no
//! Linux x86_64 binary, a missing FMI function, a mapping that does not fit), 1 for a run
//! that fails (a `doStep` returning Error or Fatal, the framework gone).

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context as _;
use tutti_core::parse::parse_duration;
use tutti_core::shm::ConnectOptions;
use tutti_fmu::ddf::{domain_name, generate, item_names, unsupported_reason, DdfOptions};
use tutti_fmu::mapping::parse_spec;
use tutti_fmu::{Fmu, FmuParticipant, Mapping, RunOptions};

use super::{load_ddf, CliResult, Failure};

/// FMI 2.0 / 3.0 co-simulation FMUs: inspect them, make a DDF for them, run them as participants.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti fmu inspect Lag.fmu --json\n  tutti fmu ddf Lag.fmu --domain lag --synchronous yes --out lag.ddf\n  tutti host lag.ddf --step 10ms &\n  tutti fmu run Lag.fmu --ddf lag.ddf --domain lag --param tau=0.2\n\nMapping rules, stepping and limits: docs/fmu.md."
)]
pub struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, clap::Subcommand)]
enum Command {
    Inspect(InspectArgs),
    Ddf(DdfArgs),
    Run(RunArgs),
}

/// Show an FMU: FMI version, model, co-simulation capabilities, default experiment, variables.
#[derive(Debug, clap::Args)]
struct InspectArgs {
    #[arg(value_name = "MODEL.fmu")]
    fmu: PathBuf,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

/// Print (or write) a DDF with one domain for an FMU: outputs in SUBSCRIBE, inputs in PUBLISH.
#[derive(Debug, clap::Args)]
struct DdfArgs {
    #[arg(value_name = "MODEL.fmu")]
    fmu: PathBuf,
    /// The domain's name (default: the model name, lower case).
    #[arg(long, value_name = "NAME")]
    domain: Option<String>,
    /// Whether the domain is synchronous (lock-step).
    #[arg(long, value_name = "yes|no", default_value = "yes", value_parser = ["yes", "no"])]
    synchronous: String,
    /// Write the DDF here instead of printing it.
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
}

/// Run an FMU as an external participant of a domain hosted by a framework (tutti host).
#[derive(Debug, clap::Args)]
#[command(
    after_help = "A synchronous domain: one doStep per framework step, with its time and period. An asynchronous one: \
                  steps every --step on the FMU's own clock with the latest inputs.\n\nExamples:\n  tutti fmu run Lag.fmu --ddf lag.ddf --domain lag\n  tutti fmu run Lag.fmu --ddf uav.ddf --domain wind --map y=gust_mps --param gain=3\n\nEnvironment: TUTTI_FMU_LOG=1 prints the FMU's log as it comes."
)]
struct RunArgs {
    #[arg(value_name = "MODEL.fmu")]
    fmu: PathBuf,
    /// The DDF of the domain.
    #[arg(long, value_name = "DDF")]
    ddf: PathBuf,
    /// The domain to join.
    #[arg(long, value_name = "NAME")]
    domain: String,
    /// Pair an FMU variable with an item (repeatable; default: identical or `tutti fmu ddf` names).
    #[arg(long = "map", value_name = "FMU_VAR=ITEM_PATH")]
    maps: Vec<String>,
    /// A file of FMU_VAR=ITEM_PATH lines (blank lines and # comments ignored).
    #[arg(long, value_name = "FILE")]
    map_file: Option<PathBuf>,
    /// Set a parameter before initialisation (repeatable).
    #[arg(long = "param", value_name = "NAME=VALUE")]
    params: Vec<String>,
    /// Step of an asynchronous domain (default: the FMU's default experiment step, else 10ms).
    #[arg(long, value_parser = parse_duration)]
    step: Option<Duration>,
    /// Stop after this many steps (default: until Ctrl-C or the framework stops).
    #[arg(long, value_name = "N")]
    steps: Option<u64>,
    /// How long to wait for the domain to appear.
    #[arg(long, value_parser = parse_duration, default_value = "10s")]
    connect_timeout: Duration,
    /// Load this shared library (globally) before the FMU: e.g. libpython for a PythonFMU model (repeatable).
    #[arg(long, value_name = "LIB", env = "TUTTI_FMU_PRELOAD", value_delimiter = ':')]
    preload: Vec<PathBuf>,
    /// The connection's name in `tutti status` (default: fmu:MODEL).
    #[arg(long)]
    name: Option<String>,
    /// Print no progress lines.
    #[arg(short, long)]
    quiet: bool,
}

pub fn run(args: Args) -> CliResult {
    match args.command {
        Command::Inspect(a) => inspect(a),
        Command::Ddf(a) => ddf(a),
        Command::Run(a) => run_fmu(a),
    }
}

fn open(path: &std::path::Path) -> Result<Fmu, Failure> {
    Fmu::open(path).map_err(Failure::invalid)
}

fn fmt_opt(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| v.to_string())
}

fn inspect(a: InspectArgs) -> CliResult {
    let fmu = open(&a.fmu)?;
    let md = &fmu.model;
    if a.json {
        let json = serde_json::json!({
            "file": a.fmu.display().to_string(),
            "fmi_version": md.fmi_version_text,
            "model_name": md.model_name,
            "token": md.token,
            "description": md.description,
            "generation_tool": md.generation_tool,
            "model_exchange": md.model_exchange,
            "co_simulation": md.co_simulation,
            "default_experiment": md.default_experiment,
            "binaries": fmu.binaries,
            "variables": md.variables,
        });
        println!("{}", serde_json::to_string_pretty(&json).context("serialising")?);
        return Ok(());
    }
    print_summary(&a.fmu, &fmu);
    println!();
    print_variables(md);
    Ok(())
}

/// The FMU's identity, kinds, default experiment and binaries, one line each.
fn print_summary(path: &std::path::Path, fmu: &Fmu) {
    let md = &fmu.model;
    println!("FMU:            {}", path.display());
    println!("FMI version:    {}", md.fmi_version_text);
    println!("model:          {}", md.model_name);
    if let Some(d) = &md.description {
        println!("description:    {d}");
    }
    if let Some(t) = &md.generation_tool {
        println!("generated by:   {t}");
    }
    match &md.co_simulation {
        Some(cs) => {
            println!("co-simulation:  yes (model identifier '{}')", cs.model_identifier);
            for (k, v) in &cs.attributes {
                println!("  {k} = {v}");
            }
            let missing = cs.missing_state_capabilities(md.fmi_version);
            if missing.is_empty() {
                println!("checkpoints:    yes (it saves and restores its state)");
            } else {
                println!(
                    "checkpoints:    no (it does not declare {}: a component that keeps no state)",
                    missing.join(", ")
                );
            }
        }
        None => println!("co-simulation:  no (tutti cannot run this FMU)"),
    }
    println!("model exchange: {}", if md.model_exchange { "yes (not used by tutti)" } else { "no" });
    match &md.default_experiment {
        Some(e) => println!(
            "default experiment: start {}, stop {}, step {}, tolerance {}",
            fmt_opt(e.start_time),
            fmt_opt(e.stop_time),
            fmt_opt(e.step_size),
            fmt_opt(e.tolerance)
        ),
        None => println!("default experiment: none"),
    }
    println!("binaries:       {}", if fmu.binaries.is_empty() { "none".to_string() } else { fmu.binaries.join(", ") });
}

/// The variables as a table: name, causality, variability, type, start, unit.
fn print_variables(md: &tutti_fmu::ModelDescription) {
    let rows: Vec<[String; 6]> = md
        .variables
        .iter()
        .map(|v| {
            [
                v.name.clone(),
                v.causality.as_str().to_string(),
                v.variability.clone(),
                format!("{}{}", v.ty.fmi_name(md.fmi_version), if v.is_array { "[]" } else { "" }),
                v.start.clone().unwrap_or_else(|| "-".into()),
                v.unit.clone().unwrap_or_else(|| "-".into()),
            ]
        })
        .collect();
    let head = ["NAME", "CAUSALITY", "VARIABILITY", "TYPE", "START", "UNIT"];
    let mut widths = head.map(str::len);
    for r in &rows {
        for (w, c) in widths.iter_mut().zip(r) {
            *w = (*w).max(c.chars().count());
        }
    }
    let line = |cells: &[String]| {
        let s: Vec<String> = cells.iter().zip(widths).map(|(c, w)| format!("{c:<w$}")).collect();
        println!("{}", s.join("  ").trim_end());
    };
    line(&head.map(String::from));
    for r in &rows {
        line(r);
    }
}

fn ddf(a: DdfArgs) -> CliResult {
    let fmu = open(&a.fmu)?;
    let domain = a.domain.unwrap_or_else(|| domain_name(&fmu.model.model_name));
    let opts = DdfOptions { domain, synchronous: a.synchronous == "yes", states: false };
    let source = a.fmu.file_name().map_or_else(|| a.fmu.display().to_string(), |n| n.to_string_lossy().into_owned());
    let text = generate(&fmu.model, &source, &opts);
    // What is written must be a valid DDF: check it with the same parser as everything else.
    tutti_core::ddf::parse_str(&text, "generated DDF")
        .map_err(|e| Failure::invalid(anyhow::anyhow!("{}: the generated DDF is not valid: {e}", a.fmu.display())))?;
    match a.out {
        Some(out) => std::fs::write(&out, text).with_context(|| format!("writing {}", out.display()))?,
        None => print!("{text}"),
    }
    Ok(())
}

/// The mapping of `--map`, `--map-file` and the names the FMU and the domain share.
fn mapping_of(a: &RunArgs, fmu: &Fmu, domain: &tutti_core::ddf::Domain) -> Result<Mapping, Failure> {
    let mut specs = a.maps.clone();
    if let Some(f) = &a.map_file {
        let text =
            std::fs::read_to_string(f).with_context(|| format!("reading {}", f.display())).map_err(Failure::invalid)?;
        specs.extend(text.lines().map(str::trim).filter(|l| !l.is_empty() && !l.starts_with('#')).map(String::from));
    }
    let explicit = specs.iter().map(|s| parse_spec(s)).collect::<Result<Vec<_>, _>>().map_err(Failure::invalid)?;
    Mapping::build(&fmu.model, domain, &explicit).map_err(|e| {
        Failure::invalid(anyhow::anyhow!("{} with {} domain '{}': {e}", a.fmu.display(), a.ddf.display(), a.domain))
    })
}

/// Which variable goes to or comes from which item, and why a variable is left out.
fn print_mapping(domain: &str, fmu: &Fmu, mapping: &Mapping) {
    let names = item_names(&fmu.model);
    for p in mapping.inputs.iter().chain(&mapping.outputs) {
        let arrow = if p.var.causality == tutti_fmu::Causality::Input { "<-" } else { "->" };
        eprintln!("fmu: {} {arrow} {domain}/{}", p.var.name, p.leaf.path);
    }
    for v in &mapping.unmapped {
        let why = fmu.model.variable(v).and_then(|var| unsupported_reason(&fmu.model, var));
        let why = why.unwrap_or_else(|| format!("no item '{}' or '{}'", v, names.get(v).map_or("", |s| s)));
        eprintln!("fmu: warning: {v} is not mapped ({why})");
    }
}

fn run_fmu(a: RunArgs) -> CliResult {
    let fmu = open(&a.fmu)?;
    let model = load_ddf(&a.ddf)?;
    let domain = model
        .domain(&a.domain)
        .ok_or_else(|| Failure::invalid(anyhow::anyhow!("{}: no domain '{}'", a.ddf.display(), a.domain)))?;
    let mapping = mapping_of(&a, &fmu, domain)?;
    let params = a
        .params
        .iter()
        .map(|p| match p.split_once('=') {
            Some((n, v)) if !n.trim().is_empty() => Ok((n.trim().to_string(), v.trim().to_string())),
            _ => Err(Failure::invalid(anyhow::anyhow!("--param {p}: expected NAME=VALUE"))),
        })
        .collect::<Result<Vec<_>, _>>()?;
    if !a.quiet {
        print_mapping(&a.domain, &fmu, &mapping);
    }
    let step = a
        .step
        .or_else(|| {
            let s = fmu.model.default_experiment.as_ref()?.step_size?;
            (s > 0.0 && s.is_finite()).then(|| Duration::from_secs_f64(s))
        })
        .unwrap_or(Duration::from_millis(10));
    let name = a.name.clone().unwrap_or_else(|| format!("fmu:{}", fmu.model.model_name));
    let instance = fmu.instantiate(&name, &a.preload).map_err(Failure::invalid)?;
    let stop = super::stop_flag()?;
    let opts = RunOptions {
        connect: ConnectOptions { name, connect_timeout: a.connect_timeout, ..Default::default() },
        step,
        params,
        max_steps: a.steps,
    };
    let participant = FmuParticipant::connect(&fmu.model, instance, domain, mapping, opts).map_err(|e| {
        if e.is_invalid_input() {
            Failure::invalid(e)
        } else {
            Failure::from(anyhow::Error::from(e))
        }
    })?;
    if !a.quiet {
        eprintln!("fmu: {} joined domain '{}' ({:?})", fmu.model.model_name, a.domain, participant.mode());
    }
    let summary = participant.run(&stop).map_err(|e| anyhow::Error::from(e).context(a.fmu.display().to_string()))?;
    if !a.quiet {
        let why = if summary.framework_stopped { " (the framework stopped)" } else { "" };
        eprintln!("fmu: {} made {} steps, time {}{why}", fmu.model.model_name, summary.steps, summary.time);
    }
    Ok(())
}
