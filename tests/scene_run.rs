//! `gelgrip run --scene`: the fingers close on a scene with the fixed current ramp, the
//! frames show the contact, and the run reports the scene, the servos and any recovered
//! servo fault.

mod common;

use common::{gelgrip, json, ok};

fn run_scene(extra: &[&str]) -> serde_json::Value {
    let mut args = vec!["run", "--headless", "--json", "--clock", "virtual"];
    args.extend_from_slice(extra);
    let out = gelgrip(&args);
    let _ = ok(&out);
    json(&out)
}

#[test]
fn closing_on_the_tennis_ball_touches_the_expected_sensors() {
    let r = run_scene(&[
        "--duration",
        "3",
        "--scene",
        "configs/scenes/tennis-ball.toml",
    ]);
    assert_eq!(r["object"], "tennis ball");
    assert_eq!(r["crushed"], false);
    let scene = &r["scene"];
    assert_eq!(scene["contact_as_expected"], true, "{scene}");
    assert_eq!(scene["touched"].as_array().map(Vec::len), Some(7));
    assert!(scene["peak_force_n"]["f1.tip"].as_f64().unwrap_or(0.0) > 0.5);
    let servos = r["servos"].as_array().expect("servo states");
    assert_eq!(servos.len(), 3);
    assert!(
        servos
            .iter()
            .all(|s| s["position_deg"].as_f64().unwrap_or(0.0) > 10.0)
    );
    assert!(r["sets"].as_u64().unwrap_or(0) > 80, "{r}");
    assert_eq!(r["faults"].as_array().map(Vec::len), Some(0));
}

#[test]
fn a_blind_squeeze_crushes_the_cup_and_the_run_says_so() {
    let r = run_scene(&[
        "--duration",
        "3",
        "--scene",
        "configs/scenes/paper-cup.toml",
    ]);
    assert_eq!(r["crushed"], true, "{}", r["scene"]);
    let events = r["scene"]["events"].as_array().expect("events");
    assert!(events.iter().any(|e| e["kind"] == "crushed"));
}

#[test]
fn an_overload_is_recovered_and_listed_in_faults() {
    let r = run_scene(&[
        "--config",
        "tests/configs/strong-servos.toml",
        "--duration",
        "5",
        "--close-current-ma",
        "2300",
    ]);
    assert_eq!(r["end_reason"], "duration");
    let faults = r["faults"].as_array().expect("faults");
    assert!(
        faults
            .iter()
            .any(|f| f.as_str().is_some_and(|s| s.contains("overload recovered"))),
        "{faults:?}"
    );
}

#[test]
fn a_scene_needs_the_sim_hub_and_a_valid_file() {
    let out = gelgrip(&[
        "run",
        "--headless",
        "--duration",
        "1",
        "--scene",
        "configs/scenes/does-not-exist.toml",
    ]);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("does-not-exist.toml"));
}
