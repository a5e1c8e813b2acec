//! The launch file: what it holds once checked ([`Launch`]), and how it is read ([`load`]).
//!
//! It is JSON5, as the gateway's config file is, read by the same reader (`tutti_config`)
//! into its keys ([`LaunchKeys`](crate::keys::LaunchKeys)), which refuse unknown keys and
//! check every value where it stands, so that each error has its line and column (see
//! [`crate::keys`]). The file is read twice: once for its shape and its `ddf`, then, with
//! the DDF loaded, again with the checks that need the DDF (a file's keys come in any order,
//! so the DDF may follow the components that name its domains). The keys then become a
//! [`Launch`]: defaults filled in, relative paths resolved.
//!
//! Relative paths (`ddf`, `run`'s program when it has a `/`, `fmu`, `cwd`, `record`,
//! `gateway.config`) are relative to the launch file's directory.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use serde::{Deserialize, Serialize};
use tutti_core::ddf::Model;
use tutti_core::shm::WaitMode;
use tutti_gateway::config::ConfigFile;
use tutti_gateway::GatewayOptions;
use tutti_host::connect::{ConnectionSpec, StepOrder};

use crate::keys::{self, ComponentKeys, FrameworkKeys, What};
use crate::{KeyError, LaunchError};

/// A launch file, checked: everything it names exists and fits.
#[derive(Debug, Clone)]
pub struct Launch {
    /// The launch file, as given.
    pub path: PathBuf,
    /// Its directory: where relative paths start.
    pub dir: PathBuf,
    /// The DDF (resolved) and its model.
    pub ddf: PathBuf,
    pub model: Model,
    pub framework: Framework,
    /// In file order, which is the order they start in.
    pub components: Vec<Component>,
    /// The gateway, if the file has one (see [`crate::gateway`]).
    pub gateway: Option<Gateway>,
    /// `connections`: outputs copied to inputs by the framework at every step
    /// (`tutti_host::connect`).
    pub connections: Vec<ConnectionSpec>,
}

/// The `framework` key: how `tutti host` would step the DDF's domains.
#[derive(Debug, Clone, PartialEq)]
pub struct Framework {
    /// `step` (default 10ms): the simulated time of a step.
    pub step: Duration,
    /// `speed` (default 1): simulated seconds per wall-clock second; a step is released
    /// every `step / speed`. 0 in the file (infinite here): as fast as possible.
    pub speed: f64,
    /// `timeout`: longest wait for a synchronous step's participants (default 1s).
    pub timeout: Duration,
    /// `hold`: participants wait to go until every component has connected.
    pub hold: bool,
    /// `duration` or `steps`: when the run ends by itself (None: at Ctrl-C or a stop).
    pub duration: Option<Duration>,
    pub steps: Option<u64>,
    /// `catch_up`: late steps run back to back instead of being skipped.
    pub catch_up: bool,
    /// `record`: recordings (by extension: `.mcap` or CSV), resolved.
    pub record: Vec<PathBuf>,
    /// `set`: `DOMAIN/ITEM=VALUE` PUBLISH values.
    pub set: Vec<String>,
    /// `wait`: how the framework waits for participants (default `adaptive`).
    pub wait: WaitMode,
    /// `ordering`: how connections are applied within a step (default `delayed`).
    pub ordering: StepOrder,
    /// `checkpoint`: saved every so many steps, its `dir` resolved.
    pub checkpoint: Option<tutti_host::Periodic>,
    /// `wait_for`: (domain, writers) the first step waits for.
    pub wait_for: Vec<(String, usize)>,
}

impl Default for Framework {
    fn default() -> Self {
        Framework {
            step: Duration::from_millis(10),
            speed: 1.0,
            timeout: tutti_core::defaults::STEP_TIMEOUT,
            hold: false,
            duration: None,
            steps: None,
            catch_up: false,
            record: Vec::new(),
            set: Vec::new(),
            wait: WaitMode::adaptive(),
            ordering: StepOrder::Delayed,
            checkpoint: None,
            wait_for: Vec::new(),
        }
    }
}

/// What a component runs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Program {
    /// `run: [PROGRAM, ARGS…]`: the program found (absolute) and its arguments.
    Run { program: PathBuf, args: Vec<String> },
    /// `fmu: FILE`: `tutti fmu run FILE --ddf DDF --domain DOMAIN`, with `params` as its
    /// `--param NAME=VALUE` (parameters and inputs' start values, set before initialisation).
    Fmu { fmu: PathBuf, params: Vec<String> },
}

/// When a component that ended is started again.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Restart {
    /// Never (the default).
    #[default]
    Never,
    /// When it ended with a non-zero status or a signal it was not sent by the supervisor.
    OnFailure,
    /// Whenever it ended by itself.
    Always,
}

/// One entry of `components`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Component {
    /// Unique; names its log file (`NAME.log`) and its output lines (`[NAME] …`).
    pub name: String,
    pub program: Program,
    /// The domain it connects to: it "has connected" once a connection of its process is
    /// in this domain. None: once its process runs.
    pub domain: Option<String>,
    /// Added to the environment it inherits (with `TUTTI_NAMESPACE` set to the run's).
    pub env: BTreeMap<String, String>,
    /// Its working directory (default: the launch file's directory).
    pub cwd: PathBuf,
    pub restart: Restart,
    /// At most this many restarts by the policy (default 3).
    pub max_restarts: u32,
    /// Longest wait for it to connect (default 10s).
    pub connect_timeout: Duration,
    /// `autostart` (default true): started with the run. A component with `autostart:
    /// false` is declared but not started: `tutti ctl start NAME` starts it while the run
    /// goes on, and the run does not wait for it to connect.
    pub autostart: bool,
    /// `stateless` (default false): it keeps no state, and a checkpoint leaves it out.
    pub stateless: bool,
}

/// The `gateway` key: the gateway config file's keys, inline or in `config: FILE`.
#[derive(Debug, Clone)]
pub struct Gateway {
    /// `config: FILE`, resolved, if the keys come from there.
    pub config: Option<PathBuf>,
    /// The keys (the file's, or those written inline).
    pub keys: ConfigFile,
    /// What they make of the DDF (checked against it: sets, QoS against the flags, clock).
    pub options: Box<GatewayOptions>,
}

/// Reads and checks the launch file at `path`.
pub fn load(path: &Path) -> Result<Launch, LaunchError> {
    let text = std::fs::read_to_string(path)
        .map_err(|source| LaunchError::Read { file: path.display().to_string(), source })?;
    parse(&text, path)
}

/// Checks the text of a launch file read from `path` (which names it in messages, and
/// whose directory relative paths start from).
pub fn parse(text: &str, path: &Path) -> Result<Launch, LaunchError> {
    let file = path.display().to_string();
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let dir = std::path::absolute(&dir).unwrap_or(dir);
    // Pass 1: the shape of the file, and where the DDF is.
    let first = keys::read(text, &file, &dir, None)?;
    // Pass 2: with the DDF (or its error, which the `ddf` key then reports where it stands).
    let ddf = dir.join(&first.ddf);
    let model = tutti_core::ddf::load(&ddf).map_err(Arc::new);
    let keys = keys::read(text, &file, &dir, Some((ddf.clone(), model.clone())))?;
    let unplaced = |error| LaunchError::Unplaced { file: file.clone(), error: Box::new(error) };
    // Refused by pass 2 already, at `ddf`.
    let model = model.map_err(|e| unplaced(KeyError::Ddf(e)))?;
    let framework = keys.framework.map(|k| Framework::from_keys(k, &dir)).unwrap_or_default();
    let components = keys
        .components
        .into_iter()
        .map(|k| Component::from_keys(k, &dir))
        .collect::<Result<_, _>>()
        .map_err(unplaced)?;
    Ok(Launch {
        path: path.to_path_buf(),
        dir,
        ddf,
        model,
        framework,
        components,
        gateway: keys.gateway,
        connections: keys.connections,
    })
}

impl Framework {
    /// The framework `k` describes, its relative paths resolved in `dir`.
    fn from_keys(k: FrameworkKeys, dir: &Path) -> Framework {
        let dflt = Framework::default();
        Framework {
            step: k.step.unwrap_or(dflt.step),
            // 0: as fast as the participants go (docs/timing.md).
            speed: k.speed.map(|v| if v == 0.0 { f64::INFINITY } else { v }).unwrap_or(dflt.speed),
            timeout: k.timeout.unwrap_or(dflt.timeout),
            hold: k.hold.unwrap_or(dflt.hold),
            duration: k.duration,
            steps: k.steps,
            catch_up: k.catch_up.unwrap_or(dflt.catch_up),
            record: k.record.iter().map(|p| dir.join(p)).collect(),
            set: k.set,
            wait: k.wait.unwrap_or(dflt.wait),
            ordering: k.ordering.unwrap_or(dflt.ordering),
            checkpoint: k.checkpoint.map(|c| tutti_host::Periodic {
                every: c.every,
                dir: dir.join(c.dir.unwrap_or_else(|| PathBuf::from("checkpoints"))),
                keep: c.keep.unwrap_or(0),
            }),
            wait_for: k.wait_for.into_iter().collect(),
        }
    }
}

impl Component {
    /// The component `k` describes (checked as it was read), its relative paths resolved
    /// in `dir`. The program of `run` is looked for again: gone since the check, it is an
    /// error.
    fn from_keys(k: ComponentKeys, dir: &Path) -> Result<Component, KeyError> {
        let who = format!("component '{}'", k.name);
        let program = match k.what(&who)? {
            What::Run(argv) => {
                let (program, args) = keys::program(&who, argv, dir)?;
                Program::Run { program, args }
            }
            What::Fmu { fmu, .. } => Program::Fmu { fmu: dir.join(fmu), params: k.params.clone().unwrap_or_default() },
        };
        Ok(Component {
            name: k.name,
            program,
            domain: k.domain,
            env: k.env,
            cwd: k.cwd.map(|c| dir.join(c)).unwrap_or_else(|| dir.to_path_buf()),
            restart: k.restart.unwrap_or_default(),
            max_restarts: k.max_restarts.unwrap_or(3),
            connect_timeout: k.connect_timeout.unwrap_or(Duration::from_secs(10)),
            autostart: k.autostart.unwrap_or(true),
            stateless: k.stateless.unwrap_or(false),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::LaunchKeys;

    /// `cosim.ddf`: one synchronous domain, `plant`, a float64 out and a float64 in.
    fn cosim_ddf() -> String {
        tutti_test_support::ddf::one_domain("plant")
            .synchronous()
            .publish("x", "float64")
            .subscribe("y", "float64")
            .text()
    }

    /// A launch file `text` in a directory with the DDF `cosim.ddf`.
    fn check(text: &str) -> (tempfile::TempDir, Result<Launch, LaunchError>) {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("cosim.ddf"), cosim_ddf()).unwrap();
        let path = dir.path().join("run.json5");
        std::fs::write(&path, text).unwrap();
        let r = load(&path);
        (dir, r)
    }

    fn error(text: &str) -> String {
        let (_dir, r) = check(text);
        let e = r.expect_err("the file is refused").to_string();
        e.split_once("run.json5").map(|(_, rest)| rest.to_string()).unwrap_or(e)
    }

    #[test]
    fn connections_are_read_and_a_bad_one_is_refused_where_it_stands() {
        let (_dir, r) = check("{ ddf: \"cosim.ddf\", connections: [\"plant/subscribe/y -> plant/publish/x * 2\"] }");
        let l = r.unwrap();
        assert_eq!(l.connections.len(), 1);
        assert_eq!(l.connections[0].gain, 2.0);
        let e = error("{ ddf: \"cosim.ddf\",\n  connections: [\"plant/subscribe/y -> plant/publish/z\"] }");
        assert!(e.starts_with(":2:16:"), "{e}");
        assert!(e.contains("connections: plant/subscribe/y -> plant/publish/z: no item 'z' in the PUBLISH set"), "{e}");
        let e = error("{ ddf: \"cosim.ddf\", connections: [\"plant/subscribe/y => plant/publish/x\"] }");
        assert!(e.contains("expected FROM -> TO"), "{e}");
        let l = check("{ ddf: \"cosim.ddf\", framework: { ordering: \"feedthrough\" } }").1.unwrap();
        assert_eq!(l.framework.ordering, StepOrder::Feedthrough);
        let e = error("{ ddf: \"cosim.ddf\",\n  framework: { ordering: \"sequential\" } }");
        assert!(e.starts_with(":2:"), "{e}");
        assert!(e.contains("ordering: 'sequential': expected 'delayed' (the default) or 'feedthrough'"), "{e}");
    }

    #[test]
    fn a_whole_file_is_read_with_its_defaults() {
        let (dir, r) = check(
            r#"{
  ddf: "cosim.ddf",
  framework: { step: "1ms", timeout: "2s", hold: true, steps: 30, catch_up: true,
               record: ["run.mcap"], set: ["plant/x=1.5"] },
  components: [
    { name: "a", run: ["sh", "-c", "true"], domain: "plant", env: { K: "1" }, restart: "on-failure", max_restarts: 2 },
    { name: "b", run: ["true"], autostart: false },
  ],
  gateway: { ros_domain_id: 7, clock: "none" },
}"#,
        );
        let l = r.unwrap();
        assert_eq!(l.framework.step, Duration::from_millis(1));
        assert_eq!((l.framework.hold, l.framework.steps, l.framework.catch_up), (true, Some(30), true));
        assert_eq!(l.framework.ordering, StepOrder::Delayed);
        assert_eq!(l.framework.record, vec![l.dir.join("run.mcap")]);
        assert_eq!(l.components.len(), 2);
        let a = &l.components[0];
        assert!(matches!(&a.program, Program::Run { program, args } if program.ends_with("sh") && args.len() == 2));
        assert_eq!((a.restart, a.max_restarts, a.domain.as_deref()), (Restart::OnFailure, 2, Some("plant")));
        assert_eq!(a.cwd, std::path::absolute(dir.path()).unwrap(), "cwd defaults to the file's directory");
        assert_eq!((l.components[1].restart, l.components[1].max_restarts), (Restart::Never, 3));
        assert_eq!((a.autostart, l.components[1].autostart), (true, false));
        assert_eq!(l.framework.speed, 1.0);
        assert_eq!(l.gateway.unwrap().options.ros_domain_id, 7);
    }

    #[test]
    fn mistakes_are_refused_with_their_line_and_column() {
        let e = error("{ ddf: \"cosim.ddf\",\n  framwork: {} }");
        assert!(e.starts_with(":2:3: unknown field `framwork`"), "{e}");
        let e = error("{ ddf: \"cosim.ddf\",\n  components: [ { name: \"a\", run: [\"true\"], domian: \"plant\" } ] }");
        assert!(e.starts_with(":2:45: unknown field `domian`"), "{e}");
        let e = error("{ ddf: \"cosim.ddf\", framework: {\n step: \"soon\" } }");
        assert!(e.starts_with(":2:8:") && e.contains("'soon' is not a duration"), "{e}");
        let e = error("{ ddf: \"cosim.ddf\", framework: { hold: \"yes\" } }");
        assert!(e.starts_with(":1:40:") && e.contains("expected a boolean"), "{e}");
        let e = error("{ ddf: \"cosim.ddf\",\n framework: { duration: \"1s\", steps: 3 } }");
        assert!(e.starts_with(":2:13:") && e.contains("not both"), "{e}");
        let e = error("{ ddf: \"cosim.ddf\", components: [\n { name: \"a\", run: [\"no-such-command-here\"] } ] }");
        assert!(e.starts_with(":2:20:") && e.contains("command 'no-such-command-here' not found on PATH"), "{e}");
        let e = error("{ ddf: \"cosim.ddf\", components: [\n { name: \"a\", run: [\"./missing\"] } ] }");
        assert!(e.starts_with(":2:20:") && e.contains("'./missing' is not an executable file"), "{e}");
        let e =
            error("{ components: [\n { name: \"ctrl\", run: [\"true\"], domain: \"nope\" } ], ddf: \"cosim.ddf\" }");
        assert!(e.starts_with(":2:41:") && e.contains("component 'ctrl': domain 'nope' is not in"), "{e}");
        assert!(e.contains("(its domains: plant)"), "{e}");
        let e = error("{ ddf: \"cosim.ddf\", components: [\n { name: \"a\", run: [\"true\"] },\n { name: \"a\", run: [\"true\"] } ] }");
        assert!(e.starts_with(":3:10:") && e.contains("'a' is given to two components"), "{e}");
        let e = error("{ ddf: \"cosim.ddf\", components: [\n { name: \"a\" } ] }");
        assert!(e.starts_with(":2:2:") && e.contains("component 'a': give `run"), "{e}");
        let e = error("{ ddf: \"cosim.ddf\", components: [\n { name: \"a\", run: [\"true\"], fmu: \"x.fmu\" } ] }");
        assert!(e.starts_with(":2:35:") && e.contains("component 'a': fmu: no file"), "{e}");
        let e = error("{ ddf: \"other.ddf\" }");
        assert!(e.starts_with(":1:8: ddf:"), "{e}");
        let e = error("{ ddf: \"cosim.ddf\", framework: { set: [\"plant/z=1\"] } }");
        assert!(e.starts_with(":1:39:") && e.contains("no item 'z'"), "{e}");
        let e = error("{ ddf: \"cosim.ddf\",\n gateway: { tiemout: \"1s\" } }");
        assert!(e.starts_with(":2:13: unknown field `tiemout`"), "{e}");
        let e = error("{ ddf: \"cosim.ddf\",\n gateway: { config: \"gw.json5\", quiet: true } }");
        assert!(e.starts_with(":2:11:") && e.contains("not both"), "{e}");
        let e = error("{ ddf: \"cosim.ddf\",\n gateway: { clock: \"elsewhere\" } }");
        assert!(e.starts_with(":2:11:") && e.contains("elsewhere"), "{e}");
        let e =
            error("{ ddf: \"cosim.ddf\", components: [ { name: \"a\", run: [\"true\"], restart: \"sometimes\" } ] }");
        assert!(e.contains("unknown variant `sometimes`") && e.contains("`on-failure`"), "{e}");
        let e = error("{ ddf: \"cosim.ddf\", components: [\n { name: \"a\", run: [\"true\"], autostart: \"no\" } ] }");
        assert!(e.starts_with(":2:41:") && e.contains("expected a boolean"), "{e}");
        // An entity of the gateway, checked against the DDF where it stands.
        let e = error(
            "{ ddf: \"cosim.ddf\",\n gateway: { entities: [\n { name: \"b\", domain: \"plant\", set: \"publish\",\n cartesian: { x: \"q\", y: \"x\", z: \"x\" } } ] } }",
        );
        assert!(e.starts_with(":3:2:") && e.contains("entity 'b': domain 'plant' has no publish item 'q'"), "{e}");
        let e = error("{ ddf: \"cosim.ddf\",\n framework: { speed: -4 } }");
        assert!(e.starts_with(":2:22:") && e.contains("speed: -4: must be a positive number"), "{e}");
        let (_dir, l) = check("{ ddf: \"cosim.ddf\", framework: { step: \"50ms\", speed: 4 } }");
        assert_eq!(l.unwrap().framework.speed, 4.0);
        let e = error("{ ddf: \"cosim.ddf\"\n  components: [] }");
        assert!(e.starts_with(":1:8: syntax error"), "{e}");
    }

    #[test]
    fn an_inline_gateway_nested_too_deep_is_refused_where_it_goes_too_deep() {
        let deep = format!(
            "{{ ddf: \"cosim.ddf\",\n gateway: {{ topics: {}1{} }} }}",
            "{a:".repeat(100_000),
            "}".repeat(100_000)
        );
        // The file is level 1, `gateway` 2, and the first `{a:` (column 21, `topics`) 3.
        let col = 21 + (tutti_config::MAX_NESTING + 1 - 3) * 3;
        let e = error(&deep);
        assert_eq!(e, format!(":2:{col}: nested more than 32 deep (a launch file needs 5 levels)"));
    }

    #[test]
    fn keys_written_are_read_back_as_they_were() {
        let keys = LaunchKeys {
            ddf: "cosim.ddf".into(),
            framework: Some(FrameworkKeys {
                step: Some(Duration::from_micros(1500)),
                speed: Some(0.0),
                timeout: Some(Duration::from_secs(2)),
                hold: Some(true),
                duration: Some(Duration::from_millis(2500)),
                catch_up: Some(true),
                record: vec!["run.mcap".into()],
                set: vec!["plant/x=1.5".into()],
                wait: Some(WaitMode::Poll(Duration::from_micros(50))),
                ordering: Some(StepOrder::Feedthrough),
                ..Default::default()
            }),
            components: vec![ComponentKeys {
                name: "a".into(),
                run: Some(vec!["sh".into(), "-c".into(), "true".into()]),
                domain: Some("plant".into()),
                env: BTreeMap::from([("K".into(), "1".into())]),
                cwd: Some(".".into()),
                restart: Some(Restart::OnFailure),
                max_restarts: Some(2),
                connect_timeout: Some(Duration::from_secs(3)),
                autostart: Some(false),
                ..Default::default()
            }],
            gateway: None,
            connections: vec![
                tutti_host::connect::parse_connection("plant/subscribe/y -> plant/publish/x * 2 + -0.5").unwrap()
            ],
        };
        let text = serde_json::to_string_pretty(&keys).unwrap();
        assert!(text.contains("\"step\": \"1ms 500us\"") && text.contains("\"wait\": \"poll:50us\""), "{text}");
        let (dir, r) = check(&text);
        let launch = r.unwrap();
        let again = keys::read(&text, "run.json5", dir.path(), None).unwrap();
        assert_eq!((again.framework, again.components), (keys.framework, keys.components));
        assert_eq!(again.connections, keys.connections);
        assert_eq!(launch.framework.speed, f64::INFINITY);
        assert_eq!(launch.connections, keys.connections);
    }

    #[test]
    fn a_gateway_config_file_is_read_relative_to_the_launch_file() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("cosim.ddf"), cosim_ddf()).unwrap();
        std::fs::write(dir.path().join("gw.json5"), "{ ros_domain_id: 9,\n  tiemout: \"1s\" }").unwrap();
        let path = dir.path().join("run.json5");
        std::fs::write(&path, "{ ddf: \"cosim.ddf\", gateway: { config: \"gw.json5\" } }").unwrap();
        let e = load(&path).unwrap_err().to_string();
        assert!(e.contains("gw.json5:2:3: unknown field `tiemout`"), "{e}");
        std::fs::write(dir.path().join("gw.json5"), "{ ros_domain_id: 9 }").unwrap();
        let g = load(&path).unwrap().gateway.unwrap();
        assert_eq!(
            (g.options.ros_domain_id, g.config),
            (9, Some(std::path::absolute(dir.path().join("gw.json5")).unwrap()))
        );
    }

    #[test]
    fn the_gateway_block_takes_the_security_keys_and_a_keystore_relative_to_the_launch_file() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("cosim.ddf"), cosim_ddf()).unwrap();
        let path = dir.path().join("run.json5");
        let text = "{ ddf: \"cosim.ddf\", gateway: { security_enable: true, security_keystore: \"keys\",\n  \
                    enclave: \"/tutti/gateway\", security_strategy: \"Enforce\" } }";
        std::fs::write(&path, text).unwrap();
        let e = load(&path).unwrap_err().to_string();
        let keys = std::path::absolute(dir.path().join("keys")).unwrap();
        assert!(e.contains(&format!("keystore {}: No such file", keys.display())), "{e}");
        // Permissive: the run goes on unsecured.
        std::fs::write(&path, text.replace("Enforce", "Permissive")).unwrap();
        assert_eq!(load(&path).unwrap().gateway.unwrap().options.security, None);
    }
}
