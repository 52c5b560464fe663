//! Task scripts: validation (every error names the file and the stage) and the runner on
//! hand-made fused sets.

use super::runner::{StageExit, TaskRunner};
use super::script::{Branch, FingerTarget, ScriptError, Source, TaskScript, Test};
use super::signals::{History, slope_per_s};
use crate::actuator::ServoState;
use crate::fusion::{SensorReading, fuse};
use crate::grasp::{Phase, TargetForce, Tuning};
use crate::layout::HandLayout;

fn layout() -> HandLayout {
    HandLayout::from_toml(
        "three-finger.toml",
        include_str!("../../../configs/layouts/three-finger.toml"),
    )
    .expect("layout")
}

fn parse(text: &str) -> Result<TaskScript, ScriptError> {
    TaskScript::from_toml("t.toml", text, &layout(), 800.0)
}

const TWO_STAGES: &str = r#"
version = 1
name = "two"
[[stage]]
name = "touch"
timeout_s = 2.0
on_timeout = "recover"
fingers.f1 = { force_n = 2.0 }
[[stage.exit]]
sensor = "f1.tip"
contact = true
for_s = 0.1
[[stage]]
name = "settle"
timeout_s = 5.0
[[stage.exit]]
sensor = "f1.tip"
rise_mm3_min = 10.0
slope_mm3_per_s_min = -2.0
slope_mm3_per_s_max = 2.0
window_s = 0.3
[[stage]]
name = "recover"
timeout_s = 1.0
next = "abort"
fingers.f1 = { open = true }
[[stage.exit]]
finger = "f1"
force_n_max = 0.1
"#;

fn err_text(text: &str) -> String {
    parse(text).expect_err("must be refused").to_string()
}

#[test]
fn auto_forces_and_settled_bounds_parse_and_bad_words_are_refused() {
    let s = parse(include_str!(
        "../../../configs/tasks/auto-pick-and-release.toml"
    ))
    .expect("valid");
    assert!(matches!(
        s.stages[0].fingers[0].map(|c| c.target),
        Some(FingerTarget::Force {
            force: TargetForce::Auto,
            current_ma: None
        })
    ));
    assert_eq!(
        s.stages[0].exit[0].tests,
        [Test::Contact(true), Test::ForceMinSettled]
    );
    assert!(s.stages[0].exit[0].label.contains("force_n ≥ settled"));
    let max = TWO_STAGES.replace("force_n_max = 0.1", "force_n_max = \"settled\"");
    assert_eq!(
        parse(&max).expect("valid").stages[2].exit[0].tests,
        [Test::ForceMaxSettled]
    );
    let e = err_text(&TWO_STAGES.replace("force_n_max = 0.1", "force_n_max = \"most\""));
    assert!(
        e.contains("stage `recover`")
            && e.contains("`exit[0].force_n_max`")
            && e.contains("= \"most\": expected a force in N or \"settled\""),
        "{e}"
    );
    let e = err_text(&TWO_STAGES.replace("{ force_n = 2.0 }", "{ force_n = \"Auto\" }"));
    assert!(e.contains("force_n") && e.contains("\"auto\""), "{e}");
    // A number beside "auto" is still bounded by what the finger can press.
    let e = err_text(&TWO_STAGES.replace("{ force_n = 2.0 }", "{ force_n = -1.0 }"));
    assert!(
        e.contains("fingers.f1.force_n") && e.contains("expected a force"),
        "{e}"
    );
}

#[test]
fn a_valid_script_parses_with_its_defaults() {
    let s = parse(TWO_STAGES).expect("valid");
    assert_eq!(s.stages.len(), 3);
    assert_eq!(s.stages[0].next, Branch::Stage(1));
    assert_eq!(s.stages[0].on_timeout, Branch::Stage(2));
    assert_eq!(s.stages[1].next, Branch::Stage(2), "the following stage");
    assert_eq!(s.stages[1].on_timeout, Branch::Abort, "default");
    assert_eq!(s.stages[2].next, Branch::Abort);
    assert!(matches!(
        s.stages[0].fingers[0].map(|c| c.target),
        Some(FingerTarget::Force { force: TargetForce::Newtons(n), current_ma: None }) if n == 2.0
    ));
    assert_eq!(s.stages[0].fingers[1], None, "unnamed fingers keep theirs");
    assert_eq!(s.stages[0].exit[0].sources, vec![Source::Sensor(1)]);
    assert_eq!(s.stages[1].exit[0].tests.len(), 3);
    assert!(s.stages[1].exit[0].tests.contains(&Test::RiseMin(10.0)));
    assert_eq!(s.stages[2].exit[0].sources, vec![Source::Finger(0)]);
}

#[test]
fn the_shipped_screwdriver_script_is_valid() {
    let s = parse(include_str!("../../../configs/tasks/screwdriver.toml")).expect("valid");
    let names: Vec<&str> = s.stages.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "rest",
            "grip",
            "press-trigger",
            "tighten",
            "release-trigger",
            "release-body"
        ]
    );
    assert!(s.stages.iter().all(|s| !s.exit.is_empty()));
}

#[test]
fn an_unknown_sensor_id_is_named_with_the_file_stage_and_choices() {
    let e = err_text(&TWO_STAGES.replace(
        "sensor = \"f1.tip\"\ncontact",
        "sensor = \"f4.tip\"\ncontact",
    ));
    assert!(
        e.starts_with("t.toml: stage `touch`: `exit[0].sensor`"),
        "{e}"
    );
    assert!(
        e.contains("\"f4.tip\"") && e.contains("f1.middle, f1.tip"),
        "{e}"
    );
}

#[test]
fn an_unknown_finger_is_refused() {
    let e = err_text(&TWO_STAGES.replace("fingers.f1 = { force_n", "fingers.f9 = { force_n"));
    assert!(
        e.contains("stage `touch`") && e.contains("fingers.f9"),
        "{e}"
    );
    let e = err_text(&TWO_STAGES.replace("finger = \"f1\"", "finger = \"thumb\""));
    assert!(e.contains("stage `recover`") && e.contains("thumb"), "{e}");
}

#[test]
fn an_unreachable_stage_is_refused() {
    // Without the timeout branch nothing leads to `recover`.
    let e = err_text(
        &TWO_STAGES
            .replace("on_timeout = \"recover\"\n", "")
            .replace(
                "name = \"settle\"\n",
                "name = \"settle\"\nnext = \"done\"\n",
            ),
    );
    assert!(e.contains("unreachable stage(s): recover"), "{e}");
    assert!(e.starts_with("t.toml: "), "{e}");
}

#[test]
fn a_missing_timeout_is_refused() {
    let e = err_text(&TWO_STAGES.replace("timeout_s = 5.0\n", ""));
    assert!(e.contains("stage `settle`: `timeout_s` is missing"), "{e}");
}

/// At the tests' 800 mA cap a shipped finger presses with at most 131.0 N (docs/control.md,
/// "Grasp limits"); the XM430-W350 turns at most 276 deg/s.
#[test]
fn forces_and_speeds_beyond_the_hardware_are_refused_with_the_range() {
    let edge = TWO_STAGES.replace(
        "{ force_n = 2.0 }",
        "{ force_n = 131.0, speed_deg_s = 276.0 }",
    );
    assert!(parse(&edge).is_ok(), "each bound itself is accepted");
    let cases = [
        (
            "{ force_n = 131.1 }",
            "stage `touch`: `fingers.f1.force_n` = 131.1: expected a force in [0.01, 131] N: \
             what f1 can press with at the 800 mA current cap",
        ),
        (
            "{ force_n = 20.0, current_ma = 100.0 }",
            "`fingers.f1.force_n` = 20: expected a force in [0.01, 16.3] N: what f1 can press \
             with at the 100 mA current cap",
        ),
        (
            "{ force_n = 2.0, speed_deg_s = 276.5 }",
            "`fingers.f1.speed_deg_s` = 276.5: expected a speed in [0.1, 276] deg/s: the \
             XM430-W350's no-load speed, 46 rpm at 12 V",
        ),
        ("{ force_n = inf }", "`fingers.f1.force_n` = inf"),
    ];
    for (target, want) in cases {
        let e = err_text(&TWO_STAGES.replace("{ force_n = 2.0 }", target));
        assert!(e.contains(want), "wanted {want:?} in: {e}");
    }
    let e = err_text(&TWO_STAGES.replace("name = \"two\"", "name = \"two\"\nspeed_deg_s = 1e9"));
    assert!(
        e.contains("`speed_deg_s` = 1e9: expected a speed in [0.1, 276] deg/s"),
        "{e}"
    );
}

#[test]
fn other_malformed_scripts_are_refused_with_the_stage_named() {
    let cases = [
        // No exit condition: a stage must end on a tactile event.
        (
            TWO_STAGES.replace("[[stage.exit]]\nfinger = \"f1\"\nforce_n_max = 0.1\n", ""),
            "stage `recover`: `exit` is empty",
        ),
        (
            TWO_STAGES.replace("on_timeout = \"recover\"", "on_timeout = \"nowhere\""),
            "`on_timeout` = \"nowhere\": no such stage",
        ),
        (
            TWO_STAGES.replace("name = \"recover\"", "name = \"touch\""),
            "used by an earlier stage",
        ),
        (
            TWO_STAGES.replace(
                "{ force_n = 2.0 }",
                "{ force_n = 2.0, position_deg = 10.0 }",
            ),
            "must set exactly one of",
        ),
        (
            TWO_STAGES.replace("{ force_n = 2.0 }", "{ current_ma = 5000.0 }"),
            "fingers.f1.current_ma` = 5000: expected a number in [0, 800]",
        ),
        (
            TWO_STAGES.replace("{ force_n = 2.0 }", "{ force_n = nan }"),
            "force_n` = NaN",
        ),
        (
            TWO_STAGES.replace("contact = true\nfor_s", "for_s"),
            "`exit[0]` has no test",
        ),
        (
            TWO_STAGES.replace("timeout_s = 2.0", "timeout_s = -1.0"),
            "timeout_s` = -1",
        ),
        (
            TWO_STAGES.replace("for_s = 0.1", "for_s = 0.1\nbogus = 1"),
            "unknown field `bogus`",
        ),
        // A stage key written after the stage's [[stage.exit]] belongs to that exit.
        (
            TWO_STAGES.replace("for_s = 0.1", "for_s = 0.1\nnext = \"settle\""),
            "stage keys (next, on_timeout, timeout_s, …) go before the stage's [[stage.exit]]",
        ),
        (
            TWO_STAGES.replace("version = 1", "version = 2"),
            "`version` = 2",
        ),
        ("version = 1\nname = \"x\"\n".to_string(), "no stages"),
    ];
    for (text, want) in cases {
        let e = err_text(&text);
        assert!(e.contains(want), "wanted {want:?} in: {e}");
        assert!(e.starts_with("t.toml: "), "{e}");
    }
}

#[test]
fn slopes_are_least_squares_and_need_enough_samples() {
    let line: Vec<(f64, f64)> = (0..10)
        .map(|i| (i as f64 * 0.1, 3.0 + 5.0 * i as f64 * 0.1))
        .collect();
    assert!((slope_per_s(&line).expect("slope") - 5.0).abs() < 1e-9);
    assert_eq!(slope_per_s(&line[..2]), None);
    assert_eq!(
        slope_per_s(&[(1.0, 1.0), (1.0, 2.0), (1.0, 3.0)]),
        None,
        "no time span"
    );
    let mut h = History::default();
    h.push(0.0, vec![Some(1.0)]);
    h.push(0.01, vec![Some(2.0)]);
    h.push(0.02, vec![Some(3.0)]);
    assert_eq!(
        h.slope(0, 0.02, 0.5),
        None,
        "the window is not yet half covered"
    );
    for k in 3..30 {
        h.push(k as f64 * 0.01, vec![Some(1.0 + k as f64)]);
    }
    assert!((h.slope(0, 0.29, 0.2).expect("slope") - 100.0).abs() < 1e-6);
    assert!(
        (h.rise(0).expect("rise") - 27.0).abs() < 1e-9,
        "median of the last three less median of the first three"
    );
}

/// One reading per sensor of the three-finger layout; `tip_mm3` on f1.tip.
fn readings(tip_mm3: Option<f64>) -> Vec<Option<SensorReading>> {
    let mut r = vec![Some(SensorReading::default()); 7];
    r[1] = tip_mm3.map(|v| SensorReading {
        in_contact: v > 0.0,
        area_mm2: v,
        max_depth_mm: v / 100.0,
        volume_mm3: v,
        force_n: v * 0.08,
        centroid_mm: Some((0.0, 0.0)),
        slip: None,
    });
    r
}

fn runner(text: &str) -> TaskRunner {
    let l = layout();
    TaskRunner::new(
        parse(text).expect("valid"),
        &l,
        Tuning::default(),
        vec![0.0; 3],
        800.0,
    )
}

fn servos() -> Vec<ServoState> {
    vec![
        ServoState {
            position_deg: 30.0,
            ..ServoState::default()
        };
        3
    ]
}

#[test]
fn the_runner_exits_on_tactile_events_only_after_for_s() {
    let l = layout();
    let mut r = runner(TWO_STAGES);
    let mut t = 0.0;
    // No contact: stays in `touch`, f1 closes under force control.
    for _ in 0..10 {
        r.step(t, &fuse(&l, &readings(Some(0.0))), &servos());
        t += 0.03;
    }
    assert_eq!(r.stage_name(), Some("touch"));
    assert_eq!(r.phases()[0], Phase::Approach);
    // Contact: it must hold 0.1 s before the stage exits.
    r.step(t, &fuse(&l, &readings(Some(50.0))), &servos());
    assert_eq!(r.stage_name(), Some("touch"), "for_s not yet met");
    t += 0.06;
    r.step(t, &fuse(&l, &readings(Some(50.0))), &servos());
    assert_eq!(r.stage_name(), Some("touch"));
    t += 0.06;
    r.step(t, &fuse(&l, &readings(Some(50.0))), &servos());
    assert_eq!(r.stage_name(), Some("settle"));
    assert_eq!(r.records()[0].exit, Some(StageExit::Exit));
    assert!(
        r.records()[0].reason.contains("f1.tip: contact = true"),
        "{:?}",
        r.records()
    );
    // A rising signal is not settled; a risen, flat one is.
    for k in 1..=10 {
        t += 0.03;
        r.step(
            t,
            &fuse(&l, &readings(Some(50.0 + 3.0 * k as f64))),
            &servos(),
        );
        assert_eq!(r.stage_name(), Some("settle"), "still rising at {t}");
    }
    for _ in 0..12 {
        t += 0.03;
        r.step(t, &fuse(&l, &readings(Some(80.0))), &servos());
    }
    assert_eq!(r.stage_name(), Some("recover"), "{:?}", r.records());
    assert_eq!(r.records()[1].exit, Some(StageExit::Exit));
    // `recover` goes to abort once f1 is free: the task ends, not completed.
    t += 0.03;
    r.step(t, &fuse(&l, &readings(Some(0.0))), &servos());
    let end = r.end().expect("ended");
    assert!(!end.completed);
    assert!(end.reason.contains("aborted in stage recover"), "{end:?}");
}

#[test]
fn a_timeout_takes_its_branch_and_a_missing_reading_never_satisfies_a_condition() {
    let l = layout();
    let mut r = runner(TWO_STAGES);
    let mut t = 0.0;
    // f1.tip's reading is missing throughout: contact can never be confirmed.
    while t < 2.5 && r.stage_name() != Some("recover") {
        let goals = r.step(t, &fuse(&l, &readings(None)), &servos());
        assert!(
            goals
                .iter()
                .all(|g| g.position_deg.is_finite() && g.goal_current_ma.is_finite())
        );
        t += 0.03;
    }
    assert_eq!(r.stage_name(), Some("recover"));
    assert_eq!(r.records()[0].exit, Some(StageExit::Timeout));
    assert!((r.records()[0].end_s.expect("ended") - 2.0).abs() < 0.05);
    assert_eq!(r.goals()[0].position_deg, 0.0, "recover opens f1");
}

#[test]
fn an_abort_holds_every_finger_where_it_is_and_nan_readings_are_harmless() {
    let l = layout();
    let text = TWO_STAGES
        .replace("on_timeout = \"recover\"", "on_timeout = \"abort\"")
        .replace(
            "name = \"settle\"\n",
            "name = \"settle\"\nnext = \"recover\"\n",
        );
    let mut r = runner(&text);
    let mut t = 0.0;
    let mut bad = readings(Some(0.0));
    bad[1] = Some(SensorReading {
        force_n: f64::NAN,
        volume_mm3: f64::INFINITY,
        area_mm2: f64::NAN,
        ..SensorReading::default()
    });
    while r.end().is_none() && t < 3.0 {
        let goals = r.step(t, &fuse(&l, &bad), &servos());
        assert!(
            goals
                .iter()
                .all(|g| g.position_deg.is_finite() && g.goal_current_ma.is_finite())
        );
        t += 0.03;
    }
    let end = r.end().expect("timed out");
    assert!(end.reason.contains("timeout after 2 s"), "{end:?}");
    assert!(
        r.goals().iter().all(|g| g.position_deg == 30.0),
        "holds at the servos' positions"
    );
    assert!(r.phases().iter().all(|p| *p == Phase::Fault));
}

#[test]
fn stop_interrupts_the_stage_and_holds() {
    let l = layout();
    let mut r = runner(TWO_STAGES);
    r.step(100.0, &fuse(&l, &readings(Some(0.0))), &servos());
    r.step(100.5, &fuse(&l, &readings(Some(0.0))), &servos());
    r.stop(&[12.0, 13.0, 14.0], "watchdog");
    assert_eq!(r.records()[0].exit, Some(StageExit::Interrupted));
    assert_eq!(
        r.records()[0].end_s,
        Some(0.5),
        "ends at the last step, task time"
    );
    assert_eq!(r.end().map(|e| e.reason.as_str()), Some("watchdog"));
    let p: Vec<f64> = r.goals().iter().map(|g| g.position_deg).collect();
    assert_eq!(p, [12.0, 13.0, 14.0]);
}

const BRANCHES: &str = r#"
version = 1
name = "branches"
[[stage]]
name = "press"
timeout_s = 5.0
on_fail = "back-off"
fingers.f1 = { position_deg = 40.0, current_ma = 300.0 }
fingers.f2 = { current_ma = 250.0, speed_deg_s = 30.0 }
[[stage.exit]]
sensor = "f1.tip"
depth_mm_min = 0.5
area_change_pct = 50.0
[[stage.fail_if]]
sensor = "f1.tip"
force_n_min = 20.0
[[stage]]
name = "back-off"
timeout_s = 1.0
next = "done"
fingers.f1 = { open = true }
[[stage.exit]]
sensor = "f1.tip"
force_n_max = 0.5
"#;

#[test]
fn position_and_current_targets_become_goals_under_their_caps() {
    let l = layout();
    let mut r = runner(BRANCHES);
    let goals = r.step(0.0, &fuse(&l, &readings(Some(10.0))), &servos());
    assert_eq!(goals[0].position_deg, 40.0);
    assert_eq!(goals[0].goal_current_ma, 300.0);
    assert_eq!(
        goals[1].position_deg, l.fingers[1].servo_range_deg,
        "pushes toward closed"
    );
    assert_eq!(goals[1].goal_current_ma, 250.0);
    assert!(
        (goals[1].profile_velocity_rpm - 5.0).abs() < 1e-12,
        "30 deg/s"
    );
    assert_eq!(goals[2].position_deg, 0.0, "unnamed: stays open");
}

#[test]
fn a_failure_condition_takes_its_branch_before_the_exit_is_tested() {
    let l = layout();
    let mut r = runner(BRANCHES);
    r.step(0.0, &fuse(&l, &readings(Some(10.0))), &servos());
    // Area grows 10 → 40 mm² (+300%) and depth 0.1 → 0.4 mm: not yet deep enough.
    r.step(0.03, &fuse(&l, &readings(Some(40.0))), &servos());
    assert_eq!(r.stage_name(), Some("press"));
    // 300 mm³ reads 24 N: the failure condition holds, although the exit does too.
    r.step(0.06, &fuse(&l, &readings(Some(300.0))), &servos());
    assert_eq!(r.stage_name(), Some("back-off"));
    assert_eq!(r.records()[0].exit, Some(StageExit::Fail));
    assert!(
        r.records()[0].reason.contains("force_n ≥ 20"),
        "{:?}",
        r.records()
    );
    assert_eq!(r.goals()[0].position_deg, 0.0, "backs off");
    r.step(0.09, &fuse(&l, &readings(Some(1.0))), &servos());
    let end = r.end().expect("done");
    assert!(!end.completed, "a failure branch ran");
    assert_eq!(end.reason, "done after a failure branch");
}

#[test]
fn depth_and_area_change_exit_together() {
    let l = layout();
    let mut r = runner(BRANCHES);
    r.step(0.0, &fuse(&l, &readings(Some(20.0))), &servos());
    // 60 mm²: +200% area and 0.6 mm deep, 4.8 N: below the failure force.
    r.step(0.03, &fuse(&l, &readings(Some(60.0))), &servos());
    assert_eq!(r.stage_name(), Some("back-off"));
    assert_eq!(r.records()[0].exit, Some(StageExit::Exit));
}
