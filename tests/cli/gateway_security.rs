//! The gateway under DDS Security (SROS2 enclaves; docs/security.md, "What the network can
//! do"): keystores made fresh by `tests/security/keystore.sh` with openssl, in sros2's layout.
//!
//! * every error the gateway checks for before DDS sees the enclave is refused at start, exit
//!   status 2, with the message naming the file (or the keystore, or the enclave);
//! * `Permissive` runs unsecured with a warning; an engine without DDS Security is refused
//!   under `Enforce`;
//! * a secured gateway and Debian's `ddsperf` with its security plugins find each other,
//!   while an unsecured Cyclone peer (the Python binding) sees none of the gateway's
//!   endpoints.
//!
//! The tests with the real rclpy are in `ros2_real` (`..._secured`). DDS domains 210..=215.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::gateway::*;
use tutti_core::ddf::Role;
use tutti_engine::security::{Enclave, SecuritySettings, Strategy};
use tutti_test_support::{namespace, require_tool, run_with_timeout, tutti_command};

/// The enclave the tests give the gateway.
pub const GATEWAY_ENCLAVE: &str = "/tutti/gateway";

/// Where Debian's libddsc0debian keeps Cyclone 0.10's security plugins (not on the loader's
/// path): ddsperf and rmw_cyclonedds load them from there.
pub const DEBIAN_PLUGINS: &str = "/usr/lib/x86_64-linux-gnu/libddsc0debian";

/// A keystore made by `tests/security/keystore.sh` in a temporary directory (removed on drop).
pub struct Keystore {
    dir: tempfile::TempDir,
}

impl Keystore {
    /// A keystore with its CA and governance, and the enclaves `enclaves` (each a name and
    /// the script's options for it: `--deny TOPIC`, `--expired`, `--ca OTHER`). None where
    /// openssl is missing (as the suite's policy for tools has it).
    pub fn new(enclaves: &[(&str, &[&str])]) -> Option<Keystore> {
        require_tool("openssl", "openssl")?;
        let dir = tempfile::tempdir().expect("a temporary directory");
        let ks = Keystore { dir };
        ks.script(&["init", ks.path_str()]);
        for (name, opts) in enclaves {
            ks.enclave(name, opts);
        }
        Some(ks)
    }

    /// Adds (or makes again) enclave `name`.
    pub fn enclave(&self, name: &str, opts: &[&str]) {
        let mut args = vec!["enclave", self.path_str(), name];
        args.extend_from_slice(opts);
        self.script(&args);
    }

    fn script(&self, args: &[&str]) {
        let script = tutti_test_support::repo_root().join("tests/security/keystore.sh");
        let mut cmd = Command::new(&script);
        cmd.args(args);
        let (status, out, err) = run_with_timeout(cmd, SECS(60));
        assert!(status.success(), "keystore.sh {}: {out}{err}", args.join(" "));
    }

    pub fn path(&self) -> &Path {
        self.dir.path()
    }

    fn path_str(&self) -> &str {
        self.dir.path().to_str().expect("a UTF-8 temporary path")
    }

    /// A file of enclave `name`.
    pub fn file(&self, enclave: &str, file: &str) -> PathBuf {
        self.path().join("enclaves").join(enclave.trim_start_matches('/')).join(file)
    }

    /// The environment a secured ROS 2 process (or gateway) of enclave `enclave` runs with:
    /// rcl's variables, `Enforce`.
    pub fn env(&self, enclave: &str) -> [(&'static str, String); 4] {
        SecuritySettings::enforce_env(self.path(), enclave)
    }

    /// Enclave `enclave`, as the gateway finds and checks it.
    pub fn enclave_of(&self, enclave: &str) -> Enclave {
        let s = SecuritySettings {
            enable: true,
            keystore: Some(self.path().into()),
            enclave: Some(enclave.into()),
            strategy: Strategy::Enforce,
        };
        s.enclave().unwrap_or_else(|e| panic!("enclave {enclave}: {e}"))
    }

    /// The gateway's flags for enclave `enclave`, `Enforce`.
    pub fn flags(&self, enclave: &str) -> Vec<String> {
        let ks = self.path_str().to_string();
        ["--security", "--security-keystore", &ks, "--enclave", enclave, "--security-strategy", "Enforce"]
            .map(String::from)
            .to_vec()
    }
}

/// `tutti gateway tests/gateway/gw.ddf` with `args`, expected to refuse to start: its
/// stderr, once it exited 2.
fn refused(args: &[String], env: &[(&str, String)]) -> String {
    let ns = namespace("secref");
    let mut cmd = tutti_command();
    cmd.args(["gateway", DDF, "--all-domains", "--interface", "127.0.0.1", "--ros-domain-id", "210"])
        .args(args)
        .env("TUTTI_NAMESPACE", &ns)
        .envs(env.iter().map(|(k, v)| (k, v)));
    let (status, out, err) = run_with_timeout(cmd, SECS(60));
    assert_eq!(status.code(), Some(2), "the gateway did not refuse to start:\n{out}\n{err}");
    err
}

fn flags_with(ks: &Keystore, enclave: &str, more: &[&str]) -> Vec<String> {
    let mut f = ks.flags(enclave);
    f.extend(more.iter().map(|s| s.to_string()));
    f
}

#[test]
fn each_unusable_enclave_is_refused_at_start_naming_its_file() {
    let Some(ks) = Keystore::new(&[(GATEWAY_ENCLAVE, &[])]) else { return };
    let Some(other) = Keystore::new(&[]) else { return };
    let cert = ks.file(GATEWAY_ENCLAVE, "cert.pem");

    // No keystore there.
    let missing = ks.path().join("nowhere");
    let mut f = ks.flags(GATEWAY_ENCLAVE);
    f[2] = missing.display().to_string();
    let err = refused(&f, &[]);
    assert!(err.contains(&format!("keystore {}", missing.display())), "{err}");

    // An enclave the keystore does not have: the message lists those it has.
    let err = refused(&ks.flags("/tutti/other"), &[]);
    assert!(
        err.contains("enclave '/tutti/other' is not in keystore") && err.contains("(it has: /tutti/gateway)"),
        "{err}"
    );

    // A relative enclave name.
    let err = refused(&ks.flags("tutti/gateway"), &[]);
    assert!(err.contains("enclave 'tutti/gateway': an enclave is an absolute name"), "{err}");

    // A certificate from another CA.
    ks.enclave("/from/other", &["--ca", other.path_str()]);
    let err = refused(&ks.flags("/from/other"), &[]);
    let other_cert = ks.file("/from/other", "cert.pem");
    assert!(err.contains(&format!("{}: not issued by the identity CA", other_cert.display())), "{err}");

    // An expired certificate.
    ks.enclave("/expired", &["--expired"]);
    let err = refused(&ks.flags("/expired"), &[]);
    let expired = ks.file("/expired", "cert.pem");
    assert!(err.contains(&format!("{}: the certificate expired on Dec 31", expired.display())), "{err}");

    // Governance signed by another CA.
    ks.enclave("/bad/governance", &[]);
    let governance = ks.file("/bad/governance", "governance.p7s");
    std::fs::copy(other.path().join("enclaves/governance.p7s"), &governance).expect("copy");
    let err = refused(&ks.flags("/bad/governance"), &[]);
    assert!(
        err.contains(&format!("{}: its signature does not verify against the permissions CA", governance.display())),
        "{err}"
    );

    // Permissions changed after they were signed: DENY made ALLOW.
    ks.enclave("/bad/permissions", &[]);
    let permissions = ks.file("/bad/permissions", "permissions.p7s");
    let text = std::fs::read_to_string(&permissions).expect("permissions.p7s");
    assert!(text.contains("<default>DENY</default>"), "{text}");
    std::fs::write(&permissions, text.replace("<default>DENY</default>", "<default>ALLOW</default>")).expect("write");
    let err = refused(&ks.flags("/bad/permissions"), &[]);
    assert!(err.contains(&format!("{}: its signature does not verify", permissions.display())), "{err}");

    // A key that is not the certificate's.
    ks.enclave("/bad/key", &[]);
    std::fs::copy(ks.file(GATEWAY_ENCLAVE, "key.pem"), ks.file("/bad/key", "key.pem")).expect("copy");
    let err = refused(&ks.flags("/bad/key"), &[]);
    assert!(err.contains("key.pem: the private key does not belong to the certificate"), "{err}");

    // Permissions granted to another subject.
    ks.enclave("/bad/grant", &[]);
    std::fs::copy(ks.file(GATEWAY_ENCLAVE, "permissions.p7s"), ks.file("/bad/grant", "permissions.p7s")).expect("copy");
    let err = refused(&ks.flags("/bad/grant"), &[]);
    assert!(err.contains("permissions.p7s: no grant for the certificate's subject 'CN=/bad/grant'"), "{err}");

    // A file missing from the enclave.
    std::fs::remove_file(&cert).expect("remove cert.pem");
    let err = refused(&ks.flags(GATEWAY_ENCLAVE), &[]);
    assert!(err.contains(&format!("{}: No such file", cert.display())), "{err}");

    // The same through rcl's variables, and through the config file's keys.
    let env = ks.env("/expired");
    let err = refused(&[], &env);
    assert!(err.contains(&format!("{}: the certificate expired", expired.display())), "{err}");
    let config = ks.path().join("gateway.json5");
    std::fs::write(
        &config,
        format!(
            "{{ security_enable: true, security_keystore: {:?}, enclave: \"/expired\", security_strategy: \"Enforce\" }}",
            ks.path_str()
        ),
    )
    .expect("the config file");
    let err = refused(&["--config".into(), config.display().to_string()], &[]);
    assert!(err.contains(&format!("{}: the certificate expired", expired.display())), "{err}");
    // A bad strategy names itself.
    let mut f = ks.flags(GATEWAY_ENCLAVE);
    f[6] = "Strict".into();
    let err = refused(&f, &[]);
    assert!(err.contains("'Strict'"), "{err}");
}

#[test]
fn permissive_runs_unsecured_with_a_warning_and_rustdds_is_refused_under_enforce() {
    let Some(ks) = Keystore::new(&[(GATEWAY_ENCLAVE, &[])]) else { return };
    // Permissive: the enclave is missing, the gateway warns and runs.
    let ns = namespace("secperm");
    let mut args = ks.flags("/not/there");
    args[6] = "Permissive".into();
    args.extend(["--all-domains".to_string()]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let mut gw = gateway(DDF, 211, &ns, &args);
    let warned = gw
        .lines()
        .iter()
        .any(|l| l.contains("enclave '/not/there' is not in keystore") && l.contains("WITHOUT security"));
    assert!(warned, "{}", gw.dump());
    assert_eq!(gw.interrupt(SECS(20)), Some(0), "{}", gw.dump());

    // An engine without DDS Security: refused under Enforce.
    if tutti_engine::EngineKind::Rustdds.is_built() {
        let err = refused(&flags_with(&ks, GATEWAY_ENCLAVE, &["--engine", "rustdds"]), &[]);
        assert!(err.contains("the rustdds engine does not do DDS Security"), "{err}");
    }
}

/// `ddsperf` (Debian's Cyclone 0.10) in enclave `enclave` of `ks` through its XML
/// configuration, on loopback, with its security plugins.
pub fn secured_ddsperf(ks: &Keystore, enclave: &str, dom: u16, args: &[&str]) -> Option<Command> {
    let ddsperf = require_tool("ddsperf", "cyclonedds-tools")?;
    let uri = concat!(
        r#"<CycloneDDS><Domain id="any"><General><Interfaces><NetworkInterface name="lo"/></Interfaces>"#,
        r#"<AllowMulticast>false</AllowMulticast></General><Discovery><Peers><Peer address="127.0.0.1"/></Peers>"#,
        r#"<ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>40</MaxAutoParticipantIndex></Discovery>"#,
        "SECURITY</Domain></CycloneDDS>"
    )
    .replace("SECURITY", &tutti_engine::cyclone::security_xml(&ks.enclave_of(enclave)));
    let mut cmd = Command::new(ddsperf);
    cmd.args(["-i", &dom.to_string()]).args(args).env("CYCLONEDDS_URI", uri).env("LD_LIBRARY_PATH", DEBIAN_PLUGINS);
    Some(cmd)
}

/// The secured peers of the benchmark and the unsecured one, beside a secured gateway: a
/// `ddsperf` ping and pong pair in enclaves of the test's keystore (Cyclone 0.10's plugins
/// reading sros2's layout as made here) exchange round trips, while an unsecured Cyclone peer
/// (the Python binding) on the same domain sees none of the gateway's endpoints, nor theirs,
/// and its writer on a SUBSCRIBE topic of the gateway never matches: the framework never
/// gets its value.
#[test]
fn secured_ddsperf_runs_in_the_keystore_and_an_unsecured_peer_sees_and_writes_nothing() {
    let Some(ks) = Keystore::new(&[(GATEWAY_ENCLAVE, &[]), ("/ddsperf", &[])]) else { return };
    let Some(py) = tutti_test_support::python(&["cyclonedds"]) else { return };
    let dom = 212;
    let ns = namespace("secdisc");
    let host = Host::start(&ns, "gw_async", SECS(1) / 100, |_| vec![0u8; 40]);
    let flags = ks.flags(GATEWAY_ENCLAVE);
    let args: Vec<&str> = flags.iter().map(String::as_str).collect();
    let gw = gateway(DDF, dom, &ns, &args);

    let Some(pong) = secured_ddsperf(&ks, "/ddsperf", dom, &["pong"]) else { return };
    let pong = Proc::spawn("secured ddsperf pong", pong, SECS(60));
    let ping_args = ["-D", "5", "-Qminmatch:1", "-Qinitwait:20", "ping"];
    let Some(mut ping) = secured_ddsperf(&ks, "/ddsperf", dom, &ping_args) else { return };
    let (status, out, err) = run_with_timeout(&mut ping, SECS(60));
    assert!(
        status.success() && out.contains(" 50% "),
        "secured ddsperf ping had no round trips:\n{out}\n{err}\n{}",
        pong.dump()
    );

    let mut endpoints = peer(&py, "unsecured endpoints", dom, "endpoints", &["--count", "1", "--timeout", "5"]);
    assert_eq!(
        endpoints.wait(SECS(60)),
        Some(3),
        "the unsecured peer saw secured endpoints:\n{}\n{}",
        endpoints.dump(),
        gw.dump()
    );
    let seen = endpoints.lines().join("\n");
    assert!(!seen.contains("gw_") && !seen.contains("DDSPerf"), "{seen}");

    let values = r#"[{"y": 7.25, "n": 3}]"#;
    let args = ["--topic", "rt/gw_async/subscribe", "--type", "gw_msgs::msg::dds_::GwAsyncSubscribe_"];
    let rest = ["--fields", ASYNC_SUB, "--values", values, "--timeout", "5"];
    let mut writer = peer(&py, "unsecured writer", dom, "pub", &[&args[..], &rest].concat());
    assert_eq!(writer.wait(SECS(60)), Some(3), "the unsecured writer matched:\n{}", writer.dump());
    assert!(writer.lines().iter().any(|l| l.contains("no matched reader")), "{}", writer.dump());
    let y = leaf_offset("gw_async", Role::Subscribe, "y");
    assert_eq!(host.wait_for(SECS(1), |_, b| f64_at(b, y) == 7.25), None, "the unsecured write reached the framework");
}
