//! `tutti-bench gateway --security`: what DDS Security costs the round trip through the
//! gateway, next to what it costs Cyclone's own `ddsperf`, in the same run and on the same
//! cores (docs/benchmarks.md, "DDS Security"). Per placement, unsecured then secured: the
//! ddsperf ping-pong (Debian's Cyclone 0.10 with its security plugins, through its XML
//! configuration) and the gateway round trip (Cyclone engine, each gateway mode asked for),
//! every party in an enclave of one keystore made for the run by `tests/security/keystore.sh`
//! (sros2's layout and default governance: discovery, liveliness and data encrypted, messages
//! signed). Target: secured round trip p50 at most 1.1x secured ddsperf's on one core.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context as _};
use tutti_gateway::engine::security::{Enclave, SecuritySettings, Strategy};
use tutti_gateway::EngineKind;

use super::figures::{noted, Fig, Rtt};
use super::processes::Cpus;
use super::{progress, Bench, GatewayMode};

/// The enclaves of the run.
pub(super) const GATEWAY_ENCLAVE: &str = "/tutti/gateway";
pub(super) const PEER_ENCLAVE: &str = "/bench/peer";
const DDSPERF_ENCLAVE: &str = "/bench/ddsperf";

/// Where Debian keeps Cyclone 0.10's security plugins (off the loader's path).
const DEBIAN_PLUGINS: &str = "/usr/lib/x86_64-linux-gnu/libddsc0debian";

/// The target: secured gateway p50 / secured ddsperf p50 on one core.
const TARGET: f64 = 1.1;

/// One placement's figures.
pub(super) struct SecurityRun {
    pub cpus: Cpus,
    pub ddsperf: Fig<Rtt>,
    pub ddsperf_secured: Fig<Rtt>,
    /// Per gateway mode: unsecured, secured.
    pub gateway: Vec<(GatewayMode, Fig<Rtt>, Fig<Rtt>)>,
}

/// The keystore script of this source tree.
fn keystore_script() -> PathBuf {
    let here = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/security/keystore.sh");
    if here.is_file() {
        here
    } else {
        PathBuf::from("tests/security/keystore.sh")
    }
}

/// A keystore in `dir` with the run's three enclaves.
pub(super) fn make_keystore(dir: &Path) -> anyhow::Result<PathBuf> {
    let ks = dir.join("keystore");
    let script = keystore_script();
    let run = |args: &[&str]| -> anyhow::Result<()> {
        let out = Command::new(&script)
            .args(args)
            .output()
            .with_context(|| format!("running {} (needs openssl)", script.display()))?;
        if !out.status.success() {
            bail!("{} {}: {}", script.display(), args.join(" "), String::from_utf8_lossy(&out.stderr));
        }
        Ok(())
    };
    let path = ks.to_str().context("a UTF-8 scratch path")?;
    run(&["init", path])?;
    for e in [GATEWAY_ENCLAVE, PEER_ENCLAVE, DDSPERF_ENCLAVE] {
        run(&["enclave", path, e])?;
    }
    Ok(ks)
}

/// Enclave `enclave` of `ks`, checked (for a gateway in this process).
pub(super) fn enclave(ks: &Path, enclave: &str) -> anyhow::Result<Enclave> {
    let s = SecuritySettings {
        enable: true,
        keystore: Some(ks.into()),
        enclave: Some(enclave.into()),
        strategy: Strategy::Enforce,
    };
    Ok(s.enclave()?)
}

/// ddsperf's configuration `base` (a `<CycloneDDS><Domain>` document) secured in
/// [`DDSPERF_ENCLAVE`] of `ks`, and the loader path of its plugins.
pub(super) fn secured_ddsperf(cmd: &mut Command, base: &str, ks: &Path) -> anyhow::Result<()> {
    let xml = tutti_gateway::engine::cyclone::security_xml(&enclave(ks, DDSPERF_ENCLAVE)?);
    let uri = base.replace("</Domain>", &format!("{xml}</Domain>"));
    cmd.env("CYCLONEDDS_URI", uri).env("LD_LIBRARY_PATH", DEBIAN_PLUGINS);
    Ok(())
}

impl Bench<'_> {
    /// Every placement's figures, unsecured then secured.
    pub(super) fn security_runs(&mut self, placements: &[Cpus], ks: &Path) -> Vec<SecurityRun> {
        let mut runs = Vec::new();
        for &cpus in placements {
            let at = |what: &str| format!("{}: {what}", cpus.key);
            self.secured = None;
            progress(&at("ddsperf"));
            let ddsperf = noted(self.ddsperf(cpus, None, false), &at("ddsperf"));
            self.secured = Some(ks.to_path_buf());
            progress(&at("ddsperf, secured"));
            let ddsperf_secured = noted(self.ddsperf(cpus, None, false), &at("ddsperf secured"));
            let mut gateway = Vec::new();
            for &mode in &self.args.gateways.clone() {
                let run = |b: &mut Bench<'_>, secured: bool| {
                    b.secured = secured.then(|| ks.to_path_buf());
                    let what = format!("{} gateway round trip{}", mode.key(), if secured { ", secured" } else { "" });
                    progress(&at(&what));
                    noted(b.round_trip(EngineKind::Cyclone, cpus, mode).map(|(hot, _)| hot), &at(&what))
                };
                let plain = run(self, false);
                let secured = run(self, true);
                gateway.push((mode, plain, secured));
            }
            self.secured = None;
            runs.push(SecurityRun { cpus, ddsperf, ddsperf_secured, gateway });
        }
        runs
    }
}

fn p(f: &Fig<Rtt>) -> String {
    match f {
        Ok(r) => format!("{:.1} / {:.1}", r.p50, r.p99),
        Err(e) => format!("not run: {e}"),
    }
}

/// The ratio of two p50s, if both ran.
fn ratio(a: &Fig<Rtt>, b: &Fig<Rtt>) -> Option<f64> {
    Some(a.as_ref().ok()?.p50 / b.as_ref().ok()?.p50)
}

/// The tables, on stdout.
pub(super) fn print(runs: &[SecurityRun]) {
    for r in runs {
        println!(
            "{} (round trips, p50 / p99 µs; target: secured gateway <= {TARGET}x secured ddsperf on one core)",
            r.cpus.key
        );
        println!("  {:<58} {:>18} {:>18}", "", "unsecured", "secured");
        println!(
            "  {:<58} {:>18} {:>18}",
            "ddsperf ping-pong (80 B), back to back",
            p(&r.ddsperf),
            p(&r.ddsperf_secured)
        );
        for (mode, plain, secured) in &r.gateway {
            let name = format!("gateway round trip (cyclone, {} gateway)", mode.key());
            println!("  {name:<58} {:>18} {:>18}", p(plain), p(secured));
            let verdict = |x: f64| {
                let one_core = r.cpus.key == "same";
                let mark = if !one_core {
                    ""
                } else if x <= TARGET {
                    " ok"
                } else {
                    " MISSED"
                };
                format!("{x:.2}{mark}")
            };
            let (u, s) = (ratio(plain, &r.ddsperf), ratio(secured, &r.ddsperf_secured));
            println!(
                "  {:<58} {:>18} {:>18}",
                format!("ratio gateway / ddsperf p50 ({} gateway)", mode.key()),
                u.map_or("-".into(), |x| format!("{x:.2}")),
                s.map_or("-".into(), verdict)
            );
        }
        let cost = |a: &Fig<Rtt>, b: &Fig<Rtt>| ratio(b, a).map_or("-".into(), |x| format!("{x:.2}x"));
        println!(
            "  {:<58} {:>18}",
            "what security costs ddsperf (secured / unsecured p50)",
            cost(&r.ddsperf, &r.ddsperf_secured)
        );
        for (mode, plain, secured) in &r.gateway {
            println!(
                "  {:<58} {:>18}",
                format!("what security costs the {} gateway", mode.key()),
                cost(plain, secured)
            );
        }
        println!();
    }
}

/// The figures as one JSON object.
pub(super) fn json(runs: &[SecurityRun]) -> serde_json::Value {
    let rtt = |f: &Fig<Rtt>| match f {
        Ok(r) => serde_json::json!({ "p50_us": r.p50, "p99_us": r.p99, "lost": r.lost }),
        Err(e) => serde_json::json!({ "not_run": e }),
    };
    let placements: Vec<serde_json::Value> = runs
        .iter()
        .map(|r| {
            let gateways: Vec<serde_json::Value> = r
                .gateway
                .iter()
                .map(|(mode, plain, secured)| {
                    serde_json::json!({
                        "gateway": mode.key(),
                        "unsecured": rtt(plain),
                        "secured": rtt(secured),
                        "ratio_to_ddsperf_unsecured": ratio(plain, &r.ddsperf),
                        "ratio_to_ddsperf_secured": ratio(secured, &r.ddsperf_secured),
                    })
                })
                .collect();
            serde_json::json!({
                "placement": r.cpus.key,
                "ddsperf": { "unsecured": rtt(&r.ddsperf), "secured": rtt(&r.ddsperf_secured) },
                "gateway": gateways,
            })
        })
        .collect();
    serde_json::json!({ "security": { "target_ratio_one_core": TARGET, "placements": placements } })
}
