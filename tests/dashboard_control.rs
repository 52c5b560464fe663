//! The dashboard's controls against a real `gelgrip run` on the simulator, over HTTP: a
//! task script started from the page runs to completion; while it runs, a second task, a
//! grasp and a scene switch are conflicts (409); a stop interrupts it and the fingers hold;
//! an injected capture delay makes the gate refuse sets; scenes switch by name; e-stop is
//! carried out; grasps as goals answer at once, report running, end as the blocking grasp
//! does, and preempt each other.

use std::time::Duration;

use serde_json::Value;

mod common;
use common::server::{post, start_gelgrip, state, wait_until};

fn rejected(s: &Value) -> u64 {
    let sum = |v: &Value| -> u64 {
        v.as_object()
            .map_or(0, |m| m.values().filter_map(Value::as_u64).sum())
    };
    sum(&s["sync"]["sets_rejected"]) + sum(&s["sync"]["drops"])
}

fn task_done(url: &str) -> Option<Value> {
    let s = state(url);
    let task = s["task"].clone();
    (task["running"] == false && task["name"] == "pick-and-release").then_some(task)
}

#[test]
fn tasks_faults_and_scenes_from_the_dashboard() {
    let (_run, url) = start_gelgrip(&["--scene", "configs/scenes/tennis-ball.toml"]);
    let s = wait_until(Duration::from_secs(30), "sets", || {
        let s = state(&url);
        (s["sync"]["sets"].as_u64() > Some(10)).then_some(s)
    });
    let names: Vec<&str> = s["tasks_available"]
        .as_array()
        .expect("tasks_available")
        .iter()
        .filter_map(Value::as_str)
        .collect();
    assert!(
        names.contains(&"pick-and-release") && names.contains(&"screwdriver"),
        "{names:?}"
    );
    assert_eq!(s["sim"]["scene"], "tennis-ball");
    assert!(s["task"].is_null(), "no task yet");
    // Each sensor's frame age at fusion: about one set latency (29.5 ms) on the simulator.
    let ages: Vec<Option<f64>> = s["sensors"]
        .as_array()
        .expect("sensors")
        .iter()
        .map(|x| x["frame_age_ms"].as_f64())
        .collect();
    assert!(
        ages.len() == 7
            && ages
                .iter()
                .all(|a| a.is_some_and(|ms| ms > 1.0 && ms < 500.0)),
        "{ages:?}"
    );

    // A scene switch with open fingers.
    let (status, body) = post(&url, "/api/sim/scene", r#"{"name": "egg"}"#);
    assert_eq!(status, 200, "{body}");
    let (status, body) = post(&url, "/api/sim/scene", r#"{"name": "moon"}"#);
    assert_eq!(status, 400, "{body}");
    assert!(
        body.contains("tennis-ball"),
        "the error lists the scenes: {body}"
    );
    assert!(
        state(&url)["sim"]["scenes"]
            .as_array()
            .is_some_and(|s| s.len() >= 7),
        "none and the six scenes"
    );
    wait_until(Duration::from_secs(2), "the scene in the state", || {
        (state(&url)["sim"]["scene"] == "egg").then_some(())
    });

    // A fresh tennis ball (scenes let go of their object a few seconds in; switching
    // places it again), then a task from the page; while it runs the gripper is busy.
    let fresh_ball = || {
        // The fingers must be open; after a task's release stage they may still be on
        // their way.
        wait_until(Duration::from_secs(10), "open fingers", || {
            state(&url)["servos"]
                .as_array()
                .is_some_and(|s| s.iter().all(|s| s["position_deg"].as_f64() < Some(5.0)))
                .then_some(())
        });
        let (status, body) = post(&url, "/api/sim/scene", r#"{"name": "tennis-ball"}"#);
        assert_eq!(status, 200, "{body}");
    };
    fresh_ball();
    let task = r#"{"name": "pick-and-release"}"#;
    let (status, body) = post(&url, "/api/task", task);
    assert_eq!(status, 200, "{body}");
    let (status, body) = post(&url, "/api/task", task);
    assert_eq!(status, 409, "a second task: {body}");
    let (status, body) = post(&url, "/api/grasp", r#"{"target_force_n": 1}"#);
    assert_eq!(status, 409, "a grasp: {body}");
    let (status, body) = post(&url, "/api/sim/scene", r#"{"name": "tennis-ball"}"#);
    assert_eq!(status, 409, "a scene switch: {body}");
    let (status, body) = post(&url, "/api/task", r#"{"name": "juggle"}"#);
    assert!(status == 409 || status == 400, "{status} {body}");
    let done = wait_until(Duration::from_secs(40), "the task to end", || {
        task_done(&url)
    });
    assert_eq!(done["outcome"], "completed", "{done}");
    assert_eq!(done["stage"], "done");

    // Again, and stop it while it holds: it ends interrupted and every finger holds where
    // it is (the controller's stopped phase is `fault`, docs/control.md).
    fresh_ball();
    let (status, body) = post(&url, "/api/task", task);
    assert_eq!(status, 200, "{body}");
    wait_until(Duration::from_secs(20), "the hold stage", || {
        (state(&url)["task"]["stage"] == "hold").then_some(())
    });
    let (status, body) = post(&url, "/api/stop", "");
    assert_eq!(status, 200, "{body}");
    let stopped = wait_until(Duration::from_secs(5), "the stop", || task_done(&url));
    let outcome = stopped["outcome"].as_str().unwrap_or_default();
    assert!(outcome.contains("stop"), "{stopped}");
    let fingers = state(&url)["fingers"].clone();
    assert!(
        fingers
            .as_array()
            .is_some_and(|f| f.iter().all(|f| f["phase"] == "fault")),
        "{fingers}"
    );
    // Closed fingers: no scene switch until they open.
    let (status, body) = post(&url, "/api/sim/scene", r#"{"name": "none"}"#);
    assert_eq!(status, 409, "{body}");
    assert!(body.contains("release"), "{body}");

    // A capture delay far past the gate's spread limit: sets are refused.
    let before = rejected(&state(&url));
    let fault = r#"{"sensor": "f1.tip", "capture_delay_us": 40000}"#;
    let (status, body) = post(&url, "/api/sim/fault", fault);
    assert_eq!(status, 200, "{body}");
    wait_until(Duration::from_secs(10), "refused sets", || {
        (rejected(&state(&url)) >= before + 10).then_some(())
    });
    assert_eq!(state(&url)["sim"]["faults"][0]["sensor"], "f1.tip");
    let (status, _) = post(&url, "/api/sim/fault", r#"{"sensor": "f1.tip"}"#);
    assert_eq!(status, 200);
    wait_until(Duration::from_secs(2), "the faults cleared", || {
        (state(&url)["sim"]["faults"] == serde_json::json!([])).then_some(())
    });

    let (status, body) = post(&url, "/api/estop", "");
    assert_eq!(status, 200, "{body}");
}

#[test]
fn the_simulated_hub_unplugs_and_a_servo_overloads_on_request() {
    let (_run, url) = start_gelgrip(&[]);
    wait_until(Duration::from_secs(30), "sets", || {
        (state(&url)["sync"]["sets"].as_u64() > Some(10)).then_some(())
    });
    for bad in [r#"{"ms": 0}"#, r#"{"ms": 600000}"#, r#"{"seconds": 1}"#] {
        let (status, body) = post(&url, "/api/sim/unplug", bad);
        assert_eq!(status, 400, "{bad}: {body}");
    }
    let disconnected = |s: &Value| {
        s["sync"]["sets_rejected"]["disconnected"]
            .as_u64()
            .unwrap_or(0)
    };
    let before = disconnected(&state(&url));
    let (status, body) = post(&url, "/api/sim/unplug", r#"{"ms": 500}"#);
    assert_eq!(status, 200, "{body}");
    // About one set per period of the outage is lost, then sets flow again.
    let after = wait_until(Duration::from_secs(10), "the outage counted", || {
        let s = state(&url);
        (disconnected(&s) >= before + 5).then_some(s)
    });
    let sets = after["sync"]["sets"].as_u64().unwrap_or(0);
    wait_until(Duration::from_secs(10), "sets again", || {
        (state(&url)["sync"]["sets"].as_u64() > Some(sets + 10)).then_some(())
    });

    let (status, body) = post(
        &url,
        "/api/sim/servo",
        r#"{"finger": "f9", "fault": "overload"}"#,
    );
    assert_eq!(status, 404, "{body}");
    let (status, body) = post(
        &url,
        "/api/sim/servo",
        r#"{"finger": "f1", "fault": "melt"}"#,
    );
    assert_eq!(status, 400, "{body}");
    let (status, body) = post(
        &url,
        "/api/sim/servo",
        r#"{"finger": "f1", "fault": "overload"}"#,
    );
    assert_eq!(status, 200, "{body}");
}

/// `GET /api/grasps/{id}`, parsed.
fn goal(url: &str, id: u64) -> Value {
    let (status, body) = common::server::http(url, "GET", &format!("/api/grasps/{id}"), None);
    assert_eq!(status, 200, "{body}");
    serde_json::from_str(&body).expect("goal JSON")
}

/// Release, wait for open fingers, and place the ball afresh.
fn fresh_ball(url: &str) {
    let (status, body) = post(url, "/api/release", "");
    assert_eq!(status, 200, "{body}");
    wait_until(Duration::from_secs(15), "open fingers", || {
        state(url)["servos"]
            .as_array()
            .is_some_and(|s| s.iter().all(|s| s["position_deg"].as_f64() < Some(5.0)))
            .then_some(())
    });
    let (status, body) = post(url, "/api/sim/scene", r#"{"name": "tennis-ball"}"#);
    assert_eq!(status, 200, "{body}");
}

#[test]
fn grasp_goals_answer_at_once_report_progress_and_end_as_the_blocking_grasp() {
    // The default config's dashboard run: the tennis ball, held until grasped.
    let (_run, url) = start_gelgrip(&[]);
    wait_until(Duration::from_secs(30), "sets", || {
        (state(&url)["sync"]["sets"].as_u64() > Some(10)).then_some(())
    });
    assert_eq!(state(&url)["sim"]["scene"], "tennis-ball");
    let body = r#"{"target_force_n": 1.5}"#;

    // The goal is accepted while the grasp runs, and reports running, then its result.
    let (status, reply) = post(&url, "/api/grasps", body);
    assert_eq!(status, 202, "{reply}");
    let id = serde_json::from_str::<Value>(&reply).expect("JSON")["id"]
        .as_u64()
        .expect("an id");
    assert_eq!(id, 1, "ids count from 1");
    let running = goal(&url, id);
    assert_eq!(running["state"], "running", "{running}");
    assert!(running["result"].is_null(), "{running}");
    let done = wait_until(Duration::from_secs(25), "the goal's end", || {
        let g = goal(&url, id);
        (g["state"] == "done").then_some(g)
    });
    let goal_result = done["result"].clone();
    assert_eq!(goal_result["grasped"], true, "{done}");

    // The blocking grasp on the same scene ends the same way.
    fresh_ball(&url);
    let (status, reply) = post(&url, "/api/grasp", body);
    assert_eq!(status, 200, "{reply}");
    let blocking: Value = serde_json::from_str(&reply).expect("JSON");
    for field in ["grasped", "status", "reason"] {
        assert_eq!(
            goal_result[field], blocking[field],
            "{field}: {goal_result} vs {blocking}"
        );
    }
    let (a, b) = (
        goal_result["final_force_n"].as_f64().expect("force"),
        blocking["final_force_n"].as_f64().expect("force"),
    );
    assert!((a - b).abs() <= 0.15 * b, "final force {a} N vs {b} N");

    // A second goal preempts the first.
    fresh_ball(&url);
    let (status, first) = post(&url, "/api/grasps", body);
    assert_eq!(status, 202, "{first}");
    assert_eq!(first, r#"{"id":2}"#);
    let (status, second) = post(&url, "/api/grasps", body);
    assert_eq!(status, 202, "{second}");
    let preempted = wait_until(Duration::from_secs(5), "the first goal's end", || {
        let g = goal(&url, 2);
        (g["state"] == "done").then_some(g)
    });
    assert_eq!(preempted["result"]["reason"], "preempted", "{preempted}");
    assert_eq!(goal(&url, 3)["state"], "running");

    // Unknown ids.
    for unknown in ["/api/grasps/99", "/api/grasps/0", "/api/grasps/one"] {
        let (status, body) = common::server::http(&url, "GET", unknown, None);
        assert_eq!(status, 404, "{unknown}: {body}");
    }
}
