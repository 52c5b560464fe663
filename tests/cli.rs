//! End-to-end tests of the `gelgrip` binary against the simulated hub.

mod common;

use std::path::PathBuf;

use common::{gelgrip, json};
use serde_json::Value;

fn fixture(name: &str) -> String {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/configs")
        .join(name);
    p.display().to_string()
}

fn repo_file(name: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join(name)
        .display()
        .to_string()
}

fn virtual_run(extra: &[&str]) -> Value {
    let mut args = vec![
        "run",
        "--duration",
        "3",
        "--headless",
        "--json",
        "--clock",
        "virtual",
    ];
    args.extend_from_slice(extra);
    json(&gelgrip(&args))
}

const REASONS: [&str; 8] = [
    "late",
    "incomplete",
    "out_of_window",
    "corrupt",
    "duplicate",
    "disconnected",
    "superseded",
    "excluded",
];

fn total(v: &Value, key: &str) -> u64 {
    REASONS
        .iter()
        .map(|r| v[key][r].as_u64().expect("count present"))
        .sum()
}

#[test]
fn default_run_reports_seven_sensors_above_30_hz_and_no_drops() {
    let v = virtual_run(&[]);
    assert_eq!(v["sensors"], 7);
    assert!(v["set_rate_hz"].as_f64().unwrap_or(0.0) >= 30.0, "{v}");
    assert!(v["sets"].as_u64().unwrap_or(0) >= 90, "{v}");
    assert_eq!(total(&v, "drops"), 0, "{v}");
    assert_eq!(total(&v, "sets_rejected"), 0, "{v}");
    assert_eq!(v["end_reason"], "duration");
    assert_eq!(v["faults"], Value::Array(vec![]));
    assert!(v["spread_us_p99"].as_u64().is_some());
}

#[test]
fn a_sensor_capturing_late_is_excluded_and_the_rest_go_on() {
    // f2.tip captures 2 ms late against a 500 us window: three refused sets exclude it,
    // and the other six sensors' sets pass from then on.
    let v = virtual_run(&["--config", &fixture("late-sensor.toml")]);
    let sets = v["sets"].as_u64().unwrap_or(0);
    assert!(sets >= 85, "{v}");
    assert_eq!(v["sets_rejected"]["out_of_window"], 3, "{v}");
    assert_eq!(total(&v, "sets_rejected"), 3, "only those: {v}");
    assert_eq!(v["drops"]["out_of_window"], 21, "{v}");
    assert!(v["drops"]["excluded"].as_u64() >= Some(sets), "{v}");
    let excluded = v["excluded_sensors"].as_array().expect("excluded_sensors");
    assert_eq!(excluded.len(), 1, "{v}");
    assert_eq!(excluded[0]["sensor"], "f2.tip");
    assert_eq!(excluded[0]["reason"], "out_of_window");
    assert!(excluded[0]["since_s"].as_f64() < Some(0.5), "{v}");
}

#[test]
fn counters_wrapping_mid_run_change_nothing() {
    let plain = virtual_run(&[]);
    let wrapped = virtual_run(&["--config", &fixture("wrap.toml")]);
    for key in [
        "sets",
        "set_rate_hz",
        "spread_us_p99",
        "drops",
        "sets_rejected",
        "frames_received",
    ] {
        assert_eq!(plain[key], wrapped[key], "{key}");
    }
}

#[test]
fn injected_faults_are_all_accounted_for() {
    let v = virtual_run(&["--config", &fixture("faults.toml")]);
    let frames = v["frames_received"].as_u64().unwrap_or(0);
    let delivered = v["sets"].as_u64().unwrap_or(0) * 7;
    let dropped = total(&v, "drops");
    // Frames still pending at the end are at most two sets' worth.
    assert!(
        frames >= delivered + dropped && frames <= delivered + dropped + 14,
        "{v}"
    );
    assert!(v["drops"]["corrupt"].as_u64().unwrap_or(0) > 0, "{v}");
    assert!(
        v["sets_rejected"]["corrupt"].as_u64().unwrap_or(0) > 0,
        "{v}"
    );
    assert!(
        v["sets_rejected"]["incomplete"].as_u64().unwrap_or(0) > 0,
        "{v}"
    );
    assert!(v["sets"].as_u64().unwrap_or(0) > 50, "{v}");
}

#[test]
fn a_sensor_delivering_late_is_excluded_as_late() {
    // f3.middle's frames arrive 40 ms late, so its sets are too old: it is excluded.
    let v = virtual_run(&["--config", &fixture("late-delivery.toml")]);
    assert!(v["sets"].as_u64() >= Some(85), "{v}");
    assert_eq!(v["sets_rejected"]["late"], 3, "{v}");
    let excluded = v["excluded_sensors"].as_array().expect("excluded_sensors");
    assert_eq!(excluded.len(), 1, "{v}");
    assert_eq!(excluded[0]["sensor"], "f3.middle");
    assert_eq!(excluded[0]["reason"], "late");
}

#[test]
fn sets_too_old_with_no_one_to_blame_are_refused_and_the_run_says_why() {
    let v = virtual_run(&["--config", &fixture("old-sets.toml")]);
    assert_eq!(v["sets"], 0, "{v}");
    let refused = total(&v, "sets_rejected");
    assert!(refused >= 90, "{v}");
    assert!(
        v["drops"]["late"].as_u64() > Some(0),
        "frames came after their sets: {v}"
    );
    assert_eq!(v["excluded_sensors"], serde_json::json!([]), "{v}");
    // The run says why nothing passes, and what to check.
    let out = gelgrip(&[
        "run",
        "--duration",
        "3",
        "--headless",
        "--clock",
        "virtual",
        "--config",
        &fixture("old-sets.toml"),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("older than the gate's max age") && err.contains("max_age_ms"),
        "{err}"
    );
    assert_eq!(
        err.matches("older than the gate's max age").count(),
        1,
        "said once: {err}"
    );
}

#[test]
fn check_config_accepts_the_shipped_sim_config() {
    let out = gelgrip(&["check-config", &repo_file("configs/gelgripper-sim.toml")]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("7 sensors"));
}

#[test]
fn check_config_names_file_field_and_range() {
    let out = gelgrip(&["check-config", &fixture("bad-range.toml")]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad-range.toml"), "{err}");
    assert!(err.contains("hub.sim.jpeg_quality"), "{err}");
    assert!(err.contains("[1, 100]"), "{err}");
}

/// A `[grasp]` whose most is below its first grip exits 2 naming the field.
#[test]
fn check_config_names_a_bad_grasp_section() {
    let out = gelgrip(&["check-config", &fixture("bad-grasp.toml")]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad-grasp.toml"), "{err}");
    assert!(err.contains("`grasp.max_force_n` = 0.5"), "{err}");
    assert!(err.contains("grasp.preload_n (1 N)"), "{err}");
}

/// Bad `[[hub.sim.faults]]` timing faults exit 2 naming the field and its range.
#[test]
fn check_config_names_a_bad_sim_timing_fault() {
    let dir = std::env::temp_dir().join(format!("gelgrip-bad-fault-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let layout = repo_file("configs/layouts/three-finger.toml");
    for (i, (key, expected)) in [
        (
            "capture_jitter_us = -5",
            "`hub.sim.faults[0].capture_jitter_us` = -5",
        ),
        (
            "clock_drift_ppm = 1001",
            "`hub.sim.faults[0].clock_drift_ppm` = 1001",
        ),
        (
            "clock_drift_ppm = -1001",
            "`hub.sim.faults[0].clock_drift_ppm` = -1001",
        ),
        ("clock_drift = 5", "unknown field `clock_drift`"),
    ]
    .into_iter()
    .enumerate()
    {
        let path = dir.join(format!("bad-fault-{i}.toml"));
        let text = format!(
            "version = 1\nlayout = {layout:?}\n[[hub.sim.faults]]\nsensor = \"palm\"\n{key}\n"
        );
        std::fs::write(&path, text).expect("write");
        let out = gelgrip(&["check-config", &path.display().to_string()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{key}: {err}");
        assert!(err.contains(&format!("bad-fault-{i}.toml")), "{err}");
        assert!(err.contains(expected), "{key}: {err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn check_config_wants_one_servo_per_finger() {
    assert!(
        gelgrip(&["check-config", &fixture("five-finger.toml")])
            .status
            .success()
    );
    let dir = std::env::temp_dir().join(format!("gelgrip-servos-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let path = dir.join("three-servos.toml");
    let text = std::fs::read_to_string(fixture("five-finger.toml"))
        .expect("fixture")
        .replace("ids = [1, 2, 3, 4, 5]", "ids = [1, 2, 3]")
        .replace(
            "../../configs/layouts/five-finger.toml",
            &repo_file("configs/layouts/five-finger.toml"),
        );
    std::fs::write(&path, text).expect("write");
    let out = gelgrip(&["check-config", &path.display().to_string()]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("servos.ids lists 3 servos for the 5 fingers of layout five-finger"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn unbuilt_backends_get_a_clear_error_listing_what_exists() {
    let out = gelgrip(&["check-config", &fixture("unbuilt-transport.toml")]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("hub.transport") && err.contains("ethernet"),
        "{err}"
    );
    assert!(err.contains("available: sim, ch347, cdc, replay"), "{err}");
    let out = gelgrip(&["check-config", &repo_file("configs/gelgripper-cdc.toml")]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The hardware template names only what this build has.
    let out = gelgrip(&["check-config", &repo_file("configs/gelgripper.toml")]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn the_ch347_transport_runs_on_its_chip_emulator_and_without_usb_fails_clearly() {
    let v = virtual_run(&["--config", &fixture("ch347-emu.toml")]);
    assert_eq!(v["transport"], "ch347");
    assert!(v["sets"].as_u64() >= Some(60), "{v}");
    assert_eq!(total(&v, "drops"), 0, "{v}");
    assert_eq!(total(&v, "sets_rejected"), 0, "{v}");
    let rate = v["set_rate_hz"].as_f64().unwrap_or(0.0);
    assert!(
        (20.0..26.0).contains(&rate),
        "7 × 20 KB at 30 MHz: {rate} Hz"
    );
    // A real chip on a machine without one: a clear error, no panic.
    let out = gelgrip(&[
        "run",
        "--config",
        &fixture("ch347-usb.toml"),
        "--headless",
        "--duration",
        "1",
    ]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("no USB on this machine") || err.contains("no CH347 matches"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn missing_config_file_is_a_config_error() {
    let out = gelgrip(&["run", "--config", "/nonexistent/gelgrip.toml", "--headless"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/gelgrip.toml"));
}

/// A config copied to another folder without its layout: the message names the config, the
/// key, the path as written and the path it resolved to, and gives the cause once.
#[test]
fn a_config_copied_without_its_layout_says_where_the_path_came_from() {
    let dir = std::env::temp_dir().join(format!("gelgrip-copied-config-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temp dir");
    let copy = dir.join("gelgripper-sim.toml");
    std::fs::copy("configs/gelgripper-sim.toml", &copy).expect("the shipped config");
    let out = gelgrip(&["check-config", &copy.display().to_string()]);
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(out.status.code(), Some(2), "{err}");
    let resolved = dir.join("layouts/three-finger.toml").display().to_string();
    assert!(err.contains(&copy.display().to_string()), "{err}");
    assert!(
        err.contains(r#"layout = "layouts/three-finger.toml""#),
        "{err}"
    );
    assert!(err.contains(&format!("resolves to {resolved}")), "{err}");
    assert_eq!(err.matches("No such file or directory").count(), 1, "{err}");
}

#[test]
fn bad_usage_exits_2() {
    assert_eq!(gelgrip(&["run", "--duration", "-1"]).status.code(), Some(2));
    assert_eq!(
        gelgrip(&["bench", "bus", "--sensors", "40"]).status.code(),
        Some(2)
    );
}

#[test]
fn bench_bus_rows_match_the_model_in_virtual_time() {
    let out = gelgrip(&[
        "bench",
        "bus",
        "--sensors",
        "7",
        "--json",
        "--clock",
        "virtual",
        "--seconds",
        "1",
    ]);
    let rows = json(&out);
    let rows = rows.as_array().expect("an array of rows");
    assert_eq!(rows.len(), 2, "both triggers");
    for row in rows {
        for key in [
            "sensors",
            "trigger",
            "model_rate_hz",
            "measured_rate_hz",
            "model_latency_ms",
            "measured_latency_ms",
            "spread_us_p99",
            "host_cpu_ms_per_set",
        ] {
            assert!(!row[key].is_null(), "{key} missing in {row}");
        }
        let model = row["model_rate_hz"].as_f64().unwrap_or(0.0);
        let measured = row["measured_rate_hz"].as_f64().unwrap_or(0.0);
        assert!((measured - model).abs() / model < 0.05, "{row}");
    }
    let seq = rows
        .iter()
        .find(|r| r["trigger"] == "sequential")
        .expect("sequential row");
    // 7 boards, 25 us apart: 150 us stagger plus up to 2 us of jitter.
    let spread = seq["spread_us_p99"].as_u64().unwrap_or(0);
    assert!((148..=153).contains(&spread), "{seq}");
}

#[test]
fn the_approximate_gate_forms_the_trigger_gates_sets_from_capture_times_alone() {
    let by_trigger = virtual_run(&["--config", &fixture("sequential.toml")]);
    let by_time = virtual_run(&["--config", &fixture("approximate.toml")]);
    let sets = |v: &Value| v["sets"].as_u64().unwrap_or(0);
    assert!(sets(&by_trigger) >= 90, "{by_trigger}");
    // The newest set waits for later frames to prove it: at most one fewer.
    assert!(
        sets(&by_trigger) - sets(&by_time) <= 1,
        "{by_trigger}\n{by_time}"
    );
    assert_eq!(by_trigger["spread_us_p99"], by_time["spread_us_p99"]);
    assert_eq!(total(&by_time, "drops"), 0, "{by_time}");
    assert_eq!(total(&by_time, "sets_rejected"), 0, "{by_time}");
}

#[test]
fn the_latest_policy_fuses_each_sensors_newest_frame_without_matching() {
    // On time, each set end finds every sensor's frame of its own trigger: the trigger
    // gate's sets.
    let by_trigger = virtual_run(&[]);
    let latest = virtual_run(&["--config", &fixture("latest.toml")]);
    let sets = |v: &Value| v["sets"].as_u64().unwrap_or(0);
    assert!(sets(&latest) >= 90, "{latest}");
    assert!(
        sets(&by_trigger).abs_diff(sets(&latest)) <= 1,
        "{by_trigger}\n{latest}"
    );
    assert_eq!(by_trigger["spread_us_p99"], latest["spread_us_p99"]);
    assert_eq!(total(&latest, "drops"), 0, "{latest}");
    assert_eq!(total(&latest, "sets_rejected"), 0, "{latest}");
    // f3.middle 20 ms late: each set fuses its frame of the trigger before (a spread of
    // one set period). Only the first set, before it ever delivered, is refused; the six
    // frames that set would have fused were replaced before the next one: superseded.
    let v = virtual_run(&["--config", &fixture("latest-late-delivery.toml")]);
    assert!(sets(&v) >= 90, "{v}");
    let spread = v["spread_us_p99"].as_u64().unwrap_or(0);
    assert!((25_000..35_000).contains(&spread), "{v}");
    assert_eq!(v["sets_rejected"]["incomplete"], 1, "{v}");
    assert_eq!(total(&v, "sets_rejected"), 1, "{v}");
    assert_eq!(v["drops"]["superseded"], 6, "{v}");
    assert_eq!(total(&v, "drops"), 6, "{v}");
    // Each frame counts once, however often it is fused; at most one per sensor is held.
    let fused_once = 7 * sets(&v) - v["frames_reused"].as_u64().expect("frames_reused");
    let frames = v["frames_received"].as_u64().unwrap_or(0);
    assert!(
        (fused_once + 6..=fused_once + 6 + 7).contains(&frames),
        "{v}"
    );
}

#[test]
fn an_unknown_gate_policy_exits_2_naming_the_field_and_the_policies() {
    let dir = std::env::temp_dir().join(format!("gelgrip-policy-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let path = dir.join("newest.toml");
    let text = std::fs::read_to_string(fixture("latest.toml"))
        .expect("fixture")
        .replace("policy = \"latest\"", "policy = \"newest\"")
        .replace(
            "../../configs/layouts/three-finger.toml",
            &repo_file("configs/layouts/three-finger.toml"),
        );
    std::fs::write(&path, text).expect("write");
    let path = path.display().to_string();
    for args in [
        vec!["check-config", &path],
        vec!["run", "--config", &path, "--headless", "--duration", "1"],
    ] {
        let out = gelgrip(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("`gate.policy` = newest"), "{err}");
        assert!(err.contains("trigger | approximate | latest"), "{err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bench_bus_measures_the_ch347_on_its_emulator_with_the_hosts_share() {
    let out = gelgrip(&[
        "bench",
        "bus",
        "--transport",
        "ch347-emu",
        "--sensors",
        "3",
        "--spi-clock-hz",
        "30000000",
        "--clock",
        "virtual",
        "--seconds",
        "0.5",
        "--json",
    ]);
    let rows = json(&out);
    let rows = rows.as_array().expect("array");
    assert_eq!(rows.len(), 2, "one row per trigger");
    for r in rows {
        assert_eq!(r["transport"], "ch347-emu");
        assert_eq!(r["usb"], "hs");
        assert_eq!(r["spi_clock_hz"], 30_000_000);
        assert_eq!(r["frames_dropped"], 0);
        let f = r["host_fraction_of_bus"].as_f64().unwrap_or(1.0);
        assert!(f > 0.0 && f < 0.1, "{r}");
    }
}

#[test]
fn bench_bus_measures_the_cdc_hub_over_a_pty_at_full_and_high_speed() {
    let out = gelgrip(&[
        "bench",
        "bus",
        "--transport",
        "cdc-pty",
        "--trigger",
        "broadcast",
        "--seconds",
        "1.5",
        "--json",
    ]);
    let rows = json(&out);
    let rows = rows.as_array().expect("array");
    assert_eq!(rows.len(), 2, "full speed, then high speed");
    let (fs, hs) = (&rows[0], &rows[1]);
    assert_eq!(
        (fs["usb"].as_str(), hs["usb"].as_str()),
        (Some("fs"), Some("hs"))
    );
    for r in rows {
        assert_eq!(r["transport"], "cdc-pty");
        assert_eq!(r["frames_dropped"], 0, "{r}");
        let share = r["host_fraction_of_bus"].as_f64().unwrap_or(1.0);
        assert!(
            share > 0.0 && share <= 0.1,
            "the host is not the bottleneck: {r}"
        );
        let (measured, bus) = (
            r["measured_rate_hz"].as_f64().unwrap_or(0.0),
            r["bus_rate_hz"].as_f64().unwrap_or(0.0),
        );
        assert!(
            (measured - bus).abs() / bus < 0.1,
            "at the modelled rate: {r}"
        );
    }
    // About 1 MB/s cannot carry 7 × 20 KB × 34 Hz: the link sets the rate.
    let rate = |r: &serde_json::Value| r["measured_rate_hz"].as_f64().unwrap_or(0.0);
    assert!(
        rate(fs) < 0.3 * rate(hs),
        "fs {} Hz, hs {} Hz",
        rate(fs),
        rate(hs)
    );
    // --usb is the CDC hub's alone.
    let out = gelgrip(&["bench", "bus", "--transport", "sim", "--usb", "fs"]);
    assert_eq!(out.status.code(), Some(2), "a usage error");
}

/// The README's main command on a fresh machine: the sensors' self-calibration (no cache
/// yet, seconds) comes before the run, and `--duration` counts from the end of the set-up,
/// so a short run still acquires (it used to end during the calibration with no set).
#[test]
fn a_first_run_with_no_calibration_cache_acquires_for_its_whole_duration() {
    let cache = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("gelgrip-cold-cache-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&cache);
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_gelgrip"))
        .args(["--duration", "1", "--json", "--http", "127.0.0.1:0"])
        .env("GELGRIP_CACHE_DIR", &cache)
        .env("RUST_LOG", "warn")
        .output()
        .expect("the gelgrip binary runs");
    let v = json(&out);
    let _ = std::fs::remove_dir_all(&cache);
    assert_eq!(v["end_reason"], "duration", "{v}");
    assert_eq!(v["clock"], "real", "{v}");
    let elapsed = v["elapsed_s"].as_f64().expect("elapsed_s");
    assert!((1.0..1.5).contains(&elapsed), "{v}");
    assert!(v["sets"].as_u64().unwrap_or(0) >= 5, "{v}");
}
