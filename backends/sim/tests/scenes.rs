//! Scene tests: for every scene in `configs/scenes`, closing the fingers with a fixed
//! current ramp touches exactly the scene's `expect_contact` sensors, and each sensor's
//! force and indentation are zero before its first contact, then non-decreasing with the
//! goal current until a crush or a joint limit.

mod common;

use common::layout;
use gelgrip_controller::layout::HandLayout;
use gelgrip_sim::scene_spec::SceneSpec;
use gelgrip_sim::world::World;
use gelgrip_sim::world_log::EventKind;

const RAMP_STEPS: u64 = 40;
const STEP_US: u64 = 100_000;
const MAX_CURRENT_MA: f64 = 800.0;

fn scenes() -> Vec<(String, String)> {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../configs/scenes");
    let mut out: Vec<(String, String)> = std::fs::read_dir(dir)
        .expect("configs/scenes")
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .map(|p| {
            let text = std::fs::read_to_string(&p).expect("read scene");
            (p.display().to_string(), text)
        })
        .collect();
    out.sort();
    assert_eq!(out.len(), 6, "the paper's six scenes");
    out
}

#[test]
fn closing_on_each_scene_touches_exactly_the_expected_sensors_with_monotonic_force() {
    let layout = layout();
    for (file, text) in scenes() {
        let scene = SceneSpec::from_toml(&file, &text, &layout).expect("valid scene");
        let expect = scene.expect_contact.clone();
        let mut world = World::new(&layout, Some(scene));
        world.advance_to(0);
        let n = layout.sensors.len();
        let mut last = vec![(0.0f64, 0.0f64); n];
        let mut limited = false;
        for step in 1..=RAMP_STEPS + 10 {
            let current = MAX_CURRENT_MA * (step.min(RAMP_STEPS) as f64 / RAMP_STEPS as f64);
            world.close_fingers(current);
            world.advance_to(step * STEP_US);
            limited |= (0..world.fingers()).any(|f| {
                let spec = &layout.fingers[f];
                world
                    .joints_rad(f)
                    .expect("finger")
                    .iter()
                    .zip(&spec.phalanges)
                    .any(|(q, p)| *q >= p.limit_deg.to_radians() - 1e-6)
            });
            let crushed = world.log().has(EventKind::Crushed);
            // Once the screwdriver runs, its reaction turns the handle into one finger and
            // away from the others: their forces may fall.
            let tool_ran = world.log().has(EventKind::TriggerOn);
            for (s, prev) in last.iter_mut().enumerate() {
                let c = world.contact(s).expect("sensor");
                let now = (c.load.force_n, c.max_depth_mm);
                assert!(now.0.is_finite() && now.1.is_finite(), "{file}: sensor {s}");
                if world.log().first_contact_s()[s].is_none() {
                    assert_eq!(now, (0.0, 0.0), "{file}: sensor {s} before contact");
                }
                if !crushed && !limited && !tool_ran {
                    assert!(
                        now.0 >= prev.0 * 0.995 - 0.005,
                        "{file}: sensor {s} force fell from {} to {} at {current} mA",
                        prev.0,
                        now.0
                    );
                }
                *prev = now;
            }
        }
        let touched: Vec<usize> = (0..n)
            .filter(|s| world.log().first_contact_s()[*s].is_some())
            .collect();
        let mut expected = expect.clone();
        expected.sort_unstable();
        assert_eq!(touched, expected, "{file}: touched sensors");
    }
}

#[test]
fn the_egg_cracks_and_the_cup_crushes_under_a_hard_squeeze_but_the_ball_does_not() {
    let layout = layout();
    for (file, text) in scenes() {
        let scene = SceneSpec::from_toml(&file, &text, &layout).expect("valid scene");
        let crushable = scene.object.crush_force_n.is_some();
        let mut world = World::new(&layout, Some(scene));
        world.advance_to(0);
        world.close_fingers(1400.0);
        world.advance_to(4_000_000);
        assert_eq!(world.log().has(EventKind::Crushed), crushable, "{file}");
    }
}

#[test]
fn a_weak_grip_drops_the_ball_when_released_and_a_firm_one_holds_it() {
    let layout = layout();
    let text = include_str!("../../../configs/scenes/tennis-ball.toml");
    for (current, held) in [(0.0, false), (600.0, true)] {
        let scene = SceneSpec::from_toml("tennis-ball.toml", text, &layout).expect("scene");
        let mut world = World::new(&layout, Some(scene));
        world.advance_to(0);
        world.close_fingers(current);
        world.advance_to(8_000_000);
        let log = world.log();
        assert!(log.has(EventKind::Released));
        assert_eq!(
            !log.has(EventKind::Dropped),
            held,
            "{current} mA: {:?}",
            log.events()
        );
        let slip = world.object().expect("object").slip_mm;
        assert!(slip.is_finite());
        if held {
            assert!(slip.abs() < 5.0, "held ball slipped {slip} mm");
        }
    }
}

#[test]
fn the_screwdriver_trigger_starts_the_tool_and_the_bolt_tightens() {
    let layout = layout();
    let text = include_str!("../../../configs/scenes/screwdriver.toml");
    let scene = SceneSpec::from_toml("screwdriver.toml", text, &layout).expect("scene");
    let mut world = World::new(&layout, Some(scene));
    world.advance_to(0);
    world.close_fingers(800.0);
    world.advance_to(10_000_000);
    let log = world.log();
    assert!(log.has(EventKind::TriggerOn), "{:?}", log.events());
    assert!(log.has(EventKind::BoltTight), "{:?}", log.events());
}

#[test]
fn a_five_finger_layout_closes_on_the_ball_with_no_code_change() {
    let layout = HandLayout::from_toml(
        "five-finger.toml",
        include_str!("../../../configs/layouts/five-finger.toml"),
    )
    .expect("layout");
    assert_eq!(layout.fingers.len(), 5);
    assert!(layout.fingers.iter().all(|f| f.phalanges.len() == 3));
    let text = include_str!("../../../configs/scenes/tennis-ball.toml")
        .replace("expect_contact = [", "expect_contact = [\"palm\"] # [");
    let scene = SceneSpec::from_toml("tennis-ball.toml", &text, &layout).expect("scene");
    let mut world = World::new(&layout, Some(scene));
    world.advance_to(0);
    world.close_fingers(800.0);
    world.advance_to(4_000_000);
    let touched = world
        .log()
        .first_contact_s()
        .iter()
        .filter(|t| t.is_some())
        .count();
    assert!(touched >= 6, "{touched} of 16 sensors touched");
    for s in 0..layout.sensors.len() {
        let c = world.contact(s).expect("sensor");
        assert!(c.load.force_n.is_finite() && c.max_depth_mm.is_finite());
    }
}

#[test]
fn a_scene_switched_mid_run_starts_afresh_and_its_fixture_counts_from_the_switch() {
    let layout = layout();
    let ball = include_str!("../../../configs/scenes/tennis-ball.toml");
    let spec = || SceneSpec::from_toml("tennis-ball.toml", ball, &layout).expect("scene");
    let release_after_s = spec().release_after_s.expect("the ball's fixture lets go");
    let mut world = World::new(&layout, Some(spec()));
    world.advance_to(0);
    // Empty hand: the ball falls once the fixture lets go.
    world.advance_to(((release_after_s + 2.0) * 1e6) as u64);
    assert!(world.log().has(EventKind::Released));
    let fallen_mm = world.object().expect("ball").slip_mm;
    assert!(fallen_mm.abs() > 1.0, "it fell: {fallen_mm} mm");

    // Switch to a fresh ball: back in place, a fresh log, and the fixture holds it again
    // until `release_after_s` after the switch.
    let switched_s = world.elapsed_s();
    world.set_scene(Some(spec()));
    assert_eq!(world.object().expect("ball").slip_mm, 0.0);
    assert!(world.log().events().is_empty());
    let half = switched_s + release_after_s / 2.0;
    world.advance_to((half * 1e6) as u64);
    assert!(
        !world.log().has(EventKind::Released),
        "{:?}",
        world.log().events()
    );
    assert_eq!(world.object().expect("ball").slip_mm, 0.0);
    world.advance_to(((switched_s + release_after_s + 0.5) * 1e6) as u64);
    assert!(world.log().has(EventKind::Released));

    // And to empty space.
    world.set_scene(None);
    assert!(world.object().is_none() && world.scene().is_none());
    world.advance_to(((switched_s + release_after_s + 1.0) * 1e6) as u64);
    assert!(
        (0..layout.sensors.len()).all(|s| world.contact(s).is_none_or(|c| c.load.force_n == 0.0))
    );
}
