//! `gelgrip run --scene … --task gentle-grasp`: the closed loop on fused tactile force, end
//! to end on the simulator (virtual clock). The pipelines calibrate themselves (cached under
//! the build's `target/tmp`, so a clean clone calibrates for real); the controller closes,
//! regulates and holds; the run reports the task fields and writes the CSV log.

mod common;

use std::process::{Command, Output};

use common::report;

fn grasp(scene: &str, log: &std::path::Path) -> serde_json::Value {
    let log = log.display().to_string();
    let out = common::virtual_run(&[
        "--duration",
        "25",
        "--scene",
        scene,
        "--task",
        "gentle-grasp",
        "--target-force",
        "1.5",
        "--log",
        &log,
    ])
    .output()
    .expect("gelgrip runs");
    report(&out, 0)
}

#[test]
fn the_tennis_ball_is_grasped_gently_held_and_logged() {
    let dir = std::env::temp_dir().join(format!("gelgrip-grasp-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let log = dir.join("ball.csv");
    let r = grasp("configs/scenes/tennis-ball.toml", &log);
    assert_eq!(r["end_reason"], "done", "{r}");
    assert_eq!(r["grasped"], true, "{r}");
    assert_eq!(r["crushed"], false);
    assert_eq!(r["reason"], "stable");
    assert_eq!(r["target_force_n"], 1.5);
    assert!(r["hold_slip_mm"].as_f64().is_some_and(|s| s < 1.0), "{r}");
    assert!(r["time_to_stable_s"].as_f64().is_some());
    // The regulated force never runs more than 10% past the target while grasping.
    assert!(
        r["peak_force_n"].as_f64().is_some_and(|p| p <= 1.1 * 1.5),
        "{r}"
    );
    // And so does the force the ball feels (the simulator's ground truth).
    assert!(
        r["true_peak_force_n"]
            .as_f64()
            .is_some_and(|p| p.is_finite() && p <= 1.1 * 1.5),
        "{r}"
    );
    for key in [
        "loop_latency_ms_p50",
        "loop_latency_ms_p99",
        "capture_to_command_ms_p99",
        "peak_force_n",
    ] {
        assert!(r[key].as_f64().is_some_and(f64::is_finite), "{key}: {r}");
    }
    let csv = std::fs::read_to_string(&log).expect("log written");
    let mut lines = csv.lines();
    let header = lines.next().expect("header");
    assert!(
        header.starts_with("t_s,stage,f1.middle_deformation_mm3"),
        "{header}"
    );
    assert!(header.contains("f3_state,f3_force_n"));
    let rows: Vec<&str> = lines.collect();
    assert!(rows.len() > 50);
    assert!(rows.iter().any(|r| r.contains(",hold,")));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_paper_cup_is_held_without_crushing_it() {
    let dir = std::env::temp_dir().join(format!("gelgrip-grasp-cup-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let r = grasp("configs/scenes/paper-cup.toml", &dir.join("cup.csv"));
    assert_eq!(r["crushed"], false, "{}", r["scene"]);
    assert_eq!(r["grasped"], true, "{r}");
    for key in ["peak_force_n", "true_peak_force_n"] {
        assert!(
            r[key].as_f64().is_some_and(|p| p <= 1.1 * 1.5),
            "{key}: {r}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_target_beyond_the_current_cap_holds_what_the_cap_allows_without_overloading() {
    // Servos allowed up to their stall current, and a target no cap can reach: the
    // controller must stall at its holding limit, hold a little below it and say so,
    // rather than strain until the servos overload.
    let out = common::virtual_run(&[
        "--duration",
        "25",
        "--config",
        "tests/configs/strong-servos.toml",
        "--scene",
        "configs/scenes/tennis-ball.toml",
        "--task",
        "gentle-grasp",
        "--target-force",
        "200",
    ])
    .output()
    .expect("gelgrip runs");
    let r = report(&out, 0);
    assert_eq!(r["reason"], "force_limited", "{r}");
    assert_eq!(r["grasped"], true, "{r}");
    assert_eq!(r["faults"], serde_json::json!([]), "no overload: {r}");
    for s in r["servos"].as_array().expect("servos") {
        let ma = s["current_ma"].as_f64().expect("current");
        assert!(ma.is_finite() && ma <= 1200.0 + 50.0, "{s}");
    }
    assert!(
        r["peak_force_n"].as_f64().is_some_and(f64::is_finite),
        "{r}"
    );
}

/// The gentle grasp on the tennis ball with `config` (a scheduled servo fault).
fn faulted_grasp(config: &str) -> Output {
    common::virtual_run(&[
        "--duration",
        "25",
        "--config",
        config,
        "--task",
        "gentle-grasp",
    ])
    .output()
    .expect("gelgrip runs")
}

#[test]
fn an_overload_mid_squeeze_is_recovered_listed_and_the_grasp_completes() {
    let r = report(&faulted_grasp("tests/configs/overload-mid-squeeze.toml"), 0);
    assert_eq!(r["end_reason"], "done", "{r}");
    let faults = r["faults"].as_array().expect("faults");
    assert!(
        faults.iter().any(|f| f
            .as_str()
            .is_some_and(|f| f.contains("servo 2") && f.contains("overload recovered"))),
        "{r}"
    );
    assert_eq!(r["grasped"], true, "{r}");
    assert!(
        r["peak_force_n"].as_f64().is_some_and(|p| p <= 1.1 * 1.5),
        "{r}"
    );
}

#[test]
fn a_servo_that_cannot_recover_mid_squeeze_ends_the_run_as_a_fault() {
    let r = report(
        &faulted_grasp("tests/configs/overheating-mid-squeeze.toml"),
        1,
    );
    assert_eq!(r["end_reason"], "fault", "{r}");
    assert_eq!(r["grasped"], false, "{r}");
    assert!(
        r["faults"].as_array().is_some_and(|f| f.iter().any(|f| f
            .as_str()
            .is_some_and(|f| f.contains("servo 2") && f.contains("persists")))),
        "{r}"
    );
}

#[test]
fn a_fault_on_an_unknown_servo_is_a_config_error() {
    let out = common::gelgrip(&["check-config", "tests/configs/bad-servo-fault.toml"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("servos.sim.faults[0].servo"), "{err}");
}

#[test]
fn an_unknown_task_is_a_usage_error() {
    let out = common::gelgrip(&["run", "--headless", "--duration", "1", "--task", "juggle"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("gentle-grasp"));
}

#[test]
fn a_dead_sensor_starves_the_gate_and_the_watchdog_stops_the_fingers() {
    let out = common::virtual_run(&[
        "--duration",
        "10",
        "--config",
        "tests/configs/dead-sensor.toml",
        "--task",
        "gentle-grasp",
    ])
    .output()
    .expect("gelgrip runs");
    let r = report(&out, 1);
    assert_eq!(r["end_reason"], "fault");
    assert!(
        r["faults"][0]
            .as_str()
            .is_some_and(|f| f.contains("watchdog")),
        "{}",
        r["faults"]
    );
    assert!(
        r["drops"]["late"].as_u64().unwrap_or(0)
            + r["sets_rejected"]["incomplete"].as_u64().unwrap_or(0)
            > 0,
        "{r}"
    );
    assert_eq!(r["grasped"], false);
}

#[test]
fn an_estop_mid_grasp_holds_at_minimum_current_and_exits_1() {
    let child = common::virtual_run(&[
        "--duration",
        "25",
        "--scene",
        "configs/scenes/rubber-duck.toml",
        "--task",
        "gentle-grasp",
    ])
    .env("RUST_LOG", "info")
    .stdout(std::process::Stdio::piped())
    .stderr(std::process::Stdio::piped())
    .spawn()
    .expect("gelgrip runs");
    // Wait for the task to run (after any calibration); the duck then takes several
    // seconds of wall time to settle, so the e-stop lands mid-grasp.
    let mut child = child;
    let stderr = child.stderr.take().expect("stderr");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        use std::io::BufRead;
        for line in std::io::BufReader::new(stderr)
            .lines()
            .map_while(Result::ok)
        {
            if line.contains("task running") {
                let _ = tx.send(());
            }
        }
    });
    rx.recv_timeout(std::time::Duration::from_secs(300))
        .expect("the task starts");
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let status = Command::new("kill")
        .args(["-USR1", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(status.success());
    let out = child.wait_with_output().expect("gelgrip ends");
    let r = report(&out, 1);
    assert_eq!(r["end_reason"], "estop", "{r}");
    assert!(
        r["faults"].as_array().is_some_and(|f| f
            .iter()
            .any(|x| x.as_str().is_some_and(|s| s.contains("e-stop")))),
        "{r}"
    );
}

/// Direction reversals of `ys`, ignoring moves smaller than `deadband`.
fn reversals(ys: &[f64], deadband: f64) -> usize {
    let (mut count, mut dir, mut extreme) = (0, 0i8, ys.first().copied().unwrap_or(0.0));
    for &y in ys.iter().skip(1) {
        let moved = if y > extreme { 1 } else { -1 };
        if dir == 0 {
            if (y - extreme).abs() > deadband {
                dir = moved;
                extreme = y;
            }
        } else if moved == dir {
            extreme = y;
        } else if (y - extreme).abs() > deadband {
            count += 1;
            dir = moved;
            extreme = y;
        }
    }
    count
}

/// Grasp the tennis ball with `config`, hold 2.5 s once stable, and check the simulator's
/// true finger forces over the hold: peak-to-peak under 5% of the target, at most one
/// reversal (beyond 1% of the target) per second, goal currents within the limit, and
/// every logged number finite.
fn steady_hold(config: &str) {
    let dir = std::env::temp_dir().join(format!(
        "gelgrip-steady-{}-{}",
        std::process::id(),
        config.replace('/', "_")
    ));
    std::fs::create_dir_all(&dir).expect("dir");
    let log = dir.join("hold.csv");
    let target = 1.5;
    let out = common::virtual_run(&[
        "--duration",
        "40",
        "--config",
        config,
        "--task",
        "gentle-grasp",
        "--target-force",
        "1.5",
        "--hold",
        "2.5",
        "--log",
        &log.display().to_string(),
    ])
    .output()
    .expect("gelgrip runs");
    let r = report(&out, 0);
    assert_eq!(r["reason"], "stable", "{config}: {r}");
    let csv = std::fs::read_to_string(&log).expect("log");
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    for row in &rows {
        for (name, v) in header.iter().zip(row) {
            if *name != "stage" && !name.ends_with("_state") && !v.is_empty() {
                let x: f64 = v.parse().expect("a number");
                assert!(x.is_finite(), "{config}: {name} = {v}");
            }
            if name.ends_with("_goal_current_ma") {
                assert!(
                    v.parse::<f64>().is_ok_and(|ma| ma <= 1000.0),
                    "{config}: {v}"
                );
            }
        }
    }
    let col = |name: &str| header.iter().position(|h| *h == name).expect(name);
    let stage = col("stage");
    let hold: Vec<&Vec<&str>> = rows.iter().filter(|r| r[stage] == "hold").collect();
    let t = col("t_s");
    let span_s: f64 = hold.last().expect("hold rows")[t]
        .parse::<f64>()
        .expect("t")
        - hold[0][t].parse::<f64>().expect("t");
    assert!(span_s >= 2.0, "{config}: held {span_s} s");
    for finger in ["f1", "f2", "f3"] {
        let pads: Vec<usize> = header
            .iter()
            .enumerate()
            .filter(|(_, h)| h.starts_with(&format!("{finger}.")) && h.ends_with("_true_force_n"))
            .map(|(i, _)| i)
            .collect();
        let force: Vec<f64> = hold
            .iter()
            .map(|r| {
                pads.iter()
                    .map(|i| r[*i].parse::<f64>().expect("force"))
                    .sum()
            })
            .collect();
        let (lo, hi) = force
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), y| (a.min(*y), b.max(*y)));
        assert!(
            hi - lo < 0.05 * target,
            "{config} {finger}: true force {lo:.3}..{hi:.3} N over the hold"
        );
        let turns = reversals(&force, 0.01 * target);
        assert!(
            turns as f64 <= span_s.ceil(),
            "{config} {finger}: {turns} reversals in {span_s:.1} s"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_held_force_is_steady_without_camera_noise_at_187_hz() {
    steady_hold("tests/configs/steady-noise0.toml");
}

#[test]
fn the_held_force_is_steady_at_the_bus_maximum_of_53_hz() {
    steady_hold("tests/configs/steady-ratemax.toml");
}

#[test]
fn the_held_force_is_steady_at_5_hz() {
    steady_hold("tests/configs/steady-5hz.toml");
}

#[test]
fn the_held_force_is_steady_at_5x_camera_noise() {
    steady_hold("tests/configs/steady-noise5.toml");
}
