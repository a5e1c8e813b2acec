//! `tutti show DDF [--json]`: domains, flags, sets, items with their layout, DDS topics and
//! QoS. The JSON schema is documented in `docs/ddf.md`.

use std::fmt::Write as _;
use std::path::PathBuf;

use serde::Serialize;
use tutti_core::ddf::{Domain, Leaf, Model, Role};
use tutti_core::mapping::{self, Endpoint, ItemTopic, Profile, Qos, SetNames};

use tutti_gateway::EngineKind;

use super::{load_ddf, CliResult};

/// Show what a DDF describes: domains, flags, sets, items (paths, types, lengths, offsets,
/// defaults), DDS topics and QoS.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti show ddf/multiuav.ddf\n  tutti show ddf/product-sample.ddf --json | python3 -m json.tool"
)]
pub struct Args {
    /// The DDF to show.
    #[arg(value_name = "DDF")]
    file: PathBuf,
    /// Print JSON (schema in docs/ddf.md) instead of text.
    #[arg(long)]
    json: bool,
    /// QoS profile to show (as `tutti gateway --qos-profile`).
    #[arg(long, value_enum, default_value_t = ProfileArg::Ros2)]
    qos_profile: ProfileArg,
    /// DDS engine to show (as `tutti gateway --dds`).
    #[arg(long = "dds", env = "TUTTI_DDS", default_value = "cyclone", value_name = "ENGINE")]
    engine: EngineKind,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum ProfileArg {
    Ros2,
    Dds,
}

impl From<ProfileArg> for Profile {
    fn from(p: ProfileArg) -> Self {
        match p {
            ProfileArg::Ros2 => Profile::Ros2,
            ProfileArg::Dds => Profile::Dds,
        }
    }
}

/// `tutti show --json` output, version 1.
#[derive(Debug, Serialize)]
struct ShowJson<'a> {
    schema: &'static str,
    source: &'a str,
    package: String,
    qos_profile: Profile,
    /// The gateway's DDS engine: "cyclone" or "rustdds".
    dds_engine: &'static str,
    domains: Vec<DomainJson<'a>>,
}

#[derive(Debug, Serialize)]
struct DomainJson<'a> {
    name: &'a str,
    synchronous: bool,
    multiple_publish_allowed: bool,
    states: bool,
    connection: Option<&'a tutti_core::ddf::Connection>,
    layout_hash: String,
    /// How writer exclusivity is enforced: null, "gateway" (the core's first-writer rule,
    /// over DDS too) or "gateway+dds" (also EXCLUSIVE ownership matched on the wire).
    exclusive_writer: Option<&'static str>,
    sets: Vec<SetJson<'a>>,
}

#[derive(Debug, Serialize)]
struct SetJson<'a> {
    role: Role,
    size: u32,
    align: u32,
    items: &'a [Leaf],
    dds: SetNames,
    per_item_topics: Vec<ItemTopic>,
    writer_qos: Qos,
    reader_qos: Qos,
}

pub fn run(args: Args) -> CliResult {
    let model = load_ddf(&args.file)?;
    let profile = Profile::from(args.qos_profile);
    let view = build(&model, &args.file, profile, args.engine);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&view).map_err(anyhow::Error::from)?);
    } else {
        print!("{}", text(&view));
    }
    Ok(())
}

fn build<'a>(model: &'a Model, path: &std::path::Path, profile: Profile, engine: EngineKind) -> ShowJson<'a> {
    let package = mapping::package_name(path);
    let domains = model.domains.iter().map(|d| domain_json(d, &package, profile)).collect();
    ShowJson {
        schema: "tutti-show/1",
        source: &model.source,
        package,
        qos_profile: profile,
        dds_engine: engine.name(),
        domains,
    }
}

fn domain_json<'a>(d: &'a Domain, package: &str, profile: Profile) -> DomainJson<'a> {
    let sets = Role::ALL
        .iter()
        .map(|&role| {
            let set = d.set(role);
            SetJson {
                role,
                size: set.layout.size,
                align: set.layout.align,
                items: &set.layout.leaves,
                dds: mapping::set_names(package, &d.name, role),
                per_item_topics: mapping::item_topics(d, role),
                writer_qos: mapping::qos(d.flags, profile, Endpoint::Writer, 100),
                reader_qos: mapping::qos(d.flags, profile, Endpoint::Reader, 100),
            }
        })
        .collect();
    let exclusive_writer = match (d.flags.multiple_publish_allowed, profile) {
        (true, _) => None,
        (false, Profile::Ros2) => Some("gateway"),
        (false, Profile::Dds) => Some("gateway+dds"),
    };
    DomainJson {
        name: &d.name,
        synchronous: d.flags.synchronous,
        multiple_publish_allowed: d.flags.multiple_publish_allowed,
        states: d.flags.states,
        connection: d.connection.as_ref(),
        layout_hash: format!("{:016x}", d.layout_hash),
        exclusive_writer,
        sets,
    }
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

fn text(v: &ShowJson<'_>) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: {} domain(s), ROS 2 package {}, QoS profile {:?}, DDS engine {}",
        v.source,
        v.domains.len(),
        v.package,
        v.qos_profile,
        v.dds_engine
    );
    for d in &v.domains {
        let _ = writeln!(
            s,
            "\ndomain {}  synchronous={} multiplePublishAllowed={} states={}  layout {}",
            d.name,
            yn(d.synchronous),
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
            let _ = writeln!(s, "    DDS topic {}  type {}", set.dds.topic, set.dds.dds_type);
            let _ = writeln!(s, "    gateway writer QoS: {}", qos_text(&set.writer_qos));
            let _ = writeln!(s, "    gateway reader QoS: {}", qos_text(&set.reader_qos));
        }
    }
    s
}
