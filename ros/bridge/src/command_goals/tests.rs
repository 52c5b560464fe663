use gelgrip_controller::grasp::FingerStatus;
use gelgrip_ros_wire::actions::CancelCode;
use gelgrip_ros_wire::msgs::Time;

use super::*;

fn request(position: f64, effort: f64) -> SendGoalRequest {
    SendGoalRequest {
        goal_id: [1; 16],
        position,
        max_effort: effort,
    }
}

#[test]
fn goals_with_bad_numbers_are_refused_with_the_field() {
    assert!(check_goal(&request(0.0, 5.0), 1.0).is_ok_and(|g| !g.auto));
    // 0 asks for auto.
    assert!(check_goal(&request(0.0, AUTO_EFFORT), 1.0).is_ok_and(|g| g.auto));
    for (p, e, field) in [
        (0.0, f64::NAN, "max_effort"),
        (0.0, -1.0, "max_effort"),
        (0.0, -1e-9, "max_effort"),
        (0.0, f64::INFINITY, "max_effort"),
        (f64::NAN, 5.0, "position"),
        (-0.1, 5.0, "position"),
        (1.5, 5.0, "position"),
    ] {
        let err = check_goal(&request(p, e), 1.0).expect_err("refused");
        assert!(err.contains(field), "{err}");
    }
}

fn finger(phase: Phase, force_n: f64) -> FingerNow {
    FingerNow {
        phase,
        force_n,
        target_force_n: 5.0,
        opening_rad: 0.5,
    }
}

fn outcome(reason: GraspReason) -> GraspOutcome {
    GraspOutcome {
        grasped: reason.is_stable(),
        status: vec![FingerStatus::ContactClosing; 3],
        final_force_n: 15.0,
        reason,
        settled_force_n: None,
    }
}

#[test]
fn outcomes_map_to_ros2_control_meanings() {
    let held = [finger(Phase::Hold, 5.0); 3];
    let (s, r, _) = finish(Some(&outcome(GraspReason::Stable)), Ending::Grasp, &held);
    assert_eq!(s, GoalStatusCode::Succeeded);
    assert!(r.reached_goal && !r.stalled);
    assert_eq!(r.effort_n, 5.0);
    let short = [finger(Phase::Hold, 2.0); 3];
    let (s, r, _) = finish(
        Some(&outcome(GraspReason::ForceLimited)),
        Ending::Grasp,
        &short,
    );
    assert_eq!(s, GoalStatusCode::Aborted);
    assert!(r.stalled && !r.reached_goal);
    let (s, _, why) = finish(
        Some(&outcome(GraspReason::Preempted)),
        Ending::Grasp,
        &short,
    );
    assert_eq!((s, why.as_str()), (GoalStatusCode::Aborted, "preempted"));
    let (s, _, _) = finish(
        Some(&outcome(GraspReason::Stopped)),
        Ending::Canceled,
        &short,
    );
    assert_eq!(s, GoalStatusCode::Canceled);
    let (s, r, _) = finish(
        Some(&outcome(GraspReason::Stopped)),
        Ending::AtPosition,
        &[],
    );
    assert_eq!(s, GoalStatusCode::Succeeded);
    assert!(!r.reached_goal);
    let (s, r, why) = finish(Some(&outcome(GraspReason::Slipping)), Ending::Grasp, &held);
    assert_eq!((s, why.as_str()), (GoalStatusCode::Aborted, "slipping"));
    assert!(!r.reached_goal && !r.stalled);
    let (s, r, _) = finish(Some(&outcome(GraspReason::Estop)), Ending::Grasp, &held);
    assert_eq!(s, GoalStatusCode::Aborted);
    assert!(!r.reached_goal);
    let (s, _, _) = finish(None, Ending::Grasp, &held);
    assert_eq!(s, GoalStatusCode::Aborted);
}

fn info(id: u8, sec: i32) -> GoalInfo {
    GoalInfo {
        goal_id: [id; 16],
        stamp: Time { sec, nanosec: 0 },
    }
}

#[test]
fn cancels_name_goals_as_action_msgs_says() {
    let goals = [(info(1, 10), true), (info(2, 20), false)];
    assert_eq!(cancel_targets(&info(2, 0), &goals), Ok(vec![info(2, 20)]));
    assert_eq!(
        cancel_targets(&info(9, 0), &goals),
        Err(CancelCode::UnknownGoalId)
    );
    assert_eq!(
        cancel_targets(&info(1, 0), &goals),
        Err(CancelCode::GoalTerminated)
    );
    assert_eq!(cancel_targets(&info(0, 0), &goals), Ok(vec![info(2, 20)]));
    assert_eq!(
        cancel_targets(&info(0, 15), &goals),
        Err(CancelCode::Rejected)
    );
    assert_eq!(cancel_targets(&info(0, 25), &goals), Ok(vec![info(2, 20)]));
    assert_eq!(cancel_targets(&info(0, 0), &[]), Err(CancelCode::Rejected));
}
