//! The simulated world's cost on this machine: stepping the rubber-duck scene for 4 s of
//! simulated time at an 800 mA squeeze, one pad height map, and one frame through the
//! reference camera and the scene camera. Run with
//! `cargo run --release -p gelgrip-sim --example world_cost`; figures are in docs/sim.md.
use gelgrip_controller::actuator::MotorCommand;
use gelgrip_controller::layout::HandLayout;
use gelgrip_sim::scene_spec::SceneSpec;
use gelgrip_sim::world::World;
use std::time::Instant;

fn main() {
    let layout = HandLayout::from_toml(
        "l",
        include_str!("../../../configs/layouts/three-finger.toml"),
    )
    .expect("layout");
    let text = include_str!("../../../configs/scenes/rubber-duck.toml");
    let scene = SceneSpec::from_toml("duck", text, &layout).expect("scene");
    let mut w = World::new(&layout, Some(scene));
    w.advance_to(0);
    for f in 0..3 {
        w.set_command(
            f,
            MotorCommand {
                torque_on: true,
                goal_position_deg: 180.0,
                goal_current_ma: 800.0,
                profile_velocity_rpm: 0.0,
            },
        );
    }
    let t = Instant::now();
    w.advance_to(4_000_000);
    println!("step: {:?} per 4 s", t.elapsed());
    let t = Instant::now();
    let mut n = 0;
    for _ in 0..10 {
        for s in 0..7 {
            if w.height_map(s).is_some() {
                n += 1;
            }
        }
    }
    println!("height maps: {:?} per map ({n})", t.elapsed() / n.max(1));
    let cfg = gelgrip_sim::config::SimConfig::from_section(
        &gelgrip_controller::config::BackendSection {
            check: gelgrip_controller::config::FieldCheck::new("x"),
            prefix: "hub.sim".into(),
            table: toml::Table::new(),
            base_dir: ".".into(),
            files: std::sync::Arc::new(gelgrip_controller::config::DiskFiles),
        },
        &layout,
    )
    .expect("cfg");
    let cam = gelgrip_sim::pool::SensorCamera::new(&layout, 1, &cfg).expect("cam");
    let map = w.height_map(1).expect("map");
    let t = Instant::now();
    for k in 0..20 {
        let _ = cam.rgb(&map, k);
    }
    println!("render: {:?}", t.elapsed() / 20);
    let fast = gelgrip_sim::pool::SceneCamera::new(cam.clone());
    let t = Instant::now();
    for k in 0..20 {
        let _ = fast.jpeg(&map, None, k);
    }
    println!("scene camera render + encode: {:?}", t.elapsed() / 20);
    let rgb = cam.rgb(&map, 0);
    let t = Instant::now();
    for _ in 0..20 {
        let _ = gelgrip_sim::pool::encode_jpeg(&rgb, 320, 240, 85);
    }
    println!("encode: {:?}", t.elapsed() / 20);
}
