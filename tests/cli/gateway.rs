//! Helpers of the gateway tests: the Python venv with Cyclone DDS, a gateway process, network
//! namespaces, the Cyclone peer, an in-process framework.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use tutti_engine::EngineKind;
use tutti_test_support::{RemoveSegments, Worker};

use tutti_core::ddf::{Model, Role};
use tutti_core::shm::{ConnectOptions, Framework, FrameworkOptions, Participant};

pub const DDF: &str = "tests/gateway/gw.ddf";
pub const PEER: &str = "tests/gateway/dds_peer.py";

/// A watchdog's limit, in seconds.
pub const SECS: fn(u64) -> Duration = Duration::from_secs;

/// The fields of the topics of `DDF` (tests/gateway/gw.ddf), as the peer takes them
/// (`--fields`): the synchronous domain's PUBLISH and SUBSCRIBE sets, the asynchronous one's,
/// and the states domain's SUBSCRIBE set.
pub const SYNC_PUB: &str = r#"[["step","uint64"],["sim_time","float64"],["x","float64"]]"#;
pub const SYNC_SUB: &str = r#"[["step","uint64"],["sim_time","float64"],["y","float64"]]"#;
pub const ASYNC_PUB: &str =
    r#"[["step","uint64"],["sim_time","float64"],["x","float64"],["flag","bool"],["v","float64[3]"]]"#;
pub const ASYNC_SUB: &str = r#"[["step","uint64"],["sim_time","float64"],["y","float64"],["n","int32"]]"#;
pub const STATES_SUB: &str = r#"[["step","uint64"],["sim_time","float64"],["y","float64"]]"#;

/// The status of `domain` in namespace `ns`, read from its segment.
pub fn status(ns: &str, domain: &str) -> tutti_core::shm::DomainStatus {
    tutti_core::shm::segment::Segment::open(ns, domain).unwrap_or_else(|e| panic!("{ns}/{domain}: {e}")).status()
}

/// The venv's Python with cyclonedds (`tutti_test_support::python`: the test is skipped when
/// it is missing, and fails under CI=true).
pub fn python() -> Option<PathBuf> {
    tutti_test_support::python(&["cyclonedds"])
}

pub use tutti_test_support::Proc;

/// The log filter of the gateways the tests start: `TUTTI_TEST_GATEWAY_LOG` when set (to
/// follow one test's gateway closer, e.g. `info,tutti_engine=debug`), else `info` with the DDS
/// stacks' own logs off.
pub fn gateway_log() -> String {
    std::env::var("TUTTI_TEST_GATEWAY_LOG").unwrap_or_else(|_| "info,rustdds=off,ros2_client=off".into())
}

/// `tutti gateway DDF` on loopback in DDS domain `domain_id`, namespace `ns`.
pub fn gateway(ddf: &str, domain_id: u16, ns: &str, extra: &[&str]) -> Proc {
    start_gateway(tutti_test_support::tutti_command(), ddf, domain_id, ns, "127.0.0.1", extra)
}

/// `tutti gateway DDF` run by `cmd` (the binary itself, or `ip netns exec NS` before it)
/// on interface `addr`; returns once it is up.
fn start_gateway(mut cmd: Command, ddf: &str, domain_id: u16, ns: &str, addr: &str, extra: &[&str]) -> Proc {
    cmd.args(["gateway", ddf, "--ros-domain-id", &domain_id.to_string(), "--interface", addr])
        .args(["--status-every", "300ms"])
        .args(extra)
        .env("TUTTI_NAMESPACE", ns)
        .env("RUST_LOG", gateway_log());
    let p = Proc::spawn(&format!("gateway {ns}"), cmd, Duration::from_secs(180));
    assert!(p.wait_line("tutti gateway: up", Duration::from_secs(60)).is_some(), "gateway did not start\n{}", p.dump());
    p
}

/// `tutti host DDF --gateway` on engine `e`, in DDS domain `dom` (loopback) and namespace
/// `ns`, stepping every 5 ms with more arguments `extra`; returns once the gateway is up. The
/// segments are removed when the returned guard drops, even if the host was killed.
pub fn host_with_gateway(e: Eng, ddf: &str, dom: u16, ns: &str, extra: &[&str]) -> (Proc, RemoveSegments) {
    host_with_gateway_by(tutti_test_support::tutti_command(), e, ddf, dom, ns, extra)
}

/// [`host_with_gateway`] run by `cmd` (the binary itself, or `ip netns exec NS` before it).
pub fn host_with_gateway_by(
    mut cmd: Command,
    e: Eng,
    ddf: &str,
    dom: u16,
    ns: &str,
    extra: &[&str],
) -> (Proc, RemoveSegments) {
    let guard = RemoveSegments(ns.to_string());
    cmd.args(["host", ddf, "--step", "5ms", "--gateway"])
        .args(extra)
        .env("TUTTI_NAMESPACE", ns)
        .env("ROS_DOMAIN_ID", dom.to_string())
        .env("TUTTI_DDS", e.name)
        .env("TUTTI_GATEWAY_INTERFACE", "127.0.0.1")
        .env("RUST_LOG", gateway_log());
    let p = Proc::spawn(&format!("host --gateway {ns}"), cmd, SECS(180));
    assert!(p.wait_line("host: gateway: up", SECS(60)).is_some(), "the gateway did not start\n{}", p.dump());
    (p, guard)
}

use tutti_test_support::{run_tool, SetupError};

/// Two network namespaces joined by a veth pair (`veth0` in each, 192.0.2.1/24 in the first,
/// 192.0.2.2/24 in the second: addresses that exist only inside them), both removed on drop.
/// Shared memory (/dev/shm) and pids are shared with the test, as on one machine with two
/// network stacks.
pub struct NetnsPair {
    pub names: [String; 2],
}

impl NetnsPair {
    pub const ADDRS: [&'static str; 2] = ["192.0.2.1", "192.0.2.2"];

    /// Creates the pair, named after `tag` and this process; Err with the reason when this
    /// machine does not let the test create namespaces (no root, no `ip`).
    pub fn create(tag: &str) -> Result<NetnsPair, SetupError> {
        let names = [0, 1].map(|i| format!("tutti-{}-{tag}-{i}", std::process::id()));
        let pair = NetnsPair { names: names.clone() };
        let ip = |args: &[&str]| run_tool("ip", args);
        for n in &names {
            ip(&["netns", "add", n])?;
        }
        ip(&["link", "add", "veth0", "netns", &names[0], "type", "veth", "peer", "name", "veth0", "netns", &names[1]])?;
        for (n, addr) in names.iter().zip(Self::ADDRS) {
            ip(&["-n", n, "addr", "add", &format!("{addr}/24"), "dev", "veth0"])?;
            ip(&["-n", n, "link", "set", "veth0", "up", "multicast", "on"])?;
            ip(&["-n", n, "link", "set", "lo", "up"])?;
            ip(&["-n", n, "route", "add", "224.0.0.0/4", "dev", "veth0"])?;
        }
        Ok(pair)
    }

    /// `tutti gateway` inside namespace `i`, on its veth address, with `env` added to its
    /// environment.
    #[allow(clippy::too_many_arguments)]
    pub fn gateway(
        &self,
        i: usize,
        e: Eng,
        ddf: &str,
        domain_id: u16,
        ns: &str,
        extra: &[&str],
        env: &[(&str, &str)],
    ) -> Proc {
        netns_gateway((&self.names[i], Self::ADDRS[i]), e, ddf, domain_id, ns, extra, env)
    }
}

/// `tutti gateway` on engine `e` inside network namespace `at.0`, on its address `at.1`, with
/// `env` added to its environment.
pub fn netns_gateway(
    at: (&str, &str),
    e: Eng,
    ddf: &str,
    domain_id: u16,
    ns: &str,
    extra: &[&str],
    env: &[(&str, &str)],
) -> Proc {
    let mut cmd = Command::new("ip");
    cmd.args(["netns", "exec", at.0]).arg(tutti_test_support::tutti_exe());
    cmd.envs(env.iter().copied());
    let args: Vec<&str> = ["--dds", e.name].into_iter().chain(extra.iter().copied()).collect();
    start_gateway(cmd, ddf, domain_id, ns, at.1, &args)
}

impl Drop for NetnsPair {
    fn drop(&mut self) {
        // Deleting a namespace deletes its end of the veth pair, and with it the other end.
        for n in &self.names {
            let _ = Command::new("ip").args(["netns", "del", n]).status();
        }
    }
}

/// A network namespace whose loopback loses `percent` % of the UDP datagrams it receives (an
/// nftables rule that draws at random, as a loaded machine's full socket buffers lose them),
/// removed on drop. Shared memory and pids are the test's.
pub struct LossyNetns {
    pub name: String,
}

impl LossyNetns {
    /// Creates it, named after `tag` and this process; Err with the reason where this machine
    /// does not let the test (no root, no `ip` or `nft`).
    pub fn create(tag: &str, percent: u8) -> Result<LossyNetns, SetupError> {
        let name = format!("tutti-{}-{tag}", std::process::id());
        run_tool("ip", &["netns", "add", &name])?;
        let net = LossyNetns { name };
        let n = net.name.as_str();
        run_tool("ip", &["-n", n, "link", "set", "lo", "up", "multicast", "on"])?;
        run_tool("ip", &["-n", n, "route", "add", "224.0.0.0/4", "dev", "lo"])?;
        let drop = format!("add rule inet tutti input meta l4proto udp numgen random mod 100 < {percent} drop");
        for rule in [
            "add table inet tutti",
            "add chain inet tutti input { type filter hook input priority 0; policy accept; }",
            drop.as_str(),
        ] {
            run_tool("ip", &["netns", "exec", n, "nft", rule])?;
        }
        Ok(net)
    }

    /// A command that runs `program` inside the namespace.
    pub fn command(&self, program: &Path) -> Command {
        let mut cmd = Command::new("ip");
        cmd.args(["netns", "exec", &self.name]).arg(program);
        cmd
    }
}

impl Drop for LossyNetns {
    fn drop(&mut self) {
        let _ = Command::new("ip").args(["netns", "del", &self.name]).status();
    }
}

/// The engine a gateway test runs against. Every DDS interop test runs once per DDS engine of
/// the build ([`per_engine!`], over `tutti_engine::for_each_dds_engine!`: the one list of
/// engines, those that speak DDS), each run with a DDS domain and namespace of its own, so
/// that the runs go in parallel.
#[derive(Debug, Clone, Copy)]
pub struct Eng {
    pub name: &'static str,
    /// Its place in the list of engines: it carves the DDS domain ids.
    index: u16,
}

impl Eng {
    pub const CYCLONE: Eng = Eng::of(EngineKind::Cyclone);
    pub const RUSTDDS: Eng = Eng::of(EngineKind::Rustdds);
    pub const ZENOH: Eng = Eng::of(EngineKind::Zenoh);

    /// The test runs of engine `kind`.
    pub const fn of(kind: EngineKind) -> Eng {
        Eng { name: kind.name(), index: kind.index() as u16 }
    }

    /// The DDS domain id of this engine's run of a test numbered `base` (50 ids per engine).
    pub fn dom(self, base: u16) -> u16 {
        base + 50 * self.index
    }

    /// The DDS domain of this engine's run of a test numbered `base` whose runs take
    /// neighbouring ids: `base` for the first engine, `base + 1` for the second.
    pub fn dom_beside(self, base: u16) -> u16 {
        base + self.index
    }

    /// The shared-memory namespace of this engine's run of a test.
    pub fn ns(self, base: &str) -> String {
        format!("{base}{}", &self.name[..2])
    }

    /// `tutti gateway --engine ENGINE DDF` (see [`gateway`]); on Zenoh, connected to the
    /// test binary's router ([`zenoh_router`]) unless `extra` names one.
    pub fn gateway(self, ddf: &str, domain_id: u16, ns: &str, extra: &[&str]) -> Proc {
        let mut args: Vec<&str> = vec!["--engine", self.name];
        if self.name == Eng::ZENOH.name && !extra.contains(&"--zenoh-connect") {
            args.extend(["--zenoh-connect", zenoh_router().endpoint()]);
        }
        args.extend(extra.iter().copied());
        gateway(ddf, domain_id, ns, &args)
    }
}

/// The Zenoh router the gateways of [`Eng::gateway`] meet at on the Zenoh engine, one for the
/// whole test binary (as `rmw_zenohd` is one per machine): the tests keep apart by their ROS
/// domain ids, the first chunk of every key and token.
pub fn zenoh_router() -> &'static tutti_test_support::ZenohRouter {
    static ROUTER: std::sync::OnceLock<tutti_test_support::ZenohRouter> = std::sync::OnceLock::new();
    ROUTER.get_or_init(tutti_test_support::ZenohRouter::start)
}

/// Turns each named `fn NAME(e: Eng)` into one test per engine of the build: `NAME::cyclone`,
/// `NAME::rustdds`.
#[macro_export]
macro_rules! per_engine {
    ($($name:ident),* $(,)?) => {$(
        tutti_engine::for_each_dds_engine!(per_engine_tests, $name);
    )*};
}

/// Turns each named `fn NAME(e: Eng)` into one test per engine of the build, Zenoh included
/// (`tutti_engine::for_each_engine!`): the tests whose peers are tutti gateways themselves.
#[macro_export]
macro_rules! per_any_engine {
    ($($name:ident),* $(,)?) => {$(
        tutti_engine::for_each_engine!(per_engine_tests, $name);
    )*};
}

/// [`per_engine!`]'s tests of one function, one per engine `for_each_dds_engine!` lists.
#[macro_export]
macro_rules! per_engine_tests {
    ($name:ident $($engine:ident: $kind:ident),* $(,)?) => {
        mod $name {
            $(
                #[test]
                fn $engine() {
                    super::$name($crate::gateway::Eng::of(tutti_engine::EngineKind::$kind))
                }
            )*
        }
    };
}

/// The Cyclone peer in `mode`.
pub fn peer(py: &Path, name: &str, domain_id: u16, mode: &str, args: &[&str]) -> Proc {
    peer_by(Command::new(py), name, domain_id, mode, args)
}

/// [`peer`] run by `cmd` (the Python, or `ip netns exec NS` before it).
pub fn peer_by(mut cmd: Command, name: &str, domain_id: u16, mode: &str, args: &[&str]) -> Proc {
    cmd.arg(PEER).arg(mode).args(["--domain", &domain_id.to_string()]).args(args);
    Proc::spawn(name, cmd, Duration::from_secs(120))
}

/// The address of a gateway's stats endpoint (started with `--http 127.0.0.1:0`).
pub fn stats_addr(gw: &Proc) -> String {
    let line = gw.wait_line("stats on http://", SECS(30)).unwrap_or_else(|| panic!("{}", gw.dump()));
    line.split("http://").nth(1).and_then(|r| r.split('/').next()).unwrap_or_else(|| panic!("{line}")).to_string()
}

/// The status of `domain` in namespace `ns`, once it is checked that the gateway's remote
/// readers made no participant of it and no connection the framework waits for (a passive
/// observer's only).
pub fn status_without_participants(ns: &str, domain: &str) -> tutti_core::shm::DomainStatus {
    let s = status(ns, domain);
    assert_eq!(s.connection_count, 0, "a remote reader counted as a participant: {:?}", s.connections);
    assert!(
        s.connections.iter().all(|c| !c.sync_reader && !c.writer),
        "a connection the framework waits for: {:?}",
        s.connections
    );
    s
}

/// The last gateway counter `name` printed in a status line.
pub fn counter(p: &Proc, name: &str) -> u64 {
    let key = format!(" {name}=");
    p.lines().iter().rev().find(|l| l.contains(&key)).map_or(0, |l| counter_in(l, name))
}

/// Counter `name` of one status line (0 when the line has none).
pub fn counter_in(line: &str, name: &str) -> u64 {
    let key = format!(" {name}=");
    line.split_once(&key).and_then(|(_, rest)| rest.split_whitespace().next()?.parse().ok()).unwrap_or(0)
}

pub fn model() -> Model {
    tutti_core::ddf::load(tutti_test_support::repo_root().join(DDF)).unwrap()
}

/// Each step's SUBSCRIBE set, as (step, bytes).
pub type Seen = Arc<Mutex<Vec<(u64, Vec<u8>)>>>;

/// Asserts that at least 9 in 10 of the steps in `seen` after `first + 5` were answered in
/// lock-step, as `answered` judges.
pub fn assert_lock_step(seen: &[(u64, Vec<u8>)], first: u64, answered: impl Fn(u64, &[u8]) -> bool) {
    let after: Vec<_> = seen.iter().filter(|(k, _)| *k > first + 5).collect();
    let in_step = after.iter().filter(|(k, b)| answered(*k, b)).count();
    assert!(
        !after.is_empty() && in_step * 10 >= after.len() * 9,
        "{in_step} of {} steps answered in lock-step",
        after.len()
    );
}

/// A framework hosting `model` in namespace `ns`, stepping every `period` in a thread;
/// `publish(step)` gives each step's PUBLISH set of domain `domain`; every step's SUBSCRIBE
/// set is kept as (step, bytes).
pub struct Host {
    pub seen: Seen,
    _stepping: Worker,
}

impl Host {
    pub fn start(ns: &str, domain: &str, period: Duration, publish: impl Fn(u64) -> Vec<u8> + Send + 'static) -> Host {
        Host::start_with(DDF, ns, domain, period, publish)
    }

    /// As [`Host::start`], for the domains of DDF `ddf` (relative to the repo root).
    pub fn start_with(
        ddf: &str,
        ns: &str,
        domain: &str,
        period: Duration,
        publish: impl Fn(u64) -> Vec<u8> + Send + 'static,
    ) -> Host {
        Host::start_opts(ddf, ns, domain, period, Duration::from_millis(500), publish)
    }

    /// As [`Host::start_with`], with the frameworks' step timeout `timeout`.
    pub fn start_opts(
        ddf: &str,
        ns: &str,
        domain: &str,
        period: Duration,
        timeout: Duration,
        publish: impl Fn(u64) -> Vec<u8> + Send + 'static,
    ) -> Host {
        let model = tutti_core::ddf::load(tutti_test_support::repo_root().join(ddf)).unwrap();
        let opts = FrameworkOptions { namespace: ns.into(), timeout, ..Default::default() };
        let mut fw = Framework::create(&model, &opts).expect("framework");
        let seen = Arc::new(Mutex::new(Vec::new()));
        let (v, domain) = (seen.clone(), domain.to_string());
        let stepping = Worker::spawn(move |s| {
            let mut k = 0u64;
            while !s.load(Ordering::Acquire) {
                k += 1;
                for d in fw.domains.iter_mut() {
                    let size = d.info().publish.size as usize;
                    let data = if d.info().name == domain { publish(k) } else { vec![0; size] };
                    if let Ok(r) = d.step(&data, k as f64 * 0.01) {
                        if d.info().name == domain {
                            v.lock().unwrap().push((r.step, d.subscribe().to_vec()));
                        }
                    }
                }
                thread::sleep(period);
            }
        });
        Host { seen, _stepping: stepping }
    }

    /// Waits until some step's SUBSCRIBE set satisfies `f`; returns that step.
    pub fn wait_for(&self, timeout: Duration, f: impl Fn(u64, &[u8]) -> bool) -> Option<u64> {
        tutti_test_support::poll_for(timeout, || {
            self.seen.lock().unwrap().iter().find(|(k, b)| f(*k, b)).map(|(k, _)| *k)
        })
    }
}

pub fn connect(ns: &str, domain: &str) -> Participant {
    let opts = ConnectOptions {
        namespace: ns.into(),
        name: "test-component".into(),
        connect_timeout: Duration::from_secs(15),
        timeout: Duration::from_secs(2),
        skip_wait_to_go: true,
        ..Default::default()
    };
    Participant::connect(domain, opts).expect("connect")
}

pub fn f64_at(b: &[u8], off: usize) -> f64 {
    f64::from_ne_bytes(b[off..off + 8].try_into().unwrap())
}

pub fn leaf_offset(domain: &str, role: Role, path: &str) -> usize {
    model().domain(domain).unwrap().set(role).layout.leaf(path).unwrap().offset as usize
}

/// Parses the JSON lines of a peer's stdout that have `key`.
pub fn json_lines(p: &Proc, key: &str) -> Vec<serde_json::Value> {
    p.lines()
        .iter()
        .filter(|l| !l.starts_with("stderr: "))
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|v| v.get(key).is_some())
        .collect()
}

/// `GET path` from the gateway's stats endpoint: the body.
pub fn http_get(addr: &str, path: &str) -> String {
    use std::io::{Read, Write};
    let mut c = std::net::TcpStream::connect(addr).unwrap_or_else(|e| panic!("{addr}: {e}"));
    c.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    write!(c, "GET {path} HTTP/1.0\r\nHost: {addr}\r\n\r\n").unwrap();
    let mut text = String::new();
    c.read_to_string(&mut text).unwrap();
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or_else(|| panic!("{text}"));
    assert!(head.starts_with("HTTP/1.") && head.contains(" 200 "), "{head}");
    body.to_string()
}
