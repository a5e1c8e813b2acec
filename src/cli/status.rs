//! `tutti status [--watch] [--json]`: the live domains of the namespace, their framework,
//! step, rates, connections and writer ownership.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::time::{Duration, Instant};

use anyhow::Context;
use tutti_core::shm::segment::namespace_from_env;
use tutti_core::shm::{list_domains, ConnectionInfo, DomainStatus, ShmError};

use super::CliResult;

/// List the live domains of the namespace (TUTTI_NAMESPACE): framework, step, rates,
/// overruns, connections (pid, name, writer or reader, since) and the exclusive owner.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:\n  tutti status\n  tutti status --watch\n  TUTTI_NAMESPACE=lab2 tutti status --json")]
pub struct Args {
    /// Refresh every second (Ctrl-C to stop), with step and commit rates.
    #[arg(long)]
    watch: bool,
    /// Print JSON: an array of domain objects (see docs/architecture.md).
    #[arg(long)]
    json: bool,
    /// Namespace to list (default: TUTTI_NAMESPACE, else tutti).
    #[arg(long)]
    namespace: Option<String>,
}

/// How long a one-shot `tutti status` watches to measure the rates.
const RATE_WINDOW: Duration = Duration::from_millis(250);

fn fmt_ns(ns: u64) -> String {
    if ns >= 1_000_000 {
        format!("{:.2}ms", ns as f64 / 1e6)
    } else {
        format!("{:.1}us", ns as f64 / 1e3)
    }
}

/// The domains as `--json` prints them, with their rates.
fn json(domains: &[Result<DomainStatus, ShmError>], rates: &HashMap<String, (f64, f64)>) -> Vec<serde_json::Value> {
    domains
        .iter()
        .map(|d| match d {
            Ok(d) => {
                let mut v = serde_json::to_value(d).unwrap_or_default();
                // Simulated time to the nanosecond: 3.05, not 3.0500000000000003.
                v["sim_time"] = serde_json::json!((d.sim_time * 1e9).round() / 1e9);
                if let Some(&(steps, commits)) = rates.get(&d.domain) {
                    v["steps_per_s"] = serde_json::json!(steps.round());
                    v["commits_per_s"] = serde_json::json!(commits.round());
                }
                v
            }
            Err(e) => serde_json::json!({ "error": e.to_string() }),
        })
        .collect()
}

fn render(domains: &[Result<DomainStatus, ShmError>], rates: &HashMap<String, (f64, f64)>, ns: &str) -> String {
    let mut s = String::new();
    if domains.is_empty() {
        let _ = writeln!(s, "no live domains in namespace '{ns}'");
        return s;
    }
    let now_ns = tutti_core::shm::os::now_ns();
    for d in domains {
        match d {
            Err(e) => {
                let _ = writeln!(s, "! {e}");
            }
            Ok(d) => {
                render_domain(&mut s, d, rates.get(&d.domain).copied().unwrap_or((0.0, 0.0)));
                for c in &d.connections {
                    render_connection(&mut s, c, now_ns);
                }
            }
        }
    }
    s
}

/// A domain's two lines: its mode, framework, step, rates and participants; its timing.
fn render_domain(s: &mut String, d: &DomainStatus, (step_rate, commit_rate): (f64, f64)) {
    let f = d.flags;
    let mode = format!(
        "{}{}{}",
        if f.event {
            "event"
        } else if f.synchronous {
            "sync"
        } else {
            "async"
        },
        if f.multiple_publish_allowed { "" } else { ",exclusive" },
        if f.states { ",states" } else { "" }
    );
    let fw = if d.framework_alive {
        format!("pid {}", d.framework_pid)
    } else {
        format!("pid {} (stopped)", d.framework_pid)
    };
    let _ = writeln!(
        s,
        "{} [{mode}] framework {fw}  step {}  sim {:.3}s  {:.0} steps/s  {:.0} commits/s  participants {}  remote writers {}  remote readers {}",
        d.domain, d.step, d.sim_time, step_rate, commit_rate, d.connection_count, d.dds_writers, d.dds_readers
    );
    let _ = writeln!(
        s,
        "    period {}  overruns {}  late last {} max {}  step timeouts {}  seeded {}  wait-to-go {}{}",
        fmt_ns(d.period_ns),
        d.overruns,
        fmt_ns(d.last_late_ns),
        fmt_ns(d.max_late_ns),
        d.step_timeouts,
        if d.seeded { "yes" } else { "no" },
        match (d.waiting_to_go, d.paused) {
            (true, _) => "held",
            (false, true) => "go (paused)",
            (false, false) => "go",
        },
        d.owner_pid.map(|p| format!("  owner pid {p}")).unwrap_or_default()
    );
}

/// A connection's line: slot, pid, name, role, since when, its counters.
fn render_connection(s: &mut String, c: &ConnectionInfo, now_ns: u64) {
    let role = match (c.observer, c.writer, c.sync_reader) {
        (true, _, _) => "observer",
        (_, true, _) => "writer",
        (_, false, true) => "sync reader",
        (_, false, false) => "reader",
    };
    let via = match (c.observer, c.remote, c.link) {
        (true, _, _) => format!("bridges {} remote reader(s)  ", c.dds_readers),
        (false, true, Some(l)) => format!(
            "via the gateway, lookahead {} (ahead {}, round trip {:.1} ms, {} steps waited for the link)  ",
            l.lookahead,
            l.ahead,
            l.rtt_us as f64 / 1e3,
            l.link_waits
        ),
        (false, true, None) => "via the gateway  ".to_string(),
        _ => String::new(),
    };
    let since = now_ns.saturating_sub(c.since_ns) as f64 / 1e9;
    let _ = writeln!(
        s,
        "    #{:<3} pid {:<7} {:<20} {:<11} {}since {:.1}s  reads {} commits {} missed {}{}",
        c.slot,
        c.pid,
        c.name,
        role,
        via,
        since,
        c.reads,
        c.commits,
        c.missed_steps,
        if c.alive { "" } else { "  (dead, being removed)" }
    );
}

pub fn run(args: Args) -> CliResult {
    let ns = args.namespace.unwrap_or_else(namespace_from_env);
    let mut previous: HashMap<String, (u64, u64)> = HashMap::new();
    let mut last = Instant::now();
    let mut first = true;
    loop {
        let mut domains = list_domains(&ns).with_context(|| format!("listing namespace '{ns}'"))?;
        // One look: a second one a moment later gives the rates (else they would read 0).
        if first && !args.watch && !domains.is_empty() {
            for d in domains.iter().flatten() {
                previous.insert(d.domain.clone(), (d.steps, d.subscribe_commits));
            }
            last = Instant::now();
            std::thread::sleep(RATE_WINDOW);
            domains = list_domains(&ns).with_context(|| format!("listing namespace '{ns}'"))?;
        }
        first = false;
        let dt = last.elapsed().as_secs_f64().max(1e-9);
        last = Instant::now();
        let mut rates = HashMap::new();
        for d in domains.iter().flatten() {
            let now = (d.steps, d.subscribe_commits);
            if let Some(p) = previous.get(&d.domain) {
                rates.insert(
                    d.domain.clone(),
                    ((now.0.saturating_sub(p.0)) as f64 / dt, (now.1.saturating_sub(p.1)) as f64 / dt),
                );
            }
            previous.insert(d.domain.clone(), now);
        }
        if args.json {
            println!("{}", serde_json::to_string_pretty(&json(&domains, &rates)).map_err(anyhow::Error::from)?);
        } else {
            if args.watch {
                print!("\x1b[2J\x1b[H");
            }
            print!("{}", render(&domains, &rates, &ns));
        }
        if !args.watch {
            return Ok(());
        }
        std::thread::sleep(Duration::from_secs(1));
    }
}
