//! The gateway's config file as a user meets it: `tutti show DDF --config FILE` (text and
//! JSON) prints the plan, and both `show` and `gateway` refuse a bad file, or a bad ROS 2
//! environment, before anything starts (exit status 2, the file, key and flag named).

use tutti_test_support as common;

use std::path::Path;

use serde_json::Value;

use common::{run_with_timeout, tutti, TIMEOUT};

const EXAMPLE: &str = "examples/gateway.json5";

/// `tutti ARGS` with extra environment variables, and none of those that change the plan.
fn tutti_env(args: &[&str], env: &[(&str, &str)]) -> (i32, String, String) {
    let mut cmd = common::tutti_command();
    cmd.args(args).current_dir(env!("CARGO_MANIFEST_DIR"));
    for v in
        ["TUTTI_DDS", "ROS_DOMAIN_ID", "ROS_LOCALHOST_ONLY", "ROS_AUTOMATIC_DISCOVERY_RANGE", "TUTTI_GATEWAY_INTERFACE"]
    {
        cmd.env_remove(v);
    }
    cmd.envs(env.iter().copied());
    let (status, out, err) = run_with_timeout(cmd, TIMEOUT);
    (status.code().unwrap_or(-1), out, err)
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

#[test]
fn show_config_prints_the_plan_of_the_example() {
    let (code, out, err) = tutti_env(&["show", "ddf/multiuav.ddf", "--config", EXAMPLE], &[]);
    assert_eq!(code, 0, "{err}");
    assert!(out.starts_with("ddf/multiuav.ddf under examples/gateway.json5: 5 of 8 sets bridged, ROS namespace /sim1, node /sim1/tutti_gateway"), "{out}");
    for want in [
        "multiuav_uav1/publish  ->  /sim1/uav1/command\n    DDS topic rt/sim1/uav1/command  type multiuav_msgs::msg::dds_::MultiuavUav1Publish_\n",
        "multiuav_uav1/subscribe  ->  /fleet/uav1/state\n    DDS topic rt/fleet/uav1/state",
        "multiuav_uav2/publish  ->  /sim1/multiuav_uav2/publish\n",
        "    gateway writer QoS: RELIABLE, KEEP_ALL, TRANSIENT_LOCAL depth 1, SHARED\n    gateway reader QoS: RELIABLE, KEEP_ALL, TRANSIENT_LOCAL depth 1, SHARED\n",
        "    out: every sample\n",
        "left out:\n",
        "  multiuav_uav3/publish            matches deny pattern 'multiuav_uav3/publish'\n",
        "  multiuav_uav4/subscribe          matches no allow pattern ('multiuav_uav[1-3]/.*')\n",
    ] {
        assert!(out.contains(want), "missing {want:?} in\n{out}");
    }
}

#[test]
fn show_config_json_has_every_set_and_why_one_is_left_out() {
    let (code, out, err) = tutti_env(&["show", "ddf/multiuav.ddf", "--config", EXAMPLE, "--json"], &[]);
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(v["schema"], "tutti-gateway-plan/1");
    assert_eq!((v["ros_namespace"].as_str(), v["node"].as_str()), (Some("sim1"), Some("/sim1/tutti_gateway")));
    assert_eq!((v["qos_profile"].as_str(), v["dds_engine"].as_str()), (Some("ros2"), Some("cyclone")));
    let sets = v["sets"].as_array().unwrap();
    let left = v["left_out"].as_array().unwrap();
    assert_eq!((sets.len(), left.len()), (5, 3));
    let uav1 = sets.iter().find(|s| s["key"] == "multiuav_uav1/subscribe").unwrap();
    assert_eq!(uav1["domain"], "multiuav_uav1");
    assert_eq!(uav1["role"], "SUBSCRIBE");
    assert_eq!(uav1["topic"], "rt/fleet/uav1/state");
    assert_eq!(uav1["ros2_topic"], "/fleet/uav1/state");
    assert_eq!(uav1["writer_qos"]["reliability"], "RELIABLE");
    assert_eq!(uav1["writer_qos"]["history"], "KEEP_ALL");
    assert_eq!(uav1["max_rate"], Value::Null);
    assert_eq!(uav1["per_item_topics"], serde_json::json!([]));
    let uav4: Vec<&str> =
        left.iter().filter(|l| l["domain"] == "multiuav_uav4").map(|l| l["reason"].as_str().unwrap()).collect();
    assert_eq!(uav4, ["matches no allow pattern ('multiuav_uav[1-3]/.*')"; 2]);
}

#[test]
fn show_flags_win_over_the_file_and_rates_and_per_item_topics_show() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = write(
        dir.path(),
        "gw.json5",
        r#"{ qos_profile: "ros2", ros2_types: "per-item", ros_namespace: "site_a",
             topics: { "grid_feeder/subscribe": { max_rate: 25, remap: "feeder/state",
                                                   qos: { history: "keep_last", depth: 4 } } } }"#,
    );
    let (code, out, err) =
        tutti_env(&["show", "ddf/product-sample.ddf", "--config", &cfg, "--json", "--qos-profile", "dds"], &[]);
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["qos_profile"], "dds", "the flag wins over the file");
    assert_eq!(v["ros2_types"], "per-item");
    let s = v["sets"].as_array().unwrap().iter().find(|s| s["key"] == "grid_feeder/subscribe").unwrap().clone();
    assert_eq!(s["max_rate"], 25.0);
    assert_eq!(s["ros2_topic"], "/site_a/feeder/state");
    assert_eq!(s["reader_qos"]["history"], serde_json::json!({ "KEEP_LAST": 4 }));
    let items = s["per_item_topics"].as_array().unwrap();
    assert!(
        !items.is_empty() && items.iter().all(|t| t["topic"].as_str().unwrap().starts_with("rt/site_a/feeder/state/")),
        "{items:?}"
    );
    let (code, out, err) = tutti_env(&["show", "ddf/product-sample.ddf", "--config", &cfg], &[]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("grid_feeder/subscribe  ->  /site_a/feeder/state\n")
            && out.contains("    out: at most 25 samples/s\n"),
        "{out}"
    );
}

#[test]
fn a_bad_file_is_refused_by_show_and_gateway_naming_file_key_and_flag() {
    let dir = tempfile::tempdir().unwrap();
    let lockstep = write(
        dir.path(),
        "lockstep.json5",
        r#"{ topics: { "multiuav_uav1/subscribe": { qos: { reliability: "best_effort" } } } }"#,
    );
    let typo = write(dir.path(), "typo.json5", "{\n  ros_namespace: \"sim1\",\n  alow: [\"x\"],\n}\n");
    let nokey = write(dir.path(), "nokey.json5", r#"{ topics: { "uav1/publish": {} } }"#);
    for cmd in ["show", "gateway"] {
        let (code, _, err) = tutti_env(&[cmd, "ddf/multiuav.ddf", "--config", &lockstep], &[]);
        assert_eq!(code, 2, "{cmd}: {err}");
        assert!(
            err.contains(&format!("{lockstep}: topics.\"multiuav_uav1/subscribe\".qos.reliability: best_effort is refused: domain 'multiuav_uav1' has synchronous=yes")),
            "{cmd}: {err}"
        );
        let (code, _, err) = tutti_env(&[cmd, "ddf/multiuav.ddf", "--config", &typo], &[]);
        assert_eq!(code, 2, "{cmd}: {err}");
        assert!(
            err.contains(&format!("{typo}:3:3: unknown field `alow`, expected one of")) && err.contains("`allow`"),
            "{cmd}: {err}"
        );
        let (code, _, err) = tutti_env(&[cmd, "ddf/multiuav.ddf", "--config", &nokey], &[]);
        assert_eq!(code, 2, "{cmd}: {err}");
        assert!(
            err.contains("the DDF has no set 'uav1/publish' (sets: multiuav_uav1/publish, multiuav_uav1/subscribe"),
            "{cmd}: {err}"
        );
    }
    let (code, _, err) = tutti(["show", "ddf/multiuav.ddf", "--config", "no/such.json5"]);
    assert_eq!(code, 2);
    assert!(err.contains("no/such.json5: cannot read the gateway config"), "{err}");
}

#[test]
fn gateway_refuses_ros2_discovery_settings_it_cannot_honour() {
    let (code, _, err) =
        tutti_env(&["gateway", "ddf/multiuav.ddf", "--duration", "1ms"], &[("ROS_AUTOMATIC_DISCOVERY_RANGE", "LAN")]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("ROS_AUTOMATIC_DISCOVERY_RANGE='LAN'"), "{err}");
    let (code, _, err) =
        tutti_env(&["gateway", "ddf/multiuav.ddf", "--duration", "1ms"], &[("ROS_AUTOMATIC_DISCOVERY_RANGE", "OFF")]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("ROS_AUTOMATIC_DISCOVERY_RANGE=OFF") && err.contains("--peer"), "{err}");
}

#[test]
fn gateway_refuses_a_lookahead_it_cannot_honour_naming_the_domain() {
    let (code, _, err) = tutti_env(&["gateway", "ddf/multiuav.ddf", "--lookahead", "uav9=3", "--duration", "1ms"], &[]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("lookahead for domain 'uav9': the DDF has no such domain"), "{err}");
    let (code, _, err) = tutti_env(
        &[
            "gateway",
            "ddf/multiuav.ddf",
            "--mirror",
            "--ros2-types",
            "per-item",
            "--lookahead",
            "4",
            "--duration",
            "1ms",
        ],
        &[],
    );
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("per-item topics carry no step"), "{err}");
    let (code, _, err) = tutti_env(&["gateway", "ddf/multiuav.ddf", "--lookahead", "ten"], &[]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("'ten' is not a lookahead"), "{err}");
    let dir = tempfile::tempdir().unwrap();
    let file = write(dir.path(), "la.json5", "{\n  lookahead: { grid_feeder: 2 },\n}\n");
    let (code, _, err) = tutti_env(&["show", "ddf/product-sample.ddf", "--config", &file], &[]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("lookahead for domain 'grid_feeder': the domain is asynchronous"), "{err}");
}
