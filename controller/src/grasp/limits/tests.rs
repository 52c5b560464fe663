//! The grasp limits on the shipped three-finger layout (the numbers `docs/control.md`
//! quotes), each field's edges, the messages, and finite bounds for extreme layouts.

use super::*;
use crate::actuator::XM430_W350;
use crate::grasp::Tuning;
use crate::gripper::GripperService;

const LAYOUT: &str = include_str!("../../../../configs/layouts/three-finger.toml");

fn layout_with(edits: &[(&str, &str)]) -> HandLayout {
    let text = edits
        .iter()
        .fold(LAYOUT.to_string(), |t, (from, to)| t.replace(from, to));
    HandLayout::from_toml("three-finger.toml", &text).expect("a valid layout")
}

fn shipped(current_limit_ma: f64) -> GraspLimits {
    GraspLimits::for_hand(&layout_with(&[]), XM430_W350, current_limit_ma)
}

fn request(force_n: f64, speed_deg_s: f64, timeout_s: f64) -> GraspRequest {
    GraspRequest {
        target_force_n: force_n,
        speed_deg_s,
        current_limit_ma: 1000.0,
        fingers: vec![0, 1, 2],
        timeout_s,
        auto_target: false,
    }
}

fn refused_field(limits: &GraspLimits, r: &GraspRequest) -> &'static str {
    match limits.check(r) {
        Err(GripperError::InvalidRequest { field, .. }) => field,
        other => panic!("{r:?}: expected a refusal, got {other:?}"),
    }
}

#[test]
fn the_shipped_hand_presses_163_7_n_per_finger_at_1000_ma_and_376_6_at_stall() {
    // T = 4.1 N·m × 1000/2300 / 10 mm = 178.3 N; × (14/20 + 3.5/16) = 163.78 N.
    let at_1000 = shipped(1000.0);
    assert_eq!(at_1000.max_force_n(&[0, 1, 2], 1000.0), 163.7);
    assert_eq!(
        at_1000.max_force_n(&[1], 500.0),
        81.8,
        "the request's own cap"
    );
    assert_eq!(
        at_1000.max_force_n(&[0], 2300.0),
        163.7,
        "never beyond the configured Current Limit"
    );
    let at_3209 = shipped(3209.0);
    assert_eq!(
        at_3209.max_force_n(&[0, 1, 2], 3000.0),
        376.6,
        "never beyond the stall current"
    );
    assert_eq!(shipped(2300.0).max_force_n(&[0, 1, 2], 2300.0), 376.6);
    assert_eq!(at_1000.max_speed_deg_s(), 276.0);
    assert_eq!(at_1000.max_force_n(&[], 1000.0), 0.0);
}

#[test]
fn each_field_is_accepted_to_its_edge_and_refused_past_it() {
    let limits = shipped(1000.0);
    for ok in [
        request(163.7, 15.0, 20.0),
        request(0.01, 276.0, 120.0),
        request(1.5, 1e-3, 1e-3),
    ] {
        assert_eq!(limits.check(&ok), Ok(()), "{ok:?}");
    }
    let cases = [
        (request(163.8, 15.0, 20.0), "target_force_n"),
        (request(0.0, 15.0, 20.0), "target_force_n"),
        (request(-1.0, 15.0, 20.0), "target_force_n"),
        (request(f64::NAN, 15.0, 20.0), "target_force_n"),
        (request(f64::INFINITY, 15.0, 20.0), "target_force_n"),
        (request(1e308, 15.0, 20.0), "target_force_n"),
        (request(1.5, 276.01, 20.0), "speed_deg_s"),
        (request(1.5, 0.0, 20.0), "speed_deg_s"),
        (request(1.5, f64::NAN, 20.0), "speed_deg_s"),
        (request(1.5, f64::INFINITY, 20.0), "speed_deg_s"),
        (request(1.5, 15.0, 120.01), "timeout_s"),
        (request(1.5, 15.0, 0.0), "timeout_s"),
        (request(1.5, 15.0, f64::NAN), "timeout_s"),
        (request(1.5, 15.0, f64::INFINITY), "timeout_s"),
        (
            GraspRequest {
                current_limit_ma: f64::NAN,
                ..request(1.5, 15.0, 20.0)
            },
            "current_limit_ma",
        ),
        (
            GraspRequest {
                fingers: vec![3],
                ..request(1.5, 15.0, 20.0)
            },
            "fingers",
        ),
    ];
    for (r, field) in cases {
        assert_eq!(refused_field(&limits, &r), field, "{r:?}");
    }
}

#[test]
fn the_messages_name_the_range_and_where_it_comes_from() {
    let limits = shipped(1000.0);
    let message = |r: GraspRequest| limits.check(&r).expect_err("refused").to_string();
    assert_eq!(
        message(request(1e308, 15.0, 20.0)),
        "invalid grasp request: target_force_n = 1e308 (a force per finger in (0, 163.7] N: \
         what f1, f2, f3 can press with at the 1000 mA current cap)"
    );
    assert_eq!(
        message(request(1.5, 1e9, 20.0)),
        "invalid grasp request: speed_deg_s = 1e9 (a speed in (0, 276] deg/s: the \
         XM430-W350's no-load speed, 46 rpm at 12 V)"
    );
    assert_eq!(
        message(request(1.5, 15.0, 500.0)),
        "invalid grasp request: timeout_s = 500 (a timeout in (0, 120] s: the longest a grasp \
         may take)"
    );
    assert!(
        message(GraspRequest {
            current_limit_ma: 250.0,
            fingers: vec![2],
            ..request(50.0, 15.0, 20.0)
        })
        .contains("(0, 40.9] N: what f3 can press with at the 250 mA current cap"),
    );
}

#[test]
fn the_weakest_finger_taking_part_sets_the_bound_and_is_named() {
    // f2 winds on a 20 mm pulley: half the tension, half the force.
    let text = LAYOUT.replacen(
        "id = \"f2\"\nbase_xyz_mm = [-20.0, 34.6, 25.0]\nyaw_deg = 120.0\npulley_radius_mm = 10.0",
        "id = \"f2\"\nbase_xyz_mm = [-20.0, 34.6, 25.0]\nyaw_deg = 120.0\npulley_radius_mm = 20.0",
        1,
    );
    assert_ne!(text, LAYOUT, "the edit applies");
    let layout = HandLayout::from_toml("l.toml", &text).expect("layout");
    let limits = GraspLimits::for_hand(&layout, XM430_W350, 1000.0);
    assert_eq!(limits.max_force_n(&[0, 1, 2], 1000.0), 81.8);
    assert_eq!(limits.max_force_n(&[0, 2], 1000.0), 163.7);
    assert_eq!(
        limits.force_reason(&[0, 1, 2], 1000.0),
        "what f2 can press with at the 1000 mA current cap"
    );
}

#[test]
fn extreme_layouts_and_caps_give_finite_bounds() {
    let strong = layout_with(&[
        ("pulley_radius_mm = 10.0", "pulley_radius_mm = 1.0"),
        ("moment_arm_mm = 14.0", "moment_arm_mm = 100.0"),
        ("moment_arm_mm = 3.5", "moment_arm_mm = 100.0"),
        ("pad_offset_mm = 20.0", "pad_offset_mm = 0.0"),
        ("pad_offset_mm = 16.0", "pad_offset_mm = 0.0"),
    ]);
    let weak = layout_with(&[
        ("pulley_radius_mm = 10.0", "pulley_radius_mm = 100.0"),
        ("moment_arm_mm = 14.0", "moment_arm_mm = 0.1"),
        ("moment_arm_mm = 3.5", "moment_arm_mm = 0.1"),
        ("pad_offset_mm = 20.0", "pad_offset_mm = 500.0"),
        ("pad_offset_mm = 16.0", "pad_offset_mm = 500.0"),
    ]);
    for layout in [strong, weak] {
        for configured in [0.0, 1.0, 1000.0, 3209.0, f64::NAN, f64::INFINITY] {
            let limits = GraspLimits::for_hand(&layout, XM430_W350, configured);
            for requested in [0.0, 1e-9, 1000.0, 1e12, f64::INFINITY] {
                let max = limits.max_force_n(&[0, 1, 2], requested);
                assert!(
                    max.is_finite() && max >= 0.0,
                    "{configured} {requested}: {max}"
                );
                let r = GraspRequest {
                    current_limit_ma: requested,
                    ..request(1e308, 15.0, 20.0)
                };
                let message = limits.check(&r).expect_err("refused").to_string();
                assert!(!message.contains("NaN"), "{message}");
            }
        }
    }
    let none = shipped(0.0);
    assert_eq!(
        none.max_force_n(&[0, 1, 2], 1000.0),
        0.0,
        "no current, no force"
    );
    assert_eq!(
        refused_field(&none, &request(0.01, 15.0, 20.0)),
        "target_force_n"
    );
}

#[test]
fn a_service_for_the_hand_refuses_out_of_range_requests_through_its_handle() {
    let (_service, handle) =
        GripperService::for_hand(&layout_with(&[]), 1000.0, Default::default());
    assert_eq!(handle.limits(), Some(&shipped(1000.0)));
    let err = handle
        .start_grasp(request(1e308, 15.0, 20.0))
        .expect_err("refused");
    assert!(err.to_string().contains("(0, 163.7] N"), "{err}");
    assert!(handle.start_grasp(request(163.7, 276.0, 120.0)).is_ok());
    let (_service, permissive) =
        GripperService::new(Tuning::default(), vec![150.0; 3], vec![0.0; 3], 1000.0);
    assert!(permissive.limits().is_none());
    assert!(
        permissive
            .start_grasp(request(500.0, 1000.0, 500.0))
            .is_ok(),
        "no hand, no bounds"
    );
}

#[test]
fn numbers_read_plainly_or_in_exponent_form() {
    assert_eq!(number(1e308), "1e308");
    assert_eq!(number(1e9), "1e9");
    assert_eq!(number(500.0), "500");
    assert_eq!(number(163.7), "163.7");
    assert_eq!(number(0.0), "0");
    assert_eq!(number(f64::NAN), "NaN");
    assert_eq!(number(f64::INFINITY), "inf");
    assert_eq!(number(-2.5e-7), "-2.5e-7");
}
