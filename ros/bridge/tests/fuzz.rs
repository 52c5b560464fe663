//! Property tests of what the GripperCommand action makes of a decoded request (issue 45),
//! after `gelgrip-ros-wire`'s decoders (fuzzed in `ros/wire/tests/fuzz.rs`): `check_goal`
//! accepts exactly the goals with a finite effort above 0 N and a finite opening within
//! the fingers' travel, whatever the bytes said (NaN, infinities, subnormals, negative
//! zero); `cancel_targets` answers any cancel request against any set of goals as
//! `action_msgs/srv/CancelGoal` defines it, never panicking and never naming a goal that
//! is not there or has ended.
//!
//! Case counts: `PROPTEST_CASES` (proptest's 256 when unset), capped per test so that
//! `scripts/test`'s 30 000-case step stays short; `GELGRIP_FUZZ_CASES` sets the exact count
//! for a long run outside CI (docs/reliability.md).

use proptest::prelude::*;

use gelgrip_ros_bridge::command_goals::{cancel_targets, check_goal};
use gelgrip_ros_wire::actions::{CancelCode, GoalInfo, SendGoalRequest};
use gelgrip_ros_wire::msgs::Time;

/// Cases per test in CI: all of `scripts/test`'s 30 000 (a check takes nanoseconds).
const CI_CASES: u32 = 30_000;

#[path = "../../../testsupport/fuzz_runner.rs"]
mod fuzz_runner;
use fuzz_runner::check;

/// Any float a request's bytes may hold, the edges weighted up.
fn float() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<f64>(),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(-0.0),
        Just(0.0),
        Just(f64::MIN_POSITIVE / 2.0),
        Just(f64::MAX),
        -10.0f64..10.0,
    ]
}

#[test]
fn a_goal_is_accepted_exactly_when_its_effort_and_opening_are_in_range() {
    let strategy = (any::<[u8; 16]>(), float(), float(), 0.0f64..4.0);
    check(
        CI_CASES,
        strategy,
        |(goal_id, position, max_effort, max_opening)| {
            let request = SendGoalRequest {
                goal_id,
                position,
                max_effort,
            };
            // 0 (either sign) asks for auto.
            let auto = max_effort == 0.0;
            let ok = (auto || max_effort.is_finite() && max_effort > 0.0)
                && position.is_finite()
                && (0.0..=max_opening).contains(&position);
            match check_goal(&request, max_opening) {
                Ok(goal) => {
                    assert!(ok, "{request:?} accepted");
                    assert_eq!(goal.position_rad.to_bits(), position.to_bits());
                    assert_eq!(goal.max_effort_n.to_bits(), max_effort.to_bits());
                    assert_eq!(goal.auto, auto);
                }
                Err(why) => {
                    assert!(!ok, "{request:?} refused: {why}");
                    assert!(why.contains("command."), "{why}");
                }
            }
        },
    );
}

/// Goal ids from a small pool (so that requests name known goals), or the zero id.
fn goal_id() -> impl Strategy<Value = [u8; 16]> {
    prop_oneof![
        1 => Just([0u8; 16]),
        4 => (1u8..6).prop_map(|n| [n; 16]),
        1 => any::<[u8; 16]>(),
    ]
}

fn time() -> impl Strategy<Value = Time> {
    prop_oneof![
        Just(Time { sec: 0, nanosec: 0 }),
        (0i32..10, 0u32..1_000_000_000).prop_map(|(sec, nanosec)| Time { sec, nanosec }),
        (any::<i32>(), any::<u32>()).prop_map(|(sec, nanosec)| Time { sec, nanosec }),
    ]
}

fn goal_info() -> impl Strategy<Value = GoalInfo> {
    (goal_id(), time()).prop_map(|(goal_id, stamp)| GoalInfo { goal_id, stamp })
}

#[test]
fn a_cancel_names_only_known_running_goals_or_says_why_not() {
    let goals = proptest::collection::vec((goal_info(), any::<bool>()), 0..8);
    check(
        CI_CASES,
        (goal_info(), goals),
        |(request, goals)| match cancel_targets(&request, &goals) {
            Ok(targets) => {
                assert!(!targets.is_empty());
                for t in &targets {
                    assert!(goals.iter().any(|(g, ended)| g == t && !ended), "{t:?}");
                }
            }
            Err(CancelCode::UnknownGoalId) => {
                assert_ne!(request.goal_id, [0; 16]);
                assert!(goals.iter().all(|(g, _)| g.goal_id != request.goal_id));
            }
            Err(code) => {
                assert!(matches!(
                    code,
                    CancelCode::Rejected | CancelCode::GoalTerminated
                ));
            }
        },
    );
}
