//! Opening an FMU archive (`Fmu::open`: the zip, `modelDescription.xml`, the binaries it
//! carries) and instantiating it for co-simulation (`Fmu::instantiate`). The calls into the
//! FMU go through the `fmi` crate; what it cannot tell apart (an archive that is not an FMU,
//! no binary for this platform, a missing FMI function) is checked here first, so that every
//! such FMU gets an error that says what is wrong.

use std::io::Read;
use std::path::{Path, PathBuf};

use fmi::traits::FmiImport as _;
use tutti_core::ddf::Value;

pub use crate::call::CallStatus;
use crate::call::{self, FMI2_STATE_FUNCTIONS, FMI3_STATE_FUNCTIONS};
use crate::fmi2::Fmi2Cs;
use crate::fmi3::Fmi3Cs;
use crate::log_capture;
use crate::model::{Causality, FmiVersion, ModelDescription, ModelError, VarType, Variable};

/// Why an FMU cannot be opened or instantiated (the user's FMU is at fault: exit 2).
///
/// The underlying error of `Io` and `Model` is a `cause`, in the message, not a `source`:
/// a chain printed whole (`{:#}`) would say it twice.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    #[error("{path}: {cause}")]
    Io { path: PathBuf, cause: std::io::Error },
    #[error("{path}: not an FMU: {reason}")]
    NotAnFmu { path: PathBuf, reason: String },
    #[error("{path}: {cause}")]
    Model { path: PathBuf, cause: ModelError },
    #[error("{path}: model '{model}' is not a co-simulation FMU (it has no <CoSimulation>{me}); tutti runs co-simulation FMUs only")]
    NotCoSimulation { path: PathBuf, model: String, me: &'static str },
    #[error("{path}: no binary for Linux x86_64: expected {expected} in the archive ({found})")]
    NoBinary { path: PathBuf, expected: String, found: String },
    #[error("{path}: cannot load {library}: {message}{hint}")]
    Library { path: PathBuf, library: String, message: String, hint: String },
    #[error("{path}: {library} does not export {symbol}, which FMI {version} co-simulation requires")]
    MissingSymbol { path: PathBuf, library: String, symbol: String, version: &'static str },
    #[error("{path}: cannot preload {library}: {message}")]
    Preload { path: PathBuf, library: String, message: String },
    #[error("{path}: the fmi crate refused the FMU: {message}")]
    Import { path: PathBuf, message: String },
    #[error("{path}: instantiating model '{model}' failed{log}")]
    Instantiate { path: PathBuf, model: String, log: String },
}

/// An FMU call that returned Error or Fatal (or failed otherwise) while running, or one the
/// FMU does not support ([`CallStatus::Unsupported`]).
#[derive(Debug, thiserror::Error)]
#[error("FMU '{model}': {call}{}{log}", outcome(.status))]
pub struct CallError {
    pub model: String,
    /// The call that failed; with [`CallStatus::Unsupported`], what the FMU cannot do and why.
    pub call: String,
    pub status: CallStatus,
    /// The FMU's log messages since the previous call, one per line, indented.
    pub log: String,
}

/// What [`CallError`] says after the call.
fn outcome(status: &CallStatus) -> String {
    match status {
        CallStatus::Unsupported => String::new(),
        status => format!(" failed with status {status}"),
    }
}

/// Why the libpython a PythonFMU model needs could not be found or loaded.
#[derive(Debug, thiserror::Error)]
enum LibPythonError {
    #[error("running python3: {0}")]
    Run(std::io::Error),
    #[error("python3 failed: {stderr}")]
    Failed { stderr: String },
    #[error("python3 names {}, which is not a file (a Python built without a shared libpython?)", .0.display())]
    NotAFile(PathBuf),
    #[error(transparent)]
    Load(libloading::Error),
}

/// Loads `lib` globally (its symbols resolve the FMU's), for the life of the process.
fn load_global(lib: &Path) -> Result<(), libloading::Error> {
    use libloading::os::unix::{Library, RTLD_GLOBAL, RTLD_NOW};
    // SAFETY: loading a library runs its initialisers; the user asked for exactly this
    // library to be loaded into this process (as `LD_PRELOAD` would), or it is the libpython
    // a PythonFMU model needs.
    let lib = unsafe { Library::open(Some(lib), RTLD_NOW | RTLD_GLOBAL) }?;
    // Kept: the FMU resolves symbols in it.
    std::mem::forget(lib);
    Ok(())
}

/// The shared libpython of the `python3` on PATH, as `sysconfig` names it.
fn libpython() -> Result<PathBuf, LibPythonError> {
    const WHERE: &str = "import sysconfig, os; \
        print(os.path.join(sysconfig.get_config_var('LIBDIR') or '', sysconfig.get_config_var('LDLIBRARY') or ''))";
    let out = std::process::Command::new("python3")
        .args(["-c", WHERE])
        .stdin(std::process::Stdio::null())
        .output()
        .map_err(LibPythonError::Run)?;
    if !out.status.success() {
        return Err(LibPythonError::Failed { stderr: String::from_utf8_lossy(&out.stderr).trim().to_string() });
    }
    let lib = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim());
    if !lib.is_file() {
        return Err(LibPythonError::NotAFile(lib));
    }
    Ok(lib)
}

/// The functions an FMI 2.0 co-simulation FMU must export for tutti.
const FMI2_SYMBOLS: &[&str] = &[
    "fmi2GetVersion",
    "fmi2Instantiate",
    "fmi2FreeInstance",
    "fmi2SetupExperiment",
    "fmi2EnterInitializationMode",
    "fmi2ExitInitializationMode",
    "fmi2Terminate",
    "fmi2GetReal",
    "fmi2GetInteger",
    "fmi2GetBoolean",
    "fmi2SetReal",
    "fmi2SetInteger",
    "fmi2SetBoolean",
    "fmi2DoStep",
];

/// The functions an FMI 3.0 co-simulation FMU must export for tutti, besides the getters and
/// setters of the types its variables have (see [`fmi3_symbols`]).
const FMI3_SYMBOLS: &[&str] = &[
    "fmi3GetVersion",
    "fmi3InstantiateCoSimulation",
    "fmi3FreeInstance",
    "fmi3EnterInitializationMode",
    "fmi3ExitInitializationMode",
    "fmi3Terminate",
    "fmi3DoStep",
];

/// The FMU-state functions of FMI `version`, for the capabilities `md`'s FMU declares
/// (`canGetAndSetFMUstate`: get, set, free; `canSerializeFMUstate`: size, serialize,
/// deserialize): declared, they must be there; undeclared, they are never called.
fn state_symbols(md: &ModelDescription) -> impl Iterator<Item = &'static str> {
    let names: &'static [&'static str; 6] = match md.fmi_version {
        FmiVersion::Fmi2 => &FMI2_STATE_FUNCTIONS,
        FmiVersion::Fmi3 => &FMI3_STATE_FUNCTIONS,
    };
    let cs = md.co_simulation.as_ref();
    let get_set = cs.is_some_and(|cs| cs.can_get_and_set_fmu_state);
    let serialize = cs.is_some_and(|cs| cs.can_serialize_fmu_state);
    let part = |declared: bool, part: &'static [&'static str]| if declared { part } else { &[] };
    part(get_set, &names[..3]).iter().chain(part(serialize, &names[3..])).copied()
}

/// Every FMI 2.0 function tutti may call on `md`'s FMU.
fn fmi2_symbols(md: &ModelDescription) -> Vec<String> {
    FMI2_SYMBOLS.iter().copied().chain(state_symbols(md)).map(String::from).collect()
}

/// Every FMI 3.0 function tutti may call on `md`'s FMU: a missing getter is an error at load
/// time rather than a failed call later.
fn fmi3_symbols(md: &ModelDescription) -> Vec<String> {
    let mut out: Vec<String> = FMI3_SYMBOLS.iter().copied().chain(state_symbols(md)).map(String::from).collect();
    for v in &md.variables {
        let used = matches!(
            v.causality,
            Causality::Input | Causality::Output | Causality::Parameter | Causality::StructuralParameter
        );
        if !used || v.ty.ddf_type(md.fmi_version).is_none() || v.is_array {
            continue;
        }
        let name = match v.ty {
            VarType::Enumeration => "Int64",
            t => t.fmi_name(FmiVersion::Fmi3),
        };
        for f in [format!("fmi3Get{name}"), format!("fmi3Set{name}")] {
            if !out.contains(&f) {
                out.push(f);
            }
        }
    }
    out
}

/// An FMU archive, opened and described.
#[derive(Debug)]
pub struct Fmu {
    pub path: PathBuf,
    pub model: ModelDescription,
    /// The entries under `binaries/` (for messages).
    pub binaries: Vec<String>,
}

impl Fmu {
    /// Opens `path`: a zip with a valid `modelDescription.xml`.
    pub fn open(path: impl AsRef<Path>) -> Result<Fmu, LoadError> {
        let path = path.as_ref().to_path_buf();
        let file = std::fs::File::open(&path).map_err(|cause| LoadError::Io { path: path.clone(), cause })?;
        let mut zip = zip::ZipArchive::new(file)
            .map_err(|e| LoadError::NotAnFmu { path: path.clone(), reason: format!("not a zip archive ({e})") })?;
        let binaries = zip.file_names().filter(|n| n.starts_with("binaries/") && !n.ends_with('/')).map(String::from);
        let mut binaries: Vec<String> = binaries.collect();
        binaries.sort();
        let mut text = String::new();
        {
            let mut entry = zip.by_name("modelDescription.xml").map_err(|_| LoadError::NotAnFmu {
                path: path.clone(),
                reason: "the archive has no modelDescription.xml at its root".into(),
            })?;
            // A model description is kilobytes; refuse to inflate anything absurd.
            (&mut entry).take(64 << 20).read_to_string(&mut text).map_err(|e| LoadError::NotAnFmu {
                path: path.clone(),
                reason: format!("modelDescription.xml cannot be read as UTF-8 text ({e})"),
            })?;
        }
        let model = ModelDescription::parse(&text).map_err(|cause| LoadError::Model { path: path.clone(), cause })?;
        Ok(Fmu { path, model, binaries })
    }

    /// The co-simulation model identifier, or the error for an FMU without co-simulation.
    pub fn model_identifier(&self) -> Result<&str, LoadError> {
        match &self.model.co_simulation {
            Some(cs) => Ok(&cs.model_identifier),
            None => Err(LoadError::NotCoSimulation {
                path: self.path.clone(),
                model: self.model.model_name.clone(),
                me: if self.model.model_exchange { ", only <ModelExchange>" } else { "" },
            }),
        }
    }

    /// The archive path of the shared library for Linux x86_64.
    pub fn binary_entry(&self) -> Result<String, LoadError> {
        let id = self.model_identifier()?;
        let expected = format!("binaries/{}/{id}.so", self.model.fmi_version.platform_folder());
        if self.binaries.contains(&expected) {
            return Ok(expected);
        }
        let found = if self.binaries.is_empty() {
            "it has no binaries at all".to_string()
        } else {
            format!("it has {}", self.binaries.join(", "))
        };
        Err(LoadError::NoBinary { path: self.path.clone(), expected, found })
    }

    /// Checks that this FMU can run here (co-simulation, a binary for this platform), loads
    /// `preload` libraries globally (an FMU that expects its host to provide symbols, such as
    /// a PythonFMU model and libpython), checks the FMI functions and instantiates it.
    pub fn instantiate(&self, instance_name: &str, preload: &[PathBuf]) -> Result<Instance, LoadError> {
        let entry = self.binary_entry()?;
        for lib in preload {
            load_global(lib).map_err(|e| LoadError::Preload {
                path: self.path.clone(),
                library: lib.display().to_string(),
                message: e.to_string(),
            })?;
        }
        let import_err = |e: fmi::Error| LoadError::Import { path: self.path.clone(), message: e.to_string() };
        let inner = match self.model.fmi_version {
            FmiVersion::Fmi2 => {
                let import: fmi::fmi2::import::Fmi2Import = fmi::import::from_path(&self.path).map_err(import_err)?;
                let symbols = fmi2_symbols(&self.model);
                let symbols: Vec<&str> = symbols.iter().map(String::as_str).collect();
                self.check_library(import.archive_path(), &entry, &symbols)?;
                let _ = log_capture::take();
                let binding = import.binding(self.model_identifier()?).map_err(import_err)?;
                let url = import.canonical_resource_path_string();
                let inst = Fmi2Cs::instantiate(binding, instance_name, &self.model.token, &url)
                    .ok_or_else(|| self.instantiate_failed())?;
                Inner::V2 { inst: Box::new(inst), _import: Box::new(import) }
            }
            FmiVersion::Fmi3 => {
                let import: fmi::fmi3::import::Fmi3Import = fmi::import::from_path(&self.path).map_err(import_err)?;
                let symbols = fmi3_symbols(&self.model);
                let symbols: Vec<&str> = symbols.iter().map(String::as_str).collect();
                self.check_library(import.archive_path(), &entry, &symbols)?;
                let _ = log_capture::take();
                let binding = import.binding(self.model_identifier()?).map_err(import_err)?;
                let resources = import.canonical_resource_path_string();
                let inst = Fmi3Cs::instantiate(binding, instance_name, &self.model.token, &resources)
                    .ok_or_else(|| self.instantiate_failed())?;
                Inner::V3 { inst: Box::new(inst), _import: Box::new(import) }
            }
        };
        Ok(Instance { model: self.model.model_name.clone(), inner, no_state: self.no_state_reason() })
    }

    /// Why this FMU cannot save and restore its state (the capabilities it does not declare),
    /// or `None` when it can.
    fn no_state_reason(&self) -> Option<String> {
        let version = self.model.fmi_version;
        let missing = self.model.co_simulation.as_ref().map(|cs| cs.missing_state_capabilities(version))?;
        if missing.is_empty() {
            return None;
        }
        let missing: Vec<String> = missing.iter().map(|m| format!("{m}=\"true\"")).collect();
        let python = self.model.generation_tool.as_deref().is_some_and(|t| t.starts_with("PythonFMU"));
        let hint = if python { " (a PythonFMU model: build it with --handle-state --serialize-state)" } else { "" };
        Some(format!("its modelDescription.xml does not declare {}{hint}", missing.join(" and ")))
    }

    fn instantiate_failed(&self) -> LoadError {
        LoadError::Instantiate { path: self.path.clone(), model: self.model.model_name.clone(), log: log_text() }
    }

    /// Opens the extracted library on its own first: a library that does not load (an
    /// unresolved symbol) or lacks an FMI function is an error here, not a panic later.
    fn check_library(&self, dir: &Path, entry: &str, symbols: &[&str]) -> Result<(), LoadError> {
        let lib_path = dir.join(entry);
        // SAFETY: this is the FMU's own library, which the user asked to run; its
        // initialisers run here as they would when the fmi crate loads it a moment later.
        let open = || unsafe { libloading::Library::new(&lib_path) };
        let python = self.model.generation_tool.as_deref().is_some_and(|t| t.starts_with("PythonFMU"));
        let failed = |e: libloading::Error, hint: String| LoadError::Library {
            path: self.path.clone(),
            library: entry.to_string(),
            message: e.to_string(),
            hint,
        };
        let lib = match open() {
            Ok(lib) => lib,
            // A PythonFMU model expects its host to provide libpython: find the one of the
            // `python3` on PATH (the interpreter the model's embedded Python also finds), load
            // it and try again (docs/fmu.md, PythonFMU models).
            Err(e) if python && e.to_string().contains("undefined symbol") => {
                match libpython().and_then(|lib| load_global(&lib).map(|()| lib).map_err(LibPythonError::Load)) {
                    Ok(libpython) => open().map_err(|e| {
                        let hint = format!(
                            "\nhint: tutti loaded {} (the libpython of the python3 on PATH) for this PythonFMU model; \
                             pass --preload with the libpython of the Python that has the model's dependencies",
                            libpython.display()
                        );
                        failed(e, hint)
                    })?,
                    Err(why) => {
                        let hint = format!(
                            "\nhint: a PythonFMU model needs the host to load libpython, and tutti could not find it \
                             ({why}): put the Python that has the model's dependencies first on PATH, or pass --preload \
                             with its libpython, e.g. --preload \"$(python3 -c 'import sysconfig, os; \
                             print(os.path.join(sysconfig.get_config_var(\"LIBDIR\"), sysconfig.get_config_var(\"LDLIBRARY\")))')\""
                        );
                        return Err(failed(e, hint));
                    }
                }
            }
            Err(e) => return Err(failed(e, String::new())),
        };
        for symbol in symbols {
            // SAFETY: only the symbol's presence is tested; the pointer is never called.
            let found = unsafe { lib.get::<*const std::ffi::c_void>(symbol.as_bytes()) };
            if found.is_err() {
                return Err(LoadError::MissingSymbol {
                    path: self.path.clone(),
                    library: entry.to_string(),
                    symbol: symbol.to_string(),
                    version: self.model.fmi_version.as_str(),
                });
            }
        }
        Ok(())
    }
}

fn log_text() -> String {
    let lines = log_capture::take();
    if lines.is_empty() {
        String::new()
    } else {
        format!("; the FMU's log:\n{}", lines.iter().map(|l| format!("  {l}")).collect::<Vec<_>>().join("\n"))
    }
}

enum Inner {
    // Field order matters: the instance is freed before its import (and its directory) goes.
    V2 { inst: Box<Fmi2Cs>, _import: Box<fmi::fmi2::import::Fmi2Import> },
    V3 { inst: Box<Fmi3Cs>, _import: Box<fmi::fmi3::import::Fmi3Import> },
}

impl std::fmt::Debug for Inner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Inner::V2 { .. } => f.write_str("FMI 2.0 co-simulation instance"),
            Inner::V3 { .. } => f.write_str("FMI 3.0 co-simulation instance"),
        }
    }
}

/// A co-simulation instance of an FMU. Values cross as [`Value`]s, typed by the variable.
#[derive(Debug)]
pub struct Instance {
    model: String,
    inner: Inner,
    /// Why the FMU cannot save and restore its state (`None`: it can).
    no_state: Option<String>,
}

impl Instance {
    fn fail(&self, call: impl Into<String>, status: CallStatus) -> CallError {
        CallError { model: self.model.clone(), call: call.into(), status, log: log_text() }
    }

    /// The FMU's model name (`modelName`).
    pub fn model_name(&self) -> &str {
        &self.model
    }

    /// Whether the FMU can save and restore its state: it declares `canGetAndSetFMUstate` and
    /// `canSerializeFMUstate` (FMI 3.0: `canGetAndSetFMUState`, `canSerializeFMUState`).
    pub fn can_save_state(&self) -> bool {
        self.no_state.is_none()
    }

    /// The error of an FMU that cannot save and restore its state, for `what` it was asked.
    fn no_state(&self, what: &str) -> Result<(), CallError> {
        match &self.no_state {
            None => Ok(()),
            Some(why) => Err(CallError {
                model: self.model.clone(),
                call: format!("{what} is not possible: {why}"),
                status: CallStatus::Unsupported,
                log: String::new(),
            }),
        }
    }

    /// The error of a failed FMU-state call.
    fn state_failed(&self, (call, status): call::StateFailure) -> CallError {
        let names = match self.inner {
            Inner::V2 { .. } => &FMI2_STATE_FUNCTIONS,
            Inner::V3 { .. } => &FMI3_STATE_FUNCTIONS,
        };
        self.fail(names[call as usize], status)
    }

    /// The FMU's state as bytes (`getFMUState`, `serializeFMUState`, `freeFMUState`), which
    /// [`restore_state`](Self::restore_state) takes back, in this instance or another of the
    /// same FMU. An FMU that cannot ([`can_save_state`](Self::can_save_state)) is an error
    /// ([`CallStatus::Unsupported`]) naming the capabilities it does not declare.
    pub fn save_state(&mut self) -> Result<Vec<u8>, CallError> {
        self.no_state("saving its state")?;
        let r = match &mut self.inner {
            Inner::V2 { inst, .. } => call::save_state(inst.as_mut()),
            Inner::V3 { inst, .. } => call::save_state(inst.as_mut()),
        };
        r.map_err(|e| self.state_failed(e))
    }

    /// Takes back a state that [`save_state`](Self::save_state) gave (`deserializeFMUState`,
    /// `setFMUState`, `freeFMUState`): the FMU continues from it. An FMU that cannot is an
    /// error, as for `save_state`.
    pub fn restore_state(&mut self, state: &[u8]) -> Result<(), CallError> {
        self.no_state("restoring its state")?;
        let r = match &mut self.inner {
            Inner::V2 { inst, .. } => call::restore_state(inst.as_mut(), state),
            Inner::V3 { inst, .. } => call::restore_state(inst.as_mut(), state),
        };
        r.map_err(|e| self.state_failed(e))
    }

    /// `setupExperiment` (FMI 2.0) and `enterInitializationMode` at `start`.
    pub fn enter_initialization(&mut self, start: f64) -> Result<(), CallError> {
        match &mut self.inner {
            Inner::V2 { inst, .. } => {
                let r = inst.setup_experiment(start);
                r.map_err(|e| self.fail("fmi2SetupExperiment", e))?;
                let Inner::V2 { inst, .. } = &mut self.inner else { unreachable!() };
                let r = inst.enter_initialization_mode();
                r.map_err(|e| self.fail("fmi2EnterInitializationMode", e))
            }
            Inner::V3 { inst, .. } => {
                let r = inst.enter_initialization_mode(start);
                r.map_err(|e| self.fail("fmi3EnterInitializationMode", e))
            }
        }
    }

    /// `exitInitializationMode`.
    pub fn exit_initialization(&mut self) -> Result<(), CallError> {
        let r = match &mut self.inner {
            Inner::V2 { inst, .. } => inst.exit_initialization_mode(),
            Inner::V3 { inst, .. } => inst.exit_initialization_mode(),
        };
        r.map_err(|e| self.fail("exitInitializationMode", e))
    }

    /// One `doStep` from `t` over `h`.
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<(), CallError> {
        let r = match &mut self.inner {
            Inner::V2 { inst, .. } => inst.do_step(t, h),
            Inner::V3 { inst, .. } => inst.do_step(t, h),
        };
        r.map_err(|e| self.fail(format!("doStep(t={t}, h={h})"), e))
    }

    /// `terminate`; errors are ignored (the instance is going away).
    pub fn terminate(&mut self) {
        match &mut self.inner {
            Inner::V2 { inst, .. } => drop(inst.terminate()),
            Inner::V3 { inst, .. } => drop(inst.terminate()),
        }
    }

    /// Sets `var` to `value` (converted to the variable's type).
    pub fn set(&mut self, var: &Variable, value: Value) -> Result<(), CallError> {
        let r: Result<(), CallStatus> = match &mut self.inner {
            Inner::V2 { inst, .. } => {
                let vr = var.value_reference;
                match var.ty {
                    VarType::Float64 => inst.set_real(vr, value.as_f64()),
                    VarType::Int32 | VarType::Enumeration => inst.set_integer(vr, value.as_i64() as i32),
                    VarType::Boolean => inst.set_boolean(vr, value.as_f64() != 0.0),
                    _ => Err(CallStatus::NotExchanged),
                }
            }
            Inner::V3 { inst, .. } => {
                let vr = var.value_reference;
                match var.ty {
                    VarType::Float64 => inst.set_float64(vr, value.as_f64()),
                    VarType::Float32 => inst.set_float32(vr, value.as_f64() as f32),
                    VarType::Int8 => inst.set_int8(vr, value.as_i64() as i8),
                    VarType::Int16 => inst.set_int16(vr, value.as_i64() as i16),
                    VarType::Int32 => inst.set_int32(vr, value.as_i64() as i32),
                    VarType::Int64 | VarType::Enumeration => inst.set_int64(vr, value.as_i64()),
                    VarType::UInt8 => inst.set_uint8(vr, value.as_u64() as u8),
                    VarType::UInt16 => inst.set_uint16(vr, value.as_u64() as u16),
                    VarType::UInt32 => inst.set_uint32(vr, value.as_u64() as u32),
                    VarType::UInt64 => inst.set_uint64(vr, value.as_u64()),
                    VarType::Boolean => inst.set_boolean(vr, value.as_f64() != 0.0),
                    _ => Err(CallStatus::NotExchanged),
                }
            }
        };
        r.map_err(|e| self.fail(format!("set '{}'", var.name), e))
    }

    /// The value of `var`.
    pub fn get(&mut self, var: &Variable) -> Result<Value, CallError> {
        let r: Result<Value, CallStatus> = match &mut self.inner {
            Inner::V2 { inst, .. } => {
                let vr = var.value_reference;
                match var.ty {
                    VarType::Float64 => inst.get_real(vr).map(Value::Float),
                    VarType::Int32 | VarType::Enumeration => inst.get_integer(vr).map(|v| Value::Int(v.into())),
                    VarType::Boolean => inst.get_boolean(vr).map(Value::Bool),
                    _ => Err(CallStatus::NotExchanged),
                }
            }
            Inner::V3 { inst, .. } => {
                let vr = var.value_reference;
                match var.ty {
                    VarType::Float64 => inst.get_float64(vr).map(Value::Float),
                    VarType::Float32 => inst.get_float32(vr).map(|v| Value::Float(v.into())),
                    VarType::Int8 => inst.get_int8(vr).map(|v| Value::Int(v.into())),
                    VarType::Int16 => inst.get_int16(vr).map(|v| Value::Int(v.into())),
                    VarType::Int32 => inst.get_int32(vr).map(|v| Value::Int(v.into())),
                    VarType::Int64 | VarType::Enumeration => inst.get_int64(vr).map(Value::Int),
                    VarType::UInt8 => inst.get_uint8(vr).map(|v| Value::UInt(v.into())),
                    VarType::UInt16 => inst.get_uint16(vr).map(|v| Value::UInt(v.into())),
                    VarType::UInt32 => inst.get_uint32(vr).map(|v| Value::UInt(v.into())),
                    VarType::UInt64 => inst.get_uint64(vr).map(Value::UInt),
                    VarType::Boolean => inst.get_boolean(vr).map(Value::Bool),
                    _ => Err(CallStatus::NotExchanged),
                }
            }
        };
        r.map_err(|e| self.fail(format!("get '{}'", var.name), e))
    }
}
