//! `tutti show DDF [--json]`: domains, flags, sets, items with their layout, DDS topics and
//! QoS. The JSON schema is documented in `docs/ddf.md`.

use std::fmt::Write as _;
use std::path::PathBuf;

use tutti_core::mapping::{self, Profile, Qos};
use tutti_core::show::{show, ShowJson};

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

pub fn run(args: Args) -> CliResult {
    let model = load_ddf(&args.file)?;
    let profile = Profile::from(args.qos_profile);
    let view = show(&model, &args.file, profile, args.engine.name());
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

fn text(v: &ShowJson<'_>) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: {}, ROS 2 package {}, QoS profile {}, DDS engine {}",
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
