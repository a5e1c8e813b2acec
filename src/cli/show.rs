//! `tutti show DDF [--json]`: domains, flags, sets, items with their layout, DDS topics and
//! QoS. The JSON schema is documented in `docs/ddf.md`. With `--config FILE`: the gateway's
//! plan under that config file instead (which sets it bridges, their names, QoS and rate
//! limits, and why a set is left out; schema in `docs/gateway.md`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;
use tutti_core::ddf::{Model, Role};
use tutti_core::mapping::{self, ItemTopic, Profile, Qos};
use tutti_core::show::{show, ShowJson};
use tutti_gateway::config::{self, ConfigFile, Plan};
use tutti_gateway::{EngineKind, GatewayOptions, TypeMode};

use super::gateway::ProfileArg;
use super::{load_ddf, CliResult, Failure};

/// Show what a DDF describes: domains, flags, sets, items (paths, types, lengths, offsets,
/// defaults), DDS topics and QoS.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti show ddf/multiuav.ddf\n  tutti show ddf/product-sample.ddf --json | python3 -m json.tool\n  tutti show ddf/multiuav.ddf --config examples/gateway.json5   # the gateway's topics under a config file"
)]
pub struct Args {
    /// The DDF to show.
    #[arg(value_name = "DDF")]
    file: PathBuf,
    /// Print JSON (schema in docs/ddf.md) instead of text.
    #[arg(long)]
    json: bool,
    /// QoS profile to show (as `tutti gateway --qos-profile`; default ros2).
    #[arg(long, value_enum)]
    qos_profile: Option<ProfileArg>,
    /// Engine to show (as `tutti gateway --engine`; `--dds` is an alias; default: TUTTI_DDS,
    /// else cyclone).
    #[arg(long = "engine", visible_alias = "dds", value_name = "ENGINE")]
    engine: Option<EngineKind>,
    /// Show the gateway's topics under this config file (as `tutti gateway --config`): which
    /// sets are bridged, their DDS and ROS 2 names, QoS and rate limits, and why a set is
    /// left out.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Check and list connections in the framework (as `tutti host --connect`): both ends,
    /// their types and lengths, and when a value arrives.
    #[arg(long = "connect", value_name = "CONNECTION", value_parser = tutti_host::connect::parse_connection)]
    connections: Vec<tutti_host::connect::ConnectionSpec>,
}

pub fn run(args: Args) -> CliResult {
    let model = load_ddf(&args.file)?;
    if !args.connections.is_empty() {
        return show_connections(&args, &model);
    }
    if let Some(cfg) = &args.config {
        return show_plan(&args, model, cfg);
    }
    let profile = args.qos_profile.map_or(Profile::Ros2, Profile::from);
    let engine = match args.engine {
        Some(e) => e,
        None => config::env::engine().map_err(Failure::invalid)?,
    };
    let view = show(&model, &args.file, profile, engine.name());
    if args.json {
        println!("{}", serde_json::to_string_pretty(&view).map_err(anyhow::Error::from)?);
    } else {
        print!("{}", text(&view));
    }
    Ok(())
}

/// `remote card=test pciindex=0`: the kind, then every attribute and setting as written.
fn connection_text(c: &tutti_core::ddf::Connection) -> String {
    let rest = c.attributes.iter().filter(|(k, _)| k != "type").chain(&c.settings);
    let mut out = c.kind.as_str().to_string();
    for (k, v) in rest {
        out.push_str(&format!(" {k}={v:?}"));
    }
    out
}

fn yn(b: bool) -> &'static str {
    if b {
        "yes"
    } else {
        "no"
    }
}

fn qos_text(q: &Qos) -> String {
    let history = match q.history {
        mapping::History::KeepAll => "KEEP_ALL".to_string(),
        mapping::History::KeepLast(n) => format!("KEEP_LAST {n}"),
    };
    let durability = match q.durability {
        mapping::Durability::Volatile => "VOLATILE".to_string(),
        mapping::Durability::TransientLocal { depth } => format!("TRANSIENT_LOCAL depth {depth}"),
    };
    let reliability = match q.reliability {
        mapping::Reliability::Reliable => "RELIABLE",
        mapping::Reliability::BestEffort => "BEST_EFFORT",
    };
    let ownership = match q.ownership {
        mapping::Ownership::Shared => "SHARED".to_string(),
        mapping::Ownership::Exclusive { strength } => format!("EXCLUSIVE strength {strength}"),
    };
    format!("{reliability}, {history}, {durability}, {ownership}")
}

/// A set's names on the engine's wire: the DDS topic on a DDS engine, the ROS 2 name that
/// rmw_zenoh's keys carry on Zenoh (docs/gateway.md, "Zenoh").
fn wire_names(engine: &str, dds_topic: &str, ros2_topic: &str, ty: &str) -> String {
    match engine.parse::<tutti_gateway::EngineKind>() {
        Ok(k) if !k.is_dds() => format!("Zenoh key <ROS domain>{ros2_topic}/{ty}/<type hash>"),
        _ => format!("DDS topic {dds_topic}  type {ty}"),
    }
}

fn text(v: &ShowJson<'_>) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: {}, ROS 2 package {}, QoS profile {}, engine {}",
        v.source,
        super::count(v.domains.len(), "domain"),
        v.package,
        v.qos_profile.name(),
        v.dds_engine
    );
    for d in &v.domains {
        let _ = writeln!(
            s,
            "\ndomain {}  synchronous={} multiplePublishAllowed={} states={}  layout {}",
            d.name,
            if d.event { "event" } else { yn(d.synchronous) },
            yn(d.multiple_publish_allowed),
            yn(d.states),
            d.layout_hash
        );
        if let Some(how) = d.exclusive_writer {
            let _ = writeln!(s, "  one external writer at a time on SUBSCRIBE (enforced by: {how})");
        }
        if let Some(c) = d.connection {
            let _ = writeln!(s, "  connection {}", connection_text(c));
        }
        for set in &d.sets {
            let _ = writeln!(
                s,
                "  {} set: {} bytes (align {}), {} item(s)",
                set.role,
                set.size,
                set.align,
                set.items.len()
            );
            for leaf in set.items {
                let len = if leaf.length == 1 { String::new() } else { format!("[{}]", leaf.length) };
                let default = leaf.default.map(|d| format!("  default {d}")).unwrap_or_default();
                let _ = writeln!(
                    s,
                    "    {:<32} {:<16} offset {:>6}  size {:>6}{}",
                    leaf.path,
                    format!("{}{len}", leaf.ty.canonical()),
                    leaf.offset,
                    leaf.size,
                    default
                );
            }
            let _ =
                writeln!(s, "    {}", wire_names(v.dds_engine, &set.dds.topic, &set.dds.ros2_topic, &set.dds.dds_type));
            let _ = writeln!(s, "    gateway writer QoS: {}", qos_text(&set.writer_qos));
            let _ = writeln!(s, "    gateway reader QoS: {}", qos_text(&set.reader_qos));
        }
    }
    s
}

/// `tutti show --config --json` (schema `tutti-gateway-plan/1`, in docs/gateway.md).
#[derive(Debug, Serialize)]
struct PlanJson<'a> {
    schema: &'static str,
    source: &'a str,
    config: String,
    package: String,
    qos_profile: Profile,
    dds_engine: &'static str,
    ros2_types: &'static str,
    /// Canonical, without slashes around it; empty for none.
    ros_namespace: &'a str,
    /// The node's full name (`/NS/NAME`).
    node: String,
    /// Whether a domain is bridged only while a framework hosts it.
    hosted_only: bool,
    sets: Vec<PlanSetJson<'a>>,
    left_out: Vec<LeftOutJson<'a>>,
}

#[derive(Debug, Serialize)]
struct PlanSetJson<'a> {
    key: &'a str,
    domain: &'a str,
    role: Role,
    topic: &'a str,
    ros2_topic: &'a str,
    dds_type: &'a str,
    writer_qos: Qos,
    reader_qos: Qos,
    /// Hz; null: every sample.
    max_rate: Option<f64>,
    /// With `ros2_types` per-item: the topics that replace `topic`; else empty.
    per_item_topics: Vec<ItemTopic>,
}

#[derive(Debug, Serialize)]
struct LeftOutJson<'a> {
    key: &'a str,
    domain: &'a str,
    role: Role,
    reason: &'a str,
}

/// The gateway's plan for the DDF under the config file `cfg`, the show flags given over it.
fn show_plan(args: &Args, model: Model, cfg: &Path) -> CliResult {
    let mut flags = ConfigFile::default();
    flags.gateway.qos_profile = args.qos_profile.map(Into::into);
    flags.engine.engine = args.engine;
    let keys = config::with_model(&model, || flags.layered(Some(cfg))).map_err(Failure::invalid)?;
    let mut opts = GatewayOptions::new(&args.file, model);
    if keys.engine.engine.is_none() {
        opts.engine = config::env::engine().map_err(Failure::invalid)?;
    }
    keys.apply(&mut opts).map_err(Failure::invalid)?;
    let plan = config::resolve(&opts).map_err(Failure::invalid)?;
    let view = plan_json(&opts, &plan, cfg);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&view).map_err(anyhow::Error::from)?);
    } else {
        print!("{}", plan_text(&view));
    }
    Ok(())
}

fn plan_json<'a>(opts: &'a GatewayOptions, plan: &'a Plan, cfg: &Path) -> PlanJson<'a> {
    let per_item = opts.types == TypeMode::PerItem;
    let domain = |i: usize| opts.model.domains[i].name.as_str();
    PlanJson {
        schema: "tutti-gateway-plan/1",
        source: &opts.model.source,
        config: cfg.display().to_string(),
        package: mapping::package_name(&opts.ddf_path),
        qos_profile: opts.profile,
        dds_engine: opts.engine.name(),
        ros2_types: if per_item { "per-item" } else { "typed" },
        ros_namespace: &opts.ros_namespace,
        node: tutti_ros2::names::under(&opts.ros_namespace, &opts.node_name),
        hosted_only: opts.hosted_only,
        sets: plan
            .sets
            .iter()
            .map(|s| PlanSetJson {
                key: &s.key,
                domain: domain(s.domain),
                role: s.role,
                topic: &s.topic,
                ros2_topic: &s.ros2_topic,
                dds_type: &s.dds_type,
                writer_qos: s.writer_qos,
                reader_qos: s.reader_qos,
                max_rate: s.max_rate,
                per_item_topics: if per_item { config::item_topics(opts, s) } else { Vec::new() },
            })
            .collect(),
        left_out: plan
            .left_out
            .iter()
            .map(|l| LeftOutJson { key: &l.key, domain: domain(l.domain), role: l.role, reason: &l.reason })
            .collect(),
    }
}

fn plan_text(v: &PlanJson<'_>) -> String {
    let mut s = String::new();
    let ns = if v.ros_namespace.is_empty() { "none".to_string() } else { format!("/{}", v.ros_namespace) };
    let _ = writeln!(
        s,
        "{} under {}: {} of {} sets bridged, ROS namespace {ns}, node {}, ROS 2 package {}, types {}, QoS profile {}, engine {}",
        v.source,
        v.config,
        v.sets.len(),
        v.sets.len() + v.left_out.len(),
        v.node,
        v.package,
        v.ros2_types,
        v.qos_profile.name(),
        v.dds_engine
    );
    let _ = writeln!(
        s,
        "{}",
        if v.hosted_only {
            "a domain is bridged while a framework hosts it"
        } else {
            "every domain is bridged from the start (all domains)"
        }
    );
    for set in &v.sets {
        let _ = writeln!(s, "\n{}  ->  {}", set.key, set.ros2_topic);
        let _ = writeln!(s, "    {}", wire_names(v.dds_engine, set.topic, set.ros2_topic, set.dds_type));
        for t in &set.per_item_topics {
            let _ = writeln!(s, "      item {:<28} {}  {}", t.path, t.topic, t.dds_type);
        }
        let _ = writeln!(s, "    gateway writer QoS: {}", qos_text(&set.writer_qos));
        let _ = writeln!(s, "    gateway reader QoS: {}", qos_text(&set.reader_qos));
        let rate = set.max_rate.map_or("every sample".to_string(), |r| format!("at most {r} samples/s"));
        let _ = writeln!(s, "    out: {rate}");
    }
    if !v.left_out.is_empty() {
        let _ = writeln!(s, "\nleft out:");
        for l in &v.left_out {
            let _ = writeln!(s, "  {:<32} {}", l.key, l.reason);
        }
    }
    s
}

/// `tutti show DDF --connect …`: the connections, checked, with both ends' types and lengths.
fn show_connections(args: &Args, model: &tutti_core::ddf::Model) -> CliResult {
    use tutti_host::connect::Connections;
    let checked = Connections::resolve(model, &args.connections, &[])
        .map_err(|e| Failure::invalid(anyhow::anyhow!("{}: {e}", args.file.display())))?;
    let rows: Vec<serde_json::Value> = checked
        .specs()
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let leaf = |r: &tutti_host::connect::ItemRef| {
                model
                    .domain(&r.domain)
                    .and_then(|d| d.set(r.role).layout.leaf(&r.item))
                    .map(|l| (l.ty.canonical(), l.length))
            };
            let from = match &c.from {
                tutti_host::connect::Source::Item(r) => leaf(r).unwrap_or(("?", 0)),
                // The simulated time, in seconds.
                tutti_host::connect::Source::SimTime => ("float64", 1),
            };
            let ((ft, fl), (tt, tl)) = (from, leaf(&c.to).unwrap_or(("?", 0)));
            serde_json::json!({
                "order": i + 1, "from": c.from.to_string(), "to": c.to.to_string(), "gain": c.gain, "offset": c.offset,
                "from_type": ft, "to_type": tt, "length": fl.max(tl),
            })
        })
        .collect();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rows).map_err(anyhow::Error::from)?);
        return Ok(());
    }
    println!(
        "{} connection(s), applied in this order after each step; a value reaches its input at the next step:",
        rows.len()
    );
    for (c, r) in checked.specs().iter().zip(&rows) {
        println!(
            "  {}. {c}   ({} -> {}, {} element(s))",
            r["order"],
            r["from_type"].as_str().unwrap_or("?"),
            r["to_type"].as_str().unwrap_or("?"),
            r["length"]
        );
    }
    Ok(())
}
