//! Property tests of scene files (`configs/scenes/*.toml`, `gelgrip run --scene FILE` and
//! the dashboard's scene switch; issue 45): random text and mutations of the six real
//! scenes (numbers swapped for values at the edges of their type, lines added or dropped,
//! bytes changed) go through `SceneSpec::from_toml`, which answers with a typed error or a
//! scene; every scene it accepts is then run, fingers closing on it for a simulated
//! second, and the world must stay finite and not panic.
//!
//! Case counts: `PROPTEST_CASES` (proptest's 256 when unset), capped per test so that
//! `scripts/test`'s 30 000-case step stays short; `GELGRIP_FUZZ_CASES` sets the exact count
//! for a long run outside CI (docs/reliability.md).

use std::time::{Duration, Instant};

use proptest::prelude::*;

use gelgrip_controller::actuator::MotorCommand;
use gelgrip_controller::layout::HandLayout;
use gelgrip_sim::scene_spec::SceneSpec;
use gelgrip_sim::world::World;

/// Cases of the text-only tests in CI (`PROPTEST_CASES` above it is capped).
const PARSE_CI_CASES: u32 = 3000;
/// Cases of the test that runs each accepted scene (a simulated second each).
const RUN_CI_CASES: u32 = 150;
/// Longest one case may take: far above a parse's microseconds, far below a hang.
const CASE_BUDGET: Duration = Duration::from_secs(20);

/// The six scenes of `configs/scenes`.
const SCENES: [&str; 6] = [
    include_str!("../../../configs/scenes/egg.toml"),
    include_str!("../../../configs/scenes/paper-cup.toml"),
    include_str!("../../../configs/scenes/rubber-duck.toml"),
    include_str!("../../../configs/scenes/screwdriver.toml"),
    include_str!("../../../configs/scenes/tennis-ball.toml"),
    include_str!("../../../configs/scenes/toy-corn.toml"),
];

fn layout() -> HandLayout {
    let text = include_str!("../../../configs/layouts/three-finger.toml");
    HandLayout::from_toml("three-finger.toml", text).expect("layout")
}

#[path = "../../../testsupport/fuzz_runner.rs"]
mod fuzz_runner;
use fuzz_runner::check;

/// A value a field may be given: numbers at the edges, other types, nothing.
fn token() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("1e308".to_string()),
        Just("-1e308".to_string()),
        Just("nan".to_string()),
        Just("inf".to_string()),
        Just("-inf".to_string()),
        Just("0".to_string()),
        Just("0.0".to_string()),
        Just("-0.0".to_string()),
        Just("1e-300".to_string()),
        Just("9223372036854775807".to_string()),
        Just("-1".to_string()),
        Just("[]".to_string()),
        Just("[0.0, 0.0, 0.0]".to_string()),
        Just("[1e308, 1e308, 1e308]".to_string()),
        Just("\"sphere\"".to_string()),
        Just("{}".to_string()),
        (-1e5f64..1e5).prop_map(|v| format!("{v:?}")),
        "[ -~]{0,8}",
    ]
}

/// Lines a scene may gain: keys of every table, set to tokens, and table headers.
fn extra_line() -> impl Strategy<Value = String> {
    let keys = [
        "version",
        "name",
        "expect_contact",
        "gravity_dir",
        "release_after_s",
        "xyz_mm",
        "rpy_deg",
        "mass_g",
        "friction",
        "slip_dir",
        "stiffness_n_per_mm",
        "crush_force_n",
        "crushed_stiffness_factor",
        "kind",
        "radius_mm",
        "radii_mm",
        "length_mm",
        "size_mm",
        "travel_dir",
        "travel_mm",
        "preload_n",
        "switch_force_n",
        "free_rpm",
        "lever_mm",
    ];
    prop_oneof![
        (proptest::sample::select(keys.to_vec()), token()).prop_map(|(k, v)| format!("{k} = {v}")),
        Just("[[object.shapes]]".to_string()),
        Just("[object.trigger]".to_string()),
        Just("[object.bolt]".to_string()),
        Just("[object]".to_string()),
        Just("kind = \"ellipsoid\"".to_string()),
        Just("kind = \"cuboid\"".to_string()),
    ]
}

/// One change to a scene's text.
#[derive(Debug, Clone)]
enum Edit {
    /// The `n`th number in the text replaced by a token.
    Number(usize, String),
    /// A line inserted before line `n`.
    Insert(usize, String),
    /// Line `n` dropped.
    Drop(usize),
    /// Byte `n` set.
    Byte(usize, u8),
    /// The `n`th number in the text multiplied by a factor.
    Scale(usize, f64),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        4 => (any::<usize>(), token()).prop_map(|(n, t)| Edit::Number(n, t)),
        2 => (any::<usize>(), extra_line()).prop_map(|(n, l)| Edit::Insert(n, l)),
        1 => any::<usize>().prop_map(Edit::Drop),
        1 => (any::<usize>(), any::<u8>()).prop_map(|(n, b)| Edit::Byte(n, b)),
    ]
}

/// Byte ranges of the numbers in `text` (a digit run with its sign, point and exponent).
fn numbers(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i].is_ascii_digit() {
            let start = if i > 0 && b[i - 1] == b'-' { i - 1 } else { i };
            let mut end = i;
            while end < b.len() && (b[end].is_ascii_digit() || b"._eE+-".contains(&b[end])) {
                end += 1;
            }
            out.push((start, end));
            i = end;
        } else {
            i += 1;
        }
    }
    out
}

/// `text` with `edit` applied.
fn apply(text: &str, edit: &Edit) -> String {
    match edit {
        Edit::Number(n, token) => {
            let spans = numbers(text);
            let Some(&(a, b)) = spans.get(n % spans.len().max(1)) else {
                return text.to_string();
            };
            format!("{}{token}{}", &text[..a], &text[b..])
        }
        Edit::Scale(n, factor) => {
            let spans = numbers(text);
            let Some(&(a, b)) = spans.get(n % spans.len().max(1)) else {
                return text.to_string();
            };
            let Ok(v) = text[a..b].parse::<f64>() else {
                return text.to_string();
            };
            format!("{}{:?}{}", &text[..a], v * factor, &text[b..])
        }
        Edit::Insert(n, line) => {
            let mut lines: Vec<&str> = text.lines().collect();
            lines.insert(n % (lines.len() + 1), line);
            lines.join("\n")
        }
        Edit::Drop(n) => {
            let mut lines: Vec<&str> = text.lines().collect();
            if !lines.is_empty() {
                lines.remove(n % lines.len());
            }
            lines.join("\n")
        }
        Edit::Byte(n, v) => {
            let mut bytes = text.as_bytes().to_vec();
            let len = bytes.len().max(1);
            if let Some(b) = bytes.get_mut(n % len) {
                *b = *v;
            }
            String::from_utf8_lossy(&bytes).into_owned()
        }
    }
}

/// Parse `text`; an error must name the file.
fn parse(layout: &HandLayout, text: &str) -> Option<SceneSpec> {
    let start = Instant::now();
    let parsed = SceneSpec::from_toml("fuzz.toml", text, layout);
    assert!(
        start.elapsed() < CASE_BUDGET,
        "parse took {:?}",
        start.elapsed()
    );
    match parsed {
        Ok(scene) => Some(scene),
        Err(e) => {
            assert!(e.to_string().contains("fuzz.toml"), "{e}");
            None
        }
    }
}

/// Close every finger on `scene` at 800 mA for a simulated second: no panic, and the
/// object's state and every contact stay finite.
fn run(layout: &HandLayout, scene: SceneSpec) {
    let start = Instant::now();
    let mut world = World::new(layout, Some(scene));
    world.advance_to(0);
    for f in 0..world.fingers() {
        let command = MotorCommand {
            torque_on: true,
            goal_position_deg: 180.0,
            goal_current_ma: 800.0,
            profile_velocity_rpm: 0.0,
        };
        world.set_command(f, command);
    }
    for step in 1..=10u64 {
        world.advance_to(step * 100_000);
    }
    if let Some(o) = world.object() {
        let state = [o.slip_mm, o.deflection_mm, o.trigger_mm, o.bolt_turns];
        assert!(state.iter().all(|v| v.is_finite()), "object {state:?}");
    }
    for s in 0..layout.sensors.len() {
        if let Some(c) = world.contact(s) {
            let v = [c.max_depth_mm, c.area_mm2, c.volume_mm3, c.trigger_force_n];
            assert!(v.iter().all(|x| x.is_finite()), "sensor {s}: {v:?}");
        }
    }
    assert!(
        start.elapsed() < CASE_BUDGET,
        "run took {:?}",
        start.elapsed()
    );
}

#[test]
fn the_six_scenes_parse_and_their_numbers_are_found() {
    let layout = layout();
    for text in SCENES {
        assert!(parse(&layout, text).is_some());
        assert!(numbers(text).len() > 5);
    }
    let nan = apply(SCENES[4], &Edit::Number(1, "nan".into()));
    assert_ne!(nan, SCENES[4]);
}

#[test]
fn random_text_is_an_error_not_a_panic() {
    let layout = layout();
    check(PARSE_CI_CASES, "(?s).{0,400}", |text: String| {
        let _ = parse(&layout, &text);
    });
}

#[test]
fn mutated_scenes_parse_or_fail_cleanly() {
    let layout = layout();
    let strategy = (0..SCENES.len(), proptest::collection::vec(edit(), 1..5));
    check(PARSE_CI_CASES, strategy, |(i, edits)| {
        let text = edits
            .iter()
            .fold(SCENES[i].to_string(), |t, e| apply(&t, e));
        let _ = parse(&layout, &text);
    });
}

#[test]
fn every_scene_the_parser_accepts_runs_without_a_panic() {
    let layout = layout();
    // Numbers scaled (most still parse, so the world runs on values out to the edges of
    // what validation lets through) or swapped for tokens.
    let factor = prop_oneof![
        Just(0.0),
        Just(1e-3),
        Just(0.1),
        Just(-1.0),
        Just(3.0),
        Just(100.0),
        Just(1e4),
        0.0f64..10.0,
    ];
    let number = prop_oneof![
        4 => (any::<usize>(), factor).prop_map(|(n, f)| Edit::Scale(n, f)),
        1 => (any::<usize>(), token()).prop_map(|(n, t)| Edit::Number(n, t)),
    ];
    let strategy = (0..SCENES.len(), proptest::collection::vec(number, 1..4));
    check(RUN_CI_CASES, strategy, |(i, edits)| {
        let text = edits
            .iter()
            .fold(SCENES[i].to_string(), |t, e| apply(&t, e));
        if let Some(scene) = parse(&layout, &text) {
            run(&layout, scene);
        }
    });
}
