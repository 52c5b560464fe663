//! Range checks from the hardware (docs/control.md, "Grasp limits"): a force beyond what the
//! fingers can press with at the current cap, a speed beyond the servo's no-load speed and a
//! timeout beyond 120 s are refused with the range named: exit 2 from `gelgrip run --task
//! gentle-grasp` and from a task script, 400 from `POST /api/grasp` on a real `gelgrip run`.
//! The shipped hand at the default 1000 mA presses with at most 163.7 N per finger.

mod common;

use common::gelgrip;
use common::server::{post, start_gelgrip};

/// `gelgrip run --task … extra` (headless, virtual clock): its exit code and stderr.
fn run_task(task: &str, extra: &[&str]) -> (Option<i32>, String) {
    let mut args = vec![
        "run",
        "--headless",
        "--json",
        "--clock",
        "virtual",
        "--duration",
        "1",
        "--task",
        task,
    ];
    args.extend_from_slice(extra);
    let out = gelgrip(&args);
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn the_cli_refuses_a_force_a_speed_a_timeout_and_a_lift_out_of_range_with_exit_2() {
    let cases: [(&[&str], &[&str]); 5] = [
        (
            &["--target-force", "500"],
            &[
                "target_force_n = 500",
                "(0, 163.7] N",
                "what f1, f2, f3 can press with at the 1000 mA current cap",
            ],
        ),
        (
            &["--speed", "1000"],
            &[
                "--speed",
                "(0, 276] deg/s",
                "the XM430-W350's no-load speed, 46 rpm at 12 V",
            ],
        ),
        (
            &["--task-timeout", "500"],
            &["--task-timeout", "(0, 120] s"],
        ),
        (
            &["--lift-rise-s", "61"],
            &["--lift-rise-s", "61 s is outside 0..=60 s"],
        ),
        (
            &["--lift-rise-s=-0.5"],
            &["--lift-rise-s", "-0.5 s is outside 0..=60 s"],
        ),
    ];
    for (args, needles) in cases {
        let (code, err) = run_task("gentle-grasp", args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        for needle in needles {
            assert!(err.contains(needle), "{args:?}: no {needle:?} in {err}");
        }
    }
    // The servos' current limit sets the force bound: 2300 mA (the stall current) allows
    // 376.6 N, and no more.
    let strong = ["--config", "tests/configs/strong-servos.toml"];
    let (code, err) = run_task(
        "gentle-grasp",
        &[&strong[..], &["--target-force", "377"]].concat(),
    );
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("(0, 376.6] N: what f1, f2, f3 can press with at the 2300 mA current cap"),
        "{err}"
    );
}

#[test]
fn a_task_script_with_an_out_of_range_force_or_speed_is_refused_with_exit_2() {
    let dir = common::scratch("grasp-limits-script");
    let shipped = std::fs::read_to_string("configs/tasks/pick-and-release.toml").expect("script");
    for (from, to, needles) in [
        (
            "fingers.f2 = { force_n = 2.0 }",
            "fingers.f2 = { force_n = 500.0 }",
            [
                "stage `close`",
                "`fingers.f2.force_n` = 500",
                "expected a force in [0.01, 163.7] N: what f2 can press with at the 1000 mA current cap",
            ],
        ),
        (
            "fingers.f2 = { force_n = 2.0 }",
            "fingers.f2 = { force_n = 20.0, current_ma = 100 }",
            [
                "stage `close`",
                "`fingers.f2.force_n` = 20",
                "expected a force in [0.01, 16.3] N: what f2 can press with at the 100 mA current cap",
            ],
        ),
        (
            "speed_deg_s = 20.0",
            "speed_deg_s = 1000.0",
            [
                "`speed_deg_s` = 1000",
                "expected a speed in [0.1, 276] deg/s",
                "the XM430-W350's no-load speed",
            ],
        ),
    ] {
        assert!(shipped.contains(from), "{from}");
        let path = dir.join("out-of-range.toml");
        std::fs::write(&path, shipped.replacen(from, to, 1)).expect("script written");
        let file = path.display().to_string();
        let (code, err) = run_task(&file, &[]);
        assert_eq!(code, Some(2), "{to}: {err}");
        assert!(err.contains(&file), "the file is named: {err}");
        for needle in needles {
            assert!(err.contains(needle), "{to}: no {needle:?} in {err}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_grasp_api_answers_400_naming_the_range() {
    let (_run, url) = start_gelgrip(&[]);
    let error = |body: &str| -> String {
        let v: serde_json::Value = serde_json::from_str(body).expect("a JSON body");
        v["error"].as_str().expect("an error message").to_string()
    };
    for (body, needles) in [
        (
            r#"{"target_force_n": 1e308}"#,
            &[
                "target_force_n = 1e308",
                "(0, 163.7] N: what f1, f2, f3 can press with at the 1000 mA current cap",
            ][..],
        ),
        (
            r#"{"target_force_n": 1.5, "speed_deg_s": 1e9}"#,
            &[
                "speed_deg_s = 1e9",
                "(0, 276] deg/s: the XM430-W350's no-load speed, 46 rpm at 12 V",
            ][..],
        ),
        (
            r#"{"target_force_n": 1.5, "timeout_s": 500}"#,
            &["timeout_s = 500", "(0, 120]"][..],
        ),
        (
            r#"{"target_force_n": 100, "current_limit_ma": 500}"#,
            &["(0, 81.8] N", "at the 500 mA current cap"][..],
        ),
    ] {
        let (status, reply) = post(&url, "/api/grasp", body);
        assert_eq!(status, 400, "{body}: {reply}");
        let message = error(&reply);
        for needle in needles {
            assert!(
                message.contains(needle),
                "{body}: no {needle:?} in {message}"
            );
        }
    }
    // Each bound itself is accepted: the grasp starts and ends on its own timeout.
    let (status, reply) = post(
        &url,
        "/api/grasp",
        r#"{"target_force_n": 163.7, "speed_deg_s": 276, "timeout_s": 0.5}"#,
    );
    assert_eq!(status, 200, "{reply}");
}
