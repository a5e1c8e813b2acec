//! FMUs that tutti cannot use give a clear error and exit status 2: a file that is not a
//! zip, a zip that is not an FMU, a broken modelDescription.xml, a model-exchange-only FMU,
//! no binary for Linux x86_64, a library missing an FMI function, a mapping that does not
//! fit (type, direction, unknown names), a model identifier that is a path or a start value
//! that is not finite (refused alike by `inspect`, `ddf` and `run`). None of them needs a
//! running framework: every check comes before connecting.

use tutti_test_support as common;
use tutti_test_support::fmu as fmu_common;

use std::path::Path;

use fmu_common::{compile_so, model_description, write_zip};

fn tutti(args: &[&std::ffi::OsStr]) -> (i32, String, String) {
    common::tutti(args)
}

fn os(s: &str) -> &std::ffi::OsStr {
    s.as_ref()
}

/// `tutti fmu run FMU --ddf DDF --domain stub` with a DDF made by `tutti fmu ddf`.
fn run_stub(dir: &Path, fmu: &Path, extra: &[&str]) -> (i32, String, String) {
    let ddf = dir.join("stub.ddf");
    if !ddf.exists() {
        let text = model_description("stub");
        let md_fmu = dir.join("md-only.fmu");
        write_zip(&md_fmu, &[("modelDescription.xml", text.as_bytes())]);
        let (code, _, err) = tutti(&[
            os("fmu"),
            os("ddf"),
            md_fmu.as_os_str(),
            os("--domain"),
            os("stub"),
            os("--out"),
            ddf.as_os_str(),
        ]);
        assert_eq!(code, 0, "{err}");
    }
    let mut args =
        vec![os("fmu"), os("run"), fmu.as_os_str(), os("--ddf"), ddf.as_os_str(), os("--domain"), os("stub")];
    args.extend(extra.iter().map(|s| os(s)));
    args.extend([os("--connect-timeout"), os("200ms")]);
    tutti(&args)
}

#[test]
fn a_file_that_is_not_a_zip_is_refused_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("text.fmu");
    std::fs::write(&f, "not a zip").unwrap();
    for cmd in ["inspect", "ddf"] {
        let (code, _, err) = tutti(&[os("fmu"), os(cmd), f.as_os_str()]);
        assert_eq!(code, 2, "{cmd}: {err}");
        assert!(err.contains("text.fmu") && err.contains("not an FMU") && err.contains("not a zip"), "{err}");
    }
}

#[test]
fn a_zip_without_a_model_description_is_not_an_fmu() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("plain.fmu");
    write_zip(&f, &[("readme.txt", b"hello")]);
    let (code, _, err) = tutti(&[os("fmu"), os("inspect"), f.as_os_str()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("no modelDescription.xml"), "{err}");
}

#[test]
fn a_broken_model_description_is_reported_with_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("broken.fmu");
    let text = model_description("stub").replace("</ModelVariables>", "</ModelVariable>");
    write_zip(&f, &[("modelDescription.xml", text.as_bytes())]);
    let (code, _, err) = tutti(&[os("fmu"), os("inspect"), f.as_os_str()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("broken.fmu: modelDescription.xml:") && err.contains("malformed XML"), "{err}");
    let bad_vr = model_description("stub").replace("valueReference=\"1\"", "valueReference=\"-1\"");
    write_zip(&f, &[("modelDescription.xml", bad_vr.as_bytes())]);
    let (code, _, err) = tutti(&[os("fmu"), os("ddf"), f.as_os_str()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("modelDescription.xml:6:") && err.contains("valueReference=\"-1\""), "{err}");
}

/// Runs every command that opens an FMU (`inspect`, `ddf`, `run`) on `fmu`: each must refuse
/// it with exit 2 and the same message (they share one validation, the model description's
/// parser), which is returned.
fn refused_alike_by_every_command(dir: &Path, fmu: &Path) -> String {
    let mut messages = Vec::new();
    for cmd in ["inspect", "ddf", "run"] {
        let (code, _, err) = match cmd {
            "run" => run_stub(dir, fmu, &[]),
            _ => tutti(&[os("fmu"), os(cmd), fmu.as_os_str()]),
        };
        assert_eq!(code, 2, "tutti fmu {cmd}: {err}");
        let message = err.lines().rfind(|l| !l.trim().is_empty()).unwrap_or_default().to_string();
        assert_eq!(message.matches("modelDescription.xml:").count(), 1, "said once: {message}");
        messages.push((cmd, message));
    }
    for (cmd, message) in &messages[1..] {
        assert_eq!(message, &messages[0].1, "tutti fmu {cmd} and inspect differ");
    }
    messages.swap_remove(0).1
}

#[test]
fn a_model_identifier_that_is_a_path_is_refused_by_inspect_ddf_and_run_alike() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("evil.fmu");
    let text = model_description("../../evil");
    write_zip(&f, &[("modelDescription.xml", text.as_bytes()), ("binaries/linux64/stub.so", b"")]);
    let err = refused_alike_by_every_command(dir.path(), &f);
    assert!(
        err.contains("evil.fmu: modelDescription.xml:3:")
            && err.contains("modelIdentifier=\"../../evil\"")
            && err.contains("not a C identifier"),
        "{err}"
    );
}

#[test]
fn start_values_that_are_not_finite_are_refused_by_inspect_ddf_and_run_alike() {
    let dir = tempfile::tempdir().unwrap();
    for start in ["NaN", "1e999"] {
        let f = dir.path().join(format!("start-{start}.fmu"));
        let text = model_description("stub").replace("<Real start=\"0\"/>", &format!("<Real start=\"{start}\"/>"));
        write_zip(&f, &[("modelDescription.xml", text.as_bytes()), ("binaries/linux64/stub.so", b"")]);
        let err = refused_alike_by_every_command(dir.path(), &f);
        let want = format!("start-{start}.fmu: modelDescription.xml:5:");
        assert!(
            err.contains(&want)
                && err.contains(&format!("variable 'u': start=\"{start}\""))
                && err.contains("not a finite Real"),
            "{err}"
        );
    }
}

#[test]
fn a_model_exchange_only_fmu_cannot_run() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("me.fmu");
    let text = model_description("stub").replace("<CoSimulation", "<ModelExchange");
    write_zip(&f, &[("modelDescription.xml", text.as_bytes()), ("binaries/linux64/stub.so", b"")]);
    let (code, out, err) = tutti(&[os("fmu"), os("inspect"), f.as_os_str()]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("co-simulation:  no"), "{out}");
    let (code, _, err) = run_stub(dir.path(), &f, &[]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("not a co-simulation FMU") && err.contains("only <ModelExchange>"), "{err}");
}

#[test]
fn an_fmu_without_a_linux_binary_names_what_it_has() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("win.fmu");
    let text = model_description("stub");
    write_zip(&f, &[("modelDescription.xml", text.as_bytes()), ("binaries/win64/stub.dll", b"MZ")]);
    let (code, out, err) = tutti(&[os("fmu"), os("inspect"), f.as_os_str(), os("--json")]);
    assert_eq!(code, 0, "{err}");
    let json: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(json["binaries"][0], "binaries/win64/stub.dll");
    let (code, _, err) = run_stub(dir.path(), &f, &[]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("no binary for Linux x86_64")
            && err.contains("binaries/linux64/stub.so")
            && err.contains("win64/stub.dll"),
        "{err}"
    );
}

#[test]
fn a_library_without_the_fmi_functions_is_refused_naming_the_function() {
    let dir = tempfile::tempdir().unwrap();
    let so = dir.path().join("stub.so");
    compile_so("const char *fmi2GetVersion(void) { return \"2.0\"; }\n", &so);
    let f = dir.path().join("nosym.fmu");
    let text = model_description("stub");
    let lib = std::fs::read(&so).unwrap();
    write_zip(&f, &[("modelDescription.xml", text.as_bytes()), ("binaries/linux64/stub.so", &lib)]);
    let (code, _, err) = run_stub(dir.path(), &f, &[]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("does not export fmi2Instantiate") && err.contains("nosym.fmu"), "{err}");
}

#[test]
fn mappings_that_do_not_fit_name_both_sides_before_anything_runs() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("stub.fmu");
    write_zip(&f, &[("modelDescription.xml", model_description("stub").as_bytes())]);
    // u is an input: it reads PUBLISH; y is in SUBSCRIBE.
    let (code, _, err) = run_stub(dir.path(), &f, &["--map", "u=y"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("FMU input 'u'") && err.contains("item 'y'") && err.contains("SUBSCRIBE"), "{err}");
    let (code, _, err) = run_stub(dir.path(), &f, &["--map", "nope=y"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("'nope'") && err.contains("does not exist"), "{err}");
    let (code, _, err) = run_stub(dir.path(), &f, &["--map", "y=absent"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("'absent'") && err.contains("neither set"), "{err}");
    // A float32 item for a Real variable.
    let ddf = dir.path().join("f32.ddf");
    std::fs::write(
        &ddf,
        r#"<orchestra><domain name="stub"><set name="PUBLISH"><item name="u"><type>float32</type></item></set></domain></orchestra>"#,
    )
    .unwrap();
    let (code, _, err) =
        tutti(&[os("fmu"), os("run"), f.as_os_str(), os("--ddf"), ddf.as_os_str(), os("--domain"), os("stub")]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("'u'") && err.contains("Real") && err.contains("float32"), "{err}");
}

#[test]
fn the_generated_ddf_passes_tutti_check_and_maps_inputs_to_publish() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("stub.fmu");
    let text = model_description("stub").replace("name=\"y\"", "name=\"der(y)\"");
    write_zip(&f, &[("modelDescription.xml", text.as_bytes())]);
    let ddf = dir.path().join("out.ddf");
    let (code, _, err) =
        tutti(&[os("fmu"), os("ddf"), f.as_os_str(), os("--synchronous"), os("no"), os("--out"), ddf.as_os_str()]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = tutti(&[os("check"), ddf.as_os_str()]);
    assert_eq!(code, 0, "{err}");
    let model = tutti_core::ddf::load(&ddf).unwrap();
    let d = &model.domains[0];
    assert_eq!(d.name, "stub");
    assert!(!d.flags.synchronous);
    assert_eq!(d.publish.layout.leaves[0].path, "u");
    assert_eq!(d.subscribe.layout.leaves[0].path, "der_y");
    let text = std::fs::read_to_string(&ddf).unwrap();
    assert!(text.contains("fmu variable \"der(y)\""), "{text}");
}
