//! The runtime's safety paths in process, on the virtual clock, through the library's API
//! (no `gelgrip` process is started): the watchdog, an e-stop mid-squeeze, a task script
//! interrupted by the dashboard's stop, and a servo overload that cannot be recovered.

use gelgrip::session::{RunOptions, Session, run_to_end};
use gelgrip_controller::clock::ClockKind;
use gelgrip_controller::grasp::{Phase, Tuning};
use gelgrip_controller::runtime::RuntimeEvent;
use gelgrip_controller::runtime::outcome::{EndReason, FaultKind};
use gelgrip_controller::task::StageExit;
use tokio::sync::mpsc;

/// The screwdriver script's first stage.
const FIRST_STAGE: &str = "rest";

fn options(config: Option<&str>, scene: Option<&str>, task: &str) -> RunOptions {
    RunOptions {
        config: config.map(Into::into),
        scene: scene.map(Into::into),
        clock: ClockKind::Virtual,
        task: Some(task.into()),
        headless: true,
        duration_s: Some(25.0),
        ..RunOptions::default()
    }
}

/// Step `session` until `done` says so; panics if the run ends first or it takes too long.
async fn step_until(session: &mut Session, what: &str, done: impl Fn(&Session) -> bool) {
    for _ in 0..5_000 {
        if done(session) {
            return;
        }
        if let Some(end) = session.runtime.step().await {
            panic!("the run ended ({end}) before {what}");
        }
    }
    panic!("no {what} in 5000 passes");
}

fn squeezing(session: &Session) -> bool {
    session
        .runtime
        .pilot()
        .is_some_and(|d| d.fingers().iter().any(|(p, _, _)| *p == Phase::Squeeze))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_watchdog_stops_the_fingers_when_sets_stop_coming() {
    let o = options(Some("tests/configs/dead-sensor.toml"), None, "gentle-grasp");
    let report = run_to_end(&o).await.expect("the run is set up");
    assert_eq!(report.end_reason, EndReason::Fault, "{:?}", report.faults);
    assert!(
        report
            .faults
            .first()
            .is_some_and(|f| f.contains("watchdog")),
        "{:?}",
        report.faults
    );
    assert_eq!(report.end_reason.exit_code(), 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_estop_mid_squeeze_holds_every_finger_at_the_minimum_current() {
    let o = options(
        None,
        Some("configs/scenes/rubber-duck.toml"),
        "gentle-grasp",
    );
    let mut session = Session::open(&o).await.expect("the run is set up");
    step_until(&mut session, "a squeeze", squeezing).await;
    let (events, rx) = mpsc::channel(1);
    events.send(RuntimeEvent::Estop).await.expect("queued");
    let end = session.runtime.run(rx).await;
    assert_eq!(end, EndReason::Estop);
    let summary = session.runtime.finish(end);
    assert!(
        summary
            .faults
            .faults()
            .iter()
            .any(|f| f.kind == FaultKind::Estop),
        "{:?}",
        summary.faults
    );
    let plant = session.runtime.pilot().expect("the grasp's pilot").plant();
    let (_, goals) = plant.goals_written_at_once();
    let goals = goals.expect("hold goals were written at once, not for a set");
    let min = Tuning::default().min_current_ma;
    assert_eq!(goals.len(), 3);
    for (goal, state) in goals.iter().zip(plant.states()) {
        assert_eq!(goal.goal_current_ma, min, "{goals:?}");
        // Held where the finger was, not opened or closed further.
        assert!(
            (goal.position_deg - state.position_deg).abs() < 2.0,
            "{goals:?}"
        );
    }
    assert_eq!(summary.end_reason.exit_code(), 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_task_script_is_interrupted_by_the_dashboards_stop_and_the_fingers_hold() {
    let o = options(
        None,
        Some("configs/scenes/screwdriver.toml"),
        "configs/tasks/screwdriver.toml",
    );
    let mut session = Session::open(&o).await.expect("the run is set up");
    // The dashboard's buttons go through this same handle (web/src/routes.rs).
    let gripper = session.runtime.gripper().expect("the grasp API");
    assert!(gripper.busy().is_some(), "the script owns the gripper");
    step_until(&mut session, "the script's second stage", |s| {
        let status = s.runtime.pilot().and_then(|d| d.status());
        // Before its first set the runner has no stage yet (`done`).
        status.is_some_and(|t| t.running && t.stage != FIRST_STAGE && t.stage != "done")
    })
    .await;
    gripper.stop().expect("the loop runs");
    let end = loop {
        if let Some(end) = session.runtime.step().await {
            break end;
        }
    };
    assert_eq!(end, EndReason::Done);
    assert!(gripper.busy().is_none(), "the script let the gripper go");
    let report = session.finish(end);
    let task = report.task.expect("the script's fields");
    assert!(
        task.reason
            .contains("interrupted: stop through the grasp API"),
        "{}",
        task.reason
    );
    assert!(!task.grasped);
    assert!(
        task.stages
            .as_ref()
            .and_then(|s| s.last())
            .is_some_and(|s| s.exit == Some(StageExit::Interrupted)),
        "{:?}",
        task.stages
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_servo_overload_that_cannot_be_recovered_mid_squeeze_ends_the_run_as_a_fault() {
    let o = options(
        Some("tests/configs/overheating-mid-squeeze.toml"),
        None,
        "gentle-grasp",
    );
    let report = run_to_end(&o).await.expect("the run is set up");
    assert_eq!(report.end_reason, EndReason::Fault);
    assert_eq!(report.end_reason.exit_code(), 1);
    assert!(
        report
            .faults
            .iter()
            .any(|f| f.starts_with("servo fault:") && f.contains("persists")),
        "{:?}",
        report.faults
    );
    assert!(!report.task.expect("task fields").grasped);
}
