//! The simulator under tangential load: a ball held by the fingers and pulled along its
//! `slip_dir` (`[object.load]`) sticks, slips incipiently as the pull grows, then slides.

mod common;

use common::layout;
use gelgrip_controller::layout::HandLayout;
use gelgrip_sim::scene_spec::SceneSpec;
use gelgrip_sim::world::World;

const STEP_US: u64 = 20_000;

/// The tennis ball, let go by its fixture at 3 s, with `load` as its `[object.load]`, the
/// fingers closing with `current_ma`.
fn held_ball(layout: &HandLayout, load: &str, current_ma: f64) -> World {
    let text = include_str!("../../../configs/scenes/tennis-ball.toml")
        .replace("release_after_s = 6.0", "release_after_s = 3.0");
    let text = format!("{text}\n[object.load]\n{load}\n");
    let scene = SceneSpec::from_toml("tennis-ball.toml", &text, layout).expect("scene");
    let mut world = World::new(layout, Some(scene));
    world.advance_to(0);
    world.close_fingers(current_ma);
    world
}

/// The least stick ratio over the loaded contacts, and their total capacity, N.
fn least_stick(world: &World) -> (f64, f64) {
    (0..world.sensors())
        .filter_map(|s| world.traction(s))
        .filter(|t| t.contact_radius_mm > 0.0)
        .fold((1.0f64, 0.0), |(r, cap), t| {
            (r.min(t.stick_ratio), cap + t.capacity_n)
        })
}

#[test]
fn a_growing_pull_makes_the_ball_slide_after_its_contacts_slip() {
    let layout = layout();
    let mut world = held_ball(
        &layout,
        "kind = \"ramp\"\nrate_n_per_s = 40.0\nstart_s = 4.0",
        300.0,
    );
    let (mut step, mut slid, mut sheared) = (0, false, false);
    while world.slip_truth().gross_s.is_none() && step < 1_000 {
        step += 1;
        world.advance_to(step * STEP_US);
        let (ratio, capacity) = least_stick(&world);
        assert!(ratio.is_finite() && capacity.is_finite());
        assert!((0.0..=1.0).contains(&ratio));
        // The gel under a loaded contact moves along the pad, from a centre on it.
        sheared |= (0..world.sensors())
            .filter_map(|s| world.gel_shear(s))
            .any(|g| {
                let (x, y) = g.centre_px;
                (0.0..320.0).contains(&x) && (0.0..240.0).contains(&y) && g.traction.shift_mm > 0.0
            });
        // Sliding: the stick zones are gone, and the gel carries its full-slip shift.
        slid |= capacity > 0.0
            && (0..world.sensors())
                .filter_map(|s| world.traction(s))
                .filter(|t| t.contact_radius_mm > 0.0 && t.capacity_n > 0.0)
                .all(|t| t.stick_ratio == 0.0 && t.shift_mm > 0.0);
        if step * STEP_US < 3_000_000 {
            // The fixture holds the ball until it lets go at 3 s.
            assert_eq!((ratio, world.slip_truth().slip_at_load_mm), (1.0, None));
        }
    }
    let truth = *world.slip_truth();
    let (incipient, gross) = (
        truth.incipient_s.expect("incipient slip"),
        truth.gross_s.expect("gross slip within 20 s"),
    );
    assert!(
        3.0 <= incipient && incipient < gross && gross > 4.0,
        "{truth:?}"
    );
    assert!(truth.motion_mm > 0.1);
    assert!(slid, "the ball slid with every contact sliding");
    assert!(sheared, "the loaded pads' gel moved");
}

/// The screwdriver rests on the palm and the fingers close on it: the palm's part of the
/// grip is the palm sensor's contact force alone, a part of the whole.
#[test]
fn the_palm_s_part_of_the_grip_is_its_contact_s_force() {
    let layout = layout();
    let text = include_str!("../../../configs/scenes/screwdriver.toml");
    let scene = SceneSpec::from_toml("screwdriver.toml", text, &layout).expect("scene");
    let mut world = World::new(&layout, Some(scene));
    world.advance_to(0);
    world.close_fingers(300.0);
    world.advance_to(2_000_000);
    let palm: f64 = (0..world.sensors())
        .filter(|&s| layout.sensors[s].id.to_string() == "palm")
        .filter_map(|s| world.contact(s))
        .map(|c| c.load.force_n.max(0.0))
        .sum();
    let (grip, palm_part) = (world.grip_n(), world.palm_grip_n());
    assert!(palm > 0.0, "the screwdriver presses the palm");
    assert_eq!(palm_part, palm);
    assert!(palm_part < grip, "{palm_part} of {grip}");
}
