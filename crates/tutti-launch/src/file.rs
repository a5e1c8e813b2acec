//! The launch file: what it holds once checked ([`Launch`]), and how it is read ([`load`]).
//!
//! It is JSON5, as the gateway's config file is, read with serde into types that refuse
//! unknown keys. Every check is made where its value stands, inside the deserialisation, so
//! json5 gives each error its line and column: an unknown key, a wrong type, a bad duration,
//! a command that cannot be found, a domain the DDF lacks, an FMU that does not fit its
//! domain, two components of one name. The file is read twice: once for its shape and its
//! `ddf`, then, with the DDF loaded, again with the checks that need the DDF (a file's keys
//! come in any order, so the DDF may follow the components that name its domains).
//!
//! Relative paths (`ddf`, `run`'s program when it has a `/`, `fmu`, `cwd`, `record`,
//! `gateway.config`) are relative to the launch file's directory.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::fmt;
use std::marker::PhantomData;
use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::de::value::{MapAccessDeserializer, SeqAccessDeserializer};
use serde::de::{self, DeserializeSeed, Deserializer, IntoDeserializer, MapAccess, SeqAccess, Visitor};
use serde::Deserialize;
use tutti_core::ddf::Model;
use tutti_core::parse::{parse_duration, parse_wait};
use tutti_core::shm::WaitMode;
use tutti_gateway::config::{self as gateway_config, ConfigFile};
use tutti_gateway::GatewayOptions;
use tutti_host::connect::{parse_connection, ConnectionSpec, Connections, StepOrder};

use crate::LaunchError;

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
    /// `wait`: how the framework waits for participants (default block).
    pub wait: WaitMode,
    /// `ordering`: how connections are applied within a step (default `delayed`).
    pub ordering: StepOrder,
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
            wait: WaitMode::Block,
            ordering: StepOrder::Delayed,
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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
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
    let first = with_context(Context::new(dir.clone(), None), || from_json5(text, &file))?;
    // Pass 2: with the DDF (or its error, which the `ddf` key then reports where it stands).
    let ddf = first.ddf.clone();
    let model = tutti_core::ddf::load(&ddf).map_err(|e| e.to_string());
    let keys = with_context(Context::new(dir.clone(), Some((ddf.clone(), model))), || {
        from_json5(text, &file).map(FileKeys::with_model)
    })?;
    let model = keys.model.ok_or_else(|| LaunchError::File { file: file.clone(), message: "no DDF".into() })?;
    Ok(Launch {
        path: path.to_path_buf(),
        dir,
        ddf,
        model,
        framework: keys.framework,
        components: keys.components,
        gateway: keys.gateway,
        connections: keys.connections,
    })
}

fn from_json5(text: &str, file: &str) -> Result<FileKeys, LaunchError> {
    json5::from_str::<FileKeys>(text).map_err(|json5::Error::Message { msg, location }| {
        // A syntax error's message is pest's drawing of the line; its last line says what
        // was expected (as the gateway's config file reports it).
        let pest = msg.trim_start().starts_with("-->");
        let message = match msg.lines().rev().find_map(|l| l.trim().strip_prefix("= ")) {
            Some(expected) if pest => format!("syntax error: {expected}"),
            _ => msg,
        };
        match location {
            Some(l) => LaunchError::At { file: file.to_string(), line: l.line, column: l.column, message },
            None => LaunchError::File { file: file.to_string(), message },
        }
    })
}

// ---------------------------------------------------------------------------------------
// What the checks need while the file is read: its directory, the DDF, the names so far.

struct Context {
    dir: PathBuf,
    /// Pass 2: the DDF's path and its model, or why it cannot be loaded.
    ddf: Option<(PathBuf, Result<Model, String>)>,
    /// The names of the components read so far.
    names: Vec<String>,
    /// The component being read: its index, and its name once read.
    current: (usize, Option<String>),
}

impl Context {
    fn new(dir: PathBuf, ddf: Option<(PathBuf, Result<Model, String>)>) -> Self {
        Context { dir, ddf, names: Vec::new(), current: (0, None) }
    }

    fn model(&self) -> Option<&Model> {
        self.ddf.as_ref().and_then(|(_, m)| m.as_ref().ok())
    }

    fn resolve(&self, p: &str) -> PathBuf {
        self.dir.join(p)
    }

    /// `component 'NAME'`, or `component #N` before its name is read.
    fn who(&self) -> String {
        match &self.current.1 {
            Some(n) => format!("component '{n}'"),
            None => format!("component #{}", self.current.0),
        }
    }
}

thread_local! {
    static CONTEXT: RefCell<Option<Context>> = const { RefCell::new(None) };
}

fn with_context<T>(ctx: Context, f: impl FnOnce() -> T) -> T {
    struct Reset;
    impl Drop for Reset {
        fn drop(&mut self) {
            CONTEXT.with(|c| c.borrow_mut().take());
        }
    }
    CONTEXT.with(|c| *c.borrow_mut() = Some(ctx));
    let _reset = Reset;
    f()
}

fn ctx<T>(f: impl FnOnce(&mut Context) -> T) -> T {
    CONTEXT.with(|c| f(c.borrow_mut().as_mut().expect("a launch file is read inside its context")))
}

// ---------------------------------------------------------------------------------------
// Checks where a value stands: `then(d, f)` reads an `R` from the value `d` and passes it
// through `f`; an error of `f` gets the value's position from json5.

struct Then<R, F>(F, PhantomData<R>);

impl<'de, R, T, F> Visitor<'de> for Then<R, F>
where
    R: Deserialize<'de>,
    F: FnOnce(R) -> Result<T, String>,
{
    type Value = T;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a value")
    }
    fn visit_bool<E: de::Error>(self, v: bool) -> Result<T, E> {
        (self.0)(R::deserialize(v.into_deserializer())?).map_err(E::custom)
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> Result<T, E> {
        (self.0)(R::deserialize(v.into_deserializer())?).map_err(E::custom)
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<T, E> {
        (self.0)(R::deserialize(v.into_deserializer())?).map_err(E::custom)
    }
    fn visit_f64<E: de::Error>(self, v: f64) -> Result<T, E> {
        (self.0)(R::deserialize(v.into_deserializer())?).map_err(E::custom)
    }
    fn visit_str<E: de::Error>(self, v: &str) -> Result<T, E> {
        (self.0)(R::deserialize(v.into_deserializer())?).map_err(E::custom)
    }
    fn visit_unit<E: de::Error>(self) -> Result<T, E> {
        (self.0)(R::deserialize(().into_deserializer())?).map_err(E::custom)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<T, A::Error> {
        (self.0)(R::deserialize(SeqAccessDeserializer::new(seq))?).map_err(de::Error::custom)
    }
    fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<T, A::Error> {
        (self.0)(R::deserialize(MapAccessDeserializer::new(map))?).map_err(de::Error::custom)
    }
}

fn then<'de, D, R, T>(d: D, f: impl FnOnce(R) -> Result<T, String>) -> Result<T, D::Error>
where
    D: Deserializer<'de>,
    R: Deserialize<'de>,
{
    d.deserialize_any(Then(f, PhantomData))
}

// ---------------------------------------------------------------------------------------
// The file's keys.

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileKeys {
    #[serde(deserialize_with = "de_ddf")]
    ddf: PathBuf,
    /// Filled by `de_ddf` in pass 2 (not a key).
    #[serde(skip)]
    model: Option<Model>,
    #[serde(default)]
    framework: Framework,
    #[serde(default)]
    components: Vec<Component>,
    #[serde(default)]
    gateway: Option<Gateway>,
    #[serde(default, deserialize_with = "de_connections")]
    connections: Vec<ConnectionSpec>,
}

/// `connections: ["plant/subscribe/y -> ctrl/publish/y_meas", …]`, checked against the DDF
/// (a connection that meets a `set` value is refused when the framework is created, before
/// any component starts).
fn de_connections<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<ConnectionSpec>, D::Error> {
    then(d, |list: Vec<String>| {
        let specs = list
            .iter()
            .map(|s| parse_connection(s))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| format!("connections: {e}"))?;
        ctx(|c| match c.model() {
            Some(m) => Connections::resolve(m, &specs, &[]).map(|_| specs).map_err(|e| format!("connections: {e}")),
            None => Ok(specs),
        })
    })
}

impl FileKeys {
    /// Takes the model from the context (pass 2), once the file is read.
    fn with_model(mut self) -> Self {
        self.model = ctx(|c| c.model().cloned());
        self
    }
}

fn de_ddf<'de, D: Deserializer<'de>>(d: D) -> Result<PathBuf, D::Error> {
    then(d, |p: String| {
        ctx(|c| match &c.ddf {
            None => Ok(c.resolve(&p)),
            Some((path, Ok(_))) => Ok(path.clone()),
            Some((_, Err(e))) => Err(format!("ddf: {e}")),
        })
    })
}

fn duration(key: &'static str) -> impl Fn(String) -> Result<Duration, String> {
    move |s: String| parse_duration(&s).map_err(|e| format!("{key}: {e}"))
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FrameworkKeys {
    #[serde(default, deserialize_with = "de_step")]
    step: Option<Duration>,
    #[serde(default, deserialize_with = "de_speed")]
    speed: Option<f64>,
    #[serde(default, deserialize_with = "de_timeout")]
    timeout: Option<Duration>,
    hold: Option<bool>,
    #[serde(default, deserialize_with = "de_duration")]
    duration: Option<Duration>,
    steps: Option<u64>,
    catch_up: Option<bool>,
    #[serde(default, deserialize_with = "de_record")]
    record: Vec<PathBuf>,
    #[serde(default, deserialize_with = "de_sets")]
    set: Vec<String>,
    #[serde(default, deserialize_with = "de_wait")]
    wait: Option<WaitMode>,
    #[serde(default, deserialize_with = "de_ordering")]
    ordering: Option<StepOrder>,
}

fn de_step<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Duration>, D::Error> {
    then(d, |s: String| match duration("step")(s)? {
        z if z.is_zero() => Err("step: must be longer than 0".into()),
        v => Ok(Some(v)),
    })
}

fn de_speed<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    then(d, |v: f64| {
        if v > 0.0 && v.is_finite() {
            Ok(Some(v))
        } else if v == 0.0 {
            // As fast as the participants go (docs/timing.md).
            Ok(Some(f64::INFINITY))
        } else {
            Err(format!("speed: {v}: must be a positive number of simulated seconds per wall-clock second, or 0 for as fast as possible"))
        }
    })
}

fn de_timeout<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Duration>, D::Error> {
    then(d, |s: String| duration("timeout")(s).map(Some))
}

fn de_duration<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Duration>, D::Error> {
    then(d, |s: String| duration("duration")(s).map(Some))
}

fn de_wait<'de, D: Deserializer<'de>>(d: D) -> Result<Option<WaitMode>, D::Error> {
    then(d, |s: String| parse_wait(&s).map(Some).map_err(|e| format!("wait: {e}")))
}

fn de_ordering<'de, D: Deserializer<'de>>(d: D) -> Result<Option<StepOrder>, D::Error> {
    then(d, |s: String| s.parse().map(Some).map_err(|e| format!("ordering: {e}")))
}

fn de_record<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<PathBuf>, D::Error> {
    then(d, |paths: Vec<String>| Ok(ctx(|c| paths.iter().map(|p| c.resolve(p)).collect())))
}

fn de_sets<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<String>, D::Error> {
    then(d, |sets: Vec<String>| {
        ctx(|c| match c.model() {
            Some(m) => tutti_host::Host::check_sets(m, &sets).map(|()| sets).map_err(|e| format!("set: {e}")),
            None => Ok(sets),
        })
    })
}

impl<'de> Deserialize<'de> for Framework {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        then(d, |k: FrameworkKeys| {
            if k.duration.is_some() && k.steps.is_some() {
                return Err("framework: give `duration` or `steps`, not both".into());
            }
            let dflt = Framework::default();
            Ok(Framework {
                step: k.step.unwrap_or(dflt.step),
                speed: k.speed.unwrap_or(dflt.speed),
                timeout: k.timeout.unwrap_or(dflt.timeout),
                hold: k.hold.unwrap_or(false),
                duration: k.duration,
                steps: k.steps,
                catch_up: k.catch_up.unwrap_or(false),
                record: k.record,
                set: k.set,
                wait: k.wait.unwrap_or(dflt.wait),
                ordering: k.ordering.unwrap_or(dflt.ordering),
            })
        })
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ComponentKeys {
    #[serde(deserialize_with = "de_name")]
    name: String,
    #[serde(default, deserialize_with = "de_run")]
    run: Option<Program>,
    #[serde(default, deserialize_with = "de_fmu")]
    fmu: Option<(PathBuf, Option<Box<tutti_fmu::ModelDescription>>)>,
    #[serde(default, deserialize_with = "de_domain")]
    domain: Option<String>,
    #[serde(default)]
    params: Option<Vec<String>>,
    #[serde(default)]
    env: BTreeMap<String, String>,
    #[serde(default, deserialize_with = "de_cwd")]
    cwd: Option<PathBuf>,
    #[serde(default)]
    restart: Restart,
    max_restarts: Option<u32>,
    #[serde(default, deserialize_with = "de_connect_timeout")]
    connect_timeout: Option<Duration>,
    autostart: Option<bool>,
}

fn de_name<'de, D: Deserializer<'de>>(d: D) -> Result<String, D::Error> {
    then(d, |name: String| {
        let ok = !name.is_empty()
            && !name.starts_with('.')
            && name.chars().all(|ch| ch.is_ascii_alphanumeric() || matches!(ch, '_' | '-' | '.'));
        if !ok {
            return Err(format!(
                "name '{name}': use letters, digits, '_', '-' and '.' (not first): it names the component's log file"
            ));
        }
        ctx(|c| {
            if c.names.contains(&name) {
                return Err(format!("name '{name}' is given to two components: names must be unique"));
            }
            c.names.push(name.clone());
            c.current.1 = Some(name.clone());
            Ok(name)
        })
    })
}

/// The program of `run: [PROGRAM, ARGS…]`: with a `/`, a path (relative to the launch
/// file's directory); without, found on PATH.
fn de_run<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Program>, D::Error> {
    then(d, |argv: Vec<String>| {
        let (who, dir) = ctx(|c| (c.who(), c.dir.clone()));
        let Some((program, args)) = argv.split_first() else {
            return Err(format!(
                "{who}: run: give the program and its arguments, like [\"./controller\", \"--gain\", \"2\"]"
            ));
        };
        let found = if program.contains('/') {
            let p = dir.join(program);
            is_executable(&p).then_some(p).ok_or_else(|| {
                format!("{who}: run: '{program}' is not an executable file ({}; relative paths start at the launch file's directory)", dir.join(program).display())
            })
        } else {
            find_on_path(program).ok_or_else(|| format!("{who}: run: command '{program}' not found on PATH"))
        }?;
        Ok(Some(Program::Run { program: found, args: args.to_vec() }))
    })
}

fn is_executable(p: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    p.metadata().is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
}

fn find_on_path(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path).map(|d| d.join(name)).find(|p| is_executable(p))
}

#[allow(clippy::type_complexity)]
fn de_fmu<'de, D: Deserializer<'de>>(
    d: D,
) -> Result<Option<(PathBuf, Option<Box<tutti_fmu::ModelDescription>>)>, D::Error> {
    then(d, |p: String| {
        let (who, path, pass2) = ctx(|c| (c.who(), c.resolve(&p), c.ddf.is_some()));
        if !path.is_file() {
            return Err(format!("{who}: fmu: no file {}", path.display()));
        }
        if !pass2 {
            return Ok(Some((path, None)));
        }
        let fmu = tutti_fmu::Fmu::open(&path).map_err(|e| format!("{who}: fmu: {e}"))?;
        fmu.model_identifier().map_err(|e| format!("{who}: fmu: {e}"))?;
        Ok(Some((path, Some(Box::new(fmu.model)))))
    })
}

/// Whether `name` is a variable of `md` that `--param` can set (a parameter or an input).
fn check_param(md: &tutti_fmu::ModelDescription, name: &str) -> Result<(), String> {
    use tutti_fmu::Causality;
    let var = md.variable(name).ok_or_else(|| format!("model '{}' has no variable '{name}'", md.model_name))?;
    match var.causality {
        Causality::Parameter | Causality::Input | Causality::StructuralParameter if var.variability != "constant" => {
            Ok(())
        }
        _ => Err(format!("'{name}' is {} {}, not a parameter or an input", var.variability, var.causality.as_str())),
    }
}

fn de_domain<'de, D: Deserializer<'de>>(d: D) -> Result<Option<String>, D::Error> {
    then(d, |domain: String| {
        ctx(|c| match (c.model(), &c.ddf) {
            (Some(m), Some((ddf, _))) if m.domain(&domain).is_none() => {
                let names: Vec<&str> = m.domains.iter().map(|d| d.name.as_str()).collect();
                Err(format!(
                    "{}: domain '{domain}' is not in {} (its domains: {})",
                    c.who(),
                    ddf.display(),
                    names.join(", ")
                ))
            }
            _ => Ok(Some(domain)),
        })
    })
}

fn de_cwd<'de, D: Deserializer<'de>>(d: D) -> Result<Option<PathBuf>, D::Error> {
    then(d, |p: String| {
        ctx(|c| {
            let dir = c.resolve(&p);
            if dir.is_dir() {
                Ok(Some(dir))
            } else {
                Err(format!("{}: cwd: no directory {}", c.who(), dir.display()))
            }
        })
    })
}

fn de_connect_timeout<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Duration>, D::Error> {
    then(d, |s: String| duration("connect_timeout")(s).map(Some))
}

impl<'de> Deserialize<'de> for Component {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        ctx(|c| c.current = (c.current.0 + 1, None));
        then(d, |k: ComponentKeys| {
            let (who, dir) = ctx(|c| (c.who(), c.dir.clone()));
            let program = match (k.run, k.fmu) {
                (Some(run), None) if k.params.is_none() => run,
                (None, Some((fmu, md))) => {
                    let md = md.map(|m| *m);
                    let Some(domain) = &k.domain else {
                        return Err(format!("{who}: an FMU component needs `domain`: the domain it joins"));
                    };
                    if let (Some(md), Some(m)) = (&md, ctx(|c| c.model().cloned())) {
                        if let Some(dom) = m.domain(domain) {
                            tutti_fmu::Mapping::build(md, dom, &[])
                                .map_err(|e| format!("{who}: {} does not fit domain '{domain}': {e}", fmu.display()))?;
                        }
                    }
                    let params = k.params.unwrap_or_default();
                    for p in &params {
                        let Some((name, _)) = p.split_once('=').filter(|(n, _)| !n.trim().is_empty()) else {
                            return Err(format!("{who}: params: '{p}' is not NAME=VALUE"));
                        };
                        if let (Some(md), true) = (&md, ctx(|c| c.model().is_some())) {
                            check_param(md, name.trim()).map_err(|why| format!("{who}: params: '{p}': {why}"))?;
                        }
                    }
                    Program::Fmu { fmu, params }
                }
                (Some(_), Some(_)) => return Err(format!("{who}: give `run` or `fmu`, not both")),
                (Some(_), None) => return Err(format!("{who}: `params` are an FMU's: give them with `fmu`")),
                (None, None) => return Err(format!("{who}: give `run: [PROGRAM, ARGS…]` or `fmu: FILE`")),
            };
            Ok(Component {
                name: k.name,
                program,
                domain: k.domain,
                env: k.env,
                cwd: k.cwd.unwrap_or(dir),
                restart: k.restart,
                max_restarts: k.max_restarts.unwrap_or(3),
                connect_timeout: k.connect_timeout.unwrap_or(Duration::from_secs(10)),
                autostart: k.autostart.unwrap_or(true),
            })
        })
    }
}

// ---------------------------------------------------------------------------------------
// The gateway: `config: FILE`, or the config file's keys inline (read by the gateway's own
// types, so the keys and their checks are the gateway's).

impl<'de> Deserialize<'de> for Gateway {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_map(GatewayVisitor)
    }
}

struct GatewayVisitor;

impl<'de> Visitor<'de> for GatewayVisitor {
    type Value = Gateway;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("the gateway config file's keys, or { config: \"gateway.json5\" }")
    }

    fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<Gateway, A::Error> {
        let mut config: Option<String> = None;
        let mut keys =
            ConfigFile::deserialize(MapAccessDeserializer::new(Intercept { inner: map, config: &mut config }))?;
        let fail = |m: String| de::Error::custom(format!("gateway: {m}"));
        let (dir, ddf) = ctx(|c| (c.dir.clone(), c.ddf.as_ref().map(|(p, m)| (p.clone(), m.clone().ok()))));
        let config = match config {
            Some(_) if keys != ConfigFile::default() => {
                return Err(fail("give `config: FILE` or the config file's keys, not both".into()))
            }
            Some(file) => {
                let path = dir.join(file);
                keys = gateway_config::load(&path).map_err(|e| fail(e.to_string()))?;
                Some(path)
            }
            None => None,
        };
        let options = match ddf {
            Some((ddf, Some(model))) => {
                let opts = GatewayOptions::configured(&ddf, model, &keys).map_err(|e| fail(e.to_string()))?;
                gateway_config::resolve(&opts).map_err(|e| fail(e.to_string()))?;
                opts
            }
            // Pass 1 (or a DDF that did not load, reported at `ddf`): checked in pass 2.
            _ => GatewayOptions::new(PathBuf::new(), Model { source: String::new(), domains: Vec::new() }),
        };
        Ok(Gateway { config, keys, options: Box::new(options) })
    }
}

/// The gateway's keys with `config` taken out (into `config`) on the way.
struct Intercept<'a, A> {
    inner: A,
    config: &'a mut Option<String>,
}

enum Key<K, V> {
    Config(K),
    Other(V),
}

struct KeyOrConfig<K>(K);

impl<'de, K: DeserializeSeed<'de>> DeserializeSeed<'de> for KeyOrConfig<K> {
    type Value = Key<K, K::Value>;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de, K: DeserializeSeed<'de>> Visitor<'de> for KeyOrConfig<K> {
    type Value = Key<K, K::Value>;
    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a key")
    }
    fn visit_str<E: de::Error>(self, v: &str) -> Result<Self::Value, E> {
        if v == "config" {
            Ok(Key::Config(self.0))
        } else {
            self.0.deserialize(v.into_deserializer()).map(Key::Other)
        }
    }
}

impl<'de, A: MapAccess<'de>> MapAccess<'de> for Intercept<'_, A> {
    type Error = A::Error;

    fn next_key_seed<K: DeserializeSeed<'de>>(&mut self, seed: K) -> Result<Option<K::Value>, A::Error> {
        let mut seed = seed;
        loop {
            match self.inner.next_key_seed(KeyOrConfig(seed))? {
                None => return Ok(None),
                Some(Key::Other(v)) => return Ok(Some(v)),
                Some(Key::Config(s)) => {
                    *self.config = Some(self.inner.next_value::<String>()?);
                    seed = s;
                }
            }
        }
    }

    fn next_value_seed<V: DeserializeSeed<'de>>(&mut self, seed: V) -> Result<V::Value, A::Error> {
        self.inner.next_value_seed(seed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DDF: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<orchestra>
  <domain name="plant">
    <synchronous>yes</synchronous>
    <multiplePublishAllowed>yes</multiplePublishAllowed>
    <states>no</states>
    <set name="PUBLISH">
      <item name="x"><type>float64</type><length>1</length></item>
    </set>
    <set name="SUBSCRIBE">
      <item name="y"><type>float64</type><length>1</length></item>
    </set>
  </domain>
</orchestra>
"#;

    /// A launch file `text` in a directory with the DDF `cosim.ddf`.
    fn check(text: &str) -> (tempfile::TempDir, Result<Launch, LaunchError>) {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("cosim.ddf"), DDF).unwrap();
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
        let e = error("{ ddf: \"cosim.ddf\",\n framework: { speed: -4 } }");
        assert!(e.starts_with(":2:22:") && e.contains("speed: -4: must be a positive number"), "{e}");
        let (_dir, l) = check("{ ddf: \"cosim.ddf\", framework: { step: \"50ms\", speed: 4 } }");
        assert_eq!(l.unwrap().framework.speed, 4.0);
        let e = error("{ ddf: \"cosim.ddf\"\n  components: [] }");
        assert!(e.starts_with(":1:8: syntax error"), "{e}");
    }

    #[test]
    fn a_gateway_config_file_is_read_relative_to_the_launch_file() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("cosim.ddf"), DDF).unwrap();
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
}
