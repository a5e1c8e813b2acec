//! Valid DDFs: the committed samples pass `tutti check`, `tutti show --json` reports what
//! they describe, both dialects read into the same model, the limits themselves are
//! accepted, and the committed 1,000-domain file is what the generator produces.

use tutti_test_support as common;

use std::path::{Path, PathBuf};

use serde_json::Value;
use tutti_core::ddf::{self, Model};

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

use common::tutti;

#[test]
fn committed_samples_pass_check() {
    for file in ["ddf/paper-figure2.ddf", "ddf/product-sample.ddf", "ddf/multiuav.ddf", "ddf/large-1000.ddf"] {
        let (code, out, err) = tutti(["check", file]);
        assert_eq!(code, 0, "tutti check {file}: {err}");
        assert!(out.starts_with(&format!("{file}: ok (")), "{out}");
        assert!(err.is_empty(), "{err}");
    }
    // Several files in one run.
    let (code, out, _) = tutti(["check", "ddf/paper-figure2.ddf", "ddf/multiuav.ddf"]);
    assert_eq!(code, 0);
    assert_eq!(out.lines().count(), 2);
    assert!(out.contains("ddf/multiuav.ddf: ok (4 domains, 52 items)"), "{out}");
}

fn leaf<'a>(set: &'a Value, path: &str) -> &'a Value {
    set["items"]
        .as_array()
        .expect("items array")
        .iter()
        .find(|l| l["path"] == path)
        .unwrap_or_else(|| panic!("no item {path} in {set}"))
}

#[test]
fn show_json_lists_paths_lengths_and_defaults() {
    let (code, out, err) = tutti(["show", "--json", "ddf/product-sample.ddf"]);
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&out).expect("show --json prints JSON");
    assert_eq!(v["schema"], "tutti-show/1");
    let domains = v["domains"].as_array().expect("domains");
    assert_eq!(domains.len(), 2);
    let feeder = &domains[0];
    assert_eq!(feeder["name"], "grid_feeder");
    assert_eq!(feeder["synchronous"], false);
    assert_eq!(feeder["states"], true);
    assert_eq!(feeder["connection"]["attributes"][0], serde_json::json!(["type", "local"]));
    let sets = feeder["sets"].as_array().expect("sets");
    let (publish, subscribe) = (&sets[0], &sets[1]);
    assert_eq!(publish["role"], "PUBLISH");
    assert_eq!(subscribe["role"], "SUBSCRIBE");

    let paths: Vec<&str> = publish["items"].as_array().unwrap().iter().map(|l| l["path"].as_str().unwrap()).collect();
    assert_eq!(paths, ["breaker_closed", "voltage_abc", "meter/power_kw", "meter/samples"]);
    assert_eq!(leaf(publish, "breaker_closed")["default"], true);
    assert_eq!(leaf(publish, "voltage_abc")["length"], 3);
    assert_eq!(leaf(publish, "voltage_abc")["type"], "float64");
    assert_eq!(leaf(publish, "voltage_abc")["size"], 24);
    assert_eq!(leaf(publish, "meter/power_kw")["type"], "float32");
    assert_eq!(leaf(publish, "meter/samples")["type"], "unsigned int32");
    assert_eq!(leaf(subscribe, "setpoint_kw")["default"], 1.5);
    assert_eq!(leaf(subscribe, "mode")["default"], 0);
    assert_eq!(leaf(publish, "voltage_abc")["default"], Value::Null);
    // C layout on LP64: bool @0, double[3] @8, {float @32, uint32 @36}, size 40.
    let offsets: Vec<u64> =
        publish["items"].as_array().unwrap().iter().map(|l| l["offset"].as_u64().unwrap()).collect();
    assert_eq!(offsets, [0, 8, 32, 36]);
    assert_eq!(publish["size"], 40);
    assert_eq!(publish["align"], 8);
    assert_eq!(subscribe["size"], 16);
    let hash = feeder["layout_hash"].as_str().unwrap();
    assert_eq!(hash.len(), 16);
    assert!(hash.chars().all(|c| c.is_ascii_hexdigit()));
}

fn parse(text: &str) -> Model {
    ddf::parse_str(text, "inline.ddf").unwrap_or_else(|e| panic!("{e}"))
}

/// The model without its source path, for comparing two files.
fn meaning(model: &Model) -> Value {
    let mut v = serde_json::to_value(model).expect("model serialises");
    v.as_object_mut().expect("object").remove("source");
    v
}

const PAPER: &str = r#"<?xml version="1.0" standalone="no" ?>
<orchestra>
<domain name="uav" >
  <synchronous>yes</synchronous>
  <multiplePublishAllowed>no</multiplePublishAllowed>
  <states>no</states>
  <block name="uav/Publish">
    <item name="Autopilot"><type>double</type></item>
    <item name="Mode"><type>int</type></item>
    <item name="Armed"><type>bool</type></item>
  </block>
  <block name="uav/Subscribe">
    <item name="Latitude"><type>double</type></item>
    <item name="Count"><type>uchar</type></item>
  </block>
</domain>
</orchestra>
"#;

const PRODUCT: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<orchestra>
  <domain name="uav">
    <synchronous>YES</synchronous>
    <multiplePublishAllowed>No</multiplePublishAllowed>
    <states>no</states>
    <set name="PUBLISH">
      <item name="Autopilot"><type>float64</type><length>1</length></item>
      <item name="Mode"><type>int32</type></item>
      <item name="Armed"><type>boolean</type><length>1</length></item>
    </set>
    <set name="SUBSCRIBE">
      <item name="Latitude"><type>float64</type></item>
      <item name="Count"><type>unsigned  int8</type></item>
    </set>
  </domain>
</orchestra>
"#;

#[test]
fn both_dialects_read_into_the_same_model() {
    let paper = parse(PAPER);
    let product = parse(PRODUCT);
    assert_eq!(meaning(&paper), meaning(&product));
    assert_eq!(paper.domains[0].layout_hash, product.domains[0].layout_hash);
    // The sets may also come in the other order, and set names are case-insensitive.
    let swapped = PRODUCT
        .replace("<set name=\"PUBLISH\">", "<set name=\"tmp\">")
        .replace("<set name=\"SUBSCRIBE\">", "<set name=\"publish\">")
        .replace("<set name=\"tmp\">", "<set name=\"Subscribe\">");
    let swapped = parse(&swapped);
    assert_eq!(swapped.domains[0].publish.layout.leaves[0].path, "Latitude");
}

#[test]
fn paper_figure2_and_multiuav_have_the_expected_shape() {
    let fig = ddf::load(repo("ddf/paper-figure2.ddf")).expect("paper-figure2.ddf is valid");
    let d = &fig.domains[0];
    assert_eq!(d.name, "multiuav_uav1");
    assert!(d.flags.synchronous && !d.flags.multiple_publish_allowed && !d.flags.states);
    assert_eq!(d.publish.layout.size, 16);
    assert_eq!(d.subscribe.layout.size, 24);
    let multi = ddf::load(repo("ddf/multiuav.ddf")).expect("multiuav.ddf is valid");
    assert_eq!(multi.domains.len(), 4);
    // Item keys: PUBLISH leaves first, then SUBSCRIBE.
    let uav = &multi.domains[0];
    assert_eq!(uav.item_key(tutti_core::ddf::Role::Publish, "Altitude"), Some(5));
    assert_eq!(uav.item_key(tutti_core::ddf::Role::Subscribe, "Latitude"), Some(7));
    assert_eq!(uav.publish.layout.size, 56);
}

#[test]
fn the_limits_themselves_are_accepted() {
    let name63 = "n".repeat(63);
    let mut bus = String::new();
    for i in 0..16 {
        bus.push_str(&format!("<item name=\"b{i}\"><type>bus</type>\n"));
    }
    bus.push_str("<item name=\"leaf\"><type>int8</type></item>\n");
    bus.push_str(&"</item>\n".repeat(16));
    let text = format!(
        r#"<orchestra><domain name="{name63}"><set name="PUBLISH">
<item name="{name63}"><type>uint8</type><length>65535</length></item>
<item name="lo"><type>int8</type><default>-128</default></item>
<item name="hi"><type>int8</type><default>127</default></item>
<item name="u"><type>uint64</type><default>18446744073709551615</default></item>
<item name="i"><type>long</type><default>-9223372036854775808</default></item>
<item name="f"><type>float</type><default>-3.4e38</default></item>
<item name="b"><type>bool</type><default>NO</default></item>
<item name="c"><type>char</type><length>1</length></item>
<item name="s"><type>short</type></item>
{bus}</set></domain></orchestra>"#
    );
    let model = parse(&text);
    let set = &model.domains[0].publish.layout;
    assert_eq!(set.leaves[0].size, 65535);
    let deepest = set.leaves.last().unwrap();
    assert_eq!(deepest.path.matches('/').count(), 16);
    assert!(deepest.path.ends_with("b15/leaf"));
    let ty = |p: &str| set.leaf(p).unwrap().ty.canonical();
    assert_eq!(ty("i"), "int64");
    assert_eq!(ty("f"), "float32");
    assert_eq!(ty("b"), "boolean");
    assert_eq!(ty("c"), "int8");
    assert_eq!(ty("s"), "int16");
}

#[test]
fn flags_are_optional_and_sets_may_be_absent() {
    let model = parse(r#"<orchestra><domain name="d"/></orchestra>"#);
    let d = &model.domains[0];
    assert!(!d.flags.synchronous && d.flags.multiple_publish_allowed && !d.flags.states);
    assert_eq!(d.publish.layout.size, 0);
    assert_eq!(d.subscribe.layout.leaves.len(), 0);
}

#[test]
fn xml_conveniences_are_accepted() {
    // BOM, comments, CDATA, character references and entities in text and attributes.
    let text =
        "\u{feff}<?xml version=\"1.0\"?>\n<!-- c --><orchestra><?pi x?><domain name=\"a&amp;b\"><set name='PUBLISH'>\
                <item name=\"x\"><type><![CDATA[double]]></type><length>&#51;</length><!-- c --></item>\
                </set></domain></orchestra>\n<!-- trailing comment -->\n";
    let model = parse(text);
    assert_eq!(model.domains[0].name, "a&b");
    assert_eq!(model.domains[0].publish.layout.leaves[0].length, 3);
}

#[test]
fn committed_large_ddf_is_the_generator_output() {
    let path = repo("ddf/large-1000.ddf");
    let generated = tutti_core::ddf::synth::large_ddf(1000, 20);
    if std::env::var_os("TUTTI_REGENERATE").is_some() {
        std::fs::write(&path, &generated).expect("write ddf/large-1000.ddf");
    }
    let committed = std::fs::read_to_string(&path).expect("read ddf/large-1000.ddf");
    assert!(
        committed == generated,
        "ddf/large-1000.ddf differs from synth::large_ddf(1000, 20); regenerate it with \
         TUTTI_REGENERATE=1 cargo test --test cli ddf_valid::committed_large_ddf"
    );
    let model = ddf::load(&path).expect("large-1000.ddf is valid");
    assert_eq!(model.domains.len(), 1000);
    assert!(model.domains.iter().all(|d| d.leaves().count() == 20));
    let (code, out, _) = tutti(["check", "ddf/large-1000.ddf"]);
    assert_eq!(code, 0);
    assert!(out.contains("(1000 domains, 20000 items)"), "{out}");
}

#[test]
fn show_names_the_dds_engine_and_refuses_an_unknown_one() {
    let engine = |args: &[&str]| -> String {
        let mut cmd = common::tutti_command();
        cmd.args(["show", "--json", "ddf/multiuav.ddf"]).args(args).current_dir(env!("CARGO_MANIFEST_DIR"));
        cmd.env_remove("TUTTI_DDS");
        let (status, out, err) = common::run_with_timeout(cmd, std::time::Duration::from_secs(60));
        assert!(status.success(), "{args:?}: {err}");
        let v: Value = serde_json::from_str(&out).expect("show --json prints JSON");
        v["dds_engine"].as_str().expect("dds_engine").to_string()
    };
    assert_eq!(engine(&[]), "cyclone", "Cyclone is the default engine");
    assert_eq!(engine(&["--dds", "rustdds"]), "rustdds");
    let (code, _, err) = tutti(["show", "ddf/multiuav.ddf", "--dds", "opendds"]);
    assert_eq!(code, 2);
    assert!(err.contains("unknown engine 'opendds'") && err.contains("cyclone, rustdds or zenoh"), "{err}");
    let (code, out, _) = tutti(["show", "ddf/multiuav.ddf", "--dds", "rustdds"]);
    assert_eq!(code, 0);
    assert!(out.lines().next().is_some_and(|l| l.ends_with("engine rustdds")), "{out}");
    assert!(out.contains("    DDS topic rt/multiuav_uav1/publish  type "), "{out}");
    // On Zenoh a set's name on the wire is rmw_zenoh's key, not a DDS topic.
    let (code, out, _) = tutti(["show", "ddf/multiuav.ddf", "--dds", "zenoh"]);
    assert_eq!(code, 0);
    assert!(out.lines().next().is_some_and(|l| l.ends_with("engine zenoh")), "{out}");
    assert!(out.contains("    Zenoh key <ROS domain>/multiuav_uav1/publish/multiuav_msgs::msg::dds_::"), "{out}");
    assert!(!out.contains("DDS topic"), "{out}");
}

#[test]
fn the_rustdds_engine_refuses_unicast_peers_with_status_2() {
    let mut cmd = common::tutti_command();
    cmd.args(["gateway", "tests/gateway/gw.ddf", "--dds", "rustdds", "--peer", "127.0.0.1", "--duration", "5s"])
        .args(["--ros-domain-id", "199", "--interface", "127.0.0.1"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("TUTTI_NAMESPACE", "ddfvalid-peer");
    let (status, _, err) = common::run_with_timeout(cmd, std::time::Duration::from_secs(60));
    assert_eq!(status.code(), Some(2), "{err}");
    assert!(err.contains("--peer") && err.contains("--dds cyclone"), "{err}");
}

/// The three `<connection>` forms the product's tools write are accepted and shown, in text
/// and JSON, with every attribute and setting as written.
#[test]
fn the_three_connection_forms_are_accepted_and_shown() {
    let (code, out, err) = tutti(["check", "tests/ddf/connection-forms.ddf"]);
    assert_eq!(code, 0, "{out}{err}");
    let (code, out, err) = tutti(["show", "tests/ddf/connection-forms.ddf"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("connection remote card=\"test\" pciindex=\"0\""), "{out}");
    assert!(out.contains("connection dolphin nodeIdFramework=\"0\" segmentId=\"0\""), "{out}");
    assert!(out.contains("connection local extcomm=\"udp\" addrframework=\"\" portframework=\"10000\""), "{out}");
    let (code, out, err) = tutti(["show", "--json", "tests/ddf/connection-forms.ddf"]);
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&out).expect("JSON");
    let c: Vec<&Value> = v["domains"].as_array().unwrap().iter().map(|d| &d["connection"]).collect();
    assert_eq!(c[0]["type"], "local");
    assert_eq!(c[0]["attributes"][3], serde_json::json!(["portframework", "10000"]));
    assert_eq!(c[1]["type"], "remote");
    assert_eq!(c[1]["settings"], serde_json::json!([["card", "test"], ["pciindex", "0"]]));
    assert_eq!(c[2]["type"], "dolphin");
    assert_eq!(c[2]["settings"], serde_json::json!([["nodeIdFramework", "0"], ["segmentId", "0"]]));
}

/// `tutti-bench ddf` outside a checkout times the same 1,000-domain file, generated, and
/// leaves nothing behind.
#[test]
fn bench_ddf_runs_outside_the_checkout() {
    let dir = tempfile::tempdir().unwrap();
    let out = std::process::Command::new(common::workspace_bin("tutti-bench", "tutti-bench"))
        .args(["ddf", "--iterations", "1"])
        .current_dir(dir.path())
        .env("TMPDIR", dir.path())
        .output()
        .unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "{stdout}{stderr}");
    assert!(stdout.contains("1000 domains, 20000 items"), "{stdout}");
    let generated = stderr.split("generated as ").nth(1).map(str::trim).expect("says which file it generated");
    assert!(!std::path::Path::new(generated).exists(), "{generated} left behind");
}
