//! The FMU participant from Rust: one program runs two FMUs (two instances of the FMI 3.0
//! Integrator built from tests/fmu/c) in two domains, one thread each, through the
//! `tutti_fmu` library, while `tutti host` steps both domains.

use std::sync::atomic::AtomicBool;
use std::thread;
use std::time::Duration;

use tutti_core::shm::ConnectOptions;
use tutti_fmu::{Fmu, FmuParticipant, Mapping, RunOptions};
use tutti_test_support::fmu::{self as fmu_common, build_integrator};
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
