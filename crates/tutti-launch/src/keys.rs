//! The launch file's keys as they are written ([`LaunchKeys`]: its schema), read and written
//! with serde.
//!
//! Reading checks every value where it stands, inside the deserialisation
//! ([`tutti_config::de`]), so that each mistake gets its line and column: an unknown key, a
//! wrong type, a bad duration, a command that cannot be found, a domain the DDF lacks, an
//! FMU that does not fit its domain, two components of one name. The checks that need the
//! launch file's directory, the DDF or the components read so far find them in a context
//! set for the read (by [`crate::parse`]). Writing gives the keys back as the file takes
//! them (`tutti ssp ddf` writes its launch file so).
//!
//! Values stay as written: relative paths are resolved, and defaults filled in, when the
//! keys become a [`Launch`](crate::Launch).

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use serde::de::value::MapAccessDeserializer;
use serde::de::{self, DeserializeSeed, Deserializer, IntoDeserializer, MapAccess, SeqAccess, Visitor};
use serde::{Deserialize, Serialize, Serializer};
use tutti_config::de::then;
use tutti_core::ddf::{DdfError, Model};
use tutti_core::parse::{parse_duration, parse_wait};
use tutti_core::shm::WaitMode;
use tutti_gateway::config::{self as gateway_config, ConfigFile};
use tutti_gateway::GatewayOptions;
use tutti_host::connect::{parse_connection, ConnectionSpec, Connections, StepOrder};

use crate::file::{Gateway, Restart};
use crate::{KeyError, ParamError};

/// What a launch file is, for the reader's messages: it needs 5 levels (the inline
/// gateway's `topics.KEY.qos`).
const LAUNCH_FILE: tutti_config::Kind = tutti_config::Kind { name: "launch file", levels: 5 };

/// A launch file's keys (docs/run.md has each).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LaunchKeys {
    /// The DDF, relative to the launch file's directory.
    #[serde(deserialize_with = "de_ddf")]
    pub ddf: PathBuf,
    #[serde(default, deserialize_with = "de_framework", skip_serializing_if = "Option::is_none")]
    pub framework: Option<FrameworkKeys>,
    /// In file order, which is the order they start in.
    #[serde(default, deserialize_with = "de_components", skip_serializing_if = "Vec::is_empty")]
    pub components: Vec<ComponentKeys>,
    /// The gateway config file's keys, inline or in `config: FILE`, read and checked by the
    /// gateway's own types (which it reads only): it is read, never written.
    #[serde(default, skip_serializing)]
    pub gateway: Option<Gateway>,
    /// `"FROM -> TO [* GAIN] [+ OFFSET]"`, each checked against the DDF.
    #[serde(
        default,
        deserialize_with = "de_connections",
        serialize_with = "ser_connections",
        skip_serializing_if = "Vec::is_empty"
    )]
    pub connections: Vec<ConnectionSpec>,
}

/// The `framework` key: how the DDF's domains are stepped ([`crate::Framework`] has the
/// defaults).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameworkKeys {
    #[serde(
        default,
        deserialize_with = "de_step",
        serialize_with = "ser_duration",
        skip_serializing_if = "Option::is_none"
    )]
    pub step: Option<Duration>,
    /// Simulated seconds per wall-clock second; 0: as fast as possible.
    #[serde(default, deserialize_with = "de_speed", skip_serializing_if = "Option::is_none")]
    pub speed: Option<f64>,
    #[serde(
        default,
        deserialize_with = "de_timeout",
        serialize_with = "ser_duration",
        skip_serializing_if = "Option::is_none"
    )]
    pub timeout: Option<Duration>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hold: Option<bool>,
    #[serde(
        default,
        deserialize_with = "de_duration",
        serialize_with = "ser_duration",
        skip_serializing_if = "Option::is_none"
    )]
    pub duration: Option<Duration>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub steps: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub catch_up: Option<bool>,
    /// Relative to the launch file's directory.
    #[serde(default, deserialize_with = "de_record", skip_serializing_if = "Vec::is_empty")]
    pub record: Vec<PathBuf>,
    /// `DOMAIN/ITEM=VALUE`, each checked against the DDF.
    #[serde(default, deserialize_with = "de_sets", skip_serializing_if = "Vec::is_empty")]
    pub set: Vec<String>,
    #[serde(
        default,
        deserialize_with = "de_wait",
        serialize_with = "ser_wait",
        skip_serializing_if = "Option::is_none"
    )]
    pub wait: Option<WaitMode>,
    #[serde(
        default,
        deserialize_with = "de_ordering",
        serialize_with = "ser_ordering",
        skip_serializing_if = "Option::is_none"
    )]
    pub ordering: Option<StepOrder>,
    /// Save a checkpoint every `every` steps into `dir`, keeping the newest `keep`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checkpoint: Option<CheckpointKeys>,
    /// `{ DOMAIN: N }`: the first step waits until N writers of the domain have connected
    /// (as `tutti host --wait-for DOMAIN=N`): another site's link, a component not launched.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub wait_for: std::collections::BTreeMap<String, usize>,
}

/// The `checkpoint` key of `framework` (docs/run.md, "Checkpoints").
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CheckpointKeys {
    /// Every this many steps (> 0).
    #[serde(deserialize_with = "de_every")]
    pub every: u64,
    /// Relative to the launch file's directory (default `checkpoints`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dir: Option<PathBuf>,
    /// The newest this many are kept (default 0: all).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub keep: Option<usize>,
}

fn de_every<'de, D: Deserializer<'de>>(d: D) -> Result<u64, D::Error> {
    then(d, |n: u64| match n {
        0 => Err(KeyError::CheckpointEvery),
        n => Ok(n),
    })
}

/// One entry of `components` ([`crate::Component`] has the defaults).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ComponentKeys {
    #[serde(deserialize_with = "de_name")]
    pub name: String,
    /// `[PROGRAM, ARGS…]`: with a `/`, a path relative to the launch file's directory;
    /// without, found on PATH.
    #[serde(default, deserialize_with = "de_run", skip_serializing_if = "Option::is_none")]
    pub run: Option<Vec<String>>,
    /// An FMU, relative to the launch file's directory.
    #[serde(default, deserialize_with = "de_fmu", skip_serializing_if = "Option::is_none")]
    pub fmu: Option<PathBuf>,
    #[serde(default, deserialize_with = "de_domain", skip_serializing_if = "Option::is_none")]
    pub domain: Option<String>,
    /// An FMU's `NAME=VALUE`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub params: Option<Vec<String>>,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub env: BTreeMap<String, String>,
    /// Relative to the launch file's directory.
    #[serde(default, deserialize_with = "de_cwd", skip_serializing_if = "Option::is_none")]
    pub cwd: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restart: Option<Restart>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_restarts: Option<u32>,
    #[serde(
        default,
        deserialize_with = "de_connect_timeout",
        serialize_with = "ser_duration",
        skip_serializing_if = "Option::is_none"
    )]
    pub connect_timeout: Option<Duration>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub autostart: Option<bool>,
    /// The component keeps no state: a checkpoint leaves it out and says so.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stateless: Option<bool>,
}

/// What a component runs, as its keys say.
pub(crate) enum What<'a> {
    /// `run: [PROGRAM, ARGS…]`.
    Run(&'a [String]),
    /// `fmu: FILE`, in `domain`.
    Fmu { fmu: &'a Path, domain: &'a str },
}

impl ComponentKeys {
    /// `run`, or `fmu` with its `domain` (and `params`): one of them, and `params` with an
    /// FMU only. `who` names the component in the error.
    pub(crate) fn what(&self, who: &str) -> Result<What<'_>, KeyError> {
        let who = || who.to_string();
        match (&self.run, &self.fmu) {
            (Some(run), None) if self.params.is_none() => Ok(What::Run(run)),
            (None, Some(fmu)) => match &self.domain {
                Some(domain) => Ok(What::Fmu { fmu, domain }),
                None => Err(KeyError::FmuWithoutDomain { who: who() }),
            },
            (Some(_), Some(_)) => Err(KeyError::RunAndFmu { who: who() }),
            (Some(_), None) => Err(KeyError::ParamsWithoutFmu { who: who() }),
            (None, None) => Err(KeyError::NoProgram { who: who() }),
        }
    }
}

/// Reads `text`, the launch file `file` in `dir`, into its keys. Pass 2 of a read
/// ([`crate::parse`]) gives the DDF's path and its model (or why it cannot be loaded, which
/// the `ddf` key then reports where it stands).
pub(crate) fn read(
    text: &str,
    file: &str,
    dir: &Path,
    ddf: Option<(PathBuf, Result<Model, Arc<DdfError>>)>,
) -> Result<LaunchKeys, tutti_config::Error> {
    with_context(Context::new(dir.to_path_buf(), ddf), || tutti_config::from_str(text, file, LAUNCH_FILE))
}

/// The program of `run: [PROGRAM, ARGS…]` (with a `/`, a path relative to `dir`; without,
/// found on PATH) and its arguments. `who` names the component in the error.
pub(crate) fn program(who: &str, argv: &[String], dir: &Path) -> Result<(PathBuf, Vec<String>), KeyError> {
    let Some((program, args)) = argv.split_first() else {
        return Err(KeyError::RunEmpty { who: who.to_string() });
    };
    let found = if program.contains('/') {
        let path = dir.join(program);
        match is_executable(&path) {
            true => path,
            false => return Err(KeyError::NotExecutable { who: who.to_string(), program: program.clone(), path }),
        }
    } else {
        find_on_path(program).ok_or_else(|| KeyError::NotOnPath { who: who.to_string(), program: program.clone() })?
    };
    Ok((found, args.to_vec()))
}

fn is_executable(p: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    p.metadata().is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
}

fn find_on_path(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path).map(|d| d.join(name)).find(|p| is_executable(p))
}

// ---------------------------------------------------------------------------------------
// What the checks need while the file is read: its directory, the DDF, the names so far.

struct Context {
    dir: PathBuf,
    /// Pass 2: the DDF's path and its model, or why it cannot be loaded.
    ddf: Option<(PathBuf, Result<Model, Arc<DdfError>>)>,
    /// The names of the components read so far.
    names: Vec<String>,
    /// The component being read: its index, and its name once read.
    current: (usize, Option<String>),
    /// Pass 2: the model description of the current component's FMU, once `fmu` is read.
    fmu: Option<Box<tutti_fmu::ModelDescription>>,
}

impl Context {
    fn new(dir: PathBuf, ddf: Option<(PathBuf, Result<Model, Arc<DdfError>>)>) -> Self {
        Context { dir, ddf, names: Vec::new(), current: (0, None), fmu: None }
    }

    fn model(&self) -> Option<&Model> {
        self.ddf.as_ref().and_then(|(_, m)| m.as_ref().ok())
    }

    fn resolve(&self, p: impl AsRef<Path>) -> PathBuf {
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

/// `f` on the context of the read under way. Keys read without one ([`LaunchKeys`]
/// deserialised elsewhere than by [`read`]) are checked as pass 1 checks them, in the
/// current directory, each component on its own.
fn ctx<T>(f: impl FnOnce(&mut Context) -> T) -> T {
    CONTEXT.with(|c| match c.borrow_mut().as_mut() {
        Some(ctx) => f(ctx),
        None => f(&mut Context::new(PathBuf::from("."), None)),
    })
}

// ---------------------------------------------------------------------------------------
// The checks, each where its value stands.

fn de_ddf<'de, D: Deserializer<'de>>(d: D) -> Result<PathBuf, D::Error> {
    then(d, |p: String| {
        ctx(|c| match &c.ddf {
            Some((_, Err(e))) => Err(KeyError::Ddf(e.clone())),
            _ => Ok(PathBuf::from(p)),
        })
    })
}

/// `connections: ["plant/subscribe/y -> ctrl/publish/y_meas", …]`, checked against the DDF
/// (a connection that meets a `set` value is refused when the framework is created, before
/// any component starts).
fn de_connections<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<ConnectionSpec>, D::Error> {
    then(d, |list: Vec<String>| {
        let specs =
            list.iter().map(|s| parse_connection(s)).collect::<Result<Vec<_>, _>>().map_err(KeyError::Connections)?;
        ctx(|c| match c.model() {
            Some(m) => Connections::resolve(m, &specs, &[]).map(|_| specs).map_err(KeyError::Connections),
            None => Ok(specs),
        })
    })
}

fn ser_connections<S: Serializer>(list: &[ConnectionSpec], s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(list.iter().map(|c| c.to_string()))
}

fn de_framework<'de, D: Deserializer<'de>>(d: D) -> Result<Option<FrameworkKeys>, D::Error> {
    then(d, |k: FrameworkKeys| match k.duration.is_some() && k.steps.is_some() {
        true => Err(KeyError::DurationAndSteps),
        false => Ok(Some(k)),
    })
}

fn duration(key: &'static str, s: &str) -> Result<Duration, KeyError> {
    parse_duration(s).map_err(|error| KeyError::Duration { key, error })
}

/// A duration as the file takes it (`10ms`, `1s 500ms`).
fn duration_text(d: Duration) -> String {
    humantime::format_duration(d).to_string()
}

fn ser_duration<S: Serializer>(d: &Option<Duration>, s: S) -> Result<S::Ok, S::Error> {
    match d {
        Some(d) => s.serialize_str(&duration_text(*d)),
        None => s.serialize_none(),
    }
}

fn de_step<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Duration>, D::Error> {
    then(d, |s: String| match duration("step", &s)? {
        z if z.is_zero() => Err(KeyError::ZeroStep),
        v => Ok(Some(v)),
    })
}

fn de_speed<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    then(d, |v: f64| match v >= 0.0 && v.is_finite() {
        true => Ok(Some(v)),
        false => Err(KeyError::Speed(v)),
    })
}

fn de_timeout<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Duration>, D::Error> {
    then(d, |s: String| duration("timeout", &s).map(Some))
}

fn de_duration<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Duration>, D::Error> {
    then(d, |s: String| duration("duration", &s).map(Some))
}

fn de_wait<'de, D: Deserializer<'de>>(d: D) -> Result<Option<WaitMode>, D::Error> {
    then(d, |s: String| parse_wait(&s).map(Some).map_err(KeyError::Wait))
}

fn ser_wait<S: Serializer>(w: &Option<WaitMode>, s: S) -> Result<S::Ok, S::Error> {
    match w {
        Some(WaitMode::Block) => s.serialize_str("block"),
        Some(WaitMode::Spin) => s.serialize_str("spin"),
        Some(WaitMode::Poll(d)) => s.serialize_str(&format!("poll:{}", duration_text(*d))),
        Some(WaitMode::Adaptive(d)) => s.serialize_str(&format!("adaptive:{}", duration_text(*d))),
        None => s.serialize_none(),
    }
}

fn de_ordering<'de, D: Deserializer<'de>>(d: D) -> Result<Option<StepOrder>, D::Error> {
    then(d, |s: String| s.parse().map(Some).map_err(KeyError::Ordering))
}

fn ser_ordering<S: Serializer>(o: &Option<StepOrder>, s: S) -> Result<S::Ok, S::Error> {
    match o {
        Some(o) => s.serialize_str(o.as_str()),
        None => s.serialize_none(),
    }
}

fn de_record<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<PathBuf>, D::Error> {
    then(d, |paths: Vec<String>| Ok::<_, KeyError>(paths.into_iter().map(PathBuf::from).collect()))
}

fn de_sets<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<String>, D::Error> {
    then(d, |sets: Vec<String>| {
        ctx(|c| match c.model() {
            Some(m) => tutti_host::Host::check_sets(m, &sets).map(|()| sets).map_err(|e| KeyError::Set(Box::new(e))),
            None => Ok(sets),
        })
    })
}

/// The components, each checked where it stands once its keys are read.
fn de_components<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<ComponentKeys>, D::Error> {
    struct Components;
    impl<'de> Visitor<'de> for Components {
        type Value = Vec<ComponentKeys>;
        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str("a sequence")
        }
        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<ComponentKeys>, A::Error> {
            let mut out = Vec::new();
            while let Some(c) = seq.next_element_seed(Checked)? {
                out.push(c);
            }
            Ok(out)
        }
    }
    struct Checked;
    impl<'de> DeserializeSeed<'de> for Checked {
        type Value = ComponentKeys;
        fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<ComponentKeys, D::Error> {
            ctx(|c| {
                c.current = (c.current.0 + 1, None);
                c.fmu = None;
            });
            then(d, check_component)
        }
    }
    d.deserialize_seq(Components)
}

/// A component's keys together: what it runs, and (pass 2) whether its FMU fits its domain
/// and has the variables of its `params`.
fn check_component(k: ComponentKeys) -> Result<ComponentKeys, KeyError> {
    ctx(|c| {
        let who = c.who();
        let What::Fmu { fmu, domain } = k.what(&who)? else { return Ok(()) };
        let md = c.fmu.take();
        if let (Some(md), Some(m)) = (&md, c.model()) {
            if let Some(dom) = m.domain(domain) {
                tutti_fmu::Mapping::build(md, dom, &[]).map_err(|error| KeyError::Misfit {
                    who: who.clone(),
                    fmu: c.resolve(fmu),
                    domain: domain.to_string(),
                    error: Box::new(error),
                })?;
            }
        }
        for p in k.params.iter().flatten() {
            let Some((name, _)) = p.split_once('=').filter(|(n, _)| !n.trim().is_empty()) else {
                return Err(KeyError::ParamForm { who, param: p.clone() });
            };
            if let (Some(md), true) = (&md, c.model().is_some()) {
                check_param(md, name.trim()).map_err(|why| KeyError::Param {
                    who: who.clone(),
                    param: p.clone(),
                    why,
                })?;
            }
        }
        Ok(())
    })?;
    Ok(k)
}

fn de_name<'de, D: Deserializer<'de>>(d: D) -> Result<String, D::Error> {
    then(d, |name: String| {
        let ok = !name.is_empty()
            && !name.starts_with('.')
            && name.chars().all(|ch| ch.is_ascii_alphanumeric() || matches!(ch, '_' | '-' | '.'));
        if !ok {
            return Err(KeyError::Name(name));
        }
        ctx(|c| {
            if c.names.contains(&name) {
                return Err(KeyError::NameTaken(name));
            }
            c.names.push(name.clone());
            c.current.1 = Some(name.clone());
            Ok(name)
        })
    })
}

fn de_run<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Vec<String>>, D::Error> {
    then(d, |argv: Vec<String>| {
        let (who, dir) = ctx(|c| (c.who(), c.dir.clone()));
        program(&who, &argv, &dir)?;
        Ok::<_, KeyError>(Some(argv))
    })
}

/// An FMU's file; in pass 2 it is opened, and its model description kept for the checks of
/// its component.
fn de_fmu<'de, D: Deserializer<'de>>(d: D) -> Result<Option<PathBuf>, D::Error> {
    then(d, |p: String| {
        let (who, path, pass2) = ctx(|c| (c.who(), c.resolve(&p), c.ddf.is_some()));
        if !path.is_file() {
            return Err(KeyError::NoFmu { who, path });
        }
        if pass2 {
            let fmu =
                tutti_fmu::Fmu::open(&path).map_err(|e| KeyError::Fmu { who: who.clone(), error: Box::new(e) })?;
            fmu.model_identifier().map_err(|e| KeyError::Fmu { who, error: Box::new(e) })?;
            ctx(|c| c.fmu = Some(Box::new(fmu.model)));
        }
        Ok(Some(PathBuf::from(p)))
    })
}

/// Whether `name` is a variable of `md` that `--param` can set (a parameter or an input).
fn check_param(md: &tutti_fmu::ModelDescription, name: &str) -> Result<(), ParamError> {
    use tutti_fmu::Causality;
    let var = md
        .variable(name)
        .ok_or_else(|| ParamError::NoVariable { model: md.model_name.clone(), name: name.to_string() })?;
    match var.causality {
        Causality::Parameter | Causality::Input | Causality::StructuralParameter if var.variability != "constant" => {
            Ok(())
        }
        _ => Err(ParamError::NotSettable {
            name: name.to_string(),
            variability: var.variability.clone(),
            causality: var.causality.as_str(),
        }),
    }
}

fn de_domain<'de, D: Deserializer<'de>>(d: D) -> Result<Option<String>, D::Error> {
    then(d, |domain: String| {
        ctx(|c| match (c.model(), &c.ddf) {
            (Some(m), Some((ddf, _))) if m.domain(&domain).is_none() => Err(KeyError::NoDomain {
                who: c.who(),
                domain,
                ddf: ddf.clone(),
                domains: m.domains.iter().map(|d| d.name.as_str()).collect::<Vec<_>>().join(", "),
            }),
            _ => Ok(Some(domain)),
        })
    })
}

fn de_cwd<'de, D: Deserializer<'de>>(d: D) -> Result<Option<PathBuf>, D::Error> {
    then(d, |p: String| {
        ctx(|c| match c.resolve(&p) {
            dir if dir.is_dir() => Ok(Some(PathBuf::from(p))),
            dir => Err(KeyError::NoCwd { who: c.who(), dir }),
        })
    })
}

fn de_connect_timeout<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Duration>, D::Error> {
    then(d, |s: String| duration("connect_timeout", &s).map(Some))
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
        let (dir, ddf) = ctx(|c| (c.dir.clone(), c.ddf.as_ref().map(|(p, m)| (p.clone(), m.clone().ok()))));
        let model = ddf.as_ref().and_then(|(_, m)| m.clone());
        // With the DDF (pass 2), each entity is checked where it stands.
        let read =
            || ConfigFile::deserialize(MapAccessDeserializer::new(Intercept { inner: map, config: &mut config }));
        let mut keys = match &model {
            Some(m) => gateway_config::with_model(m, read),
            None => read(),
        }?;
        let fail = |e: KeyError| de::Error::custom(e);
        let config = match config {
            Some(_) if keys != ConfigFile::default() => return Err(fail(KeyError::GatewayConfigAndKeys)),
            Some(file) => {
                let path = dir.join(file);
                let load = || gateway_config::load(&path);
                let loaded = match &model {
                    Some(m) => gateway_config::with_model(m, load),
                    None => load(),
                };
                keys = loaded.map_err(|e| fail(KeyError::Gateway(Box::new(e))))?;
                Some(path)
            }
            None => None,
        };
        // A keystore, as every path of a launch file, is relative to the launch file.
        if let Some(ks) = keys.engine.security_keystore.take() {
            keys.engine.security_keystore = Some(dir.join(ks));
        }
        let options = match ddf {
            Some((ddf, Some(model))) => {
                let opts =
                    GatewayOptions::configured(&ddf, model, &keys).map_err(|e| fail(KeyError::Gateway(Box::new(e))))?;
                gateway_config::resolve(&opts).map_err(|e| fail(KeyError::Gateway(Box::new(e))))?;
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
