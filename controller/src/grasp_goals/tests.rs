//! Goals over the grasp API, with the service applying commands as the run loop does: ids
//! count up from 1, a second goal preempts the first, refused requests use no id, a
//! stopped run loop ends every goal, and only the last [`GraspGoals::KEPT`] are kept.

use super::*;
use crate::grasp::tests::request;
use crate::grasp::{GraspReason, Tuning};
use crate::gripper::GripperService;

fn service() -> (GripperService, GripperHandle) {
    GripperService::new(Tuning::default(), vec![150.0; 3], vec![0.0; 3], 1000.0)
}

#[test]
fn a_goal_runs_until_a_second_preempts_it() {
    let (mut svc, handle) = service();
    let goals = GraspGoals::new();
    assert_eq!(goals.latest(), None);
    let first = goals.start(&handle, request(2.0)).expect("accepted");
    assert_eq!(first, 1);
    svc.apply_commands(&[0.0; 3]);
    let s = goals.status(first).expect("kept");
    assert_eq!(s.state, GoalState::Running);
    assert_eq!(s.result, None);

    let second = goals.start(&handle, request(2.0)).expect("accepted");
    assert_eq!(second, 2);
    svc.apply_commands(&[0.0; 3]);
    let s = goals.status(first).expect("kept");
    assert_eq!(s.state, GoalState::Done);
    let result = s.result.expect("an outcome");
    assert_eq!(result.reason, GraspReason::Preempted);
    assert!(!result.grasped);
    assert_eq!(
        goals.latest().map(|g| (g.id, g.state)),
        Some((2, GoalState::Running))
    );
    assert_eq!(goals.status(3), None, "never started");
}

#[test]
fn refused_requests_use_no_id_and_a_stopped_loop_ends_every_goal() {
    let (svc, handle) = service();
    let goals = GraspGoals::new();
    let mut bad = request(2.0);
    bad.speed_deg_s = f64::NAN;
    assert!(matches!(
        goals.start(&handle, bad),
        Err(GripperError::InvalidRequest { .. })
    ));
    handle.set_busy(Some("screwdriver"));
    assert!(matches!(
        goals.start(&handle, request(2.0)),
        Err(GripperError::Busy { .. })
    ));
    handle.set_busy(None);
    let id = goals.start(&handle, request(2.0)).expect("accepted");
    assert_eq!(id, 1, "refusals took no id");
    drop(svc);
    let s = goals.status(id).expect("kept");
    assert_eq!(s.state, GoalState::Done);
    assert_eq!(s.result, None);
    assert!(
        s.error.as_deref().is_some_and(|e| e.contains("stopped")),
        "{s:?}"
    );
}

#[test]
fn only_the_last_hundred_are_kept() {
    let (mut svc, handle) = service();
    let goals = GraspGoals::new();
    for _ in 0..(GraspGoals::KEPT + 5) {
        goals.start(&handle, request(2.0)).expect("accepted");
        svc.apply_commands(&[0.0; 3]);
    }
    assert_eq!(goals.status(5), None);
    assert!(goals.status(6).is_some());
    assert_eq!(goals.latest().map(|g| g.id), Some(105));
}
