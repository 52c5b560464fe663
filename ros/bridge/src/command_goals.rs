//! The `gripper_cmd` action's goals, without the network: what a goal asks
//! ([`GoalRequest`], checked), how a grasp's outcome becomes the action's status and result
//! (as ros2_control's gripper action controller means `stalled` and `reached_goal`), which
//! goals a cancel request names, and the gripper's state as feedback and result carry it.
//! `command` (the Zenoh side) drives these.

use gelgrip_controller::grasp::{GraspOutcome, GraspReason, Phase};
use gelgrip_ros_wire::actions::{GoalInfo, GoalStatusCode, GripperState, SendGoalRequest};

/// Below this `command.position` (rad of opening) a goal closes until contact; above, it
/// also stops at that opening when no contact comes first.
pub const CLOSE_POSITION_RAD: f64 = 0.01;

/// A goal as the action accepts it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GoalRequest {
    /// The opening to stop at when no contact is met, rad (0: close until contact).
    pub position_rad: f64,
    /// The force per finger to regulate to, N (under `auto`, where the fingers close to:
    /// `[grasp] preload_n`).
    pub max_effort_n: f64,
    /// `command.max_effort` was 0: the grasp finds its own force (`auto`).
    pub auto: bool,
}

/// The `command.max_effort` that asks for `auto`: the grasp closes to `[grasp] preload_n`
/// and its slip reflex finds the force (docs/ros.md).
pub const AUTO_EFFORT: f64 = 0.0;

/// Check a `SendGoal` request: the effort a finite force above 0 N (its upper bound is the
/// grasp API's), the position a finite opening within the fingers' travel.
pub fn check_goal(request: &SendGoalRequest, max_opening_rad: f64) -> Result<GoalRequest, String> {
    let effort = request.max_effort;
    let auto = effort == AUTO_EFFORT;
    if !(auto || effort.is_finite() && effort > 0.0) {
        return Err(format!(
            "command.max_effort = {effort}: expected a finite force above 0 N per finger, \
             or 0 for auto"
        ));
    }
    let position = request.position;
    if !(position.is_finite() && (0.0..=max_opening_rad).contains(&position)) {
        return Err(format!(
            "command.position = {position}: expected an opening in [0, {max_opening_rad:.3}] rad \
             (0: close until contact; docs/ros.md)"
        ));
    }
    Ok(GoalRequest {
        position_rad: position,
        max_effort_n: effort,
        auto,
    })
}

/// One finger as the last report showed it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FingerNow {
    /// Its phase.
    pub phase: Phase,
    /// Its regulated force, N.
    pub force_n: f64,
    /// Its force target, N.
    pub target_force_n: f64,
    /// Its opening: the servo's travel left to its closed end, rad.
    pub opening_rad: f64,
}

/// The fingers in contact (touching, squeezing or holding).
pub fn in_contact(fingers: &[FingerNow]) -> bool {
    fingers
        .iter()
        .any(|f| matches!(f.phase, Phase::Contact | Phase::Squeeze | Phase::Hold))
}

/// The gripper's state as feedback carries it: the mean opening, the mean force per
/// finger, `reached_goal` once every finger holds, never `stalled` (only a result says so).
pub fn state_now(fingers: &[FingerNow]) -> GripperState {
    let n = fingers.len().max(1) as f64;
    GripperState {
        position_rad: fingers.iter().map(|f| f.opening_rad).sum::<f64>() / n,
        effort_n: fingers.iter().map(|f| f.force_n).sum::<f64>() / n,
        stalled: false,
        reached_goal: !fingers.is_empty() && fingers.iter().all(|f| f.phase == Phase::Hold),
    }
}

/// Why a goal ended besides its grasp's outcome: what the action did to it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ending {
    /// Nothing: the grasp ended on its own, or by another command.
    Grasp,
    /// A cancel request stopped it.
    Canceled,
    /// It reached `command.position` without contact and was stopped there.
    AtPosition,
}

/// The action's status and result for a grasp that ended with `outcome` (`None`: the run
/// loop stopped first), the fingers as they were then.
pub fn finish(
    outcome: Option<&GraspOutcome>,
    ending: Ending,
    fingers: &[FingerNow],
) -> (GoalStatusCode, GripperState, String) {
    let mut state = state_now(fingers);
    state.reached_goal = false;
    let Some(o) = outcome else {
        return (
            GoalStatusCode::Aborted,
            state,
            "the run loop stopped".into(),
        );
    };
    let reason = o.reason.to_string();
    let status = match (o.reason, ending) {
        (GraspReason::Stable, _) => {
            state.reached_goal = true;
            GoalStatusCode::Succeeded
        }
        (GraspReason::Stopped, Ending::AtPosition) => GoalStatusCode::Succeeded,
        (GraspReason::Stopped, Ending::Canceled) => GoalStatusCode::Canceled,
        (GraspReason::ForceLimited, _) => {
            state.stalled = true;
            GoalStatusCode::Aborted
        }
        (GraspReason::Timeout { .. }, _) => {
            state.stalled = in_contact(fingers);
            GoalStatusCode::Aborted
        }
        _ => GoalStatusCode::Aborted,
    };
    let why = match (o.reason, ending) {
        (GraspReason::Stopped, Ending::AtPosition) => "at the commanded opening, no contact".into(),
        (GraspReason::Stopped, Ending::Canceled) => "canceled: holding".into(),
        _ => reason,
    };
    (status, state, why)
}

/// Which of `goals` (id, accepted at, ended) a cancel request for `request` names, as
/// `action_msgs/srv/CancelGoal` defines it: a zero id and zero stamp, every goal; a zero id,
/// the goals accepted at or before the stamp; an id, that goal (and, with a stamp, those
/// accepted at or before it). `Err`: the id is unknown, or it names a goal that has ended.
pub fn cancel_targets(
    request: &GoalInfo,
    goals: &[(GoalInfo, bool)],
) -> Result<Vec<GoalInfo>, gelgrip_ros_wire::actions::CancelCode> {
    use gelgrip_ros_wire::actions::CancelCode;
    let zero_id = request.goal_id == [0; 16];
    let stamp_ns = request.stamp.unix_ns();
    let mut out = Vec::new();
    if !zero_id {
        match goals.iter().find(|(g, _)| g.goal_id == request.goal_id) {
            None => return Err(CancelCode::UnknownGoalId),
            Some((_, true)) if stamp_ns == 0 => return Err(CancelCode::GoalTerminated),
            Some((g, false)) => out.push(*g),
            Some((_, true)) => {}
        }
    }
    for (g, ended) in goals {
        let by_stamp = if zero_id && stamp_ns == 0 {
            true
        } else {
            stamp_ns != 0 && g.stamp.unix_ns() <= stamp_ns
        };
        if by_stamp && !ended && !out.contains(g) {
            out.push(*g);
        }
    }
    if out.is_empty() {
        return Err(if zero_id {
            CancelCode::Rejected
        } else {
            CancelCode::GoalTerminated
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
