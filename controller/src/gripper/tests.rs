//! The grasp API against the toy finger of the controller's tests: a grasp resolves with
//! the controller's outcome, a second grasp preempts the first, stop, e-stop and release
//! take effect and resolve a waiting call, bad requests are typed errors, and no call
//! outlives the run loop.

use super::*;
use crate::grasp::Phase;
use crate::grasp::tests::{ToyFinger, request, toy, toy_set};

const RATE_HZ: f64 = 30.0;

fn service() -> (GripperService, GripperHandle) {
    GripperService::new(Tuning::default(), vec![150.0; 3], vec![0.0; 3], 1000.0)
}

/// Run the loop for `seconds` as the run loop does: commands, one step per set, goals to
/// the toy fingers. Returns the time reached.
fn drive(
    svc: &mut GripperService,
    fingers: &mut [ToyFinger],
    from_s: f64,
    seconds: f64,
    mut each: impl FnMut(&mut GripperService, f64),
) -> f64 {
    let dt = 1.0 / RATE_HZ;
    let mut goals = svc.goals().unwrap_or_default();
    let mut t = from_s;
    while t < from_s + seconds {
        let positions: Vec<f64> = fingers.iter().map(|f| f.position_deg).collect();
        if svc.apply_commands(&positions) {
            goals = svc.goals().unwrap_or_default();
        }
        let set = toy_set(fingers);
        let states: Vec<ServoState> = fingers
            .iter()
            .enumerate()
            .map(|(i, f)| match goals.get(i) {
                Some(g) => f.state(g),
                None => ServoState {
                    position_deg: f.position_deg,
                    ..ServoState::default()
                },
            })
            .collect();
        if let Some(g) = svc.step(t, Some(&set), &states) {
            goals = g;
        }
        for (f, g) in fingers.iter_mut().zip(&goals) {
            f.step(g, dt);
        }
        each(svc, t);
        t += dt;
    }
    t
}

#[test]
fn a_grasp_through_the_handle_resolves_with_the_controllers_outcome() {
    let (mut svc, handle) = service();
    let mut fingers = toy(Some(50.0));
    assert!(
        svc.step(0.0, None, &[]).is_none(),
        "idle before any command"
    );
    let mut pending = handle.start_grasp(request(2.0)).expect("valid");
    let mut outcome = None;
    drive(&mut svc, &mut fingers, 0.0, 15.0, |_, _| {
        if outcome.is_none() {
            outcome = pending.try_outcome();
        }
    });
    let outcome = outcome.expect("resolved").expect("not stopped");
    assert!(outcome.grasped, "{outcome:?}");
    assert_eq!(outcome.reason, "stable");
    assert_eq!(outcome.status, vec![FingerStatus::ContactClosing; 3]);
    assert!((outcome.final_force_n - 6.0).abs() < 0.6, "{outcome:?}");
}

#[test]
fn a_second_grasp_preempts_the_first() {
    let (mut svc, handle) = service();
    let mut fingers = toy(Some(50.0));
    let mut first = handle.start_grasp(request(2.0)).expect("valid");
    let t = drive(&mut svc, &mut fingers, 0.0, 0.5, |_, _| {});
    let mut second = handle.start_grasp(request(1.0)).expect("valid");
    drive(&mut svc, &mut fingers, t, 0.1, |_, _| {});
    let first = first.try_outcome().expect("resolved").expect("outcome");
    assert_eq!(first.reason, "preempted");
    assert!(!first.grasped);
    assert!(second.try_outcome().is_none(), "the second grasp runs on");
    assert_eq!(svc.controller().map(|c| c.targets_n()), Some(vec![1.0; 3]));
}

#[test]
fn stop_estop_and_release_take_effect_and_resolve_a_waiting_grasp() {
    let (mut svc, handle) = service();
    let mut fingers = toy(Some(50.0));
    let mut pending = handle.start_grasp(request(2.0)).expect("valid");
    let t = drive(&mut svc, &mut fingers, 0.0, 1.0, |_, _| {});
    handle.estop().expect("running");
    let positions: Vec<f64> = fingers.iter().map(|f| f.position_deg).collect();
    assert!(
        svc.apply_commands(&positions),
        "an e-stop is written at once"
    );
    let goals = svc.goals().expect("goals");
    for (g, p) in goals.iter().zip(&positions) {
        assert_eq!(g.position_deg, *p);
        assert_eq!(g.goal_current_ma, Tuning::default().min_current_ma);
    }
    let outcome = pending.try_outcome().expect("resolved").expect("outcome");
    assert_eq!(outcome.reason, "estop");
    // Release after the e-stop, on the same service: the fingers go back open and stay
    // open (the e-stop's hold does not swallow the release).
    let t = drive(&mut svc, &mut fingers, t, 1.0, |_, _| {});
    assert!(
        fingers.iter().all(|f| f.position_deg > 2.0),
        "held closed until the release: {:?}",
        fingers.iter().map(|f| f.position_deg).collect::<Vec<_>>()
    );
    handle.release().expect("running");
    drive(&mut svc, &mut fingers, t, 6.0, |_, _| {});
    assert!(
        fingers.iter().all(|f| f.position_deg <= 2.0),
        "opened: {:?}",
        fingers.iter().map(|f| f.position_deg).collect::<Vec<_>>()
    );
    let phases = svc.controller().map(GraspController::phases);
    assert_eq!(phases, Some(vec![Phase::Open; 3]));
    handle.stop().expect("running");
    assert!(svc.apply_commands(&[1.0, 2.0, 3.0]));
    let held = goal_positions(&svc);
    assert_eq!(held, vec![1.0, 2.0, 3.0]);
}

#[test]
fn a_task_that_owns_the_gripper_refuses_grasps_but_not_stops() {
    let (mut svc, handle) = service();
    let other = handle.clone();
    handle.set_busy(Some("screwdriver"));
    assert_eq!(
        other.busy().as_deref(),
        Some("screwdriver"),
        "clones share it"
    );
    match other.start_grasp(request(2.0)) {
        Err(GripperError::Busy { task }) => assert_eq!(task, "screwdriver"),
        r => panic!("expected Busy, got {r:?}"),
    }
    assert_eq!(svc.commands_applied(), 0);
    other.stop().expect("a stop always goes through");
    other.estop().expect("an e-stop always goes through");
    assert!(svc.apply_commands(&[1.0, 2.0, 3.0]));
    assert_eq!(svc.commands_applied(), 2, "the owner sees the interruption");
    assert_eq!(svc.last_command(), Some(CommandKind::Estop));
    svc.forget();
    assert!(svc.goals().is_none(), "forgotten: nothing is written");
    handle.set_busy(None);
    assert!(other.start_grasp(request(2.0)).is_ok(), "free again");
}

#[test]
fn a_bad_request_is_a_typed_error_naming_the_field() {
    let (_svc, handle) = service();
    let bad = [
        (
            "target_force_n",
            GraspRequest {
                target_force_n: f64::NAN,
                ..request(1.0)
            },
        ),
        (
            "speed_deg_s",
            GraspRequest {
                speed_deg_s: 0.0,
                ..request(1.0)
            },
        ),
        (
            "current_limit_ma",
            GraspRequest {
                current_limit_ma: -1.0,
                ..request(1.0)
            },
        ),
        (
            "timeout_s",
            GraspRequest {
                timeout_s: f64::INFINITY,
                ..request(1.0)
            },
        ),
        (
            "fingers",
            GraspRequest {
                fingers: vec![0, 3],
                ..request(1.0)
            },
        ),
        (
            "fingers",
            GraspRequest {
                fingers: vec![],
                ..request(1.0)
            },
        ),
    ];
    for (field, req) in bad {
        match handle.start_grasp(req) {
            Err(GripperError::InvalidRequest { field: f, .. }) => assert_eq!(f, field),
            other => panic!("{field}: {other:?}"),
        }
    }
}

#[tokio::test]
async fn no_call_outlives_the_run_loop() {
    let (svc, handle) = service();
    let pending = handle.start_grasp(request(1.0)).expect("valid");
    drop(svc);
    assert_eq!(pending.outcome().await, Err(GripperError::Stopped));
    assert_eq!(handle.grasp(request(1.0)).await, Err(GripperError::Stopped));
    assert_eq!(handle.estop(), Err(GripperError::Stopped));
}

#[test]
fn a_grasp_stopped_by_a_call_or_the_watchdog_says_which() {
    for (stop, reason) in [
        (
            GripperHandle::stop as fn(&GripperHandle) -> Result<(), GripperError>,
            "stopped",
        ),
        (GripperHandle::stop_on_watchdog, "watchdog"),
    ] {
        let (mut svc, handle) = service();
        let mut pending = handle.start_grasp(request(2.0)).expect("valid");
        assert!(
            !svc.apply_commands(&[0.0, 0.0, 0.0]),
            "a grasp is not urgent"
        );
        stop(&handle).expect("running");
        assert!(
            svc.apply_commands(&[4.0, 5.0, 6.0]),
            "a stop is written at once"
        );
        let outcome = pending.try_outcome().expect("resolved").expect("outcome");
        assert_eq!(outcome.reason, reason);
        assert!(!outcome.grasped);
        assert_eq!(svc.last_command(), Some(CommandKind::Stop));
        let held = goal_positions(&svc);
        assert_eq!(
            held,
            vec![4.0, 5.0, 6.0],
            "{reason}: the fingers hold where they are"
        );
    }
}

/// The goal positions the service writes, deg.
fn goal_positions(svc: &GripperService) -> Vec<f64> {
    let goals = svc.goals().expect("goals");
    goals.iter().map(|g| g.position_deg).collect()
}

#[test]
fn a_full_queue_refuses_grasps_but_never_a_stop_or_an_e_stop() {
    let (mut svc, handle) = service();
    for _ in 0..COMMAND_QUEUE {
        handle.release().expect("room in the queue");
    }
    assert_eq!(
        handle.release(),
        Err(GripperError::QueueFull {
            capacity: COMMAND_QUEUE
        })
    );
    assert!(matches!(
        handle.start_grasp(request(1.0)),
        Err(GripperError::QueueFull { .. })
    ));
    // A stop and an e-stop on a full queue are kept aside, the e-stop over the stop, and
    // applied after everything queued before them.
    handle.stop().expect("a stop is never refused");
    handle.estop().expect("an e-stop is never refused");
    assert!(svc.apply_commands(&[0.0; 3]), "the e-stop is urgent");
    assert_eq!(svc.commands_applied(), COMMAND_QUEUE as u64 + 1);
    assert_eq!(svc.last_command(), Some(CommandKind::Estop));
    // The queue has room again, and nothing is kept aside.
    handle.release().expect("room again");
    assert!(!svc.apply_commands(&[0.0; 3]));
    assert_eq!(svc.last_command(), Some(CommandKind::Release));
}
