//! The FMU participant from Rust: one program runs two FMUs (two instances of the FMI 3.0
//! Integrator built from tests/fmu/c) in two domains, one thread each, through the
//! `tutti_fmu` library, while `tutti host` steps both domains. And FMU states (checkpoints,
//! docs/fmu.md): saved and restored by an instance (the C Integrator, the PythonFMU Lag), and
//! by an FMU participant at a framework's request.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::Duration;

use tutti_core::ddf::Value;
use tutti_core::shm::{ConnectOptions, Framework, FrameworkOptions, StateAnswer, StateRequest};
use tutti_fmu::{CallStatus, Fmu, FmuParticipant, Instance, Mapping, RunOptions};
use tutti_test_support::fmu::{
    self as fmu_common, build_integrator, build_lag, build_lag_with, compile_so, libpython, model_description,
    write_zip, PythonFmuOptions,
};
use tutti_test_support::{namespace, run_with_timeout, tutti_command};

const DDF: &str = r#"<orchestra>
  <domain name="int_a"><synchronous>yes</synchronous><multiplePublishAllowed>no</multiplePublishAllowed><states>no</states>
    <set name="PUBLISH"><item name="u"><type>float64</type></item></set>
    <set name="SUBSCRIBE"><item name="y"><type>float64</type></item><item name="steps"><type>int32</type></item></set>
  </domain>
  <domain name="int_b"><synchronous>no</synchronous><multiplePublishAllowed>no</multiplePublishAllowed><states>no</states>
    <set name="PUBLISH"><item name="u"><type>float64</type></item></set>
    <set name="SUBSCRIBE"><item name="integral"><type>float64</type></item><item name="steps"><type>int32</type></item></set>
  </domain>
</orchestra>"#;

#[test]
fn one_program_runs_two_fmus_in_two_domains_through_the_library() {
    let dir = tempfile::tempdir().unwrap();
    let ns = namespace("fmulib");
    let fmu_path = build_integrator(dir.path());
    let ddf = dir.path().join("two.ddf");
    std::fs::write(&ddf, DDF).unwrap();
    let csv = dir.path().join("run.csv");
    let mut host = tutti_command();
    host.arg("host")
        .arg(&ddf)
        // --catch-up: each step is 10 ms of simulated time even on a loaded machine, so 40
        // steps integrate over exactly 0.4 s. --hold: the FMUs connect once the host has
        // published its inputs; an asynchronous FMU that connected first would integrate the
        // defaults (u = 0) in its first step.
        .args(["--step", "10ms", "--catch-up", "--hold", "300ms", "--duration", "3s", "--timeout", "2s", "-q"])
        .args(["--set", "int_a/u=1", "--set", "int_b/u=-2", "--record"])
        .arg(&csv)
        .env("TUTTI_NAMESPACE", &ns);
    let host = thread::spawn(move || run_with_timeout(host, Duration::from_secs(120)));
    let model = tutti_core::ddf::load(&ddf).unwrap();
    let runs: Vec<_> = [("int_a", vec![]), ("int_b", vec![("y".to_string(), "integral".to_string())])]
        .into_iter()
        .map(|(name, explicit)| {
            let domain = model.domain(name).unwrap().clone();
            let (path, ns) = (fmu_path.clone(), ns.clone());
            // An FMU instance stays on the thread that creates it. (Each is unpacked by the
            // fmi crate into a temporary directory of its own, removed when it is dropped.)
            thread::spawn(move || {
                let fmu = Fmu::open(&path).expect("open");
                let mapping = Mapping::build(&fmu.model, &domain, &explicit).expect("mapping");
                let instance = fmu.instantiate(name, &[]).expect("instantiate");
                let opts = RunOptions {
                    connect: ConnectOptions {
                        namespace: ns,
                        name: format!("fmu:{name}"),
                        connect_timeout: Duration::from_secs(20),
                        ..Default::default()
                    },
                    step: Duration::from_millis(10),
                    params: vec![("k".into(), "0.5".into())],
                    max_steps: Some(40),
                };
                let p = FmuParticipant::connect(&fmu.model, instance, &domain, mapping, opts).expect("connect");
                p.run(&AtomicBool::new(false)).expect("run")
            })
        })
        .collect();
    let summaries: Vec<_> = runs.into_iter().map(|t| t.join().expect("FMU thread")).collect();
    let (status, _, err) = host.join().unwrap();
    assert!(status.success(), "tutti host: {err}");
    assert!(summaries.iter().all(|s| s.steps == 40), "{summaries:?}");
    // Each domain's recording (run-DOMAIN.csv) ends with its FMU's last answer:
    // y = 40 steps · 0.01 s · k · u.
    for (domain, item, want) in
        [("int_a", "y", 40.0 * 0.01 * 0.5 * 1.0), ("int_b", "integral", 40.0 * 0.01 * 0.5 * -2.0)]
    {
        let text = std::fs::read_to_string(dir.path().join(format!("run-{domain}.csv"))).unwrap();
        let head: Vec<&str> = text.lines().next().unwrap().split(',').collect();
        let col = head.iter().position(|h| *h == format!("subscribe.{item}")).unwrap();
        let last: f64 = text.lines().last().unwrap().split(',').nth(col).unwrap().parse().unwrap();
        assert!(fmu_common::close(last, want), "{domain}: {item} = {last}, expected {want}");
    }
}

/// The communication step of the state tests.
const H: f64 = 0.01;

/// The input of step `i` of the state tests: it changes every step.
fn input_at(i: u64) -> f64 {
    (i as f64 * 0.7).sin() + 0.25
}

/// An output as bits, so that equal is bit-identical.
fn bits(v: Value) -> u64 {
    match v {
        Value::Float(f) => f.to_bits(),
        Value::Int(i) => i as u64,
        Value::UInt(u) => u,
        Value::Bool(b) => u64::from(b),
    }
}

/// Steps `inst` from step `from` (at time `from·H`) for `n` steps, input `input` set to
/// [`input_at`] each step; `outputs` after each step, as bits.
fn steps(fmu: &Fmu, inst: &mut Instance, input: &str, outputs: &[&str], from: u64, n: u64) -> Vec<Vec<u64>> {
    let var = |name: &str| fmu.model.variable(name).unwrap_or_else(|| panic!("no variable {name}")).clone();
    let (input, outputs): (_, Vec<_>) = (var(input), outputs.iter().map(|o| var(o)).collect());
    (from..from + n)
        .map(|i| {
            inst.set(&input, Value::Float(input_at(i))).unwrap();
            inst.do_step(i as f64 * H, H).unwrap();
            outputs.iter().map(|o| bits(inst.get(o).unwrap())).collect()
        })
        .collect()
}

/// Steps an instance of `fmu` (parameter `param` set) 7 times, saves its state, steps 9 more,
/// restores the state and steps the 9 again: the outputs are bit-identical. A fresh instance
/// (a restarted component: not even initialised) that takes the state continues alike.
fn a_restored_state_continues_bit_identically(
    fmu: &Fmu,
    preload: &[PathBuf],
    param: (&str, f64),
    input: &str,
    outputs: &[&str],
) {
    const N: u64 = 7;
    const M: u64 = 9;
    let mut a = fmu.instantiate("a", preload).expect("instantiate");
    assert!(a.can_save_state(), "{} declares its state capabilities", fmu.model.model_name);
    a.set(fmu.model.variable(param.0).unwrap(), Value::Float(param.1)).unwrap();
    a.enter_initialization(0.0).unwrap();
    a.exit_initialization().unwrap();
    steps(fmu, &mut a, input, outputs, 0, N);
    let saved = a.save_state().expect("save_state");
    let first = steps(fmu, &mut a, input, outputs, N, M);
    assert_ne!(first[0], first[M as usize - 1], "the outputs change from step to step");
    a.restore_state(&saved).expect("restore_state");
    let again = steps(fmu, &mut a, input, outputs, N, M);
    assert_eq!(again, first, "{}: the steps after the restored state differ", fmu.model.model_name);
    let mut b = fmu.instantiate("b", preload).expect("instantiate");
    b.restore_state(&saved).expect("restore_state in a fresh instance");
    let fresh = steps(fmu, &mut b, input, outputs, N, M);
    assert_eq!(fresh, first, "{}: a fresh instance with the state differs", fmu.model.model_name);
}

#[test]
fn the_c_integrator_restores_its_state_bit_identically() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = Fmu::open(build_integrator(dir.path())).unwrap();
    let cs = fmu.model.co_simulation.as_ref().unwrap();
    assert!(cs.can_get_and_set_fmu_state && cs.can_serialize_fmu_state);
    // k (a parameter) is restored too: the fresh instance has its default, 1.
    a_restored_state_continues_bit_identically(&fmu, &[], ("k", 0.5), "u", &["y", "steps", "rising"]);
}

#[test]
fn the_pythonfmu_lag_restores_its_state_bit_identically() {
    let Some(py) = fmu_common::python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let fmu = Fmu::open(build_lag_with(&py, dir.path(), PythonFmuOptions { state: true })).unwrap();
    // tau (a parameter) is restored too: the fresh instance has its default, 0.5.
    let outputs = ["y", "integral", "t", "count", "positive"];
    a_restored_state_continues_bit_identically(&fmu, &[libpython(&py)], ("tau", 0.25), "u", &outputs);
}

#[test]
fn an_fmu_without_the_state_capabilities_says_which_it_lacks() {
    let Some(py) = fmu_common::python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let fmu = Fmu::open(build_lag(&py, dir.path())).unwrap();
    let mut inst = fmu.instantiate("nostate", &[libpython(&py)]).expect("instantiate");
    assert!(!inst.can_save_state());
    let e = inst.save_state().unwrap_err();
    assert_eq!(e.status, CallStatus::Unsupported);
    let text = e.to_string();
    for want in ["FMU 'Lag': saving its state is not possible", "canGetAndSetFMUstate=\"true\"", "canSerializeFMUstate"]
    {
        assert!(text.contains(want), "{text}");
    }
    assert!(text.contains("--handle-state --serialize-state"), "a PythonFMU model is told how: {text}");
    let e = inst.restore_state(b"whatever").unwrap_err();
    assert!(e.to_string().contains("FMU 'Lag': restoring its state is not possible"), "{e}");
}

/// An FMI 2.0 library with every function tutti calls, and `extra` ones.
fn stub_library(dir: &Path, extra: &[&str]) -> Vec<u8> {
    let mut src = String::from("const char *fmi2GetVersion(void) { return \"2.0\"; }\n");
    let required = [
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
    for f in required.iter().chain(extra) {
        src.push_str(&format!("int {f}(void) {{ return 3; }}\n"));
    }
    let so = dir.join("stub.so");
    compile_so(&src, &so);
    std::fs::read(&so).unwrap()
}

#[test]
fn declared_state_capabilities_need_their_functions_at_load_time() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("declared.fmu");
    let md = model_description("stub").replace(
        "modelIdentifier=\"stub\"",
        "modelIdentifier=\"stub\" canGetAndSetFMUstate=\"true\" canSerializeFMUstate=\"true\"",
    );
    let lib = stub_library(dir.path(), &["fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate"]);
    write_zip(&f, &[("modelDescription.xml", md.as_bytes()), ("binaries/linux64/stub.so", &lib)]);
    let e = Fmu::open(&f).unwrap().instantiate("stub", &[]).unwrap_err();
    assert!(e.to_string().contains("does not export fmi2SerializedFMUstateSize"), "{e}");
}

const CHECKPOINT_DDF: &str = r#"<orchestra>
  <domain name="ckpt"><synchronous>yes</synchronous><multiplePublishAllowed>no</multiplePublishAllowed><states>yes</states>
    <set name="PUBLISH"><item name="u"><type>float64</type></item></set>
    <set name="SUBSCRIBE"><item name="y"><type>float64</type></item><item name="steps"><type>int32</type></item></set>
  </domain>
</orchestra>"#;

/// A framework in this process steps an FMU participant (the C Integrator, on a thread of its
/// own) and asks it for its state between two steps; it steps on, has the participant take
/// the state back and steps the same steps again (the same simulated times and inputs): the
/// FMU's answers are bit-identical, and its step count was restored with it. The requests
/// are answered from inside the participant's wait for the next step, so this is also the
/// proof that the state handler and the run loop do not block each other.
#[test]
fn an_fmu_participant_saves_and_restores_its_state_at_the_framework_s_request() {
    const N: u64 = 5;
    const M: u64 = 8;
    let dir = tempfile::tempdir().unwrap();
    let ns = namespace("fmuckpt");
    let path = build_integrator(dir.path());
    let model = tutti_core::ddf::parse_str(CHECKPOINT_DDF, "ckpt.ddf").unwrap();
    let fopts = FrameworkOptions { namespace: ns.clone(), timeout: Duration::from_secs(20), ..Default::default() };
    let mut fw = Framework::create(&model, &fopts).unwrap();
    fw.domains[0].set_period(Duration::from_millis(10));
    let stop = Arc::new(AtomicBool::new(false));
    let domain = model.domain("ckpt").unwrap().clone();
    let fmu_thread = {
        let stop = Arc::clone(&stop);
        thread::spawn(move || {
            let fmu = Fmu::open(&path).expect("open");
            let mapping = Mapping::build(&fmu.model, &domain, &[]).expect("mapping");
            let instance = fmu.instantiate("ckpt", &[]).expect("instantiate");
            let opts = RunOptions {
                connect: ConnectOptions {
                    namespace: ns,
                    name: "fmu:ckpt".into(),
                    connect_timeout: Duration::from_secs(20),
                    timeout: Duration::from_secs(20),
                    ..Default::default()
                },
                step: Duration::from_millis(10),
                params: vec![("k".into(), "0.5".into())],
                max_steps: None,
            };
            let p = FmuParticipant::connect(&fmu.model, instance, &domain, mapping, opts).expect("connect");
            assert!(p.keeps_state());
            p.run(&stop).expect("run")
        })
    };
    // Step i (from 0) at simulated time i·H with input `input_at(i)`; the FMU's answer.
    let step = |fw: &mut Framework, i: u64| -> (u64, i32) {
        let host = &mut fw.domains[0];
        let report = host.step(&input_at(i).to_ne_bytes(), i as f64 * H).unwrap();
        assert_eq!(report.timed_out, 0, "the FMU answered step {i}");
        let sub = host.subscribe();
        (u64::from_ne_bytes(sub[0..8].try_into().unwrap()), i32::from_ne_bytes(sub[8..12].try_into().unwrap()))
    };
    for i in 0..N {
        step(&mut fw, i);
    }
    let conns = fw.domains[0].state_connections();
    let fmu_conn = conns.iter().find(|c| c.name == "fmu:ckpt").expect("the FMU's connection");
    assert!(fmu_conn.keeps_state, "{conns:?}");
    let exchange = |fw: &Framework, kind, bytes: &[u8]| {
        let mut answers = fw.exchange_states(kind, &[vec![(fmu_conn, bytes)]], Duration::from_secs(20)).unwrap();
        answers.remove(0).remove(0)
    };
    let StateAnswer::Saved(saved) = exchange(&fw, StateRequest::Save, &[]) else { panic!("the FMU saved no state") };
    let first: Vec<_> = (N..N + M).map(|i| step(&mut fw, i)).collect();
    assert_eq!(first.last().unwrap().1, (N + M) as i32, "{first:?}");
    assert_eq!(exchange(&fw, StateRequest::Restore, &saved), StateAnswer::Restored);
    let again: Vec<_> = (N..N + M).map(|i| step(&mut fw, i)).collect();
    assert_eq!(again, first, "the steps after the restored state differ");
    stop.store(true, Ordering::Release);
    let summary = fmu_thread.join().expect("FMU thread");
    assert_eq!(summary.steps, N + M, "the step count went back with the state: {summary:?}");
}
